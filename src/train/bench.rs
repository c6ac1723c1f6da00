//! Training throughput at the paper's batch sizes (`rtr bench train`): closed-loop IL in
//! initial scenes per second (one AdamW step on `il_minibatch` nominal scenes, BPTT through
//! the whole 6 s rollout), and PPO in agent-steps per second (one RL iteration: `ppo_batch`
//! rollouts collected with sampled actions, then one step per `ppo_minibatch`), both through
//! the real training loop on the real A9 scenes.

use std::time::Instant;

use indicatif::ProgressBar;
use serde::Serialize;

use super::config::{Method, TrainConfig};
use super::session::{devices, training_data};
use super::trainer::Trainer;
use crate::backend::Backend;
use crate::data::A9Dataset;
use crate::error::Result;
use crate::model::ModelConfig;

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
    pub threads: usize,
}

/// Times one IL step and one RL (factorized PPO) iteration.
pub fn bench_training(
    dataset: &A9Dataset,
    backend: Backend,
    model: ModelConfig,
    il_minibatch: usize,
    ppo_batch: usize,
    ppo_minibatch: usize,
) -> Result<TrainBenchReport> {
    let run = |method: Method| -> Result<(f64, usize)> {
        let mut config =
            TrainConfig::from_toml_str(&format!("method = \"{}\"", method.name()), "bench")?;
        config.model = model.clone();
        config.run.backend = backend;
        config.run.max_iterations = Some(1);
        config.imitation.minibatch = il_minibatch;
        config.ppo.batch = ppo_batch;
        config.ppo.minibatch = ppo_minibatch;
        config.validate("bench")?;
        let data = training_data(dataset, &config)?;
        let dir = std::env::temp_dir().join(format!(
            "rtr-bench-{}-{}",
            method.name(),
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        let mut trainer = Trainer::new(config.clone(), &data, devices(&config)?, &dir, false)?;
        let start = Instant::now();
        trainer.run(&ProgressBar::hidden(), Some(1))?;
        let seconds = start.elapsed().as_secs_f64();
        let steps = trainer.curves().last().map_or(0, |r| r.ppo_agent_steps);
        let _ = std::fs::remove_dir_all(&dir);
        Ok((seconds, steps))
    };
    let (il_s, _) = run(Method::Il)?;
    let (ppo_s, agent_steps) = run(Method::Rl)?;
    #[allow(deprecated)]
    let parameters = {
        use burn::module::Module;
        crate::model::PolicyNetwork::new(&model, &burn::prelude::Device::ndarray()).num_params()
    };
    Ok(TrainBenchReport {
        backend: backend.to_string(),
        model_parameters: parameters,
        il_minibatch,
        il_step_s: il_s,
        il_scenes_per_s: il_minibatch as f64 / il_s,
        ppo_batch,
        ppo_minibatch,
        ppo_iteration_s: ppo_s,
        ppo_agent_steps: agent_steps,
        ppo_agent_steps_per_s: agent_steps as f64 / ppo_s,
        threads: rayon::current_num_threads(),
    })
}
