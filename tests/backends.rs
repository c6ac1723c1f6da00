//! The backend swap: the same closed-loop rollout, imitation loss and gradient on NdArray and
//! on a second backend must agree. Needs that backend compiled in:
//! `cargo test --features flex --test backends` (or `--features wgpu`; without a GPU, wgpu
//! runs on Mesa's software Vulkan: `apt-get install mesa-vulkan-drivers libvulkan1`).
#![cfg(any(feature = "flex", feature = "wgpu"))]

mod common;

use burn::prelude::*;
use burn::tensor::TensorData;
use rtr::backend::Backend;
use rtr::scene::{Scene, SceneBatch};
use rtr::sim::bench::agent_features;
use rtr::sim::{
    Controls, Dynamics, MapCaches, Observation, RolloutConfig, imitation_loss, rollout,
};

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
        let x = agent_features(obs).reshape([b * n, 3]);
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

#[test]
fn second_backend_matches_ndarray() {
    let other = if cfg!(feature = "flex") {
        Backend::Flex
    } else {
        Backend::Wgpu
    };
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
