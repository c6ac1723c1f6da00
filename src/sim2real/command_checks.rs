//! Whether a recording's commands can drive the simulator: they change where the motion
//! does, and they turn and push the way the motion goes (the simulator replays them, so a
//! column left at zero or recorded with the other sign convention would be fitted as physics).

use crate::data::{RecordedTrack, Recordings};
use crate::error::{Error, Result};
use crate::geometry::wrap_angle;

/// Both checks below.
pub(super) fn check_commands(recordings: &Recordings) -> Result<()> {
    check_commands_vary(recordings)?;
    check_command_signs(recordings)
}

/// Refuses a command column that holds one value on every row while the motion it drives
/// changes (speeds by more than 2 m/s, headings by more than 0.2 rad): the simulator replays
/// the recorded commands, and a column left at zero (or never filled) carries none.
pub(super) fn check_commands_vary(recordings: &Recordings) -> Result<()> {
    type Column = fn(&RecordedTrack) -> &[f64];
    type Change = fn(&RecordedTrack) -> f64;
    fn range(values: &[f64]) -> f64 {
        values.iter().copied().fold(f64::MIN, f64::max)
            - values.iter().copied().fold(f64::MAX, f64::min)
    }
    let speed_range: Change = |t| range(&t.speed);
    let turned: Change = |t| range(&super::windows::unwrap(&t.heading));
    let checks: [(&str, Column, Change, f64, &str); 2] = [
        (
            "accel_cmd",
            |t| &t.accel_cmd,
            speed_range,
            2.0,
            "speeds change",
        ),
        ("steer_cmd", |t| &t.steer_cmd, turned, 0.2, "vehicles turn"),
    ];
    for (name, command, motion, moves, what) in checks {
        let first = recordings
            .tracks
            .iter()
            .find_map(|t| command(t).first().copied());
        let constant = recordings
            .tracks
            .iter()
            .all(|t| command(t).iter().all(|&v| Some(v) == first));
        let moving = recordings.tracks.iter().any(|t| motion(t) > moves);
        if constant && moving {
            return Err(Error::invalid(
                &recordings.source,
                format!("column `{name}`"),
                format!(
                    "is {} on every row, yet the {what}: sim2real replays the recorded \
                     commands, and this column carries none; expected the commands the \
                     vehicles received",
                    first.unwrap_or_default()
                ),
            ));
        }
    }
    Ok(())
}

/// Share of a command's clear samples whose response goes the other way above which the
/// column is taken for the other sign convention: lags and delays make some disagree, never
/// most.
const OPPOSITE_SHARE: f64 = 0.8;
/// Fewest clear samples that make a verdict.
const MIN_CLEAR_SAMPLES: usize = 50;

/// A command column and the response that shows its sign.
struct SignCheck {
    column: &'static str,
    command: fn(&RecordedTrack) -> &[f64],
    /// The response over the sample after `k`.
    response: fn(&RecordedTrack, usize) -> f64,
    /// Smallest command and response that say their sign clearly.
    clear_command: f64,
    clear_response: f64,
    convention: &'static str,
}

const SIGN_CHECKS: [SignCheck; 2] = [
    SignCheck {
        column: "steer_cmd",
        command: |t| &t.steer_cmd,
        response: |t, k| wrap_angle(t.heading[k + 1] - t.heading[k]) / t.period,
        clear_command: 0.01,
        clear_response: 0.05,
        convention: "positive steer_cmd turns left (counter-clockwise, as heading grows)",
    },
    SignCheck {
        column: "accel_cmd",
        command: |t| &t.accel_cmd,
        response: |t, k| (t.speed[k + 1] - t.speed[k]) / t.period,
        clear_command: 1.0,
        clear_response: 1.0,
        convention: "positive accel_cmd speeds up",
    },
];

/// Refuses a command column whose sign disagrees with the motion on most samples where both
/// are clear: steering that says right while the vehicles turn left (a clockwise convention),
/// acceleration that says speed up while they brake.
fn check_command_signs(recordings: &Recordings) -> Result<()> {
    for check in &SIGN_CHECKS {
        let (mut clear, mut opposite) = (0usize, 0usize);
        for track in &recordings.tracks {
            for k in 0..track.len().saturating_sub(1) {
                let (u, r) = ((check.command)(track)[k], (check.response)(track, k));
                if track.speed[k] < 3.0
                    || u.abs() < check.clear_command
                    || r.abs() < check.clear_response
                {
                    continue;
                }
                clear += 1;
                opposite += usize::from(u.signum() != r.signum());
            }
        }
        if clear >= MIN_CLEAR_SAMPLES && opposite as f64 > OPPOSITE_SHARE * clear as f64 {
            return Err(Error::invalid(
                &recordings.source,
                format!("column `{}`", check.column),
                format!(
                    "goes against the motion on {opposite} of {clear} samples where both are \
                     clear: recorded with the other sign? expected that {}",
                    check.convention
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim2real::generator::{GeneratorConfig, generate};

    /// A command column left at zero while the vehicles brake and turn, or recorded with the
    /// other sign, is refused by name; the generated recordings pass.
    #[test]
    fn a_command_column_that_never_changes_or_has_the_other_sign_is_refused() {
        let mut config = GeneratorConfig::with_effect(None, 3);
        config.tracks = 4;
        let recordings = generate(&config, &crate::backend::Backend::reference_device(false));
        check_commands(&recordings).expect("usable commands");
        let changed = |column: &str, change: fn(f64) -> f64| {
            let mut out = recordings.clone();
            for track in &mut out.tracks {
                let values = match column {
                    "accel_cmd" => &mut track.accel_cmd,
                    _ => &mut track.steer_cmd,
                };
                values.iter_mut().for_each(|v| *v = change(*v));
            }
            out
        };
        for column in ["accel_cmd", "steer_cmd"] {
            for (what, change) in [
                ("zero", (|_| 0.0) as fn(f64) -> f64),
                ("negated", |v: f64| -v),
            ] {
                let err = check_commands(&changed(column, change))
                    .expect_err(what)
                    .to_string();
                assert!(err.contains(&format!("column `{column}`")), "{what}: {err}");
            }
        }
    }
}
