//! The two imitation losses.
//!
//! - Closed-loop IL (paper eq. 3): the policy drives every controlled agent from the scene's
//!   initial state through the differentiable simulator; the Huber distance to the logged
//!   future is backpropagated through every step (BPTT).
//! - BC (open loop, SimNet-style): at every logged step the policy sees the logged history and
//!   is scored by the negative log-likelihood of the inverse-model action that reproduces the
//!   log.
//!
//! Both return sums; the trainer divides by counts known before the forward pass
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
