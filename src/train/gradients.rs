//! Gradient bookkeeping burn leaves to the caller: the global L2 norm of a network's gradient,
//! clipping to it (PyTorch's `clip_grad_norm_`, which the paper's "grad clip norm 1.0" means;
//! burn's own `GradientClipping::Norm` clips each parameter tensor on its own), and summing
//! gradients computed on several devices.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{GradientsAccumulator, GradientsParams};
use burn::prelude::*;

struct SquaredNorm<'g> {
    grads: &'g GradientsParams,
    sum: f64,
}

impl ModuleVisitor for SquaredNorm<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(param.id) {
            self.sum += g.powi_scalar(2).sum().into_scalar::<f64>();
        }
    }
}

struct Scale<'g> {
    grads: &'g mut GradientsParams,
    factor: f64,
}

impl ModuleVisitor for Scale<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(param.id) {
            self.grads.register(param.id, g.mul_scalar(self.factor));
        }
    }
}

/// The L2 norm of all of `module`'s gradients together (NaN or inf if any entry is).
pub fn global_norm<M: Module>(module: &M, grads: &GradientsParams) -> f64 {
    let mut visitor = SquaredNorm { grads, sum: 0.0 };
    module.visit(&mut visitor);
    visitor.sum.sqrt()
}

/// Scales the gradients so that their global norm is at most `max_norm`; returns the norm
/// before clipping.
pub fn clip_global_norm<M: Module>(module: &M, grads: &mut GradientsParams, max_norm: f64) -> f64 {
    let norm = global_norm(module, grads);
    if norm.is_finite() && norm > max_norm {
        let mut visitor = Scale {
            grads,
            factor: max_norm / norm,
        };
        module.visit(&mut visitor);
    }
    norm
}

/// Sums gradients computed on several devices onto `device` (data parallelism: each device
/// computed its share of one minibatch's loss).
pub fn sum_on_device<M: Module>(
    module: &M,
    parts: Vec<GradientsParams>,
    device: &Device,
) -> GradientsParams {
    let mut accumulator = GradientsAccumulator::<M>::new();
    for grads in parts {
        accumulator.accumulate(module, grads.to_device(device, module));
    }
    accumulator.grads()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{Linear, LinearConfig};
    use burn::tensor::TensorData;

    #[test]
    fn clipping_scales_every_tensor_by_one_global_factor() {
        #[allow(deprecated)]
        let device = Device::ndarray().autodiff();
        let layer: Linear = LinearConfig::new(3, 2).init(&device);
        let x = Tensor::<2>::from_data(TensorData::new(vec![1.0f32, -2.0, 3.0], [1, 3]), &device);
        let loss = layer.forward(x).sum().mul_scalar(10.0);
        let mut grads = GradientsParams::from_grads(loss.backward(), &layer);
        let weight_before = grads.get::<2>(layer.weight.id).expect("weight grad");
        // d/dW of 10 sum(W x + b) = 10 x per output, d/db = 10: norm^2 = 2 * 100 * 14 + 2 * 100.
        let expected = (2.0 * 100.0 * 14.0 + 200.0f64).sqrt();
        let norm = clip_global_norm(&layer, &mut grads, 1.0);
        assert!((norm - expected).abs() < 1e-3, "{norm} vs {expected}");
        assert!((global_norm(&layer, &grads) - 1.0).abs() < 1e-5);
        let after = grads.get::<2>(layer.weight.id).expect("weight grad");
        let ratio: Vec<f32> = (after / weight_before)
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .expect("f32");
        assert!(
            ratio
                .iter()
                .all(|r| (*r as f64 - 1.0 / expected).abs() < 1e-6)
        );
    }
}
