//! Training curves: one CSV row per optimizer step, rewritten atomically after each step (the
//! file is small) so it always matches the run up to its last completed step. A resumed run
//! drops the rows past its checkpoint and continues the same file.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::atomic_write;

/// One optimizer step. Losses are per agent-step means (0 where a method has no such term).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CurveRow {
    pub iteration: usize,
    pub update: usize,
    pub epoch: usize,
    pub learning_rate: f64,
    /// The total loss the step minimised.
    pub loss: f64,
    pub il_loss: f64,
    pub bc_loss: f64,
    pub policy_loss: f64,
    pub value_loss: f64,
    pub kl: f64,
    /// Share of PPO ratios outside the clip range.
    pub clip_fraction: f64,
    /// Before clipping.
    pub policy_grad_norm: f64,
    pub value_grad_norm: f64,
    /// Of the controlled agents in this iteration's PPO rollouts (0 without PPO).
    pub collision_pct: f64,
    pub offroad_pct: f64,
    /// Mean PPO reward per alive agent-step.
    pub mean_reward: f64,
    /// Alive agent-steps in this iteration's PPO rollouts (the PPO sample count).
    pub ppo_agent_steps: usize,
    /// Initial states in this step's minibatch.
    pub scenes: usize,
    /// Seconds since the run (or the resumed run) started: the only column that differs
    /// between an interrupted and an uninterrupted run.
    pub elapsed_s: f64,
    /// Estimated KL divergence per PPO agent-step of the policy before this step from the one
    /// that collected the experience (0 without PPO; absent in curves written before it).
    #[serde(default)]
    pub approx_kl: f64,
}

pub struct Curves {
    path: PathBuf,
    rows: Vec<CurveRow>,
}

impl Curves {
    /// A new file at `path` (any existing one is replaced at the first write).
    pub fn new(path: PathBuf) -> Self {
        Self {
            path,
            rows: Vec::new(),
        }
    }

    /// The rows of `path` up to `iteration`, to continue after a checkpoint. A file that is
    /// gone (deleted) does not stop the run: its curves go on from `iteration`.
    pub fn resume(path: PathBuf, iteration: usize) -> Result<Self> {
        if path.symlink_metadata().is_err() {
            return Ok(Self {
                path,
                rows: Vec::new(),
            });
        }
        let rows: Vec<CurveRow> = read(&path)?
            .into_iter()
            .filter(|r| r.iteration < iteration)
            .collect();
        // Every finished iteration wrote rows: none means the file is not this run's.
        if iteration > 0 && rows.is_empty() {
            return Err(Error::invalid(
                path.display().to_string(),
                "rows",
                format!(
                    "no curve rows before iteration {iteration}, where the checkpoint is; \
                     expected this run's curves.csv"
                ),
            ));
        }
        Ok(Self { path, rows })
    }

    pub fn push(&mut self, row: CurveRow) -> Result<()> {
        self.rows.push(row);
        self.write()
    }

    /// Drops the rows from `iteration` on (those of iterations no checkpoint holds, after a
    /// checkpoint failed to be written), so the file again matches the run's newest
    /// checkpoint.
    pub fn truncate(&mut self, iteration: usize) -> Result<()> {
        self.rows.retain(|r| r.iteration < iteration);
        self.write()
    }

    fn write(&self) -> Result<()> {
        if self.rows.is_empty() {
            let header = format!("{}\n", columns().join(","));
            return atomic_write(&self.path, header.as_bytes());
        }
        let mut writer = csv::Writer::from_writer(Vec::new());
        for r in &self.rows {
            writer.serialize(r).map_err(|e| {
                Error::invalid(self.path.display().to_string(), "row", e.to_string())
            })?;
        }
        let bytes = writer
            .into_inner()
            .map_err(|e| Error::invalid(self.path.display().to_string(), "csv", e.to_string()))?;
        atomic_write(&self.path, &bytes)
    }

    pub fn rows(&self) -> &[CurveRow] {
        &self.rows
    }
}

/// Reads a curves file; errors name the line.
pub fn read(path: &Path) -> Result<Vec<CurveRow>> {
    let text = crate::io::read_bytes(path, crate::io::Format::Curves)?;
    let mut reader = csv::Reader::from_reader(text.as_slice());
    // The header is the columns `push` writes, so a foreign file is refused even without rows.
    let header = reader.headers().map_err(|e| csv_error(path, e))?.clone();
    let expected = columns();
    // Files written before the newest columns existed lack them; those read as their default.
    let known =
        header.len() >= expected.len() - COLUMNS_ADDED_LATER && header.len() <= expected.len();
    if !known
        || header
            .iter()
            .ne(expected.iter().take(header.len()).map(String::as_str))
    {
        return Err(Error::Parse {
            source_name: path.display().to_string(),
            line: 1,
            column: 0,
            message: format!(
                "header is `{}`; expected the training-curve columns `{}`",
                header.iter().collect::<Vec<_>>().join(","),
                expected.join(",")
            ),
        });
    }
    reader
        .deserialize()
        .map(|r| r.map_err(|e| csv_error(path, e)))
        .collect()
}

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line() as usize);
    Error::Parse {
        source_name: path.display().to_string(),
        line,
        column: 0,
        message: e.to_string(),
    }
}

/// Trailing columns of [`CurveRow`] that older curve files do not have (`approx_kl`).
const COLUMNS_ADDED_LATER: usize = 1;

/// The column names `push` writes: the header csv gives a serialised row.
fn columns() -> Vec<String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let _ = writer.serialize(CurveRow::default());
    let bytes = writer.into_inner().unwrap_or_default();
    let text = String::from_utf8_lossy(&bytes);
    let header = text.lines().next().unwrap_or_default();
    header.split(',').map(str::to_string).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A curve file written before `approx_kl` existed (every shipped model's) still reads, the
    /// missing column as 0; a header that is neither is refused.
    #[test]
    fn older_curve_files_read_and_foreign_ones_do_not() {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut columns = columns();
        assert_eq!(columns.pop().as_deref(), Some("approx_kl"));
        let row: Vec<String> = (0..columns.len())
            .map(|k| {
                if [0, 1, 2, 16, 17].contains(&k) {
                    "1".into()
                } else {
                    "0.5".into()
                }
            })
            .collect();
        let old = dir.path().join("old.csv");
        std::fs::write(&old, format!("{}\n{}\n", columns.join(","), row.join(","))).unwrap();
        let rows = read(&old).expect("an older file reads");
        assert_eq!(rows.len(), 1);
        assert_eq!((rows[0].iteration, rows[0].approx_kl), (1, 0.0));

        columns.pop();
        let foreign = dir.path().join("foreign.csv");
        std::fs::write(&foreign, format!("{}\n", columns.join(","))).unwrap();
        assert!(read(&foreign).is_err());
    }

    /// Rows dropped past a failed checkpoint are gone from the file too; a file deleted by
    /// the user does not stop a resume.
    #[test]
    fn truncation_rewrites_the_file_and_a_deleted_file_resumes_empty() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("curves.csv");
        let mut curves = Curves::new(path.clone());
        for iteration in 0..3 {
            curves
                .push(CurveRow {
                    iteration,
                    ..CurveRow::default()
                })
                .expect("push");
        }
        curves.truncate(1).expect("truncate");
        assert_eq!(read(&path).expect("read").len(), 1);
        curves.truncate(0).expect("truncate");
        assert!(read(&path).expect("a header alone reads").is_empty());
        std::fs::remove_file(&path).expect("remove");
        let resumed = Curves::resume(path, 2).expect("gone, the run goes on");
        assert!(resumed.rows().is_empty());
    }
}
