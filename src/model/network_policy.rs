//! A [`PolicyNetwork`] as a simulator [`Policy`]: each step it builds the agents' input from
//! the simulated frames (never the log past the current step) and returns the mean action or
//! a reparameterised sample. The lane graph is encoded once per rollout.

use super::distribution::ActionDistribution;
use super::input::{AgentInput, LaneInput};
use super::network::{EncodedLanes, PolicyNetwork};
use crate::scene::SceneBatch;
use crate::sim::{Controls, Observation, Policy};

/// How a network policy turns its distribution into controls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionMode {
    /// The mean (the paper's choice for closed-loop imitation).
    Mean,
    /// mean + sigma * eps, differentiable in mean and sigma.
    Sample,
}

pub struct NetworkPolicy<'n> {
    network: &'n PolicyNetwork,
    lanes: LaneInput,
    encoded: EncodedLanes,
    mode: ActionMode,
}

impl<'n> NetworkPolicy<'n> {
    pub fn new(network: &'n PolicyNetwork, batch: &SceneBatch, mode: ActionMode) -> Self {
        let lanes = LaneInput::from_batch(batch, network.config());
        let encoded = network.encode_lanes(&lanes);
        Self {
            network,
            lanes,
            encoded,
            mode,
        }
    }

    /// The action distribution for this observation.
    pub fn distribution(&self, obs: &Observation) -> ActionDistribution {
        let agents = AgentInput::from_frames(obs.batch, obs.frames, self.network.config());
        self.network.forward(&agents, &self.lanes, &self.encoded)
    }
}

impl Policy for NetworkPolicy<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let distribution = self.distribution(obs);
        Controls::from_stacked(match self.mode {
            ActionMode::Mean => distribution.mean,
            ActionMode::Sample => distribution.sample(),
        })
    }
}
