//! `rtr eval`: evaluate trained policies on the nominal, long-tail, OOD and CommonRoad sets.

use std::path::PathBuf;

use clap::Args;

use rtr::backend::Backend;
use rtr::data::{SceneConfig, bend_scenes, commonroad};
use rtr::eval::study::{Entry, evaluate_entries, load_entries, write_study};
use rtr::eval::{EvalConfig, EvalScenes, EvalSet, load_sets, markdown_table};
use rtr::io::{Inputs, OutputClaim, StagedFolder, check_result_folder, claim_output_folder};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

#[derive(Args)]
pub struct EvalArgs {
    /// A finished run folder (runs/<name>, models/<method>), a checkpoints/iter-* folder or a
    /// policy.bpk beside its run's config.toml. Repeat for more rows.
    #[arg(long = "checkpoint")]
    checkpoints: Vec<PathBuf>,
    /// Also evaluate the IDM + lane-keeping reference driver (not learned).
    #[arg(long)]
    idm: bool,
    /// Scene sets, comma-separated: nominal, longtail, ood.
    #[arg(long, value_delimiter = ',', default_value = "nominal")]
    set: Vec<String>,
    /// Scenarios from `rtr scenarios generate` (its eval/ and ood/); default: draw the
    /// default sets now (about a minute).
    #[arg(long)]
    scenarios: Option<PathBuf>,
    /// CommonRoad scenario files (.xml, .xml.gz) or folders of them: their recorded scenes
    /// become the `commonroad` set, next to the sets of --set. Repeatable.
    #[arg(long = "commonroad")]
    commonroad: Vec<PathBuf>,
    /// Speed limit (m/s) of CommonRoad lanes whose file gives none (default: 130 km/h).
    #[arg(long, requires = "commonroad")]
    commonroad_speed_limit: Option<f64>,
    /// Evaluate the nominal set on the A9 road bent by this curvature (1/m, added to its
    /// reference line; not in the paper): the same recorded test scenes on a road of another
    /// curvature, to see whether policies follow the lane or the A9's curve.
    #[arg(long, allow_hyphen_values = true)]
    a9_bend: Option<f64>,
    /// Evaluate the long-tail and OOD sets with every generated road carrying this speed limit
    /// (km/h; they are built with 120) instead: a probe of how much a policy steers by the
    /// limit, which every recorded road holds constant (not in the paper).
    #[arg(long)]
    generated_speed_limit: Option<f64>,
    /// Write results.json, table.md and the figures here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Bootstrap resamples over scenes for the +- intervals (at least 100).
    #[arg(long, default_value_t = 1000, value_parser = count(100, 1_000_000))]
    resamples: usize,
    /// Scenes per tensor batch.
    #[arg(long, default_value_t = 16, value_parser = count(1, 4096))]
    batch: usize,
    /// Evaluate only the first N scenes of each set (a quick look).
    #[arg(long, value_parser = count(1, 1_000_000))]
    scenes: Option<usize>,
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

/// Checks the inputs and claims `--out` (if given) before any work.
fn claim_output(args: &EvalArgs) -> Result<Option<OutputClaim>> {
    for path in &args.checkpoints {
        rtr::io::check_input_path(path, "--checkpoint")?;
    }
    if let Some(dir) = &args.scenarios {
        rtr::io::check_input_folder(dir, "--scenarios", SCENARIO_FOLDER)?;
    }
    let inputs =
        rtr::eval::trained::with_run_inputs(Inputs::new(), "--checkpoint", &args.checkpoints)?
            .with_all("--scenarios", &args.scenarios)
            .with_all("--commonroad", &args.commonroad)
            .with("--data", args.data.dir());
    let Some(out) = &args.out else {
        return Ok(None);
    };
    let claim = claim_output_folder(out, "--out", &inputs)?;
    check_result_folder(out, EVAL_RESULTS, &EVAL_FILES)?;
    Ok(Some(claim))
}

/// What `--scenarios` names.
pub const SCENARIO_FOLDER: &str =
    "the folder `rtr scenarios generate --out` wrote (holding train/, eval/, ood/)";

/// The kind of result set `rtr eval --out` writes, and its top-level files and folders.
const EVAL_RESULTS: &str = "rtr eval";
const EVAL_FILES: [&str; 4] = ["results.json", "table.md", "figures", "commonroad.json"];

pub fn run(args: EvalArgs) -> Result<()> {
    if args.checkpoints.is_empty() && !args.idm {
        return Err(Error::InvalidArgument(
            "nothing to evaluate: pass --checkpoint DIR (repeatable) and/or --idm".into(),
        ));
    }
    let _claim = claim_output(&args)?;
    if let Some(problem) = args.a9_bend.and_then(rtr::map::bend_curvature_problem) {
        return Err(Error::InvalidArgument(format!("--a9-bend {problem}")));
    }
    if let Some(kmh) = args.generated_speed_limit {
        let max = rtr::data::track::MAX_SPEED * 3.6;
        if !(kmh > 0.0 && kmh <= max) {
            return Err(Error::InvalidArgument(format!(
                "--generated-speed-limit {kmh}: expected a speed limit in (0, {max}] km/h"
            )));
        }
    }
    let mut sets = EvalSet::parse_list(&args.set)?;
    let generated = |s: &EvalSet| matches!(s, EvalSet::Longtail | EvalSet::Ood);
    if args.generated_speed_limit.is_some() && !sets.iter().any(generated) {
        return Err(Error::InvalidArgument(
            "--generated-speed-limit changes the generated roads: add longtail or ood to --set"
                .into(),
        ));
    }
    let device = args.backend.device(false)?;
    let commonroad = commonroad_set(&args.commonroad, args.commonroad_speed_limit)?;
    let entries = load_entries(&args.checkpoints, args.idm, &device)?;
    for (path, entry) in args.checkpoints.iter().zip(&entries) {
        if let Entry::Trained(t) = entry
            && let Some(note) = t.unfinished_note(path, "evaluating")
        {
            rtr::errln!("{note}");
        }
    }
    let dataset = args.data.load()?;
    sets.retain(|&s| s != EvalSet::CommonRoad || commonroad.is_none());
    let mut scenes = load_sets(&dataset, args.scenarios.as_deref(), &sets)?;
    if let Some(curvature) = args.a9_bend {
        let nominal = scenes
            .iter_mut()
            .find(|s| s.set == EvalSet::Nominal)
            .ok_or_else(|| {
                Error::InvalidArgument("--a9-bend bends the nominal set: add it to --set".into())
            })?;
        nominal.scenes = bend_scenes(&nominal.scenes, curvature)?;
    }
    if let Some(kmh) = args.generated_speed_limit {
        for set in scenes.iter_mut().filter(|s| generated(&s.set)) {
            set.set_speed_limit(kmh / 3.6);
        }
    }
    let mut clip_summaries = Vec::new();
    if let Some((set, summaries)) = commonroad {
        sets.push(EvalSet::CommonRoad);
        scenes.push(set);
        clip_summaries = summaries;
    }
    if let Some(n) = args.scenes {
        scenes.iter_mut().for_each(|s| s.keep_first(n));
    }
    let config = EvalConfig {
        batch: args.batch,
        resamples: args.resamples,
        ..EvalConfig::default()
    };
    let progress = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(
            "eval [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
        )
        .map_err(|e| Error::InvalidArgument(format!("progress template: {e}")))?,
    );
    let results = evaluate_entries(&entries, &scenes, &device, &config, &progress)?;
    progress.finish_and_clear();
    // The files first: a reader of stdout that goes away (`| head`) must not cost them.
    let mut wrote = None;
    if let Some(out) = &args.out {
        // Tables and figures land together or not at all (a figure that fails leaves no table).
        let staged = StagedFolder::new(out, EVAL_RESULTS)?;
        let written = staged.fill(|dir| {
            let mut written = write_study(dir, &entries, &results, &scenes, &device)?;
            if !clip_summaries.is_empty() {
                let path = dir.join("commonroad.json");
                let text = serde_json::to_string_pretty(&clip_summaries)
                    .map_err(|e| Error::InvalidArgument(format!("cannot encode clips: {e}")))?;
                rtr::io::atomic_write(&path, text.as_bytes())?;
                written.push(path);
            }
            Ok(written)
        })?;
        staged.commit()?;
        wrote = Some(format!(
            "wrote {} files to {}",
            written.len(),
            out.display()
        ));
    }
    rtr::out!("{}", markdown_table(&results, &sets))?;
    if let Some(line) = wrote {
        rtr::outln!("{line}")?;
    }
    Ok(())
}

/// The `commonroad` eval set from the files and folders of `--commonroad`, with one line per
/// file on stderr saying what it gave; `None` without paths.
fn commonroad_set(
    paths: &[PathBuf],
    speed_limit: Option<f64>,
) -> Result<Option<(EvalScenes, Vec<commonroad::ClipSummary>)>> {
    if paths.is_empty() {
        return Ok(None);
    }
    for path in paths {
        rtr::io::check_input_path(path, "--commonroad")?;
    }
    let clips = commonroad::load_commonroad(paths, speed_limit)?;
    let (scenes, summaries) = commonroad::commonroad_scenes(&clips, &SceneConfig::default())?;
    rtr::io::console::write_stderr(&commonroad::describe_clips(&summaries));
    if scenes.is_empty() {
        return Err(Error::InvalidArgument(
            "the CommonRoad files yield no scene (each file's reason is printed above)".into(),
        ));
    }
    Ok(Some((EvalScenes::commonroad(scenes), summaries)))
}
