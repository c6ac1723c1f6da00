//! `cargo run --release --example rtr`: the end-to-end demo on a fresh clone.
//!
//! 1. Loads the shipped real A9 recording and its OpenDRIVE map and cuts them into scenes.
//! 2. Draws the long-tail training / evaluation / OOD scenario sets (or reuses them).
//! 3. Trains RTR and the IL baseline on the small budget (`experiments/main/small/`), or with
//!    `--full` on the paper's (`experiments/main/`; hours to days on a CPU).
//! 4. Evaluates both, every shipped checkpoint in `models/` and the IDM reference driver on
//!    the nominal (real A9 test split), long-tail and OOD sets.
//! 5. Prints the paper's table and writes `results.json`, `table.md` and the figures.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use rtr::backend::Backend;
use rtr::data::{A9Dataset, SceneConfig, TrafficStatistics, a9};
use rtr::eval::study::{Entry, evaluate_entries, write_study};
use rtr::eval::{EvalConfig, EvalSet, TrainedPolicy, load_sets, markdown_table};
use rtr::scenario::{GenerateConfig, builtin_families, generate_sets, load_families};
use rtr::train::TrainConfig;

#[derive(Parser)]
#[command(about = "rtr end-to-end demo: train RTR and IL, evaluate them with the shipped models")]
struct Args {
    /// Folder for runs, scenarios, the table and the figures.
    #[arg(long, default_value = "results/demo")]
    out: PathBuf,
    /// Train with the paper's budget and network (experiments/main/*.toml) instead of the
    /// small one (experiments/main/small/*.toml).
    #[arg(long)]
    full: bool,
    /// Device backend for training and evaluation (flex in the default build).
    #[arg(long, default_value_t = Backend::cpu_default())]
    backend: Backend,
    /// Skip training; evaluate the shipped models/ only.
    #[arg(long)]
    no_train: bool,
}

fn main() -> std::process::ExitCode {
    rtr::allocator::tune_for_tensors();
    match run(Args::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn progress(prefix: &str) -> ProgressBar {
    let bar = ProgressBar::new(0);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len}, eta {eta} {msg}",
    ) {
        bar.set_style(style);
    }
    bar.set_prefix(prefix.to_string());
    bar
}

fn run(args: Args) -> rtr::Result<()> {
    let clock = Instant::now();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dataset = A9Dataset::load(&a9::default_dir())?;
    let split = dataset.scenes(&SceneConfig::default())?;
    println!(
        "A9: {} vehicles over {:.0} s; {} training and {} test scenes (dt 0.5 s, 2 s history, 6 s future)",
        dataset.recording.tracks.len(),
        dataset.recording.duration(),
        split.train.len(),
        split.test.len()
    );

    let scenarios = args.out.join("scenarios");
    if scenarios.join("ood").is_dir() {
        println!("long-tail sets: reusing {}", scenarios.display());
    } else {
        let started = Instant::now();
        let families = load_families(&builtin_families())?;
        let stats = TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
        let sets = generate_sets(&families, &stats, &GenerateConfig::default())?;
        let written = sets.write(&scenarios)?;
        println!(
            "long-tail sets: {} train / {} eval / {} OOD scenarios from {} families in {:.0} s -> {}",
            sets.train.len(),
            sets.eval.len(),
            sets.ood.len(),
            families.len(),
            started.elapsed().as_secs_f64(),
            scenarios.display()
        );
        debug_assert_eq!(written, sets.train.len() + sets.eval.len() + sets.ood.len());
    }

    let device = args.backend.device(false)?;
    let mut entries = Vec::new();
    if !args.no_train {
        let folder = if args.full {
            root.join("experiments/main")
        } else {
            root.join("experiments/main/small")
        };
        for method in ["il", "rtr"] {
            let run_dir = args.out.join("runs").join(method);
            if !run_dir.join("policy.bpk").is_file() {
                let mut config =
                    TrainConfig::from_toml_file(&folder.join(format!("{method}.toml")))?;
                config.data.longtail_dir = Some(scenarios.clone());
                config.run.backend = args.backend;
                let started = Instant::now();
                let bar = progress(config.method.name());
                let resume = run_dir.join("checkpoints").is_dir();
                rtr::train::session::train(config, &dataset, &run_dir, resume, &bar)?;
                bar.finish_and_clear();
                println!(
                    "trained {method} in {:.0} s -> {}",
                    started.elapsed().as_secs_f64(),
                    run_dir.display()
                );
            } else {
                println!("trained {method}: reusing {}", run_dir.display());
            }
            entries.push(Entry::Trained(Box::new(TrainedPolicy::load(
                &run_dir, &device,
            )?)));
        }
    }
    let models = root.join("models");
    let mut shipped: Vec<PathBuf> = std::fs::read_dir(&models)
        .map_err(|e| rtr::Error::io(&models, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("policy.bpk").is_file())
        .collect();
    shipped.sort();
    for path in &shipped {
        entries.push(Entry::Trained(Box::new(TrainedPolicy::load(
            path, &device,
        )?)));
    }
    entries.push(Entry::idm());
    println!(
        "evaluating {} policies ({} trained here, {} shipped in models/, IDM) on nominal, long-tail and OOD",
        entries.len(),
        entries.len() - 1 - shipped.len(),
        shipped.len()
    );

    let sets = [EvalSet::Nominal, EvalSet::Longtail, EvalSet::Ood];
    let scenes = load_sets(&dataset, Some(&scenarios), &sets)?;
    let bar = progress("eval");
    let results = evaluate_entries(&entries, &scenes, &device, &EvalConfig::default(), &bar)?;
    bar.finish_and_clear();
    // Rows trained here are told apart from the shipped ones by their folder.
    println!("\n{}", markdown_table(&results, &sets));
    let written = write_study(&args.out, &entries, &results, &scenes, &device)?;
    println!(
        "wrote {} files (results.json, table.md, Pareto plots, histograms, curves, rollouts) to {}\n\
         done in {:.0} s",
        written.len(),
        args.out.display(),
        clock.elapsed().as_secs_f64()
    );
    Ok(())
}
