//! The study's figures: the Pareto plot (long-tail infractions against nominal realism, the
//! baselines' frontier shaded), the feature histograms behind each JSD, training curves, and
//! top-down rollouts beside the log. Charts are SVG (their text needs no fonts there; a PNG
//! chart would need system fonts); rollouts are PNG through [`crate::render`], whose SVG of a
//! whole road is ten times the size (`rtr render` draws one when wanted).

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::features::Feature;
use super::metrics::Metric;
use super::report::MethodResult;
use super::sets::EvalSet;
use crate::error::Result;
use crate::io::atomic_write_with;
use crate::render::{RenderOptions, drawing_error, render_scene};
use crate::scene::{AgentRole, Scene};
use crate::train::CurveRow;

type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(214, 39, 40),
];

/// The method the paper proposes; every other learned method is a baseline of the frontier.
const PROPOSED: &str = "RTR";
/// The hand-written reference driver: drawn, but not a learned baseline of the frontier.
const REFERENCE: &str = "IDM";

/// A row or scene name as one file-name part: lower case, letters, digits, `-` and `.` kept,
/// every other run of characters one `_` (so `RL (small/rl)` cannot name a folder).
pub fn file_stem(name: &str) -> String {
    let mut out = String::new();
    for c in name.to_lowercase().chars() {
        if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
            out.push(c);
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    out.trim_matches('_').to_string()
}

/// Points (x = nominal `realism`, y = long-tail infraction %, collision or off-road, the
/// paper's trade-off) of the methods that have both.
fn pareto_points(methods: &[MethodResult], realism: Metric) -> Vec<(String, f64, f64)> {
    methods
        .iter()
        .filter_map(|m| {
            let x = m.set(EvalSet::Nominal)?.get(realism)?.value;
            let y = m.set(EvalSet::Longtail)?.get(Metric::InfractionPct)?.value;
            Some((m.method.clone(), x, y))
        })
        .collect()
}

/// The lower-left staircase of `points` (both axes lower is better): the baselines' frontier.
pub fn frontier(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for p in sorted {
        if out.last().is_none_or(|last| p.1 < last.1) {
            out.push(p);
        }
    }
    out
}

/// `pareto_<metric>.svg`: long-tail infraction % against a nominal realism metric; the region
/// the learned baselines dominate is shaded, so a method outside it is beyond their frontier.
pub fn pareto(dir: &Path, methods: &[MethodResult], realism: Metric) -> Result<Option<PathBuf>> {
    let points = pareto_points(methods, realism);
    if points.is_empty() {
        return Ok(None);
    }
    let path = dir.join(format!("pareto_{}.svg", realism.key()));
    atomic_write_with(&path, |tmp| {
        draw_pareto(tmp, &points, realism).map_err(|e| drawing_error(&path, e))
    })?;
    Ok(Some(path))
}

fn draw_pareto(path: &Path, points: &[(String, f64, f64)], realism: Metric) -> DrawResult {
    // Realism spans decades (a policy that parks has 40x IL's FDE): a log axis keeps the
    // realistic methods apart instead of in one corner.
    let floor = 1e-3;
    let xs = || points.iter().map(|p| p.1.max(floor));
    let x_min = xs().fold(f64::INFINITY, f64::min) / 1.5;
    let x_max = xs().fold(floor, f64::max) * 1.5;
    let y_max = points.iter().map(|p| p.2).fold(0.0, f64::max) * 1.25 + 1.0;
    let root = SVGBackend::new(path, (720, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Long-tail infractions vs nominal realism",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d((x_min..x_max).log_scale(), 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc(format!(
            "nominal {} (lower is better; log scale)",
            realism.header()
        ))
        .y_desc("long-tail collision or off-road % (lower is better)")
        .draw()?;
    let baselines: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.0 != PROPOSED && p.0 != REFERENCE)
        .map(|p| (p.1.max(floor), p.2))
        .collect();
    let front = frontier(&baselines);
    if let (Some(first), Some(last)) = (front.first(), front.last()) {
        // Dominated region: above and right of the staircase.
        let mut outline = vec![(first.0, y_max)];
        let mut previous_y = y_max;
        for &(x, y) in &front {
            outline.push((x, previous_y));
            outline.push((x, y));
            previous_y = y;
        }
        outline.push((x_max, last.1));
        outline.push((x_max, y_max));
        chart.draw_series(std::iter::once(Polygon::new(
            outline,
            RGBColor(200, 200, 200).mix(0.5).filled(),
        )))?;
    }
    for (k, (name, x, y)) in points.iter().enumerate() {
        let color = if name == PROPOSED {
            PALETTE[7]
        } else {
            PALETTE[k % 7]
        };
        chart
            .draw_series(std::iter::once(Circle::new(
                (x.max(floor), *y),
                6,
                color.filled(),
            )))?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x, y), 5, color.filled()));
        chart.draw_series(std::iter::once(Text::new(
            name.clone(),
            (x.max(floor), *y),
            ("sans-serif", 14).into_font(),
        )))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// `histograms_<method>.svg`: for each feature, the simulated and the logged distribution on
/// the nominal set (what its JSD compares).
pub fn histograms(dir: &Path, method: &MethodResult) -> Result<Option<PathBuf>> {
    let Some(nominal) = method.set(EvalSet::Nominal) else {
        return Ok(None);
    };
    let name = file_stem(&method.method);
    let path = dir.join(format!("histograms_{name}.svg"));
    atomic_write_with(&path, |tmp| {
        draw_histograms(tmp, method, nominal).map_err(|e| drawing_error(&path, e))
    })?;
    Ok(Some(path))
}

fn draw_histograms(
    path: &Path,
    method: &MethodResult,
    nominal: &super::evaluate::SetResult,
) -> DrawResult {
    let root = SVGBackend::new(path, (1600, 380)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, Feature::ALL.len()));
    for ((panel, feature), (sim, log)) in panels
        .iter()
        .zip(Feature::ALL)
        .zip(nominal.total.simulated.iter().zip(&nominal.total.logged))
    {
        let (p_sim, p_log) = (
            sim.probabilities().unwrap_or_else(|| vec![0.0; sim.bins()]),
            log.probabilities().unwrap_or_else(|| vec![0.0; log.bins()]),
        );
        let top = p_sim.iter().chain(&p_log).fold(0.01f64, |a, &b| a.max(b));
        let jsd = nominal
            .get(Metric::Jsd(feature))
            .map_or("–".into(), |e| format!("{:.3}", e.value));
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{}: JSD {jsd} nats", method.method),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(45)
            .build_cartesian_2d(sim.lo..sim.hi, 0.0..top * 1.1)?;
        chart
            .configure_mesh()
            .x_desc(feature.label())
            .y_desc("share")
            .draw()?;
        let steps = |p: &[f64]| -> Vec<(f64, f64)> {
            let mut out = Vec::with_capacity(2 * p.len());
            for (k, &v) in p.iter().enumerate() {
                out.push((sim.edge(k), v));
                out.push((sim.edge(k + 1), v));
            }
            out
        };
        chart
            .draw_series(LineSeries::new(steps(&p_log), BLACK.stroke_width(2)))?
            .label("log")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLACK));
        chart
            .draw_series(LineSeries::new(steps(&p_sim), PALETTE[0].stroke_width(2)))?
            .label("simulated")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], PALETTE[0]));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// `training_curves.svg`: each method's rollout collision % and loss per iteration.
pub fn training_curves(dir: &Path, runs: &[(String, Vec<CurveRow>)]) -> Result<Option<PathBuf>> {
    if runs.iter().all(|(_, rows)| rows.is_empty()) {
        return Ok(None);
    }
    let path = dir.join("training_curves.svg");
    atomic_write_with(&path, |tmp| {
        draw_curves(tmp, runs).map_err(|e| drawing_error(&path, e))
    })?;
    Ok(Some(path))
}

fn draw_curves(path: &Path, runs: &[(String, Vec<CurveRow>)]) -> DrawResult {
    let root = SVGBackend::new(path, (1300, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, 2));
    type Pick = fn(&CurveRow) -> f64;
    let series: [(&str, Pick); 2] = [
        ("rollout collision % (PPO methods)", |r| r.collision_pct),
        ("training loss", |r| r.loss),
    ];
    let last_iteration = runs
        .iter()
        .flat_map(|(_, rows)| rows.iter().map(|r| r.iteration))
        .max()
        .unwrap_or(0) as f64
        + 1.0;
    for (panel, (title, pick)) in panels.iter().zip(series) {
        let values: Vec<f64> = runs
            .iter()
            .flat_map(|(_, rows)| rows.iter().map(pick))
            .filter(|v| v.is_finite())
            .collect();
        let lo = values.iter().copied().fold(0.0, f64::min);
        let hi = values.iter().copied().fold(1e-6, f64::max);
        let mut chart = ChartBuilder::on(panel)
            .caption(title, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(0.0..last_iteration, lo..hi * 1.05)?;
        chart.configure_mesh().x_desc("iteration").draw()?;
        for (k, (name, rows)) in runs.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let points: Vec<(f64, f64)> = rows
                .iter()
                .map(|r| (r.iteration as f64 + 0.5, pick(r)))
                .filter(|p| p.1.is_finite())
                .collect();
            chart
                .draw_series(LineSeries::new(points, color.stroke_width(2)))?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// `scene` with its controlled agents' (and heroes') future replaced by the simulated one (`poses`
/// `[N][T + 1]` of centre x, y, heading, speed; `present` likewise), for drawing a rollout
/// exactly as a log is drawn.
pub fn simulated_scene(scene: &Scene, poses: &[Vec<[f64; 4]>], present: &[Vec<bool>]) -> Scene {
    let mut out = scene.clone();
    let now = scene.current_step();
    for (i, agent) in out.agents.iter_mut().enumerate() {
        if agent.role == AgentRole::Replayed || i >= poses.len() {
            continue;
        }
        for (t, (p, &ok)) in poses[i].iter().zip(&present[i]).enumerate().skip(1) {
            let step = now + t;
            if step >= agent.states.len() {
                break;
            }
            agent.valid[step] = ok;
            agent.states[step] = crate::data::AgentState {
                x: p[0],
                y: p[1],
                heading: p[2],
                speed: p[3],
                accel: 0.0,
            };
        }
    }
    out
}

/// `rollout_<scene>_log.png` and `rollout_<scene>_<method>.png`: the same view of the
/// log and of each method's rollout (history, current boxes, future paths). A generated
/// scene's "log" holds only its initial state.
pub fn rollout_pictures(
    dir: &Path,
    log: &Scene,
    rollouts: &[(String, Scene)],
) -> Result<Vec<PathBuf>> {
    let centre = log
        .agents
        .iter()
        .filter_map(|a| a.footprint(log.current_step()).map(|b| b.center))
        .fold(([0.0, 0.0], 0.0), |(s, n), c| {
            ([s[0] + c[0], s[1] + c[1]], n + 1.0)
        });
    let focus = (centre.1 > 0.0).then(|| ([centre.0[0] / centre.1, centre.0[1] / centre.1], 160.0));
    let options = RenderOptions {
        width_px: 1600,
        focus,
        ..RenderOptions::default()
    };
    let id = file_stem(&log.id);
    let mut written = Vec::new();
    let named = std::iter::once(("log".to_string(), log))
        .chain(rollouts.iter().map(|(m, s)| (file_stem(m), s)));
    for (name, scene) in named {
        let path = dir.join(format!("rollout_{id}_{name}.png"));
        render_scene(scene, &path, &options)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_stems_never_name_folders() {
        assert_eq!(file_stem("RL (small/scene_level)"), "rl_small_scene_level");
        assert_eq!(file_stem("BC+RL"), "bc_rl");
        assert_eq!(file_stem("a9-test-t0436.0"), "a9-test-t0436.0");
        assert_eq!(file_stem("lambda=5 alpha=0.3"), "lambda_5_alpha_0.3");
    }

    #[test]
    fn frontier_keeps_the_non_dominated_staircase() {
        let points = [(1.0, 9.0), (2.0, 5.0), (3.0, 6.0), (4.0, 1.0), (2.5, 5.0)];
        assert_eq!(frontier(&points), vec![(1.0, 9.0), (2.0, 5.0), (4.0, 1.0)]);
        assert!(frontier(&[]).is_empty());
    }
}
