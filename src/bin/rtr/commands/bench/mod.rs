//! `rtr bench`: simulator, network and training throughput benchmarks, printed as JSON.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use clap::{Args, Subcommand};

use rtr::backend::Backend;
use rtr::data::a9;
use rtr::map::Map;
use rtr::model::ModelConfig;
use rtr::train::{PpoConfig, TrainConfig};
use rtr::{Error, Result};

use super::args::{DataArgs, count, device_count};

mod model;
mod sim;
mod train;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Closed-loop simulator: non-neural agent-steps/s (B=64 x N=50) and rollout gradient time
    /// (T=10, B=32 x N=20) on the A9 map.
    Sim(BenchArgs),
    /// Policy + value networks at the paper's size (hidden 128): forward and forward+backward
    /// time and peak memory for B=32 scenes x N=32 agents, H=5, on the A9 lane graph.
    Model(BenchArgs),
    /// Training throughput: one closed-loop IL step (scenes/s) and one factorized-PPO
    /// iteration (agent-steps/s collected and updated) at the paper's batch sizes.
    Train(TrainBenchArgs),
}

#[derive(Args)]
pub struct TrainBenchArgs {
    #[command(flatten)]
    data: DataArgs,
    /// flex (the default build's CPU backend), ndarray, or wgpu (cargo feature `wgpu`).
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    /// The small network of the tests instead of the paper's (hidden 128).
    #[arg(long, conflicts_with = "config")]
    small: bool,
    /// A run file whose `[model]` and `[ppo]` settings are timed (e.g. the main table's
    /// `experiments/main/rtr.toml`) instead of the defaults; its other sections are ignored.
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long, default_value_t = 32, value_parser = count(1, 4096))]
    il_minibatch: usize,
    #[arg(long, default_value_t = 192, value_parser = count(1, 4096))]
    ppo_batch: usize,
    #[arg(long, default_value_t = 32, value_parser = count(1, 4096))]
    ppo_minibatch: usize,
    /// Worker devices (data parallel); default one per core (one on wgpu).
    #[arg(long, value_parser = count(1, 256))]
    devices: Option<usize>,
    /// Print one JSON object (the only output format; accepted for symmetry).
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    data: DataArgs,
    /// flex (the default build's CPU backend), ndarray, or wgpu (cargo feature `wgpu`).
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    /// Timed repetitions per measurement (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = count(1, 1000))]
    repetitions: usize,
    /// Worker devices the model benchmark splits its batch over; default one per core (one on
    /// wgpu). The simulator benchmark has no network and ignores it.
    #[arg(long, value_parser = count(1, 256))]
    devices: Option<usize>,
    /// Print one JSON object (the only output format; the flag is accepted for symmetry with
    /// other commands).
    #[arg(long)]
    json: bool,
}

pub fn run(command: BenchCommand) -> Result<()> {
    let report = match command {
        BenchCommand::Train(args) => {
            let (model, ppo) = match &args.config {
                Some(path) => {
                    rtr::io::check_input_file(path, "--config")?;
                    let run = TrainConfig::from_toml_file(path)?;
                    (run.model, run.ppo)
                }
                None if args.small => (ModelConfig::small(), PpoConfig::default()),
                None => (ModelConfig::default(), PpoConfig::default()),
            };
            let devices = device_count(args.devices, args.backend)?;
            train::check_settings(
                args.backend,
                &model,
                &ppo,
                args.il_minibatch,
                args.ppo_batch,
                args.ppo_minibatch,
                devices,
            )?;
            serde_json::to_value(train::bench_training(
                &args.data.load()?,
                args.backend,
                model,
                &ppo,
                args.il_minibatch,
                args.ppo_batch,
                args.ppo_minibatch,
                devices,
            )?)
        }
        BenchCommand::Sim(args) => {
            args.backend.device(false)?;
            let (map, repetitions) = bench_inputs(&args)?;
            serde_json::to_value(sim::run(map, args.backend, repetitions)?)
        }
        BenchCommand::Model(args) => {
            args.backend.device(false)?;
            let devices = device_count(args.devices, args.backend)?;
            let (map, repetitions) = bench_inputs(&args)?;
            serde_json::to_value(model::run(map, args.backend, devices, repetitions)?)
        }
    }
    .map_err(|e| Error::InvalidArgument(format!("cannot encode report: {e}")))?;
    rtr::outln!("{report}")?;
    Ok(())
}

/// The A9 map and the repetition count (at least 1, checked by its parser) of a simulator or
/// model benchmark.
fn bench_inputs(args: &BenchArgs) -> Result<(Arc<Map>, usize)> {
    let map = Arc::new(a9::load_map(&args.data.checked_dir()?)?);
    Ok((map, args.repetitions))
}

/// Seconds of one run of `f`: one untimed warm-up run (first-use setup: query grids, kernel
/// compilation), then the median of `repetitions` (at least one) timed runs.
fn median_seconds(repetitions: usize, f: &mut dyn FnMut() -> Result<()>) -> Result<f64> {
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
