//! Plots of a sim-to-real run (SVG, so they need no fonts): short-window position error by
//! regime before and after, the same against the noise floor (the unexplained excess), every
//! hypothesis's held-out error with the discovered equation beside the catalogue's fits, and
//! the worst held-out windows simulated before and after against the recording.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::identify::{Evaluated, Outcome};
use super::locate::Mismatch;
use super::report::Report;
use super::unexplained::{RegimeExcess, UNEXPLAINED_RATIO};
use super::windows::Window;
use crate::error::Result;
use crate::render::drawing_error;

/// The files [`write_plots`] writes into its folder.
pub const PLOT_FILES: [&str; 4] = ["regimes.svg", "excess.svg", "hypotheses.svg", "tracks.svg"];

/// Writes `regimes.svg`, `excess.svg`, `hypotheses.svg` and `tracks.svg` into `dir`;
/// returns their paths.
pub fn write_plots(dir: &Path, outcome: &Outcome) -> Result<Vec<PathBuf>> {
    crate::io::create_folder(dir)?;
    let report = &outcome.report;
    let [regimes, excess, hypotheses, tracks] = PLOT_FILES.map(|name| dir.join(name));
    crate::io::atomic_write_with(&regimes, |tmp| {
        draw_regimes(tmp, &report.mismatch, &report.final_model.mismatch)
            .map_err(|e| drawing_error(&regimes, e))
    })?;
    crate::io::atomic_write_with(&excess, |tmp| {
        draw_excess(tmp, &outcome.excess_before, &outcome.excess_after)
            .map_err(|e| drawing_error(&excess, e))
    })?;
    crate::io::atomic_write_with(&hypotheses, |tmp| {
        draw_hypotheses(tmp, report).map_err(|e| drawing_error(&hypotheses, e))
    })?;
    crate::io::atomic_write_with(&tracks, |tmp| {
        draw_tracks(
            tmp,
            &outcome.heldout,
            &outcome.baseline,
            &outcome.final_model,
        )
        .map_err(|e| drawing_error(&tracks, e))
    })?;
    Ok(vec![regimes, excess, hypotheses, tracks])
}

/// Per regime variable: each bin's short-window error over its noise floor, before and
/// after, with the floor (1) and the "unexplained" bar (1.2) drawn.
fn draw_excess(path: &Path, before: &[RegimeExcess], after: &[RegimeExcess]) -> DrawResult {
    let mut variables: Vec<&str> = before.iter().map(|b| b.variable.as_str()).collect();
    variables.dedup();
    let root = SVGBackend::new(path, (1500, 340)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, variables.len().max(1)));
    for (panel, variable) in panels.iter().zip(&variables) {
        let bins_of = |all: &[RegimeExcess]| -> Vec<RegimeExcess> {
            all.iter()
                .filter(|b| b.variable == *variable)
                .cloned()
                .collect()
        };
        let (b, a) = (bins_of(before), bins_of(after));
        let unit = b.first().map_or("", |x| x.unit.as_str());
        bin_panel(
            panel,
            &format!("{variable} ({unit})"),
            "error / noise floor",
            &b.iter().map(|x| x.range.clone()).collect::<Vec<_>>(),
            [
                &b.iter().map(|x| x.ratio).collect::<Vec<_>>(),
                &a.iter().map(|x| x.ratio).collect::<Vec<_>>(),
            ],
            &[1.0, UNEXPLAINED_RATIO],
        )?;
    }
    root.present()?;
    Ok(())
}

/// Held-out position RMSE of every hypothesis: baseline, nominal refit, each catalogue
/// effect, the discovered equation (written out) and the final model, against the floor.
fn draw_hypotheses(path: &Path, report: &Report) -> DrawResult {
    let mut rows: Vec<(String, f64, RGBColor)> = vec![
        ("baseline".into(), report.baseline.heldout_pos_rmse_m, RED),
        (
            "nominal refit".into(),
            report.nominal_refit.heldout_pos_rmse_m,
            RGBColor(120, 120, 120),
        ),
    ];
    for c in &report.candidates {
        let params: Vec<String> = c
            .params
            .iter()
            .map(|(k, v)| format!("{k} {:.3}", v.value))
            .collect();
        rows.push((
            format!("{} ({})", c.effect, params.join(", ")),
            c.heldout_pos_rmse_m,
            RGBColor(90, 140, 200),
        ));
    }
    if let Some(d) = &report.discovered_candidate {
        rows.push((
            format!("discovered: {}", d.equation),
            d.heldout_pos_rmse_m,
            RGBColor(230, 140, 20),
        ));
    }
    rows.push((
        format!("final: {}", report.final_model.model),
        report.final_model.heldout_pos_rmse_m,
        BLUE,
    ));
    let top = rows
        .iter()
        .map(|r| r.1)
        .fold(report.unexplained.floor_pos_m, f64::max)
        * 1.1;
    let height = 60 + 34 * rows.len() as u32;
    let root = SVGBackend::new(path, (1500, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let (labels, bars) = root.split_horizontally(760);
    let n = rows.len() as f64;
    let mut chart = ChartBuilder::on(&bars)
        .caption(
            "held-out position RMSE (m); black: noise floor",
            ("sans-serif", 16),
        )
        .margin(8)
        .x_label_area_size(30)
        .build_cartesian_2d(0.0..top, 0.0..n)?;
    chart.configure_mesh().disable_y_mesh().draw()?;
    let floor = report.unexplained.floor_pos_m;
    chart.draw_series(LineSeries::new(
        [(floor, 0.0), (floor, n)],
        BLACK.stroke_width(2),
    ))?;
    chart.draw_series(rows.iter().enumerate().map(|(k, (_, rmse, colour))| {
        let y = n - k as f64 - 1.0;
        Rectangle::new([(0.0, y + 0.2), (*rmse, y + 0.8)], colour.filled())
    }))?;
    // Labels in the left area, one per bar (aligned with the chart's rows).
    let plot_top = 8 + 24;
    let row_height = (height as i32 - plot_top - 30 - 8) as f64 / n;
    for (k, (label, rmse, _)) in rows.iter().enumerate() {
        let y = plot_top + (row_height * (k as f64 + 0.35)) as i32;
        labels.draw(&Text::new(
            format!("{label}: {rmse:.3} m"),
            (8, y),
            ("sans-serif", 14),
        ))?;
    }
    root.present()?;
    Ok(())
}

type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

/// One panel of bars per bin (`labels`), before (red) and after (blue), with horizontal
/// reference lines at `levels`.
fn bin_panel(
    panel: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    caption: &str,
    y_desc: &str,
    labels: &[String],
    [before, after]: [&[f64]; 2],
    levels: &[f64],
) -> DrawResult {
    let top = before
        .iter()
        .chain(after)
        .chain(levels)
        .fold(0.01, |a, &b| f64::max(a, b));
    let width = labels.len() as f64;
    let mut chart = ChartBuilder::on(panel)
        .caption(caption, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(45)
        .build_cartesian_2d(-0.5..(width - 0.5), 0.0..top * 1.1)?;
    chart
        .configure_mesh()
        .x_labels(labels.len())
        .x_label_formatter(&|x| {
            let k = x.round();
            if (x - k).abs() < 1e-6 && k >= 0.0 {
                labels.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(y_desc)
        .draw()?;
    for &level in levels {
        chart.draw_series(LineSeries::new(
            [(-0.5, level), (width - 0.5, level)],
            BLACK.mix(0.6).stroke_width(1),
        ))?;
    }
    for (values, colour, offset, name) in
        [(before, RED, -0.18, "before"), (after, BLUE, 0.02, "after")]
    {
        chart
            .draw_series(values.iter().enumerate().map(|(k, &value)| {
                let x = k as f64 + offset;
                Rectangle::new([(x, 0.0), (x + 0.16, value)], colour.filled())
            }))?
            .label(name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 10, y + 4)], colour.filled()));
    }
    chart.configure_series_labels().border_style(BLACK).draw()?;
    Ok(())
}

fn draw_regimes(path: &Path, before: &Mismatch, after: &Mismatch) -> DrawResult {
    let root = SVGBackend::new(path, (1500, 320)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, before.regimes.len().max(1)));
    for (panel, (b, a)) in panels.iter().zip(before.regimes.iter().zip(&after.regimes)) {
        bin_panel(
            panel,
            &format!("{} ({})", b.variable, b.unit),
            "position RMSE (m)",
            &b.bins.iter().map(|x| x.range.clone()).collect::<Vec<_>>(),
            [
                &b.bins.iter().map(|x| x.rms.pos_m).collect::<Vec<_>>(),
                &a.bins.iter().map(|x| x.rms.pos_m).collect::<Vec<_>>(),
            ],
            &[],
        )?;
    }
    root.present()?;
    Ok(())
}

fn draw_tracks(
    path: &Path,
    heldout: &[Window],
    baseline: &Evaluated,
    final_model: &Evaluated,
) -> DrawResult {
    // The three held-out windows the baseline gets most wrong.
    let mut worst: Vec<usize> = (0..heldout.len()).collect();
    let end_error = |w: usize| baseline.errors[w].last().map_or(0.0, |e| e.position_sq());
    worst.sort_by(|a, b| end_error(*b).total_cmp(&end_error(*a)));
    worst.truncate(3);
    let root = SVGBackend::new(path, (1500, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, 3));
    for (panel, &w) in panels.iter().zip(&worst) {
        let window = &heldout[w];
        let recorded: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
            .chain(window.recorded.iter().map(|r| (r[0], r[1])))
            .collect();
        let path_of = |e: &Evaluated| -> Vec<(f64, f64)> {
            std::iter::once((0.0, 0.0))
                .chain(e.errors[w].iter().map(|s| s.simulated))
                .collect()
        };
        let (before, after) = (path_of(baseline), path_of(final_model));
        let all = recorded.iter().chain(&before).chain(&after);
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for &(x, y) in all {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        // Equal axes, so turns look like turns.
        let span = (hi.0 - lo.0).max(hi.1 - lo.1).max(1.0) * 0.55;
        let centre = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!(
                    "track {} at t = {:.1} s",
                    window.track,
                    window.start as f64 * window.period
                ),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(
                centre.0 - span..centre.0 + span,
                centre.1 - span..centre.1 + span,
            )?;
        chart
            .configure_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()?;
        for (points, colour, name) in [
            (recorded, BLACK, "recorded"),
            (before, RED, "nominal (before)"),
            (after, BLUE, "identified (after)"),
        ] {
            chart
                .draw_series(LineSeries::new(points, colour.stroke_width(2)))?
                .label(name)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 14, y)], colour));
        }
        chart.configure_series_labels().border_style(BLACK).draw()?;
    }
    root.present()?;
    Ok(())
}
