//! The `rtr` command-line tool. Thin: parses arguments, calls the library, prints.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};

use rtr::backend::Backend;
use rtr::data::{A9Dataset, SceneConfig, a9, commonroad, summarize};
use rtr::io::{OutputKind, check_output};
use rtr::map::{LaneGraph, Map, ProceduralMap, to_xodr};
use rtr::model::{ModelConfig, PolicyNetwork, ValueNetwork};
use rtr::render::{RenderOptions, output_paths, render_map, render_scene};
use rtr::{Error, Result};

/// A count flag within `min..=max`; clap's error names the flag, the value and the range.
fn count(min: u64, max: u64) -> impl clap::builder::TypedValueParser<Value = usize> {
    use clap::builder::TypedValueParser;
    clap::value_parser!(u64)
        .range(min..=max)
        .map(|v| usize::try_from(v).unwrap_or(usize::MAX))
}

#[derive(Parser)]
#[command(
    name = "rtr",
    version,
    about = "Learning realistic traffic agents in closed loop"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The nominal dataset (real A9 recording).
    Data {
        #[command(subcommand)]
        command: DataCommand,
    },
    /// Draw a scene of the nominal dataset (road, lane marks, boxes, history, logged future).
    Render(RenderArgs),
    /// Throughput benchmarks, printed as JSON.
    Bench {
        #[command(subcommand)]
        command: BenchCommand,
    },
    /// OpenDRIVE and procedural maps: describe, draw, export.
    Map {
        #[command(subcommand)]
        command: MapCommand,
    },
    /// The policy and value networks.
    Model {
        #[command(subcommand)]
        command: ModelCommand,
    },
    /// Long-tail scenarios: logical families, concrete sets.
    Scenarios {
        #[command(subcommand)]
        command: ScenariosCommand,
    },
    /// Train a policy from a run file (experiments/*/*.toml): BC, IL, RL, RL-Shaped, BC+RL,
    /// RTR, KL-L or KL-R. Writes OUT/curves.csv, OUT/config.toml and OUT/checkpoints/.
    Train(TrainArgs),
    /// Evaluate trained policies on the nominal (real A9 test), long-tail and OOD sets: prints
    /// the paper's table (Markdown, one row per checkpoint) and writes JSON and figures.
    Eval(EvalArgs),
    /// The lambda x alpha study: train RTR at every point from one base run file, then
    /// evaluate each (paper table "Balancing realism and infraction avoidance").
    Sweep(SweepArgs),
    /// The downstream study (paper section 4.2): each policy simulates the A9 training split,
    /// a trajectory predictor is trained on each simulated dataset and scored on the real test
    /// split (minFDE, minCTE over modes; mean +- std over seeds).
    Downstream(DownstreamArgs),
    /// List the nominal A9 training scenes a trained policy commits an infraction on (the
    /// paper's "Curated" scenario set): a scene list for a run file's `data.curated`.
    Curate(CurateArgs),
    /// Sim-to-real: locate where the simulator and vehicle recordings differ, name the physics
    /// the bicycle model left out, fit it and show held-out error before and after.
    Sim2real(Sim2RealArgs),
    /// Vehicle recordings for sim-to-real.
    Recordings {
        #[command(subcommand)]
        command: RecordingsCommand,
    },
}

#[derive(Args)]
struct EvalArgs {
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
    /// Write results.json, table.md and the figures here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Bootstrap resamples over scenes for the +- intervals (at least 100).
    #[arg(long, default_value_t = 1000, value_parser = count(100, 1_000_000))]
    resamples: usize,
    /// Scenes per tensor batch.
    #[arg(long, default_value_t = 16, value_parser = count(1, 4096))]
    batch: usize,
    #[arg(long, default_value_t = Backend::NdArray)]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

#[derive(Args)]
struct DownstreamArgs {
    /// A trained policy (run folder, models/<method>, checkpoint folder or policy.bpk).
    /// Repeat for more rows.
    #[arg(long = "checkpoint")]
    checkpoints: Vec<PathBuf>,
    /// Also generate data with the IDM + lane-keeping reference driver.
    #[arg(long)]
    idm: bool,
    /// Synthetic datasets and predictors per method.
    #[arg(long, default_value_t = 4, value_parser = count(1, 1000))]
    seeds: usize,
    /// Predictor training epochs.
    #[arg(long, default_value_t = rtr::predict::FitConfig::default().epochs, value_parser = count(1, 100_000))]
    epochs: usize,
    /// Write results.json and table.md here.
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value_t = Backend::NdArray)]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

#[derive(Args)]
struct CurateArgs {
    /// The policy to mine failures of (the paper uses IL): a run folder, models/<method>, a
    /// checkpoint folder or a policy.bpk.
    #[arg(long)]
    checkpoint: PathBuf,
    /// The scene list to write (one scene id per line).
    #[arg(long)]
    out: PathBuf,
    /// Scenes per tensor batch.
    #[arg(long, default_value_t = 16, value_parser = count(1, 4096))]
    batch: usize,
    #[arg(long, default_value_t = Backend::NdArray)]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

#[derive(Args)]
struct SweepArgs {
    /// The base run file (method RTR); lambda and alpha are set per point.
    #[arg(long)]
    config: PathBuf,
    /// Points LAMBDA:ALPHA, comma-separated; default: the paper's six.
    #[arg(long, default_value = "0:0,1:0.5,5:0.5,10:0.5,5:0.3,5:0.7")]
    points: String,
    /// Folder of the point runs (OUT/lambda<L>_alpha<A>), results.json and table.md.
    #[arg(long, default_value = "runs/sweep")]
    out: PathBuf,
    /// Scenarios from `rtr scenarios generate`, for training (train/) and evaluation (eval/,
    /// ood/); default: drawn now.
    #[arg(long)]
    scenarios: Option<PathBuf>,
    /// Scene sets to evaluate on, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "nominal,longtail")]
    set: Vec<String>,
    /// Bootstrap resamples over scenes (at least 100).
    #[arg(long, default_value_t = 1000, value_parser = count(100, 1_000_000))]
    resamples: usize,
    #[command(flatten)]
    data: DataArgs,
}

#[derive(Args)]
struct Sim2RealArgs {
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
}

#[derive(Subcommand)]
enum RecordingsCommand {
    /// Recordings from a plant with one concealed catalogue effect (or none), under sensor
    /// noise: a known answer for `rtr sim2real`.
    Generate {
        /// accel_lag, steer_lag, dead_time, drag, understeer, steer_rate_limit, sideslip, none,
        /// or physics outside the catalogue: speed_dependent_steering, brake_gain.
        #[arg(long)]
        effect: String,
        #[arg(long, default_value_t = 11)]
        seed: u64,
        /// One-minute tracks to generate.
        #[arg(long, default_value_t = 24, value_parser = count(3, 10_000))]
        tracks: usize,
        /// Output CSV.
        #[arg(long)]
        out: PathBuf,
    },
}

#[derive(Args)]
struct TrainArgs {
    /// The run file (TOML).
    #[arg(long)]
    config: PathBuf,
    /// Run folder; default: runs/<config file stem>.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Continue the run in OUT from its last checkpoint (same result as an uninterrupted run).
    #[arg(long)]
    resume: bool,
    /// Physics terms from `rtr sim2real --save-dynamics`, replacing the run file's `dynamics`.
    #[arg(long)]
    dynamics: Option<PathBuf>,
    /// Long-tail training scenarios from `rtr scenarios generate` (its train/), replacing the
    /// run file's `data.longtail_dir` (saves drawing them at start).
    #[arg(long)]
    scenarios: Option<PathBuf>,
    #[command(flatten)]
    data: DataArgs,
}

#[derive(Subcommand)]
enum ScenariosCommand {
    /// Draw the default train / eval / OOD sets (167 / 166 / 84) from the family files and
    /// write one JSON file per concrete scenario to OUT/train, OUT/eval, OUT/ood.
    Generate {
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = rtr::scenario::DEFAULT_SEED)]
        seed: u64,
        /// Folder of family files (*.toml, searched recursively); default: the shipped ones.
        #[arg(long)]
        families: Option<PathBuf>,
        /// Concrete scenarios from the training families (split alternately into train/eval).
        #[arg(long, default_value_t = 333)]
        in_distribution: usize,
        /// Concrete scenarios from the held-out families.
        #[arg(long, default_value_t = 84)]
        ood: usize,
        #[command(flatten)]
        data: DataArgs,
    },
    /// List the families with their set and description.
    List {
        #[arg(long)]
        families: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum ModelCommand {
    /// Configuration and parameter counts of the policy and value networks.
    Info {
        /// A model config (TOML); missing fields take the paper's defaults.
        #[arg(long)]
        config: Option<PathBuf>,
        /// The small configuration of the tests and the quick example.
        #[arg(long, conflicts_with = "config")]
        small: bool,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
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
struct TrainBenchArgs {
    #[command(flatten)]
    data: DataArgs,
    #[arg(long, default_value = "ndarray")]
    backend: Backend,
    /// The small network of the tests instead of the paper's (hidden 128).
    #[arg(long)]
    small: bool,
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
struct BenchArgs {
    #[command(flatten)]
    data: DataArgs,
    /// ndarray, flex or wgpu (the latter two need their cargo features).
    #[arg(long, default_value = "ndarray")]
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

#[derive(Subcommand)]
enum MapCommand {
    /// Road length, lanes and lane-graph size as JSON.
    Summary(MapSource),
    /// Draw the empty map to PNG/SVG.
    Render {
        #[command(flatten)]
        source: MapSource,
        /// Output file (.png or .svg), or a prefix without extension for both.
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 2400)]
        width: u32,
    },
    /// Write the map as an OpenDRIVE file (procedural maps open in any OpenDRIVE viewer).
    Export {
        #[command(flatten)]
        source: MapSource,
        #[arg(long)]
        out: PathBuf,
    },
}

#[derive(Args)]
#[group(required = true, multiple = false)]
struct MapSource {
    /// An OpenDRIVE file.
    #[arg(long)]
    xodr: Option<PathBuf>,
    /// A generated map: a preset name (straight, curve, on_ramp_merge, off_ramp_fork,
    /// lane_drop) or a JSON object such as
    /// '{"kind":"lane_drop","lanes":3,"lane_width":3.75,"length":500,"drop_s":200,"taper_length":100}'.
    #[arg(long)]
    procedural: Option<String>,
}

impl MapSource {
    fn load(&self) -> Result<Map> {
        match (&self.xodr, &self.procedural) {
            (Some(path), _) => Map::from_xodr_file(path),
            (None, Some(spec)) => {
                let od = self.procedural_spec(spec)?.build()?;
                Map::from_opendrive(&od, &format!("procedural:{spec}"))
            }
            (None, None) => Err(Error::InvalidArgument("give --xodr or --procedural".into())),
        }
    }

    fn procedural_spec(&self, spec: &str) -> Result<ProceduralMap> {
        if spec.trim_start().starts_with('{') {
            serde_json::from_str(spec).map_err(|e| Error::Parse {
                source_name: "--procedural".into(),
                line: e.line(),
                column: e.column(),
                message: e.to_string(),
            })
        } else {
            ProceduralMap::preset(spec)
        }
    }
}

#[derive(Subcommand)]
enum DataCommand {
    /// Counts, scene split and logged-driver infraction rates.
    Summary {
        #[command(flatten)]
        data: DataArgs,
        /// Summarise these CommonRoad files or folders (repeatable) instead of the A9 data:
        /// per file, its vehicles, duration, lanelets and scenes (or why it gives none).
        #[arg(long = "commonroad")]
        commonroad: Vec<PathBuf>,
        /// Speed limit (m/s) of CommonRoad lanes whose file gives none (default: 130 km/h).
        #[arg(long, requires = "commonroad")]
        commonroad_speed_limit: Option<f64>,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args)]
struct DataArgs {
    /// Folder with the AUTOMATUM A9 files (default: the copy shipped in data/automatum-a9).
    #[arg(long)]
    data: Option<PathBuf>,
}

impl DataArgs {
    fn load(&self) -> Result<A9Dataset> {
        let dir = self.data.clone().unwrap_or_else(a9::default_dir);
        A9Dataset::load(&dir)
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum Split {
    Train,
    Test,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    data: DataArgs,
    /// A concrete long-tail scenario (JSON from `rtr scenarios generate`) instead of a
    /// nominal scene; drawn with its reference run as the future, heroes in red.
    #[arg(long, conflicts_with_all = ["scene", "index"])]
    scenario: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "test")]
    split: Split,
    /// Scene id (as printed by `rtr data summary`), e.g. a9-test-t0450.0.
    #[arg(long, conflicts_with = "index")]
    scene: Option<String>,
    /// Position of the scene in its split.
    #[arg(long, default_value_t = 0)]
    index: usize,
    /// Output file (.png or .svg), or a prefix without extension for both.
    #[arg(long)]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 2400)]
    width: u32,
}

fn main() -> ExitCode {
    rtr::allocator::tune_for_tensors();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut shown = e.to_string();
            let mut source = std::error::Error::source(&e);
            while let Some(cause) = source {
                // Variants that wrap a cause already print it in their own message.
                let text = cause.to_string();
                if !shown.contains(&text) {
                    eprintln!("  caused by: {text}");
                    shown.push_str(&text);
                }
                source = cause.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Data {
            command:
                DataCommand::Summary {
                    data,
                    commonroad,
                    commonroad_speed_limit,
                    json,
                },
        } => {
            if !commonroad.is_empty() {
                let clips = commonroad::load_commonroad(&commonroad, commonroad_speed_limit)?;
                let (_, summaries) =
                    commonroad::commonroad_scenes(&clips, &SceneConfig::default())?;
                if json {
                    let text = serde_json::to_string_pretty(&summaries).map_err(|e| {
                        Error::InvalidArgument(format!("cannot encode summary: {e}"))
                    })?;
                    println!("{text}");
                } else {
                    print!("{}", commonroad::describe_clips(&summaries));
                }
                return Ok(());
            }
            let dataset = data.load()?;
            let summary = summarize(&dataset, &SceneConfig::default())?;
            if json {
                let text = serde_json::to_string_pretty(&summary)
                    .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
                println!("{text}");
            } else {
                let value = serde_json::to_value(&summary)
                    .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
                if let Some(fields) = value.as_object() {
                    for (key, v) in fields {
                        println!("{key:<26} {v}");
                    }
                }
            }
            Ok(())
        }
        Command::Render(args) => render(args),
        Command::Map { command } => map_command(command),
        Command::Model {
            command:
                ModelCommand::Info {
                    config,
                    small,
                    json,
                },
        } => model_info(config, small, json),
        Command::Bench { command } => bench(command),
        Command::Scenarios { command } => scenarios(command),
        Command::Train(args) => train(args),
        Command::Eval(args) => eval(args),
        Command::Sweep(args) => sweep(args),
        Command::Curate(args) => curate(args),
        Command::Downstream(args) => downstream(args),
        Command::Sim2real(args) => sim2real(args),
        Command::Recordings {
            command:
                RecordingsCommand::Generate {
                    effect,
                    seed,
                    tracks,
                    out,
                },
        } => generate_recordings(&effect, seed, tracks, &out),
    }
}

fn eval(args: EvalArgs) -> Result<()> {
    use rtr::eval::study::{evaluate_entries, load_entries, write_study};
    use rtr::eval::{EvalConfig, EvalSet, load_sets, markdown_table};
    if args.checkpoints.is_empty() && !args.idm {
        return Err(Error::InvalidArgument(
            "nothing to evaluate: pass --checkpoint DIR (repeatable) and/or --idm".into(),
        ));
    }
    if let Some(out) = &args.out {
        check_output(out, OutputKind::Folder, "--out")?;
    }
    let mut sets = args
        .set
        .iter()
        .map(|s| EvalSet::parse(s.trim()))
        .collect::<Result<Vec<_>>>()?;
    let commonroad = commonroad_set(&args.commonroad, args.commonroad_speed_limit)?;
    let device = args.backend.device(false)?;
    let entries = load_entries(&args.checkpoints, args.idm, &device)?;
    let dataset = args.data.load()?;
    sets.retain(|&s| s != EvalSet::CommonRoad || commonroad.is_none());
    let mut scenes = load_sets(&dataset, args.scenarios.as_deref(), &sets)?;
    let mut clip_summaries = Vec::new();
    if let Some((set, summaries)) = commonroad {
        sets.push(EvalSet::CommonRoad);
        scenes.push(set);
        clip_summaries = summaries;
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
    print!("{}", markdown_table(&results, &sets));
    if let Some(out) = &args.out {
        let mut written = write_study(out, &entries, &results, &scenes, &device)?;
        if !clip_summaries.is_empty() {
            let path = out.join("commonroad.json");
            let text = serde_json::to_string_pretty(&clip_summaries)
                .map_err(|e| Error::InvalidArgument(format!("cannot encode clips: {e}")))?;
            rtr::io::atomic_write(&path, text.as_bytes())?;
            written.push(path);
        }
        println!("wrote {} files to {}", written.len(), out.display());
    }
    Ok(())
}

/// The `commonroad` eval set from the files and folders of `--commonroad`, with one line per
/// file on stderr saying what it gave; `None` without paths.
fn commonroad_set(
    paths: &[PathBuf],
    speed_limit: Option<f64>,
) -> Result<Option<(rtr::eval::EvalScenes, Vec<commonroad::ClipSummary>)>> {
    if paths.is_empty() {
        return Ok(None);
    }
    let clips = commonroad::load_commonroad(paths, speed_limit)?;
    let (scenes, summaries) = commonroad::commonroad_scenes(&clips, &SceneConfig::default())?;
    eprint!("{}", commonroad::describe_clips(&summaries));
    if scenes.is_empty() {
        return Err(Error::InvalidArgument(
            "the CommonRoad files yield no scene (each file's reason is printed above)".into(),
        ));
    }
    Ok(Some((rtr::eval::EvalScenes::commonroad(scenes), summaries)))
}

fn downstream(args: DownstreamArgs) -> Result<()> {
    use rtr::eval::downstream::{DownstreamConfig, downstream, downstream_table};
    use rtr::eval::study::load_entries;
    use rtr::eval::{EvalConfig, EvalScenes};
    if let Some(out) = &args.out {
        check_output(out, OutputKind::Folder, "--out")?;
    }
    let entries = load_entries(&args.checkpoints, args.idm, &args.backend.device(false)?)?;
    let dataset = args.data.load()?;
    let split = dataset.scenes(&SceneConfig::default())?;
    let (train, test) = (EvalScenes::real(split.train), EvalScenes::real(split.test));
    let mut config = DownstreamConfig {
        seeds: args.seeds,
        ..DownstreamConfig::default()
    };
    config.fit.epochs = args.epochs;
    let progress = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(
            "downstream [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
        )
        .map_err(|e| Error::InvalidArgument(format!("progress template: {e}")))?,
    );
    let started = std::time::Instant::now();
    let rows = downstream(
        &entries,
        &train,
        &test,
        &args.backend.device(true)?,
        &config,
        &EvalConfig::default(),
        &progress,
    )?;
    progress.finish_and_clear();
    let table = downstream_table(&rows);
    print!("{table}");
    if let Some(out) = &args.out {
        let json = serde_json::json!({
            "config": config,
            "train_scenes": train.scenes.len(),
            "test_scenes": test.scenes.len(),
            "wall_time_s": started.elapsed().as_secs_f64(),
            "rows": rows,
        });
        let text = serde_json::to_string_pretty(&json)
            .map_err(|e| Error::InvalidArgument(format!("results.json: {e}")))?;
        rtr::io::atomic_write(&out.join("results.json"), text.as_bytes())?;
        rtr::io::atomic_write(&out.join("table.md"), table.as_bytes())?;
        println!("wrote {}/results.json and table.md", out.display());
    }
    Ok(())
}

fn curate(args: CurateArgs) -> Result<()> {
    use rtr::eval::curate::scene_outcomes;
    use rtr::eval::{EvalConfig, TrainedPolicy};
    check_output(&args.out, OutputKind::File, "--out")?;
    let device = args.backend.device(false)?;
    let trained = TrainedPolicy::load(&args.checkpoint, &device)?;
    let dataset = args.data.load()?;
    let scenes = dataset.scenes(&SceneConfig::default())?.train;
    let config = EvalConfig {
        batch: args.batch,
        ..EvalConfig::default()
    };
    let outcomes = scene_outcomes(
        &trained.network,
        &trained.dynamics,
        scenes,
        &device,
        &config,
    )?;
    let failed: Vec<_> = outcomes.iter().filter(|o| o.failed()).collect();
    if failed.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "{}: no infraction on any of the {} training scenes, so there is nothing to curate",
            args.checkpoint.display(),
            outcomes.len()
        )));
    }
    let count = |f: fn(&rtr::eval::curate::SceneOutcome) -> usize| -> usize {
        failed.iter().map(|o| f(o)).sum()
    };
    let header = format!(
        "Curated scenes: the nominal A9 training scenes on which {} ({}) commits an\n\
         infraction (collision or off-road, mean action, no early termination).\n\
         {} of {} scenes; {} agents collided, {} went off-road.\n\
         Written by: rtr curate --checkpoint {} --out {}",
        trained.method,
        trained.path.display(),
        failed.len(),
        outcomes.len(),
        count(|o| o.collided),
        count(|o| o.offroad),
        args.checkpoint.display(),
        args.out.display()
    );
    let ids: Vec<String> = failed.iter().map(|o| o.id.clone()).collect();
    rtr::data::write_scene_list(&args.out, &header, &ids)?;
    println!(
        "{}: {} of {} training scenes failed; list written to {}",
        trained.method,
        failed.len(),
        outcomes.len(),
        args.out.display()
    );
    Ok(())
}

fn sweep(args: SweepArgs) -> Result<()> {
    use rtr::eval::sweep::{evaluate_points, parse_points, train_points, write_sweep};
    use rtr::eval::{EvalConfig, EvalSet, load_sets};
    let points = parse_points(&args.points)?;
    check_output(&args.out, OutputKind::Folder, "--out")?;
    let sets = args
        .set
        .iter()
        .map(|s| EvalSet::parse(s.trim()))
        .collect::<Result<Vec<_>>>()?;
    let mut base = rtr::train::TrainConfig::from_toml_file(&args.config)?;
    if let Some(dir) = &args.scenarios {
        base.data.longtail_dir = Some(dir.clone());
    }
    let dataset = args.data.load()?;
    let bar = |prefix: &str| {
        let b = indicatif::ProgressBar::new(0);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} iterations, eta {eta} {msg}",
        ) {
            b.set_style(style);
        }
        b.set_prefix(prefix.to_string());
        b
    };
    let dirs = train_points(&base, &points, &dataset, &args.out, &bar)?;
    let device = rtr::backend::Backend::NdArray.device(false)?;
    let scenes = load_sets(&dataset, args.scenarios.as_deref(), &sets)?;
    let config = EvalConfig {
        resamples: args.resamples,
        realism_samples: 0,
        ..EvalConfig::default()
    };
    let progress = bar("eval");
    let results = evaluate_points(&points, &dirs, &scenes, &device, &config, &progress)?;
    progress.finish_and_clear();
    write_sweep(&args.out, &results, &scenes)?;
    print!("{}", rtr::eval::markdown_table(&results, &sets));
    println!(
        "wrote {} and {}",
        args.out.join("results.json").display(),
        args.out.join("table.md").display()
    );
    Ok(())
}

fn sim2real(args: Sim2RealArgs) -> Result<()> {
    use rtr::sim2real::{Sim2RealOptions, a9::a9_recordings, identify, plots::write_plots};
    if !(args.horizon > 0.0 && args.horizon <= 60.0) {
        return Err(Error::InvalidArgument(format!(
            "--horizon {}: expected seconds in (0, 60]",
            args.horizon
        )));
    }
    check_output(&args.report, OutputKind::File, "--report")?;
    if let Some(dir) = &args.plots {
        check_output(dir, OutputKind::Folder, "--plots")?;
    }
    if let Some(path) = &args.save_dynamics {
        check_output(path, OutputKind::File, "--save-dynamics")?;
    }
    let (recordings, commands_inferred) = match &args.recordings {
        Some(path) => (rtr::data::Recordings::load(path)?, false),
        None => (
            a9_recordings(&args.data.load()?, 0.1, args.horizon + 2.0),
            true,
        ),
    };
    let mut options = Sim2RealOptions {
        horizon_s: args.horizon,
        seed: args.seed,
        commands_inferred,
        discover: !args.catalogue_only,
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
        println!("{line}");
    }
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode the report: {e}")))?;
    rtr::io::atomic_write(&args.report, json.as_bytes())?;
    println!("report: {}", args.report.display());
    if let Some(dir) = &args.plots {
        let written = write_plots(dir, &outcome)?;
        for path in written {
            println!("plot: {}", path.display());
        }
    }
    if let Some(path) = &args.save_dynamics {
        report.dynamics().save(path)?;
        println!(
            "dynamics ({} terms): {}",
            report.dynamics().terms.len(),
            path.display()
        );
    }
    Ok(())
}

fn generate_recordings(effect: &str, seed: u64, tracks: usize, out: &Path) -> Result<()> {
    use rtr::sim2real::{Effect, GeneratorConfig, Uncatalogued, generate};
    check_output(out, OutputKind::File, "--out")?;
    let mut config = match effect {
        "none" => GeneratorConfig::with_effect(None, seed),
        name => match (Effect::from_name(name), Uncatalogued::typical(name)) {
            (Some(effect), _) => GeneratorConfig::with_effect(Some(effect), seed),
            (None, Some(physics)) => GeneratorConfig::with_uncatalogued(physics, seed),
            (None, None) => {
                let names: Vec<&str> = Effect::ALL
                    .iter()
                    .map(|e| e.name())
                    .chain(Uncatalogued::NAMES)
                    .collect();
                return Err(Error::InvalidArgument(format!(
                    "unknown --effect `{name}`: expected none or one of {}",
                    names.join(", ")
                )));
            }
        },
    };
    config.tracks = tracks;
    let device = rtr::backend::Backend::NdArray.device(false)?;
    let recordings = generate(&config, &device);
    recordings.save(out)?;
    println!(
        "{} tracks of {} s at {} Hz{} -> {}",
        tracks,
        config.duration_s,
        1.0 / config.period_s,
        match (&config.effect, config.uncatalogued) {
            (Some((e, v)), _) => format!(", concealed {e} {v:?}"),
            (None, Some(physics)) => format!(", concealed {physics:?} (not in the catalogue)"),
            (None, None) => ", no concealed effect".into(),
        },
        out.display()
    );
    Ok(())
}

fn train(args: TrainArgs) -> Result<()> {
    let mut config = rtr::train::TrainConfig::from_toml_file(&args.config)?;
    if let Some(path) = &args.dynamics {
        config.dynamics = Some(path.clone());
    }
    if let Some(dir) = &args.scenarios {
        config.data.longtail_dir = Some(dir.clone());
        config.validate(&format!("{} with --scenarios", args.config.display()))?;
    }
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .config
            .file_stem()
            .map_or("run".into(), |s| s.to_owned());
        PathBuf::from("runs").join(stem)
    });
    check_output(&out, OutputKind::Folder, "--out")?;
    let dataset = args.data.load()?;
    let method = config.method.name();
    let progress = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} iterations, eta {eta} {msg}",
        )
        .map_err(|e| Error::InvalidArgument(format!("progress template: {e}")))?,
    );
    progress.set_prefix(method.to_string());
    let summary = rtr::train::session::train(config, &dataset, &out, args.resume, &progress)?;
    progress.finish();
    println!(
        "{method}: {} iterations, {} optimizer steps; checkpoint {}; curves {}",
        summary.iterations,
        summary.updates,
        summary.checkpoint.display(),
        out.join("curves.csv").display()
    );
    if let Some(last) = summary.last {
        println!(
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
        );
    }
    Ok(())
}

fn render_scenario(path: &std::path::Path, args: &RenderArgs) -> Result<()> {
    let scenario = rtr::scenario::ConcreteScenario::from_json_file(path)?;
    let scene = rtr::scenario::scene_with_reference_future(&scenario)?;
    // The stretch where it happens: around the target, a little ahead of it.
    let target = scene.agents[scenario.target]
        .footprint(scene.current_step())
        .map_or([0.0, 0.0], |b| {
            let d = [b.heading.cos(), b.heading.sin()];
            [b.center[0] + 80.0 * d[0], b.center[1] + 80.0 * d[1]]
        });
    let opts = RenderOptions {
        width_px: args.width,
        highlight: scenario.heroes.iter().map(|h| h.agent).collect(),
        focus: Some((target, 200.0)),
        ..Default::default()
    };
    for target in &targets(&args.out) {
        render_scene(&scene, target, &opts)?;
        println!("wrote {}", target.display());
    }
    println!(
        "scenario {} ({}): {} agents; heroes red, policy-driven agents blue; solid line = history, \
         faded line and dots = the IDM reference run",
        scenario.id(),
        scenario.description,
        scenario.agents.len()
    );
    Ok(())
}

fn scenarios(command: ScenariosCommand) -> Result<()> {
    use rtr::scenario::{
        GenerateConfig, ScenarioSet, builtin_families, generate_sets, load_families,
    };
    match command {
        ScenariosCommand::List { families } => {
            let families = load_families(&families.unwrap_or_else(builtin_families))?;
            for f in &families {
                println!(
                    "{:<28} {:<5} {}",
                    f.name,
                    format!("{:?}", f.set).to_lowercase(),
                    f.description
                );
            }
            Ok(())
        }
        ScenariosCommand::Generate {
            out,
            seed,
            families,
            in_distribution,
            ood,
            data,
        } => {
            let start = std::time::Instant::now();
            let families = load_families(&families.unwrap_or_else(builtin_families))?;
            let dataset = data.load()?;
            let stats =
                rtr::data::TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
            let config = GenerateConfig {
                seed,
                in_distribution,
                ood,
                ..Default::default()
            };
            let sets = generate_sets(&families, &stats, &config)?;
            let written = sets.write(&out)?;
            for set in ScenarioSet::ALL {
                let list = sets.set(set);
                let collided = list
                    .iter()
                    .filter(|s| !s.reference.collided_agents.is_empty())
                    .count();
                let agents: usize = list.iter().map(|s| s.agents.len()).sum();
                println!(
                    "{:<5} {:>4} scenarios, {:>5} agents; IDM reference: a collision in {collided} ({:.1} %)",
                    set.name(),
                    list.len(),
                    agents,
                    100.0 * collided as f64 / list.len().max(1) as f64
                );
            }
            println!(
                "wrote {written} scenarios to {} in {:.1} s (seed {seed})",
                out.display(),
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
    }
}

fn bench(command: BenchCommand) -> Result<()> {
    let report = match command {
        BenchCommand::Train(args) => {
            let model = if args.small {
                ModelConfig::small()
            } else {
                ModelConfig::default()
            };
            let devices = device_count(args.devices, args.backend)?;
            serde_json::to_value(rtr::train::bench::bench_training(
                &args.data.load()?,
                args.backend,
                model,
                args.il_minibatch,
                args.ppo_batch,
                args.ppo_minibatch,
                devices,
            )?)
        }
        BenchCommand::Sim(args) => {
            let (map, repetitions) = bench_inputs(&args)?;
            serde_json::to_value(rtr::sim::bench::run(map, args.backend, repetitions)?)
        }
        BenchCommand::Model(args) => {
            let devices = device_count(args.devices, args.backend)?;
            let (map, repetitions) = bench_inputs(&args)?;
            serde_json::to_value(rtr::model::bench::run(
                map,
                args.backend,
                devices,
                repetitions,
            )?)
        }
    }
    .map_err(|e| Error::InvalidArgument(format!("cannot encode report: {e}")))?;
    println!("{report}");
    Ok(())
}

/// `--devices` checked, or the backend's default worker count.
/// `--devices` (at least 1, checked by its parser), or the backend's default.
fn device_count(devices: Option<usize>, backend: Backend) -> Result<usize> {
    Ok(devices.unwrap_or_else(|| rtr::train::shards::default_devices(backend)))
}

/// The A9 map and the repetition count (at least 1, checked by its parser) of a simulator or
/// model benchmark.
fn bench_inputs(args: &BenchArgs) -> Result<(std::sync::Arc<Map>, usize)> {
    let dir = args.data.data.clone().unwrap_or_else(a9::default_dir);
    let map = std::sync::Arc::new(Map::from_xodr_file(&dir.join(a9::STATIC_FILE))?);
    Ok((map, args.repetitions))
}

fn model_info(config: Option<PathBuf>, small: bool, json: bool) -> Result<()> {
    let config = match (&config, small) {
        (Some(path), _) => ModelConfig::from_toml_file(path)?,
        (None, true) => ModelConfig::small(),
        (None, false) => ModelConfig::default(),
    };
    // Parameter counting needs no gradients; the plain CPU device is always compiled in.
    let device = Backend::NdArray.device(false)?;
    let policy = PolicyNetwork::new(&config, &device).parameter_counts();
    let value = ValueNetwork::new(&config, &device).parameter_counts();
    if json {
        let report = serde_json::json!({
            "config": config,
            "policy": policy,
            "value": value,
            "params": policy.total + value.total,
        });
        println!("{report:#}");
        return Ok(());
    }
    let text = toml::to_string(&config)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode config: {e}")))?;
    println!("# model config\n{text}");
    println!("{:<22} {:>12} {:>12}", "parameters", "policy", "value");
    let rows = [
        (
            "history encoder",
            policy.history_encoder,
            value.history_encoder,
        ),
        (
            "lane-graph encoder",
            policy.lane_graph_encoder,
            value.lane_graph_encoder,
        ),
        ("interaction (GNN)", policy.interaction, value.interaction),
        ("head (MLP)", policy.head, value.head),
        ("total", policy.total, value.total),
    ];
    for (name, p, v) in rows {
        println!("{name:<22} {p:>12} {v:>12}");
    }
    println!("policy + value: {}", policy.total + value.total);
    Ok(())
}

fn map_command(command: MapCommand) -> Result<()> {
    match command {
        MapCommand::Summary(source) => {
            let map = source.load()?;
            let graph = LaneGraph::build(&map, a9::LANE_NODE_LENGTH);
            let summary = serde_json::json!({
                "source": map.source(),
                "roads": map.opendrive().map_or(0, |od| od.roads.len()),
                "junctions": map.opendrive().map_or(0, |od| od.junctions.len()),
                "road_length_m": map.road_length(),
                "driving_lanes": map.driving_lane_count(),
                "sampled_lanes": map.lanes().len(),
                "lane_graph_nodes": graph.nodes.len(),
                "bounds_m": map.bounds(),
            });
            println!("{summary:#}");
            Ok(())
        }
        MapCommand::Render { source, out, width } => {
            let map = source.load()?;
            let opts = RenderOptions {
                width_px: width,
                ..Default::default()
            };
            for path in targets(&out) {
                render_map(&map, &path, &opts)?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        MapCommand::Export { source, out } => {
            let map = source.load()?;
            let od = map.opendrive().ok_or_else(|| {
                Error::InvalidArgument(format!("{} is not an OpenDRIVE map", map.source()))
            })?;
            rtr::io::atomic_write(&out, to_xodr(od).as_bytes())?;
            println!("wrote {}", out.display());
            Ok(())
        }
    }
}

/// The files an `--out` names: itself if it has an extension, else PREFIX.png and PREFIX.svg.
fn targets(out: &std::path::Path) -> Vec<PathBuf> {
    match out.extension() {
        Some(_) => vec![out.to_path_buf()],
        None => output_paths(out).to_vec(),
    }
}

fn render(args: RenderArgs) -> Result<()> {
    if let Some(path) = &args.scenario {
        return render_scenario(path, &args);
    }
    let dataset = args.data.load()?;
    let split = dataset.scenes(&SceneConfig::default())?;
    let scenes = match args.split {
        Split::Train => &split.train,
        Split::Test => &split.test,
    };
    let scene = match &args.scene {
        Some(id) => scenes.iter().find(|s| &s.id == id).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "no scene `{id}` in this split; ids run from {} to {}",
                scenes.first().map_or("-", |s| s.id.as_str()),
                scenes.last().map_or("-", |s| s.id.as_str())
            ))
        })?,
        None => scenes.get(args.index).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "--index {} is past the split's {} scenes",
                args.index,
                scenes.len()
            ))
        })?,
    };
    let opts = RenderOptions {
        width_px: args.width,
        ..Default::default()
    };
    for path in &targets(&args.out) {
        render_scene(scene, path, &opts)?;
        println!("wrote {}", path.display());
    }
    println!(
        "scene {}: {} agents ({} controlled, blue; replayed, orange); solid line = history, \
         faded line and dots = logged future",
        scene.id,
        scene.agents.len(),
        scene.controlled_count()
    );
    Ok(())
}
