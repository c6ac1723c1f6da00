//! `cargo run --release --example rtr`: the end-to-end demo.
//!
//! Today it runs what rtr has: it loads the real A9 recording and its OpenDRIVE map, builds
//! the lane graph and the train/test scenes, batches them into tensors, replays the logged
//! drivers in closed loop through the differentiable simulator (inverse-model controls) and
//! measures their infractions, lets the (untrained, paper-size) policy network drive the same
//! scenes in closed loop, draws a scene, then generates one long-tail scenario per family
//! (A9 background traffic, scripted heroes, validated) and measures how often the IDM
//! baseline collides in them. Training runs through `rtr train` (not yet in this demo); the
//! paper's evaluation table is not built yet (open issue); this demo says so instead of
//! pretending.

use std::path::PathBuf;
use std::time::Instant;

use burn::prelude::*;
use clap::Parser;

use burn::module::Module;
use rtr::data::{A9Dataset, SceneConfig, a9, logged_infractions};
use rtr::model::{ActionMode, ModelConfig, NetworkPolicy, PolicyNetwork};
use rtr::render::{RenderOptions, render_scene};
use rtr::scene::SceneBatch;
use rtr::sim::{Dynamics, MapCaches, RolloutConfig, imitation_loss, replay_logs, rollout};

#[derive(Parser)]
#[command(about = "rtr end-to-end demo on the shipped A9 recording")]
struct Args {
    /// Folder for pictures and the JSON report.
    #[arg(long, default_value = "results/demo")]
    out: PathBuf,
    /// Scenes per tensor batch.
    #[arg(long, default_value_t = 32)]
    batch: usize,
}

fn main() -> std::process::ExitCode {
    match run(Args::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> rtr::Result<()> {
    let clock = Instant::now();
    let dataset = A9Dataset::load(&a9::default_dir())?;
    let rec = &dataset.recording;
    println!(
        "loaded {} vehicles, {:.1} s at {:.2} Hz; map {:.2} m, {} driving lanes, {} lane-graph nodes ({:.1} s)",
        rec.tracks.len(),
        rec.duration(),
        rec.fps,
        dataset.map.road_length(),
        dataset.map.driving_lane_count(),
        dataset.lane_graph.nodes.len(),
        clock.elapsed().as_secs_f64()
    );

    let config = SceneConfig::default();
    let split = dataset.scenes(&config)?;
    println!(
        "scenes: {} train, {} test (dt {} s, {} s history, {} s future, split at {:.1} s)",
        split.train.len(),
        split.test.len(),
        config.dt,
        config.history_s,
        config.future_s,
        split.split_time
    );

    #[allow(deprecated)] // NdArray is the CPU backend every build has; flex is a feature.
    let device = Device::ndarray();
    let first: Vec<_> = split.test.iter().take(args.batch).collect();
    let batch = SceneBatch::from_scenes(&first, &device)?;
    println!(
        "tensor batch: agent_states {:?}, lane_features {:?}, successors {:?}",
        batch.agent_states.dims(),
        batch.lane_features.dims(),
        batch.lane_successors.index.dims()
    );

    // Closed-loop log replay: the inverse model's controls drive every controlled agent of the
    // test scenes through the differentiable simulator.
    let dynamics = Dynamics::bicycle(config.dt);
    let test: Vec<_> = split.test.iter().collect();
    let (replay, _) = replay_logs(&test, &dynamics, &device)?;
    println!(
        "closed-loop log replay of {} test scenes: {} agent-steps, position error mean {:.3} m, \
         max {:.3} m; {} collisions, {} off-road",
        replay.scenes,
        replay.agent_steps,
        replay.mean_position_error_m,
        replay.max_position_error_m,
        replay.collisions,
        replay.offroad
    );
    // The policy network (paper size, random weights until training exists) driving the
    // batch in closed loop: the plumbing end to end, not a result.
    let started = Instant::now();
    device.seed(0);
    let network = PolicyNetwork::new(&ModelConfig::default(), &device);
    let mut policy = NetworkPolicy::new(&network, &batch, ActionMode::Mean);
    let driven = rollout(
        &first,
        &batch,
        &dynamics,
        &mut policy,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
    )?;
    let loss = imitation_loss(&driven, &batch, 1.0)
        .mean()
        .into_scalar::<f32>();
    let count = |flags: Tensor<3, burn::tensor::Bool>| flags.int().sum().into_scalar::<i64>();
    println!(
        "untrained policy network ({} parameters) drove {} test scenes for {} steps in {:.1} s: \
         Huber imitation loss {:.2}, {} collisions, {} off-road (train with `rtr train --config experiments/main/rtr.toml`)",
        network.num_params(),
        first.len(),
        driven.steps,
        started.elapsed().as_secs_f64(),
        loss,
        count(driven.collision),
        count(driven.offroad)
    );

    let all = logged_infractions(rec, &dataset.map);
    println!(
        "whole recording at 29.97 Hz: {:.2}% of vehicles ever off-road, {:.2}% ever overlap another",
        all.offroad_pct(),
        all.collision_pct()
    );

    let picture = args.out.join("a9-test-scene.png");
    if let Some(scene) = split.test.get(split.test.len() / 2) {
        render_scene(scene, &picture, &RenderOptions::default())?;
        render_scene(
            scene,
            &picture.with_extension("svg"),
            &RenderOptions::default(),
        )?;
        println!(
            "drew scene {} to {} (and .svg)",
            scene.id,
            picture.display()
        );
    }

    long_tail(&dataset, &args)?;

    println!(
        "\ntraining: `cargo run --release -- train --config experiments/main/<method>.toml`\n\
         sim-to-real: `cargo run --release --example sim2real`\n\
         not yet built (open issue): evaluation table and training in this demo (#7).\n\
         done in {:.1} s",
        clock.elapsed().as_secs_f64()
    );
    Ok(())
}

/// One concrete long-tail scenario per family, validated against the IDM reference driver;
/// reports how many reference runs had a collision and draws the first OOD scenario.
fn long_tail(dataset: &A9Dataset, args: &Args) -> rtr::Result<()> {
    use rtr::scenario::{GenerateConfig, builtin_families, generate_sets, load_families};
    let started = Instant::now();
    let families = load_families(&builtin_families())?;
    let stats = rtr::data::TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
    let train = families
        .iter()
        .filter(|f| f.set == rtr::scenario::FamilySet::Train)
        .count();
    let sets = generate_sets(
        &families,
        &stats,
        &GenerateConfig {
            in_distribution: train,
            ood: families.len() - train,
            ..Default::default()
        },
    )?;
    let all: Vec<_> = sets
        .train
        .iter()
        .chain(&sets.eval)
        .chain(&sets.ood)
        .collect();
    let collided = all
        .iter()
        .filter(|s| !s.reference.collided_agents.is_empty())
        .count();
    println!(
        "long-tail: {} families ({} held out), one scenario each in {:.1} s; the IDM baseline \
         collides in {collided} of them",
        families.len(),
        families.len() - train,
        started.elapsed().as_secs_f64()
    );
    if let Some(first) = sets.ood.first() {
        let path = args.out.join(format!("{}.json", first.id()));
        first.write(&path)?;
        println!(
            "wrote {} (draw it: cargo run --release -- render --scenario {} --out {})",
            path.display(),
            path.display(),
            args.out.join(first.id()).display()
        );
    }
    Ok(())
}
