//! The lambda x alpha study (paper table "Balancing realism and infraction avoidance") as one
//! command: RTR is trained at every (lambda, alpha) point from one base run file, each point
//! in its own run folder (finished points are kept, interrupted ones resumed), then every
//! point is evaluated and tabulated.

use std::path::{Path, PathBuf};

use indicatif::ProgressBar;

use crate::data::A9Dataset;
use crate::error::{Error, Result};
use crate::eval::evaluate::EvalConfig;
use crate::eval::report::{MethodResult, markdown_table, results_json};
use crate::eval::sets::EvalScenes;
use crate::eval::study::{Entry, evaluate_entries};
use crate::eval::trained::TrainedPolicy;
use crate::io::atomic_write;
use crate::train::{Method, TrainConfig};

/// The paper's table: (lambda, alpha).
pub const PAPER_POINTS: [(f64, f64); 6] = [
    (0.0, 0.0),
    (1.0, 0.5),
    (5.0, 0.5),
    (10.0, 0.5),
    (5.0, 0.3),
    (5.0, 0.7),
];

/// Parses `L:A,L:A,...`.
pub fn parse_points(text: &str) -> Result<Vec<(f64, f64)>> {
    text.split(',')
        .map(|p| {
            let bad = || {
                Error::InvalidArgument(format!(
                    "sweep point `{p}`: expected LAMBDA:ALPHA with lambda >= 0 and alpha in [0, 1], e.g. 5:0.5"
                ))
            };
            let (l, a) = p.trim().split_once(':').ok_or_else(bad)?;
            let (l, a): (f64, f64) = (
                l.trim().parse().map_err(|_| bad())?,
                a.trim().parse().map_err(|_| bad())?,
            );
            if !(l.is_finite() && l >= 0.0 && (0.0..=1.0).contains(&a)) {
                return Err(bad());
            }
            Ok((l, a))
        })
        .collect::<Result<Vec<_>>>()
        .and_then(refuse_repeated_points)
}

/// Points this close count as one: lambda relative to its size, alpha (a share of the
/// batch's initial states, far coarser than this) absolute.
const SAME_POINT: f64 = 1e-6;

/// Two spellings of one point (`1:0.5`, `1.0:0.50`) would train one folder twice, and two
/// points a rounding apart (`1:0.5`, `1:0.50000000001`) would train the same run twice.
fn refuse_repeated_points(points: Vec<(f64, f64)>) -> Result<Vec<(f64, f64)>> {
    let same = |a: &(f64, f64), b: &(f64, f64)| {
        (a.0 - b.0).abs() <= SAME_POINT * a.0.abs().max(1.0) && (a.1 - b.1).abs() <= SAME_POINT
    };
    for (k, point) in points.iter().enumerate() {
        if let Some(earlier) = points[..k].iter().find(|p| same(p, point)) {
            let what = if earlier == point {
                "is given twice".to_string()
            } else {
                format!(
                    "is {}:{} again, within {SAME_POINT:e}",
                    earlier.0, earlier.1
                )
            };
            return Err(Error::InvalidArgument(format!(
                "sweep point {}:{} {what}; expected each LAMBDA:ALPHA once",
                point.0, point.1
            )));
        }
    }
    Ok(points)
}

/// The run folder of one point.
pub fn point_dir(out: &Path, lambda: f64, alpha: f64) -> PathBuf {
    out.join(format!("lambda{lambda}_alpha{alpha}"))
}

/// The run config of one point: `base` with its lambda and alpha, validated.
fn point_config(base: &TrainConfig, lambda: f64, alpha: f64) -> Result<TrainConfig> {
    let mut config = base.clone();
    config.lambda = lambda;
    config.alpha = alpha;
    config.validate("sweep point")?;
    Ok(config)
}

/// Refuses what [`train_points`] would refuse, before any data is loaded or point trained: a
/// base run file of another method than RTR, a point not yet finished that its config rejects.
pub fn check_points(base: &TrainConfig, points: &[(f64, f64)], out: &Path) -> Result<()> {
    if base.method != Method::Rtr {
        return Err(Error::InvalidArgument(format!(
            "a lambda x alpha sweep trains RTR, but the base run file says method = \"{}\"",
            base.method.name()
        )));
    }
    for &(lambda, alpha) in points {
        if !point_dir(out, lambda, alpha).join("policy.bpk").is_file() {
            point_config(base, lambda, alpha)?;
        }
    }
    Ok(())
}

/// Trains every point not yet finished (with `stop_after`, at most that many iterations per
/// point in this call); returns the run folders in point order.
pub fn train_points(
    base: &TrainConfig,
    points: &[(f64, f64)],
    dataset: &A9Dataset,
    out: &Path,
    stop_after: Option<usize>,
    progress: &dyn Fn(&str) -> ProgressBar,
) -> Result<Vec<PathBuf>> {
    check_points(base, points, out)?;
    points
        .iter()
        .map(|&(lambda, alpha)| {
            let dir = point_dir(out, lambda, alpha);
            let config = point_config(base, lambda, alpha)?;
            crate::train::identity::check_same_run(&dir, &config)?;
            if dir.join("policy.bpk").is_file() {
                return Ok(dir);
            }
            let resume = dir.join("checkpoints").is_dir();
            let bar = progress(&format!("lambda {lambda} alpha {alpha}"));
            crate::train::session::train(config, dataset, &dir, resume, stop_after, &bar)?;
            bar.finish_and_clear();
            Ok(dir)
        })
        .collect()
}

/// Evaluates the points' policies on `sets`; rows are named `lambda=L alpha=A`, with the
/// checkpoint evaluated for a point not yet finished.
pub fn evaluate_points(
    points: &[(f64, f64)],
    dirs: &[PathBuf],
    sets: &[EvalScenes],
    device: &burn::prelude::Device,
    config: &EvalConfig,
    progress: &ProgressBar,
) -> Result<Vec<MethodResult>> {
    let entries = dirs
        .iter()
        .map(|d| TrainedPolicy::load(d, device).map(|t| Entry::Trained(Box::new(t))))
        .collect::<Result<Vec<_>>>()?;
    let mut results = evaluate_entries(&entries, sets, device, config, progress)?;
    for ((r, (lambda, alpha)), entry) in results.iter_mut().zip(points).zip(&entries) {
        r.method = match entry {
            Entry::Trained(t) if t.checkpoint().is_some() => format!(
                "lambda={lambda} alpha={alpha} ({}, unfinished)",
                t.checkpoint().unwrap_or_default()
            ),
            _ => format!("lambda={lambda} alpha={alpha}"),
        };
    }
    Ok(results)
}

/// Writes `results.json` and `table.md` of a sweep into `out`.
pub fn write_sweep(out: &Path, results: &[MethodResult], sets: &[EvalScenes]) -> Result<()> {
    let json = serde_json::to_string_pretty(&results_json(results))
        .map_err(|e| Error::InvalidArgument(format!("results do not serialise: {e}")))?;
    atomic_write(&out.join("results.json"), json.as_bytes())?;
    let names: Vec<_> = sets.iter().map(|s| s.set).collect();
    atomic_write(
        &out.join("table.md"),
        markdown_table(results, &names).as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_parse_and_bad_ones_are_named() {
        assert_eq!(
            parse_points("0:0, 5:0.5").unwrap(),
            vec![(0.0, 0.0), (5.0, 0.5)]
        );
        for bad in ["5", "5:1.5", "-1:0.5", "x:0.2"] {
            let e = parse_points(bad).unwrap_err().to_string();
            assert!(e.contains(&format!("`{bad}`")), "{e}");
        }
        let e = parse_points("1:0.5,1:0.50000000001")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is 1:0.5 again"), "{e}");
        let e = parse_points("1000000:0.5,1000000.5:0.5")
            .unwrap_err()
            .to_string();
        assert!(e.contains("again"), "lambda relative to its size: {e}");
        assert_eq!(parse_points("1:0.5,1:0.501").unwrap().len(), 2);
        assert_eq!(
            point_dir(Path::new("runs/sweep"), 5.0, 0.3),
            Path::new("runs/sweep/lambda5_alpha0.3")
        );
    }
}
