//! The two imitation losses.
//!
//! - Closed-loop IL (paper eq. 3): the policy drives every controlled agent from the scene's
//!   initial state through the differentiable simulator; the Huber distance to the logged
//!   future is backpropagated through every step (BPTT).
//! - BC (open loop, SimNet-style): at every logged step the policy sees the logged history and
//!   is scored by the negative log-likelihood of the inverse-model action that reproduces the
//!   log.
//!
//! - [`logged_action_rms`]: how far the policy's mean is from the logged actions, as BC sees
//!   them; a warm start's sigma (`[init] std_from_logs`). [`logged_action_fit`] adds the
//!   policy's own sigma beside it.
//!
//! Both losses return sums; the trainer divides by counts known before the forward pass
//! ([`imitation_count`], [`BcLabels::count`]) so that losses split across devices add up.

use burn::prelude::*;
use burn::tensor::{Bool, TensorData};

use super::config::ImitationConfig;
use crate::error::Result;
use crate::model::{AgentInput, LaneInput, NetworkPolicy, PolicyNetwork};
use crate::scene::{AgentRole, Scene, SceneBatch};
use crate::sim::{
    ActionLimits, Dynamics, MapCaches, RolloutConfig, imitation_loss, inverse_actions,
    logged_frames, rollout,
};

/// Logged agent-steps of controlled agents over the first `steps` future steps: the number
/// closed-loop IL's sum is divided by (an agent terminated early keeps its weight).
pub fn imitation_count(scenes: &[&Scene], steps: usize) -> usize {
    scenes
        .iter()
        .map(|s| {
            let from = s.history_steps + 1;
            let to = (from + steps).min(s.steps());
            s.agents
                .iter()
                .filter(|a| a.role == AgentRole::Controlled)
                .map(|a| a.valid[from..to].iter().filter(|&&v| v).count())
                .sum::<usize>()
        })
        .sum()
}

/// Sum over logged agent-steps of the Huber distance of a closed-loop rollout of `policy`
/// (nominal scenes only: they have logs).
pub fn closed_loop_imitation(
    policy: &PolicyNetwork,
    scenes: &[&Scene],
    batch: &SceneBatch,
    dynamics: &Dynamics,
    caches: &mut MapCaches,
    steps: usize,
    config: &ImitationConfig,
) -> Result<Tensor<1>> {
    let mut driver = NetworkPolicy::new(policy, batch, config.action);
    let out = rollout(
        scenes,
        batch,
        dynamics,
        &mut driver,
        caches,
        &RolloutConfig {
            steps: Some(steps),
            early_termination: true,
        },
    )?;
    Ok(imitation_loss(&out, batch, config.huber_delta).sum)
}

/// Behaviour-cloning targets: the inverse-model raw actions of the controlled agents at the
/// first `steps` steps from the current one.
#[derive(Debug, Clone)]
pub struct BcLabels {
    /// Per step, `[B, N, 2]`.
    pub actions: Vec<Tensor<3>>,
    /// Per step, `[B, N]`: a label exists (three consecutive logged states).
    pub mask: Vec<Tensor<2, Bool>>,
    pub count: usize,
}

impl BcLabels {
    pub fn new(
        scenes: &[&Scene],
        n: usize,
        steps: usize,
        limits: &ActionLimits,
        device: &Device,
    ) -> Self {
        let b = scenes.len();
        let mut actions = vec![vec![0.0f32; b * n * 2]; steps];
        let mut mask = vec![vec![false; b * n]; steps];
        let mut count = 0;
        for (bi, scene) in scenes.iter().enumerate() {
            for (ai, agent) in scene.agents.iter().enumerate() {
                if agent.role != AgentRole::Controlled {
                    continue;
                }
                let inverse = inverse_actions(agent, scene.dt, limits);
                for t in 0..steps {
                    let k = scene.history_steps + t;
                    if k < inverse.valid.len() && inverse.valid[k] {
                        let slot = bi * n + ai;
                        actions[t][slot * 2] = inverse.raw_accel[k] as f32;
                        actions[t][slot * 2 + 1] = inverse.raw_steer[k] as f32;
                        mask[t][slot] = true;
                        count += 1;
                    }
                }
            }
        }
        Self {
            actions: actions
                .into_iter()
                .map(|a| Tensor::from_data(TensorData::new(a, [b, n, 2]), device))
                .collect(),
            mask: mask
                .into_iter()
                .map(|m| Tensor::from_data(TensorData::new(m, [b, n]), device))
                .collect(),
            count,
        }
    }
}

/// Sum over labelled agent-steps of -log pi(label | logged history).
pub fn behaviour_cloning(
    policy: &PolicyNetwork,
    batch: &SceneBatch,
    labels: &BcLabels,
) -> Tensor<1> {
    let config = policy.config();
    let lanes = LaneInput::from_batch(batch, config);
    let encoded = policy.encode_lanes(&lanes);
    let device = batch.agent_states.device();
    let mut total = Tensor::<1>::zeros([1], &device);
    for (t, (action, mask)) in labels.actions.iter().zip(&labels.mask).enumerate() {
        let frames = logged_frames(batch, batch.history_steps + t);
        let agents = AgentInput::from_frames(batch, &frames, config);
        let dist = policy.forward(&agents, &lanes, &encoded);
        let nll = dist.log_prob(action.clone()).neg() * mask.clone().float();
        total = total + nll.sum();
    }
    total
}

/// Root-mean-square difference between `policy`'s mean action and the inverse-model action of
/// the log, per control (m/s^2, rad), over every labelled agent-step of `scenes`, the policy
/// seeing the logged history as in BC: the maximum-likelihood sigma of a state-independent
/// Normal around the policy's mean. Scenes go in batches of `batch` with one window shape.
pub fn logged_action_rms(
    policy: &PolicyNetwork,
    scenes: &[&Scene],
    limits: &ActionLimits,
    batch: usize,
    device: &Device,
) -> Result<([f64; 2], usize)> {
    let fit = logged_action_fit(policy, scenes, limits, batch, device)?;
    Ok((fit.mean_error_rms, fit.count))
}

/// How well a policy's Normal describes the logged actions, per control (m/s^2, rad), over the
/// labelled agent-steps of the logs as BC sees them ([`logged_action_fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoggedActionFit {
    /// RMS of mean - logged action: the noise a calibrated sampler would add.
    pub mean_error_rms: [f64; 2],
    /// RMS of the policy's own sigma: the noise its samples do add.
    pub sigma_rms: [f64; 2],
    /// Labelled agent-steps measured.
    pub count: usize,
}

/// [`logged_action_rms`] together with the RMS of the policy's sigma over the same agent-steps:
/// where the second exceeds the first, the policy's samples scatter wider than its mean misses
/// the log, so data sampled from it is noisier than its mean-action driving.
pub fn logged_action_fit(
    policy: &PolicyNetwork,
    scenes: &[&Scene],
    limits: &ActionLimits,
    batch: usize,
    device: &Device,
) -> Result<LoggedActionFit> {
    let mut groups: Vec<Vec<&Scene>> = Vec::new();
    for &scene in scenes {
        let shape = |s: &Scene| (s.history_steps, s.future_steps);
        match groups
            .iter_mut()
            .find(|g| g.len() < batch.max(1) && shape(g[0]) == shape(scene))
        {
            Some(g) => g.push(scene),
            None => groups.push(vec![scene]),
        }
    }
    let (mut error_squares, mut sigma_squares, mut count) = ([0.0f64; 2], [0.0f64; 2], 0usize);
    for group in groups {
        let scene_batch = SceneBatch::from_scenes(&group, device)?;
        let n = scene_batch.agent_states.dims()[1];
        let labels = BcLabels::new(&group, n, group[0].future_steps, limits, device);
        let config = policy.config();
        let lanes = LaneInput::from_batch(&scene_batch, config);
        let encoded = policy.encode_lanes(&lanes);
        for (t, (action, mask)) in labels.actions.iter().zip(&labels.mask).enumerate() {
            let frames = logged_frames(&scene_batch, scene_batch.history_steps + t);
            let agents = AgentInput::from_frames(&scene_batch, &frames, config);
            let distribution = policy.forward(&agents, &lanes, &encoded);
            let weight = mask.clone().float().unsqueeze_dim::<3>(2);
            let error = (distribution.mean - action.clone()).powi_scalar(2);
            let variance = distribution.log_std.mul_scalar(2.0).exp();
            add_per_control(&mut error_squares, error * weight.clone());
            add_per_control(&mut sigma_squares, variance * weight);
        }
        count += labels.count;
    }
    if count == 0 {
        return Err(crate::error::Error::InvalidArgument(
            "no logged agent-steps with an inverse-model action to measure the policy's error on"
                .into(),
        ));
    }
    let rms = |squares: [f64; 2]| squares.map(|s| (s / count as f64).sqrt());
    Ok(LoggedActionFit {
        mean_error_rms: rms(error_squares),
        sigma_rms: rms(sigma_squares),
        count,
    })
}

/// Adds the sums over batch and agents of `[B, N, 2]` values to `sums`, per control.
fn add_per_control(sums: &mut [f64; 2], values: Tensor<3>) {
    let per_control: Vec<f32> = values
        .sum_dim(0)
        .sum_dim(1)
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default();
    for (k, v) in per_control.iter().take(2).enumerate() {
        sums[k] += *v as f64;
    }
}
