//! Curated scenes (paper section 4.3, "Long-tail scenarios"): the alternative to procedural
//! long-tail generation is mining hard cases from the logs, here the nominal A9 training
//! scenes on which a policy (the paper uses IL) commits an infraction in closed loop.

use super::evaluate::{EvalConfig, evaluate_tallies};
use super::policy::EvalPolicy;
use super::sets::EvalScenes;
use crate::error::Result;
use crate::scene::Scene;
use crate::sim::Dynamics;

/// One training scene and how the policy fared on it.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneOutcome {
    pub id: String,
    /// Controlled agents, and those with a collision / off-road step.
    pub agents: usize,
    pub collided: usize,
    pub offroad: usize,
}

impl SceneOutcome {
    /// The policy commits at least one infraction in the scene.
    pub fn failed(&self) -> bool {
        self.collided + self.offroad > 0
    }
}

/// Rolls `policy` out (mean action, no early termination, as `rtr eval`) on every scene of
/// `scenes` and returns each scene's outcome, in scene order.
pub fn scene_outcomes(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    scenes: Vec<Scene>,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<Vec<SceneOutcome>> {
    let set = EvalScenes::real(scenes);
    let tallies = evaluate_tallies(policy, dynamics, &set, device, config)?;
    Ok(set
        .scenes
        .iter()
        .zip(tallies)
        .map(|(scene, t)| SceneOutcome {
            id: scene.id.clone(),
            agents: t.agents.round() as usize,
            collided: t.collided.round() as usize,
            offroad: t.offroad.round() as usize,
        })
        .collect())
}
