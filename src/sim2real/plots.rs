//! Plots of a sim-to-real run (SVG, so they need no fonts): short-window position error by
//! regime before and after, and the worst held-out windows simulated before and after
//! against the recording.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::identify::Evaluated;
use super::locate::Mismatch;
use super::windows::Window;
use crate::error::{Error, Result};

fn plot_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::InvalidArgument(format!("cannot draw {}: {e}", path.display()))
}

/// Writes `regimes.svg` and `tracks.svg` into `dir`; returns their paths.
pub fn write_plots(
    dir: &Path,
    before: &Mismatch,
    after: &Mismatch,
    heldout: &[Window],
    baseline: &Evaluated,
    final_model: &Evaluated,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let regimes = dir.join("regimes.svg");
    let tracks = dir.join("tracks.svg");
    crate::io::atomic_write_with(&regimes, |tmp| {
        draw_regimes(tmp, before, after).map_err(|e| plot_error(&regimes, e))
    })?;
    crate::io::atomic_write_with(&tracks, |tmp| {
        draw_tracks(tmp, heldout, baseline, final_model).map_err(|e| plot_error(&tracks, e))
    })?;
    Ok(vec![regimes, tracks])
}

type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

fn draw_regimes(path: &Path, before: &Mismatch, after: &Mismatch) -> DrawResult {
    let root = SVGBackend::new(path, (1500, 320)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, before.regimes.len().max(1)));
    for (panel, (b, a)) in panels.iter().zip(before.regimes.iter().zip(&after.regimes)) {
        let top = b
            .bins
            .iter()
            .chain(&a.bins)
            .map(|x| x.rms.pos_m)
            .fold(0.01, f64::max);
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{} ({})", b.variable, b.unit), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(45)
            .build_cartesian_2d(-0.5..(b.bins.len() as f64 - 0.5), 0.0..top * 1.1)?;
        let labels: Vec<String> = b.bins.iter().map(|x| x.range.clone()).collect();
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
            .y_desc("position RMSE (m)")
            .draw()?;
        for (bins, colour, offset, name) in [
            (&b.bins, RED, -0.18, "before"),
            (&a.bins, BLUE, 0.02, "after"),
        ] {
            chart
                .draw_series(bins.iter().enumerate().map(|(k, bin)| {
                    let x = k as f64 + offset;
                    Rectangle::new([(x, 0.0), (x + 0.16, bin.rms.pos_m)], colour.filled())
                }))?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 4), (x + 10, y + 4)], colour.filled())
                });
        }
        chart.configure_series_labels().border_style(BLACK).draw()?;
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
