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
    /// limit is chosen from the data ([`Feature::power_limit_grid`]); with coefficient -1 the
    /// acceleration is capped at p / v.
    PowerLimit { specific_power_w_kg: f64 },
}

/// Speeds below this (m/s) count as this in `p / v`: at a standstill the limit is far above any
/// command anyway.
const POWER_LIMIT_MIN_SPEED_M_S: f64 = 0.1;

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
            Equation::HeadingRate => &[
                Feature::One,
                Feature::TanPhi,
                Feature::KappaV,
                Feature::KappaV2,
            ],
        }
    }

    /// The limits [`Feature::PowerLimit`] is tried at, W/kg: 2 to 400 in steps of 5 %, from
    /// a laden lorry's to a sports car's power over mass.
    pub fn power_limit_grid() -> impl Iterator<Item = Feature> {
        (0..110).map(|k| Feature::PowerLimit {
            specific_power_w_kg: 2.0 * 1.05f64.powi(k),
        })
    }

    /// Whether `self` is a term of `equation`'s library (a power limit at any positive,
    /// finite specific power).
    pub fn is_in_library(self, equation: Equation) -> bool {
        match self {
            Feature::PowerLimit {
                specific_power_w_kg,
            } => {
                equation == Equation::Speed
                    && specific_power_w_kg.is_finite()
                    && specific_power_w_kg > 0.0
            }
            f => Feature::library(equation).contains(&f),
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
            if equation == Equation::Speed {
                features.push(limit);
            }
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
