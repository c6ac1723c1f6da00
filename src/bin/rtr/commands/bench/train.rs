//! Training throughput at the paper's batch sizes (`rtr bench train`): closed-loop IL in
//! initial scenes per second (one AdamW step on `il_minibatch` nominal scenes, BPTT through
//! the whole 6 s rollout), and PPO in agent-steps per second (one RL iteration: `ppo_batch`
//! rollouts collected with sampled actions, then one step per `ppo_minibatch`), both through
//! the real training loop on the real A9 scenes, with `devices` data-parallel workers. Each
//! figure also comes with the cores it kept busy and the process's peak memory.

use std::time::Instant;

use indicatif::ProgressBar;
use serde::Serialize;

use rtr::backend::Backend;
use rtr::data::A9Dataset;
use rtr::model::ModelConfig;
use rtr::train::session::{devices, training_data};
use rtr::train::{IterationTiming, Method, PpoConfig, TrainConfig, Trainer};
use rtr::usage::{CoreMeter, peak_rss_mb, reset_peak_rss};
use rtr::{Error, Result};

#[derive(Debug, Clone, Serialize)]
pub struct TrainBenchReport {
    pub backend: String,
    pub model_parameters: usize,
    pub il_minibatch: usize,
    pub il_step_s: f64,
    pub il_scenes_per_s: f64,
    pub ppo_batch: usize,
    pub ppo_minibatch: usize,
    pub ppo_iteration_s: f64,
    /// Alive agent-steps collected in the iteration (each also re-evaluated in its update).
    pub ppo_agent_steps: usize,
    pub ppo_agent_steps_per_s: f64,
    /// The iteration's two phases: sampled rollouts (no autodiff), then the updates.
    pub ppo_collect_s: f64,
    pub ppo_collect_agent_steps_per_s: f64,
    pub ppo_update_s: f64,
    pub ppo_update_agent_steps_per_s: f64,
    pub devices: usize,
    /// CPU time / wall time over the IL step and over the PPO iteration.
    pub il_cores_busy: Option<f64>,
    pub ppo_cores_busy: Option<f64>,
    /// Resident-memory high-water mark of each run (MiB), reset at its start. The PPO figure
    /// includes heap the allocator kept from the IL run before it (`rtr::allocator`), so it
    /// is an upper bound; the process's own maximum is the figure to compare across builds.
    pub il_peak_rss_mb: Option<f64>,
    pub ppo_peak_rss_mb: Option<f64>,
    pub threads: usize,
}

/// One timed iteration of a method.
struct Timed {
    seconds: f64,
    agent_steps: usize,
    timing: IterationTiming,
    cores_busy: Option<f64>,
    peak_rss_mb: Option<f64>,
}

/// The run config `bench_training` times `method` with, validated: the default run of that
/// method with `model` and `ppo`'s settings, at the given batch sizes.
#[allow(clippy::too_many_arguments)]
fn bench_config(
    method: Method,
    backend: Backend,
    model: &ModelConfig,
    ppo: &PpoConfig,
    il_minibatch: usize,
    ppo_batch: usize,
    ppo_minibatch: usize,
    device_count: usize,
) -> Result<TrainConfig> {
    let mut config =
        TrainConfig::from_toml_str(&format!("method = \"{}\"", method.name()), "bench")?;
    config.model = model.clone();
    config.ppo = ppo.clone();
    // The timed iteration is a full one: policy and value both step.
    config.ppo.value_warmup_iterations = 0;
    config.run.backend = backend;
    config.run.max_iterations = Some(1);
    config.imitation.minibatch = il_minibatch;
    config.ppo.batch = ppo_batch;
    config.ppo.minibatch = ppo_minibatch;
    config.run.devices = Some(device_count);
    config.validate("bench").map_err(in_flag_words)?;
    Ok(config)
}

/// The run-config fields `bench train` sets from its flags, by flag.
const FLAG_FIELDS: [(&str, &str); 4] = [
    ("imitation.minibatch", "--il-minibatch"),
    ("ppo.minibatch", "--ppo-minibatch"),
    ("ppo.batch", "--ppo-batch"),
    ("run.devices", "--devices"),
];

/// `e`, a refusal of the config built from the flags, naming the flags the user gave rather
/// than run-file fields they never wrote (`ppo.minibatch` is `--ppo-minibatch` here).
fn in_flag_words(e: Error) -> Error {
    let mut text = e.to_string();
    if !FLAG_FIELDS.iter().any(|(field, _)| text.contains(field)) {
        return e;
    }
    for (field, flag) in FLAG_FIELDS {
        text = text
            .replace(&format!("field `{field}`"), flag)
            .replace(field, flag);
    }
    Error::InvalidArgument(text.replacen("bench: ", "bench train: ", 1))
}

/// Refuses what `bench_training` would refuse about its settings (a backend not built in,
/// sizes its configs reject), with the same messages, before any data is loaded.
pub fn check_settings(
    backend: Backend,
    model: &ModelConfig,
    ppo: &PpoConfig,
    il_minibatch: usize,
    ppo_batch: usize,
    ppo_minibatch: usize,
    device_count: usize,
) -> Result<()> {
    for method in [Method::Il, Method::Rl] {
        bench_config(
            method,
            backend,
            model,
            ppo,
            il_minibatch,
            ppo_batch,
            ppo_minibatch,
            device_count,
        )?;
    }
    backend.device(true).map(|_| ())
}

/// Times one IL step and one RL (factorized PPO) iteration.
#[allow(clippy::too_many_arguments)]
pub fn bench_training(
    dataset: &A9Dataset,
    backend: Backend,
    model: ModelConfig,
    ppo: &PpoConfig,
    il_minibatch: usize,
    ppo_batch: usize,
    ppo_minibatch: usize,
    device_count: usize,
) -> Result<TrainBenchReport> {
    let run = |method: Method| -> Result<Timed> {
        let config = bench_config(
            method,
            backend,
            &model,
            ppo,
            il_minibatch,
            ppo_batch,
            ppo_minibatch,
            device_count,
        )?;
        let data = training_data(dataset, &config)?;
        let dir = std::env::temp_dir().join(format!(
            "rtr-bench-{}-{}",
            method.name(),
            std::process::id()
        ));
        let _ = rtr::io::remove_folder(&dir);
        let mut trainer = Trainer::new(config.clone(), &data, devices(&config)?, &dir, false)?;
        reset_peak_rss();
        let meter = CoreMeter::start();
        let start = Instant::now();
        trainer.run(&ProgressBar::hidden(), Some(1))?;
        let seconds = start.elapsed().as_secs_f64();
        let cores_busy = meter.cores_busy();
        let agent_steps = trainer.curves().last().map_or(0, |r| r.ppo_agent_steps);
        let _ = rtr::io::remove_folder(&dir);
        Ok(Timed {
            seconds,
            agent_steps,
            timing: trainer.last_timing(),
            cores_busy,
            peak_rss_mb: peak_rss_mb(),
        })
    };
    let il = run(Method::Il)?;
    let ppo = run(Method::Rl)?;
    let per_s = |steps: usize, s: f64| steps as f64 / s.max(1e-9);
    let parameters = {
        use burn::module::Module;
        rtr::model::PolicyNetwork::new(&model, &Backend::reference_device(false)).num_params()
    };
    Ok(TrainBenchReport {
        backend: backend.to_string(),
        model_parameters: parameters,
        il_minibatch,
        il_step_s: il.seconds,
        il_scenes_per_s: il_minibatch as f64 / il.seconds,
        ppo_batch,
        ppo_minibatch,
        ppo_iteration_s: ppo.seconds,
        ppo_agent_steps: ppo.agent_steps,
        ppo_agent_steps_per_s: per_s(ppo.agent_steps, ppo.seconds),
        ppo_collect_s: ppo.timing.collect_s,
        ppo_collect_agent_steps_per_s: per_s(ppo.agent_steps, ppo.timing.collect_s),
        ppo_update_s: ppo.timing.update_s,
        ppo_update_agent_steps_per_s: per_s(ppo.agent_steps, ppo.timing.update_s),
        devices: device_count,
        il_cores_busy: il.cores_busy,
        ppo_cores_busy: ppo.cores_busy,
        il_peak_rss_mb: il.peak_rss_mb,
        ppo_peak_rss_mb: ppo.peak_rss_mb,
        threads: rayon::current_num_threads(),
    })
}
