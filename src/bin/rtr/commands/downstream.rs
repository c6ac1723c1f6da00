//! `rtr downstream`: score trajectory predictors trained on each policy's simulated data.

use std::path::PathBuf;

use clap::Args;

use rtr::backend::Backend;
use rtr::data::SceneConfig;
use rtr::eval::study::load_entries;
use rtr::eval::{EvalConfig, EvalScenes};
use rtr::io::{Inputs, check_result_folder, claim_output_folder};
use rtr::studies::downstream::{DownstreamConfig, downstream, downstream_table};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

/// The kind of result set `rtr downstream --out` writes.
const DOWNSTREAM_RESULTS: &str = "rtr downstream";

#[derive(Args)]
pub struct DownstreamArgs {
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
    /// Drive with each policy's mean action instead of sampling it (not in the paper): the
    /// synthetic data then no longer depends on the policies' sigmas.
    #[arg(long)]
    mean_actions: bool,
    /// Write results.json and table.md here.
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

pub fn run(args: DownstreamArgs) -> Result<()> {
    if args.checkpoints.is_empty() && !args.idm {
        return Err(Error::InvalidArgument(
            "nothing to compare with the real logs: pass --checkpoint DIR (repeatable) and/or \
             --idm"
                .into(),
        ));
    }
    let inputs = rtr::eval::trained::with_run_inputs(
        Inputs::new().with("--data", args.data.dir()),
        "--checkpoint",
        &args.checkpoints,
    )?;
    let _claim = match &args.out {
        Some(out) => {
            let claim = claim_output_folder(out, "--out", &inputs)?;
            check_result_folder(out, DOWNSTREAM_RESULTS, &["results.json", "table.md"])?;
            Some(claim)
        }
        None => None,
    };
    let entries = load_entries(&args.checkpoints, args.idm, &args.backend.device(false)?)?;
    let dataset = args.data.load()?;
    let split = dataset.scenes(&SceneConfig::default())?;
    let (train, test) = (EvalScenes::real(split.train), EvalScenes::real(split.test));
    let mut config = DownstreamConfig {
        seeds: args.seeds,
        mean_actions: args.mean_actions,
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
    // The files first (together), then stdout: a reader that goes away must not cost them.
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
        let staged = rtr::io::StagedFolder::new(out, DOWNSTREAM_RESULTS)?;
        staged.fill(|dir| {
            rtr::io::atomic_write(&dir.join("results.json"), text.as_bytes())?;
            rtr::io::atomic_write(&dir.join("table.md"), table.as_bytes())
        })?;
        staged.commit()?;
    }
    rtr::out!("{table}")?;
    if let Some(out) = &args.out {
        rtr::outln!("wrote {}/results.json and table.md", out.display())?;
    }
    Ok(())
}
