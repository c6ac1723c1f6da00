//! Animated GIFs of a scene's whole window, e.g. a policy's closed-loop rollout put into the
//! scene's future.
//!
//! Frame rule: one frame per step of the window, from the first history step through the last
//! future (simulated) step, [`Scene::steps`] frames in all (A9 scenes: 4 history steps, the
//! current step and 12 simulated ones, 17 frames 0.5 s apart). Each frame draws the road as
//! [`super::render_scene`] does, every car's box at that step and the path it drove over the
//! 4 steps (2 s) before, and a progress bar along the bottom edge (grey over the history, blue
//! from the current step on). The view stays fixed for the whole animation (the caller picks
//! it, e.g. with [`window_focus`]). A car with an [`Infraction`] gets a thick [`INFRACTION`]
//! outline from that step on. The last frame stays one second longer before the animation
//! loops. All frames share one colour table (`palette`).

use std::path::Path;

use plotters::prelude::*;

use super::palette::{ColorCounts, Palette};
use super::{CONTROLLED, INFRACTION, RenderOptions, View};
use super::{agent_color, draw_road, drawing_failed};
use crate::error::{Error, Result};
use crate::io::atomic_write_with;
use crate::map::Map;
use crate::scene::Scene;

/// Highest `fps`: GIF delays are whole hundredths of a second, and viewers slow down delays
/// under 2.
pub const MAX_FPS: u32 = 50;
/// How much longer the last frame stays (hundredths of a second).
const LAST_FRAME_HOLD_CS: u16 = 100;
/// Space around the area the cars cover in [`window_focus`] (m).
const FOCUS_MARGIN_M: f64 = 40.0;
const HISTORY_BAR: RGBColor = RGBColor(90, 90, 90);
/// Steps of the path drawn behind each car (2 s at 0.5 s a step).
const TRAIL_STEPS: usize = 4;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InfractionKind {
    Collision,
    Offroad,
}

impl InfractionKind {
    pub fn name(self) -> &'static str {
        match self {
            InfractionKind::Collision => "collision",
            InfractionKind::Offroad => "off-road",
        }
    }
}

/// An infraction of `scene.agents[agent]`, first seen at window step `step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Infraction {
    pub agent: usize,
    pub step: usize,
    pub kind: InfractionKind,
}

/// What [`animate_scene`] refuses before drawing, checked without a map: a width outside 16 to
/// [`super::MAX_WIDTH_PX`] px, `fps` outside 1 to [`MAX_FPS`], a file name that is not `.gif`.
pub fn check_animation_target(path: &Path, opts: &RenderOptions, fps: u32) -> Result<()> {
    super::check_width(opts)?;
    if !(1..=MAX_FPS).contains(&fps) {
        return Err(Error::InvalidArgument(format!(
            "{fps} frames per second: expected 1 to {MAX_FPS}"
        )));
    }
    match path.extension().and_then(|e| e.to_str()) {
        Some("gif") => Ok(()),
        _ => Err(Error::InvalidArgument(format!(
            "{}: --animate writes an animated GIF: expected a .gif file name",
            path.display()
        ))),
    }
}

/// The frame size (px) of an animation of a scene on `map`: `opts.width_px` wide, as tall as
/// the view of the map (within `opts.focus`) at that width.
pub fn frame_size(map: &Map, opts: &RenderOptions) -> Result<(u32, u32)> {
    Ok((opts.width_px, View::fit(map, opts)?.height_px))
}

/// The part of the map to show for a window of `scenes` (one scene's log and its rollouts,
/// which share agents): around the centre of the area the cars `agents` (indices into each
/// scene's agents; empty: every car) cover over the window in any of them, as far as its
/// corners plus a margin. `None` where they have no valid state.
pub fn window_focus(scenes: &[&Scene], agents: &[usize]) -> Option<([f64; 2], f64)> {
    let mut min = [f64::INFINITY; 2];
    let mut max = [f64::NEG_INFINITY; 2];
    let chosen = |i: &usize| agents.is_empty() || agents.contains(i);
    let all = scenes.iter().flat_map(|s| s.agents.iter().enumerate());
    for (_, agent) in all.filter(|(i, _)| chosen(i)) {
        for (s, _) in agent.states.iter().zip(&agent.valid).filter(|(_, v)| **v) {
            min = [min[0].min(s.x), min[1].min(s.y)];
            max = [max[0].max(s.x), max[1].max(s.y)];
        }
    }
    if !min[0].is_finite() {
        return None;
    }
    let centre = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
    let radius = 0.5 * (max[0] - min[0]).hypot(max[1] - min[1]) + FOCUS_MARGIN_M;
    Some((centre, radius))
}

/// The animation [`animate_scene`] wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AnimationSummary {
    pub frames: usize,
    pub width_px: u32,
    pub height_px: u32,
}

/// Writes `scene`'s window as an animated GIF to `path` (atomically), `fps` frames per second,
/// with `infractions` marked (see the module's frame rule).
pub fn animate_scene(
    scene: &Scene,
    infractions: &[Infraction],
    path: &Path,
    opts: &RenderOptions,
    fps: u32,
) -> Result<AnimationSummary> {
    check_animation_target(path, opts, fps)?;
    let view = View::fit(&scene.map, opts)?;
    let size = (opts.width_px, view.height_px);
    let dims = (u16::try_from(size.0), u16::try_from(size.1));
    let (Ok(w), Ok(h)) = dims else {
        return Err(Error::InvalidArgument(format!(
            "{}: a {} x {} px frame is larger than a GIF holds ({} px a side); pass a \
             smaller --width",
            path.display(),
            size.0,
            size.1,
            u16::MAX
        )));
    };
    let mut road = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut road, size).into_drawing_area();
        draw_road(&area, &scene.map, &view).map_err(drawing_failed)?;
        area.present().map_err(drawing_failed)?;
    }
    let frame = |step: usize| draw_frame(&road, scene, step, infractions, &view, opts);
    let mut counts = ColorCounts::default();
    for step in 0..scene.steps() {
        counts.add(&frame(step)?);
    }
    let mut palette = Palette::from_counts(counts);
    let delay = (100.0 / f64::from(fps)).round() as u16;
    atomic_write_with(path, |tmp| {
        write_gif(tmp, (w, h), &mut palette, scene.steps(), delay, frame)
    })?;
    Ok(AnimationSummary {
        frames: scene.steps(),
        width_px: size.0,
        height_px: size.1,
    })
}

/// An animation as an output: a `.gif` file that is one.
pub const ANIMATION: crate::io::FileKind = crate::io::FileKind {
    name: "a GIF animation",
    extensions: &["gif"],
    recognise: |head| head.starts_with(b"GIF87a") || head.starts_with(b"GIF89a"),
};

/// Encodes frames `0..count` of `frame` (RGB) in `palette` as a looping GIF at `path`, each
/// shown `delay` hundredths of a second, the last [`LAST_FRAME_HOLD_CS`] longer.
fn write_gif(
    path: &Path,
    (w, h): (u16, u16),
    palette: &mut Palette,
    count: usize,
    delay: u16,
    frame: impl Fn(usize) -> Result<Vec<u8>>,
) -> Result<()> {
    let file = crate::io::create_file(path)?;
    let fail = |e| gif_failed(path, e);
    let writer = std::io::BufWriter::new(file);
    let mut encoder = gif::Encoder::new(writer, w, h, &palette.rgb()).map_err(fail)?;
    encoder.set_repeat(gif::Repeat::Infinite).map_err(fail)?;
    for step in 0..count {
        let indices = palette.indices(&frame(step)?);
        let mut gif_frame = gif::Frame::from_indexed_pixels(w, h, indices, None);
        gif_frame.delay = match step + 1 == count {
            true => delay + LAST_FRAME_HOLD_CS,
            false => delay,
        };
        encoder.write_frame(&gif_frame).map_err(fail)?;
    }
    let writer = encoder.into_inner().map_err(fail)?;
    writer
        .into_inner()
        .map_err(|e| Error::io(path, e.into_error()))?;
    Ok(())
}

fn gif_failed(path: &Path, e: gif::EncodingError) -> Error {
    match e {
        gif::EncodingError::Io(io) => Error::io(path, io),
        other => Error::InvalidArgument(format!("{}: GIF encoding: {other}", path.display())),
    }
}

/// Frame `step` (RGB): the cars over a copy of the drawn road.
fn draw_frame(
    road: &[u8],
    scene: &Scene,
    step: usize,
    infractions: &[Infraction],
    view: &View,
    opts: &RenderOptions,
) -> Result<Vec<u8>> {
    let mut rgb = road.to_vec();
    {
        let size = (opts.width_px, view.height_px);
        let area = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw_cars(&area, scene, step, infractions, view, opts).map_err(drawing_failed)?;
        draw_progress(&area, scene, step).map_err(drawing_failed)?;
        area.present().map_err(drawing_failed)?;
    }
    Ok(rgb)
}

/// Every car valid at `step`: the paths they drove over the last [`TRAIL_STEPS`] steps, then
/// their boxes, flagged cars last (a car that ran into another is not hidden under it).
fn draw_cars<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    scene: &Scene,
    step: usize,
    infractions: &[Infraction],
    view: &View,
    opts: &RenderOptions,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let line_px = ((0.3 * view.scale).round() as u32).max(1);
    let mark_px = ((0.5 * view.scale).round() as u32).max(2);
    let shown: Vec<_> = (scene.agents.iter().enumerate())
        .filter_map(|(i, a)| a.footprint(step).map(|b| (i, a, b)))
        .collect();
    for (_, agent, _) in &shown {
        let path: Vec<_> = (step.saturating_sub(TRAIL_STEPS)..=step)
            .filter(|&t| agent.valid[t])
            .map(|t| view.px([agent.states[t].x, agent.states[t].y]))
            .collect();
        let color = agent_color(agent, opts);
        area.draw(&PathElement::new(path, color.stroke_width(line_px)))?;
    }
    let flagged = |i: usize| infractions.iter().any(|f| f.agent == i && f.step <= step);
    for pass in [false, true] {
        for (_, agent, footprint) in shown.iter().filter(|(i, _, _)| flagged(*i) == pass) {
            let corners: Vec<_> = footprint.corners().iter().map(|&c| view.px(c)).collect();
            area.draw(&Polygon::new(
                corners.clone(),
                agent_color(agent, opts).filled(),
            ))?;
            let mut closed = corners;
            closed.push(closed[0]);
            let outline = match pass {
                true => INFRACTION.stroke_width(mark_px),
                false => BLACK.stroke_width(1),
            };
            area.draw(&PathElement::new(closed, outline))?;
        }
    }
    Ok(())
}

/// The bar along the bottom edge: its length the time from the window's start to `step`,
/// grey over the history, blue after the current step.
fn draw_progress<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    scene: &Scene,
    step: usize,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (width, height) = area.dim_in_pixel();
    let (width, height) = (width as i32, height as i32);
    let bar = (height / 40).max(3);
    let x = |k: usize| (i64::from(width) * (k as i64 + 1) / scene.steps() as i64) as i32;
    let now = scene.current_step();
    let top = height - bar;
    let history = Rectangle::new([(0, top), (x(step.min(now)), height)], HISTORY_BAR.filled());
    area.draw(&history)?;
    if step > now {
        let simulated = Rectangle::new([(x(now), top), (x(step), height)], CONTROLLED.filled());
        area.draw(&simulated)?;
    }
    Ok(())
}
