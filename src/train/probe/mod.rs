//! PPO probes: small closed-loop tasks whose right behaviour is known, run with the project's
//! own scenarios, simulator and trainer, so "does PPO learn?" is answered before any long run
//! (the practice of "debugging RL" write-ups: probe environments first).
//!
//! - *brake* and *recover* ([`ProbeTask`]) train PPO alone (the RL method, the paper's sparse
//!   reward) from a warm start on one task's scenarios and measure held-out draws of the same
//!   families before and after: the share of cars with an infraction under the mean action,
//!   and the training reward of sampled rollouts;
//! - *credit* checks, on scenes where only the acceleration can change the outcome (a slow
//!   car, a car standing ahead), that the surrogate's gradient pushes the acceleration towards
//!   braking and leaves the steering without a direction ([`credit`]).

pub mod credit;
pub mod measure;
pub mod tasks;

use std::path::PathBuf;
use std::time::Instant;

use burn::module::Module;
use indicatif::ProgressBar;
use serde::Serialize;

use super::config::{Method, TrainConfig};
use super::experience::{CollectNetworks, RewardSettings, collect};
use super::sources::TrainingData;
use super::trainer::Trainer;
use crate::data::{A9Dataset, SceneConfig, TrafficStatistics};
use crate::error::{Error, Result};
use crate::model::{PolicyNetwork, ValueNetwork};
use crate::scene::Scene;
use crate::sim::MapCaches;
pub use credit::ControlPush;
use measure::{infraction_pct, parts, sampled_return};
pub use tasks::{ProbeScenarios, ProbeTask, probe_scenarios};

/// A trained task passes when at most this share of held-out cars has an infraction...
pub const PASS_INFRACTION_PCT: f64 = 5.0;
/// ...starting from a warm start that fails at least this share (else the task is too easy
/// for it to show anything).
pub const MIN_WARM_START_INFRACTION_PCT: f64 = 50.0;
/// Credit passes when the push towards braking has at least this t statistic and the steering
/// push stays below it.
pub const CREDIT_MIN_T: f64 = 3.0;
/// PPO iterations in which credit trains the value network (the policy stays the warm start)
/// before measuring.
pub const CREDIT_VALUE_ITERATIONS: usize = 4;

/// How the probes run.
#[derive(Debug, Clone)]
pub struct ProbeSettings {
    /// The run file the probes train with: its method must be RL; its model, warm start
    /// (`init`), PPO, optimizer and run sections are used, its data and alpha replaced by the
    /// task's scenarios.
    pub base: TrainConfig,
    /// PPO iterations (of `base.ppo.batch` initial states) per trained task.
    pub iterations: usize,
    pub train_scenarios: usize,
    pub eval_scenarios: usize,
    /// Seeds the scenario draws (the run's own randomness is `base.seed`).
    pub scenario_seed: u64,
    /// Keep each task's run folder (checkpoints, curves) as `out/<task>`; `None`: a temporary
    /// folder, removed afterwards.
    pub out: Option<PathBuf>,
}

/// One task's result (the `--json` object's entries).
#[derive(Debug, Clone, Serialize)]
pub struct TaskReport {
    pub name: &'static str,
    /// Held-out cars with a collision or off-road event under the mean action (%).
    pub infraction_pct_before: f64,
    pub infraction_pct_after: f64,
    /// Mean undiscounted training reward per car of sampled rollouts on the held-out draws.
    pub reward_before: f64,
    pub reward_after: f64,
    /// Agent-steps PPO collected (trained tasks) or scored (credit).
    pub agent_steps: usize,
    pub wall_s: f64,
    pub passed: bool,
    /// Credit only: the push on the mean acceleration and steering.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub push: Option<[ControlPush; 2]>,
}

/// The state a probe measures and trains: its scenes and the run around them.
struct TaskData {
    scenarios: ProbeScenarios,
    eval_scenes: Vec<Scene>,
    training: TrainingData,
}

impl TaskData {
    fn new(
        task: ProbeTask,
        settings: &ProbeSettings,
        dataset: &A9Dataset,
        stats: &TrafficStatistics,
    ) -> Result<Self> {
        let scenarios = probe_scenarios(
            task,
            stats,
            settings.train_scenarios,
            settings.eval_scenarios,
            settings.scenario_seed,
        )?;
        let eval_scenes = scenes_of(&scenarios.eval)?;
        let longtail = scenarios
            .train
            .iter()
            .map(|s| s.to_scene().map(|scene| (s.clone(), scene)))
            .collect::<Result<Vec<_>>>()?;
        // The recorded scenes are never drawn (alpha = 1); the warm start's sigma may be
        // measured on them (`init.std_from_logs`).
        let nominal = if settings.base.init.as_ref().is_some_and(|i| i.std_from_logs) {
            dataset.scenes(&SceneConfig::default())?.train
        } else {
            Vec::new()
        };
        let training = TrainingData {
            nominal_sources: vec![(0..nominal.len(), 1.0)],
            nominal,
            bent: 0..0,
            longtail,
            curated: Vec::new(),
        };
        Ok(Self {
            scenarios,
            eval_scenes,
            training,
        })
    }
}

fn scenes_of(scenarios: &[crate::scenario::ConcreteScenario]) -> Result<Vec<Scene>> {
    scenarios.iter().map(|s| s.to_scene()).collect()
}

/// The run file of a probe: `base` on the task's scenarios alone, `iterations` PPO
/// iterations at a constant learning rate, one checkpoint at the end.
fn probe_config(settings: &ProbeSettings) -> Result<TrainConfig> {
    let mut config = settings.base.clone();
    if config.method != Method::Rl {
        return Err(Error::InvalidArgument(format!(
            "the PPO probes train PPO alone: the run file's method must be RL, not {}",
            config.method.name()
        )));
    }
    config.alpha = 1.0;
    config.optimizer.epochs = 1;
    config.optimizer.epoch_scenes = Some(config.ppo.batch * settings.iterations.max(1));
    config.run.max_iterations = None;
    config.run.checkpoint_every = settings.iterations.max(1);
    Ok(config)
}

/// Runs `tasks` and reports each; `dataset` gives the vehicle sizes (and the logs a sigma may
/// be measured on).
pub fn run_probes(
    tasks: &[ProbeTask],
    settings: &ProbeSettings,
    dataset: &A9Dataset,
    progress: &dyn Fn(&str),
) -> Result<Vec<TaskReport>> {
    check_settings(tasks, settings)?;
    let stats = TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
    tasks
        .iter()
        .map(|&task| {
            let data = TaskData::new(task, settings, dataset, &stats)?;
            progress(&format!(
                "{}: {} training and {} held-out scenarios",
                task.name(),
                data.scenarios.train.len(),
                data.scenarios.eval.len()
            ));
            match task {
                ProbeTask::Credit => credit_task(settings, &data),
                _ => trained_task(task, settings, &data, progress),
            }
        })
        .collect()
}

/// Refuses, before any data is loaded or scenario drawn, what [`run_probes`] would refuse
/// about its settings: a run file of another method than RL, an `--out` that would stay empty
/// (`credit` alone trains nothing), an earlier probe's run in a task's folder.
pub fn check_settings(tasks: &[ProbeTask], settings: &ProbeSettings) -> Result<()> {
    probe_config(settings)?;
    if settings.out.is_some() && tasks.iter().all(|&t| t == ProbeTask::Credit) {
        return Err(Error::InvalidArgument(
            "--out: `credit` measures PPO's gradient without training, so it writes no run \
             folder and --out would stay empty; drop --out, or add a trained task (brake, \
             recover)"
                .into(),
        ));
    }
    // A probe always trains afresh (it has no --resume): an earlier probe's run in a task's
    // folder is refused before any work, by the flag the user can change.
    for &task in tasks {
        let (dir, _) = run_dir(task, settings);
        if super::checkpoint::has_checkpoint(&dir) {
            return Err(Error::InvalidArgument(format!(
                "--out: {} already holds a probe run of `{}`; probes always start afresh, so \
                 choose another --out folder or remove that one",
                dir.display(),
                task.name()
            )));
        }
    }
    Ok(())
}

/// The run folder of `task` and whether it is temporary.
fn run_dir(task: ProbeTask, settings: &ProbeSettings) -> (PathBuf, bool) {
    match &settings.out {
        Some(out) => (out.join(task.name()), false),
        None => (
            std::env::temp_dir().join(format!("rtr-probe-{}-{}", task.name(), std::process::id())),
            true,
        ),
    }
}

/// Mean-action infractions and sampled reward of the networks on the held-out scenes.
fn measure(
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    config: &TrainConfig,
    data: &TaskData,
    device: &burn::prelude::Device,
) -> Result<(f64, f64)> {
    let dynamics = config.dynamics(device)?;
    let eval = parts(&data.scenarios.eval, &data.eval_scenes);
    let infractions = infraction_pct(policy, &eval, &dynamics, device)?;
    let reward = sampled_return(
        policy,
        value,
        &eval,
        &dynamics,
        &config.ppo,
        config.seed ^ 0x5EED,
        device,
    )?;
    Ok((infractions, reward))
}

fn trained_task(
    task: ProbeTask,
    settings: &ProbeSettings,
    data: &TaskData,
    progress: &dyn Fn(&str),
) -> Result<TaskReport> {
    let started = Instant::now();
    let config = probe_config(settings)?;
    let (dir, temporary) = run_dir(task, settings);
    if temporary {
        let _ = crate::io::remove_folder(&dir);
    }
    let devices = super::session::devices(&config)?;
    let plain = devices[0].clone().inner();
    let mut trainer = Trainer::new(config.clone(), &data.training, devices, &dir, false)?;
    let (infraction_before, reward_before) = measure(
        &trainer.policy().valid(),
        &trainer.value().valid(),
        &config,
        data,
        &plain,
    )?;
    progress(&format!(
        "{}: before {infraction_before:.1} % infractions, reward {reward_before:.3}",
        task.name()
    ));
    let outcome = trainer.run(&ProgressBar::hidden(), None);
    let after = outcome.and_then(|_| {
        measure(
            &trainer.policy().valid(),
            &trainer.value().valid(),
            &config,
            data,
            &plain,
        )
    });
    let agent_steps = collected_agent_steps(trainer.curves());
    if temporary {
        let _ = crate::io::remove_folder(&dir);
    }
    let (infraction_after, reward_after) = after?;
    progress(&format!(
        "{}: after {infraction_after:.1} % infractions, reward {reward_after:.3} \
         ({agent_steps} agent-steps)",
        task.name()
    ));
    Ok(TaskReport {
        name: task.name(),
        infraction_pct_before: infraction_before,
        infraction_pct_after: infraction_after,
        reward_before,
        reward_after,
        agent_steps,
        wall_s: started.elapsed().as_secs_f64(),
        passed: infraction_before >= MIN_WARM_START_INFRACTION_PCT
            && infraction_after <= PASS_INFRACTION_PCT,
        push: None,
    })
}

/// Agent-steps collected over the run (each iteration's rows repeat its collection's count).
fn collected_agent_steps(rows: &[super::CurveRow]) -> usize {
    let mut total = 0;
    let mut last_iteration = None;
    for row in rows {
        if last_iteration != Some(row.iteration) {
            total += row.ppo_agent_steps;
            last_iteration = Some(row.iteration);
        }
    }
    total
}

fn credit_task(settings: &ProbeSettings, data: &TaskData) -> Result<TaskReport> {
    let started = Instant::now();
    // Only the value network trains (the trainer's value warm-up), so the advantages are
    // measured against a baseline of the task rather than a random one; the policy is the
    // warm start exactly as a run builds it (sigma included).
    let config = probe_config(&ProbeSettings {
        iterations: CREDIT_VALUE_ITERATIONS,
        ..settings.clone()
    })
    .map(|mut c| {
        c.ppo.value_warmup_iterations = CREDIT_VALUE_ITERATIONS;
        c
    })?;
    let scratch = std::env::temp_dir().join(format!("rtr-probe-credit-{}", std::process::id()));
    let _ = crate::io::remove_folder(&scratch);
    let devices = super::session::devices(&config)?;
    let plain = devices[0].clone().inner();
    let trained = Trainer::new(config.clone(), &data.training, devices, &scratch, false).and_then(
        |mut trainer| {
            trainer.run(&ProgressBar::hidden(), None)?;
            Ok(trainer)
        },
    );
    let _ = crate::io::remove_folder(&scratch);
    let trainer = trained?;
    let (policy, value) = (trainer.policy().valid(), trainer.value().valid());
    let (infractions, reward) = measure(&policy, &value, &config, data, &plain)?;
    let dynamics = config.dynamics(&plain)?;
    let nets = CollectNetworks {
        policy: &policy,
        value: &value,
        reference: None,
    };
    let rewards = RewardSettings::of(&config);
    let mut caches = MapCaches::default();
    let eval = parts(&data.scenarios.eval, &data.eval_scenes);
    let experiences = eval
        .iter()
        .map(|part| {
            collect(
                part,
                &nets,
                &plain,
                &dynamics,
                &mut caches,
                None,
                &config.ppo,
                &rewards,
                config.seed,
            )
        })
        .collect::<Result<Vec<_>>>()?;
    let push = credit::mean_action_push(&policy, &experiences, &config.ppo);
    let [acceleration, steering] = push;
    // With the steering not explored its push is 0 by construction, which proves nothing.
    let both_explored = config.ppo.explored_controls() == [true, true];
    Ok(TaskReport {
        name: ProbeTask::Credit.name(),
        infraction_pct_before: infractions,
        infraction_pct_after: infractions,
        reward_before: reward,
        reward_after: reward,
        agent_steps: experiences.iter().map(|e| e.stats.agent_steps).sum(),
        wall_s: started.elapsed().as_secs_f64(),
        passed: both_explored && acceleration.t <= -CREDIT_MIN_T && steering.t.abs() < CREDIT_MIN_T,
        push: Some(push),
    })
}
