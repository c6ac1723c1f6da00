//! The policy and value networks on real A9 scenes: viewpoint invariance, permutation
//! equivariance, padding, gradients to every parameter, and closed-loop driving.

mod common;

use std::sync::Arc;

use burn::module::{Module, ModuleVisitor, Param};
use burn::prelude::*;
use burn::tensor::TensorData;
use rtr::map::{LaneGraph, Map, straight};
use rtr::model::{
    ActionMode, AgentInput, LaneInput, ModelConfig, NetworkPolicy, PolicyNetwork, ValueNetwork,
};
use rtr::scene::synthetic_scene;
use rtr::scene::{Scene, SceneBatch};
use rtr::sim::{Dynamics, MapCaches, RolloutConfig, imitation_loss, logged_frames, rollout};

fn device(autodiff: bool) -> Device {
    let device = rtr::backend::Backend::reference_device(false);
    if autodiff { device.autodiff() } else { device }
}

fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("floats")
}

/// Policy means and log sigmas, and values, for the batch's current step.
struct Outputs {
    mean: Vec<f32>,
    log_std: Vec<f32>,
    value: Vec<f32>,
}

fn outputs(policy: &PolicyNetwork, value: &ValueNetwork, batch: &SceneBatch) -> Outputs {
    let config = policy.config();
    let lanes = LaneInput::from_batch(batch, config);
    let frames = logged_frames(batch, batch.history_steps);
    let agents = AgentInput::from_frames(batch, &frames, config);
    let dist = policy.forward(&agents, &lanes, &policy.encode_lanes(&lanes));
    let v = value.forward(&agents, &lanes, &value.encode_lanes(&lanes));
    Outputs {
        mean: values(dist.mean),
        log_std: values(dist.log_std),
        value: values(v),
    }
}

fn scene_outputs(
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    scene: &Scene,
    device: &Device,
) -> Outputs {
    let batch = SceneBatch::from_scenes(&[scene], device).expect("batch");
    outputs(policy, value, &batch)
}

fn networks(device: &Device, seed: u64) -> (PolicyNetwork, ValueNetwork) {
    device.seed(seed);
    let config = ModelConfig::small();
    (
        PolicyNetwork::new(&config, device),
        ValueNetwork::new(&config, device),
    )
}

fn test_scenes(count: usize) -> Vec<&'static Scene> {
    common::a9_scenes()
        .test
        .iter()
        .step_by(17)
        .take(count)
        .collect()
}

fn max_difference(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Rotates by `angle` about the origin, then translates, every agent state and lane pose.
fn move_batch(batch: &SceneBatch, angle: f32, shift: [f32; 2]) -> SceneBatch {
    let (c, s) = (angle.cos(), angle.sin());
    let turn = |x: Tensor<3>, y: Tensor<3>, h: Tensor<3>| {
        let nx = x.clone().mul_scalar(c) - y.clone().mul_scalar(s);
        let ny = x.mul_scalar(s) + y.mul_scalar(c);
        (
            nx.add_scalar(shift[0]),
            ny.add_scalar(shift[1]),
            h.add_scalar(angle),
        )
    };
    let mut moved = batch.clone();
    let [b, a, t, f] = batch.agent_states.dims();
    let states = batch.agent_states.clone().reshape([b, a * t, f]);
    let part = |k: usize| states.clone().narrow(2, k, 1);
    let (x, y, h) = turn(part(0), part(1), part(2));
    let rest = states.clone().narrow(2, 3, f - 3);
    // Absent entries stay zero, as the batch builder leaves them.
    let valid = batch.agent_valid.clone().reshape([b, a * t, 1]).float();
    moved.agent_states =
        Tensor::cat(vec![Tensor::cat(vec![x, y, h], 2) * valid, rest], 2).reshape([b, a, t, f]);
    let lanes = batch.lane_poses.clone();
    let lp = |k: usize| lanes.clone().narrow(2, k, 1);
    let (x, y, h) = turn(lp(0), lp(1), lp(2));
    moved.lane_poses = Tensor::cat(vec![x, y, h], 2);
    moved
}

#[test]
fn rotating_and_translating_the_scene_changes_no_action() {
    let device = device(false);
    let (policy, value) = networks(&device, 11);
    let scenes = test_scenes(3);
    let batch = SceneBatch::from_scenes(&scenes, &device).expect("batch");
    let base = outputs(&policy, &value, &batch);
    let moved = outputs(&policy, &value, &move_batch(&batch, 2.1, [-350.0, 125.0]));
    let (dm, dv) = (
        max_difference(&base.mean, &moved.mean),
        max_difference(&base.value, &moved.value),
    );
    println!("viewpoint change: max |d mean| {dm:e}, max |d value| {dv:e}");
    assert!(dm <= 1e-4, "action means moved by {dm}");
    assert!(dv <= 1e-4, "values moved by {dv}");
    assert!(
        base.mean.iter().any(|m| m.abs() > 1e-3),
        "the policy outputs something"
    );
}

#[test]
fn permuting_agents_permutes_outputs() {
    let device = device(false);
    let (policy, value) = networks(&device, 12);
    let scene = test_scenes(1)[0];
    let n = scene.agents.len();
    assert!(n >= 4, "scene has {n} agents");
    // order[i] = original index of the agent at position i.
    let mut order: Vec<usize> = (0..n).rev().collect();
    order.rotate_left(n / 3);
    let mut permuted = scene.clone();
    permuted.agents = order.iter().map(|&i| scene.agents[i].clone()).collect();

    let (base, perm) = (
        scene_outputs(&policy, &value, scene, &device),
        scene_outputs(&policy, &value, &permuted, &device),
    );
    let mut worst = 0.0f32;
    for (i, &j) in order.iter().enumerate() {
        for c in 0..2 {
            worst = worst.max((perm.mean[i * 2 + c] - base.mean[j * 2 + c]).abs());
            worst = worst.max((perm.log_std[i * 2 + c] - base.log_std[j * 2 + c]).abs());
        }
        worst = worst.max((perm.value[i] - base.value[j]).abs());
    }
    println!("agent permutation: max output difference {worst:e}");
    assert!(worst < 1e-5, "permuted outputs differ by {worst}");
}

/// The same lane graph with its nodes in another order (neighbour lists remapped).
fn permuted_graph(graph: &LaneGraph, order: &[usize]) -> LaneGraph {
    let mut position = vec![0; order.len()];
    for (new, &old) in order.iter().enumerate() {
        position[old] = new;
    }
    let remap = |lists: &Vec<Vec<usize>>| -> Vec<Vec<usize>> {
        order
            .iter()
            .map(|&old| lists[old].iter().rev().map(|&j| position[j]).collect())
            .collect()
    };
    LaneGraph {
        node_length: graph.node_length,
        nodes: order.iter().map(|&old| graph.nodes[old].clone()).collect(),
        successors: remap(&graph.successors),
        predecessors: remap(&graph.predecessors),
        left: remap(&graph.left),
        right: remap(&graph.right),
        lane_nodes: graph.lane_nodes.clone(),
    }
}

#[test]
fn permuting_lane_nodes_changes_nothing() {
    let device = device(false);
    let (policy, value) = networks(&device, 13);
    let scene = test_scenes(1)[0];
    let l = scene.lane_graph.nodes.len();
    let mut order: Vec<usize> = (0..l).rev().collect();
    order.rotate_left(l / 3);
    let mut permuted = scene.clone();
    permuted.lane_graph = Arc::new(permuted_graph(&scene.lane_graph, &order));
    let (base, perm) = (
        scene_outputs(&policy, &value, scene, &device),
        scene_outputs(&policy, &value, &permuted, &device),
    );
    let worst = max_difference(&base.mean, &perm.mean)
        .max(max_difference(&base.log_std, &perm.log_std))
        .max(max_difference(&base.value, &perm.value));
    println!("lane-node permutation: max output difference {worst:e}");
    assert!(worst < 1e-5, "lane order changed outputs by {worst}");
}

/// Bigger scenes (more agents, a longer road with more lane nodes) with the A9 window length.
fn big_scenes(like: &Scene) -> Vec<Scene> {
    let od = straight(4, 3.5, 900.0).expect("straight road");
    let map = Arc::new(Map::from_opendrive(&od, "straight").expect("map"));
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    assert!(graph.nodes.len() > like.lane_graph.nodes.len());
    (0..2)
        .map(|seed| {
            synthetic_scene(
                &map,
                &graph,
                like.agents.len() + 9,
                seed,
                like.history_steps,
                like.future_steps,
            )
        })
        .collect()
}

#[test]
fn padding_changes_nothing_and_padded_agents_get_no_gradient() {
    let device = device(true);
    let (policy, value) = networks(&device, 14);
    let scene = test_scenes(1)[0];
    let big = big_scenes(scene);
    let alone = scene_outputs(&policy, &value, scene, &device);
    let n = scene.agents.len();
    let mut batch = SceneBatch::from_scenes(&[&big[0], scene, &big[1]], &device).unwrap();
    let padded = outputs(&policy, &value, &batch);
    let width = batch.max_agents();
    assert!(width > n);
    let slice = |v: &[f32], per: usize| v[width * per..(width + n) * per].to_vec();
    let worst = max_difference(&alone.mean, &slice(&padded.mean, 2))
        .max(max_difference(&alone.log_std, &slice(&padded.log_std, 2)))
        .max(max_difference(&alone.value, &slice(&padded.value, 1)));
    println!("padding: max output difference {worst:e}");
    assert!(worst < 1e-5, "padding changed outputs by {worst}");

    // Junk in the padding rows changes nothing real...
    let [b, a, t, f] = batch.agent_states.dims();
    let mut junk = vec![0.0f32; b * a * t * f];
    for agent in n..a {
        for k in 0..t * f {
            junk[((a + agent) * t) * f + k] = 1e3 * ((agent * 31 + k) as f32).sin();
        }
    }
    batch.agent_states = batch.agent_states.clone()
        + Tensor::from_data(TensorData::new(junk, [b, a, t, f]), &device);
    let junked = outputs(&policy, &value, &batch);
    assert_eq!(junked.mean, padded.mean, "padding rows leaked into outputs");
    assert_eq!(
        junked.value, padded.value,
        "padding rows leaked into values"
    );

    // ...and a loss over every output, padding included, gives the padding rows no gradient.
    let states = batch.agent_states.clone().require_grad();
    batch.agent_states = states.clone();
    let config = policy.config();
    let lanes = LaneInput::from_batch(&batch, config);
    let frames = logged_frames(&batch, batch.history_steps);
    let agents = AgentInput::from_frames(&batch, &frames, config);
    let dist = policy.forward(&agents, &lanes, &policy.encode_lanes(&lanes));
    let v = value.forward(&agents, &lanes, &value.encode_lanes(&lanes));
    let grads = (dist.mean.sum() + dist.log_std.sum() + v.sum()).backward();
    let grad = values(states.grad(&grads).expect("states reach the outputs"));
    let row = |agent: usize| &grad[(a + agent) * t * f..(a + agent + 1) * t * f];
    assert!(
        (0..n).any(|agent| row(agent).iter().any(|g| *g != 0.0)),
        "real agents get gradient"
    );
    for agent in n..a {
        assert!(
            row(agent).iter().all(|g| *g == 0.0),
            "padded agent {agent} got gradient"
        );
    }
}

/// Counts float parameters, and those without any non-zero gradient.
struct GradientCheck<'g> {
    grads: &'g burn::tensor::Gradients,
    params: usize,
    without: Vec<Vec<usize>>,
}

impl ModuleVisitor for GradientCheck<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        self.params += 1;
        let has = param
            .val()
            .grad(self.grads)
            .is_some_and(|g| values(g.abs().max()).first().is_some_and(|m| *m > 0.0));
        if !has {
            self.without.push(param.val().dims().to_vec());
        }
    }
}

#[test]
fn gradients_reach_every_parameter_through_a_closed_loop_rollout() {
    let device = device(true);
    let (policy, value) = networks(&device, 15);
    let scenes = test_scenes(2);
    let batch = SceneBatch::from_scenes(&scenes, &device).unwrap();
    let mut driver = NetworkPolicy::new(&policy, &batch, ActionMode::Sample);
    let config = RolloutConfig {
        steps: Some(4),
        early_termination: true,
    };
    let out = rollout(
        &scenes,
        &batch,
        &Dynamics::bicycle(0.5),
        &mut driver,
        &mut MapCaches::default(),
        &config,
    )
    .expect("rollout");
    let loss = imitation_loss(&out, &batch, 1.0).mean();
    assert!(values(loss.clone())[0].is_finite());
    let grads = loss.backward();
    let mut check = GradientCheck {
        grads: &grads,
        params: 0,
        without: Vec::new(),
    };
    policy.visit(&mut check);
    assert!(check.params > 50, "{} parameter tensors", check.params);
    assert!(
        check.without.is_empty(),
        "policy parameters without gradient (shapes): {:?}",
        check.without
    );

    let config = value.config();
    let lanes = LaneInput::from_batch(&batch, config);
    let frames = logged_frames(&batch, batch.history_steps);
    let agents = AgentInput::from_frames(&batch, &frames, config);
    let v = value.forward(&agents, &lanes, &value.encode_lanes(&lanes));
    let grads = v.powi_scalar(2).sum().backward();
    let mut check = GradientCheck {
        grads: &grads,
        params: 0,
        without: Vec::new(),
    };
    value.visit(&mut check);
    assert!(
        check.without.is_empty(),
        "value parameters without gradient (shapes): {:?}",
        check.without
    );
}

#[test]
fn parameter_counts_follow_the_config() {
    let device = device(false);
    let paper = PolicyNetwork::new(&ModelConfig::default(), &device).num_params();
    let small = PolicyNetwork::new(&ModelConfig::small(), &device).num_params();
    let value = ValueNetwork::new(&ModelConfig::default(), &device).num_params();
    assert!(small * 4 < paper, "small {small} vs paper {paper}");
    // Same architecture, a 1-wide output instead of 4 (mean and log sigma of two controls).
    assert_eq!(paper - value, 3 * (128 + 1));
}

/// `with_constant_std` sets every present agent's sigma and leaves the mean alone, also on an
/// autodiff device, where the new weights must stay trainable leaves.
#[test]
fn constant_std_sets_sigma_everywhere_and_keeps_the_mean() {
    for autodiff in [false, true] {
        let device = device(autodiff);
        let (policy, value) = networks(&device, 5);
        let batch = SceneBatch::from_scenes(&test_scenes(3), &device).expect("batch");
        let before = outputs(&policy, &value, &batch);
        let sigma = [0.4, 0.0022];
        let policy = policy.with_constant_std(sigma);
        let after = outputs(&policy, &value, &batch);
        assert_eq!(before.mean, after.mean);
        let frames = logged_frames(&batch, batch.history_steps);
        let agents = AgentInput::from_frames(&batch, &frames, policy.config());
        let present = values(agents.mask.clone().float());
        assert!(present.iter().filter(|&&p| p > 0.5).count() > 5);
        for (slot, &p) in present.iter().enumerate() {
            if p > 0.5 {
                for (k, &s) in sigma.iter().enumerate() {
                    let got = after.log_std[slot * 2 + k].exp() as f64;
                    assert!(
                        (got / s - 1.0).abs() < 1e-3,
                        "slot {slot} control {k}: {got} vs {s}"
                    );
                }
            }
        }
    }
}

/// The fit's sigma is the policy's own: a policy given a constant sigma reports exactly it,
/// per control, beside the same mean error as `logged_action_rms`; the sigma does not move
/// the mean error.
#[test]
fn logged_action_fit_reports_the_policys_sigma_beside_its_mean_error() {
    let device = device(false);
    let (policy, _) = networks(&device, 9);
    let scenes = test_scenes(4);
    let limits = rtr::sim::ActionLimits::default();
    let fit = |p: &rtr::model::PolicyNetwork| {
        rtr::train::imitation::logged_action_fit(p, &scenes, &limits, 16, &device).expect("fit")
    };
    let (rms, count) =
        rtr::train::imitation::logged_action_rms(&policy, &scenes, &limits, 16, &device)
            .expect("rms");
    for sigma in [[0.5, 0.002], [1.7, 0.01]] {
        let measured = fit(&policy.clone().with_constant_std(sigma));
        assert_eq!(measured.count, count);
        for k in 0..2 {
            let relative = (measured.sigma_rms[k] - sigma[k]).abs() / sigma[k];
            assert!(
                relative < 1e-3,
                "control {k}: sigma {} for {}",
                measured.sigma_rms[k],
                sigma[k]
            );
            let moved = (measured.mean_error_rms[k] - rms[k]).abs() / rms[k];
            assert!(
                moved < 1e-5,
                "control {k}: mean error {} against {}",
                measured.mean_error_rms[k],
                rms[k]
            );
        }
    }
}

/// The RMS error of the mean against the logged actions is the sigma that maximises the BC
/// likelihood among state-independent ones: a tenth more or less scores worse.
#[test]
fn logged_action_rms_is_the_maximum_likelihood_sigma() {
    let device = device(false);
    let (policy, _) = networks(&device, 9);
    let scenes = test_scenes(4);
    let limits = rtr::sim::ActionLimits::default();
    let (rms, count) =
        rtr::train::imitation::logged_action_rms(&policy, &scenes, &limits, 16, &device)
            .expect("rms");
    assert!(count > 50, "{count} labelled agent-steps");
    let batch = SceneBatch::from_scenes(&scenes, &device).expect("batch");
    let n = batch.agent_states.dims()[1];
    let labels =
        rtr::train::imitation::BcLabels::new(&scenes, n, scenes[0].future_steps, &limits, &device);
    assert_eq!(labels.count, count);
    let nll = |scale: f64| {
        let p = policy
            .clone()
            .with_constant_std([rms[0] * scale, rms[1] * scale]);
        values(rtr::train::imitation::behaviour_cloning(
            &p, &batch, &labels,
        ))[0]
    };
    let (at, low, high) = (nll(1.0), nll(0.9), nll(1.1));
    assert!(
        at < low && at < high,
        "NLL {low} / {at} / {high} at 0.9 / 1 / 1.1 x RMS"
    );
}

/// The lane-node curvature reaches the network multiplied by `lane_curvature_scale`, every
/// other feature as before; the A9's curves are then of order one at 1000.
#[test]
fn lane_curvature_scale_multiplies_the_curvature_feature_alone() {
    let device = device(false);
    let batch = SceneBatch::from_scenes(&test_scenes(2), &device).expect("batch");
    let features = |scale: f64| {
        let config = ModelConfig {
            lane_curvature_scale: scale,
            ..ModelConfig::small()
        };
        values(LaneInput::from_batch(&batch, &config).features)
    };
    let (default, scaled) = (features(100.0), features(1000.0));
    let width = rtr::map::LANE_NODE_FEATURES;
    let mut largest_curvature = 0f32;
    for (k, (d, s)) in default.iter().zip(&scaled).enumerate() {
        if k % width == 2 {
            assert!(
                (s - 10.0 * d).abs() <= 1e-5 * s.abs().max(1.0),
                "curvature {d} -> {s}"
            );
            largest_curvature = largest_curvature.max(s.abs());
        } else {
            assert_eq!(d, s, "feature {} of node {}", k % width, k / width);
        }
    }
    assert!(
        (0.1..=1.0).contains(&largest_curvature),
        "the A9's largest curvature x 1000: {largest_curvature}"
    );
}

/// Without `lane_speed_limit_input` the speed limit reaches the network as 0 on every node,
/// every other feature as with it (which carries the A9's 100 km/h).
#[test]
fn lane_speed_limit_input_off_removes_that_feature_alone() {
    let device = device(false);
    let batch = SceneBatch::from_scenes(&test_scenes(2), &device).expect("batch");
    let features = |with_limit: bool| {
        let config = ModelConfig {
            lane_speed_limit_input: with_limit,
            ..ModelConfig::small()
        };
        values(LaneInput::from_batch(&batch, &config).features)
    };
    let (with, without) = (features(true), features(false));
    let width = rtr::map::LANE_NODE_FEATURES;
    let mut limits = 0;
    for (k, (w, o)) in with.iter().zip(&without).enumerate() {
        if k % width == 3 {
            assert_eq!(*o, 0.0, "node {}", k / width);
            if (w - 100.0 / 3.6 / 30.0).abs() < 1e-5 {
                limits += 1;
            }
        } else {
            assert_eq!(w, o, "feature {} of node {}", k % width, k / width);
        }
    }
    assert!(limits > 0, "no lane node carried the A9's limit");
    assert!(ModelConfig::default().lane_speed_limit_input);
    let text = toml::to_string(&ModelConfig::default()).expect("toml");
    assert!(!text.contains("lane_speed_limit_input"), "{text}");
}

/// The lane steering feed-forward shifts the steering mean by exactly itself and nothing else,
/// on the A9's real lanes (whose nodes curve at about +-0.0003 1/m).
#[test]
fn lane_steer_feedforward_shifts_the_steering_mean_alone() {
    let device = device(false);
    let (policy, _) = networks(&device, 21);
    let config = ModelConfig {
        lane_steer_feedforward: true,
        ..policy.config().clone()
    };
    let batch = SceneBatch::from_scenes(&test_scenes(2), &device).expect("batch");
    let lanes = LaneInput::from_batch(&batch, &config);
    let frames = logged_frames(&batch, batch.history_steps);
    let with = AgentInput::from_frames(&batch, &frames, &config);
    let feedforward = values(with.steer_feedforward.clone().expect("feed-forward on"));
    let without = AgentInput {
        steer_feedforward: None,
        ..with.clone()
    };
    let encoded = policy.encode_lanes(&lanes);
    let (on, off) = (
        policy.forward(&with, &lanes, &encoded),
        policy.forward(&without, &lanes, &encoded),
    );
    assert_eq!(values(on.log_std), values(off.log_std));
    let (on, off) = (values(on.mean), values(off.mean));
    let present = values(with.mask.clone().float());
    let mut curved = 0;
    for (slot, ff) in feedforward.iter().enumerate() {
        assert_eq!(on[2 * slot], off[2 * slot], "acceleration of slot {slot}");
        assert!((on[2 * slot + 1] - off[2 * slot + 1] - ff).abs() < 1e-7);
        if present[slot] > 0.5 && (1e-4..3e-3).contains(&ff.abs()) {
            curved += 1;
        }
    }
    assert!(curved > 5, "{curved} agents steered by their lane");
    let text = toml::to_string(&ModelConfig::default()).expect("toml");
    assert!(!text.contains("lane_steer_feedforward"), "{text}");
}

/// Steering the feed-forward alone keeps cars near their lane centres through the clothoid
/// into a generated bend of 0.002 1/m (the long-tail roads' range) for 5 s, where steering
/// straight leaves the lane.
#[test]
fn lane_steer_feedforward_alone_follows_a_curved_lane() {
    let device = device(false);
    let od = rtr::map::curve(3, 3.75, 800.0, 0.002).expect("curve");
    let map = Arc::new(Map::from_opendrive(&od, "curve").expect("map"));
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let scene = synthetic_scene(&map, &graph, 3, 0, 4, 10);
    let batch = SceneBatch::from_scenes(&[&scene], &device).expect("batch");
    let config = ModelConfig {
        lane_steer_feedforward: true,
        ..ModelConfig::small()
    };
    let worst_offset = |follow: bool| {
        let mut policy = |obs: &rtr::sim::Observation| {
            let agents = AgentInput::from_frames(obs.batch, obs.frames, &config);
            let steer = agents.steer_feedforward.expect("feed-forward on");
            rtr::sim::Controls {
                accel: steer.zeros_like(),
                steer: if follow {
                    steer.clone()
                } else {
                    steer.zeros_like()
                },
            }
        };
        let out = rollout(
            &[&scene],
            &batch,
            &Dynamics::bicycle(0.5),
            &mut policy,
            &mut MapCaches::default(),
            &RolloutConfig {
                steps: Some(10),
                early_termination: false,
            },
        )
        .expect("rollout");
        let poses = values(out.poses);
        (0..3)
            .map(|agent| {
                let at = (agent * 11 + 10) * 4;
                let p = [poses[at] as f64, poses[at + 1] as f64];
                map.lane_projection(p, poses[at + 2] as f64)
                    .map_or(f64::INFINITY, |l| l.distance)
            })
            .fold(0.0, f64::max)
    };
    let (following, straight) = (worst_offset(true), worst_offset(false));
    // What is left is forward Euler's lag at dt = 0.5 s (each step moves along the heading it
    // starts with), which the network's correction has to take out: 1.3 m here.
    assert!(
        following < 1.5 && following < straight / 4.0,
        "{following} m from the lane centre following it, {straight} m steering straight"
    );
}
