//! Sizes and input encodings of the policy and value networks, as a serde config (TOML in
//! experiment files). The defaults are the paper's (hidden 128, lane encoder [128; 4], action
//! MLP [128, 128, 128]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::parse_toml;

/// Upper bounds that no sensible configuration reaches.
const MAX_WIDTH: usize = 8192;
const MAX_STEPS: usize = 200;
const MAX_LAYERS: usize = 64;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelConfig {
    /// Width of every node embedding (agents and lane nodes).
    pub hidden: usize,
    /// Past frames the history encoder sees, the current one included.
    pub history_steps: usize,
    /// Residual blocks of the 1D CNN before the GRU.
    pub history_blocks: usize,
    /// Temporal kernel of the 1D CNN.
    pub history_kernel: usize,
    /// Graph-convolution layers of the lane-graph encoder (LaneGCN).
    pub lane_layers: usize,
    /// Message-passing rounds of the HeteroGNN over agents and lane nodes.
    pub interaction_rounds: usize,
    /// Each agent receives from its this many closest lane nodes.
    pub agent_lane_edges: usize,
    /// Each lane node receives from its this many closest agents within `lane_agent_radius`.
    pub lane_agent_edges: usize,
    /// Metres.
    pub lane_agent_radius: f64,
    /// Hidden widths of the action and value decoders (the paper's 4-layer MLP has three).
    pub head_hidden: Vec<usize>,
    /// Wavelengths (m) of the sine/cosine encoding of distances between two poses.
    pub distance_wavelengths: Vec<f64>,
    /// Physical size of one unit of the action mean: (m/s^2, rad).
    #[serde(deserialize_with = "exactly_two")]
    pub action_scale: [f64; 2],
    /// Range of log sigma, relative to `action_scale`: sigma = scale * exp(value in range).
    #[serde(deserialize_with = "exactly_two")]
    pub log_std_range: [f64; 2],
    /// Not in the paper: agent <- agent edges also carry the sender's motion relative to the
    /// receiver (relative velocity, range rate; [`super::relative_motion`]), not only its pose.
    /// Off by default (the paper's edges).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub agent_edge_motion: bool,
    /// Not in the paper: the relative-motion edge inputs are multiplied by this before their
    /// weights. Adam moves every weight by about the learning rate per step whatever the scale
    /// of its gradient, so an input `g` times larger lets its contribution grow `g` times
    /// faster: a fine-tune that adds the motion inputs with zero weights
    /// (`[init] agent_edge_motion_scale = 0`) can learn them at `g` times the learning rate of
    /// the trained weights, with one optimizer. At 1 (default) a short fine-tune barely moves the
    /// new weights; a large gain lets them swamp the trained ones (`experiments/recipe/ppo_credit/`).
    #[serde(skip_serializing_if = "is_unit_gain")]
    pub agent_edge_motion_gain: f64,
    /// Multiplier bringing lane-node curvature (1/m) to network units (the other lane-node
    /// features' scales are fixed in [`super::input`]). The default 100 puts a 100 m radius at 1
    /// but the A9's 3.3 km radius at 0.03; 1000 puts motorway curves (0.0003 to 0.003 1/m) at
    /// 0.3 to 3 (compared in `experiments/recipe/agent_dropout/`).
    #[serde(skip_serializing_if = "is_default_curvature_scale")]
    pub lane_curvature_scale: f64,
    /// Not in the paper: whether lane nodes carry the road's speed limit (the paper's feature;
    /// default). Every recorded road
    /// has one limit on all its lanes (A9 100 km/h, the US-101 clips none, so 130), so the
    /// feature names the road rather than describing a lane: a policy trained on both keys its
    /// steering on it, and the same IL policy leaves 85 / 35 / 25 % of the long-tail agents off
    /// the generated roads at 100 / 120 / 130 km/h (`experiments/recipe/speed_limit/`). `false`
    /// feeds the network a 0 in its place (measured: IL then drives every generated road as
    /// the A9 and leaves it; the option is kept for that ablation).
    #[serde(skip_serializing_if = "is_true")]
    pub lane_speed_limit_input: bool,
    /// Not in the paper: the steering mean is the network's output plus the bicycle model's
    /// steady-state steering on the agent's lane, `atan(L k)` ([`super::steer_feedforward`]),
    /// so the network learns the correction to lane following rather than each road's
    /// curvature (its effect on lane keeping: `experiments/recipe/steer_feedforward/`). Off by
    /// default (the paper's head). It adds no parameters, so any checkpoint can warm-start
    /// either way.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub lane_steer_feedforward: bool,
    /// Not in the paper (its value network is the policy's architecture): the value network's
    /// hidden width, its decoder layers all this wide too, with the policy's layers and rounds.
    /// A PPO agent-step evaluates both networks in collection and in the update, so a narrower
    /// value network is a direct saving; `None` (default): the policy's widths.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value_hidden: Option<usize>,
    /// Not in the paper: the value network's HeteroGNN rounds. The value only has to rank
    /// states by return, not drive, so it can see less of the scene than the policy; each
    /// round is about a quarter of a PPO agent-step's cost at hidden 64. `None` (default): the
    /// policy's rounds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value_interaction_rounds: Option<usize>,
}

impl ModelConfig {
    /// The value network's architecture: this one, at [`Self::value_hidden`]'s width and with
    /// [`Self::value_interaction_rounds`]' rounds where set.
    pub fn value_network(&self) -> ModelConfig {
        let (hidden, head_hidden) = match self.value_hidden {
            Some(width) => (width, vec![width; self.head_hidden.len()]),
            None => (self.hidden, self.head_hidden.clone()),
        };
        ModelConfig {
            hidden,
            head_hidden,
            interaction_rounds: self
                .value_interaction_rounds
                .unwrap_or(self.interaction_rounds),
            value_hidden: None,
            value_interaction_rounds: None,
            ..self.clone()
        }
    }
}

fn is_true(flag: &bool) -> bool {
    *flag
}

fn is_unit_gain(gain: &f64) -> bool {
    *gain == 1.0
}

/// [`ModelConfig::lane_curvature_scale`]'s default.
pub const DEFAULT_LANE_CURVATURE_SCALE: f64 = 100.0;

fn is_default_curvature_scale(scale: &f64) -> bool {
    *scale == DEFAULT_LANE_CURVATURE_SCALE
}

impl Default for ModelConfig {
    fn default() -> Self {
        Self {
            hidden: 128,
            history_steps: 5,
            history_blocks: 2,
            history_kernel: 3,
            lane_layers: 4,
            interaction_rounds: 3,
            agent_lane_edges: 8,
            lane_agent_edges: 4,
            lane_agent_radius: 30.0,
            head_hidden: vec![128, 128, 128],
            distance_wavelengths: vec![4.0, 16.0, 64.0, 256.0],
            action_scale: [2.0, 0.02],
            log_std_range: [-4.0, 1.0],
            agent_edge_motion: false,
            agent_edge_motion_gain: 1.0,
            lane_curvature_scale: DEFAULT_LANE_CURVATURE_SCALE,
            lane_speed_limit_input: true,
            lane_steer_feedforward: false,
            value_hidden: None,
            value_interaction_rounds: None,
        }
    }
}

impl ModelConfig {
    /// A small network for tests and the quick example (same structure, narrow layers).
    pub fn small() -> Self {
        Self {
            hidden: 32,
            lane_layers: 2,
            interaction_rounds: 2,
            head_hidden: vec![32, 32, 32],
            ..Self::default()
        }
    }

    /// Reads a TOML file; missing fields take the defaults.
    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path, crate::io::Format::Settings)?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses TOML text; `source_name` names it in errors.
    pub fn from_toml_str(text: &str, source_name: &str) -> Result<Self> {
        let config: Self = parse_toml(text, source_name)?;
        config.validate_text(text, source_name, "")?;
        Ok(config)
    }

    /// [`Self::validate`] of a config read from the settings file `text`, its fields under
    /// `table` (`"model."` in a run file): a refused value is reported at its line.
    pub fn validate_text(&self, text: &str, source_name: &str, table: &str) -> Result<()> {
        match self.size_problem().or_else(|| self.scale_problem()) {
            Some((field, message)) => Err(crate::io::field_error(
                text,
                source_name,
                &format!("{table}{field}"),
                &message,
            )),
            None => Ok(()),
        }
    }

    /// Checks every size and range; `source_name` names the config in errors.
    pub fn validate(&self, source_name: &str) -> Result<()> {
        match self.size_problem().or_else(|| self.scale_problem()) {
            Some((field, message)) => Err(Error::invalid(
                source_name,
                format!("model config field `{field}`"),
                message,
            )),
            None => Ok(()),
        }
    }

    /// The first width, count or layer number out of range, as (field, what was expected).
    fn size_problem(&self) -> Option<(&'static str, String)> {
        let positive = [
            ("hidden", self.hidden),
            ("value_hidden", self.value_hidden.unwrap_or(self.hidden)),
            ("history_steps", self.history_steps),
            ("history_kernel", self.history_kernel),
            ("agent_lane_edges", self.agent_lane_edges),
            ("lane_agent_edges", self.lane_agent_edges),
        ];
        for (field, value) in positive {
            if value == 0 {
                return Some((field, "expected a positive integer, got 0".into()));
            }
        }
        // Catches typos (an extra zero) before they become a multi-gigabyte allocation.
        let bounded = [
            ("hidden", self.hidden, MAX_WIDTH),
            (
                "value_hidden",
                self.value_hidden.unwrap_or(self.hidden),
                MAX_WIDTH,
            ),
            ("history_steps", self.history_steps, MAX_STEPS),
            ("history_kernel", self.history_kernel, MAX_STEPS),
            ("history_blocks", self.history_blocks, MAX_LAYERS),
            ("lane_layers", self.lane_layers, MAX_LAYERS),
            ("interaction_rounds", self.interaction_rounds, MAX_LAYERS),
            (
                "value_interaction_rounds",
                self.value_interaction_rounds.unwrap_or(0),
                MAX_LAYERS,
            ),
        ];
        for (field, value, max) in bounded {
            if value > max {
                return Some((field, format!("expected at most {max}, got {value}")));
            }
        }
        if let Some(w) = self.head_hidden.iter().find(|&&w| w > MAX_WIDTH) {
            return Some((
                "head_hidden",
                format!("expected widths of at most {MAX_WIDTH}, got {w}"),
            ));
        }
        if self.history_kernel.is_multiple_of(2) {
            return Some((
                "history_kernel",
                format!(
                    "expected an odd kernel (the sequence keeps its length), got {}",
                    self.history_kernel
                ),
            ));
        }
        if let Some(rounds) = self.value_interaction_rounds
            && rounds > self.interaction_rounds
        {
            // The edges (and the lane crop the lane rounds update) are built once, for the
            // policy's rounds, and shared by both networks.
            return Some((
                "value_interaction_rounds",
                format!(
                    "expected at most interaction_rounds ({}), got {rounds}",
                    self.interaction_rounds
                ),
            ));
        }
        if self.head_hidden.contains(&0) {
            return Some(("head_hidden", "expected positive widths".into()));
        }
        None
    }

    /// The first scale or range out of bounds, as (field, what was expected).
    fn scale_problem(&self) -> Option<(&'static str, String)> {
        if !(self.lane_agent_radius.is_finite() && self.lane_agent_radius > 0.0) {
            return Some((
                "lane_agent_radius",
                format!("expected metres > 0, got {}", self.lane_agent_radius),
            ));
        }
        if self
            .distance_wavelengths
            .iter()
            .any(|w| !(w.is_finite() && *w > 0.0))
        {
            return Some((
                "distance_wavelengths",
                "expected finite wavelengths > 0 (m)".into(),
            ));
        }
        if self
            .action_scale
            .iter()
            .any(|s| !(s.is_finite() && *s > 0.0))
        {
            return Some((
                "action_scale",
                format!("expected two scales > 0, got {:?}", self.action_scale),
            ));
        }
        if !(self.lane_curvature_scale.is_finite() && self.lane_curvature_scale > 0.0) {
            return Some((
                "lane_curvature_scale",
                format!(
                    "expected a finite scale > 0 (m), got {}",
                    self.lane_curvature_scale
                ),
            ));
        }
        if !(self.agent_edge_motion_gain.is_finite() && self.agent_edge_motion_gain > 0.0) {
            return Some((
                "agent_edge_motion_gain",
                format!(
                    "expected a finite factor > 0, got {}",
                    self.agent_edge_motion_gain
                ),
            ));
        }
        if self.agent_edge_motion_gain != 1.0 && !self.agent_edge_motion {
            return Some((
                "agent_edge_motion_gain",
                "scales the relative-motion inputs: it needs agent_edge_motion = true".into(),
            ));
        }
        let [lo, hi] = self.log_std_range;
        // exp(5) = 148 action scales is already no action; below exp(-20) sigma underflows f32.
        if !(lo >= -20.0 && hi <= 5.0 && lo < hi) {
            return Some((
                "log_std_range",
                format!("expected [low, high] with -20 <= low < high <= 5, got [{lo}, {hi}]"),
            ));
        }
        None
    }
}

/// A pair given as exactly two numbers: serde's fixed-size arrays ignore extra elements.
fn exactly_two<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<[f64; 2], D::Error> {
    use serde::Deserialize;
    let values = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(values.as_slice())
        .map_err(|_| serde::de::Error::invalid_length(values.len(), &"exactly two numbers"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let c = ModelConfig::default();
        assert_eq!((c.hidden, c.lane_layers), (128, 4));
        assert!(!c.lane_steer_feedforward && !c.agent_edge_motion);
        assert_eq!(c.head_hidden, vec![128, 128, 128]);
        c.validate("default").unwrap();
        ModelConfig::small().validate("small").unwrap();
    }

    #[test]
    fn toml_overrides_and_errors_name_the_place() {
        let c =
            ModelConfig::from_toml_str("hidden = 64\nhead_hidden = [64, 64]\n", "m.toml").unwrap();
        assert_eq!((c.hidden, c.head_hidden.len()), (64, 2));
        assert_eq!(c.lane_layers, 4);

        let err = ModelConfig::from_toml_str("hidden = 64\nhiden = 3\n", "m.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("m.toml") && err.contains("line 2"), "{err}");
        assert!(err.contains("hiden"), "{err}");

        let err = ModelConfig::from_toml_str("history_kernel = 4\n", "m.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("history_kernel") && err.contains("odd"),
            "{err}"
        );

        let err = ModelConfig::from_toml_str("hidden = 1280000\n", "m.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("hidden") && err.contains("at most"), "{err}");

        let err = ModelConfig::from_toml_str("lane_curvature_scale = 0.0\n", "m.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("lane_curvature_scale"), "{err}");

        for bad in [
            "agent_edge_motion_gain = 0.0\nagent_edge_motion = true\n",
            "agent_edge_motion_gain = 10.0\n",
        ] {
            let err = ModelConfig::from_toml_str(bad, "m.toml")
                .unwrap_err()
                .to_string();
            assert!(err.contains("agent_edge_motion_gain"), "{err}");
        }

        let err = ModelConfig::from_toml_str("log_std_range = [1.0, -1.0]\n", "m.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("log_std_range"), "{err}");

        for bad in ["value_hidden = 0\n", "value_hidden = 1280000\n"] {
            let err = ModelConfig::from_toml_str(bad, "m.toml")
                .unwrap_err()
                .to_string();
            assert!(err.contains("value_hidden"), "{bad}: {err}");
        }
        for bad in [
            "value_interaction_rounds = 65\n",
            "value_interaction_rounds = 3\ninteraction_rounds = 2\n",
        ] {
            let err = ModelConfig::from_toml_str(bad, "m.toml")
                .unwrap_err()
                .to_string();
            assert!(err.contains("value_interaction_rounds"), "{bad}: {err}");
        }
    }

    /// The value network's width replaces the hidden and decoder widths and nothing else, is
    /// written only when set, and reads back.
    #[test]
    fn value_width_narrows_only_the_value_network() {
        let config = ModelConfig::from_toml_str("value_hidden = 32\n", "m.toml").unwrap();
        let value = config.value_network();
        assert_eq!((value.hidden, value.head_hidden.clone()), (32, vec![32; 3]));
        assert_eq!(
            ModelConfig {
                hidden: 128,
                head_hidden: vec![128; 3],
                value_hidden: Some(32),
                ..value
            },
            config
        );
        assert_round_trip_written_only_when_set(&config, "value_hidden");
        assert_eq!(
            ModelConfig::default().value_network(),
            ModelConfig::default()
        );
    }

    /// The value network's rounds replace its rounds and nothing else, the policy keeps its
    /// own, and the setting is written only when set and reads back.
    #[test]
    fn value_rounds_change_only_the_value_network() {
        let config =
            ModelConfig::from_toml_str("value_interaction_rounds = 1\n", "m.toml").unwrap();
        assert_eq!(config.interaction_rounds, 3);
        let value = config.value_network();
        assert_eq!(value.interaction_rounds, 1);
        assert_eq!(
            ModelConfig {
                interaction_rounds: 3,
                value_interaction_rounds: Some(1),
                ..value
            },
            config
        );
        assert_round_trip_written_only_when_set(&config, "value_interaction_rounds");
    }

    /// `config` reads back from the TOML it writes, and the default config does not write
    /// `field` (so run files and checkpoints without it keep meaning the paper's network).
    fn assert_round_trip_written_only_when_set(config: &ModelConfig, field: &str) {
        let text = toml::to_string(config).unwrap();
        assert_eq!(
            &ModelConfig::from_toml_str(&text, "m.toml").unwrap(),
            config
        );
        let default = toml::to_string(&ModelConfig::default()).unwrap();
        assert!(!default.contains(field), "{default}");
    }
}
