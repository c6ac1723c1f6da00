//! The real A9 drone recording as sim-to-real recordings. Drones see motion, not commands,
//! so the commands are inferred from the motion: acceleration from the tracked longitudinal
//! acceleration, steering from the heading rate through the nominal bicycle,
//! phi = atan(L psi' / v). Effects that act on the commands (lags, dead time, rate limits,
//! drag, understeer) are then already inside the inferred commands and cannot be identified;
//! what remains testable is how the recorded point moves relative to the heading (sideslip)
//! and the wheelbase.

use crate::data::{A9Dataset, RecordedTrack, Recordings};
use crate::sim::wheelbase_of;

/// Half-width (s) of the central difference that gives the heading rate.
const RATE_HALF_WIDTH_S: f64 = 0.2;
/// Below this speed the heading rate says little about steering.
const MIN_SPEED_M_S: f64 = 2.0;

/// Every A9 track, resampled to `period_s` by taking every k-th frame (no interpolation),
/// as recordings with inferred commands; tracks shorter than `min_duration_s` are left out.
pub fn a9_recordings(dataset: &A9Dataset, period_s: f64, min_duration_s: f64) -> Recordings {
    let fps = dataset.recording.fps;
    let every = ((period_s * fps).round() as usize).max(1);
    let half = ((RATE_HALF_WIDTH_S * fps).round() as usize).max(1);
    let mut tracks = Vec::new();
    for track in &dataset.recording.tracks {
        let s = &track.samples;
        if s.len() < 2 * half + 2 || track.last_time() - track.first_time() < min_duration_s {
            continue;
        }
        let wheelbase = wheelbase_of(track.length);
        let heading: Vec<f64> =
            super::windows::unwrap(&s.iter().map(|x| x.state.heading).collect::<Vec<_>>());
        let picks: Vec<usize> = (half..s.len() - half).step_by(every).collect();
        let mut out =
            RecordedTrack::empty(format!("{}", track.id), every as f64 / fps, Some(wheelbase));
        for &k in &picks {
            let state = s[k].state;
            let rate = (heading[k + half] - heading[k - half]) / (s[k + half].t - s[k - half].t);
            let steer = if state.speed > MIN_SPEED_M_S {
                (wheelbase * rate / state.speed).atan()
            } else {
                0.0
            };
            out.t.push(s[k].t);
            out.x.push(state.x);
            out.y.push(state.y);
            out.heading.push(state.heading);
            out.speed.push(state.speed);
            out.accel_cmd.push(state.accel);
            out.steer_cmd.push(steer);
        }
        tracks.push(out);
    }
    Recordings {
        source: format!(
            "{} (A9, commands inferred from motion)",
            dataset.recording.source.display()
        ),
        tracks,
    }
}
