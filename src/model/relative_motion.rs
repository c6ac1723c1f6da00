//! Viewpoint-invariant encoding of one agent's motion relative to another's, for the
//! agent <- agent edges of the HeteroGNN (`ModelConfig::agent_edge_motion`).
//!
//! Why: with the paper's pose-only edges a receiver learns how fast the car ahead closes in only
//! by pairing the sender's speed (inside the sender's embedding) with its own speed after a max
//! over all senders, which loses which sender was which. Models trained with pose-only edges
//! showed no car-following response (`experiments/main/car_following.md`): their acceleration
//! did not depend on the closing speed or the leader's braking. These features hand every edge the quantities a car-following rule
//! uses, the way GoRela's relative pose hands it the geometry.
//!
//! For a receiver at (x_i, y_i, theta_i) with speed s_i and a sender at (x_j, y_j, theta_j)
//! with speed s_j, (u, v) the sender's position in the receiver's frame, r its distance and
//! (du, dv) the sender's velocity minus the receiver's, in the receiver's frame:
//! `[0.1 du, 0.1 dv, 0.1 dr/dt, dr/dt / (1 + r)]` with `dr/dt = (u du + v dv) / r` the range
//! rate (negative while closing) and the last term the rate of ln(1 + r), the pose encoding's
//! distance feature (order 1 / s: closing at 7 m/s from 20 m is -0.33).

use burn::prelude::*;

/// Length of the encoding.
pub const RELATIVE_MOTION_FEATURES: usize = 4;

/// Speeds (m/s) to network units, as the history encoder's speed input.
const SPEED_SCALE: f64 = 0.1;
/// Same offset as the pose encoding, so an agent seen from itself has finite gradients.
const DISTANCE_EPSILON_SQ: f64 = 1e-6;

/// Encodes the motion of `sender` states seen from `receiver` states. Both are `[..., 4]`
/// (x, y, heading, speed) with the same shape; the result is `[..., RELATIVE_MOTION_FEATURES]`.
pub fn relative_motion<const D: usize>(receiver: Tensor<D>, sender: Tensor<D>) -> Tensor<D> {
    let last = D - 1;
    let channel = |t: &Tensor<D>, c: usize| t.clone().narrow(last, c, 1);
    let heading_i = channel(&receiver, 2);
    let (cos_i, sin_i) = (heading_i.clone().cos(), heading_i.clone().sin());
    let (dx, dy) = (
        channel(&sender, 0) - channel(&receiver, 0),
        channel(&sender, 1) - channel(&receiver, 1),
    );
    let u = dx.clone() * cos_i.clone() + dy.clone() * sin_i.clone();
    let v = dy * cos_i - dx * sin_i;
    let r = (u.clone().powi_scalar(2) + v.clone().powi_scalar(2))
        .add_scalar(DISTANCE_EPSILON_SQ)
        .sqrt();
    let dheading = channel(&sender, 2) - heading_i;
    let speed_j = channel(&sender, 3);
    let du = speed_j.clone() * dheading.clone().cos() - channel(&receiver, 3);
    let dv = speed_j * dheading.sin();
    let range_rate = (u * du.clone() + v * dv.clone()) / r.clone();
    Tensor::cat(
        vec![
            du.mul_scalar(SPEED_SCALE),
            dv.mul_scalar(SPEED_SCALE),
            range_rate.clone().mul_scalar(SPEED_SCALE),
            range_rate / r.add_scalar(1.0),
        ],
        last,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn states(values: &[[f32; 4]], device: &Device) -> Tensor<2> {
        let flat: Vec<f32> = values.iter().flatten().copied().collect();
        Tensor::from_data(TensorData::new(flat, [values.len(), 4]), device)
    }

    fn values(t: Tensor<2>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap()
    }

    #[test]
    fn a_slower_car_ahead_closes_at_the_speed_difference() {
        let device = crate::backend::Backend::reference_device(false);
        // Receiver heading +y at 35 m/s; a car 20 m ahead (also +y) at 28 m/s.
        let pi2 = std::f32::consts::FRAC_PI_2;
        let receiver = states(&[[5.0, -3.0, pi2, 35.0]], &device);
        let sender = states(&[[5.0, 17.0, pi2, 28.0]], &device);
        let f = values(relative_motion(receiver, sender));
        let expect = [-0.7, 0.0, -0.7, -7.0 / 21.0];
        for (k, (a, b)) in f.iter().zip(expect).enumerate() {
            assert!((a - b).abs() < 1e-4, "feature {k}: {a} vs {b}");
        }
    }

    #[test]
    fn a_car_passing_alongside_has_no_range_rate() {
        let device = crate::backend::Backend::reference_device(false);
        // Sender 3.5 m to the left (receiver faces +x), 5 m/s faster: moving, not closing.
        let receiver = states(&[[0.0, 0.0, 0.0, 30.0]], &device);
        let sender = states(&[[0.0, 3.5, 0.0, 35.0]], &device);
        let f = values(relative_motion(receiver, sender));
        assert!((f[0] - 0.5).abs() < 1e-5 && f[1].abs() < 1e-5, "{f:?}");
        assert!(f[2].abs() < 1e-5 && f[3].abs() < 1e-5, "{f:?}");
    }

    #[test]
    fn invariant_to_moving_the_scene() {
        let device = crate::backend::Backend::reference_device(false);
        let a = [[3.0, -4.0, 0.3, 20.0], [100.0, 7.0, -2.0, 5.0]];
        let b = [[10.0, 1.0, 1.1, 31.0], [90.0, 7.5, 3.0, 0.0]];
        let moved = |p: &[[f32; 4]; 2]| {
            let (c, s) = (0.7f32.cos(), 0.7f32.sin());
            p.map(|[x, y, h, v]| [c * x - s * y + 250.0, s * x + c * y - 80.0, h + 0.7, v])
        };
        let base = values(relative_motion(states(&a, &device), states(&b, &device)));
        let other = values(relative_motion(
            states(&moved(&a), &device),
            states(&moved(&b), &device),
        ));
        for (x, y) in base.iter().zip(&other) {
            assert!((x - y).abs() < 2e-4, "{x} vs {y}");
        }
    }
}
