//! Open-ended physics: a library of candidate terms in the state and the commands, from which
//! sim-to-real's discovery stage selects a sparse few (SINDy) when the catalogue's named
//! effects do not explain the recordings. A selection becomes a [`LibraryTerm`], a
//! differentiable simulator term like the catalogue's, whose coefficients are refitted through
//! the rollout and which a dynamics file carries into training.
//!
//! Terms add to one state derivative each: the speed (`dv/dt`) or the heading rate
//! (`dtheta/dt`). They are memoryless functions of speed, acceleration command and steering
//! angle; effects with memory (lags, delays, rate limits) are the catalogue's.

use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::dynamics::{Derivative, DynamicsTerm, TermInput};

/// Which derivative a library term adds to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Equation {
    /// dv/dt (m/s^2).
    Speed,
    /// dtheta/dt (rad/s).
    HeadingRate,
}

impl Equation {
    pub fn symbol(self) -> &'static str {
        match self {
            Equation::Speed => "dv/dt",
            Equation::HeadingRate => "dtheta/dt",
        }
    }
}

/// One candidate term: `v` speed, `u` acceleration command, `phi` steering angle (after any
/// actuation term). `v tan(phi)` itself is left out: it is the nominal yaw rate times 1 / L,
/// which the wheelbase refit already owns.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// 1 (a constant offset).
    One,
    /// v.
    V,
    /// v^2.
    V2,
    /// u.
    U,
    /// min(u, 0): the braking part of the command.
    UBrake,
    /// v u.
    VU,
    /// tan(phi).
    TanPhi,
    /// v^2 tan(phi).
    KappaV,
    /// v^3 tan(phi).
    KappaV2,
    /// max(u - p / v, 0): the command above a limit that tightens with speed, as an engine's
    /// power caps the acceleration at power / (mass x speed); `p` in W/kg (m^2/s^3). The
    /// limit is chosen from the data ([`Feature::limit_grids`]); with coefficient -1 the
    /// acceleration is capped at p / v.
    PowerLimit { specific_power_w_kg: f64 },
    /// max(u - a, 0): the throttle above a fixed cap; with coefficient -1 the acceleration
    /// saturates at `a` (m/s^2), as a powertrain's or a controller's limit does.
    AccelLimit { accel_m_s2: f64 },
    /// min(u + b, 0): braking beyond a fixed deceleration; with coefficient -1 the brakes
    /// saturate at `b` (m/s^2).
    BrakeLimit { decel_m_s2: f64 },
    /// v (tan(phi) - tan(clamp(phi, -a, a))): steering beyond an angle `a` (rad); with
    /// coefficient -1 / L the road wheels stop at `a`, a steering rack's end stop or an
    /// actuator's saturation.
    SteerLimit { angle_rad: f64 },
}

/// Speeds below this (m/s) count as this in `p / v`: at a standstill the limit is far above any
/// command anyway.
const POWER_LIMIT_MIN_SPEED_M_S: f64 = 0.1;

/// What a limit term's coefficient means: -1 cuts everything beyond the limit.
fn limit_meaning(coefficient: f64, beyond: &str) -> String {
    let pct = 100.0 * coefficient.abs();
    if coefficient < 0.0 {
        format!("{beyond} is cut by {pct:.0} % (a saturating actuator)")
    } else {
        format!("{beyond} acts {pct:.0} % more")
    }
}

impl Feature {
    /// The library of each equation.
    pub fn library(equation: Equation) -> &'static [Feature] {
        match equation {
            Equation::Speed => &[
                Feature::One,
                Feature::V,
                Feature::V2,
                Feature::U,
                Feature::UBrake,
                Feature::VU,
            ],
            // v: a steering command biased by b rad turns at v tan(phi + b) / L, which is
            // v tan(phi) / L + (b / L) v to first order.
            Equation::HeadingRate => &[
                Feature::One,
                Feature::V,
                Feature::TanPhi,
                Feature::KappaV,
                Feature::KappaV2,
            ],
        }
    }

    /// The library's terms with a parameter that enters non-linearly (a limit), one grid of
    /// values per kind: discovery picks each kind's best value by a search over its grid.
    /// Grids step by 5 % over what road vehicles span.
    pub fn limit_grids(equation: Equation) -> Vec<Vec<Feature>> {
        let grid = |from: f64, steps: i32| (0..steps).map(move |k| from * 1.05f64.powi(k));
        match equation {
            // Power over mass from a laden lorry's 2 W/kg to a sports car's 400; throttle caps
            // of 0.5 to 5.7 m/s^2; brake caps of 1 to 11.5 m/s^2.
            Equation::Speed => vec![
                grid(2.0, 110)
                    .map(|p| Feature::PowerLimit {
                        specific_power_w_kg: p,
                    })
                    .collect(),
                grid(0.5, 51)
                    .map(|a| Feature::AccelLimit { accel_m_s2: a })
                    .collect(),
                grid(1.0, 51)
                    .map(|b| Feature::BrakeLimit { decel_m_s2: b })
                    .collect(),
            ],
            // Road-wheel stops from 0.01 rad (a motorway's steering stays near there) to 0.6.
            Equation::HeadingRate => vec![
                grid(0.01, 85)
                    .map(|a| Feature::SteerLimit { angle_rad: a })
                    .collect(),
            ],
        }
    }

    /// The equation a limit term belongs to and its parameter's name and value; `None` for
    /// the terms without a parameter.
    pub fn limit(self) -> Option<(Equation, &'static str, f64)> {
        match self {
            Feature::PowerLimit {
                specific_power_w_kg,
            } => Some((Equation::Speed, "specific_power_w_kg", specific_power_w_kg)),
            Feature::AccelLimit { accel_m_s2 } => Some((Equation::Speed, "accel_m_s2", accel_m_s2)),
            Feature::BrakeLimit { decel_m_s2 } => Some((Equation::Speed, "decel_m_s2", decel_m_s2)),
            Feature::SteerLimit { angle_rad } => {
                Some((Equation::HeadingRate, "angle_rad", angle_rad))
            }
            _ => None,
        }
    }

    /// The same kind of limit at `value`; a term without a limit is returned as it is.
    pub fn with_limit(self, value: f64) -> Feature {
        match self {
            Feature::PowerLimit { .. } => Feature::PowerLimit {
                specific_power_w_kg: value,
            },
            Feature::AccelLimit { .. } => Feature::AccelLimit { accel_m_s2: value },
            Feature::BrakeLimit { .. } => Feature::BrakeLimit { decel_m_s2: value },
            Feature::SteerLimit { .. } => Feature::SteerLimit { angle_rad: value },
            other => other,
        }
    }

    /// Whether `self` is a term of `equation`'s library (a limit at any positive, finite
    /// value).
    pub fn is_in_library(self, equation: Equation) -> bool {
        match self.limit() {
            Some((own, _, value)) => own == equation && value.is_finite() && value > 0.0,
            None => Feature::library(equation).contains(&self),
        }
    }

    /// Whether the feature involves a command (so it cannot be identified when the commands
    /// were inferred from the motion itself).
    pub fn involves_commands(self) -> bool {
        !matches!(self, Feature::One | Feature::V | Feature::V2)
    }

    /// The feature's kind, as dynamics files spell it (a power limit without its value).
    pub fn name(self) -> &'static str {
        match self {
            Feature::One => "one",
            Feature::V => "v",
            Feature::V2 => "v2",
            Feature::U => "u",
            Feature::UBrake => "u_brake",
            Feature::VU => "v_u",
            Feature::TanPhi => "tan_phi",
            Feature::KappaV => "kappa_v",
            Feature::KappaV2 => "kappa_v2",
            Feature::PowerLimit { .. } => "power_limit",
            Feature::AccelLimit { .. } => "accel_limit",
            Feature::BrakeLimit { .. } => "brake_limit",
            Feature::SteerLimit { .. } => "steer_limit",
        }
    }

    pub fn symbol(self) -> String {
        match self {
            Feature::One => "1".into(),
            Feature::V => "v".into(),
            Feature::V2 => "v^2".into(),
            Feature::U => "u".into(),
            Feature::UBrake => "min(u, 0)".into(),
            Feature::VU => "v u".into(),
            Feature::TanPhi => "tan(phi)".into(),
            Feature::KappaV => "v^2 tan(phi)".into(),
            Feature::KappaV2 => "v^3 tan(phi)".into(),
            Feature::PowerLimit {
                specific_power_w_kg,
            } => format!("max(u - {specific_power_w_kg:.1} / v, 0)"),
            Feature::AccelLimit { accel_m_s2 } => format!("max(u - {accel_m_s2:.2}, 0)"),
            Feature::BrakeLimit { decel_m_s2 } => format!("min(u + {decel_m_s2:.2}, 0)"),
            Feature::SteerLimit { angle_rad } => {
                format!("v (tan(phi) - tan(clamp(phi, +-{angle_rad:.3})))")
            }
        }
    }

    /// What a term in this feature means, for people (sign-aware).
    pub fn meaning(self, equation: Equation, coefficient: f64) -> String {
        let more = if coefficient > 0.0 { "more" } else { "less" };
        let pct = 100.0 * coefficient.abs();
        match (equation, self) {
            (Equation::Speed, Feature::One) => {
                if coefficient < 0.0 {
                    "a constant deceleration (rolling resistance, a slope)".into()
                } else {
                    "a constant acceleration (a downhill slope, a biased accelerometer)".into()
                }
            }
            (Equation::Speed, Feature::V) => "a resistance proportional to speed".into(),
            (Equation::Speed, Feature::V2) => {
                "a resistance growing with speed squared (aerodynamic drag)".into()
            }
            (Equation::Speed, Feature::U) => {
                format!("the vehicle accelerates {pct:.0} % {more} than commanded")
            }
            (Equation::Speed, Feature::UBrake) => {
                format!("braking acts {pct:.0} % {more} strongly than commanded; throttle does not")
            }
            (Equation::Speed, Feature::VU) => "the command's effect changes with speed".into(),
            (Equation::HeadingRate, Feature::One) => {
                "a constant yaw drift (heading sensor bias)".into()
            }
            (Equation::HeadingRate, Feature::TanPhi) => {
                "yaw rate from steering independent of speed".into()
            }
            (Equation::HeadingRate, Feature::KappaV) => {
                if coefficient < 0.0 {
                    "steering becomes less effective in proportion to speed (a speed-dependent steering ratio)".into()
                } else {
                    "steering becomes more effective in proportion to speed".into()
                }
            }
            (Equation::HeadingRate, Feature::KappaV2) => {
                if coefficient < 0.0 {
                    "yaw rate falls with speed squared (understeer)".into()
                } else {
                    "yaw rate grows with speed squared (oversteer)".into()
                }
            }
            (
                Equation::Speed,
                Feature::PowerLimit {
                    specific_power_w_kg,
                },
            ) => {
                if coefficient < 0.0 {
                    format!(
                        "acceleration above {specific_power_w_kg:.1} / v m/s^2 is cut by {pct:.0} % \
                         (an engine's power limit, {specific_power_w_kg:.1} W/kg)"
                    )
                } else {
                    format!(
                        "acceleration above {specific_power_w_kg:.1} / v m/s^2 acts {pct:.0} % more"
                    )
                }
            }
            (Equation::Speed, Feature::AccelLimit { accel_m_s2 }) => limit_meaning(
                coefficient,
                &format!("throttle above {accel_m_s2:.2} m/s^2"),
            ),
            (Equation::Speed, Feature::BrakeLimit { decel_m_s2 }) => limit_meaning(
                coefficient,
                &format!("braking beyond {decel_m_s2:.2} m/s^2"),
            ),
            (Equation::HeadingRate, Feature::V) => {
                "a yaw rate that grows with speed at zero steering (a steering-command bias: the \
                 wheels point off centre)"
                    .into()
            }
            (Equation::HeadingRate, Feature::SteerLimit { angle_rad }) => {
                if coefficient < 0.0 {
                    format!(
                        "steering beyond {angle_rad:.3} rad turns the vehicle less than commanded \
                         (a saturated steering actuator)"
                    )
                } else {
                    format!(
                        "steering beyond {angle_rad:.3} rad turns the vehicle more than commanded"
                    )
                }
            }
            (_, f) => format!("a term in {}", f.symbol()),
        }
    }

    /// The feature's value on the host.
    pub fn value(self, v: f64, u: f64, phi: f64) -> f64 {
        let tan = phi.tan();
        match self {
            Feature::One => 1.0,
            Feature::V => v,
            Feature::V2 => v * v,
            Feature::U => u,
            Feature::UBrake => u.min(0.0),
            Feature::VU => v * u,
            Feature::TanPhi => tan,
            Feature::KappaV => v * v * tan,
            Feature::KappaV2 => v * v * v * tan,
            Feature::PowerLimit {
                specific_power_w_kg,
            } => (u - specific_power_w_kg / v.max(POWER_LIMIT_MIN_SPEED_M_S)).max(0.0),
            Feature::AccelLimit { accel_m_s2 } => (u - accel_m_s2).max(0.0),
            Feature::BrakeLimit { decel_m_s2 } => (u + decel_m_s2).min(0.0),
            Feature::SteerLimit { angle_rad } => v * (tan - phi.clamp(-angle_rad, angle_rad).tan()),
        }
    }

    /// The feature as tensor ops (differentiable in the state and the commands).
    pub fn tensor(self, input: &TermInput) -> Tensor<2> {
        let v = input.state.speed.clone();
        let u = input.controls.accel.clone();
        let tan = || input.controls.steer.clone().tan();
        match self {
            Feature::One => v.ones_like(),
            Feature::V => v,
            Feature::V2 => v.clone() * v,
            Feature::U => u,
            Feature::UBrake => u.clamp_max(0.0),
            Feature::VU => v * u,
            Feature::TanPhi => tan(),
            Feature::KappaV => v.clone() * v * tan(),
            Feature::KappaV2 => v.clone() * v.clone() * v * tan(),
            Feature::PowerLimit {
                specific_power_w_kg,
            } => {
                let limit = v
                    .clamp_min(POWER_LIMIT_MIN_SPEED_M_S)
                    .recip()
                    .mul_scalar(specific_power_w_kg);
                (u - limit).clamp_min(0.0)
            }
            Feature::AccelLimit { accel_m_s2 } => u.sub_scalar(accel_m_s2).clamp_min(0.0),
            Feature::BrakeLimit { decel_m_s2 } => u.add_scalar(decel_m_s2).clamp_max(0.0),
            Feature::SteerLimit { angle_rad } => {
                let phi = input.controls.steer.clone();
                v * (tan() - phi.clamp(-angle_rad, angle_rad).tan())
            }
        }
    }
}

/// A selection of library features with their coefficients (`[1, 1]` tensors, possibly
/// being fitted).
#[derive(Debug)]
pub struct LibraryTerm {
    pub terms: Vec<(Equation, Feature, Tensor<2>)>,
}

impl DynamicsTerm for LibraryTerm {
    fn name(&self) -> &str {
        "discovered"
    }

    fn derivative(&self, mut d: Derivative, input: &TermInput) -> Derivative {
        for (equation, feature, coefficient) in &self.terms {
            let added = feature.tensor(input) * coefficient.clone();
            match equation {
                Equation::Speed => d.speed = d.speed + added,
                Equation::HeadingRate => d.heading = d.heading + added,
            }
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{Controls, Dynamics, VehicleState};
    use burn::tensor::TensorData;

    fn scalar(v: f64) -> Tensor<2> {
        let device = crate::backend::Backend::reference_device(false);
        Tensor::from_data(TensorData::new(vec![v as f32], [1, 1]), &device)
    }

    /// One step of `dynamics` (limits off) from 12 m/s under (`u` m/s^2, 0.04 rad).
    fn step(mut dynamics: Dynamics, u: f64) -> VehicleState {
        dynamics.limits = None;
        dynamics.step(
            &VehicleState {
                x: scalar(0.0),
                y: scalar(0.0),
                heading: scalar(0.0),
                speed: scalar(12.0),
                aux: Vec::new(),
            },
            &Controls {
                accel: scalar(u),
                steer: scalar(0.04),
            },
            &scalar(2.8),
        )
    }

    #[test]
    fn tensor_and_host_features_agree_and_add_to_their_equation() {
        // A limit of 20 W/kg at 12 m/s is 1.67 m/s^2: below the throttle tried here.
        let limit = Feature::PowerLimit {
            specific_power_w_kg: 20.0,
        };
        assert!(limit.value(12.0, 2.0, 0.04) > 0.3);
        for (equation, (v, u, phi)) in [
            (Equation::Speed, (12.0, -2.0, 0.04)),
            (Equation::Speed, (12.0, 2.0, 0.04)),
            (Equation::HeadingRate, (12.0, -2.0, 0.04)),
        ] {
            let plain = step(Dynamics::bicycle(0.5), u);
            let mut features = Feature::library(equation).to_vec();
            // Limits that the tried (u, phi) exceed.
            let limits = [
                limit,
                Feature::AccelLimit { accel_m_s2: 1.0 },
                Feature::BrakeLimit { decel_m_s2: 1.0 },
                Feature::SteerLimit { angle_rad: 0.02 },
            ];
            features.extend(limits.into_iter().filter(|f| f.is_in_library(equation)));
            for feature in features {
                let next = step(
                    Dynamics::bicycle(0.5).with_term(Box::new(LibraryTerm {
                        terms: vec![(equation, feature, scalar(0.1))],
                    })),
                    u,
                );
                let host =
                    |t: &Tensor<2>| t.to_data().convert::<f64>().try_to_vec::<f64>().unwrap()[0];
                let expected = 0.1 * feature.value(v, u, phi) * 0.5;
                let (dv, dh) = (
                    host(&next.speed) - host(&plain.speed),
                    host(&next.heading) - host(&plain.heading),
                );
                let (got, other) = match equation {
                    Equation::Speed => (dv, dh),
                    Equation::HeadingRate => (dh, dv),
                };
                assert!(
                    (got - expected).abs() < 1e-4 * expected.abs().max(1.0),
                    "{feature:?}: {got} vs {expected}"
                );
                assert!(
                    other.abs() < 1e-9,
                    "{feature:?} leaked into the other equation"
                );
            }
        }
    }
}
