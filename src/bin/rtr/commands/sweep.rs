//! `rtr sweep`: train RTR at every lambda x alpha point of a base run file, then evaluate each.

use std::path::PathBuf;

use clap::Args;

use rtr::Result;
use rtr::eval::{EvalConfig, EvalSet, load_sets};
use rtr::io::{Inputs, check_result_folder, claim_output_folder};
use rtr::studies::sweep::{check_points, evaluate_points, parse_points, train_points, write_sweep};

use super::args::{DataArgs, count};

/// The kind of result set `rtr sweep --out` writes (beside its points' training folders).
const SWEEP_RESULTS: &str = rtr::io::SWEEP_KIND;

#[derive(Args)]
pub struct SweepArgs {
    /// The base run file (method RTR); lambda and alpha are set per point.
    #[arg(long)]
    config: PathBuf,
    /// Points LAMBDA:ALPHA, comma-separated; default: the paper's six.
    #[arg(
        long,
        default_value = "0:0,1:0.5,5:0.5,10:0.5,5:0.3,5:0.7",
        allow_hyphen_values = true
    )]
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
    /// Train each unfinished point at most this many iterations in this call (run the same
    /// command again to continue); a point not yet finished is evaluated at its newest
    /// checkpoint.
    #[arg(long, value_parser = count(1, 1_000_000_000))]
    stop_after: Option<usize>,
    /// Evaluate only the first N scenes of each set (a quick look).
    #[arg(long, value_parser = count(1, 1_000_000))]
    scenes: Option<usize>,
    #[command(flatten)]
    data: DataArgs,
}

pub fn run(args: SweepArgs) -> Result<()> {
    let points = parse_points(&args.points)?;
    let inputs = Inputs::new()
        .with("--config", &args.config)
        .with_all("--scenarios", &args.scenarios)
        .with("--data", args.data.dir());
    if let Some(dir) = &args.scenarios {
        rtr::io::check_input_folder(dir, "--scenarios", super::eval::SCENARIO_FOLDER)?;
    }
    let _claim = claim_output_folder(&args.out, "--out", &inputs)?;
    check_result_folder(&args.out, SWEEP_RESULTS, &["results.json", "table.md"])?;
    let sets = EvalSet::parse_list(&args.set)?;
    rtr::io::check_input_file(&args.config, "--config")?;
    let mut base = rtr::train::TrainConfig::from_toml_file(&args.config)?;
    if let Some(dir) = &args.scenarios {
        base.data.longtail_dir = Some(dir.clone());
    }
    check_points(&base, &points, &args.out)?;
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
    let dirs = train_points(&base, &points, &dataset, &args.out, args.stop_after, &bar)?;
    let device = rtr::backend::Backend::NdArray.device(false)?;
    let mut scenes = load_sets(&dataset, args.scenarios.as_deref(), &sets)?;
    if let Some(n) = args.scenes {
        scenes.iter_mut().for_each(|s| s.keep_first(n));
    }
    let config = EvalConfig {
        resamples: args.resamples,
        realism_samples: 0,
        ..EvalConfig::default()
    };
    let progress = bar("eval");
    let results = evaluate_points(&points, &dirs, &scenes, &device, &config, &progress)?;
    progress.finish_and_clear();
    let staged = rtr::io::StagedFolder::new(&args.out, SWEEP_RESULTS)?;
    staged.fill(|dir| write_sweep(dir, &results, &scenes))?;
    staged.commit()?;
    rtr::out!("{}", rtr::eval::markdown_table(&results, &sets))?;
    rtr::outln!(
        "wrote {} and {}",
        args.out.join("results.json").display(),
        args.out.join("table.md").display()
    )?;
    Ok(())
}
