//! How often the logged drivers close on the car ahead, and what they do next: the examples
//! imitation has for braking: a policy can learn to brake for a slower car ahead only from
//! demonstrations like these.
//!
//! A *closing event* is a follower, sampled every [`SAMPLE_DT_S`], whose leader (the nearest
//! vehicle ahead in its lane, as the evaluation's lead-gap feature finds it,
//! [`crate::agent_view::leader`]) is slower by more than [`CLOSING_SPEED_MS`] with under
//! [`TIME_TO_CONTACT_S`] to contact at the current speeds. Each follower counts at most once
//! per [`RESPONSE_S`], and only where it is still logged that long after. Its response over that
//! window is a lane change (its logged lane label changes), else braking (its speed falls by
//! more than [`SLOWED_MS`]), else neither.

use crate::agent_view::{AgentView, leader};
use crate::data::Recording;

/// Sampling step over the recording (s): the simulator's.
pub const SAMPLE_DT_S: f64 = 0.5;
/// A follower closes when it is faster than its leader by more than this (m/s).
pub const CLOSING_SPEED_MS: f64 = 2.0;
/// ... and would reach it within this at the current speeds (s).
pub const TIME_TO_CONTACT_S: f64 = 8.0;
/// The window over which the response is read (s).
pub const RESPONSE_S: f64 = 3.0;
/// A speed drop over the window larger than this counts as braking (m/s).
pub const SLOWED_MS: f64 = 1.0;

#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ClosingEvents {
    pub events: usize,
    /// The follower's lane label changed within the window.
    pub lane_changes: usize,
    /// It stayed in its lane and its speed fell by more than [`SLOWED_MS`].
    pub braked: usize,
    /// It stayed in its lane and did not slow that much.
    pub neither: usize,
    /// Means over the events: closing speed (m/s), gap (m), and the follower's speed change
    /// over the window (m/s).
    pub mean_closing_speed_ms: f64,
    pub mean_gap_m: f64,
    pub mean_speed_change_ms: f64,
}

/// The closing events of every track of `recording`.
pub fn closing_events(recording: &Recording) -> ClosingEvents {
    let tracks = &recording.tracks;
    let start = tracks
        .iter()
        .map(|t| t.first_time())
        .fold(f64::INFINITY, f64::min);
    let end = tracks
        .iter()
        .map(|t| t.last_time())
        .fold(f64::NEG_INFINITY, f64::max);
    let mut counted_until = vec![f64::NEG_INFINITY; tracks.len()];
    let mut found = ClosingEvents::default();
    let (mut closing_sum, mut gap_sum, mut change_sum) = (0.0, 0.0, 0.0);
    let steps = if end > start {
        ((end - start) / SAMPLE_DT_S) as usize
    } else {
        0
    };
    for k in 0..=steps {
        let t = start + k as f64 * SAMPLE_DT_S;
        let views = views_at(recording, t);
        for (i, track) in tracks.iter().enumerate() {
            let Some((j, gap)) = views[i].present.then(|| leader(i, &views)).flatten() else {
                continue;
            };
            let closing = views[i].speed - views[j].speed;
            let later = track.state_at(t + RESPONSE_S);
            let (Some(later), true) = (later, t >= counted_until[i]) else {
                continue;
            };
            if closing <= CLOSING_SPEED_MS || gap >= closing * TIME_TO_CONTACT_S {
                continue;
            }
            counted_until[i] = t + RESPONSE_S;
            let speed_change = later.speed - views[i].speed;
            found.events += 1;
            if changes_lane(track, t, t + RESPONSE_S) {
                found.lane_changes += 1;
            } else if speed_change < -SLOWED_MS {
                found.braked += 1;
            } else {
                found.neither += 1;
            }
            closing_sum += closing;
            gap_sum += gap;
            change_sum += speed_change;
        }
    }
    if found.events > 0 {
        let n = found.events as f64;
        found.mean_closing_speed_ms = closing_sum / n;
        found.mean_gap_m = gap_sum / n;
        found.mean_speed_change_ms = change_sum / n;
    }
    found
}

/// Every track at time `t` (absent where it is not logged then).
fn views_at(recording: &Recording, t: f64) -> Vec<AgentView> {
    recording
        .tracks
        .iter()
        .map(|track| match track.state_at(t) {
            Some(s) => AgentView {
                x: s.x,
                y: s.y,
                heading: s.heading,
                speed: s.speed,
                length: track.length,
                width: track.width,
                present: true,
            },
            None => AgentView {
                x: 0.0,
                y: 0.0,
                heading: 0.0,
                speed: 0.0,
                length: track.length,
                width: track.width,
                present: false,
            },
        })
        .collect()
}

/// Whether the track's logged lane label changes between `from` and `to`.
fn changes_lane(track: &crate::data::Track, from: f64, to: f64) -> bool {
    let mut lanes = track
        .samples
        .iter()
        .filter(|s| s.t >= from - 1e-9 && s.t <= to + 1e-9)
        .map(|s| s.lane_id);
    match lanes.next() {
        Some(first) => lanes.any(|lane| lane != first),
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{AgentState, Track, TrackSample, VehicleClass};

    /// A car on the x axis from `t0` for `seconds`, its speed `speed(t)`, in lane `lane(t)`.
    fn track(
        id: usize,
        x0: f64,
        seconds: f64,
        speed: impl Fn(f64) -> f64,
        lane: impl Fn(f64) -> i32,
    ) -> Track {
        let dt = 0.1;
        let mut x = x0;
        let samples = (0..=(seconds / dt) as usize)
            .map(|k| {
                let t = k as f64 * dt;
                let s = TrackSample {
                    t,
                    state: AgentState {
                        x,
                        y: 0.0,
                        heading: 0.0,
                        speed: speed(t),
                        accel: 0.0,
                    },
                    lateral_speed: 0.0,
                    lateral_accel: 0.0,
                    lane_id: lane(t),
                };
                x += speed(t) * dt;
                s
            })
            .collect();
        Track {
            id,
            uuid: format!("car-{id}"),
            class: VehicleClass::Car,
            length: 4.5,
            width: 1.8,
            samples,
        }
    }

    fn recording(tracks: Vec<Track>) -> Recording {
        Recording {
            source: "synthetic".into(),
            fps: 10.0,
            frame_count: 100,
            utm_reference: String::new(),
            tracks,
        }
    }

    #[test]
    fn a_follower_that_slows_behind_a_slower_car_is_one_braking_event() {
        // 30 m behind a car at 25 m/s, at 31 m/s, braking at 3 m/s^2 from the start.
        let follower = track(0, 0.0, 10.0, |t| (31.0 - 3.0 * t).max(25.0), |_| -2);
        let lead = track(1, 34.5, 10.0, |_| 25.0, |_| -2);
        let found = closing_events(&recording(vec![follower, lead]));
        assert_eq!(
            (found.events, found.braked, found.lane_changes),
            (1, 1, 0),
            "{found:?}"
        );
        assert!(
            (found.mean_closing_speed_ms - 6.0).abs() < 1e-6,
            "{found:?}"
        );
        assert!((found.mean_gap_m - 30.0).abs() < 1e-6, "{found:?}");
    }

    #[test]
    fn lane_changes_and_steady_followers_are_told_apart() {
        // Closing at 4 m/s from 20 m: one changes lane after 1 s (logged for 5 s, so counted
        // once), the other holds its speed.
        let changer = track(0, 0.0, 5.0, |_| 29.0, |t| if t < 1.0 { -2 } else { -3 });
        let lead = track(1, 24.5, 5.0, |_| 25.0, |_| -2);
        let found = closing_events(&recording(vec![changer, lead]));
        assert_eq!((found.events, found.lane_changes), (1, 1), "{found:?}");

        let steady = track(0, 0.0, 10.0, |_| 29.0, |_| -2);
        let lead = track(1, 24.5, 10.0, |_| 25.0, |_| -2);
        let found = closing_events(&recording(vec![steady, lead]));
        // Counted once per response window while it keeps closing, holding its speed each time.
        assert!(
            found.events >= 1 && found.events == found.neither,
            "{found:?}"
        );
        assert_eq!(found.braked, 0);
    }

    #[test]
    fn slow_closing_and_far_leaders_are_not_events() {
        // 1 m/s faster: below the closing threshold.
        let follower = track(0, 0.0, 10.0, |_| 26.0, |_| -2);
        let lead = track(1, 24.5, 10.0, |_| 25.0, |_| -2);
        assert_eq!(closing_events(&recording(vec![follower, lead])).events, 0);
        // 5 m/s faster but 60 m behind: 12 s to contact.
        let follower = track(0, 0.0, 6.0, |_| 30.0, |_| -2);
        let lead = track(1, 64.5, 6.0, |_| 25.0, |_| -2);
        assert_eq!(closing_events(&recording(vec![follower, lead])).events, 0);
    }
}
