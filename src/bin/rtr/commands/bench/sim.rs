//! `rtr bench sim`: simulator throughput on a real-size road, as one JSON object.
//!
//! - `agent_steps_per_s`: the non-neural closed-loop step (dynamics, replay bookkeeping,
//!   collision and off-road checks) through [`rollout`] with a zero policy, B = 64 scenes x
//!   N = 50 agents on the A9 map.
//! - `rollout_grad_ms`: forward + backward of a T = 10 rollout and its imitation loss through
//!   a small MLP policy (burn `Linear` layers), B = 32 x N = 20, on the autodiff device.

use std::sync::Arc;

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;

use rtr::Result;
use rtr::backend::Backend;
use rtr::map::{LaneGraph, Map};
use rtr::scene::{Scene, SceneBatch, synthetic_scene};
use rtr::sim::{
    Controls, Dynamics, MapCaches, Observation, RolloutConfig, coast, imitation_loss, rollout,
};

use super::median_seconds;

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
        let x = obs.kinematic_features();
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
