//! What a probe reports of a policy on held-out scenarios: the share of its cars with an
//! infraction when it drives its mean action (as `rtr eval` does), and the training reward of
//! its sampled rollouts (what PPO maximises), collected as training collects.

use burn::prelude::*;
use burn::tensor::Bool;

use super::super::config::PpoConfig;
use super::super::experience::{CollectNetworks, CollectStats, RewardSettings, collect};
use super::super::sources::Part;
use crate::error::Result;
use crate::model::{ActionMode, NetworkPolicy, PolicyNetwork, ValueNetwork};
use crate::scenario::{ConcreteScenario, rollout_with_heroes};
use crate::scene::{Scene, SceneBatch};
use crate::sim::{Dynamics, MapCaches, Policy, Rollout, RolloutConfig};

/// Scenes simulated in one batch.
const PART_SCENES: usize = 32;

/// The scenarios as parts of at most [`PART_SCENES`] scenes of one window length, as training
/// batches them; `scenes` are the scenarios' scenes in the same order.
pub fn parts<'a>(scenarios: &'a [ConcreteScenario], scenes: &'a [Scene]) -> Vec<Part<'a>> {
    let mut parts: Vec<Part> = Vec::new();
    for (slot, (scenario, scene)) in scenarios.iter().zip(scenes).enumerate() {
        let fits = parts.last().is_some_and(|p: &Part| {
            p.scenes.len() < PART_SCENES && p.scenes[0].steps() == scene.steps()
        });
        if !fits {
            parts.push(Part {
                scenes: Vec::new(),
                scenarios: Vec::new(),
                slots: Vec::new(),
            });
        }
        let part = parts.last_mut().expect("a part was just pushed");
        part.scenes.push(scene);
        part.scenarios.push(scenario);
        part.slots.push(slot);
    }
    parts
}

/// How the controlled cars of some rollouts fared.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CarOutcomes {
    pub cars: usize,
    pub collided: usize,
    pub offroad: usize,
    /// Either.
    pub failed: usize,
}

impl CarOutcomes {
    /// Percentage of `count` among the cars.
    pub fn pct(&self, count: usize) -> f64 {
        100.0 * count as f64 / self.cars.max(1) as f64
    }

    fn add(&mut self, out: &Rollout) {
        let [b, n, _] = out.simulated.dims();
        let per_car = |flags: Tensor<3, Bool>| -> Vec<bool> {
            flags
                .any_dim(2)
                .reshape([b * n])
                .into_data()
                .try_into_vec_as::<bool>()
                .unwrap_or_default()
        };
        let controlled = per_car(out.simulated.clone().narrow(2, 0, 1));
        let collided = per_car(out.collision.clone());
        let offroad = per_car(out.offroad.clone());
        for k in 0..controlled.len() {
            if controlled[k] {
                self.cars += 1;
                self.collided += usize::from(collided[k]);
                self.offroad += usize::from(offroad[k]);
                self.failed += usize::from(collided[k] || offroad[k]);
            }
        }
    }
}

/// The outcomes of the cars of `parts` driven by the policy `drive` makes for each part and
/// its batch (heroes scripted, early termination as in training).
pub fn rollout_outcomes<'p>(
    parts: &[Part],
    dynamics: &Dynamics,
    device: &Device,
    drive: impl Fn(&Part, &SceneBatch) -> Box<dyn Policy + 'p>,
) -> Result<CarOutcomes> {
    let mut caches = MapCaches::default();
    let mut outcomes = CarOutcomes::default();
    for part in parts {
        let batch = SceneBatch::from_scenes(&part.scenes, device)?;
        let mut driver = drive(part, &batch);
        let out = rollout_with_heroes(
            &part.scenarios,
            &part.scenes,
            &batch,
            dynamics,
            driver.as_mut(),
            &mut caches,
            &RolloutConfig {
                steps: None,
                early_termination: true,
            },
        )?;
        outcomes.add(&out);
    }
    Ok(outcomes)
}

/// Percentage of the policy's cars that collide or leave the road when every one drives the
/// policy's mean action (heroes scripted).
pub fn infraction_pct(
    policy: &PolicyNetwork,
    parts: &[Part],
    dynamics: &Dynamics,
    device: &Device,
) -> Result<f64> {
    let outcomes = rollout_outcomes(parts, dynamics, device, |_, batch| {
        Box::new(NetworkPolicy::new(policy, batch, ActionMode::Mean))
    })?;
    Ok(outcomes.pct(outcomes.failed))
}

/// The training reward of `policy`'s sampled rollouts on `parts` (PPO's reward and early
/// termination, noise seeded by `seed`): per car, the undiscounted sum of its rewards.
pub fn sampled_return(
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    parts: &[Part],
    dynamics: &Dynamics,
    ppo: &PpoConfig,
    seed: u64,
    device: &Device,
) -> Result<f64> {
    let nets = CollectNetworks {
        policy,
        value,
        reference: None,
    };
    let rewards = RewardSettings {
        shaping: None,
        kl_weight: None,
    };
    let mut caches = MapCaches::default();
    let mut stats = CollectStats::default();
    for part in parts {
        let e = collect(
            part,
            &nets,
            device,
            dynamics,
            &mut caches,
            None,
            ppo,
            &rewards,
            seed,
        )?;
        stats += e.stats;
    }
    Ok(stats.reward_sum / stats.agents.max(1) as f64)
}
