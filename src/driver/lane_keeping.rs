//! Lane keeping by pure pursuit (Coulter 1992): steer the rear axle along the circular arc
//! through a look-ahead point on the path, the standard geometric tracker for the kinematic
//! bicycle the simulator integrates.

use crate::geometry::wrap_angle;
use crate::sim::{ActionLimits, soft_clamp_inverse};

/// A physical control (m/s^2, rad at the front wheel) before the simulator's soft limits.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlCommand {
    pub accel: f64,
    pub steer: f64,
}

impl ControlCommand {
    /// The raw command that the simulator's smooth limits map onto this control (values at
    /// or past a limit saturate there).
    pub fn raw(&self, limits: &ActionLimits) -> (f64, f64) {
        (
            soft_clamp_inverse(self.accel, limits.accel_min, limits.accel_max),
            soft_clamp_inverse(self.steer, -limits.steer_max, limits.steer_max),
        )
    }
}

/// Front-wheel angle that takes a bicycle with its rear axle at `rear`, heading `heading`,
/// through `target`: phi = atan(2 L sin(alpha) / l_d).
pub fn pure_pursuit_steer(rear: [f64; 2], heading: f64, wheelbase: f64, target: [f64; 2]) -> f64 {
    let d = [target[0] - rear[0], target[1] - rear[1]];
    let distance = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1.0);
    let alpha = wrap_angle(d[1].atan2(d[0]) - heading);
    (2.0 * wheelbase * alpha.sin() / distance).atan()
}

/// Look-ahead distance (m) at speed `v`: 1.5 s of travel, at least 12 m, so the tracker stays
/// stable at the simulator's 0.5 s step (a look-ahead shorter than about two steps of travel
/// oscillates).
pub fn look_ahead(v: f64) -> f64 {
    (1.5 * v).max(12.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_ahead_needs_no_steering_and_left_targets_steer_left() {
        assert!(pure_pursuit_steer([0.0, 0.0], 0.0, 2.8, [20.0, 0.0]).abs() < 1e-12);
        assert!(pure_pursuit_steer([0.0, 0.0], 0.0, 2.8, [20.0, 2.0]) > 0.0);
        assert!(pure_pursuit_steer([0.0, 0.0], 0.0, 2.8, [20.0, -2.0]) < 0.0);
    }

    #[test]
    fn steering_follows_the_arc_through_the_target() {
        // A target on a circle of radius R through the rear axle, tangent to the heading:
        // the bicycle's curvature tan(phi) / L must be 1 / R.
        let (radius, wheelbase) = (50.0_f64, 2.8);
        let angle = 0.4_f64;
        let target = [radius * angle.sin(), radius * (1.0 - angle.cos())];
        let phi = pure_pursuit_steer([0.0, 0.0], 0.0, wheelbase, target);
        assert!((phi.tan() / wheelbase - 1.0 / radius).abs() < 1e-9);
    }

    #[test]
    fn raw_commands_reproduce_the_control_through_the_limits() {
        let limits = ActionLimits::default();
        let c = ControlCommand {
            accel: -3.0,
            steer: 0.1,
        };
        let (a, s) = c.raw(&limits);
        let back = |v: f64, lo: f64, hi: f64| {
            if v >= 0.0 {
                hi * (v / hi).tanh()
            } else {
                lo * (v / lo).tanh()
            }
        };
        assert!((back(a, limits.accel_min, limits.accel_max) + 3.0).abs() < 1e-9);
        assert!((back(s, -limits.steer_max, limits.steer_max) - 0.1).abs() < 1e-9);
    }
}
