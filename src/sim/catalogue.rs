//! The physics catalogue by name: each [`Effect`] names a term of `sim::terms`, its parameters
//! with units and plausible ranges, and builds the term from parameter tensors. Sim-to-real
//! tries each as an explanation; [`DynamicsFile`] carries what it identified into training.
//! Fitting works on unbounded raw values mapped into the range by a sigmoid, so gradient
//! descent can never leave physics (a negative lag, a wheelbase of zero).

use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::library::{Equation, Feature, LibraryTerm};
use super::terms::{
    Channel, DeadTime, Drag, FirstOrderLag, Sideslip, SteerRateLimit, Understeer, parameter,
};
use super::{Dynamics, DynamicsTerm};
use crate::error::{Error, Result};

/// Longest input delay `dead_time` can represent (s).
pub const MAX_DEAD_TIME_S: f64 = 1.0;

/// One physics term of the catalogue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    AccelLag,
    SteerLag,
    DeadTime,
    Drag,
    Understeer,
    SteerRateLimit,
    Sideslip,
}

/// A parameter's name, unit, range and starting value for fitting.
#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    pub name: &'static str,
    pub unit: &'static str,
    pub min: f64,
    pub max: f64,
    pub start: f64,
}

const fn spec(name: &'static str, unit: &'static str, min: f64, max: f64, start: f64) -> ParamSpec {
    ParamSpec {
        name,
        unit,
        min,
        max,
        start,
    }
}

impl Effect {
    pub const ALL: [Effect; 7] = [
        Effect::AccelLag,
        Effect::SteerLag,
        Effect::DeadTime,
        Effect::Drag,
        Effect::Understeer,
        Effect::SteerRateLimit,
        Effect::Sideslip,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Effect::AccelLag => "accel_lag",
            Effect::SteerLag => "steer_lag",
            Effect::DeadTime => "dead_time",
            Effect::Drag => "drag",
            Effect::Understeer => "understeer",
            Effect::SteerRateLimit => "steer_rate_limit",
            Effect::Sideslip => "sideslip",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// What the effect is, in words, for the report.
    pub fn description(self) -> &'static str {
        match self {
            Effect::AccelLag => "first-order lag between commanded and applied acceleration",
            Effect::SteerLag => "first-order lag between commanded and actual steering angle",
            Effect::DeadTime => "pure delay on both commands",
            Effect::Drag => "aerodynamic and rolling resistance (dv/dt -= c_d v^2 + c_r)",
            Effect::Understeer => "understeer: yaw rate falls below v tan(phi) / L at speed",
            Effect::SteerRateLimit => "limited steering rate",
            Effect::Sideslip => {
                "recorded point is the centre of gravity ahead of the rear axle (sideslip)"
            }
        }
    }

    /// Ranges: the physically plausible span for road vehicles, wide enough that a fit
    /// never sits on a bound for a real effect.
    pub fn params(self) -> &'static [ParamSpec] {
        const ACCEL_LAG: [ParamSpec; 1] = [spec("tau_s", "s", 0.01, 2.0, 0.2)];
        const STEER_LAG: [ParamSpec; 1] = [spec("tau_s", "s", 0.01, 2.0, 0.2)];
        const DEAD_TIME: [ParamSpec; 1] = [spec("delay_s", "s", 0.0, MAX_DEAD_TIME_S, 0.2)];
        const DRAG: [ParamSpec; 2] = [
            spec("c_d", "1/m", 0.0, 0.005, 0.0003),
            spec("c_r", "m/s^2", 0.0, 0.5, 0.05),
        ];
        const UNDERSTEER: [ParamSpec; 1] = [spec("k_us", "rad/(m/s^2)", 0.0, 0.02, 0.002)];
        const RATE: [ParamSpec; 1] = [spec("rate_rad_s", "rad/s", 0.02, 2.0, 0.5)];
        const SIDESLIP: [ParamSpec; 1] = [spec("lr_m", "m", 0.0, 3.0, 0.7)];
        match self {
            Effect::AccelLag => &ACCEL_LAG,
            Effect::SteerLag => &STEER_LAG,
            Effect::DeadTime => &DEAD_TIME,
            Effect::Drag => &DRAG,
            Effect::Understeer => &UNDERSTEER,
            Effect::SteerRateLimit => &RATE,
            Effect::Sideslip => &SIDESLIP,
        }
    }

    /// Whether the effect acts on the commands (so it cannot be seen when the commands were
    /// inferred from the motion itself).
    pub fn acts_on_commands(self) -> bool {
        !matches!(self, Effect::Sideslip)
    }

    /// The term, from parameter tensors in the order of [`Effect::params`].
    pub fn term(self, params: &[Tensor<2>], dt: f64) -> Box<dyn DynamicsTerm> {
        let p = |k: usize| params[k].clone();
        match self {
            Effect::AccelLag => Box::new(FirstOrderLag {
                channel: Channel::Accel,
                tau_s: p(0),
            }),
            Effect::SteerLag => Box::new(FirstOrderLag {
                channel: Channel::Steer,
                tau_s: p(0),
            }),
            Effect::DeadTime => Box::new(DeadTime::new(p(0), MAX_DEAD_TIME_S, dt)),
            Effect::Drag => Box::new(Drag {
                c_d: p(0),
                c_r: p(1),
            }),
            Effect::Understeer => Box::new(Understeer { k_us: p(0) }),
            Effect::SteerRateLimit => Box::new(SteerRateLimit { rate_rad_s: p(0) }),
            Effect::Sideslip => Box::new(Sideslip { lr_m: p(0) }),
        }
    }
}

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Raw (unbounded) value → parameter value in `[min, max]`, as tensors (differentiable).
pub fn bounded(raw: Tensor<1>, spec: &ParamSpec) -> Tensor<1> {
    burn::tensor::activation::sigmoid(raw)
        .mul_scalar(spec.max - spec.min)
        .add_scalar(spec.min)
}

/// Inverse of [`bounded`] for one value (clamped inside the range).
pub fn unbounded(value: f64, spec: &ParamSpec) -> f64 {
    let share = ((value - spec.min) / (spec.max - spec.min)).clamp(1e-4, 1.0 - 1e-4);
    (share / (1.0 - share)).ln()
}

/// One identified term with its fitted parameter values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FittedTerm {
    pub effect: Effect,
    /// Parameter values by name (SI units as in [`Effect::params`]).
    pub params: std::collections::BTreeMap<String, f64>,
}

/// The physics terms sim-to-real identified, as saved for the training simulator
/// (`rtr sim2real`'s `dynamics.toml`, loaded by `rtr train --dynamics` or the run file's
/// `dynamics` key).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsFile {
    #[serde(default)]
    pub terms: Vec<FittedTerm>,
    /// Terms found by sim-to-real's open-ended discovery ([`super::library`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub discovered: Vec<DiscoveredTerm>,
}

/// One library term with its coefficient: `equation += coefficient * feature`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscoveredTerm {
    pub equation: Equation,
    pub feature: Feature,
    pub coefficient: f64,
}

/// Largest |coefficient| of a discovered term in a dynamics file.
const MAX_COEFFICIENT: f64 = 1e3;

impl DynamicsFile {
    pub fn load(path: &std::path::Path) -> Result<Self> {
        let text = crate::io::read_text(path, crate::io::Format::Settings)?;
        let file: DynamicsFile = crate::io::parse_toml(&text, &path.display().to_string())?;
        file.validate(&path.display().to_string())?;
        Ok(file)
    }

    pub fn save(&self, path: &std::path::Path) -> Result<()> {
        crate::io::atomic_write(path, self.to_toml()?.as_bytes())
    }

    /// The TOML text [`Self::save`] writes.
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string_pretty(self)
            .map_err(|e| Error::InvalidArgument(format!("cannot write dynamics: {e}")))
    }

    /// Every term names each of its parameters once, inside the catalogue's range.
    pub fn validate(&self, source: &str) -> Result<()> {
        for (k, term) in self.discovered.iter().enumerate() {
            let place = format!("discovered[{k}]");
            if let Some((_, parameter, value)) = term.feature.limit()
                && !(value.is_finite() && value > 0.0)
            {
                return Err(Error::invalid(
                    source,
                    format!("{place}.feature.{}.{parameter}", term.feature.name()),
                    format!("{value}: expected a limit > 0"),
                ));
            }
            if !term.feature.is_in_library(term.equation) {
                let mut names: Vec<String> = Feature::library(term.equation)
                    .iter()
                    .map(|f| f.symbol())
                    .collect();
                // A limit kind once, spelt as a dynamics file writes it.
                for grid in Feature::limit_grids(term.equation) {
                    if let Some((_, parameter, _)) = grid.first().and_then(|f| f.limit()) {
                        let name = grid[0].name();
                        names.push(format!(
                            "{name} (feature = {{ {name} = {{ {parameter} = x }} }})"
                        ));
                    }
                }
                return Err(Error::invalid(
                    source,
                    &place,
                    format!(
                        "feature `{}` is not in the {} library: expected one of {}",
                        term.feature.symbol(),
                        term.equation.symbol(),
                        names.join(", ")
                    ),
                ));
            }
            // A discovered term adds coefficient x feature to an acceleration (m/s^2) or a
            // yaw rate; features are O(1) to O(100), so far above 1e3 is no physics.
            if !(term.coefficient.is_finite() && term.coefficient.abs() <= MAX_COEFFICIENT) {
                return Err(Error::invalid(
                    source,
                    &place,
                    format!(
                        "coefficient {}: expected a finite value with |coefficient| <= {MAX_COEFFICIENT}",
                        term.coefficient
                    ),
                ));
            }
        }
        for (k, term) in self.terms.iter().enumerate() {
            let place = format!("terms[{k}] ({})", term.effect);
            if let Some(first) = self.terms[..k].iter().position(|t| t.effect == term.effect) {
                return Err(Error::invalid(
                    source,
                    &place,
                    format!(
                        "{} is already terms[{first}]; expected each effect once (two would stack)",
                        term.effect
                    ),
                ));
            }
            for spec in term.effect.params() {
                let value = term.params.get(spec.name).ok_or_else(|| {
                    Error::invalid(source, &place, format!("missing parameter `{}`", spec.name))
                })?;
                if !(spec.min..=spec.max).contains(value) {
                    return Err(Error::invalid(
                        source,
                        &place,
                        format!(
                            "{} = {value} is outside [{}, {}] {}",
                            spec.name, spec.min, spec.max, spec.unit
                        ),
                    ));
                }
            }
            if let Some(extra) = term
                .params
                .keys()
                .find(|name| !term.effect.params().iter().any(|s| s.name == *name))
            {
                return Err(Error::invalid(
                    source,
                    &place,
                    format!("unknown parameter `{extra}`"),
                ));
            }
        }
        Ok(())
    }

    /// Adds the terms, as constants, to `dynamics`.
    pub fn apply(&self, mut dynamics: Dynamics, device: &Device) -> Dynamics {
        for term in &self.terms {
            let params: Vec<Tensor<2>> = term
                .effect
                .params()
                .iter()
                .map(|s| parameter(term.params[s.name], device))
                .collect();
            let dt = dynamics.dt;
            dynamics = dynamics.with_term(term.effect.term(&params, dt));
        }
        if !self.discovered.is_empty() {
            let terms = self
                .discovered
                .iter()
                .map(|t| (t.equation, t.feature, parameter(t.coefficient, device)))
                .collect();
            dynamics = dynamics.with_term(Box::new(LibraryTerm { terms }));
        }
        dynamics
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_ranges_hold_their_start() {
        for effect in Effect::ALL {
            assert_eq!(Effect::from_name(effect.name()), Some(effect));
            for s in effect.params() {
                assert!(s.min < s.start && s.start < s.max, "{effect} {}", s.name);
                let device = crate::backend::Backend::reference_device(false);
                let raw = Tensor::<1>::from_floats([unbounded(s.start, s) as f32], &device);
                let back = bounded(raw, s).into_scalar::<f64>();
                assert!((back - s.start).abs() < 1e-5 * (s.max - s.min));
            }
        }
    }

    #[test]
    fn a_dynamics_file_with_a_bad_parameter_names_it() {
        let bad = "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = -1.0 }\n";
        let file: DynamicsFile = crate::io::parse_toml(bad, "d.toml").expect("toml");
        let message = file
            .validate("d.toml")
            .expect_err("negative lag")
            .to_string();
        assert!(message.contains("terms[0] (accel_lag)") && message.contains("tau_s"));
        let unknown = "[[terms]]\neffect = \"warp\"\nparams = {}\n";
        let err = crate::io::parse_toml::<DynamicsFile>(unknown, "d.toml").expect_err("effect");
        assert!(err.to_string().contains("line"), "{err}");
    }
}
