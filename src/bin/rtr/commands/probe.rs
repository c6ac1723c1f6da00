//! `rtr probe ppo`: PPO on tasks whose right behaviour is known (brake, recover, credit).

use std::path::PathBuf;

use clap::{Args, Subcommand};

use rtr::model::ModelConfig;
use rtr::train::probe::{ProbeSettings, ProbeTask, TaskReport, run_probes};
use rtr::train::{InitConfig, TrainConfig};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

#[derive(Subcommand)]
pub enum ProbeCommand {
    /// Train PPO alone on each probe task from a warm start and report the held-out infraction
    /// rate and training reward before and after (brake, recover), and the direction of the
    /// PPO gradient on each control (credit).
    Ppo(PpoProbeArgs),
}

#[derive(Args)]
pub struct PpoProbeArgs {
    /// Comma-separated tasks: brake, recover, credit.
    #[arg(long, default_value = "brake,recover,credit", value_delimiter = ',')]
    tasks: Vec<String>,
    /// The policy PPO starts from (a model folder or policy.bpk with its run's config.toml);
    /// its sigma is measured on the logs (`init.std_from_logs`). With --config it replaces
    /// the run file's `[init] policy` [default: models/il_ff]
    #[arg(long, conflicts_with = "small")]
    warm_start: Option<PathBuf>,
    /// Start from a fresh small network (the tests' size) instead of a warm start.
    #[arg(long)]
    small: bool,
    /// A run file with method = "RL" whose PPO, optimizer, model and init sections the probes
    /// use (its data and alpha are replaced); default: the trainer's defaults with the warm
    /// start above.
    #[arg(long, conflicts_with_all = ["small"])]
    config: Option<PathBuf>,
    /// PPO iterations per trained task (each of the run file's `ppo.batch` initial states).
    #[arg(long, default_value_t = 40, value_parser = count(1, 100_000))]
    iterations: usize,
    /// Training scenarios drawn per task.
    #[arg(long, default_value_t = 128, value_parser = count(1, 100_000))]
    train_scenarios: usize,
    /// Held-out scenarios the infraction rate and reward are measured on.
    #[arg(long, default_value_t = 128, value_parser = count(2, 100_000))]
    eval_scenarios: usize,
    /// Seed of the scenario draws.
    #[arg(long, default_value_t = 7)]
    scenario_seed: u64,
    /// Keep each trained task's run folder (checkpoints, curves.csv) as OUT/<task>.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print one JSON object {"tasks": [...]} instead of a table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    data: DataArgs,
}

pub fn run(command: ProbeCommand) -> Result<()> {
    let ProbeCommand::Ppo(args) = command;
    let tasks = args
        .tasks
        .iter()
        .map(|t| {
            ProbeTask::parse(t.trim()).map_err(|e| Error::InvalidArgument(format!("--tasks: {e}")))
        })
        .collect::<Result<Vec<_>>>()?;
    if let Some(k) = (1..tasks.len()).find(|&k| tasks[..k].contains(&tasks[k])) {
        return Err(Error::InvalidArgument(format!(
            "--tasks: `{}` is given twice; expected each task once",
            args.tasks[k].trim()
        )));
    }
    let base = base_config(&args)?;
    let inputs = rtr::eval::trained::with_run_inputs(
        rtr::io::Inputs::new().with_all("--config", &args.config),
        "--warm-start",
        &args.warm_start,
    )?;
    let _claim = match &args.out {
        Some(out) => Some(rtr::io::claim_output_folder(out, "--out", &inputs)?),
        None => None,
    };
    let settings = ProbeSettings {
        base,
        iterations: args.iterations,
        train_scenarios: args.train_scenarios,
        eval_scenarios: args.eval_scenarios,
        scenario_seed: args.scenario_seed,
        out: args.out.clone(),
    };
    rtr::train::probe::check_settings(&tasks, &settings)?;
    let dataset = args.data.load()?;
    let reports = run_probes(&tasks, &settings, &dataset, &|line| rtr::errln!("{line}"))
        .map_err(|e| warm_start_named(e, &args))?;
    if args.json {
        let json = serde_json::json!({ "tasks": reports });
        rtr::outln!("{json}")?;
    } else {
        rtr::outln!("{}", table(&reports))?;
    }
    Ok(())
}

/// An error of the warm start said of `--warm-start` where the user wrote no run file: the
/// probes' own run file, which names it as `init.policy`, is not one the user knows.
fn warm_start_named(error: Error, args: &PpoProbeArgs) -> Error {
    match error {
        Error::InvalidData {
            source_name,
            place,
            message,
        } if args.config.is_none()
            && source_name == "run file"
            && place == "field `init.policy`" =>
        {
            Error::InvalidArgument(format!("--warm-start: {message}"))
        }
        other => other,
    }
}

/// The run file the probes train with.
fn base_config(args: &PpoProbeArgs) -> Result<TrainConfig> {
    if let Some(path) = &args.config {
        rtr::io::check_input_file(path, "--config")?;
        let mut config = TrainConfig::from_toml_file(path)?;
        if let Some(warm_start) = &args.warm_start {
            check_warm_start(warm_start)?;
            let policy = std::path::absolute(warm_start).map_err(|e| Error::io(warm_start, e))?;
            config.init = Some(match config.init {
                Some(init) => InitConfig { policy, ..init },
                None => default_init(policy),
            });
        }
        return Ok(config);
    }
    let mut config = TrainConfig::from_toml_str("method = \"RL\"\n", "the probes' default run")?;
    if args.small {
        config.model = ModelConfig::small();
        return Ok(config);
    }
    let warm_start = args
        .warm_start
        .clone()
        .unwrap_or_else(|| PathBuf::from("models/il_ff"));
    config.model = TrainConfig::from_toml_file(&check_warm_start(&warm_start)?)?.model;
    config.init = Some(default_init(warm_start));
    Ok(config)
}

/// Starts from `policy` with the sigma measured on the logs.
fn default_init(policy: PathBuf) -> InitConfig {
    InitConfig {
        policy,
        std_from_logs: true,
        std_scale: [1.0, 1.0],
        add_agent_edge_motion: false,
        agent_edge_motion_scale: 1.0,
    }
}

/// The run file beside the warm start, checked as an input of --warm-start.
fn check_warm_start(warm_start: &std::path::Path) -> Result<PathBuf> {
    rtr::io::check_input_path(warm_start, "--warm-start")?;
    let run_file = warm_start_config(warm_start)?;
    rtr::io::check_input_file(&run_file, "--warm-start")?;
    // The policy itself, before any scenario is drawn.
    let policy = warm_start.join("policy.bpk");
    if warm_start.is_dir()
        && let Some(why) = rtr::io::not_regular(&policy)
    {
        return Err(Error::InvalidArgument(format!(
            "--warm-start {}: {}",
            policy.display(),
            why
        )));
    }
    if warm_start.is_dir() && !policy.is_file() {
        return Err(Error::InvalidArgument(format!(
            "--warm-start {}: no policy.bpk there: an unfinished run keeps its policy in \
             checkpoints/iter-*/ (name that folder), and a model folder holds one",
            warm_start.display()
        )));
    }
    Ok(run_file)
}

/// The run's `config.toml` beside a model folder or policy file (it names the model size).
fn warm_start_config(warm_start: &std::path::Path) -> Result<PathBuf> {
    let dir = if warm_start.is_file() {
        warm_start.parent().map(PathBuf::from).unwrap_or_default()
    } else {
        warm_start.to_path_buf()
    };
    // A checkpoint folder (`checkpoints/iter-*`) sits two levels below its run's config.
    let candidates = [
        dir.join("config.toml"),
        dir.join("../..").join("config.toml"),
    ];
    candidates.into_iter().find(|c| c.is_file()).ok_or_else(|| {
        Error::InvalidArgument(format!(
            "--warm-start {}: no config.toml there (a model folder such as models/il_ff, \
                 a finished run folder or a run's checkpoints/iter-* folder was expected)",
            warm_start.display()
        ))
    })
}

fn table(reports: &[TaskReport]) -> String {
    let mut out = String::from(
        "| task | infractions before % | after % | reward before | after | agent-steps | wall s | passed |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in reports {
        out.push_str(&format!(
            "| {} | {:.1} | {:.1} | {:.3} | {:.3} | {} | {:.0} | {} |\n",
            r.name,
            r.infraction_pct_before,
            r.infraction_pct_after,
            r.reward_before,
            r.reward_after,
            r.agent_steps,
            r.wall_s,
            if r.passed { "yes" } else { "no" }
        ));
        if let Some([acceleration, steering]) = &r.push {
            out.push_str(&format!(
                "\ncredit: PPO's push on the mean acceleration t = {:.1} (braking is negative), \
                 on the mean steering t = {:.1}, over {} cars\n",
                acceleration.t, steering.t, acceleration.cars
            ));
        }
    }
    out.trim_end().to_string()
}
