//! `rtr bench sim`: simulator throughput on a real-size road, as one JSON object.
//!
//! - `agent_steps_per_s`: the non-neural closed-loop step (dynamics, replay bookkeeping,
//!   collision and off-road checks) through [`rollout`] with a zero policy, B = 64 scenes x
//!   N = 50 agents on the A9 map.
//! - `rollout_grad_ms`: forward + backward of a T = 10 rollout and its imitation loss through
//!   a small MLP policy (burn `Linear` layers), B = 32 x N = 20, on the autodiff device.

use std::sync::Arc;
use std::time::Instant;

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;

use super::dynamics::Dynamics;
use super::infractions::MapCaches;
use super::loss::imitation_loss;
use super::rollout::{Observation, RolloutConfig, coast, rollout};
use super::state::Controls;
use crate::backend::Backend;
use crate::data::{AgentState, VehicleClass};
use crate::error::Result;
use crate::map::{LaneGraph, Map};
use crate::scene::{AgentRole, Scene, SceneAgent, SceneBatch};

#[derive(Debug, Clone, serde::Serialize)]
pub struct SimBench {
    pub bench: &'static str,
    pub backend: String,
    pub map: String,
    pub step_batch: [usize; 2],
    pub steps: usize,
    pub agent_steps_per_s: f64,
    pub grad_batch: [usize; 2],
    pub grad_steps: usize,
    pub rollout_grad_ms: f64,
    pub repetitions: usize,
}

/// Point and heading at arc length `s` along a polyline with cumulative lengths `cum`.
fn along(points: &[[f64; 2]], cum: &[f64], s: f64) -> ([f64; 2], f64) {
    let i = cum.partition_point(|&c| c <= s).clamp(1, points.len() - 1);
    let (a, b) = (points[i - 1], points[i]);
    let w = ((s - cum[i - 1]) / (cum[i] - cum[i - 1]).max(1e-9)).clamp(0.0, 1.0);
    (
        [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])],
        (b[1] - a[1]).atan2(b[0] - a[0]),
    )
}

/// A scene of `agents` controlled cars spread over the map's graph lanes, each logged at
/// constant speed along its lane centreline for `history` past and `future` steps. `seed`
/// shifts the placement.
pub fn synthetic_scene(
    map: &Arc<Map>,
    graph: &Arc<LaneGraph>,
    agents: usize,
    seed: usize,
    history: usize,
    future: usize,
) -> Scene {
    let lanes: Vec<_> = map.lanes().iter().filter(|l| l.is_graph_lane()).collect();
    let per_lane = agents.div_ceil(lanes.len().max(1));
    let dt = 0.5;
    let steps = history + 1 + future;
    let mut out = Vec::with_capacity(agents);
    for i in 0..agents {
        let lane = lanes[i % lanes.len()];
        let slot = i / lanes.len();
        let spacing = lane.length() / per_lane as f64;
        let speed = 25.0 + ((i * 7 + seed * 3) % 10) as f64;
        let s0 = (slot as f64 + 0.2 + 0.05 * (seed % 5) as f64) * spacing;
        let states = (0..steps)
            .map(|k| {
                let s = (s0 + speed * (k as f64 - history as f64) * dt).clamp(0.0, lane.length());
                let (p, heading) = along(&lane.centerline, &lane.s, s);
                AgentState {
                    x: p[0],
                    y: p[1],
                    heading,
                    speed,
                    accel: 0.0,
                }
            })
            .collect();
        out.push(SceneAgent {
            track_id: i,
            class: VehicleClass::Car,
            length: 4.6,
            width: 1.9,
            role: AgentRole::Controlled,
            states,
            valid: vec![true; steps],
        });
    }
    Scene {
        id: format!("synthetic-{seed}"),
        t0: 0.0,
        dt,
        history_steps: history,
        future_steps: future,
        map: map.clone(),
        lane_graph: graph.clone(),
        agents: out,
    }
}

/// Seconds of one run of `f`: one untimed warm-up run (first-use setup: query grids, kernel
/// compilation), then the median of `repetitions` (at least one) timed runs.
pub fn median_seconds(repetitions: usize, f: &mut dyn FnMut() -> Result<()>) -> Result<f64> {
    f()?;
    let mut times = Vec::with_capacity(repetitions.max(1));
    for _ in 0..repetitions.max(1) {
        let start = Instant::now();
        f()?;
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// Frame-free per-agent inputs of the small benchmark and test policies: `[B, N, 3]` =
/// (speed / 30 m/s, sin heading, cos heading).
pub fn agent_features(obs: &Observation) -> Tensor<3> {
    let h = obs.state.heading.clone();
    Tensor::<2>::stack::<3>(
        vec![
            obs.state.speed.clone().div_scalar(30.0),
            h.clone().sin(),
            h.cos(),
        ],
        2,
    )
}

/// The small policy of the gradient benchmark: per agent (speed, sin, cos of heading) -> 64
/// -> 64 -> (accel, steer).
#[derive(Module, Debug)]
pub struct BenchMlp {
    input: Linear,
    hidden: Linear,
    output: Linear,
}

impl BenchMlp {
    pub fn new(device: &Device) -> Self {
        Self {
            input: LinearConfig::new(3, 64).init(device),
            hidden: LinearConfig::new(64, 64).init(device),
            output: LinearConfig::new(64, 2).init(device),
        }
    }

    pub fn act(&self, obs: &Observation) -> Controls {
        let [b, n] = obs.state.speed.dims();
        let x = agent_features(obs);
        let x = self.input.forward(x).tanh();
        let x = self.hidden.forward(x).tanh();
        Controls::from_stacked(self.output.forward(x).mul_scalar(0.1).reshape([b, n, 2]))
    }
}

/// Runs both measurements on `map` with `backend`; `repetitions` timed runs each (median).
pub fn run(map: Arc<Map>, backend: Backend, repetitions: usize) -> Result<SimBench> {
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let dynamics = Dynamics::bicycle(0.5);
    let mut caches = MapCaches::default();
    let repetitions = repetitions.max(1);
    let median_time = |f: &mut dyn FnMut() -> Result<()>| median_seconds(repetitions, f);

    let (b, n, steps) = (64, 50, 10);
    let scenes: Vec<Scene> = (0..b)
        .map(|i| synthetic_scene(&map, &graph, n, i, 1, steps))
        .collect();
    let refs: Vec<&Scene> = scenes.iter().collect();
    let device = backend.device(false)?;
    let batch = SceneBatch::from_scenes(&refs, &device)?;
    let config = RolloutConfig::default();
    let step_time = median_time(&mut || {
        rollout(&refs, &batch, &dynamics, &mut coast, &mut caches, &config).map(|_| ())
    })?;
    let agent_steps_per_s = (b * n * steps) as f64 / step_time;

    let (gb, gn, gsteps) = (32, 20, 10);
    let scenes: Vec<Scene> = (0..gb)
        .map(|i| synthetic_scene(&map, &graph, gn, i, 1, gsteps))
        .collect();
    let refs: Vec<&Scene> = scenes.iter().collect();
    let device = backend.device(true)?;
    let batch = SceneBatch::from_scenes(&refs, &device)?;
    let policy = BenchMlp::new(&device);
    let grad_time = median_time(&mut || {
        let mut act = |obs: &Observation| policy.act(obs);
        let out = rollout(&refs, &batch, &dynamics, &mut act, &mut caches, &config)?;
        let _grads = imitation_loss(&out, &batch, 1.0).mean().backward();
        Ok(())
    })?;
    Ok(SimBench {
        bench: "sim",
        backend: backend.to_string(),
        map: map.source().to_string(),
        step_batch: [b, n],
        steps,
        agent_steps_per_s,
        grad_batch: [gb, gn],
        grad_steps: gsteps,
        rollout_grad_ms: 1e3 * grad_time,
        repetitions,
    })
}
