//! `rtr sim2real`: identify and fit the physics the simulator leaves out of vehicle recordings.

use std::path::PathBuf;

use clap::Args;

use rtr::io::{Inputs, StagedFolder, claim_output_file, claim_output_folder};
use rtr::sim2real::{
    CommandTiming, Sim2RealOptions, a9::a9_recordings, identify, plots::write_plots, thinning,
};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

/// The kind of result set `rtr sim2real --plots` writes.
const PLOTS: &str = "rtr sim2real --plots";

#[derive(Args)]
pub struct Sim2RealArgs {
    /// Recordings CSV: track_id,t,x,y,heading,speed,accel_cmd,steer_cmd[,wheelbase] (SI).
    #[arg(long, required_unless_present = "a9", conflicts_with = "a9")]
    recordings: Option<PathBuf>,
    /// Use the shipped A9 drone recording instead (no commands recorded: they are inferred
    /// from the motion, so only effects outside the actuators can be identified).
    #[arg(long)]
    a9: bool,
    #[command(flatten)]
    data: DataArgs,
    /// Where to write the JSON report.
    #[arg(long)]
    report: PathBuf,
    /// Folder for plots (regimes.svg, tracks.svg).
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Write the identified terms (TOML) for `rtr train --dynamics` or a run file's `dynamics`.
    #[arg(long)]
    save_dynamics: Option<PathBuf>,
    /// Gradient-descent iterations per candidate.
    #[arg(long, default_value_t = 120, value_parser = count(1, 100_000))]
    iterations: usize,
    /// Horizon of the fitting and held-out windows (s).
    #[arg(long, default_value_t = 5.0)]
    horizon: f64,
    /// Seed of the train / held-out split.
    #[arg(long, default_value_t = 2023)]
    seed: u64,
    /// Only the catalogue's named effects compete; the open-ended stage's equation is still
    /// regressed and reported, but not kept.
    #[arg(long)]
    catalogue_only: bool,
    /// How the logged commands were applied between samples: `held` for the period after
    /// each sample (a controller at the log's rate), `sampled` from a controller faster than
    /// the log, or `auto`: fit both and keep the one held-out error or fewer terms favour
    /// (held when neither does; the report says which and why). Sampled commands read as
    /// held make lags and dead time about half a period short.
    #[arg(long, default_value = "auto")]
    command_timing: String,
}

pub fn run(args: Sim2RealArgs) -> Result<()> {
    if !(args.horizon > 0.0 && args.horizon <= 60.0) {
        return Err(Error::InvalidArgument(format!(
            "--horizon {}: expected seconds in (0, 60]",
            args.horizon
        )));
    }
    let command_timing = command_timing(&args.command_timing)?;
    let inputs = Inputs::new()
        .with_all("--recordings", &args.recordings)
        .with("--data", args.data.dir());
    let _report_claim = claim_output_file(&args.report, "--report", &inputs)?;
    check_distinct_outputs(&args)?;
    let _claim = match &args.plots {
        Some(dir) => {
            let claim = claim_output_folder(dir, "--plots", &inputs)?;
            rtr::io::check_result_folder(dir, PLOTS, &["regimes.svg", "tracks.svg"])?;
            Some(claim)
        }
        None => None,
    };
    let _dynamics_claim = match &args.save_dynamics {
        Some(path) => Some(claim_output_file(path, "--save-dynamics", &inputs)?),
        None => None,
    };
    let (recordings, commands_inferred) = match &args.recordings {
        Some(path) => {
            rtr::io::check_input_file(path, "--recordings")?;
            (rtr::data::Recordings::load(path)?, false)
        }
        None => (
            a9_recordings(&args.data.load()?, 0.1, args.horizon + 2.0),
            true,
        ),
    };
    if let Some(fast) = recordings.tracks.iter().find(|t| thinning(t.period) > 1) {
        rtr::outln!(
            "note: track `{}` is sampled every {:.4} s; tracks faster than 100 Hz are fitted on \
             one sample in {}",
            fast.id,
            fast.period,
            thinning(fast.period)
        )?;
    }
    let mut options = Sim2RealOptions {
        horizon_s: args.horizon,
        seed: args.seed,
        commands_inferred,
        discover: !args.catalogue_only,
        command_timing,
        ..Default::default()
    };
    options.fit.iterations = args.iterations;
    let progress = indicatif::ProgressBar::new_spinner();
    progress.enable_steady_tick(std::time::Duration::from_millis(200));
    let outcome = identify(&recordings, &options, &|stage: &str| {
        progress.set_message(stage.to_string())
    })?;
    progress.finish_and_clear();
    let report = &outcome.report;
    for line in report.summary() {
        rtr::outln!("{line}")?;
    }
    // Everything is rendered before anything is written, and written together: a plot that
    // fails leaves no report behind.
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode the report: {e}")))?;
    let dynamics = match &args.save_dynamics {
        Some(_) => Some(report.dynamics().to_toml()?),
        None => None,
    };
    let plots = match &args.plots {
        Some(dir) => {
            let staged = StagedFolder::new(dir, PLOTS)?;
            let written = write_plots(staged.path(), &outcome)?;
            Some((staged, written))
        }
        None => None,
    };
    rtr::io::atomic_write(&args.report, json.as_bytes())?;
    if let (Some(path), Some(text)) = (&args.save_dynamics, &dynamics) {
        rtr::io::atomic_write(path, text.as_bytes())?;
    }
    if let Some((staged, written)) = plots {
        let written: Vec<_> = written.iter().map(|p| staged.final_path(p)).collect();
        staged.commit()?;
        for path in written {
            rtr::outln!("plot: {}", path.display())?;
        }
    }
    rtr::outln!("report: {}", args.report.display())?;
    if let Some(path) = &args.save_dynamics {
        rtr::outln!(
            "dynamics ({} terms): {}",
            report.dynamics().terms.len(),
            path.display()
        )?;
    }
    Ok(())
}

/// The report, the dynamics file and the plots are different files: one written over another
/// would lose it.
fn check_distinct_outputs(args: &Sim2RealArgs) -> Result<()> {
    let same = |a: &std::path::Path, b: &std::path::Path| {
        a == b || matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
    };
    if let Some(dynamics) = &args.save_dynamics
        && same(dynamics, &args.report)
    {
        return Err(Error::InvalidArgument(format!(
            "--save-dynamics and --report are both {}; expected two different files",
            args.report.display()
        )));
    }
    if let Some(dir) = &args.plots {
        for path in std::iter::once(&args.report).chain(&args.save_dynamics) {
            if path.parent().is_some_and(|p| same(p, dir))
                && path
                    .file_name()
                    .is_some_and(|n| rtr::sim2real::plots::PLOT_FILES.iter().any(|p| n == *p))
            {
                return Err(Error::InvalidArgument(format!(
                    "{} is one of the plots --plots writes ({}); expected another name",
                    path.display(),
                    rtr::sim2real::plots::PLOT_FILES.join(", ")
                )));
            }
        }
    }
    Ok(())
}

/// `auto` (none: decided from the data) or a named timing.
fn command_timing(name: &str) -> Result<Option<CommandTiming>> {
    if name == "auto" {
        return Ok(None);
    }
    CommandTiming::from_name(name).map(Some).ok_or_else(|| {
        Error::InvalidArgument(format!(
            "unknown --command-timing `{name}`: expected auto, {}",
            CommandTiming::NAMES.join(" or ")
        ))
    })
}
