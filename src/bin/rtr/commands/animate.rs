//! `rtr render --animate`: a policy's closed-loop rollout on a scene as an animated GIF
//! (`rtr::render::animation`), rolled out as `rtr eval` rolls it out (`rtr::eval::watch`).

use rtr::eval::study::Entry;
use rtr::eval::{EvalPolicy, EvalScenes, EvalSet, TrainedPolicy, WatchedRollout, watch_rollout};
use rtr::io::claim_output_file;
use rtr::render::{RenderOptions, animate_scene, check_animation_target, window_focus};
use rtr::scene::Scene;
use rtr::sim::Dynamics;
use rtr::{Error, Result};

use super::render::{RenderArgs, Source, scenario_highlight, source};

/// `--width` of an animation without the flag.
const ANIMATION_WIDTH_PX: u32 = 960;
/// `--fps` without the flag: twice real time (a frame is a 0.5 s step).
const DEFAULT_FPS: u32 = 4;

/// What drives the controlled agents: a trained policy or the IDM reference, with its name.
struct Driver {
    name: String,
    entry: Entry,
    device: burn::prelude::Device,
}

pub fn run(args: &RenderArgs) -> Result<()> {
    let fps = args.fps.unwrap_or(DEFAULT_FPS);
    let opts = RenderOptions {
        width_px: args.width.unwrap_or(ANIMATION_WIDTH_PX),
        ..Default::default()
    };
    check_animation_target(&args.out, &opts, fps).map_err(|e| match e {
        Error::InvalidArgument(why) => Error::InvalidArgument(format!("--out {why}")),
        other => other,
    })?;
    let _claim = claim_output_file(&args.out, "--out", &args.inputs()?, &rtr::render::ANIMATION)?;
    let driver = load_driver(args)?;
    // The view: where every car of a recorded scene drives, in the log and in the rollout; a
    // scenario's target and heroes only (its other cars spread over a kilometre of road).
    let (log, set, highlight, framed) = match source(args)? {
        Source::Recorded { scene, set } => {
            let log = (*scene).clone();
            (log, recorded_set(*scene, set), Vec::new(), Vec::new())
        }
        Source::Scenario(scenario) => {
            let highlight = scenario_highlight(&scenario);
            let framed = std::iter::once(scenario.target).chain(highlight.clone());
            (
                rtr::scenario::scene_with_reference_future(&scenario)?,
                EvalScenes::generated(EvalSet::Longtail, vec![(*scenario).clone()])?,
                highlight.clone(),
                framed.collect(),
            )
        }
    };
    let watched = match &driver {
        None => WatchedRollout {
            scene: log.clone(),
            infractions: Vec::new(),
        },
        Some(d) => {
            let (policy, dynamics) = parts(&d.entry);
            watch_rollout(policy, dynamics, &set, 0, &d.device)?
        }
    };
    let opts = RenderOptions {
        highlight,
        focus: window_focus(&[&log, &watched.scene], &framed),
        ..opts
    };
    let summary = animate_scene(&watched.scene, &watched.infractions, &args.out, &opts, fps)?;
    rtr::outln!(
        "wrote {}: {} frames of {} x {} px at {fps} fps ({} history steps, the current step, \
         then {} steps of {} s)",
        args.out.display(),
        summary.frames,
        summary.width_px,
        summary.height_px,
        log.history_steps,
        log.future_steps,
        log.dt
    )?;
    describe(&watched, driver.as_ref().map(|d| d.name.as_str()))?;
    Ok(())
}

/// One recorded scene as a set of its kind.
fn recorded_set(scene: Scene, set: EvalSet) -> EvalScenes {
    EvalScenes {
        set,
        scenes: vec![scene],
        scenarios: Vec::new(),
    }
}

/// `--checkpoint` or `--idm` on `--backend`; `None` without either (the log is drawn).
fn load_driver(args: &RenderArgs) -> Result<Option<Driver>> {
    if args.checkpoint.is_none() && !args.idm {
        return Ok(None);
    }
    let device = args.backend.device(false)?;
    let (name, entry) = match &args.checkpoint {
        Some(path) => {
            rtr::io::check_input_path(path, "--checkpoint")?;
            let trained = TrainedPolicy::load(path, &device)?;
            if let Some(note) = trained.unfinished_note(path, "driving with") {
                rtr::errln!("{note}");
            }
            let name = format!("{} ({})", trained.method, path.display());
            (name, Entry::Trained(Box::new(trained)))
        }
        None => ("IDM (reference driver)".to_string(), Entry::idm()),
    };
    Ok(Some(Driver {
        name,
        entry,
        device,
    }))
}

fn parts(entry: &Entry) -> (&dyn EvalPolicy, &Dynamics) {
    match entry {
        Entry::Trained(t) => (&t.network, &t.dynamics),
        Entry::Idm { driver, dynamics } => (driver, dynamics),
    }
}

/// The legend, and one line per infraction.
fn describe(watched: &WatchedRollout, driver: Option<&str>) -> Result<()> {
    let scene = &watched.scene;
    let who = match driver {
        Some(name) => format!("{name} drives the {} blue agents", scene.controlled_count()),
        None => format!(
            "the log (blue: the {} agents --checkpoint or --idm would drive)",
            scene.controlled_count()
        ),
    };
    rtr::outln!(
        "scene {}: {who}; orange: replayed from the log; red: heroes; magenta outline: a car \
         from its first collision or off-road step on; bottom bar: time (grey history, blue \
         rollout)",
        scene.id
    )?;
    for f in &watched.infractions {
        let agent = &scene.agents[f.agent];
        let seconds = (f.step - scene.current_step()) as f64 * scene.dt;
        rtr::outln!(
            "  {}: agent {} (track {}) at +{seconds:.1} s",
            f.kind.name(),
            f.agent,
            agent.track_id
        )?;
    }
    Ok(())
}
