//! Viewpoint-invariant encoding of one pose seen from another (GoRela, as the paper's
//! "Input Parameterization"): everything is expressed in the receiver's frame, so rotating and
//! translating the whole scene changes nothing the network sees.
//!
//! For a receiver at (x_i, y_i, theta_i) and a sender at (x_j, y_j, theta_j), with (u, v) the
//! sender's position in the receiver's frame and r its distance:
//! `[u / r, v / r, sin dtheta, cos dtheta, ln(1 + r), sin(2 pi r / w_k), cos(2 pi r / w_k)...]`
//! for the configured wavelengths w_k. (u/r, v/r) is the sine/cosine of the bearing.

use std::f64::consts::{FRAC_PI_2, TAU};

use burn::prelude::*;
use burn::tensor::TensorData;

/// Small offset under the square root so the encoding of a pose seen from itself has a finite
/// gradient (r is then 1e-3 m, the bearing terms 0).
const DISTANCE_EPSILON_SQ: f64 = 1e-6;

/// Length of the encoding for `wavelengths` distance frequencies.
pub fn relative_pose_features(wavelengths: usize) -> usize {
    5 + 2 * wavelengths
}

/// Encodes `sender` poses in the frames of `receiver` poses. Both are `[..., 3]` (x, y,
/// heading) with the same shape; the result is `[..., relative_pose_features(k)]`.
pub fn relative_pose<const D: usize>(
    receiver: Tensor<D>,
    sender: Tensor<D>,
    wavelengths: &[f64],
) -> Tensor<D> {
    let last = D - 1;
    let channel = |t: &Tensor<D>, c: usize| t.clone().narrow(last, c, 1);
    let (xi, yi, hi) = (
        channel(&receiver, 0),
        channel(&receiver, 1),
        channel(&receiver, 2),
    );
    let (dx, dy) = (channel(&sender, 0) - xi, channel(&sender, 1) - yi);
    let dheading = channel(&sender, 2) - hi.clone();
    let (cos_i, sin_i) = (hi.clone().cos(), hi.sin());
    let u = dx.clone() * cos_i.clone() + dy.clone() * sin_i.clone();
    let v = dy * cos_i - dx * sin_i;
    let r = (u.clone().powi_scalar(2) + v.clone().powi_scalar(2))
        .add_scalar(DISTANCE_EPSILON_SQ)
        .sqrt();
    let bearing = Tensor::cat(vec![u, v], last) / r.clone();
    // Every sine and cosine in one op: cos x = sin(x + pi/2), so the angles
    // [dheading, dheading, 2 pi r / w_1, 2 pi r / w_1, ...] plus [0, pi/2, 0, pi/2, ...] go
    // through one `sin` (a handful of ops instead of one pair per wavelength; the encoding is
    // computed for every agent pair at every step).
    let device = r.device();
    let phase_scale: Vec<f32> = wavelengths
        .iter()
        .flat_map(|w| [(TAU / w) as f32; 2])
        .collect();
    let shift: Vec<f32> = (0..=wavelengths.len())
        .flat_map(|_| [0.0, FRAC_PI_2 as f32])
        .collect();
    // A row broadcast along every axis but the last.
    let row = |values: &[f32]| {
        let mut shape = [1; D];
        shape[last] = values.len();
        Tensor::<1>::from_data(TensorData::new(values.to_vec(), [values.len()]), &device)
            .reshape(shape)
    };
    let width = |w: usize| {
        let mut dims = r.dims();
        dims[last] = w;
        dims
    };
    let mut angles = vec![dheading.expand(width(2))];
    if !wavelengths.is_empty() {
        angles.push(r.clone().expand(width(phase_scale.len())) * row(&phase_scale));
    }
    let trig = (Tensor::cat(angles, last) + row(&shift)).sin();
    let mut parts = vec![bearing, trig.clone().narrow(last, 0, 2), r.log1p()];
    if !wavelengths.is_empty() {
        parts.push(trig.narrow(last, 2, phase_scale.len()));
    }
    Tensor::cat(parts, last)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn poses(values: &[[f32; 3]], device: &Device) -> Tensor<2> {
        let flat: Vec<f32> = values.iter().flatten().copied().collect();
        Tensor::from_data(TensorData::new(flat, [values.len(), 3]), device)
    }

    fn values(t: Tensor<2>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap()
    }

    #[test]
    fn encodes_bearing_heading_and_distance_in_the_receivers_frame() {
        let device = crate::backend::Backend::reference_device(false);
        // Receiver facing +y; sender 10 m to its left (-x in the world), facing -x.
        let pi2 = std::f32::consts::FRAC_PI_2;
        let receiver = poses(&[[1.0, 2.0, pi2]], &device);
        let sender = poses(&[[-9.0, 2.0, 2.0 * pi2]], &device);
        let f = values(relative_pose(receiver, sender, &[10.0]));
        assert_eq!(f.len(), relative_pose_features(1));
        let expect = [0.0, 1.0, 1.0, 0.0, 11f32.ln(), 0.0, 1.0];
        for (k, (a, b)) in f.iter().zip(expect).enumerate() {
            assert!((a - b).abs() < 1e-4, "feature {k}: {a} vs {b}");
        }
    }

    #[test]
    fn invariant_to_moving_both_poses_together() {
        let device = crate::backend::Backend::reference_device(false);
        let a = [[3.0, -4.0, 0.3], [100.0, 7.0, -2.0]];
        let b = [[10.0, 1.0, 1.1], [90.0, 7.5, 3.0]];
        let moved = |p: &[[f32; 3]; 2]| {
            let (c, s) = (0.7f32.cos(), 0.7f32.sin());
            p.map(|[x, y, h]| [c * x - s * y + 250.0, s * x + c * y - 80.0, h + 0.7])
        };
        let base = values(relative_pose(
            poses(&a, &device),
            poses(&b, &device),
            &[4.0, 64.0],
        ));
        let other = values(relative_pose(
            poses(&moved(&a), &device),
            poses(&moved(&b), &device),
            &[4.0, 64.0],
        ));
        for (x, y) in base.iter().zip(&other) {
            assert!((x - y).abs() < 2e-4, "{x} vs {y}");
        }
    }
}
