//! Batched vehicle state and controls as burn tensors, `[batch, agents]` each.
//!
//! The bicycle model's state is at the rear axle (paper appendix); scenes and collision boxes
//! use the box centre. Rule: the axles sit symmetrically about the box centre, the wheelbase
//! being `WHEELBASE_RATIO` of the box length, so rear axle = centre - wheelbase / 2 along the
//! heading.

use burn::prelude::*;

/// Wheelbase as a share of the box length (passenger cars: 2.8 m of 4.7 m).
pub const WHEELBASE_RATIO: f64 = 0.6;

/// Wheelbase (m) of a box of `length` (m), per the rule above.
pub fn wheelbase_of(length: f64) -> f64 {
    WHEELBASE_RATIO * length
}

/// Kinematic state of every agent. `aux` holds extra channels that dynamics terms keep (e.g.
/// the lagged acceleration of an actuator-lag term), in the order the terms were added.
#[derive(Debug, Clone)]
pub struct VehicleState {
    /// Rear-axle position (m).
    pub x: Tensor<2>,
    pub y: Tensor<2>,
    /// Yaw (rad).
    pub heading: Tensor<2>,
    /// Longitudinal speed (m/s).
    pub speed: Tensor<2>,
    pub aux: Vec<Tensor<2>>,
}

impl VehicleState {
    /// From box-centre poses: moves the point back by half the wheelbase.
    pub fn from_centre(
        cx: Tensor<2>,
        cy: Tensor<2>,
        heading: Tensor<2>,
        speed: Tensor<2>,
        wheelbase: &Tensor<2>,
    ) -> Self {
        let half = wheelbase.clone().mul_scalar(0.5);
        Self {
            x: cx - heading.clone().cos() * half.clone(),
            y: cy - heading.clone().sin() * half,
            heading,
            speed,
            aux: Vec::new(),
        }
    }

    /// Box-centre position `(cx, cy)`.
    pub fn centre(&self, wheelbase: &Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let half = wheelbase.clone().mul_scalar(0.5);
        (
            self.x.clone() + self.heading.clone().cos() * half.clone(),
            self.y.clone() + self.heading.clone().sin() * half,
        )
    }

    /// Keeps `self` where `keep` is true and takes `other` elsewhere (aux channels too).
    pub fn select(self, keep: &Tensor<2, Bool>, other: VehicleState) -> Self {
        // mask_where takes the *other* value where the mask is true.
        let take = keep.clone().bool_not();
        let pick = |a: Tensor<2>, b: Tensor<2>| a.mask_where(take.clone(), b);
        Self {
            x: pick(self.x, other.x),
            y: pick(self.y, other.y),
            heading: pick(self.heading, other.heading),
            speed: pick(self.speed, other.speed),
            aux: self
                .aux
                .into_iter()
                .zip(other.aux)
                .map(|(a, b)| pick(a, b))
                .collect(),
        }
    }

    pub fn detach(self) -> Self {
        Self {
            x: self.x.detach(),
            y: self.y.detach(),
            heading: self.heading.detach(),
            speed: self.speed.detach(),
            aux: self.aux.into_iter().map(Tensor::detach).collect(),
        }
    }
}

/// The bicycle model's inputs: longitudinal acceleration u (m/s^2) and front-wheel steering
/// angle phi (rad).
#[derive(Debug, Clone)]
pub struct Controls {
    pub accel: Tensor<2>,
    pub steer: Tensor<2>,
}

impl Controls {
    /// `[B, N, 2]` (accel, steer) → controls.
    pub fn from_stacked(actions: Tensor<3>) -> Self {
        let [b, n, _] = actions.dims();
        Self {
            accel: actions.clone().narrow(2, 0, 1).reshape([b, n]),
            steer: actions.narrow(2, 1, 1).reshape([b, n]),
        }
    }

    pub fn stacked(&self) -> Tensor<3> {
        Tensor::stack(vec![self.accel.clone(), self.steer.clone()], 2)
    }
}
