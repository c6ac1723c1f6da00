//! Top-down drawings of scenes: road surface, lane marks, vehicle boxes at the current step,
//! their history and their logged future. PNG (plotters' bitmap backend) and SVG; animated GIFs
//! of a whole window in [`animation`].
//!
//! The view is rotated so the road's main direction runs left to right (highway maps are long
//! and thin), and scaled to a fixed width. No text is drawn: plotters needs system fonts for
//! text, and the picture reads without it (colours are explained by `rtr render`).

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::error::{Error, Result};
use crate::io::atomic_write_all;
use crate::map::{Map, RoadMark};
use crate::scene::{AgentRole, Scene, SceneAgent};

pub mod animation;
mod palette;

pub use animation::{
    ANIMATION, AnimationSummary, Infraction, InfractionKind, MAX_FPS, animate_scene,
    check_animation_target, frame_size, window_focus,
};

const ASPHALT: RGBColor = RGBColor(150, 150, 150);
const SHOULDER: RGBColor = RGBColor(190, 190, 185);
const GROUND: RGBColor = RGBColor(226, 233, 214);
const MARK: RGBColor = RGBColor(255, 255, 255);
/// Controlled agents.
pub const CONTROLLED: RGBColor = RGBColor(31, 119, 180);
/// Replayed agents.
pub const REPLAYED: RGBColor = RGBColor(255, 127, 14);
/// Highlight (e.g. a long-tail scenario's hero).
pub const HIGHLIGHT: RGBColor = RGBColor(214, 39, 40);
/// Outline of a car from its first infraction on (animations).
pub const INFRACTION: RGBColor = RGBColor(230, 0, 230);

/// German motorway broken line: 6 m dash, 12 m gap.
const DASH_M: f64 = 6.0;
const GAP_M: f64 = 12.0;

/// Widest picture drawn (px); beyond it the bitmap alone would take gigabytes.
pub const MAX_WIDTH_PX: u32 = 20_000;

/// Most pixels of one picture (width x height): 100 M, 300 MB as RGB.
const MAX_PIXELS: f64 = 1e8;

#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Image width in pixels; the height follows the map's aspect ratio.
    pub width_px: u32,
    /// Margin around the map (m).
    pub margin_m: f64,
    /// Track ids drawn in the highlight colour.
    pub highlight: Vec<usize>,
    /// Draw only the part of the map within this distance (m) of this point (x, y), e.g.
    /// the stretch of a long generated road where a scenario happens.
    pub focus: Option<([f64; 2], f64)>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width_px: 2400,
            margin_m: 4.0,
            highlight: Vec::new(),
            focus: None,
        }
    }
}

/// World → pixel transform: rotate by `-angle` about the origin, then scale and shift.
struct View {
    cos: f64,
    sin: f64,
    min: [f64; 2],
    scale: f64,
    height_px: u32,
}

impl View {
    fn fit(map: &Map, opts: &RenderOptions) -> Result<View> {
        // Axial mean of lane headings (directions modulo pi), so opposite carriageways agree.
        let (mut s2, mut c2) = (0.0, 0.0);
        for lane in map.lanes() {
            for h in &lane.headings {
                s2 += (2.0 * h).sin();
                c2 += (2.0 * h).cos();
            }
        }
        let angle = 0.5 * f64::atan2(s2, c2);
        let (sin, cos) = angle.sin_cos();
        let mut min = [f64::INFINITY; 2];
        let mut max = [f64::NEG_INFINITY; 2];
        let in_focus = |p: &[f64; 2]| {
            opts.focus.is_none_or(|(c, radius)| {
                (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) <= radius * radius
            })
        };
        for lane in map.lanes() {
            for p in lane.left_boundary.iter().chain(&lane.right_boundary) {
                if !in_focus(p) {
                    continue;
                }
                let r = rotate(*p, cos, sin);
                for k in 0..2 {
                    min[k] = min[k].min(r[k]);
                    max[k] = max[k].max(r[k]);
                }
            }
        }
        if !min[0].is_finite() {
            return Err(Error::InvalidArgument(format!(
                "map {} has no lanes to draw",
                map.source()
            )));
        }
        for k in 0..2 {
            min[k] -= opts.margin_m;
            max[k] += opts.margin_m;
        }
        // A map far taller than wide (two roads a thousand kilometres apart) would need a
        // picture millions of pixels tall at the asked width: it is drawn smaller instead,
        // within the tallest picture the pixel budget allows at that width.
        let tallest = (MAX_PIXELS / f64::from(opts.width_px)).min(f64::from(MAX_WIDTH_PX));
        let scale = (f64::from(opts.width_px) / (max[0] - min[0])).min(tallest / (max[1] - min[1]));
        let height_px = ((max[1] - min[1]) * scale).ceil().clamp(1.0, tallest) as u32;
        Ok(View {
            cos,
            sin,
            min,
            scale,
            height_px,
        })
    }

    fn px(&self, p: [f64; 2]) -> (i32, i32) {
        let r = rotate(p, self.cos, self.sin);
        let x = (r[0] - self.min[0]) * self.scale;
        // Image y grows downwards.
        let y = self.height_px as f64 - (r[1] - self.min[1]) * self.scale;
        (x.round() as i32, y.round() as i32)
    }
}

fn rotate(p: [f64; 2], cos: f64, sin: f64) -> [f64; 2] {
    // Rotation by -angle.
    [cos * p[0] + sin * p[1], -sin * p[0] + cos * p[1]]
}

/// Draws `scene` at its current step to `path`: `.png` or `.svg` by extension. The file is
/// written atomically.
pub fn render_scene(scene: &Scene, path: &Path, opts: &RenderOptions) -> Result<()> {
    render(&scene.map, Some(scene), &[path.to_path_buf()], opts)
}

/// [`render_scene`] into every path of `paths` (a PNG and an SVG), written as one set: a
/// failure leaves every path as it was.
pub fn render_scene_files(scene: &Scene, paths: &[PathBuf], opts: &RenderOptions) -> Result<()> {
    render(&scene.map, Some(scene), paths, opts)
}

/// Draws an empty map (road surface and lane marks), e.g. a procedural one.
pub fn render_map(map: &Map, paths: &[PathBuf], opts: &RenderOptions) -> Result<()> {
    render(map, None, paths, opts)
}

/// What `render_scene` and `render_map` refuse before drawing, checked without a map (so a
/// command can refuse it before loading one): a width outside 16 to [`MAX_WIDTH_PX`] px, a
/// file name that is not `.png` or `.svg`.
pub fn check_target(path: &Path, opts: &RenderOptions) -> Result<()> {
    check_width(opts)?;
    match path.extension().and_then(|e| e.to_str()).unwrap_or("") {
        "svg" | "png" => Ok(()),
        other => Err(Error::InvalidArgument(format!(
            "{}: cannot render to `.{other}`: expected a .png or .svg file name",
            path.display()
        ))),
    }
}

fn check_width(opts: &RenderOptions) -> Result<()> {
    if !(16..=MAX_WIDTH_PX).contains(&opts.width_px) {
        return Err(Error::InvalidArgument(format!(
            "image width {} px: expected 16 to {MAX_WIDTH_PX} px",
            opts.width_px
        )));
    }
    Ok(())
}

/// Draws into every path of `paths` (written as one set).
fn render(map: &Map, scene: Option<&Scene>, paths: &[PathBuf], opts: &RenderOptions) -> Result<()> {
    let view = View::fit(map, opts)?;
    let drawn = paths
        .iter()
        .map(|path| {
            check_target(path, opts)?;
            Ok((path.as_path(), drawing(map, scene, path, &view, opts)?))
        })
        .collect::<Result<Vec<_>>>()?;
    let files: Vec<(&Path, &[u8])> = drawn.iter().map(|(p, b)| (*p, b.as_slice())).collect();
    atomic_write_all(&files)
}

/// The picture for `path` (PNG or SVG, by its extension) as the file's bytes.
fn drawing(
    map: &Map,
    scene: Option<&Scene>,
    path: &Path,
    view: &View,
    opts: &RenderOptions,
) -> Result<Vec<u8>> {
    let size = (opts.width_px, view.height_px);
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    // Drawn in memory and written through the one writer, so a failed write (a full disk)
    // is said as the file system says it, of the output.
    Ok(match ext {
        "svg" => {
            let mut svg = String::new();
            draw(
                SVGBackend::with_string(&mut svg, size).into_drawing_area(),
                map,
                scene,
                view,
                opts,
            )
            .map_err(|e| drawing_error(path, e))?;
            svg.into_bytes()
        }
        // `.png`: `check_target` let no other extension through.
        _ => {
            let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
            draw(
                BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
                map,
                scene,
                view,
                opts,
            )
            .map_err(|e| drawing_error(path, e))?;
            png_bytes(&rgb, size).map_err(|e| drawing_error(path, e))?
        }
    })
}

/// An RGB image of `width` x `height` as PNG.
fn png_bytes(
    rgb: &[u8],
    (width, height): (u32, u32),
) -> std::result::Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgb)?;
    writer.finish()?;
    Ok(out)
}

/// A picture as an output: a `.png` or `.svg` file that is one.
pub const PICTURE: crate::io::FileKind = crate::io::FileKind {
    name: "a PNG or SVG picture",
    extensions: &["png", "svg"],
    recognise: |head| head.starts_with(b"\x89PNG\r\n\x1a\n") || is_svg(head),
};

/// Whether `head` starts an SVG document: XML whose first bytes hold an `<svg` element.
fn is_svg(head: &[u8]) -> bool {
    let text = String::from_utf8_lossy(head);
    let text = text.trim_start();
    (text.starts_with("<?xml") || text.starts_with("<svg") || text.starts_with("<!--"))
        && text.contains("<svg")
}

/// `PREFIX.png` and `PREFIX.svg` for an output prefix.
pub fn output_paths(prefix: &Path) -> [PathBuf; 2] {
    [prefix.with_extension("png"), prefix.with_extension("svg")]
}

fn draw<DB: DrawingBackend>(
    area: DrawingArea<DB, plotters::coord::Shift>,
    map: &Map,
    scene: Option<&Scene>,
    view: &View,
    opts: &RenderOptions,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    draw_road(&area, map, view)?;
    if let Some(scene) = scene {
        draw_agents(&area, scene, view, opts)?;
    }
    area.present()
}

/// A frame that could not be drawn into memory (the animations' buffers).
fn drawing_failed<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> Error {
    Error::InvalidArgument(format!("drawing failed: {e}"))
}

/// A figure that could not be drawn at `path`, said of the file: what fails there is
/// writing it (a full disk, a folder gone), since every figure's input was checked before.
pub fn drawing_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::io(
        path,
        std::io::Error::other(format!("cannot draw the figure: {e}")),
    )
}

/// The ground, the road surface (shoulders, then driving lanes) and the lane marks.
fn draw_road<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    map: &Map,
    view: &View,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    area.fill(&GROUND)?;
    // Shoulders first, so driving lanes paint over shared edges.
    for pass_shoulder in [true, false] {
        for lane in map.lanes().iter().filter(|l| l.is_drivable()) {
            if lane.is_graph_lane() == pass_shoulder {
                continue;
            }
            let color = if pass_shoulder { SHOULDER } else { ASPHALT };
            let outline: Vec<_> = lane.polygon().into_iter().map(|p| view.px(p)).collect();
            area.draw(&Polygon::new(outline, color.filled()))?;
        }
    }
    let mark_px = ((0.15 * view.scale).round() as u32).max(1);
    for lane in map.lanes().iter().filter(|l| l.is_drivable()) {
        for (line, mark) in [
            (&lane.left_boundary, &lane.left_mark),
            (&lane.right_boundary, &lane.right_mark),
        ] {
            let style = MARK.stroke_width(mark_px);
            for piece in mark_pieces(line, mark) {
                let pts: Vec<_> = piece.iter().map(|&p| view.px(p)).collect();
                area.draw(&PathElement::new(pts, style))?;
            }
        }
    }
    Ok(())
}

fn draw_agents<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    scene: &Scene,
    view: &View,
    opts: &RenderOptions,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let now = scene.current_step();
    let line_px = ((0.3 * view.scale).round() as u32).max(1);
    for agent in &scene.agents {
        let color = agent_color(agent, opts);
        let points = |range: std::ops::Range<usize>| -> Vec<(i32, i32)> {
            range
                .filter(|&i| agent.valid[i])
                .map(|i| view.px([agent.states[i].x, agent.states[i].y]))
                .collect()
        };
        let history = points(0..now + 1);
        let future = points(now..scene.steps());
        area.draw(&PathElement::new(
            future,
            color.mix(0.45).stroke_width(line_px),
        ))?;
        area.draw(&PathElement::new(history, color.stroke_width(line_px)))?;
        for i in (now + 1..scene.steps()).filter(|&i| agent.valid[i]) {
            let p = view.px([agent.states[i].x, agent.states[i].y]);
            area.draw(&Circle::new(p, line_px, color.mix(0.6).filled()))?;
        }
        if let Some(footprint) = agent.footprint(now) {
            let corners: Vec<_> = footprint.corners().iter().map(|&c| view.px(c)).collect();
            area.draw(&Polygon::new(corners.clone(), color.filled()))?;
            let mut closed = corners;
            closed.push(closed[0]);
            area.draw(&PathElement::new(closed, BLACK.stroke_width(1)))?;
        }
    }
    Ok(())
}

/// An agent's colour: highlighted, controlled or replayed.
fn agent_color(agent: &SceneAgent, opts: &RenderOptions) -> RGBColor {
    if opts.highlight.contains(&agent.track_id) {
        HIGHLIGHT
    } else if agent.role == AgentRole::Controlled {
        CONTROLLED
    } else {
        REPLAYED
    }
}

/// The visible pieces of a lane boundary with a given mark: the whole line for solid marks,
/// dashes for broken ones, nothing for none.
fn mark_pieces(line: &[[f64; 2]], mark: &RoadMark) -> Vec<Vec<[f64; 2]>> {
    match mark {
        RoadMark::None | RoadMark::Grass | RoadMark::Other(_) => Vec::new(),
        RoadMark::Broken | RoadMark::BrokenBroken | RoadMark::BottsDots => dashes(line),
        _ => vec![line.to_vec()],
    }
}

/// Cuts a polyline into dashes of `DASH_M` separated by gaps of `GAP_M`.
fn dashes(line: &[[f64; 2]]) -> Vec<Vec<[f64; 2]>> {
    let period = DASH_M + GAP_M;
    let mut out = Vec::new();
    let mut current: Vec<[f64; 2]> = Vec::new();
    let mut s = 0.0;
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        // Walk the segment in sub-steps so dash ends land within 10 cm.
        let n = (len / 0.1).ceil().max(1.0) as usize;
        for k in 0..=n {
            let f = k as f64 / n as f64;
            let p = [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])];
            let on = (s + f * len).rem_euclid(period) < DASH_M;
            if on {
                current.push(p);
            } else if current.len() > 1 {
                out.push(std::mem::take(&mut current));
            } else {
                current.clear();
            }
        }
        s += len;
    }
    if current.len() > 1 {
        out.push(current);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two roads a thousand kilometres apart: the picture is drawn within the pixel budget
    /// (smaller), not allocated millions of pixels tall.
    #[test]
    fn a_map_far_taller_than_wide_fits_the_pixel_budget() {
        let road = |id: &str, y: f64| {
            format!(
                r#"<road id="{id}" length="400" junction="-1"><link/>
 <planView><geometry s="0" x="0" y="{y}" hdg="0" length="400"><line/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>
  <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
 </right></laneSection></lanes>
</road>
"#
            )
        };
        let text = format!(
            "<OpenDRIVE><header/>\n{}{}</OpenDRIVE>",
            road("a", 0.0),
            road("b", 1e6)
        );
        let map = Map::from_xodr_str(&text, "far.xodr").expect("two roads");
        for width_px in [2400, MAX_WIDTH_PX] {
            let opts = RenderOptions {
                width_px,
                ..RenderOptions::default()
            };
            let view = View::fit(&map, &opts).expect("a view");
            assert!(view.height_px <= MAX_WIDTH_PX, "{}", view.height_px);
            assert!(f64::from(view.height_px) * f64::from(width_px) <= MAX_PIXELS);
            // Both roads are inside the picture.
            for y in [0.0, 1e6] {
                let (x_px, y_px) = view.px([200.0, y]);
                assert!((0..=width_px as i32).contains(&x_px), "{x_px}");
                assert!((0..=view.height_px as i32).contains(&y_px), "{y_px}");
            }
        }
    }

    #[test]
    fn dashes_follow_the_german_pattern() {
        let line = vec![[0.0, 0.0], [36.0, 0.0]];
        let pieces = dashes(&line);
        assert_eq!(pieces.len(), 2);
        let len = |p: &Vec<[f64; 2]>| p.last().unwrap()[0] - p[0][0];
        assert!((len(&pieces[0]) - DASH_M).abs() < 0.2);
        assert!((pieces[1][0][0] - 18.0).abs() < 0.2);
    }
}
