//! `rtr bench model`: speed and memory of policy + value networks at the paper's size, as one
//! JSON object. B = 32 scenes x N = 32 agents on the A9 map (162 lane nodes), H = 5 history
//! frames, the default [`ModelConfig`] (hidden 128).
//!
//! - `forward_ms`: both networks' full forward (lane encoder included) on the plain device;
//! - `forward_backward_ms`: the same on the autodiff device plus backward of a scalar of all
//!   outputs;
//! - `peak_rss_mb`: the process's resident-memory high-water mark over the timed runs (Linux
//!   `VmHWM`, reset before measuring; `null` elsewhere), `baseline_rss_mb` before them.

use std::sync::Arc;

use burn::module::Module;
use burn::prelude::*;

use super::config::ModelConfig;
use super::input::{AgentInput, LaneInput};
use super::network::{PolicyNetwork, ValueNetwork};
use crate::backend::Backend;
use crate::error::Result;
use crate::map::{LaneGraph, Map};
use crate::scene::{Scene, SceneBatch};
use crate::sim::bench::{median_seconds, synthetic_scene};
use crate::sim::logged_frames;

#[derive(Debug, Clone, serde::Serialize)]
pub struct ModelBench {
    pub bench: &'static str,
    pub backend: String,
    pub batch: [usize; 2],
    pub lane_nodes: usize,
    pub history_steps: usize,
    pub hidden: usize,
    pub policy_params: usize,
    pub value_params: usize,
    pub params: usize,
    pub forward_ms: f64,
    pub forward_backward_ms: f64,
    pub baseline_rss_mb: Option<f64>,
    pub peak_rss_mb: Option<f64>,
    pub repetitions: usize,
}

/// Resident-set high-water mark of this process (MiB), from `/proc/self/status`.
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Resets the high-water mark to the current resident size (Linux >= 4.0).
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

pub fn run(map: Arc<Map>, backend: Backend, repetitions: usize) -> Result<ModelBench> {
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let config = ModelConfig::default();
    let (b, n) = (32, 32);
    let history = config.history_steps - 1;
    let scenes: Vec<Scene> = (0..b)
        .map(|i| synthetic_scene(&map, &graph, n, i, history, 1))
        .collect();
    let refs: Vec<&Scene> = scenes.iter().collect();

    // One timed closure per device: inputs and networks are built outside the timing.
    let forward = |device: &Device, backward: bool| -> Result<Box<dyn FnMut() -> Result<()>>> {
        let config = config.clone();
        let batch = SceneBatch::from_scenes(&refs, device)?;
        let frames = logged_frames(&batch, batch.history_steps);
        let policy = PolicyNetwork::new(&config, device);
        let value = ValueNetwork::new(&config, device);
        Ok(Box::new(move || {
            let lanes = LaneInput::from_batch(&batch, &config);
            let agents = AgentInput::from_frames(&batch, &frames, &config);
            let dist = policy.forward(&agents, &lanes, policy.encode_lanes(&lanes));
            let v = value.forward(&agents, &lanes, value.encode_lanes(&lanes));
            let total = dist.mean.sum() + dist.log_std.sum() + v.sum();
            if backward {
                let _grads = total.backward();
            } else {
                // Wait for the result (asynchronous backends).
                let _ = total.into_data();
            }
            Ok(())
        }))
    };

    let device = backend.device(false)?;
    let probe = PolicyNetwork::new(&config, &device);
    let policy_params = probe.num_params();
    let value_params = ValueNetwork::new(&config, &device).num_params();
    drop(probe);

    let baseline_rss_mb = peak_rss_mb();
    reset_peak_rss();
    let forward_s = median_seconds(repetitions, &mut *forward(&device, false)?)?;
    let forward_backward_s =
        median_seconds(repetitions, &mut *forward(&backend.device(true)?, true)?)?;
    Ok(ModelBench {
        bench: "model",
        backend: backend.to_string(),
        batch: [b, n],
        lane_nodes: graph.nodes.len(),
        history_steps: config.history_steps,
        hidden: config.hidden,
        policy_params,
        value_params,
        params: policy_params + value_params,
        forward_ms: 1e3 * forward_s,
        forward_backward_ms: 1e3 * forward_backward_s,
        baseline_rss_mb,
        peak_rss_mb: peak_rss_mb(),
        repetitions: repetitions.max(1),
    })
}
