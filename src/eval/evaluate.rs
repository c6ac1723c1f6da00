//! Runs a policy over a scene set in closed loop and measures it: batches of same-length
//! scenes are rolled out (heroes follow their scripts), each scene is tallied against its log,
//! and the tallies become the table's metrics with bootstrap intervals.
//!
//! Evaluation rollouts keep every agent to the end (no early termination), so every agent
//! still on the map is measured at the 5 s horizon and the feature histograms cover the whole
//! horizon; an infraction still counts the agent once. The policy acts with its mean action
//! (deterministic); the realism score alone samples.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bootstrap::{Additive, Estimate, estimate, resampled_totals, total};
use super::collisions::{CollisionBreakdown, FirstCollision, first_collisions};
use super::metrics::{Metric, SceneTally};
use super::plots::simulated_scene;
use super::policy::EvalPolicy;
use super::realism::{RealismTally, agent_tally};
use super::sets::{EvalScenes, EvalSet};
use super::tally::{logged_features, simulated_features, tally_rollout};
use crate::error::Result;
use crate::scenario::rollout_with_heroes;
use crate::scene::{Scene, SceneBatch};
use crate::sim::{Dynamics, MapCaches, RolloutConfig};

/// How a set is evaluated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalConfig {
    /// Scenes per tensor batch.
    pub batch: usize,
    /// FDE horizon (s); the paper's 5 s.
    pub fde_horizon_s: f64,
    /// Bootstrap resamples over scenes.
    pub resamples: usize,
    pub seed: u64,
    /// Sampled rollouts per scene for the WOSAC-style realism score (sets with logs only);
    /// 0 skips it.
    pub realism_samples: usize,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            batch: 16,
            fde_horizon_s: 5.0,
            resamples: 1000,
            seed: 2023,
            realism_samples: 8,
        }
    }
}

/// Index groups of at most `batch` scenes sharing one window shape (history, future steps),
/// in first-seen order.
fn batches(windows: &[(usize, usize)], batch: usize) -> Vec<Vec<usize>> {
    let mut shapes: Vec<((usize, usize), Vec<usize>)> = Vec::new();
    for (k, &shape) in windows.iter().enumerate() {
        match shapes.iter_mut().find(|(sh, _)| *sh == shape) {
            Some((_, v)) => v.push(k),
            None => shapes.push((shape, vec![k])),
        }
    }
    shapes
        .into_iter()
        .flat_map(|(_, v)| {
            v.chunks(batch.max(1))
                .map(<[usize]>::to_vec)
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Runs `per_batch` on every batch of `set` (same-window scenes, at most `config.batch`) in
/// parallel (rayon), each worker with its own map caches, and returns its per-scene results
/// in scene order. `per_batch` gets the caches, the batch's index and its scene indices.
fn per_scene<T: Send>(
    set: &EvalScenes,
    config: &EvalConfig,
    per_batch: impl Fn(&mut MapCaches, usize, &[usize]) -> Result<Vec<T>> + Sync,
) -> Result<Vec<T>> {
    let windows: Vec<(usize, usize)> = set
        .scenes
        .iter()
        .map(|s| (s.history_steps, s.future_steps))
        .collect();
    let groups = batches(&windows, config.batch);
    let per_group: Vec<Result<Vec<T>>> = groups
        .par_iter()
        .enumerate()
        .map_init(MapCaches::default, |caches, (g, group)| {
            per_batch(caches, g, group)
        })
        .collect();
    let mut out: Vec<Option<T>> = (0..set.scenes.len()).map(|_| None).collect();
    for (group, results) in groups.iter().zip(per_group) {
        for (&k, t) in group.iter().zip(results?) {
            out[k] = Some(t);
        }
    }
    Ok(out.into_iter().flatten().collect())
}

/// Per-scene tallies of `policy` on `set`, in scene order.
pub fn evaluate_tallies(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<Vec<SceneTally>> {
    Ok(evaluate_scenes(policy, dynamics, set, device, config)?
        .into_iter()
        .map(|(tally, _)| tally)
        .collect())
}

/// Per scene, in scene order: its tally and its controlled agents' first collisions, from one
/// deterministic rollout.
fn evaluate_scenes(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<Vec<(SceneTally, Vec<FirstCollision>)>> {
    per_scene(set, config, |caches, _, group| {
        let (batch, out) = rollout_group(policy, dynamics, set, group, device, caches, None)?;
        let scenes: Vec<&Scene> = group.iter().map(|&k| &set.scenes[k]).collect();
        let fde_step = (config.fde_horizon_s / batch.dt).round() as usize;
        let tallies = tally_rollout(&scenes, &out, fde_step, set.set.has_logs())?;
        Ok(tallies
            .into_iter()
            .zip(first_collisions(&scenes, &out, batch.dt))
            .collect())
    })
}

/// Per-scene WOSAC-style realism tallies ([`super::realism`]) of `policy` on a set with logs:
/// `config.realism_samples` sampled rollouts per batch, each seeded from the config's seed,
/// the batch and the sample index.
pub fn realism_tallies(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<Vec<RealismTally>> {
    per_scene(set, config, |caches, g, group| {
        let scenes: Vec<&Scene> = group.iter().map(|&k| &set.scenes[k]).collect();
        let mut sampled = Vec::with_capacity(config.realism_samples);
        for k in 0..config.realism_samples {
            let seed = crate::seeding::stream_seed(config.seed, g, k as u64);
            let (_, out) = rollout_group(policy, dynamics, set, group, device, caches, Some(seed))?;
            sampled.push(simulated_features(&scenes, &out));
        }
        Ok(scenes
            .iter()
            .enumerate()
            .map(|(b, scene)| {
                let mut tally = RealismTally::default();
                for (i, log_rows) in logged_features(scene, scene.future_steps)
                    .iter()
                    .enumerate()
                {
                    if log_rows.is_empty() {
                        continue;
                    }
                    let mut samples: [Vec<f64>; 4] = Default::default();
                    let mut values: [Vec<f64>; 4] = Default::default();
                    for run in &sampled {
                        for f in run[b][i].iter().flatten() {
                            for (k, v) in f.iter().enumerate() {
                                samples[k].extend(v);
                            }
                        }
                    }
                    for f in log_rows.iter().flatten() {
                        for (k, v) in f.iter().enumerate() {
                            values[k].extend(v);
                        }
                    }
                    tally.add_scaled(&agent_tally(&samples, &values), 1.0);
                }
                tally
            })
            .collect())
    })
}

/// One set's row of the table: each metric with its bootstrap half-width (`None` where the
/// set has no logs or the metric no samples).
#[derive(Debug, Clone, PartialEq)]
pub struct SetResult {
    pub set: EvalSet,
    pub scenes: usize,
    pub agents: usize,
    pub metrics: BTreeMap<Metric, Option<Estimate>>,
    /// The summed tally (histograms for plots).
    pub total: SceneTally,
    /// The WOSAC-style realism score: kinematic, interactive, map and composite, where
    /// computed.
    pub realism: Option<[Option<Estimate>; 4]>,
    /// Whom the agents' first collisions were with, where computed.
    pub collisions: Option<CollisionBreakdown>,
}

impl SetResult {
    pub fn get(&self, metric: Metric) -> Option<Estimate> {
        self.metrics.get(&metric).copied().flatten()
    }
}

/// The metrics of `set` from its per-scene tallies.
pub fn summarise(set: EvalSet, tallies: &[SceneTally], config: &EvalConfig) -> SetResult {
    let full = total(tallies).unwrap_or_default();
    let resampled = resampled_totals(tallies, config.resamples, config.seed);
    let metrics = Metric::ALL
        .into_iter()
        .map(|m| {
            let applies = set.has_logs() || !m.needs_log();
            let e = applies
                .then(|| estimate(&full, &resampled, |t| m.value(t)))
                .flatten();
            (m, e)
        })
        .collect();
    SetResult {
        set,
        scenes: tallies.len(),
        agents: full.agents as usize,
        metrics,
        total: full,
        realism: None,
        collisions: None,
    }
}

/// The realism score's components and composite from per-scene realism tallies.
pub fn summarise_realism(tallies: &[RealismTally], config: &EvalConfig) -> [Option<Estimate>; 4] {
    let full = total(tallies).unwrap_or_default();
    let resampled = resampled_totals(tallies, config.resamples, config.seed);
    std::array::from_fn(|k| estimate(&full, &resampled, |t| t.score(k)))
}

/// Evaluates and summarises in one call.
pub fn evaluate(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<SetResult> {
    let (tallies, collisions): (Vec<SceneTally>, Vec<Vec<FirstCollision>>) =
        evaluate_scenes(policy, dynamics, set, device, config)?
            .into_iter()
            .unzip();
    let mut result = summarise(set.set, &tallies, config);
    result.collisions = Some(CollisionBreakdown {
        agents: result.agents,
        collisions: collisions.into_iter().flatten().collect(),
    });
    if set.set.has_logs() && config.realism_samples > 0 {
        let realism = realism_tallies(policy, dynamics, set, device, config)?;
        result.realism = Some(summarise_realism(&realism, config));
    }
    Ok(result)
}

/// Rolls out the scenes `indices` of `set` (same window shape) and returns the batch's scenes
/// and the rollout.
fn rollout_group(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    indices: &[usize],
    device: &burn::prelude::Device,
    caches: &mut MapCaches,
    noise: Option<u64>,
) -> Result<(SceneBatch, crate::sim::Rollout)> {
    let scenes: Vec<&Scene> = indices.iter().map(|&k| &set.scenes[k]).collect();
    let batch = SceneBatch::from_scenes(&scenes, device)?;
    let config = RolloutConfig {
        steps: None,
        early_termination: false,
    };
    let mut learned = policy.policy(&scenes, &batch, noise);
    // Recorded sets have no scenarios; generated ones one per scene.
    let scenarios: Vec<_> = if set.scenarios.is_empty() {
        Vec::new()
    } else {
        indices.iter().map(|&k| &set.scenarios[k]).collect()
    };
    let out = rollout_with_heroes(
        &scenarios,
        &scenes,
        &batch,
        dynamics,
        &mut *learned,
        caches,
        &config,
    )?;
    Ok((batch, out))
}

/// The scenes `indices` of `set` (one window shape) as `policy` drives them: each scene with
/// its controlled agents' future replaced by the simulated one, for pictures beside the log.
pub fn simulated_scenes(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    indices: &[usize],
    device: &burn::prelude::Device,
) -> Result<Vec<Scene>> {
    Ok(simulated_rollout(policy, dynamics, set, indices, device)?.0)
}

/// As [`simulated_scenes`], with the rollout they were made from (its infraction flags).
pub fn simulated_rollout(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    indices: &[usize],
    device: &burn::prelude::Device,
) -> Result<(Vec<Scene>, crate::sim::Rollout)> {
    let (_, out) = rollout_group(
        policy,
        dynamics,
        set,
        indices,
        device,
        &mut MapCaches::default(),
        None,
    )?;
    let scenes: Vec<&Scene> = indices.iter().map(|&k| &set.scenes[k]).collect();
    Ok((rollout_scenes(&scenes, &out), out))
}

/// Every scene of `set` as `policy` drives it (see [`simulated_scenes`]), in scene order: with
/// its mean action, or with `noise = Some(seed)` sampled, each batch seeded from `seed` and
/// its index (synthetic data for the downstream study).
pub fn simulate_set(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
    noise: Option<u64>,
) -> Result<Vec<Scene>> {
    per_scene(set, config, |caches, g, group| {
        let seed = noise.map(|s| crate::seeding::stream_seed(s, g, 0));
        let (_, out) = rollout_group(policy, dynamics, set, group, device, caches, seed)?;
        let scenes: Vec<&Scene> = group.iter().map(|&k| &set.scenes[k]).collect();
        Ok(rollout_scenes(&scenes, &out))
    })
}

/// The rolled-out `scenes` with their controlled agents' futures replaced by the simulated
/// ones.
pub fn rollout_scenes(scenes: &[&Scene], out: &crate::sim::Rollout) -> Vec<Scene> {
    let [b, n, t1, _] = out.poses.dims();
    let poses: Vec<f32> = out
        .poses
        .clone()
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default();
    let present: Vec<bool> = out
        .present
        .clone()
        .into_data()
        .try_into_vec_as::<bool>()
        .unwrap_or_default();
    (0..b)
        .map(|bi| {
            let agent = |i: usize| (bi * n + i) * t1;
            let p: Vec<Vec<[f64; 4]>> = (0..n)
                .map(|i| {
                    (0..t1)
                        .map(|t| {
                            let k = (agent(i) + t) * 4;
                            std::array::from_fn(|c| poses.get(k + c).copied().unwrap_or(0.0) as f64)
                        })
                        .collect()
                })
                .collect();
            let ok: Vec<Vec<bool>> = (0..n)
                .map(|i| {
                    (0..t1)
                        .map(|t| present.get(agent(i) + t) == Some(&true))
                        .collect()
                })
                .collect();
            simulated_scene(scenes[bi], &p, &ok)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_group_by_window_and_cap_size() {
        let windows = [(4, 12), (4, 20), (4, 12), (4, 12), (4, 20)];
        assert_eq!(batches(&windows, 2), vec![vec![0, 2], vec![3], vec![1, 4]]);
    }
}
