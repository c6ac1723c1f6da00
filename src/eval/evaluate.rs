//! Runs a policy over a scene set in closed loop and measures it: batches of same-length
//! scenes are rolled out (heroes follow their scripts), each scene is tallied against its log,
//! and the tallies become the table's metrics with bootstrap intervals.
//!
//! Evaluation rollouts keep every agent to the end (no early termination), so FDE, ATE, CTE
//! and the feature histograms cover the whole horizon for every agent; an infraction still
//! counts the agent once. The policy acts with its mean action (deterministic).

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bootstrap::{Estimate, estimate, resampled_totals, total};
use super::metrics::{Metric, SceneTally};
use super::plots::simulated_scene;
use super::sets::{EvalScenes, EvalSet};
use super::tally::tally_rollout;
use crate::driver::{IdmDriver, IdmParams};
use crate::error::Result;
use crate::model::{ActionMode, NetworkPolicy, PolicyNetwork};
use crate::scenario::hero_scripts;
use crate::scene::{Scene, SceneBatch};
use crate::sim::{ActionLimits, Dynamics, MapCaches, Policy, RolloutConfig, Scripted, rollout};

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
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            batch: 16,
            fde_horizon_s: 5.0,
            resamples: 1000,
            seed: 2023,
        }
    }
}

/// Something that drives the controlled agents of a batch: a trained network or a baseline.
pub trait EvalPolicy: Sync {
    fn policy<'a>(&'a self, scenes: &[&Scene], batch: &SceneBatch) -> Box<dyn Policy + 'a>;
}

impl EvalPolicy for PolicyNetwork {
    fn policy<'a>(&'a self, _: &[&Scene], batch: &SceneBatch) -> Box<dyn Policy + 'a> {
        Box::new(NetworkPolicy::new(self, batch, ActionMode::Mean))
    }
}

/// The IDM + pure-pursuit lane keeper (a hand-written reference, not a learned method).
pub struct IdmBaseline {
    pub params: IdmParams,
    pub limits: ActionLimits,
}

impl EvalPolicy for IdmBaseline {
    fn policy<'a>(&'a self, scenes: &[&Scene], _: &SceneBatch) -> Box<dyn Policy + 'a> {
        Box::new(IdmDriver::new(scenes, self.params, self.limits))
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

/// Per-scene tallies of `policy` on `set`, in scene order. Batches run in parallel (rayon),
/// each on its own map caches.
pub fn evaluate_tallies(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<Vec<SceneTally>> {
    let windows: Vec<(usize, usize)> = set
        .scenes
        .iter()
        .map(|s| (s.history_steps, s.future_steps))
        .collect();
    let groups = batches(&windows, config.batch);
    let per_group: Vec<Result<Vec<(usize, SceneTally)>>> = groups
        .par_iter()
        .map_init(MapCaches::default, |caches, group| {
            let (batch, out) = rollout_group(policy, dynamics, set, group, device, caches)?;
            let scenes: Vec<&Scene> = group.iter().map(|&k| &set.scenes[k]).collect();
            let fde_step = (config.fde_horizon_s / batch.dt).round() as usize;
            let tallies = tally_rollout(&scenes, &out, fde_step, set.set.has_logs())?;
            Ok(group.iter().copied().zip(tallies).collect())
        })
        .collect();
    let mut tallies: Vec<Option<SceneTally>> = vec![None; set.scenes.len()];
    for group in per_group {
        for (k, t) in group? {
            tallies[k] = Some(t);
        }
    }
    Ok(tallies.into_iter().flatten().collect())
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
    }
}

/// Evaluates and summarises in one call.
pub fn evaluate(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<SetResult> {
    let tallies = evaluate_tallies(policy, dynamics, set, device, config)?;
    Ok(summarise(set.set, &tallies, config))
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
) -> Result<(SceneBatch, crate::sim::Rollout)> {
    let scenes: Vec<&Scene> = indices.iter().map(|&k| &set.scenes[k]).collect();
    let batch = SceneBatch::from_scenes(&scenes, device)?;
    let config = RolloutConfig {
        steps: None,
        early_termination: false,
    };
    let mut learned = policy.policy(&scenes, &batch);
    let out = if set.scenarios.is_empty() {
        rollout(&scenes, &batch, dynamics, &mut *learned, caches, &config)?
    } else {
        let scenarios: Vec<_> = indices.iter().map(|&k| &set.scenarios[k]).collect();
        let mut heroes = hero_scripts(&scenarios, &scenes);
        let mut driver = Scripted {
            policy: &mut *learned,
            script: &mut heroes,
            mask: batch.agent_hero.clone(),
        };
        rollout(&scenes, &batch, dynamics, &mut driver, caches, &config)?
    };
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
    let (_, out) = rollout_group(
        policy,
        dynamics,
        set,
        indices,
        device,
        &mut MapCaches::default(),
    )?;
    let scenes: Vec<&Scene> = indices.iter().map(|&k| &set.scenes[k]).collect();
    let [b, n, t1, _] = out.poses.dims();
    let poses: Vec<f32> = out
        .poses
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default();
    let present: Vec<bool> = out
        .present
        .into_data()
        .try_into_vec::<bool>()
        .unwrap_or_default();
    Ok((0..b)
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
        .collect())
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
