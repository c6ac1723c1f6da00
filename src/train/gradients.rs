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

/// The weighted loss terms built on one autodiff graph, summed for one backward pass.
#[derive(Default)]
pub struct GraphLoss {
    total: Option<Tensor<1>>,
    /// Host value of the weighted sum.
    pub value: f64,
}

impl GraphLoss {
    /// Adds `weight * sum / count` and returns `sum / count` (the term as the curves show
    /// it), or `None` when the term has no count or no weight and so is left out.
    pub fn add(&mut self, sum: Tensor<1>, count: usize, weight: f64) -> Option<f64> {
        if count == 0 || weight == 0.0 {
            return None;
        }
        let mean = sum.div_scalar(count as f64);
        let host = mean.clone().into_scalar::<f64>();
        let weighted = mean.mul_scalar(weight);
        self.total = Some(match self.total.take() {
            Some(total) => total + weighted,
            None => weighted,
        });
        self.value += weight * host;
        Some(host)
    }
}

/// Gradients of a sum of losses, taken one graph at a time and added up.
///
/// The gradient is linear in the loss, so backpropagating each term's graph as soon as it is
/// built gives the gradient of the sum while only one graph is alive. Summing first and
/// differentiating once held a minibatch's closed-loop imitation and PPO graphs together:
/// 24 GB on an all-nominal RTR minibatch (the sweep's lambda 0, alpha 0 point), over this
/// machine's 23 GB. Sums differ from the one-pass gradient by float rounding only.
pub struct GraphwiseGradients<'m, P: Module, V: Module> {
    policy: &'m P,
    value: Option<&'m V>,
    policy_sum: GradientsAccumulator<P>,
    value_sum: GradientsAccumulator<V>,
}

impl<'m, P: Module, V: Module> GraphwiseGradients<'m, P, V> {
    /// Collects the gradients of `policy` and, when given, of `value`.
    pub fn new(policy: &'m P, value: Option<&'m V>) -> Self {
        Self {
            policy,
            value,
            policy_sum: GradientsAccumulator::new(),
            value_sum: GradientsAccumulator::new(),
        }
    }

    /// Backpropagates `loss` now (nothing when it holds no term).
    pub fn backward(&mut self, loss: GraphLoss) {
        let Some(total) = loss.total else {
            return;
        };
        let mut grads = total.backward();
        self.policy_sum.accumulate(
            self.policy,
            GradientsParams::from_module(&mut grads, self.policy),
        );
        if let Some(value) = self.value {
            self.value_sum
                .accumulate(value, GradientsParams::from_module(&mut grads, value));
        }
    }

    /// The summed gradients of the policy and of the value network (if it was given); empty
    /// where no loss was backpropagated.
    pub fn finish(mut self) -> (GradientsParams, Option<GradientsParams>) {
        let value = self.value.map(|_| self.value_sum.grads());
        (self.policy_sum.grads(), value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{Linear, LinearConfig};
    use burn::tensor::TensorData;

    fn weight_grad(grads: &GradientsParams, layer: &Linear) -> Vec<f32> {
        grads
            .get::<2>(layer.weight.id)
            .expect("weight grad")
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .expect("f32")
    }

    #[test]
    fn graph_by_graph_gradients_add_up_to_the_gradient_of_the_sum() {
        let device = crate::backend::Backend::reference_device(true);
        let policy: Linear = LinearConfig::new(3, 2).init(&device);
        let value: Linear = LinearConfig::new(3, 1).init(&device);
        let x = Tensor::<2>::from_data(TensorData::new(vec![1.0f32, -2.0, 3.0], [1, 3]), &device);
        // Two terms on separate graphs (the first reaches both networks) and one left out.
        let first = || {
            let p = policy.forward(x.clone()).powi_scalar(2).sum();
            p + value.forward(x.clone()).sum()
        };
        let second = || policy.forward(x.clone()).tanh().sum();
        let one_pass = first().div_scalar(4.0).mul_scalar(0.5) + second().div_scalar(2.0);
        let mut grads = one_pass.backward();
        let expected_policy = GradientsParams::from_module(&mut grads, &policy);
        let expected_value = GradientsParams::from_module(&mut grads, &value);

        let mut graphwise = GraphwiseGradients::new(&policy, Some(&value));
        let mut loss = GraphLoss::default();
        let shown = loss.add(first(), 4, 0.5).expect("weighted term");
        assert_eq!(
            loss.add(second(), 2, 0.0),
            None,
            "a zero weight leaves the term out"
        );
        assert_eq!(loss.add(second(), 0, 1.0), None, "so does a zero count");
        let first_value = first().into_scalar::<f64>();
        assert!((shown - first_value / 4.0).abs() < 1e-5);
        assert!((loss.value - 0.5 * first_value / 4.0).abs() < 1e-5);
        graphwise.backward(loss);
        let mut loss = GraphLoss::default();
        loss.add(second(), 2, 1.0);
        graphwise.backward(loss);
        graphwise.backward(GraphLoss::default());
        let (got_policy, got_value) = graphwise.finish();

        for (got, want) in [
            (
                weight_grad(&got_policy, &policy),
                weight_grad(&expected_policy, &policy),
            ),
            (
                weight_grad(&got_value.expect("value grads"), &value),
                weight_grad(&expected_value, &value),
            ),
        ] {
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() < 1e-5 * (1.0 + w.abs()), "{g} vs {w}");
            }
        }
    }

    #[test]
    fn no_graph_leaves_the_gradients_empty() {
        let device = crate::backend::Backend::reference_device(true);
        let policy: Linear = LinearConfig::new(3, 2).init(&device);
        let graphwise = GraphwiseGradients::<Linear, Linear>::new(&policy, None);
        let (policy_grads, value_grads) = graphwise.finish();
        assert!(policy_grads.get::<2>(policy.weight.id).is_none());
        assert!(value_grads.is_none());
    }

    #[test]
    fn clipping_scales_every_tensor_by_one_global_factor() {
        let device = crate::backend::Backend::reference_device(true);
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
