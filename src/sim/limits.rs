//! Physical limits on the controls, applied smoothly so gradients never vanish: a command c
//! becomes hi * tanh(c / hi) above zero and lo * tanh(c / lo) below, which is the identity near
//! zero (slope 1 on both sides, so continuous derivative) and saturates at the limits.

use burn::prelude::*;

use super::state::Controls;

/// Control ranges. Defaults: braking to -8 m/s^2 (emergency braking on dry asphalt),
/// accelerating to 4 m/s^2, steering +-0.6 rad at the front wheel.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ActionLimits {
    pub accel_min: f64,
    pub accel_max: f64,
    pub steer_max: f64,
}

impl Default for ActionLimits {
    fn default() -> Self {
        Self {
            accel_min: -8.0,
            accel_max: 4.0,
            steer_max: 0.6,
        }
    }
}

impl ActionLimits {
    /// Physical bounds: braking below 0 down to at most 20 m/s^2, acceleration above 0 up to
    /// 20 m/s^2, a road-wheel angle above 0 up to 1 rad (57 degrees: larger is a value in
    /// degrees). The message names the field.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !(self.accel_min >= -20.0 && self.accel_min < 0.0) {
            return Err(format!(
                "accel_min {}: expected braking in [-20, 0) m/s^2",
                self.accel_min
            ));
        }
        if !(self.accel_max > 0.0 && self.accel_max <= 20.0) {
            return Err(format!(
                "accel_max {}: expected acceleration in (0, 20] m/s^2",
                self.accel_max
            ));
        }
        if !(self.steer_max > 0.0 && self.steer_max <= 1.0) {
            return Err(format!(
                "steer_max {}: expected a road-wheel angle in (0, 1] rad (degrees?)",
                self.steer_max
            ));
        }
        Ok(())
    }
}

/// `hi * tanh(c / hi)` for c >= 0, `lo * tanh(c / lo)` for c < 0 (lo < 0 < hi).
pub fn soft_clamp(c: Tensor<2>, lo: f64, hi: f64) -> Tensor<2> {
    let upper = c.clone().div_scalar(hi).tanh().mul_scalar(hi);
    let lower = c.clone().div_scalar(-lo).tanh().mul_scalar(-lo);
    let negative = c.lower_elem(0.0);
    upper.mask_where(negative, lower)
}

/// Exact inverse of [`soft_clamp`] for values strictly inside (lo, hi); values at or beyond a
/// limit map to the command that reaches 99.99 % of it.
pub fn soft_clamp_inverse(y: f64, lo: f64, hi: f64) -> f64 {
    let bound = if y >= 0.0 { hi } else { -lo };
    let r = (y / bound).clamp(-0.9999, 0.9999);
    bound * r.atanh()
}

impl ActionLimits {
    /// Bounds so far out that the smooth clamp is the identity for any physical control
    /// (relative change below 1e-9), for code that needs limits where a model has none.
    pub fn unbounded() -> Self {
        Self {
            accel_min: -1e6,
            accel_max: 1e6,
            steer_max: 1e6,
        }
    }

    pub fn apply(&self, c: &Controls) -> Controls {
        Controls {
            accel: soft_clamp(c.accel.clone(), self.accel_min, self.accel_max),
            steer: soft_clamp(c.steer.clone(), -self.steer_max, self.steer_max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn soft_clamp_is_identity_near_zero_saturates_and_inverts() {
        let device = crate::backend::Backend::reference_device(false);
        let raw = vec![-100.0f32, -1.0, -0.01, 0.0, 0.01, 1.0, 100.0];
        let t = Tensor::<2>::from_data(burn::tensor::TensorData::new(raw.clone(), [1, 7]), &device);
        let out = soft_clamp(t, -8.0, 4.0)
            .to_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .expect("f64");
        assert!((out[0] + 8.0).abs() < 1e-4 && (out[6] - 4.0).abs() < 1e-4);
        assert!((out[2] + 0.01).abs() < 1e-5 && (out[4] - 0.01).abs() < 1e-5);
        assert_eq!(out[3], 0.0);
        for (&r, &y) in raw.iter().zip(&out).skip(1).take(5) {
            assert!((soft_clamp_inverse(y, -8.0, 4.0) - r as f64).abs() < 1e-4);
        }
    }
}
