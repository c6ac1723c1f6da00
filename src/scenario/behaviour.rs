//! Hero behaviours as data: a hero follows a list of phases, each a trigger and an action.
//! A phase's action starts when its trigger fires (checked once the previous phase has
//! completed) and sets the hero's lateral mode or its longitudinal mode; the other mode
//! carries on. So "cut in, then brake hard" is two phases, and a tailgater that overtakes
//! and cuts in is three.
//!
//! The same types hold ranges in a logical scenario (`P` = [`Range`]) and the drawn numbers in
//! a concrete one (`P` = `f64`).

use serde::{Deserialize, Serialize};

use super::range::{Range, Sampler};

/// Side of a lane change or the first half-wave of a swerve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    Left,
    Right,
}

/// When a phase starts. Gaps are bumper to bumper along the hero's heading; "ahead" means the
/// hero is in front of its target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Trigger<P> {
    /// At the scenario's first step.
    Start,
    /// This many seconds after the previous phase completed.
    After { seconds: P },
    /// Hero ahead of the target by less than `metres` (the target has closed in).
    AheadGapBelow { metres: P },
    /// Hero ahead of the target by more than `metres` (the hero has overtaken).
    AheadGapAbove { metres: P },
    /// Hero behind the target by less than `metres`.
    BehindGapBelow { metres: P },
    /// Time to collision between hero and target, whichever is behind closing in, below
    /// `seconds`.
    TtcBelow { seconds: P },
    /// The hero has driven `metres` since the scenario started.
    Travelled { metres: P },
}

/// What a phase does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Action<P> {
    /// Move one lane over at about `lateral_speed` (m/s); lateral.
    ChangeLane {
        direction: Direction,
        lateral_speed: P,
    },
    /// One full sine wave of lateral offset, `amplitude` (m) to `direction` first, over
    /// `period` (s); lateral.
    Swerve {
        direction: Direction,
        amplitude: P,
        period: P,
    },
    /// Brake at up to `decel` (m/s^2, reached at `jerk` m/s^3) down to `min_speed` (m/s) and
    /// hold it (0 = stop and stand); longitudinal.
    Brake { decel: P, jerk: P, min_speed: P },
    /// Accelerate at `accel` (m/s^2) up to `max_speed` (m/s) and hold it; longitudinal. Like
    /// the other speed modes (cruise, follow) it counts as complete once started; a lane
    /// change completes on reaching the new lane, a swerve after its period, braking on
    /// reaching its speed.
    Accelerate { accel: P, max_speed: P },
    /// Drive at `speed` (m/s), following the vehicle ahead (IDM); longitudinal.
    Cruise { speed: P },
    /// Follow the target at a `time_gap` (s) far below the safe one, up to `max_speed`
    /// (m/s); longitudinal.
    FollowTarget { time_gap: P, max_speed: P },
}

/// One step of a hero's script.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Phase<P> {
    pub trigger: Trigger<P>,
    pub action: Action<P>,
}

impl Phase<f64> {
    /// The bounds of [`Phase::<Range>::check`] on drawn numbers (a scenario file's phases).
    pub fn check(&self, name: &str) -> Result<(), String> {
        // A number is a fixed range: the same serde form, so one set of bounds serves both.
        let ranges: Phase<Range> = serde_json::to_value(self)
            .and_then(serde_json::from_value)
            .map_err(|e| format!("{name}: {e}"))?;
        ranges.check(name)
    }
}

impl Phase<Range> {
    /// Checks every range against physically sensible bounds; `name` locates the phase.
    pub fn check(&self, name: &str) -> Result<(), String> {
        let at = |field: &str| format!("{name}.{field}");
        match &self.trigger {
            Trigger::Start => {}
            Trigger::After { seconds } => seconds.check(&at("trigger.seconds"), 0.0, 60.0)?,
            Trigger::AheadGapBelow { metres }
            | Trigger::AheadGapAbove { metres }
            | Trigger::BehindGapBelow { metres } => {
                metres.check(&at("trigger.metres"), 0.0, 500.0)?
            }
            Trigger::TtcBelow { seconds } => seconds.check(&at("trigger.seconds"), 0.1, 30.0)?,
            Trigger::Travelled { metres } => metres.check(&at("trigger.metres"), 0.0, 5000.0)?,
        }
        match &self.action {
            Action::ChangeLane { lateral_speed, .. } => {
                lateral_speed.check(&at("action.lateral_speed"), 0.2, 4.0)?
            }
            Action::Swerve {
                amplitude, period, ..
            } => {
                amplitude.check(&at("action.amplitude"), 0.1, 4.0)?;
                period.check(&at("action.period"), 1.0, 20.0)?;
            }
            Action::Brake {
                decel,
                jerk,
                min_speed,
            } => {
                decel.check(&at("action.decel"), 0.5, 10.0)?;
                jerk.check(&at("action.jerk"), 1.0, 100.0)?;
                min_speed.check(&at("action.min_speed"), 0.0, 60.0)?;
            }
            Action::Accelerate { accel, max_speed } => {
                accel.check(&at("action.accel"), 0.1, 5.0)?;
                max_speed.check(&at("action.max_speed"), 0.0, 60.0)?;
            }
            Action::Cruise { speed } => speed.check(&at("action.speed"), 0.0, 60.0)?,
            Action::FollowTarget {
                time_gap,
                max_speed,
            } => {
                time_gap.check(&at("action.time_gap"), 0.05, 3.0)?;
                max_speed.check(&at("action.max_speed"), 0.0, 60.0)?;
            }
        }
        Ok(())
    }

    /// The phase's ranges by the name [`Self::sample`] records each draw under
    /// (`trigger.<field>`, `action.<field>`).
    pub fn ranges(&self) -> Vec<(String, Range)> {
        let mut out = Vec::new();
        match &self.trigger {
            Trigger::Start => {}
            Trigger::After { seconds } | Trigger::TtcBelow { seconds } => {
                out.push(("trigger.seconds".to_string(), *seconds));
            }
            Trigger::AheadGapBelow { metres }
            | Trigger::AheadGapAbove { metres }
            | Trigger::BehindGapBelow { metres }
            | Trigger::Travelled { metres } => out.push(("trigger.metres".to_string(), *metres)),
        }
        let action: Vec<(&str, Range)> = match &self.action {
            Action::ChangeLane { lateral_speed, .. } => vec![("lateral_speed", *lateral_speed)],
            Action::Swerve {
                amplitude, period, ..
            } => vec![("amplitude", *amplitude), ("period", *period)],
            Action::Brake {
                decel,
                jerk,
                min_speed,
            } => vec![
                ("decel", *decel),
                ("jerk", *jerk),
                ("min_speed", *min_speed),
            ],
            Action::Accelerate { accel, max_speed } => {
                vec![("accel", *accel), ("max_speed", *max_speed)]
            }
            Action::Cruise { speed } => vec![("speed", *speed)],
            Action::FollowTarget {
                time_gap,
                max_speed,
            } => vec![("time_gap", *time_gap), ("max_speed", *max_speed)],
        };
        out.extend(action.into_iter().map(|(f, r)| (format!("action.{f}"), r)));
        out
    }

    /// Draws the concrete phase; every value is recorded as `name.trigger.<field>` or
    /// `name.action.<field>`.
    pub fn sample(&self, sampler: &mut Sampler, name: &str) -> Phase<f64> {
        let mut d = |field: &str, r: &Range| sampler.draw(&format!("{name}.{field}"), r);
        let trigger = match &self.trigger {
            Trigger::Start => Trigger::Start,
            Trigger::After { seconds } => Trigger::After {
                seconds: d("trigger.seconds", seconds),
            },
            Trigger::AheadGapBelow { metres } => Trigger::AheadGapBelow {
                metres: d("trigger.metres", metres),
            },
            Trigger::AheadGapAbove { metres } => Trigger::AheadGapAbove {
                metres: d("trigger.metres", metres),
            },
            Trigger::BehindGapBelow { metres } => Trigger::BehindGapBelow {
                metres: d("trigger.metres", metres),
            },
            Trigger::TtcBelow { seconds } => Trigger::TtcBelow {
                seconds: d("trigger.seconds", seconds),
            },
            Trigger::Travelled { metres } => Trigger::Travelled {
                metres: d("trigger.metres", metres),
            },
        };
        let action = match &self.action {
            Action::ChangeLane {
                direction,
                lateral_speed,
            } => Action::ChangeLane {
                direction: *direction,
                lateral_speed: d("action.lateral_speed", lateral_speed),
            },
            Action::Swerve {
                direction,
                amplitude,
                period,
            } => Action::Swerve {
                direction: *direction,
                amplitude: d("action.amplitude", amplitude),
                period: d("action.period", period),
            },
            Action::Brake {
                decel,
                jerk,
                min_speed,
            } => Action::Brake {
                decel: d("action.decel", decel),
                jerk: d("action.jerk", jerk),
                min_speed: d("action.min_speed", min_speed),
            },
            Action::Accelerate { accel, max_speed } => Action::Accelerate {
                accel: d("action.accel", accel),
                max_speed: d("action.max_speed", max_speed),
            },
            Action::Cruise { speed } => Action::Cruise {
                speed: d("action.speed", speed),
            },
            Action::FollowTarget {
                time_gap,
                max_speed,
            } => Action::FollowTarget {
                time_gap: d("action.time_gap", time_gap),
                max_speed: d("action.max_speed", max_speed),
            },
        };
        Phase { trigger, action }
    }
}
