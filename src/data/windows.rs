//! Cutting a recording into scenes: resample the logs onto the policy's time grid
//! (dt = 0.5 s), slide a window of history + future over it, and split by time.
//!
//! Which agents are controlled: a vehicle present at the current step and at the step before
//! it (so it has at least `dt` of history to start from). Every other vehicle seen in the
//! window is replayed from the log while the log has it: vehicles that enter the road after
//! the current step, or appeared less than `dt` before it. A vehicle whose log ends inside the
//! window has driven out of the observed road; in simulation that is an exit (the map's
//! `BoxOnRoad::Exiting`), never an off-road infraction.
//!
//! Split: train windows lie wholly in the first `train_fraction` of the recording, test
//! windows wholly after it; no window spans the boundary.

use std::sync::Arc;

use crate::data::Recording;
use crate::data::track::AgentState;
use crate::error::{Error, Result};
use crate::map::{LaneGraph, Map};
use crate::scene::{AgentRole, Scene, SceneAgent};

/// How recordings become scenes. Defaults follow the paper (dt = 0.5 s) and the foundation
/// issue (2 s of history); 6 s of future covers the 5 s FDE horizon with margin.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Policy and dynamics step (s).
    pub dt: f64,
    /// Seconds of history before the current step.
    pub history_s: f64,
    /// Seconds simulated after the current step.
    pub future_s: f64,
    /// Seconds between the current steps of consecutive windows.
    pub stride_s: f64,
    /// Share of the recording (by time) used for training; the rest is the test split.
    pub train_fraction: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            dt: 0.5,
            history_s: 2.0,
            future_s: 6.0,
            stride_s: 1.0,
            train_fraction: 0.8,
        }
    }
}

impl SceneConfig {
    /// Number of steps in `seconds`, which must be a whole multiple of `dt`.
    fn steps(&self, field: &str, seconds: f64) -> Result<usize> {
        let n = seconds / self.dt;
        if !(n.is_finite() && n >= 0.0 && (n - n.round()).abs() < 1e-6) {
            return Err(Error::InvalidArgument(format!(
                "scene config `{field}` = {seconds} s must be a non-negative multiple of dt = {} s",
                self.dt
            )));
        }
        Ok(n.round() as usize)
    }

    pub fn history_steps(&self) -> Result<usize> {
        self.steps("history_s", self.history_s)
    }

    pub fn future_steps(&self) -> Result<usize> {
        self.steps("future_s", self.future_s)
    }

    fn validate(&self) -> Result<()> {
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(Error::InvalidArgument(format!(
                "scene config `dt` must be positive, found {}",
                self.dt
            )));
        }
        if !(self.stride_s.is_finite() && self.stride_s > 0.0) {
            return Err(Error::InvalidArgument(format!(
                "scene config `stride_s` must be positive, found {}",
                self.stride_s
            )));
        }
        if !(self.train_fraction > 0.0 && self.train_fraction < 1.0) {
            return Err(Error::InvalidArgument(format!(
                "scene config `train_fraction` must lie strictly between 0 and 1, found {}",
                self.train_fraction
            )));
        }
        if self.future_steps()? == 0 {
            return Err(Error::InvalidArgument(
                "scene config `future_s` must cover at least one step".into(),
            ));
        }
        self.history_steps().map(|_| ())
    }
}

/// Scenes of one recording, split by time.
#[derive(Debug, Clone)]
pub struct SceneSplit {
    pub train: Vec<Scene>,
    pub test: Vec<Scene>,
    /// Recording time separating the splits (s).
    pub split_time: f64,
}

/// Cuts `recording` into scenes on `map`. Windows with no controllable agent are skipped.
pub fn build_scenes(
    recording: &Recording,
    name: &str,
    map: Arc<Map>,
    lane_graph: Arc<LaneGraph>,
    config: &SceneConfig,
) -> Result<SceneSplit> {
    config.validate()?;
    let duration = recording.duration();
    let split_time = config.train_fraction * duration;
    let cut = |part: &str, start: f64, end: f64| {
        let id = |t0: f64| format!("{name}-{part}-t{t0:06.1}");
        cut_span(recording, start, end, &id, &map, &lane_graph, config)
    };
    Ok(SceneSplit {
        train: cut("train", 0.0, split_time)?,
        test: cut("test", split_time, duration)?,
        split_time,
    })
}

/// Every scene of `recording` with no train/test split (short clips that are evaluated or
/// trained on whole); scene ids are `{name}-t{t0}`.
pub fn build_all_scenes(
    recording: &Recording,
    name: &str,
    map: Arc<Map>,
    lane_graph: Arc<LaneGraph>,
    config: &SceneConfig,
) -> Result<Vec<Scene>> {
    config.validate()?;
    let id = |t0: f64| format!("{name}-t{t0:06.1}");
    cut_span(
        recording,
        0.0,
        recording.duration(),
        &id,
        &map,
        &lane_graph,
        config,
    )
}

/// The scenes whose windows lie wholly in `[start, end]` (s), current steps on the
/// recording's grid of `stride_s` (whole multiples of it from time 0).
fn cut_span(
    recording: &Recording,
    start: f64,
    end: f64,
    id: &dyn Fn(f64) -> String,
    map: &Arc<Map>,
    lane_graph: &Arc<LaneGraph>,
    config: &SceneConfig,
) -> Result<Vec<Scene>> {
    let history = config.history_steps()?;
    let future = config.future_steps()?;
    let before = history as f64 * config.dt;
    let after = future as f64 * config.dt;
    let mut scenes = Vec::new();
    let mut k = ((start + before) / config.stride_s - 1e-9).ceil().max(0.0) as usize;
    loop {
        let t0 = k as f64 * config.stride_s;
        k += 1;
        if t0 + after > end + 1e-9 {
            break;
        }
        if let Some(agents) = cut_window(recording, t0, history, future, config.dt) {
            scenes.push(Scene {
                id: id(t0),
                t0,
                dt: config.dt,
                history_steps: history,
                future_steps: future,
                map: map.clone(),
                lane_graph: lane_graph.clone(),
                agents,
            });
        }
    }
    Ok(scenes)
}

/// The agents of the window whose current step is at `t0`, or `None` if none is controllable.
fn cut_window(
    recording: &Recording,
    t0: f64,
    history: usize,
    future: usize,
    dt: f64,
) -> Option<Vec<SceneAgent>> {
    let steps = history + 1 + future;
    let time = |i: usize| t0 + (i as f64 - history as f64) * dt;
    let (w_start, w_end) = (time(0), time(steps - 1));
    let mut controlled = Vec::new();
    let mut replayed = Vec::new();
    for track in &recording.tracks {
        if track.last_time() < w_start || track.first_time() > w_end {
            continue;
        }
        let mut states = vec![AgentState::default(); steps];
        let mut valid = vec![false; steps];
        for i in 0..steps {
            if let Some(s) = track.state_at(time(i)) {
                states[i] = s;
                valid[i] = true;
            }
        }
        if !valid.iter().any(|&v| v) {
            continue;
        }
        let has_history = valid[history] && (history == 0 || valid[history - 1]);
        let agent = SceneAgent {
            track_id: track.id,
            class: track.class.clone(),
            length: track.length,
            width: track.width,
            role: if has_history {
                AgentRole::Controlled
            } else {
                AgentRole::Replayed
            },
            states,
            valid,
        };
        if has_history {
            controlled.push(agent);
        } else {
            replayed.push(agent);
        }
    }
    if controlled.is_empty() {
        return None;
    }
    controlled.extend(replayed);
    Some(controlled)
}
