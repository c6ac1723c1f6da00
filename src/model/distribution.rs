//! The policy's action distribution: independent Normals over (acceleration, steering) per
//! agent (paper section 3.3), so the joint policy factorises over agents given the shared
//! context.

use std::f64::consts::{E, PI};

use burn::prelude::*;
use burn::tensor::{Distribution, TensorData};

/// A diagonal Normal over the two raw controls of every agent.
#[derive(Debug, Clone)]
pub struct ActionDistribution {
    /// `[B, N, 2]`: mean (m/s^2, rad), the deterministic action.
    pub mean: Tensor<3>,
    /// `[B, N, 2]`: log sigma.
    pub log_std: Tensor<3>,
}

impl ActionDistribution {
    /// `[B, N]`: log density of `action` (`[B, N, 2]`), summed over the two controls.
    pub fn log_prob(&self, action: Tensor<3>) -> Tensor<2> {
        let [b, n, _] = action.dims();
        let z = (action - self.mean.clone()) / self.log_std.clone().exp();
        (z.powi_scalar(2).mul_scalar(-0.5) - self.log_std.clone())
            .sub_scalar(0.5 * (2.0 * PI).ln())
            .sum_dim(2)
            .reshape([b, n])
    }

    /// `[B, N]`: log density of `action` counting only the controls marked in `explored`
    /// (acceleration, steering): the density of the explored controls when the others are
    /// taken at their mean, as PPO sees actions sampled that way (`ppo.explore_steering`).
    pub fn log_prob_of(&self, action: Tensor<3>, explored: [bool; 2]) -> Tensor<2> {
        if explored == [true, true] {
            return self.log_prob(action);
        }
        let [b, n, _] = action.dims();
        let device = action.device();
        let weight = Tensor::<3>::from_data(
            TensorData::new(explored.map(|e| f32::from(u8::from(e))).to_vec(), [1, 1, 2]),
            &device,
        );
        let z = (action - self.mean.clone()) / self.log_std.clone().exp();
        ((z.powi_scalar(2).mul_scalar(-0.5) - self.log_std.clone())
            .sub_scalar(0.5 * (2.0 * PI).ln())
            * weight)
            .sum_dim(2)
            .reshape([b, n])
    }

    /// `[B, N]`: differential entropy, summed over the two controls.
    pub fn entropy(&self) -> Tensor<2> {
        let [b, n, _] = self.mean.dims();
        self.log_std
            .clone()
            .add_scalar(0.5 * (2.0 * PI * E).ln())
            .sum_dim(2)
            .reshape([b, n])
    }

    /// A reparameterised sample, `mean + sigma * eps` with eps ~ N(0, 1) drawn on the mean's
    /// device (seed it with `device.seed`): gradients flow to mean and sigma.
    pub fn sample(&self) -> Tensor<3> {
        let noise = Tensor::random(
            self.mean.dims(),
            Distribution::Normal(0.0, 1.0),
            &self.mean.device(),
        );
        self.mean.clone() + self.log_std.clone().exp() * noise
    }

    /// `[B, N, 2]`: sigma.
    pub fn std(&self) -> Tensor<3> {
        self.log_std.clone().exp()
    }

    /// `[B, N]`: KL(self || other), summed over the two controls (closed form for Normals).
    pub fn kl(&self, other: &ActionDistribution) -> Tensor<2> {
        let [b, n, _] = self.mean.dims();
        let log_ratio = other.log_std.clone() - self.log_std.clone();
        let variance = self.log_std.clone().mul_scalar(2.0).exp();
        let other_variance = other.log_std.clone().mul_scalar(2.0).exp();
        let gap = (self.mean.clone() - other.mean.clone()).powi_scalar(2);
        (log_ratio + (variance + gap) / other_variance.mul_scalar(2.0))
            .sub_scalar(0.5)
            .sum_dim(2)
            .reshape([b, n])
    }

    /// This step's Normal given the agent's previous standardised exploration noise `z`
    /// (`[B, N, 2]`) when the noise of each control is an AR(1) process with correlation
    /// `rho` (acceleration, steering; `ppo.noise_correlation`):
    /// `N(mu + rho sigma z, (1 - rho^2) sigma^2)`, whose samples are `mu + sigma z'` with
    /// `z' = rho z + sqrt(1 - rho^2) eta`. With `z` read as part of the agent's state this is
    /// still one Normal per step, so PPO's ratios and log-probabilities keep their form;
    /// `rho = 0` is the distribution itself.
    pub fn following(&self, previous_noise: Tensor<3>, rho: [f64; 2]) -> Self {
        let device = self.mean.device();
        let per_control = |v: [f64; 2]| {
            Tensor::<3>::from_data(
                TensorData::new(vec![v[0] as f32, v[1] as f32], [1, 1, 2]),
                &device,
            )
        };
        let keep = rho.map(|r| 0.5 * (1.0 - r * r).ln());
        Self {
            mean: self.mean.clone() + self.std() * previous_noise * per_control(rho),
            log_std: self.log_std.clone() + per_control(keep),
        }
    }

    /// The same distribution cut from the autodiff graph (PPO's "old" policy).
    pub fn detach(&self) -> Self {
        Self {
            mean: self.mean.clone().detach(),
            log_std: self.log_std.clone().detach(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap()
    }

    #[test]
    fn log_prob_entropy_and_samples_match_the_normal() {
        let device = crate::backend::Backend::reference_device(false);
        let dist = ActionDistribution {
            mean: Tensor::from_data(TensorData::new(vec![1.0f32, -0.5], [1, 1, 2]), &device),
            log_std: Tensor::from_data(
                TensorData::new(vec![0.0f32, (0.1f32).ln()], [1, 1, 2]),
                &device,
            ),
        };
        // N(1, 1) at 2 and N(-0.5, 0.1) at -0.5.
        let at = Tensor::from_data(TensorData::new(vec![2.0f32, -0.5], [1, 1, 2]), &device);
        let acceleration = -0.5 - 0.5 * (2.0 * PI).ln();
        let expect = acceleration + (-(0.1f64).ln() - 0.5 * (2.0 * PI).ln());
        let got = values(dist.log_prob(at.clone()))[0] as f64;
        assert!((got - expect).abs() < 1e-5, "{got} vs {expect}");
        let both = values(dist.log_prob_of(at.clone(), [true, true]))[0] as f64;
        assert!((both - expect).abs() < 1e-5, "{both} vs {expect}");
        let first = values(dist.log_prob_of(at, [true, false]))[0] as f64;
        assert!(
            (first - acceleration).abs() < 1e-5,
            "{first} vs {acceleration}"
        );
        let entropy = values(dist.entropy())[0] as f64;
        let expect = (2.0 * PI * E).ln() + (0.1f64).ln();
        assert!((entropy - expect).abs() < 1e-5, "{entropy} vs {expect}");

        device.seed(3);
        let wide = ActionDistribution {
            mean: Tensor::zeros([1, 4000, 2], &device).add_scalar(0.3),
            log_std: Tensor::zeros([1, 4000, 2], &device).add_scalar((2.0f32).ln()),
        };
        let s = values(wide.sample());
        let mean = s.iter().map(|&v| v as f64).sum::<f64>() / s.len() as f64;
        let var = s.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / s.len() as f64;
        assert!((mean - 0.3).abs() < 0.08, "sample mean {mean}");
        assert!(
            (var.sqrt() - 2.0).abs() < 0.08,
            "sample sigma {}",
            var.sqrt()
        );
    }

    /// Stepping z' = rho z + sqrt(1 - rho^2) eta from z ~ N(0, 1) keeps z' ~ N(0, 1) with
    /// correlation rho to z, and the conditioned Normal's density at mu + sigma z' is that of
    /// eta, less ln sqrt(1 - rho^2) per control.
    #[test]
    fn following_the_previous_noise_is_an_ar1_step_of_unit_variance() {
        let device = crate::backend::Backend::reference_device(false);
        let (n, rho) = (100_000, [0.8, 0.8]);
        let normal = |seed: u64| {
            device.seed(seed);
            Tensor::<3>::random([1, n, 2], Distribution::Normal(0.0, 1.0), &device)
        };
        let dist = ActionDistribution {
            mean: Tensor::zeros([1, n, 2], &device).add_scalar(0.5),
            log_std: Tensor::zeros([1, n, 2], &device).add_scalar((2.0f32).ln()),
        };
        let (z, eta) = (normal(1), normal(2));
        let step = dist.following(z.clone(), rho);
        let action = step.mean.clone() + step.std() * eta.clone();
        let next = values((action.clone() - dist.mean.clone()) / dist.std());
        let z = values(z);
        let moment = |f: &dyn Fn(usize) -> f64| (0..2 * n).map(f).sum::<f64>() / (2 * n) as f64;
        let variance = moment(&|k| (next[k] as f64).powi(2));
        let correlation = moment(&|k| next[k] as f64 * z[k] as f64);
        assert!((variance - 1.0).abs() < 0.02, "variance {variance}");
        assert!(
            (correlation - rho[0]).abs() < 0.02,
            "correlation {correlation}"
        );

        let independent = dist.log_prob(dist.mean.clone() + dist.std() * eta);
        let shrink = 2.0 * 0.5 * (1.0 - rho[0] * rho[0]).ln();
        let gap = values(step.log_prob(action) - independent);
        assert!(
            gap.iter().all(|&g| (g as f64 + shrink).abs() < 1e-4),
            "{:?}",
            &gap[..4]
        );
        // rho = 0: the distribution itself; each control follows its own rho.
        let same = dist.following(Tensor::ones([1, n, 2], &device), [0.0, 0.0]);
        assert_eq!(values(same.mean), values(dist.mean.clone()));
        assert_eq!(values(same.log_std), values(dist.log_std.clone()));
        let steering_only = values(
            dist.following(Tensor::ones([1, n, 2], &device), [0.0, 0.6])
                .mean,
        );
        assert_eq!(&steering_only[..2], &[0.5, 0.5 + 0.6 * 2.0]);
    }

    #[test]
    fn kl_is_zero_for_equal_normals_and_matches_the_closed_form() {
        let device = crate::backend::Backend::reference_device(false);
        let normal = |mean: [f32; 2], sigma: [f32; 2]| ActionDistribution {
            mean: Tensor::from_data(TensorData::new(mean.to_vec(), [1, 1, 2]), &device),
            log_std: Tensor::from_data(
                TensorData::new(sigma.iter().map(|s| s.ln()).collect::<Vec<_>>(), [1, 1, 2]),
                &device,
            ),
        };
        let p = normal([1.0, 0.0], [0.5, 2.0]);
        assert!(values(p.kl(&p))[0].abs() < 1e-6);
        // KL(N(1, 0.5^2) || N(0, 1^2)) = ln(1 / 0.5) + (0.25 + 1) / 2 - 0.5; the second control
        // is equal in both.
        let q = normal([0.0, 0.0], [1.0, 2.0]);
        let want = (2.0f64).ln() + 1.25 / 2.0 - 0.5;
        assert!((values(p.kl(&q))[0] as f64 - want).abs() < 1e-5);
    }

    /// KL-R's penalty is log p(a) - log q(a) at the sampled action (`train::experience`): its
    /// mean is KL(p || q), and the score-function gradient PPO takes of it, E[d log p(a)/d mu *
    /// (log p(a) - log q(a))], is the KL's own gradient (mu_p - mu_q) / sigma_q^2 per control.
    /// The exact KL as the penalty would give that gradient zero: it does not depend on a.
    #[test]
    fn the_sampled_log_ratio_has_the_kl_as_mean_and_its_gradient_as_score_gradient() {
        let device = crate::backend::Backend::reference_device(false);
        let n = 200_000;
        let normal = |mean: [f32; 2], sigma: [f32; 2]| ActionDistribution {
            mean: Tensor::<3>::from_data(TensorData::new(mean.to_vec(), [1, 1, 2]), &device)
                .repeat_dim(1, n),
            log_std: Tensor::<3>::from_data(
                TensorData::new(sigma.iter().map(|s| s.ln()).collect::<Vec<_>>(), [1, 1, 2]),
                &device,
            )
            .repeat_dim(1, n),
        };
        let (mean_p, sigma_p) = ([0.5f32, 0.0], [1.0f32, 0.2]);
        let (mean_q, sigma_q) = ([0.0f32, 0.1], [1.5f32, 0.25]);
        let (p, q) = (normal(mean_p, sigma_p), normal(mean_q, sigma_q));
        device.seed(7);
        let actions = p.sample();
        let ratio = values(p.log_prob(actions.clone()) - q.log_prob(actions.clone()));
        let a = values(actions);
        let kl = values(p.kl(&q))[0] as f64;
        let mean_ratio = ratio.iter().map(|&r| r as f64).sum::<f64>() / n as f64;
        assert!(
            (mean_ratio - kl).abs() < 0.02 * (1.0 + kl),
            "{mean_ratio} vs {kl}"
        );
        for d in 0..2 {
            let (mu, sigma) = (mean_p[d] as f64, sigma_p[d] as f64);
            let score_gradient = (0..n)
                .map(|k| (a[2 * k + d] as f64 - mu) / (sigma * sigma) * ratio[k] as f64)
                .sum::<f64>()
                / n as f64;
            let want = (mu - mean_q[d] as f64) / (sigma_q[d] as f64).powi(2);
            assert!(
                (score_gradient - want).abs() < 0.05 * (1.0 + want.abs()),
                "control {d}: {score_gradient} vs {want}"
            );
        }
    }
}
