//! `rtr render`: draw a nominal scene, a CommonRoad scene or a concrete long-tail scenario to
//! PNG/SVG, or (`--animate`) a policy's closed-loop rollout on it to an animated GIF.

use std::path::PathBuf;

use clap::Args;

use rtr::backend::Backend;
use rtr::data::{SceneConfig, commonroad};
use rtr::eval::EvalSet;
use rtr::io::Inputs;
use rtr::render::{MAX_FPS, RenderOptions, render_scene_files};
use rtr::scenario::ConcreteScenario;
use rtr::scene::Scene;
use rtr::{Error, Result};

use super::args::{DataArgs, Split, image_targets, image_width};

/// `--width` of a picture without the flag.
const PICTURE_WIDTH_PX: u32 = 2400;

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    data: DataArgs,
    /// A concrete long-tail scenario (JSON from `rtr scenarios generate`) instead of a
    /// nominal scene; drawn with its reference run as the future, heroes in red.
    #[arg(long, conflicts_with_all = ["scene", "index", "commonroad", "split"])]
    scenario: Option<PathBuf>,
    /// A CommonRoad scenario file (.xml, .xml.gz) instead of the A9 recording: one of its
    /// recorded scenes, chosen with --scene or --index (lanes without a speed limit get 130 km/h).
    #[arg(long, conflicts_with = "split")]
    commonroad: Option<PathBuf>,
    /// The A9 split the scene is taken from.
    #[arg(long, value_enum, default_value = "test")]
    split: Split,
    /// Scene id (as printed by `rtr data summary`), e.g. a9-test-t0450.0.
    #[arg(long, conflicts_with = "index")]
    scene: Option<String>,
    /// Position of the scene in its split (or CommonRoad file).
    #[arg(long, default_value_t = 0)]
    index: usize,
    /// Output file (.png or .svg), or a prefix without extension for both; a .gif with
    /// --animate.
    #[arg(long)]
    pub(super) out: PathBuf,
    /// Image width in pixels (default 2400; 960 with --animate).
    #[arg(long, value_parser = image_width())]
    pub(super) width: Option<u32>,
    /// Write an animated GIF of the scene's whole window instead: one frame per 0.5 s step,
    /// the logged history, then the rollout of --checkpoint or --idm (without either, the log
    /// itself; a scenario's IDM reference run).
    #[arg(long)]
    pub(super) animate: bool,
    /// With --animate: the policy driving the controlled agents (a model folder such as
    /// models/il_main, a run folder or a checkpoints/iter-* folder, as `rtr eval` takes).
    #[arg(long, requires = "animate", conflicts_with = "idm")]
    pub(super) checkpoint: Option<PathBuf>,
    /// With --animate: the IDM + lane-keeping reference driver drives them.
    #[arg(long, requires = "animate")]
    pub(super) idm: bool,
    /// With --animate: frames per second (default 4, twice real time).
    #[arg(long, requires = "animate",
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_FPS)))]
    pub(super) fps: Option<u32>,
    /// With --checkpoint or --idm: the device the rollout runs on.
    #[arg(long, default_value_t = Backend::cpu_default())]
    pub(super) backend: Backend,
}

/// The scene to draw: a recorded one (the set it belongs to), or a long-tail scenario.
pub(super) enum Source {
    Recorded { scene: Box<Scene>, set: EvalSet },
    Scenario(Box<ConcreteScenario>),
}

impl RenderArgs {
    /// The files and folders the command reads, for the output checks.
    pub(super) fn inputs(&self) -> Result<Inputs> {
        let inputs = Inputs::new()
            .with("--data", self.data.dir())
            .with_all("--scenario", &self.scenario)
            .with_all("--commonroad", &self.commonroad);
        rtr::eval::trained::with_run_inputs(inputs, "--checkpoint", &self.checkpoint)
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    if args.animate {
        return super::animate::run(&args);
    }
    let opts = RenderOptions {
        width_px: args.width.unwrap_or(PICTURE_WIDTH_PX),
        ..Default::default()
    };
    let (targets, _claims) = image_targets(&args.out, &opts, &args.inputs()?)?;
    let scene = match source(&args)? {
        Source::Scenario(scenario) => return render_scenario(&scenario, &opts, &targets),
        Source::Recorded { scene, .. } => scene,
    };
    // Every file first, as one set: a full stdout must not cut the set short.
    render_scene_files(&scene, &targets, &opts)?;
    for path in &targets {
        rtr::outln!("wrote {}", path.display())?;
    }
    rtr::outln!(
        "scene {}: {} agents ({} controlled, blue; replayed, orange); solid line = history, \
         faded line and dots = logged future",
        scene.id,
        scene.agents.len(),
        scene.controlled_count()
    )?;
    Ok(())
}

/// The scene the flags choose: `--scenario`, a scene of `--commonroad`, or an A9 one.
pub(super) fn source(args: &RenderArgs) -> Result<Source> {
    if let Some(path) = &args.scenario {
        rtr::io::check_input_file(path, "--scenario")?;
        let scenario = ConcreteScenario::from_json_file(path)?;
        scenario.check_reference(&path.display().to_string())?;
        return Ok(Source::Scenario(Box::new(scenario)));
    }
    if let Some(path) = &args.commonroad {
        rtr::io::check_input_file(path, "--commonroad")?;
        let clips = commonroad::load_commonroad(std::slice::from_ref(path), None)?;
        let (scenes, summaries) = commonroad::commonroad_scenes(&clips, &SceneConfig::default())?;
        if scenes.is_empty() {
            let why = summaries.iter().find_map(|s| s.no_scene_because.clone());
            return Err(Error::InvalidArgument(format!(
                "--commonroad {}: the file yields no scene ({})",
                path.display(),
                why.unwrap_or_else(|| "no reason given".into())
            )));
        }
        let scene = pick(scenes, args, "file")?;
        return Ok(Source::Recorded {
            scene: Box::new(scene),
            set: EvalSet::CommonRoad,
        });
    }
    let dataset = args.data.load()?;
    let split = dataset.scenes(&SceneConfig::default())?;
    let scenes = match args.split {
        Split::Train => split.train,
        Split::Test => split.test,
    };
    let scene = pick(scenes, args, "split")?;
    Ok(Source::Recorded {
        scene: Box::new(scene),
        set: EvalSet::Nominal,
    })
}

/// The scene of `--scene` or `--index` among `scenes` (of a `within`: split, file).
fn pick(scenes: Vec<Scene>, args: &RenderArgs, within: &str) -> Result<Scene> {
    let found = match &args.scene {
        Some(id) => scenes.iter().position(|s| &s.id == id).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "no scene `{id}` in this {within}; ids run from {} to {}",
                scenes.first().map_or("-", |s| s.id.as_str()),
                scenes.last().map_or("-", |s| s.id.as_str())
            ))
        })?,
        None if args.index < scenes.len() => args.index,
        None => {
            return Err(Error::InvalidArgument(format!(
                "--index {} is past the {within}'s {} scenes",
                args.index,
                scenes.len()
            )));
        }
    };
    Ok(scenes.into_iter().nth(found).expect("index checked"))
}

/// The track ids drawn highlighted in a scenario's pictures: its heroes.
pub(super) fn scenario_highlight(scenario: &ConcreteScenario) -> Vec<usize> {
    scenario.heroes.iter().map(|h| h.agent).collect()
}

fn render_scenario(
    scenario: &ConcreteScenario,
    opts: &RenderOptions,
    targets: &[PathBuf],
) -> Result<()> {
    let scene = rtr::scenario::scene_with_reference_future(scenario)?;
    // The stretch where it happens: around the target, a little ahead of it.
    let target = scene.agents[scenario.target]
        .footprint(scene.current_step())
        .map_or([0.0, 0.0], |b| {
            let d = [b.heading.cos(), b.heading.sin()];
            [b.center[0] + 80.0 * d[0], b.center[1] + 80.0 * d[1]]
        });
    let opts = RenderOptions {
        highlight: scenario_highlight(scenario),
        focus: Some((target, 200.0)),
        ..opts.clone()
    };
    render_scene_files(&scene, targets, &opts)?;
    for target in targets {
        rtr::outln!("wrote {}", target.display())?;
    }
    rtr::outln!(
        "scenario {} ({}): {} agents; heroes red, policy-driven agents blue; solid line = history, \
         faded line and dots = the IDM reference run",
        scenario.id(),
        scenario.description,
        scenario.agents.len()
    )?;
    Ok(())
}
