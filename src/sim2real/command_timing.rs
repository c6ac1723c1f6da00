//! How a log's commands relate to what the vehicle received between two samples, and the
//! commands a simulator stepping once per sample should apply for each convention.
//!
//! A log records the command at each sample time. Whether it was then held for the period
//! (a controller at the log's rate) or kept changing (a controller faster than the log,
//! sampled by the logger) is not in the log, and a command sampled from a fast controller
//! acts about half a period earlier than the same log read as held: exactly what a dead time
//! half a period shorter does, so with a dead time in the model the data cannot tell. System identification tools ask for
//! a signal's inter-sample behaviour (zero- or first-order hold); here it may be declared, or
//! both readings are fitted and the data decides where it can (see [`TimingDecision`]).

use std::collections::BTreeMap;

use crate::data::Recordings;
use crate::sim::catalogue::Effect;

/// How a log's commands relate to what the vehicle received between two samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CommandTiming {
    /// Each logged command was held over the period that follows it (a controller running at
    /// the log's rate).
    #[default]
    Held,
    /// A controller faster than the log: its command changes between samples, and the log
    /// keeps its value at each sample time.
    Sampled,
}

impl CommandTiming {
    pub const NAMES: [&'static str; 2] = ["held", "sampled"];

    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "held" => Some(Self::Held),
            "sampled" => Some(Self::Sampled),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Held => "held",
            Self::Sampled => "sampled",
        }
    }
}

/// `recordings` with each period's command replaced by what a simulator stepping once per
/// sample should apply under `timing`: held commands as they are; sampled ones as the mean of
/// the command over the period, linearly interpolated between its two samples (the last
/// sample as it is).
pub fn as_held(recordings: &Recordings, timing: CommandTiming) -> Recordings {
    let mut out = recordings.clone();
    if timing == CommandTiming::Held {
        return out;
    }
    for track in &mut out.tracks {
        for channel in [&mut track.accel_cmd, &mut track.steer_cmd] {
            let sampled = channel.clone();
            for (k, value) in channel.iter_mut().enumerate() {
                if let Some(next) = sampled.get(k + 1) {
                    *value = 0.5 * (sampled[k] + next);
                }
            }
        }
    }
    out
}

/// Why the commands were read the way they were.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TimingEvidence {
    /// `--command-timing` named it.
    Declared,
    /// The other reading's final model is worse on held-out tracks by the parsimony rule.
    HeldOutError,
    /// Both fit alike, and the other reading needed more terms (a held log read as sampled
    /// needs a dead time of half a period; a sampled log read as held cannot express the
    /// negative delay it would need).
    FewerTerms,
    /// Both fit alike with as many terms: with a pure delay among the effects the log cannot
    /// tell (a sampled command acts half a period earlier, which a delay half a period
    /// longer undoes). Read as held; the other reading's estimates bound the intervals.
    Ambiguous,
}

/// What one reading of the commands ended with.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ReadingOutcome {
    pub reading: CommandTiming,
    /// The final model's label (`nominal` or its terms joined by `+`).
    pub model: String,
    pub terms: usize,
    pub heldout_pos_rmse_m: f64,
    /// Its identified effects' parameters, by effect and name.
    pub params: Vec<(Effect, BTreeMap<String, f64>)>,
}

/// How the commands were read, why, and what the other reading gave.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TimingDecision {
    pub reading: CommandTiming,
    pub decided_by: TimingEvidence,
    /// The reading not taken (none when only one was tried).
    pub alternative: Option<ReadingOutcome>,
    /// Held-out comparison of the sampled reading's final model against the held one's,
    /// paired by track (none when only one reading was tried).
    pub sampled_vs_held: Option<PairedGain>,
}

/// How much one model lowers held-out position error against another, paired by track.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct PairedGain {
    pub improvement_pct: f64,
    pub t_stat: f64,
    /// Passes the parsimony rule.
    pub significant: bool,
}

impl TimingDecision {
    /// Only `reading` was tried.
    pub fn single(reading: CommandTiming, decided_by: TimingEvidence) -> Self {
        Self {
            reading,
            decided_by,
            alternative: None,
            sampled_vs_held: None,
        }
    }

    /// Held against sampled: a reading whose final model is better on held-out tracks by the
    /// parsimony rule wins; else the one with fewer terms; with as many terms, the parsimony
    /// rule's margin alone decides (its t-test guards against a term fitted to noise, and
    /// neither reading adds one); else held, marked ambiguous.
    pub fn between(
        held: ReadingOutcome,
        sampled: ReadingOutcome,
        [sampled_vs_held, held_vs_sampled]: [PairedGain; 2],
        min_improvement_pct: f64,
    ) -> Self {
        let same_terms = held.terms == sampled.terms;
        let clearly_better = |g: &PairedGain| {
            g.significant || (same_terms && g.improvement_pct >= min_improvement_pct)
        };
        let (reading, decided_by) = if clearly_better(&sampled_vs_held) {
            (CommandTiming::Sampled, TimingEvidence::HeldOutError)
        } else if clearly_better(&held_vs_sampled) {
            (CommandTiming::Held, TimingEvidence::HeldOutError)
        } else if sampled.terms < held.terms {
            (CommandTiming::Sampled, TimingEvidence::FewerTerms)
        } else if held.terms < sampled.terms {
            (CommandTiming::Held, TimingEvidence::FewerTerms)
        } else {
            (CommandTiming::Held, TimingEvidence::Ambiguous)
        };
        let alternative = if reading == CommandTiming::Held {
            sampled
        } else {
            held
        };
        Self {
            reading,
            decided_by,
            alternative: Some(alternative),
            sampled_vs_held: Some(sampled_vs_held),
        }
    }

    /// The other reading's value of `effect`'s `param` when the choice was ambiguous: what
    /// an interval must also cover, since the log cannot tell the two apart.
    pub fn ambiguous_value(&self, effect: Effect, param: &str) -> Option<f64> {
        if self.decided_by != TimingEvidence::Ambiguous {
            return None;
        }
        let alternative = self.alternative.as_ref()?;
        alternative
            .params
            .iter()
            .find(|(e, _)| *e == effect)
            .and_then(|(_, params)| params.get(param).copied())
    }

    /// One line for the summary.
    pub fn summary(&self) -> String {
        let read = format!("commands read as {}", self.reading.name());
        let Some(other) = &self.alternative else {
            return format!("{read} (declared)");
        };
        let other_reading = format!(
            "read as {}: {}, held-out {:.3} m",
            other.reading.name(),
            describe(other),
            other.heldout_pos_rmse_m
        );
        match self.decided_by {
            TimingEvidence::HeldOutError => {
                format!("{read}: clearly better on held-out tracks than {other_reading}")
            }
            TimingEvidence::FewerTerms => {
                format!("{read}: no worse with fewer terms than {other_reading}")
            }
            _ => format!(
                "{read}, but the log cannot tell (both readings fit alike with as many terms; \
                 declare --command-timing): {other_reading}; parameter intervals span both"
            ),
        }
    }
}

/// `accel_lag (tau_s 0.456)` or `nominal`.
fn describe(outcome: &ReadingOutcome) -> String {
    if outcome.params.is_empty() {
        return outcome.model.clone();
    }
    let effects: Vec<String> = outcome
        .params
        .iter()
        .map(|(effect, params)| {
            let values: Vec<String> = params.iter().map(|(k, v)| format!("{k} {v:.3}")).collect();
            format!("{effect} ({})", values.join(", "))
        })
        .collect();
    if outcome.terms > outcome.params.len() {
        format!("{} + discovered", effects.join(" + "))
    } else {
        effects.join(" + ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(reading: CommandTiming, terms: usize, delay_s: f64) -> ReadingOutcome {
        ReadingOutcome {
            reading,
            model: "dead_time".into(),
            terms,
            heldout_pos_rmse_m: 0.2,
            params: vec![(Effect::DeadTime, [("delay_s".to_string(), delay_s)].into())],
        }
    }

    fn gain(improvement_pct: f64, significant: bool) -> PairedGain {
        PairedGain {
            improvement_pct,
            t_stat: if significant { 3.0 } else { 1.0 },
            significant,
        }
    }

    #[test]
    fn the_reading_that_fits_better_or_simpler_wins_and_a_tie_is_ambiguous() {
        let decide = |held_terms, sampled_terms, sampled_vs_held, held_vs_sampled| {
            let d = TimingDecision::between(
                outcome(CommandTiming::Held, held_terms, 0.25),
                outcome(CommandTiming::Sampled, sampled_terms, 0.30),
                [sampled_vs_held, held_vs_sampled],
                10.0,
            );
            (d.reading, d.decided_by, d)
        };
        use CommandTiming::{Held, Sampled};
        use TimingEvidence::*;
        // Significant by the parsimony rule, even with more terms.
        let (r, why, _) = decide(1, 2, gain(15.0, true), gain(-18.0, false));
        assert_eq!((r, why), (Sampled, HeldOutError));
        // As many terms: the margin alone decides (the t-test guards added terms only).
        let (r, why, _) = decide(0, 0, gain(32.0, false), gain(-47.0, false));
        assert_eq!((r, why), (Sampled, HeldOutError));
        // Different terms and no clear winner: fewer terms.
        let (r, why, _) = decide(1, 2, gain(2.0, false), gain(-2.0, false));
        assert_eq!((r, why), (Held, FewerTerms));
        let (r, why, _) = decide(2, 1, gain(-1.0, false), gain(1.0, false));
        assert_eq!((r, why), (Sampled, FewerTerms));
        // A tie: held, and the sampled values widen the intervals.
        let (r, why, d) = decide(1, 1, gain(1.0, false), gain(-1.0, false));
        assert_eq!((r, why), (Held, Ambiguous));
        assert_eq!(d.ambiguous_value(Effect::DeadTime, "delay_s"), Some(0.30));
        assert_eq!(d.ambiguous_value(Effect::AccelLag, "tau_s"), None);
        let (_, _, d) = decide(1, 2, gain(2.0, false), gain(-2.0, false));
        assert_eq!(d.ambiguous_value(Effect::DeadTime, "delay_s"), None);
    }

    #[test]
    fn sampled_commands_apply_as_their_mean_over_the_period() {
        let mut track = crate::data::RecordedTrack::empty("a".into(), 0.1, None);
        for (k, (u, phi)) in [(0.0, 0.0), (1.0, 0.02), (3.0, 0.02)]
            .into_iter()
            .enumerate()
        {
            track.t.push(0.1 * k as f64);
            track.x.push(0.0);
            track.y.push(0.0);
            track.heading.push(0.0);
            track.speed.push(0.0);
            track.accel_cmd.push(u);
            track.steer_cmd.push(phi);
        }
        let recordings = Recordings {
            source: "test".into(),
            tracks: vec![track],
        };
        assert_eq!(
            as_held(&recordings, CommandTiming::Held).tracks[0].accel_cmd,
            [0.0, 1.0, 3.0]
        );
        let sampled = &as_held(&recordings, CommandTiming::Sampled).tracks[0];
        assert_eq!(sampled.accel_cmd, [0.5, 2.0, 3.0]);
        assert_eq!(sampled.steer_cmd, [0.01, 0.02, 0.02]);
    }
}
