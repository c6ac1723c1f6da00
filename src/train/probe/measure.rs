//! What a probe reports of a policy on held-out scenarios: the share of its cars with an
//! infraction when it drives its mean action (as `rtr eval` does), and the training reward of
//! its sampled rollouts (what PPO maximises), collected as training collects.

use burn::prelude::*;

use super::super::config::PpoConfig;
use super::super::experience::{CollectNetworks, CollectStats, RewardSettings, collect};
use super::super::sources::Part;
use crate::error::Result;
use crate::model::{ActionMode, NetworkPolicy, PolicyNetwork, ValueNetwork};
use crate::scenario::{ConcreteScenario, rollout_with_heroes};
use crate::scene::{Scene, SceneBatch};
use crate::sim::{Dynamics, MapCaches, RolloutConfig};

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

/// Percentage of the policy's cars that collide or leave the road when every one drives the
/// policy's mean action (heroes scripted).
pub fn infraction_pct(
    policy: &PolicyNetwork,
    parts: &[Part],
    dynamics: &Dynamics,
    device: &Device,
) -> Result<f64> {
    let mut caches = MapCaches::default();
    let (mut cars, mut failed) = (0usize, 0usize);
    for part in parts {
        let batch = SceneBatch::from_scenes(&part.scenes, device)?;
        let mut driver = NetworkPolicy::new(policy, &batch, ActionMode::Mean);
        let out = rollout_with_heroes(
            &part.scenarios,
            &part.scenes,
            &batch,
            dynamics,
            &mut driver,
            &mut caches,
            &RolloutConfig {
                steps: None,
                early_termination: true,
            },
        )?;
        let [b, n, _] = out.simulated.dims();
        let controlled: Vec<bool> = out
            .simulated
            .clone()
            .narrow(2, 0, 1)
            .reshape([b * n])
            .into_data()
            .try_into_vec_as::<bool>()
            .unwrap_or_default();
        let any = out
            .collision
            .clone()
            .bool_or(out.offroad.clone())
            .int()
            .sum_dim(2)
            .reshape([b * n])
            .into_data()
            .convert::<i64>()
            .try_into_vec::<i64>()
            .unwrap_or_default();
        for (c, k) in controlled.iter().zip(&any) {
            cars += usize::from(*c);
            failed += usize::from(*c && *k > 0);
        }
    }
    Ok(100.0 * failed as f64 / cars.max(1) as f64)
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
