//! `rtr train`: train a policy from a run file into a run folder.

use std::path::{Path, PathBuf};

use clap::Args;

use rtr::io::{Inputs, claim_output_folder};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

#[derive(Args)]
pub struct TrainArgs {
    /// The run file (TOML).
    #[arg(long)]
    config: PathBuf,
    /// Run folder; default: runs/<config file stem>.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Continue the run in OUT from its last checkpoint (same result as an uninterrupted run).
    #[arg(long)]
    resume: bool,
    /// Physics terms from `rtr sim2real` (`dynamics.toml` in its `--out`), replacing the run
    /// file's `dynamics`.
    #[arg(long)]
    dynamics: Option<PathBuf>,
    /// Long-tail training scenarios: the folder `rtr scenarios generate --out` wrote (its
    /// train/ set is used), replacing the run file's `data.longtail_dir` (saves drawing them
    /// at start).
    #[arg(long)]
    scenarios: Option<PathBuf>,
    /// Keep this many checkpoints besides the newest (default: the run file's
    /// `run.keep_checkpoints`, else 1), e.g. to evaluate the last few side by side.
    #[arg(long)]
    keep_checkpoints: Option<usize>,
    /// Stop after this many iterations of this call, with a checkpoint (continue it with
    /// --resume): a long run in sittings, or a quick look at a run file.
    #[arg(long, value_parser = count(1, 1_000_000_000))]
    stop_after: Option<usize>,
    #[command(flatten)]
    data: DataArgs,
}

/// `dir` without its `.` parts, so `./scenarios/` resumes a run started with `scenarios`.
fn without_dot_parts(dir: &Path) -> PathBuf {
    let spelt: PathBuf = dir
        .components()
        .filter(|c| !matches!(c, std::path::Component::CurDir))
        .collect();
    if spelt.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        spelt
    }
}

pub fn run(args: TrainArgs) -> Result<()> {
    rtr::io::check_input_file(&args.config, "--config")?;
    let mut config = rtr::train::TrainConfig::from_toml_file(&args.config)?;
    if let Some(path) = &args.dynamics {
        rtr::io::check_input_file(path, "--dynamics")?;
        // Absolute in the run's config.toml, so the run evaluates from any folder.
        config.dynamics = Some(path.canonicalize().unwrap_or_else(|_| path.clone()));
    }
    if let Some(dir) = &args.scenarios {
        if !config.uses_longtail() {
            return Err(Error::InvalidArgument(format!(
                "--scenarios {}: {} trains on no long-tail scenarios (alpha = {}{}), so the \
                 folder would be ignored; drop --scenarios, or give the run a share of them",
                dir.display(),
                args.config.display(),
                config.alpha,
                if config.data.curated.is_some() {
                    ", and a curated scene list"
                } else {
                    ""
                }
            )));
        }
        rtr::io::check_input_folder(dir, "--scenarios", super::eval::SCENARIO_FOLDER)?;
        if !dir.join("train").is_dir() {
            return Err(Error::InvalidArgument(format!(
                "--scenarios {}: no train/ folder in it; expected {}",
                dir.display(),
                super::eval::SCENARIO_FOLDER
            )));
        }
        config.data.longtail_dir = Some(without_dot_parts(dir));
        config.validate(&format!("{} with --scenarios", args.config.display()))?;
    }
    if let Some(keep) = args.keep_checkpoints {
        config.run.keep_checkpoints = Some(keep);
    }
    // Checked here, not with the file: a finished run's config.toml loads in any build.
    if !config.run.backend.is_compiled() {
        let name = config.run.backend;
        return Err(Error::invalid(
            args.config.display().to_string(),
            "field `run.backend`",
            format!("rtr was built without `{name}`: rebuild with `--features {name}`"),
        ));
    }
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .config
            .file_stem()
            .map_or("run".into(), |s| s.to_owned());
        PathBuf::from("runs").join(stem)
    });
    let inputs = config.input_paths().into_iter().fold(
        Inputs::new()
            .with("--config", &args.config)
            .with("--data", args.data.dir()),
        |inputs, (field, path)| inputs.with(field, path),
    );
    let _claim = claim_output_folder(&out, "--out", &inputs)?;
    // A new run's folder holding files but no run is refused here too.
    rtr::train::checkpoint::resume_point(&out, args.resume)?;
    check_named_inputs(&config, args.resume)?;
    let dataset = args.data.load()?;
    let method = config.method.name();
    let progress = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} iterations, eta {eta} {msg}",
        )
        .map_err(|e| Error::InvalidArgument(format!("progress template: {e}")))?,
    );
    progress.set_prefix(method.to_string());
    let created = !out.exists();
    let summary = rtr::train::session::train(
        config,
        &dataset,
        &out,
        args.resume,
        args.stop_after,
        &progress,
    )
    .inspect_err(|_| {
        if !args.resume {
            remove_unfinished_run(&out, created);
        }
    })?;
    progress.finish();
    if !out.join("policy.bpk").is_file() {
        rtr::outln!(
            "stopped after {} of the run's iterations (--stop-after); continue with --resume",
            summary.iterations
        )?;
    }
    rtr::outln!(
        "{method}: {} iterations, {} optimizer steps; checkpoint {}; curves {}",
        summary.iterations,
        summary.updates,
        summary.checkpoint.display(),
        out.join("curves.csv").display()
    )?;
    if let Some(last) = summary.last {
        rtr::outln!(
            "last step: loss {:.5} (IL {:.5}, BC {:.5}, PPO policy {:.5}, value {:.5}, KL {:.5}); \
             rollout collisions {:.1}%, off-road {:.1}%",
            last.loss,
            last.il_loss,
            last.bc_loss,
            last.policy_loss,
            last.value_loss,
            last.kl,
            last.collision_pct,
            last.offroad_pct
        )?;
    }
    Ok(())
}

/// The files and folders the run file names, each there and of a readable kind, checked
/// before the data loads: a typo is named at once, not after the loading. A resumed run
/// does not read its warm start again.
fn check_named_inputs(config: &rtr::train::TrainConfig, resume: bool) -> Result<()> {
    for (field, path) in config.input_paths() {
        let path = match (field, &config.init) {
            ("init.policy", _) if resume => continue,
            ("init.policy", Some(init)) => init.policy_file(),
            _ => path,
        };
        rtr::io::check_input_path(&path, field).map_err(|e| e.in_field(field))?;
        rtr::io::check_size(&path, rtr::train::identity::format_of(field))
            .map_err(|e| e.in_field(field))?;
    }
    Ok(())
}

/// A fresh run that failed before its first checkpoint (bad data found late, divergence at the
/// first step) leaves nothing: the folder if this run created it, else the files it wrote.
fn remove_unfinished_run(out: &Path, created: bool) {
    if rtr::train::checkpoint::has_checkpoint(out) {
        return;
    }
    if created {
        let _ = rtr::io::remove_folder(out);
    } else {
        for name in ["config.toml", "curves.csv"] {
            let _ = rtr::io::remove_file(&out.join(name));
        }
        let _ = rtr::io::remove_folder(&out.join(rtr::train::kept_inputs::KEPT_FOLDER));
    }
}
