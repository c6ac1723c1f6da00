//! `rtr sim2real`: identify and fit the physics the simulator leaves out of vehicle recordings.

use std::path::PathBuf;

use clap::Args;

use rtr::io::{Inputs, StagedFolder, claim_output_folder};
use rtr::sim2real::{
    CommandTiming, Sim2RealOptions, a9::a9_recordings, identify, plots::write_plots, thinning,
};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

/// The kind of result set `rtr sim2real` writes.
const KIND: &str = "rtr sim2real";
/// The JSON report in the result folder.
const REPORT: &str = "report.json";
/// The identified terms (TOML) in the result folder, for `rtr train --dynamics`.
const DYNAMICS: &str = "dynamics.toml";

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
    /// Result folder: `report.json`, `dynamics.toml` (the identified terms, for `rtr train
    /// --dynamics` or a run file's `dynamics`) and the plots (`regimes.svg`, `excess.svg`,
    /// `hypotheses.svg`, `tracks.svg`), written together: an interrupted run leaves the
    /// earlier results whole.
    #[arg(long)]
    out: PathBuf,
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
    let _claim = claim_output_folder(&args.out, "--out", &inputs)?;
    let mut names = vec![REPORT, DYNAMICS];
    names.extend(rtr::sim2real::plots::PLOT_FILES);
    rtr::io::check_result_folder(&args.out, KIND, &names)?;
    let mut source_sha256 = None;
    let (recordings, commands_inferred) = match &args.recordings {
        Some(path) => {
            rtr::io::check_input_file(path, "--recordings")?;
            // Read once: the digest is of exactly what was fitted, whatever lies at the path
            // later (another command may replace it).
            let text = rtr::data::recordings::read_recordings_text(path)?;
            source_sha256 = Some(rtr::data::automatum::sha256_hex(text.as_bytes()));
            (
                rtr::data::Recordings::parse(&path.display().to_string(), &text)?,
                false,
            )
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
    let mut outcome = identify(&recordings, &options, &|stage: &str| {
        progress.set_message(stage.to_string())
    })?;
    outcome.report.source_sha256 = source_sha256;
    progress.finish_and_clear();
    let report = &outcome.report;
    for line in report.summary() {
        rtr::outln!("{line}")?;
    }
    write_results(&args.out, &outcome)?;
    rtr::outln!("report: {}", args.out.join(REPORT).display())?;
    rtr::outln!(
        "dynamics ({} terms): {}",
        report.dynamics().terms.len(),
        args.out.join(DYNAMICS).display()
    )?;
    Ok(())
}

/// The report, the dynamics file and the plots, staged and swapped in as one result set: a
/// failure or a kill on the way leaves the folder's earlier results as they were.
fn write_results(out: &std::path::Path, outcome: &rtr::sim2real::Outcome) -> Result<()> {
    let report = &outcome.report;
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode the report: {e}")))?;
    let staged = StagedFolder::new(out, KIND)?;
    staged.fill(|dir| {
        rtr::io::atomic_write(&dir.join(REPORT), json.as_bytes())?;
        rtr::io::atomic_write(&dir.join(DYNAMICS), report.dynamics().to_toml()?.as_bytes())?;
        write_plots(dir, outcome)
    })?;
    staged.commit()
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
