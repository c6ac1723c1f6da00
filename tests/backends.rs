//! The backend swap: the same closed-loop rollout, imitation loss and gradient, and the same
//! policy network output and gradient, on NdArray and on every other backend compiled in:
//! Flex (the default features) and Wgpu (`--features wgpu`; without a GPU it runs on Mesa's
//! software Vulkan: `apt-get install mesa-vulkan-drivers libvulkan1`). `.ci/backends` runs both.
#![cfg(any(feature = "flex", feature = "wgpu"))]

mod common;

use burn::prelude::*;
use burn::tensor::{Bool, Int, TensorData};
use rtr::backend::Backend;
use rtr::model::{AgentInput, LaneInput, ModelConfig};
use rtr::scene::{Scene, SceneBatch};
use rtr::sim::{
    Controls, Dynamics, MapCaches, Observation, RolloutConfig, imitation_loss, rollout,
};
use rtr::train::load_policy;

/// Loss, gradient of the first weight matrix, and final positions, on `backend`.
fn run(backend: Backend, scenes: &[&Scene]) -> (f64, Vec<f64>, Vec<f64>) {
    let device = backend.device(true).expect("backend compiled in");
    let batch = SceneBatch::from_scenes(scenes, &device).expect("batch");
    let w1_init: Vec<f32> = (0..24).map(|i| 0.3 * ((i as f32) * 1.7).sin()).collect();
    let w2_init: Vec<f32> = (0..16).map(|i| 0.2 * ((i as f32) * 0.9).cos()).collect();
    let w1 = Tensor::<2>::from_data(TensorData::new(w1_init, [3, 8]), &device).require_grad();
    let w2 = Tensor::<2>::from_data(TensorData::new(w2_init, [8, 2]), &device);
    let mut policy = |obs: &Observation| {
        let [b, n] = obs.state.speed.dims();
        let x = obs.kinematic_features().reshape([b * n, 3]);
        let out = x
            .matmul(w1.clone())
            .tanh()
            .matmul(w2.clone())
            .reshape([b, n, 2]);
        Controls::from_stacked(out)
    };
    let out = rollout(
        scenes,
        &batch,
        &Dynamics::bicycle(0.5),
        &mut policy,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
    )
    .expect("rollout");
    let loss = imitation_loss(&out, &batch, 1.0).mean();
    let grads = loss.backward();
    let to_vec = |d: TensorData| d.convert::<f64>().try_into_vec::<f64>().expect("floats");
    let grad = to_vec(w1.grad(&grads).expect("gradient").into_data());
    let last = out
        .poses
        .clone()
        .narrow(2, out.steps, 1)
        .detach()
        .into_data();
    (to_vec(loss.into_data())[0], grad, to_vec(last))
}

fn rollout_matches_ndarray(other: Backend) {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().step_by(25).take(4).collect();
    let (loss_a, grad_a, pos_a) = run(Backend::NdArray, &scenes);
    let (loss_b, grad_b, pos_b) = run(other, &scenes);
    println!("loss ndarray {loss_a}, {other} {loss_b}");
    assert!((loss_a - loss_b).abs() <= 1e-4 * loss_a.abs().max(1.0));
    let scale = grad_a.iter().fold(0f64, |m, g| m.max(g.abs())).max(1e-6);
    for (a, b) in grad_a.iter().zip(&grad_b) {
        assert!((a - b).abs() <= 1e-3 * scale, "gradient {a} vs {b}");
    }
    for (a, b) in pos_a.iter().zip(&pos_b) {
        assert!((a - b).abs() < 1e-2, "position {a} vs {b}");
    }
}

/// The policy's action means on real scenes (steering on the lane feed-forward) and the gradient of their sum with respect to the
/// agents' poses (through the relative-pose edges and every max aggregation, whose fastest form
/// differs by backend: `rtr::model::aggregate`).
fn policy_output_and_pose_gradient(backend: Backend, scenes: &[&Scene]) -> (Vec<f64>, Vec<f64>) {
    let device = backend.device(true).expect("backend compiled in");
    // The shipped small IL model (ModelConfig::small), loaded on each backend as `rtr eval`
    // loads a checkpoint.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/il/policy.bpk");
    let policy = load_policy(&path, &ModelConfig::small(), &device).expect("models/il loads");
    let batch = SceneBatch::from_scenes(scenes, &device).expect("batch");
    // With the lane steering feed-forward (no parameters, so the same weights load), whose
    // nearest-lane choice (argmin, gather) also has to agree.
    let config = ModelConfig {
        lane_steer_feedforward: true,
        ..policy.config().clone()
    };
    let lanes = LaneInput::from_batch(&batch, &config);
    // The current poses as a leaf, so the gradient reaches them through every edge.
    let mut frames = rtr::sim::logged_frames(&batch, batch.history_steps);
    let last = frames.len() - 1;
    let poses = frames[last].poses.clone().require_grad();
    frames[last].poses = poses.clone();
    let agents = AgentInput::from_frames(&batch, &frames, &config);
    let mean = policy
        .forward(&agents, &lanes, &policy.encode_lanes(&lanes))
        .mean;
    let grads = mean.clone().sum().backward();
    let to_vec = |d: TensorData| d.convert::<f64>().try_into_vec::<f64>().expect("floats");
    (
        to_vec(mean.into_data()),
        to_vec(poses.grad(&grads).expect("pose gradient").into_data()),
    )
}

fn policy_matches_ndarray(other: Backend) {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().step_by(20).take(3).collect();
    let (mean_a, grad_a) = policy_output_and_pose_gradient(Backend::NdArray, &scenes);
    let (mean_b, grad_b) = policy_output_and_pose_gradient(other, &scenes);
    let close = |a: &[f64], b: &[f64], what: &str| {
        let scale = a.iter().fold(0f64, |m, v| m.max(v.abs())).max(1e-6);
        assert!(scale > 1e-4, "{what} is all zero");
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-3 * scale, "{what}: {x} vs {y}");
        }
    };
    close(&mean_a, &mean_b, "action mean");
    close(&grad_a, &grad_b, "pose gradient");
}

#[cfg(feature = "flex")]
#[test]
fn flex_rollout_matches_ndarray() {
    rollout_matches_ndarray(Backend::Flex);
}

#[cfg(feature = "flex")]
#[test]
fn flex_policy_network_matches_ndarray() {
    policy_matches_ndarray(Backend::Flex);
}

#[cfg(feature = "wgpu")]
#[test]
fn wgpu_rollout_matches_ndarray() {
    rollout_matches_ndarray(Backend::Wgpu);
}

#[cfg(feature = "wgpu")]
#[test]
fn wgpu_policy_network_matches_ndarray() {
    policy_matches_ndarray(Backend::Wgpu);
}

/// Max aggregation output and the gradient reaching the senders, on `backend`: `k` neighbours
/// per receiver, some masked out, one receiver with none (which outputs 0 and gets no gradient).
fn max_aggregation(backend: Backend, k: usize) -> (Vec<f64>, Vec<f64>) {
    use rtr::model::aggregate::{gather_neighbours, masked_max};
    let device = backend.device(true).expect("backend compiled in");
    let (b, m, r, c) = (2, 2 * k + 1, 5, 6);
    let nodes: Vec<f32> = (0..b * m * c)
        .map(|i| ((i as f32) * 2.3 + 0.4).sin())
        .collect();
    let index: Vec<i64> = (0..b * r * k).map(|i| ((i * 7 + 3) % m) as i64).collect();
    let mask: Vec<bool> = (0..b * r * k).map(|i| i % 5 != 2 && i / k != 3).collect();
    let weights: Vec<f32> = (0..b * r * c).map(|i| ((i as f32) * 1.3).cos()).collect();
    let nodes = Tensor::<3>::from_data(TensorData::new(nodes, [b, m, c]), &device).require_grad();
    let index = Tensor::<3, Int>::from_data(TensorData::new(index, [b, r, k]), &device);
    let mask = Tensor::<3, Bool>::from_data(TensorData::new(mask, [b, r, k]), &device);
    let weights = Tensor::<3>::from_data(TensorData::new(weights, [b, r, c]), &device);
    let messages = gather_neighbours(nodes.clone(), index)
        .tanh()
        .mul_scalar(2.0);
    let out = masked_max(messages, mask);
    let grads = (out.clone() * weights).sum().backward();
    let to_vec = |d: TensorData| d.convert::<f64>().try_into_vec::<f64>().expect("floats");
    (
        to_vec(out.into_data()),
        to_vec(nodes.grad(&grads).expect("gradient").into_data()),
    )
}

/// Flex takes the max with its own fused kernel and backward (`rtr::model::fused_max`); NdArray
/// composes burn ops, checked against finite differences in `tests/gradients.rs`.
#[cfg(feature = "flex")]
#[test]
fn flex_fused_max_aggregation_matches_ndarray() {
    for k in [1, 3, 17] {
        let (out_a, grad_a) = max_aggregation(Backend::NdArray, k);
        let (out_b, grad_b) = max_aggregation(Backend::Flex, k);
        assert!(out_a.iter().any(|v| *v != 0.0) && grad_a.iter().any(|g| *g != 0.0));
        for (x, y) in out_a.iter().zip(&out_b).chain(grad_a.iter().zip(&grad_b)) {
            assert!((x - y).abs() <= 1e-6, "{k} neighbours: {x} vs {y}");
        }
    }
}
