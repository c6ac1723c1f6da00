//! `rtr render`: draw a nominal scene or a concrete long-tail scenario to PNG/SVG.

use std::path::{Path, PathBuf};

use clap::Args;

use rtr::data::SceneConfig;
use rtr::render::{RenderOptions, render_scene};
use rtr::{Error, Result};

use super::args::{DataArgs, Split, image_targets, image_width};

#[derive(Args)]
pub struct RenderArgs {
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
    #[arg(long, default_value_t = 2400, value_parser = image_width())]
    width: u32,
}

pub fn run(args: RenderArgs) -> Result<()> {
    let opts = RenderOptions {
        width_px: args.width,
        ..Default::default()
    };
    let targets = image_targets(&args.out, &opts)?;
    if let Some(path) = &args.scenario {
        rtr::io::check_input_file(path, "--scenario")?;
        return render_scenario(path, &args, &targets);
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
    for path in &targets {
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

fn render_scenario(path: &Path, args: &RenderArgs, targets: &[PathBuf]) -> Result<()> {
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
    for target in targets {
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
