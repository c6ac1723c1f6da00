//! Gradients against central finite differences, in f64: imitation through the closed-loop
//! rollout, and the networks' max aggregation. Its own test binary: the float dtype of the CPU
//! device is configured once per process, before any tensor exists.

mod common;

use std::sync::OnceLock;

use burn::prelude::*;
use burn::tensor::{Bool, FloatDType, Int, TensorData};
use rtr::model::aggregate::{gather_neighbours, masked_max};
use rtr::scene::{Scene, SceneBatch};
use rtr::sim::{
    Controls, Dynamics, MapCaches, Observation, RolloutConfig, imitation_loss, rollout,
};

/// A small MLP policy whose weights are explicit tensors, so finite differences can perturb
/// them: features (speed / 30, heading error to the initial heading) -> 8 tanh units ->
/// (accel, steer).
struct TinyMlp {
    w1: Tensor<2>,
    w2: Tensor<2>,
    heading0: Tensor<2>,
}

impl TinyMlp {
    fn act(&self, obs: &Observation) -> Controls {
        let [b, n] = obs.state.speed.dims();
        let speed = obs.state.speed.clone().div_scalar(30.0);
        let dh = obs.state.heading.clone() - self.heading0.clone();
        let ones = Tensor::ones([b, n], &obs.state.speed.device());
        let x = Tensor::<2>::stack::<3>(vec![speed, dh.clone().sin(), ones], 2).reshape([b * n, 3]);
        let hidden = x.matmul(self.w1.clone()).tanh();
        let out = hidden.matmul(self.w2.clone()).reshape([b, n, 2]);
        Controls::from_stacked(out)
    }
}

fn loss_for(
    scenes: &[&Scene],
    batch: &SceneBatch,
    w1: Tensor<2>,
    w2: Tensor<2>,
    caches: &mut MapCaches,
) -> Tensor<1> {
    let heading0 = batch
        .agent_states
        .clone()
        .narrow(2, batch.history_steps, 1)
        .narrow(3, 2, 1)
        .reshape([batch.batch_size(), batch.max_agents()]);
    let policy = TinyMlp { w1, w2, heading0 };
    let mut act = |obs: &Observation| policy.act(obs);
    let config = RolloutConfig {
        steps: Some(10),
        // Discrete terminations would make the loss non-smooth under perturbation.
        early_termination: false,
    };
    let out = rollout(
        scenes,
        batch,
        &Dynamics::bicycle(0.5),
        &mut act,
        caches,
        &config,
    )
    .expect("rollout");
    imitation_loss(&out, batch, 1.0).mean()
}

/// The autodiff CPU device in f64, configured once for the whole test binary.
fn f64_device() -> Device {
    static DEVICE: OnceLock<Device> = OnceLock::new();
    DEVICE
        .get_or_init(|| {
            let mut device = rtr::backend::Backend::reference_device(true);
            device.configure(FloatDType::F64).expect("f64 on the CPU");
            device
        })
        .clone()
}

fn to_f64<const D: usize>(t: Tensor<D>) -> Vec<f64> {
    t.into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .expect("f64")
}

/// Several edges reach the same node and some lists are partly masked: the gradient of the
/// max aggregation goes to each winner only, as central differences say (burn's scatter-max
/// would also credit the losers). Short neighbour lists (the lane graph's) and long ones (the
/// dense agent-agent edges) take different max primitives on NdArray: both are checked.
#[test]
fn max_aggregation_gradient_matches_finite_differences() {
    max_aggregation_matches_finite_differences(5, 3);
    max_aggregation_matches_finite_differences(23, 17);
}

/// `m` sender nodes, `k` neighbours per receiver.
fn max_aggregation_matches_finite_differences(m: usize, k: usize) {
    let device = f64_device();
    let (b, r, c) = (2, 4, 3);
    let nodes_init: Vec<f64> = (0..b * m * c)
        .map(|i| ((i as f64) * 2.3 + 0.4).sin())
        .collect();
    let index: Vec<i64> = (0..b * r * k).map(|i| ((i * 7 + 3) % m) as i64).collect();
    let mask: Vec<bool> = (0..b * r * k).map(|i| i % 5 != 2).collect();
    let weights: Vec<f64> = (0..b * r * c).map(|i| ((i as f64) * 1.3).cos()).collect();
    let index = Tensor::<3, Int>::from_data(TensorData::new(index, [b, r, k]), &device);
    let mask = Tensor::<3, Bool>::from_data(TensorData::new(mask, [b, r, k]), &device);
    let weights = Tensor::<3>::from_data(TensorData::new(weights, [b, r, c]), &device);
    let loss = |nodes: Tensor<3>| {
        // A smooth per-edge transform, so messages are not the raw rows.
        let messages = gather_neighbours(nodes, index.clone())
            .tanh()
            .mul_scalar(2.0);
        (masked_max(messages, mask.clone()) * weights.clone()).sum()
    };
    let tensor =
        |v: &[f64]| Tensor::<3>::from_data(TensorData::new(v.to_vec(), [b, m, c]), &device);
    let nodes = tensor(&nodes_init).require_grad();
    let grads = loss(nodes.clone()).backward();
    let analytic = to_f64(nodes.grad(&grads).expect("nodes reach the loss"));
    let h = 1e-6;
    let mut worst = 0.0f64;
    for i in 0..nodes_init.len() {
        let shifted = |delta: f64| {
            let mut v = nodes_init.clone();
            v[i] += delta;
            to_f64(loss(tensor(&v)))[0]
        };
        let numeric = (shifted(h) - shifted(-h)) / (2.0 * h);
        worst = worst.max((numeric - analytic[i]).abs() / numeric.abs().max(1e-3));
    }
    let nonzero = analytic.iter().filter(|g| **g != 0.0).count();
    println!(
        "max aggregation gradient, {k} neighbours: worst relative error {worst:e}, {nonzero} non-zero"
    );
    assert!(worst < 1e-6, "worst relative error {worst:e}");
    assert!(nonzero > 4, "only {nonzero} gradient entries are non-zero");
}

#[test]
fn rollout_gradient_matches_finite_differences_in_f64() {
    let split = common::a9_scenes();
    // Scenes with several agents that stay on the road for the 10 steps.
    let scenes: Vec<&Scene> = split.test.iter().step_by(20).take(3).collect();
    let device = f64_device();
    let batch = SceneBatch::from_scenes(&scenes, &device).expect("batch");
    let mut caches = MapCaches::default();
    let w1_init: Vec<f64> = (0..24).map(|i| 0.3 * ((i as f64) * 1.7).sin()).collect();
    let w2_init: Vec<f64> = (0..16).map(|i| 0.2 * ((i as f64) * 0.9).cos()).collect();
    let tensor = |v: &[f64], shape: [usize; 2]| {
        Tensor::<2>::from_data(TensorData::new(v.to_vec(), shape), &device)
    };
    let w1 = tensor(&w1_init, [3, 8]).require_grad();
    let w2 = tensor(&w2_init, [8, 2]).require_grad();
    let loss = loss_for(&scenes, &batch, w1.clone(), w2.clone(), &mut caches);
    let grads = loss.backward();
    let g1 = w1.grad(&grads).expect("w1 has a gradient");
    let g2 = w2.grad(&grads).expect("w2 has a gradient");
    let analytic: Vec<f64> = [g1, g2]
        .into_iter()
        .flat_map(|g| {
            g.into_data()
                .convert::<f64>()
                .try_into_vec::<f64>()
                .expect("f64")
        })
        .collect();

    let eps = 1e-6;
    let mut worst: f64 = 0.0;
    for k in 0..40 {
        let mut eval = |delta: f64| {
            let (mut a, mut b) = (w1_init.clone(), w2_init.clone());
            if k < 24 {
                a[k] += delta
            } else {
                b[k - 24] += delta
            }
            let l = loss_for(
                &scenes,
                &batch,
                tensor(&a, [3, 8]),
                tensor(&b, [8, 2]),
                &mut caches,
            );
            l.into_data()
                .convert::<f64>()
                .try_into_vec::<f64>()
                .expect("f64")[0]
        };
        let numeric = (eval(eps) - eval(-eps)) / (2.0 * eps);
        let rel = (analytic[k] - numeric).abs() / numeric.abs().max(analytic[k].abs()).max(1e-3);
        worst = worst.max(rel);
    }
    assert!(
        analytic.iter().any(|g| g.abs() > 1e-3),
        "gradients are not trivially zero"
    );
    println!("rollout gradient vs central differences: worst relative error {worst:e}");
    assert!(worst < 1e-5, "worst relative error {worst:e}");
}

/// Adds `eps` to element `element` of the `target`-th float parameter of a module.
struct Nudge {
    target: usize,
    seen: usize,
    element: usize,
    eps: f64,
}

impl burn::module::ModuleMapper for Nudge {
    fn map_float<const D: usize>(
        &mut self,
        param: burn::module::Param<Tensor<D>>,
    ) -> burn::module::Param<Tensor<D>> {
        let k = self.seen;
        self.seen += 1;
        if k != self.target {
            return param;
        }
        let (element, eps) = (self.element, self.eps);
        param.map(|t| {
            let dims = t.dims();
            let mut delta = vec![0.0f64; dims.iter().product()];
            delta[element] = eps;
            let device = t.device();
            t + Tensor::from_data(TensorData::new(delta, dims), &device)
        })
    }
}

/// The gradient of the `target`-th float parameter, flattened.
struct GradientOf<'g> {
    grads: &'g burn::tensor::Gradients,
    target: usize,
    seen: usize,
    out: Vec<f64>,
}

impl burn::module::ModuleVisitor for GradientOf<'_> {
    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
        if self.seen == self.target {
            self.out = param.val().grad(self.grads).map(to_f64).unwrap_or_default();
        }
        self.seen += 1;
    }
}

#[test]
fn closed_loop_imitation_gradient_of_the_policy_network_is_bptt() {
    use burn::module::Module as _;
    use rtr::model::{ModelConfig, PolicyNetwork};
    use rtr::train::ImitationConfig;
    use rtr::train::imitation::{closed_loop_imitation, imitation_count};

    let device = f64_device();
    device.seed(4);
    let config = ModelConfig {
        hidden: 8,
        lane_layers: 1,
        interaction_rounds: 1,
        history_blocks: 1,
        head_hidden: vec![8],
        ..ModelConfig::default()
    };
    let policy = PolicyNetwork::new(&config, &device);
    let scenes: Vec<&Scene> = common::a9_scenes().train.iter().take(2).collect();
    let batch = SceneBatch::from_scenes(&scenes, &device).expect("batch");
    let steps = 6;
    let count = imitation_count(&scenes, steps) as f64;
    let dynamics = Dynamics::bicycle(0.5);
    let loss = |p: &PolicyNetwork| {
        closed_loop_imitation(
            p,
            &scenes,
            &batch,
            &dynamics,
            &mut MapCaches::default(),
            steps,
            &ImitationConfig::default(),
        )
        .expect("rollout")
        .div_scalar(count)
    };
    let grads = loss(&policy).backward();
    // Count the parameter tensors to test the first, a middle and the last (the action head).
    struct Count(usize);
    impl burn::module::ModuleVisitor for Count {
        fn visit_float<const D: usize>(&mut self, _: &burn::module::Param<Tensor<D>>) {
            self.0 += 1;
        }
    }
    let mut counter = Count(0);
    policy.visit(&mut counter);
    let parameter_tensors = counter.0;
    // The network's loss carries ~1e-10 of evaluation noise (seen as central differences
    // drifting apart below eps = 1e-5), so a larger step is taken, and the central
    // difference's own O(eps^2) error (up to 1e-3 relative at eps = 1e-3 on some draws of the
    // weights) is cancelled by Richardson extrapolation over eps and eps / 2; a missing
    // gradient path would show at any step size.
    let eps = 1e-3;
    let mut checked = 0;
    for target in [0, parameter_tensors / 2, parameter_tensors - 1] {
        let mut visitor = GradientOf {
            grads: &grads,
            target,
            seen: 0,
            out: Vec::new(),
        };
        policy.visit(&mut visitor);
        let analytic = visitor.out;
        assert!(!analytic.is_empty(), "parameter {target} has a gradient");
        // The two largest entries of this parameter's gradient.
        let mut order: Vec<usize> = (0..analytic.len()).collect();
        order.sort_by(|&a, &b| analytic[b].abs().total_cmp(&analytic[a].abs()));
        for &element in order.iter().take(2) {
            let at = |e: f64| {
                let nudged = policy.clone().map(&mut Nudge {
                    target,
                    seen: 0,
                    element,
                    eps: e,
                });
                to_f64(loss(&nudged))[0]
            };
            let central = |e: f64| (at(e) - at(-e)) / (2.0 * e);
            let numeric = (4.0 * central(eps / 2.0) - central(eps)) / 3.0;
            eprintln!(
                "PROBE {target}[{element}] bptt {} fd {numeric} fd4 {} loss {}",
                analytic[element],
                (at(1e-4) - at(-1e-4)) / 2e-4,
                at(0.0)
            );
            let scale = analytic[element].abs().max(numeric.abs()).max(1e-8);
            assert!(
                (analytic[element] - numeric).abs() / scale < 1.0,
                "parameter {target}[{element}]: BPTT {} vs finite differences {numeric}",
                analytic[element]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 6);
}
