//! `rtr curate`: list the nominal training scenes a trained policy commits an infraction on.

use std::path::PathBuf;

use clap::Args;

use rtr::backend::Backend;
use rtr::data::SceneConfig;
use rtr::data::scene_list::SCENE_LIST;
use rtr::eval::curate::{SceneOutcome, scene_outcomes};
use rtr::eval::{EvalConfig, TrainedPolicy};
use rtr::io::{Inputs, claim_output_file};
use rtr::{Error, Result};

use super::args::{DataArgs, count};

#[derive(Args)]
pub struct CurateArgs {
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
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    #[command(flatten)]
    data: DataArgs,
}

pub fn run(args: CurateArgs) -> Result<()> {
    rtr::io::check_input_path(&args.checkpoint, "--checkpoint")?;
    let inputs = rtr::eval::trained::with_run_inputs(
        Inputs::new().with("--data", args.data.dir()),
        "--checkpoint",
        [&args.checkpoint],
    )?;
    let _claim = claim_output_file(&args.out, "--out", &inputs, &SCENE_LIST)?;
    let device = args.backend.device(false)?;
    let trained = TrainedPolicy::load(&args.checkpoint, &device)?;
    if let Some(note) = trained.unfinished_note(&args.checkpoint, "curating with") {
        rtr::errln!("{note}");
    }
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
    let count = |f: fn(&SceneOutcome) -> usize| -> usize { failed.iter().map(|o| f(o)).sum() };
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
    rtr::outln!(
        "{}: {} of {} training scenes failed; list written to {}",
        trained.method,
        failed.len(),
        outcomes.len(),
        args.out.display()
    )?;
    Ok(())
}
