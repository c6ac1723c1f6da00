//! A rollout in which the long-tail scenarios' heroes follow their scripts and a policy drives
//! every other agent: what training, evaluation and the probes all run on generated scenes.

use super::concrete::{ConcreteScenario, hero_scripts};
use crate::error::Result;
use crate::scene::{Scene, SceneBatch};
use crate::sim::{Dynamics, MapCaches, Policy, Rollout, RolloutConfig, Scripted, rollout};

/// Rolls out `scenes` with `policy`, the heroes of `scenarios` (`scenes[b]` built from
/// `scenarios[b]`) driven by their scripts. Recorded scenes have no scenarios: pass none and
/// `policy` drives them alone.
pub fn rollout_with_heroes(
    scenarios: &[&ConcreteScenario],
    scenes: &[&Scene],
    batch: &SceneBatch,
    dynamics: &Dynamics,
    policy: &mut dyn Policy,
    caches: &mut MapCaches,
    config: &RolloutConfig,
) -> Result<Rollout> {
    if scenarios.is_empty() {
        return rollout(scenes, batch, dynamics, policy, caches, config);
    }
    let mut heroes = hero_scripts(scenarios, scenes);
    let mut driver = Scripted {
        policy,
        script: &mut heroes,
        mask: batch.agent_hero.clone(),
    };
    rollout(scenes, batch, dynamics, &mut driver, caches, config)
}
