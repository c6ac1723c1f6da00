//! The policy's action distribution: independent Normals over (acceleration, steering) per
//! agent (paper section 3.3), so the joint policy factorises over agents given the shared
//! context.

use std::f64::consts::{E, PI};

use burn::prelude::*;
use burn::tensor::Distribution;

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
    use burn::tensor::TensorData;

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap()
    }

    #[test]
    fn log_prob_entropy_and_samples_match_the_normal() {
        #[allow(deprecated)]
        let device = Device::ndarray();
        let dist = ActionDistribution {
            mean: Tensor::from_data(TensorData::new(vec![1.0f32, -0.5], [1, 1, 2]), &device),
            log_std: Tensor::from_data(
                TensorData::new(vec![0.0f32, (0.1f32).ln()], [1, 1, 2]),
                &device,
            ),
        };
        // N(1, 1) at 2 and N(-0.5, 0.1) at -0.5.
        let at = Tensor::from_data(TensorData::new(vec![2.0f32, -0.5], [1, 1, 2]), &device);
        let expect = (-0.5 - 0.5 * (2.0 * PI).ln()) + (-(0.1f64).ln() - 0.5 * (2.0 * PI).ln());
        let got = values(dist.log_prob(at))[0] as f64;
        assert!((got - expect).abs() < 1e-5, "{got} vs {expect}");
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
}
