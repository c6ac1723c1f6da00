//! The PPO losses as tensor ops (paper appendix "Reinforcement Learning Loss").
//!
//! Factorized: every agent i has its own ratio r_i = pi(a_i | s) / pi_old(a_i | s), advantage
//! A_i and value target; the surrogate is summed over agents. Scene-level (the ablation): one
//! joint ratio prod_i r_i per scene and step (the sum of the agents' log-ratios), the scene's
//! summed reward and value. Both take their means over the agent-steps (scene-steps) that are
//! alive, so early-terminated steps contribute nothing.

use burn::prelude::*;
use burn::tensor::Bool;

use super::config::{PpoConfig, PpoVariant};
use super::experience::Experience;
use crate::model::{PolicyNetwork, ValueNetwork};

/// A loss summed over masked entries, with the count it should be divided by.
#[derive(Debug, Clone)]
pub struct MaskedSum {
    /// Scalar tensor (differentiable).
    pub sum: Tensor<1>,
    pub count: usize,
}

/// The clipped surrogate of some masked entries, and how far the policy has moved from the one
/// that collected them.
#[derive(Debug, Clone)]
pub struct Surrogate {
    pub loss: MaskedSum,
    /// Entries whose ratio lies outside the clip range.
    pub clipped: usize,
    /// Sum over the entries of `(r - 1) - ln r`, an unbiased and never negative estimate of
    /// KL(pi_old || pi) per entry from actions drawn by pi_old (Schulman's k3 estimator).
    pub approx_kl: f64,
}

/// Clipped surrogate `-min(r A, clip(r, 1 - eps, 1 + eps) A)` summed over `mask`, with
/// r = exp(new_log_prob - old_log_prob); `[B, N, T]` inputs (N = 1 for the scene-level
/// variant).
pub fn clipped_surrogate(
    new_log_prob: Tensor<3>,
    old_log_prob: Tensor<3>,
    advantages: Tensor<3>,
    mask: Tensor<3, Bool>,
    clip: f64,
) -> Surrogate {
    let weight = mask.clone().float();
    // Masked entries get log-ratio 0 so no exp can overflow there.
    let log_ratio = (new_log_prob - old_log_prob.detach()) * weight.clone();
    let ratio = log_ratio.clone().exp();
    let clipped = ratio.clone().clamp(1.0 - clip, 1.0 + clip);
    let unclipped_term = ratio.clone() * advantages.clone();
    let clipped_term = clipped * advantages;
    let surrogate = unclipped_term.clone().min_pair(clipped_term.clone());
    let clipped_count = ratio
        .sub_scalar(1.0)
        .abs()
        .greater_elem(clip)
        .bool_and(mask.clone())
        .int()
        .sum()
        .into_scalar::<i64>() as usize;
    let count = mask.int().sum().into_scalar::<i64>() as usize;
    let detached = log_ratio.detach();
    let approx_kl = (detached.clone().exp().sub_scalar(1.0) - detached)
        .sum()
        .into_scalar::<f64>();
    Surrogate {
        loss: MaskedSum {
            sum: (surrogate * weight).sum().neg(),
            count,
        },
        clipped: clipped_count,
        approx_kl,
    }
}

/// Bounds of the factor `ppo.target_kl` puts on the scheduled learning rate.
pub const LR_SCALE_RANGE: (f64, f64) = (1e-3, 10.0);

/// The next learning-rate factor of the adaptive schedule (rsl_rl's): / 1.5 when the KL
/// measured at an update exceeds twice the target, x 1.5 when it is below half of it, within
/// [`LR_SCALE_RANGE`].
pub fn adapt_lr_scale(scale: f64, kl: f64, target: f64) -> f64 {
    let next = if kl > 2.0 * target {
        scale / 1.5
    } else if kl < 0.5 * target {
        scale * 1.5
    } else {
        scale
    };
    next.clamp(LR_SCALE_RANGE.0, LR_SCALE_RANGE.1)
}

/// Squared error of `values` against `returns`, summed over `mask`.
pub fn value_loss(values: Tensor<3>, returns: Tensor<3>, mask: Tensor<3, Bool>) -> MaskedSum {
    let count = mask.clone().int().sum().into_scalar::<i64>() as usize;
    let error = (values - returns.detach()).powi_scalar(2) * mask.float();
    MaskedSum {
        sum: error.sum(),
        count,
    }
}

/// `[B, N, T]` -> `[B, 1, T]`: the sum over the agents in `mask` (joint log-probability or
/// scene value).
pub fn sum_over_agents(x: Tensor<3>, mask: Tensor<3, Bool>) -> Tensor<3> {
    (x * mask.float()).sum_dim(1)
}

/// The PPO terms of one collected part under the current (differentiated) parameters.
pub struct PpoTerms {
    pub policy: MaskedSum,
    pub value: MaskedSum,
    /// KL(pi || pi_ref) summed over alive agent-steps (KL-L).
    pub kl: Option<MaskedSum>,
    pub clipped: usize,
    /// [`Surrogate::approx_kl`] of the part.
    pub approx_kl: f64,
}

/// Affine standardisation of advantages (identity unless `ppo.normalize_advantages`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdvantageScale {
    pub mean: f64,
    pub std: f64,
}

impl AdvantageScale {
    pub const IDENTITY: Self = Self {
        mean: 0.0,
        std: 1.0,
    };

    /// The mean and standard deviation of `advantages` (the alive agent-steps of a minibatch);
    /// the identity for fewer than two.
    pub fn of(advantages: &[f32]) -> Self {
        if advantages.len() < 2 {
            return Self::IDENTITY;
        }
        let n = advantages.len() as f64;
        let mean = advantages.iter().map(|&a| a as f64).sum::<f64>() / n;
        let var = advantages
            .iter()
            .map(|&a| (a as f64 - mean).powi(2))
            .sum::<f64>()
            / n;
        Self {
            mean,
            std: var.sqrt(),
        }
    }

    /// The alive entries of `advantages` (`[B, N, T]`, `alive` its mask) on the host.
    pub fn alive_values(advantages: Tensor<3>, alive: Tensor<3, Bool>) -> Vec<f32> {
        let a: Vec<f32> = advantages
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .unwrap_or_default();
        let m: Vec<bool> = alive.into_data().try_into_vec().unwrap_or_default();
        a.iter()
            .zip(&m)
            .filter(|(_, m)| **m)
            .map(|(a, _)| *a)
            .collect()
    }
}

/// Re-evaluates the stored observations of `exp` with `policy` and `value` and forms the
/// variant's clipped surrogate, value loss and (for KL-L) the KL to the stored reference.
pub fn ppo_terms(
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    exp: &Experience,
    config: &PpoConfig,
    scale: AdvantageScale,
    with_kl: bool,
) -> PpoTerms {
    let lanes = &exp.lanes;
    let policy_lanes = policy.encode_lanes(lanes);
    let value_lanes = value.encode_lanes(lanes);
    let mut log_probs = Vec::with_capacity(exp.steps);
    let mut values = Vec::with_capacity(exp.steps);
    let mut kls = Vec::new();
    // One stored observation and action per simulated step.
    for (t, (agents, action)) in exp.observations.iter().zip(&exp.actions).enumerate() {
        let dist = exp.as_sampled(t, policy.forward(agents, lanes, &policy_lanes));
        log_probs.push(dist.log_prob_of(action.clone(), exp.explored));
        values.push(value.forward(agents, lanes, &value_lanes));
        if with_kl && let Some(reference) = exp.reference.get(t) {
            kls.push(dist.kl(reference));
        }
    }
    let new_log_prob = Tensor::stack::<3>(log_probs, 2);
    let values = Tensor::stack::<3>(values, 2);
    let standardise = |a: Tensor<3>| a.sub_scalar(scale.mean).div_scalar(scale.std.max(1e-8));
    let (surrogate, value_loss) = match config.variant {
        PpoVariant::Factorized => {
            let surrogate = clipped_surrogate(
                new_log_prob,
                exp.old_log_prob.clone(),
                standardise(exp.advantages.clone()),
                exp.alive.clone(),
                config.clip,
            );
            let value = value_loss(values, exp.returns.clone(), exp.alive.clone());
            (surrogate, value)
        }
        PpoVariant::SceneLevel => {
            let joint_new = sum_over_agents(new_log_prob, exp.alive.clone());
            let joint_old = sum_over_agents(exp.old_log_prob.clone(), exp.alive.clone());
            let surrogate = clipped_surrogate(
                joint_new,
                joint_old,
                standardise(exp.scene_advantages.clone()),
                exp.scene_alive.clone(),
                config.clip,
            );
            let scene_values = sum_over_agents(values, exp.alive.clone());
            let value = value_loss(
                scene_values,
                exp.scene_returns.clone(),
                exp.scene_alive.clone(),
            );
            (surrogate, value)
        }
    };
    let kl = (!kls.is_empty()).then(|| {
        let kl = Tensor::stack::<3>(kls, 2) * exp.alive.clone().float();
        MaskedSum {
            sum: kl.sum(),
            count: exp.stats.agent_steps,
        }
    });
    PpoTerms {
        policy: surrogate.loss,
        value: value_loss,
        kl,
        clipped: surrogate.clipped,
        approx_kl: surrogate.approx_kl,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn device() -> Device {
        crate::backend::Backend::reference_device(false)
    }

    fn t3(v: &[f32], shape: [usize; 3]) -> Tensor<3> {
        Tensor::from_data(TensorData::new(v.to_vec(), shape), &device())
    }

    fn mask(v: &[bool], shape: [usize; 3]) -> Tensor<3, Bool> {
        Tensor::from_data(TensorData::new(v.to_vec(), shape), &device())
    }

    #[test]
    fn factorized_surrogate_matches_a_hand_computed_example() {
        // One scene, three agents, one step; the third agent is terminated (masked).
        // Agent 0: r = e^0.1 = 1.105 (inside the clip), A = 2 -> min(2.210, 2.210) = 2.210.
        // Agent 1: r = e^0.5 = 1.649 (clipped to 1.2), A = 1 -> min(1.649, 1.2) = 1.2.
        let new = t3(&[0.1, 0.5, 9.0], [1, 3, 1]);
        let old = t3(&[0.0, 0.0, 0.0], [1, 3, 1]);
        let adv = t3(&[2.0, 1.0, 100.0], [1, 3, 1]);
        let alive = mask(&[true, true, false], [1, 3, 1]);
        let s = clipped_surrogate(new, old, adv, alive, 0.2);
        let want = -(2.0 * 0.1f64.exp() + 1.2);
        let got = s.loss.sum.into_scalar::<f64>();
        assert!((got - want).abs() < 1e-5, "{got} vs {want}");
        assert_eq!((s.loss.count, s.clipped), (2, 1));
        // k3 over the two live entries only: (e^x - 1) - x at x = 0.1 and 0.5.
        let k3 = |x: f64| x.exp() - 1.0 - x;
        assert!(
            (s.approx_kl - (k3(0.1) + k3(0.5))).abs() < 1e-5,
            "{}",
            s.approx_kl
        );

        // Negative advantage: r = e^-0.5 = 0.607 clipped to 0.8; min(-0.607, -0.8) = -0.8.
        let s = clipped_surrogate(
            t3(&[-0.5], [1, 1, 1]),
            t3(&[0.0], [1, 1, 1]),
            t3(&[-1.0], [1, 1, 1]),
            mask(&[true], [1, 1, 1]),
            0.2,
        );
        assert!((s.loss.sum.into_scalar::<f64>() - 0.8).abs() < 1e-6);
    }

    /// Samples of N(mu_old, sigma) scored under N(mu_new, sigma): the k3 estimate averages to
    /// the closed-form KL (mu_new - mu_old)^2 / (2 sigma^2).
    #[test]
    fn approx_kl_estimates_the_kl_to_the_collecting_policy() {
        let (n, sigma, shift) = (200_000, 0.5f64, 0.3f64);
        let mut rng = 5u64;
        let draws: Vec<f64> = (0..n)
            .map(|_| {
                let u1 = 1.0 - crate::test_rng::uniform(&mut rng, 0.0, 1.0);
                let u2 = crate::test_rng::uniform(&mut rng, 0.0, 1.0);
                sigma * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            })
            .collect();
        let log_density = |x: f64, mu: f64| -(x - mu).powi(2) / (2.0 * sigma * sigma);
        let old: Vec<f32> = draws.iter().map(|&x| log_density(x, 0.0) as f32).collect();
        let new: Vec<f32> = draws
            .iter()
            .map(|&x| log_density(x, shift) as f32)
            .collect();
        let s = clipped_surrogate(
            t3(&new, [1, n, 1]),
            t3(&old, [1, n, 1]),
            Tensor::zeros([1, n, 1], &device()),
            mask(&vec![true; n], [1, n, 1]),
            0.2,
        );
        let want = shift * shift / (2.0 * sigma * sigma);
        let got = s.approx_kl / n as f64;
        assert!((got - want).abs() < 0.03 * want, "{got} vs {want}");
    }

    #[test]
    fn the_adaptive_rate_moves_only_outside_the_band_and_stays_bounded() {
        let target = 0.01;
        assert_eq!(adapt_lr_scale(1.0, 0.03, target), 1.0 / 1.5);
        assert_eq!(adapt_lr_scale(1.0, 0.001, target), 1.5);
        assert_eq!(adapt_lr_scale(1.0, 0.01, target), 1.0);
        assert_eq!(adapt_lr_scale(1.0, 0.019, target), 1.0);
        let mut scale = 1.0;
        for _ in 0..100 {
            scale = adapt_lr_scale(scale, 1.0, target);
        }
        assert_eq!(scale, LR_SCALE_RANGE.0);
        for _ in 0..100 {
            scale = adapt_lr_scale(scale, 0.0, target);
        }
        assert_eq!(scale, LR_SCALE_RANGE.1);
    }

    #[test]
    fn scene_level_ratio_is_the_product_of_the_agent_ratios() {
        let logp = t3(&[0.1, 0.2, 7.0], [1, 3, 1]);
        let alive = mask(&[true, true, false], [1, 3, 1]);
        let joint = sum_over_agents(logp, alive).into_scalar::<f64>();
        assert!((joint - 0.3).abs() < 1e-6);
    }

    #[test]
    fn masked_steps_get_no_gradient() {
        let device = device().autodiff();
        let new = Tensor::<3>::from_data(TensorData::new(vec![0.1f32, 0.3], [1, 1, 2]), &device)
            .require_grad();
        let old = Tensor::<3>::zeros([1, 1, 2], &device);
        let adv = Tensor::<3>::ones([1, 1, 2], &device);
        let alive =
            Tensor::<3, Bool>::from_data(TensorData::new(vec![true, false], [1, 1, 2]), &device);
        let s = clipped_surrogate(new.clone(), old, adv, alive, 0.2);
        let grads = s.loss.sum.backward();
        let g: Vec<f32> = new
            .grad(&grads)
            .expect("gradient")
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .expect("f32");
        // d(-r A)/d logp = -r at the live step; exactly 0 at the terminated one.
        assert!((g[0] + 0.1f32.exp()).abs() < 1e-5, "{g:?}");
        assert_eq!(g[1], 0.0);
    }
}
