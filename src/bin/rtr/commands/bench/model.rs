//! `rtr bench model`: speed and memory of policy + value networks at the paper's size, as one
//! JSON object. B = 32 scenes x N = 32 agents on the A9 map (162 lane nodes), H = 5 history
//! frames, the default [`ModelConfig`] (hidden 128).
//!
//! - `forward_ms`: both networks' full forward (lane encoder included) on the plain device;
//! - `forward_backward_ms`: the same on the autodiff device plus backward of a scalar of all
//!   outputs;
//! - both with the batch split over `devices` worker threads (each a contiguous share of the
//!   scenes on its own device, as the trainer splits a minibatch), and on one device
//!   (`*_one_device_ms`);
//! - `peak_rss_mb`: the process's resident-memory high-water mark over the timed forward +
//!   backward runs (Linux `VmHWM`, reset before them and measured first; `null` elsewhere),
//!   `baseline_rss_mb` before them.

use std::sync::Arc;

use burn::module::Module;
use burn::prelude::*;

use rtr::backend::Backend;
use rtr::map::{LaneGraph, Map};
use rtr::model::{AgentInput, LaneInput, ModelConfig, PolicyNetwork, ValueNetwork};
use rtr::scene::{Scene, SceneBatch, synthetic_scene};
use rtr::sim::logged_frames;
use rtr::usage::{CoreMeter, peak_rss_mb, reset_peak_rss};
use rtr::{Error, Result};

use super::median_seconds;

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
    /// Worker devices the batch is split over (data parallel, as training runs it).
    pub devices: usize,
    pub forward_ms: f64,
    pub forward_backward_ms: f64,
    /// The same two on one device (one worker), for the speed-up of the split.
    pub forward_one_device_ms: f64,
    pub forward_backward_one_device_ms: f64,
    /// Cores kept busy (CPU time / wall time) during the timed forward + backward runs.
    pub cores_busy: Option<f64>,
    pub baseline_rss_mb: Option<f64>,
    pub peak_rss_mb: Option<f64>,
    pub repetitions: usize,
}

/// One worker's share: its batch, frames and network copies, built outside the timing.
struct Shard {
    batch: SceneBatch,
    frames: Vec<rtr::sim::Frame>,
    policy: PolicyNetwork,
    value: ValueNetwork,
}

impl Shard {
    fn new(
        scenes: &[&Scene],
        policy: &PolicyNetwork,
        value: &ValueNetwork,
        device: &Device,
    ) -> Result<Self> {
        let batch = SceneBatch::from_scenes(scenes, device)?;
        let frames = logged_frames(&batch, batch.history_steps);
        Ok(Self {
            batch,
            frames,
            policy: policy.clone().fork(device),
            value: value.clone().fork(device),
        })
    }

    /// Both networks' full forward (lane encoder included), then backward when `backward`.
    fn run(&self, backward: bool) {
        let config = self.policy.config();
        let lanes = LaneInput::from_batch(&self.batch, config);
        let agents = AgentInput::from_frames(&self.batch, &self.frames, config);
        let dist = self
            .policy
            .forward(&agents, &lanes, &self.policy.encode_lanes(&lanes));
        let v = self
            .value
            .forward(&agents, &lanes, &self.value.encode_lanes(&lanes));
        let total = dist.mean.sum() + dist.log_std.sum() + v.sum();
        if backward {
            let _grads = total.backward();
        } else {
            // Wait for the result (asynchronous backends).
            let _ = total.into_data();
        }
    }
}

/// Scenes in the benchmark's batch (of 32 agents each).
const BATCH_SCENES: usize = 32;

/// The batch cut into `devices` contiguous shards, each on its own device.
fn shards(
    scenes: &[&Scene],
    devices: usize,
    backend: Backend,
    autodiff: bool,
    config: &ModelConfig,
) -> Result<Vec<Shard>> {
    let main = backend.device(autodiff)?;
    let policy = PolicyNetwork::new(config, &main);
    let value = ValueNetwork::new(config, &main);
    scenes
        .chunks(scenes.len().div_ceil(devices.max(1)))
        .map(|chunk| Shard::new(chunk, &policy, &value, &backend.device(autodiff)?))
        .collect()
}

/// Times every shard's run, in parallel (rayon tasks, as the trainer runs them) when there
/// are several.
fn timed(repetitions: usize, shards: &[Shard], backward: bool) -> Result<f64> {
    use rayon::prelude::*;
    median_seconds(repetitions, &mut || {
        shards.par_iter().for_each(|shard| shard.run(backward));
        Ok(())
    })
}

pub fn run(
    map: Arc<Map>,
    backend: Backend,
    devices: usize,
    repetitions: usize,
) -> Result<ModelBench> {
    let (b, n) = (BATCH_SCENES, 32);
    if devices > b {
        return Err(Error::InvalidArgument(format!(
            "--devices {devices}: the benchmark's batch holds {b} scenes, so at most {b} \
             devices can each take a share"
        )));
    }
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let config = ModelConfig::default();
    let history = config.history_steps - 1;
    let scenes: Vec<Scene> = (0..b)
        .map(|i| synthetic_scene(&map, &graph, n, i, history, 1))
        .collect();
    let refs: Vec<&Scene> = scenes.iter().collect();

    let device = backend.device(false)?;
    let policy_params = PolicyNetwork::new(&config, &device).num_params();
    let value_params = ValueNetwork::new(&config, &device).num_params();

    let measure = |workers: usize, autodiff: bool| -> Result<f64> {
        let shards = shards(&refs, workers, backend, autodiff, &config)?;
        timed(repetitions, &shards, autodiff)
    };
    // The training figure first, with the memory high-water mark of that run alone (freed
    // buffers stay in the process's heap, so later runs would report the earlier ones' peak).
    let baseline_rss_mb = peak_rss_mb();
    reset_peak_rss();
    let meter = CoreMeter::start();
    let forward_backward_s = measure(devices, true)?;
    let cores_busy = meter.cores_busy();
    let peak = peak_rss_mb();
    let forward_s = measure(devices, false)?;
    let forward_one_device_s = measure(1, false)?;
    let forward_backward_one_device_s = measure(1, true)?;
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
        devices,
        forward_ms: 1e3 * forward_s,
        forward_backward_ms: 1e3 * forward_backward_s,
        forward_one_device_ms: 1e3 * forward_one_device_s,
        forward_backward_one_device_ms: 1e3 * forward_backward_one_device_s,
        cores_busy,
        baseline_rss_mb,
        peak_rss_mb: peak,
        repetitions: repetitions.max(1),
    })
}
