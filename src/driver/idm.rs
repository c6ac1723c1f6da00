//! The Intelligent Driver Model (Treiber, Hennecke, Helbing 2000): car following with a
//! desired speed, a safe time gap and comfortable acceleration and braking.

/// IDM parameters. Defaults are the motorway values of Treiber & Kesting, "Traffic Flow
/// Dynamics" (2013), table 11.2, with the braking bound of the simulator's action limits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IdmParams {
    /// Safe time headway T (s).
    pub time_gap_s: f64,
    /// Jam distance s0 (m).
    pub min_gap_m: f64,
    /// Maximum acceleration a (m/s^2).
    pub accel: f64,
    /// Comfortable deceleration b (m/s^2).
    pub comfort_decel: f64,
    /// Hardest braking the driver uses (m/s^2, positive).
    pub max_decel: f64,
    /// Acceleration exponent delta.
    pub exponent: f64,
}

impl Default for IdmParams {
    fn default() -> Self {
        Self {
            time_gap_s: 1.0,
            min_gap_m: 2.0,
            accel: 1.0,
            comfort_decel: 1.5,
            max_decel: 8.0,
            exponent: 4.0,
        }
    }
}

/// IDM acceleration (m/s^2) at speed `v` with desired speed `v0`, given the bumper-to-bumper
/// `gap` to the leader (m) and the approach rate `v - v_leader` (m/s); `None` = free road.
/// Bounded below by `-max_decel`.
pub fn idm_accel(p: &IdmParams, v: f64, v0: f64, leader: Option<(f64, f64)>) -> f64 {
    let v = v.max(0.0);
    let free = 1.0 - (v / v0.max(0.1)).powf(p.exponent);
    let interaction = match leader {
        Some((gap, approach)) => {
            let desired = p.min_gap_m
                + (v * p.time_gap_s + v * approach / (2.0 * (p.accel * p.comfort_decel).sqrt()))
                    .max(0.0);
            (desired / gap.max(0.1)).powi(2)
        }
        None => 0.0,
    };
    (p.accel * (free - interaction)).max(-p.max_decel)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_road_accelerates_below_and_brakes_above_the_desired_speed() {
        let p = IdmParams::default();
        assert!((idm_accel(&p, 0.0, 30.0, None) - p.accel).abs() < 1e-12);
        assert!(idm_accel(&p, 30.0, 30.0, None).abs() < 1e-12);
        assert!(idm_accel(&p, 35.0, 30.0, None) < 0.0);
    }

    #[test]
    fn steady_following_at_the_equilibrium_gap() {
        // Equilibrium: free term equals interaction term.
        let p = IdmParams::default();
        let (v, v0) = (20.0, 30.0);
        let s_star = p.min_gap_m + v * p.time_gap_s;
        let gap = s_star / (1.0 - (v / v0).powf(p.exponent)).sqrt();
        assert!(idm_accel(&p, v, v0, Some((gap, 0.0))).abs() < 1e-9);
        // Closer than equilibrium brakes, farther accelerates.
        assert!(idm_accel(&p, v, v0, Some((0.8 * gap, 0.0))) < 0.0);
        assert!(idm_accel(&p, v, v0, Some((1.2 * gap, 0.0))) > 0.0);
    }

    #[test]
    fn closing_fast_on_a_near_leader_brakes_at_the_bound() {
        let p = IdmParams::default();
        assert_eq!(idm_accel(&p, 30.0, 30.0, Some((5.0, 20.0))), -p.max_decel);
    }
}
