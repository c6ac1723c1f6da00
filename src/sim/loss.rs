//! The imitation distance D(tau_E, tau) = sum_t d(s_E_t, s_t): a Huber penalty on the gap
//! between simulated and logged box-centre positions, summed over the agent-steps where the
//! agent is simulated and logged. Tensor ops throughout, so its gradient reaches the policy
//! through every step of the rollout.

use burn::prelude::*;

use super::rollout::Rollout;
use crate::scene::SceneBatch;

/// Elementwise Huber: 0.5 d^2 for |d| <= delta, delta (|d| - 0.5 delta) beyond.
pub fn huber(d: Tensor<4>, delta: f64) -> Tensor<4> {
    let abs = d.clone().abs();
    let quadratic = d.powi_scalar(2).mul_scalar(0.5);
    let linear = abs.clone().sub_scalar(0.5 * delta).mul_scalar(delta);
    quadratic.mask_where(abs.greater_elem(delta), linear)
}

/// Imitation loss of a rollout against the batch's logged future.
#[derive(Debug, Clone)]
pub struct ImitationLoss {
    /// Sum over valid agent-steps of the Huber distance of x and y (scalar tensor).
    pub sum: Tensor<1>,
    /// Number of agent-steps in the sum.
    pub count: usize,
}

impl ImitationLoss {
    /// Mean per valid agent-step (0 when there are none).
    pub fn mean(&self) -> Tensor<1> {
        self.sum.clone().div_scalar(self.count.max(1) as f64)
    }
}

/// Huber distance (threshold `delta`, m) between simulated and logged centre positions over
/// steps 1..=T of the rollout.
pub fn imitation_loss(rollout: &Rollout, batch: &SceneBatch, delta: f64) -> ImitationLoss {
    let [b, n, t_total, _] = batch.agent_states.dims();
    let h = batch.history_steps;
    let steps = rollout.steps.min(t_total - 1 - h);
    let logged = batch
        .agent_states
        .clone()
        .narrow(2, h + 1, steps)
        .narrow(3, 0, 2);
    let simulated = rollout.poses.clone().narrow(2, 1, steps).narrow(3, 0, 2);
    let valid = batch
        .agent_valid
        .clone()
        .narrow(2, h + 1, steps)
        .bool_and(rollout.simulated.clone().narrow(2, 1, steps));
    let weight = valid.clone().float().reshape([b, n, steps, 1]);
    let per_coordinate = huber(simulated - logged, delta) * weight;
    let count = valid.int().sum().into_scalar::<i64>() as usize;
    ImitationLoss {
        sum: per_coordinate.sum(),
        count,
    }
}
