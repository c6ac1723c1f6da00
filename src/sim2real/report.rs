//! The sim-to-real report: JSON for machines, a short summary for people.

use std::collections::BTreeMap;

use serde::Serialize;

use super::command_timing::TimingDecision;
use super::discover::Discovery;
use super::fit::Fit;
use super::identify::{Evaluated, Selection, Sim2RealOptions};
use super::locate::{ChannelRms, Mismatch};
use super::simulate::StepError;
use super::unexplained::Unexplained;
use super::windows::Window;
use crate::data::Recordings;
use crate::sim::catalogue::{DiscoveredTerm, DynamicsFile, Effect, FittedTerm};
use crate::sim::library::{Equation, Feature};

/// Held-out comparison of a model against a reference model, paired by track.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub rmse_before_m: f64,
    pub rmse_after_m: f64,
    pub improvement_pct: f64,
    /// Mean over held-out tracks of ln(MSE before / MSE after), over its standard error.
    pub t_stat: f64,
    /// One-sided p-value of the exact sign-flip test of the same mean ([`sign_flip_p`]);
    /// `None` with more than [`MAX_EXACT_TRACKS`] held-out tracks.
    pub sign_flip_p: Option<f64>,
    pub tracks: usize,
    /// Passes the parsimony rule.
    pub significant: bool,
}

fn rmse(errors: &[Vec<StepError>]) -> f64 {
    ChannelRms::of(errors.iter().flatten()).pos_m
}

impl Comparison {
    pub fn paired(
        windows: &[Window],
        reference: &[Vec<StepError>],
        new: &[Vec<StepError>],
        options: &Sim2RealOptions,
    ) -> Self {
        // Per held-out track: mean squared position error of each model.
        let mut per_track: BTreeMap<usize, (f64, f64, usize)> = BTreeMap::new();
        for ((w, a), b) in windows.iter().zip(reference).zip(new) {
            let entry = per_track.entry(w.track).or_default();
            for (ea, eb) in a.iter().zip(b) {
                entry.0 += ea.position_sq();
                entry.1 += eb.position_sq();
                entry.2 += 1;
            }
        }
        // Log-ratios, so a track driven gently (small errors either way) counts as much as
        // one with hard manoeuvres: a real effect improves every track by some factor.
        let ratios: Vec<f64> = per_track
            .values()
            .map(|(a, b, _)| (a.max(1e-12) / b.max(1e-12)).ln())
            .collect();
        let n = ratios.len() as f64;
        let mean = ratios.iter().sum::<f64>() / n.max(1.0);
        let var = ratios.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let t_stat = if var > 0.0 {
            mean / (var / n).sqrt()
        } else if mean > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        let (before, after) = (rmse(reference), rmse(new));
        let improvement_pct = 100.0 * (1.0 - after / before.max(1e-12));
        let sign_flip_p = sign_flip_p(&ratios);
        let consistent = t_stat >= options.min_t_stat
            || sign_flip_p.is_some_and(|p| p <= options.max_sign_flip_p);
        Self {
            rmse_before_m: before,
            rmse_after_m: after,
            improvement_pct,
            t_stat,
            sign_flip_p,
            tracks: ratios.len(),
            significant: improvement_pct >= options.min_improvement_pct && consistent,
        }
    }
}

/// Held-out tracks up to which [`sign_flip_p`] enumerates every sign pattern (2^16).
pub const MAX_EXACT_TRACKS: usize = 16;

/// One-sided p-value of the exact sign-flip (permutation) test that the per-track log-ratios
/// `ratios` have mean > 0: the share of the 2^n patterns of signs whose sum is at least the
/// observed one. Under no effect each track's ratio is as likely negative as positive, and
/// no normality is assumed, so an effect that shows on some tracks only (a steering rate
/// limit reached in brisk steering alone) is judged by how consistently it helps rather than
/// how evenly; the t statistic's standard error grows with that unevenness. `None` above
/// [`MAX_EXACT_TRACKS`] tracks, where the t statistic's normal limit serves.
pub fn sign_flip_p(ratios: &[f64]) -> Option<f64> {
    let n = ratios.len();
    if n == 0 || n > MAX_EXACT_TRACKS {
        return None;
    }
    let observed: f64 = ratios.iter().sum();
    // A pattern ties the observed sum when it flips only zero ratios: compare with slack.
    let slack = 1e-12 * ratios.iter().map(|r| r.abs()).sum::<f64>().max(1e-300);
    let at_least = (0u32..1 << n)
        .filter(|mask| {
            let sum: f64 = ratios
                .iter()
                .enumerate()
                .map(|(i, r)| if mask & (1 << i) != 0 { -r } else { *r })
                .sum();
            sum >= observed - slack
        })
        .count();
    Some(at_least as f64 / (1u64 << n) as f64)
}

/// A fitted value with its standard error.
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    pub value: f64,
    pub std_error: f64,
}

/// Fitted parameters of each effect, by name.
type EffectEstimates = Vec<(Effect, BTreeMap<String, Estimate>)>;

/// The discovered terms of a fit, with their refitted coefficients.
fn discovered_estimates(fit: &Fit) -> Vec<DiscoveredEstimate> {
    let n = fit.candidate.discovered.len();
    let at = fit.values.len() - n;
    fit.candidate
        .discovered
        .iter()
        .enumerate()
        .map(|(k, &(equation, feature, start))| DiscoveredEstimate {
            equation,
            feature,
            regression_coefficient: start,
            coefficient: Estimate {
                value: fit.values[at + k],
                std_error: fit.std_errors[at + k],
            },
            meaning: feature.meaning(equation, fit.values[at + k]),
        })
        .collect()
}

/// The discovered terms as equations, e.g. `dv/dt = u + 0.297 min(u, 0)`.
pub fn equation_text(terms: &[DiscoveredEstimate]) -> String {
    let mut lines = Vec::new();
    for equation in [Equation::Speed, Equation::HeadingRate] {
        let extra: Vec<String> = terms
            .iter()
            .filter(|t| t.equation == equation)
            .map(|t| {
                let c = t.coefficient.value;
                let sign = if c < 0.0 { "-" } else { "+" };
                format!("{sign} {:.4e} {}", c.abs(), t.feature.symbol())
            })
            .collect();
        if !extra.is_empty() {
            let nominal = match equation {
                Equation::Speed => "u",
                Equation::HeadingRate => "v tan(phi) / L",
            };
            lines.push(format!(
                "{} = {nominal} {}",
                equation.symbol(),
                extra.join(" ")
            ));
        }
    }
    lines.join("; ")
}

/// The wheelbase scale and each effect's parameters of a fit.
pub(super) fn estimates(fit: &Fit) -> (Estimate, EffectEstimates) {
    let specs = fit.candidate.specs();
    let wheelbase = Estimate {
        value: fit.values[0],
        std_error: fit.std_errors[0],
    };
    let mut at = 1;
    let effects = fit
        .candidate
        .effects
        .iter()
        .map(|&e| {
            let params = e
                .params()
                .iter()
                .map(|s| {
                    let k = at;
                    at += 1;
                    debug_assert_eq!(specs[k].name, s.name);
                    (
                        s.name.to_string(),
                        Estimate {
                            value: fit.values[k],
                            std_error: fit.std_errors[k],
                        },
                    )
                })
                .collect();
            (e, params)
        })
        .collect();
    (wheelbase, effects)
}

#[derive(Debug, Clone, Serialize)]
pub struct Baseline {
    pub heldout_pos_rmse_m: f64,
    pub wheelbase: &'static str,
}

#[derive(Debug, Clone, Serialize)]
pub struct NominalRefit {
    pub heldout_pos_rmse_m: f64,
    pub wheelbase_scale: Estimate,
}

#[derive(Debug, Clone, Serialize)]
pub struct CandidateResult {
    pub effect: Effect,
    pub params: BTreeMap<String, Estimate>,
    pub heldout_pos_rmse_m: f64,
    /// Against the nominal refit.
    pub improvement_pct: f64,
    pub t_stat: f64,
    /// The exact sign-flip test's p-value ([`sign_flip_p`]), beside the t statistic.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sign_flip_p: Option<f64>,
    pub significant: bool,
}

/// A discovered library term with its coefficient refitted through the rollout.
#[derive(Debug, Clone, Serialize)]
pub struct DiscoveredEstimate {
    pub equation: Equation,
    pub feature: Feature,
    /// From the sparse regression on derivative residuals.
    pub regression_coefficient: f64,
    /// Refitted through the rollout, with its standard error.
    pub coefficient: Estimate,
    pub meaning: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    /// The catalogue effect, or none for a discovered equation.
    pub effect: Option<Effect>,
    /// The effect's name, or `discovered`.
    pub name: String,
    pub description: String,
    /// For a discovered equation: it in symbols, with the refitted coefficients.
    pub equation: Option<String>,
    pub discovered: Vec<DiscoveredEstimate>,
    pub params: BTreeMap<String, f64>,
    pub params_std_error: BTreeMap<String, f64>,
    /// About 95 %: two cluster-robust standard errors either side; times (lags, delays)
    /// also +- a tenth of the sampling period ([`TIME_RESOLUTION_PERIODS`]), and sideslip's
    /// `lr` that time at the median speed; widened to the other reading's value when the
    /// command timing was ambiguous.
    pub params_interval: BTreeMap<String, [f64; 2]>,
    /// Held-out error of the model with this and every earlier finding.
    pub heldout_pos_rmse_m: f64,
    /// Against the model before this finding (the nominal refit for the first).
    pub improvement_pct: f64,
    pub t_stat: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Final {
    /// `nominal` or the effects joined by `+`.
    pub model: String,
    pub heldout_pos_rmse_m: f64,
    pub wheelbase_scale: Estimate,
    /// Every identified term with the values fitted jointly in the final model.
    pub terms: Vec<FittedTerm>,
    /// Discovered library terms in the final model, refitted jointly.
    pub discovered: Vec<DiscoveredEstimate>,
    pub improvement_vs_baseline_pct: f64,
    pub mismatch: Mismatch,
}

#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub source: String,
    /// The sha256 of the recordings file as it was read (none for the A9 or generated
    /// tracks): the report describes these contents, whatever lies at `source` later.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_sha256: Option<String>,
    pub tracks: usize,
    pub training_windows: usize,
    pub heldout_windows: usize,
    pub heldout_tracks: usize,
    /// Tracks that declare no wheelbase (they get `options.default_wheelbase_m`).
    pub tracks_without_wheelbase: usize,
    pub options: Sim2RealOptions,
    /// How the commands were read between samples, and why.
    pub command_timing: TimingDecision,
    pub baseline: Baseline,
    pub nominal_refit: NominalRefit,
    pub mismatch: Mismatch,
    pub candidates: Vec<CandidateResult>,
    pub findings: Vec<Finding>,
    /// Effects that cannot be identified from these recordings, and why.
    pub not_identifiable: Vec<(Effect, String)>,
    #[serde(rename = "final")]
    pub final_model: Final,
    /// The final model's held-out error against the noise floor.
    pub unexplained: Unexplained,
    /// The open-ended stage's sparse regression (whether or not it was kept).
    pub discovery: Discovery,
    /// The discovered equation refitted through the rollout as a candidate on its own, and
    /// its held-out comparison with the nominal refit (none when nothing was selected).
    pub discovered_candidate: Option<DiscoveredCandidate>,
    /// When the final model stays above the noise floor: one line on what was tried and
    /// which channel and regime the rest of the mismatch sits in.
    pub still_open: Option<String>,
}

/// The discovered equation as a candidate beside the catalogue's.
#[derive(Debug, Clone, Serialize)]
pub struct DiscoveredCandidate {
    pub equation: String,
    pub terms: Vec<DiscoveredEstimate>,
    pub heldout_pos_rmse_m: f64,
    pub improvement_pct: f64,
    pub t_stat: f64,
    pub significant: bool,
}

impl DiscoveredCandidate {
    pub fn new(evaluated: &Evaluated, comparison: &Comparison) -> Self {
        let terms = discovered_estimates(&evaluated.fit);
        Self {
            equation: equation_text(&terms),
            terms,
            heldout_pos_rmse_m: comparison.rmse_after_m,
            improvement_pct: comparison.improvement_pct,
            t_stat: comparison.t_stat,
            significant: comparison.significant,
        }
    }
}

/// Where the mismatch is before and after the chosen model, and what is left unexplained.
pub struct Diagnosis {
    pub before: Mismatch,
    pub after: Mismatch,
    pub unexplained: Unexplained,
}

impl Report {
    /// `windows` are the training and held-out windows.
    pub fn new(
        recordings: &Recordings,
        options: &Sim2RealOptions,
        [train, heldout]: [&[Window]; 2],
        selection: &Selection,
        diagnosis: Diagnosis,
        command_timing: TimingDecision,
    ) -> Self {
        let baseline_rmse = rmse(&selection.baseline.errors);
        let (refit_wheelbase, _) = estimates(&selection.refit.fit);
        Self {
            source: recordings.source.clone(),
            source_sha256: None,
            tracks: recordings.tracks.len(),
            training_windows: train.len(),
            heldout_windows: heldout.len(),
            heldout_tracks: heldout
                .iter()
                .map(|w| w.track)
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            tracks_without_wheelbase: recordings
                .tracks
                .iter()
                .filter(|t| t.wheelbase.is_none())
                .count(),
            options: options.clone(),
            findings: findings(
                &selection.chosen,
                &command_timing,
                Resolution::of(recordings, train),
            ),
            command_timing,
            baseline: Baseline {
                heldout_pos_rmse_m: baseline_rmse,
                wheelbase: "declared",
            },
            nominal_refit: NominalRefit {
                heldout_pos_rmse_m: rmse(&selection.refit.errors),
                wheelbase_scale: refit_wheelbase,
            },
            mismatch: diagnosis.before,
            candidates: candidate_results(selection),
            not_identifiable: not_identifiable(&selection.tried, options),
            final_model: Final::new(&selection.final_model, baseline_rmse, diagnosis.after),
            unexplained: diagnosis.unexplained,
            discovery: selection.discovery.clone(),
            discovered_candidate: selection
                .discovered
                .as_ref()
                .map(|(e, c)| DiscoveredCandidate::new(e, c)),
            still_open: None,
        }
        .with_still_open()
    }

    fn with_still_open(mut self) -> Self {
        self.still_open = super::still_open::line(&self);
        self
    }

    /// The identified terms, to load into the training simulator.
    pub fn dynamics(&self) -> DynamicsFile {
        DynamicsFile {
            terms: self.final_model.terms.clone(),
            discovered: self
                .final_model
                .discovered
                .iter()
                .map(|t| DiscoveredTerm {
                    equation: t.equation,
                    feature: t.feature,
                    coefficient: t.coefficient.value,
                })
                .collect(),
        }
    }

    /// A short human summary.
    pub fn summary(&self) -> Vec<String> {
        let m = &self.mismatch;
        let mut lines = vec![format!(
            "{}: {} tracks, {} training / {} held-out windows of {} s",
            self.source,
            self.tracks,
            self.training_windows,
            self.heldout_windows,
            self.options.horizon_s
        )];
        if self.tracks_without_wheelbase > 0 {
            lines.push(format!(
                "{} tracks declare no wheelbase: {} m assumed (the refit scales it)",
                self.tracks_without_wheelbase, self.options.default_wheelbase_m
            ));
        }
        lines.push(format!(
            "baseline (nominal bicycle, declared wheelbase): held-out position RMSE {:.3} m \
             (along {:.3} m, across {:.3} m, heading {:.4} rad, speed {:.3} m/s)",
            self.baseline.heldout_pos_rmse_m,
            m.channels.along_m,
            m.channels.across_m,
            m.channels.heading_rad,
            m.channels.speed_m_s
        ));
        for c in m.concentrations.iter().take(3) {
            lines.push(format!(
                "  mismatch concentrates where {} is {}: {} error {:.3} = {:.1}x its average",
                c.variable, c.range, c.channel, c.rms, c.ratio
            ));
        }
        let wb = &self.nominal_refit.wheelbase_scale;
        lines.push(format!(
            "nominal refit: wheelbase x{:.3} (+-{:.3}), held-out {:.3} m",
            wb.value, wb.std_error, self.nominal_refit.heldout_pos_rmse_m
        ));
        lines.push(self.command_timing.summary());
        if self.findings.is_empty() {
            lines.push(if self.unexplained.at_floor {
                "findings: none. No catalogue effect lowers held-out error by a clear margin, \
                 and the nominal model's error is at the noise floor: it explains these \
                 recordings"
                    .into()
            } else {
                "findings: none from the catalogue. No catalogue effect lowers held-out error \
                 by a clear margin, yet the error stays above the noise floor (see \
                 unexplained)"
                    .into()
            });
        }
        for f in &self.findings {
            let params: Vec<String> = match &f.equation {
                Some(equation) => vec![equation.clone()],
                None => f
                    .params
                    .iter()
                    .map(|(k, v)| {
                        let [low, high] = f.params_interval[k];
                        format!("{k} = {v:.4} (95 % {low:.4} .. {high:.4})")
                    })
                    .collect(),
            };
            lines.push(format!(
                "finding: {} ({}), {}: held-out {:.3} m, -{:.1} %",
                f.name,
                f.description,
                params.join(", "),
                f.heldout_pos_rmse_m,
                f.improvement_pct
            ));
        }
        if self.findings.iter().all(|f| f.effect.is_some()) {
            let regression: Vec<String> = self
                .discovery
                .terms()
                .iter()
                .map(|(e, f, c)| format!("{} += {c:.4e} {}", e.symbol(), f.symbol()))
                .collect();
            if !regression.is_empty() {
                let why = if self.options.discover {
                    "on held-out tracks it did not pass the parsimony rule against the nominal \
                     refit, or did not beat the catalogue's best by it"
                } else {
                    "catalogue only"
                };
                lines.push(format!(
                    "discovery (not kept: {why}): {}",
                    regression.join(", ")
                ));
            }
        }
        for (e, why) in &self.not_identifiable {
            lines.push(format!("not identifiable: {e}: {why}"));
        }
        lines.push(format!(
            "final ({}): held-out position RMSE {:.3} m, {:.1} % below baseline",
            self.final_model.model,
            self.final_model.heldout_pos_rmse_m,
            self.final_model.improvement_vs_baseline_pct
        ));
        lines.extend(self.unexplained.summary());
        lines.extend(self.still_open.clone());
        lines
    }
}

/// Every tried catalogue effect with its estimates, best held-out error first.
fn candidate_results(selection: &Selection) -> Vec<CandidateResult> {
    selection
        .ranked
        .iter()
        .map(|(k, c)| {
            let (_, effects) = estimates(&selection.singles[*k].fit);
            let (effect, params) = effects.into_iter().next().expect("one effect");
            CandidateResult {
                effect,
                params,
                heldout_pos_rmse_m: c.rmse_after_m,
                improvement_pct: c.improvement_pct,
                t_stat: c.t_stat,
                sign_flip_p: c.sign_flip_p,
                significant: c.significant,
            }
        })
        .collect()
}

/// How finely, in sampling periods, a simulator stepping once per sample resolves a time
/// constant. Where within a period a command takes effect and how the actuator moves within
/// it are below what the step sees, so a fitted lag or delay carries a discretisation error
/// that no amount of data shrinks: on the generator's continuous plant, about 0.04 periods
/// (10 and 20 Hz logs, lags and delay); a tenth leaves a margin.
pub const TIME_RESOLUTION_PERIODS: f64 = 0.1;

/// What a simulator stepping once per sample cannot resolve, for the parameter intervals.
#[derive(Debug, Clone, Copy)]
struct Resolution {
    /// The coarsest sampling period of the recordings (s).
    period_s: f64,
    /// The median speed at the training windows' starts (m/s).
    speed_m_s: f64,
}

impl Resolution {
    fn of(recordings: &Recordings, train: &[Window]) -> Self {
        let mut speeds: Vec<f64> = train.iter().map(|w| w.initial[3]).collect();
        speeds.sort_by(f64::total_cmp);
        Self {
            period_s: recordings
                .tracks
                .iter()
                .map(|t| t.period)
                .fold(0.0, f64::max),
            speed_m_s: speeds.get(speeds.len() / 2).copied().unwrap_or(0.0),
        }
    }

    /// The unresolved part of `effect`'s parameter `name`: for times (lags, delay) a tenth
    /// of a period; for sideslip's `lr`, whose lateral offset leads the path by `lr / v`, the
    /// same time as a length at the typical speed; nothing for the rest.
    fn of_param(self, effect: Effect, name: &str) -> f64 {
        let is_time = effect
            .params()
            .iter()
            .any(|p| p.name == name && p.unit == "s");
        let time = TIME_RESOLUTION_PERIODS * self.period_s;
        match effect {
            _ if is_time => time,
            Effect::Sideslip => time * self.speed_m_s,
            _ => 0.0,
        }
    }
}

/// One finding per kept model: what it added to the model before it.
fn findings(
    chosen: &[(Evaluated, Comparison)],
    timing: &TimingDecision,
    resolution: Resolution,
) -> Vec<Finding> {
    let mut previous: Option<&Fit> = None;
    chosen
        .iter()
        .map(|(e, c)| {
            let added_discovered = !e.fit.candidate.discovered.is_empty()
                && previous.is_none_or(|p| p.candidate.discovered.is_empty());
            previous = Some(&e.fit);
            if added_discovered {
                Finding::discovered(&e.fit, c)
            } else {
                Finding::catalogue(&e.fit, c, timing, resolution)
            }
        })
        .collect()
}

/// The catalogue effects not tried, and why.
fn not_identifiable(tried: &[Effect], options: &Sim2RealOptions) -> Vec<(Effect, String)> {
    Effect::ALL
        .into_iter()
        .filter(|e| !tried.contains(e))
        .map(|e| {
            let why = if options.commands_inferred && e.acts_on_commands() {
                "the commands were inferred from the motion, so whatever the actuators did \
                 is already in them: this needs recorded commands"
            } else {
                "not among the candidates requested"
            };
            (e, why.to_string())
        })
        .collect()
}

impl Finding {
    /// The discovered terms that `fit` added.
    fn discovered(fit: &Fit, c: &Comparison) -> Self {
        let terms = discovered_estimates(fit);
        let meanings: Vec<&str> = terms.iter().map(|t| t.meaning.as_str()).collect();
        Self {
            effect: None,
            name: "discovered".into(),
            description: meanings.join("; "),
            equation: Some(equation_text(&terms)),
            discovered: terms,
            params: BTreeMap::new(),
            params_std_error: BTreeMap::new(),
            params_interval: BTreeMap::new(),
            heldout_pos_rmse_m: c.rmse_after_m,
            improvement_pct: c.improvement_pct,
            t_stat: c.t_stat,
        }
    }

    /// The catalogue effect that `fit` added (its last).
    fn catalogue(
        fit: &Fit,
        c: &Comparison,
        timing: &TimingDecision,
        resolution: Resolution,
    ) -> Self {
        let (_, effects) = estimates(fit);
        let (effect, params) = effects.last().cloned().expect("an effect");
        let interval = |name: &str, e: &Estimate| {
            let half_width = 2.0 * e.std_error + resolution.of_param(effect, name);
            let (mut low, mut high) = (e.value - half_width, e.value + half_width);
            if let Some(other) = timing.ambiguous_value(effect, name) {
                (low, high) = (low.min(other), high.max(other));
            }
            [low, high]
        };
        Self {
            effect: Some(effect),
            name: effect.name().into(),
            description: effect.description().into(),
            equation: None,
            discovered: Vec::new(),
            params: params.iter().map(|(k, v)| (k.clone(), v.value)).collect(),
            params_std_error: params
                .iter()
                .map(|(k, v)| (k.clone(), v.std_error))
                .collect(),
            params_interval: params
                .iter()
                .map(|(k, v)| (k.clone(), interval(k, v)))
                .collect(),
            heldout_pos_rmse_m: c.rmse_after_m,
            improvement_pct: c.improvement_pct,
            t_stat: c.t_stat,
        }
    }
}

impl Final {
    fn new(final_model: &Evaluated, baseline_rmse: f64, mismatch: Mismatch) -> Self {
        let final_rmse = rmse(&final_model.errors);
        let (wheelbase_scale, effects) = estimates(&final_model.fit);
        Self {
            model: final_model.fit.candidate.label(),
            heldout_pos_rmse_m: final_rmse,
            wheelbase_scale,
            terms: effects
                .into_iter()
                .map(|(effect, params)| FittedTerm {
                    effect,
                    params: params.into_iter().map(|(k, v)| (k, v.value)).collect(),
                })
                .collect(),
            discovered: discovered_estimates(&final_model.fit),
            improvement_vs_baseline_pct: 100.0 * (1.0 - final_rmse / baseline_rmse.max(1e-12)),
            mismatch,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::sign_flip_p;

    #[test]
    fn the_sign_flip_test_counts_sign_patterns_exactly() {
        // Every track better, however unevenly: only the observed pattern reaches its sum.
        let uneven = [
            0.01, 0.02, 0.9, 0.01, 1.5, 0.03, 0.02, 0.01, 0.04, 0.02, 2.0, 0.01,
        ];
        let p = sign_flip_p(&uneven).expect("12 tracks");
        assert!((p - 1.0 / 4096.0).abs() < 1e-15, "{p}");
        // Balanced gains and losses: about half the patterns do at least as well.
        let balanced = [0.5, -0.5, 0.3, -0.3, 0.2, -0.2];
        let p = sign_flip_p(&balanced).expect("6 tracks");
        assert!((0.5..0.7).contains(&p), "{p}");
        // No change at all is no evidence.
        assert_eq!(sign_flip_p(&[0.0; 8]), Some(1.0));
        // Beyond the exact limit the t statistic serves.
        assert_eq!(sign_flip_p(&[0.1; 17]), None);
        assert_eq!(sign_flip_p(&[]), None);
    }
}
