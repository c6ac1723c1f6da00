//! The identification pipeline: baseline, nominal refit, one fit per catalogue effect,
//! selection on held-out tracks with a parsimony rule, pairs when one effect is not enough.

use burn::prelude::Device;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::command_timing::{
    CommandTiming, PairedGain, ReadingOutcome, TimingDecision, TimingEvidence, as_held,
};
use super::discover::Discovery;
use super::discover::discover;
use super::fit::{Fit, FitOptions, evaluate, fit, standard_errors};
use super::locate::{ChannelRms, locate};
use super::noise::NoiseLevels;
use super::report::{Comparison, Diagnosis, Report, estimates};
use super::simulate::{Candidate, StepError, WindowBatch, batches};
use super::unexplained::{RegimeExcess, Unexplained, regime_excess};
use super::windows::{Starts, Window, rebuilt, windows};
use crate::backend::Backend;
use crate::data::Recordings;
use crate::error::{Error, Result};
use crate::sim::catalogue::Effect;

/// Settings of a sim-to-real run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Sim2RealOptions {
    /// Horizon of fitting and held-out evaluation windows (s).
    pub horizon_s: f64,
    /// Start-to-start spacing of those windows (s).
    pub stride_s: f64,
    /// Horizon of the short windows that localise the mismatch (s).
    pub short_window_s: f64,
    /// One track in this many is held out.
    pub heldout_every: usize,
    pub seed: u64,
    pub fit: FitOptions,
    /// Parsimony rule: an effect is reported only if it lowers held-out position RMSE by at
    /// least this much ...
    pub min_improvement_pct: f64,
    /// ... and the per-track paired improvement has at least this t statistic, or an exact
    /// sign-flip p-value at most [`Self::max_sign_flip_p`] (an effect that helps on every
    /// track where it acts, but acts on some only).
    pub min_t_stat: f64,
    pub max_sign_flip_p: f64,
    /// Candidates to try.
    pub effects: Vec<Effect>,
    /// Wheelbase for tracks that declare none (m).
    pub default_wheelbase_m: f64,
    /// Whether the commands were inferred from the motion (then effects acting on the
    /// commands cannot be identified and are not tried).
    pub commands_inferred: bool,
    /// Whether equations found by the open-ended stage ([`super::discover`]) compete with
    /// the catalogue (the regression is always run and reported).
    pub discover: bool,
    /// How the recordings' commands were applied between samples; none to fit both
    /// readings and let held-out error decide ([`TimingDecision::between`]).
    pub command_timing: Option<CommandTiming>,
}

impl Default for Sim2RealOptions {
    fn default() -> Self {
        Self {
            horizon_s: 5.0,
            stride_s: 2.5,
            short_window_s: 1.0,
            heldout_every: 2,
            seed: 2023,
            fit: FitOptions::default(),
            min_improvement_pct: 10.0,
            min_t_stat: 2.5,
            max_sign_flip_p: 0.005,
            effects: Effect::ALL.to_vec(),
            default_wheelbase_m: 2.8,
            commands_inferred: false,
            discover: true,
            command_timing: None,
        }
    }
}

/// What a run produced: the report, and what the plots need.
pub struct Outcome {
    pub report: Report,
    pub heldout: Vec<Window>,
    pub baseline: Evaluated,
    pub final_model: Evaluated,
    /// Short-window error against the noise floor by regime bin, baseline and final model.
    pub excess_before: Vec<RegimeExcess>,
    pub excess_after: Vec<RegimeExcess>,
}

/// Held-out errors of one model.
#[derive(Debug, Clone)]
pub struct Evaluated {
    pub fit: Fit,
    pub errors: Vec<Vec<StepError>>,
}

#[derive(Clone)]
struct Split {
    train_tracks: Vec<usize>,
    heldout_tracks: Vec<usize>,
    train: Vec<Window>,
    heldout: Vec<Window>,
    short: Vec<Window>,
}

/// Shortest simulation step sim2real fits at (s): every effect in the catalogue acts over
/// tens of milliseconds or more, and a 1 kHz log simulated step by step over a 5 s horizon
/// costs ten times a 100 Hz one for no information.
const MIN_SIM_PERIOD: f64 = 0.01;

/// Every how many samples a track sampled every `period` s is fitted: the smallest k that
/// reaches 100 Hz or slower (1 for tracks at 100 Hz or slower).
pub fn thinning(period: f64) -> usize {
    ((MIN_SIM_PERIOD / period * (1.0 - 1e-6)).ceil() as usize).max(1)
}

/// Tracks sampled faster than 100 Hz, thinned to every k-th sample ([`thinning`]); slower
/// tracks as they are.
fn at_most_100_hz(recordings: &Recordings) -> Recordings {
    let mut thinned = recordings.clone();
    for track in &mut thinned.tracks {
        let k = thinning(track.period);
        if k > 1 {
            *track = track.decimated(k);
        }
    }
    thinned
}

/// The horizons must hold whole sampling periods of every track (a window of fewer than 2
/// steps compares nothing).
fn check_horizons(recordings: &Recordings, options: &Sim2RealOptions) -> Result<()> {
    let shortest = options.horizon_s.min(options.short_window_s);
    if !(shortest.is_finite() && shortest > 0.0 && options.horizon_s.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "the horizon ({} s) and short window ({} s) must be positive seconds",
            options.horizon_s, options.short_window_s
        )));
    }
    match recordings.tracks.iter().find(|t| 2.0 * t.period > shortest) {
        Some(t) => Err(Error::invalid(
            &recordings.source,
            format!("track `{}` (line {}), column `t`", t.id, t.first_line),
            format!(
                "sampled every {} s, but the {} s horizon needs at least 2 samples: expected \
                 a sampling period of at most {} s (or a longer --horizon; timestamps in \
                 milliseconds?)",
                t.period,
                shortest,
                shortest / 2.0
            ),
        )),
        None => Ok(()),
    }
}

/// Fastest a vehicle of the recordings must drive (m/s) for its motion to say anything about
/// the physics: standing or creeping vehicles excite nothing, and a model that keeps them
/// still would be reported as explaining them.
const MIN_TOP_SPEED: f64 = 1.0;

/// Refuses recordings in which no vehicle moves.
fn check_excitation(recordings: &Recordings) -> Result<()> {
    let top = recordings
        .tracks
        .iter()
        .flat_map(|t| t.speed.iter().copied())
        .fold(0.0, f64::max);
    if top >= MIN_TOP_SPEED {
        return super::command_checks::check_commands(recordings);
    }
    Err(Error::invalid(
        &recordings.source,
        "column `speed`",
        format!(
            "no vehicle drives faster than {top} m/s in these recordings: there is no motion to \
             compare the simulator with; expected recordings of driving vehicles (at least \
             {MIN_TOP_SPEED} m/s)"
        ),
    ))
}

fn split(recordings: &Recordings, options: &Sim2RealOptions) -> Result<Split> {
    check_horizons(recordings, options)?;
    check_excitation(recordings)?;
    let mut order: Vec<usize> = (0..recordings.tracks.len()).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(options.seed));
    let every = options.heldout_every.max(2);
    let (mut train_tracks, mut heldout_tracks) = (Vec::new(), Vec::new());
    for (k, t) in order.into_iter().enumerate() {
        if k % every == every - 1 {
            heldout_tracks.push(t);
        } else {
            train_tracks.push(t);
        }
    }
    let past = crate::sim::catalogue::MAX_DEAD_TIME_S;
    let wb = options.default_wheelbase_m;
    let long = |tracks: &[usize]| {
        windows(
            recordings,
            tracks,
            options.horizon_s,
            options.stride_s,
            past,
            wb,
            Starts::ClearOfCommandChanges,
        )
    };
    let (train, heldout) = (long(&train_tracks), long(&heldout_tracks));
    let all: Vec<usize> = (0..recordings.tracks.len()).collect();
    let short = windows(
        recordings,
        &all,
        options.short_window_s,
        options.short_window_s / 2.0,
        past,
        wb,
        Starts::Regular,
    );
    if train.is_empty() || heldout.is_empty() {
        return Err(Error::invalid(
            &recordings.source,
            "tracks",
            format!(
                "need at least {every} tracks longer than {} s (the horizon plus 1 s for \
                 denoising) to fit on some and hold others out; got {} tracks, {} training \
                 and {} held-out windows",
                options.horizon_s + 1.0,
                recordings.tracks.len(),
                train.len(),
                heldout.len()
            ),
        ));
    }
    Ok(Split {
        train_tracks,
        heldout_tracks,
        train,
        heldout,
        short,
    })
}

/// Runs the whole pipeline; `progress` hears each stage.
pub fn identify(
    recordings: &Recordings,
    options: &Sim2RealOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<Outcome> {
    let logged = at_most_100_hz(recordings);
    let logged_split = split(&logged, options)?;
    let readings: Vec<Reading> = timings_to_try(options)
        .into_iter()
        .map(|timing| Reading::new(&logged, &logged_split, timing, options))
        .collect();
    let fitters = readings
        .iter()
        .map(|r| Fitter::new(&r.split, options))
        .collect::<Result<Vec<_>>>()?;
    let selections: Vec<Selection> = readings
        .iter()
        .zip(&fitters)
        .map(|(reading, fitter)| {
            if readings.len() > 1 {
                progress(&format!(
                    "reading the commands as {}",
                    reading.timing.name()
                ));
            }
            select(fitter, &reading.recordings, progress)
        })
        .collect();
    let decision = decide_timing(&readings, &fitters[0], &selections);
    let chosen = readings
        .iter()
        .position(|r| r.timing == decision.reading)
        .unwrap_or(0);
    diagnose(
        &readings[chosen],
        &fitters[chosen],
        selections
            .into_iter()
            .nth(chosen)
            .expect("one selection per reading"),
        decision,
        progress,
    )
}

/// The recordings with their commands read one way, cut into the logged split's windows.
struct Reading {
    timing: CommandTiming,
    recordings: Recordings,
    split: Split,
}

impl Reading {
    fn new(
        logged: &Recordings,
        split: &Split,
        timing: CommandTiming,
        options: &Sim2RealOptions,
    ) -> Self {
        let recordings = as_held(logged, timing);
        let split = if timing == CommandTiming::Held {
            // The log's own commands: its windows as they are.
            split.clone()
        } else {
            let past = crate::sim::catalogue::MAX_DEAD_TIME_S;
            let again = |w: &[Window]| rebuilt(&recordings, w, past, options.default_wheelbase_m);
            Split {
                train_tracks: split.train_tracks.clone(),
                heldout_tracks: split.heldout_tracks.clone(),
                train: again(&split.train),
                heldout: again(&split.heldout),
                short: again(&split.short),
            }
        };
        Self {
            timing,
            recordings,
            split,
        }
    }
}

/// The command readings to fit: the declared one, else both.
fn timings_to_try(options: &Sim2RealOptions) -> Vec<CommandTiming> {
    match options.command_timing {
        Some(timing) => vec![timing],
        None => vec![CommandTiming::Held, CommandTiming::Sampled],
    }
}

/// Which reading's model to report. Both readings share their windows, so their held-out
/// errors compare pair by pair.
fn decide_timing(
    readings: &[Reading],
    fitter: &Fitter,
    selections: &[Selection],
) -> TimingDecision {
    let [held, sampled] = selections else {
        return TimingDecision::single(readings[0].timing, TimingEvidence::Declared);
    };
    let outcome = |timing, selection: &Selection| {
        let fit = &selection.final_model.fit;
        let (_, effects) = estimates(fit);
        ReadingOutcome {
            reading: timing,
            model: fit.candidate.label(),
            terms: fit.candidate.effects.len() + fit.candidate.discovered.len(),
            heldout_pos_rmse_m: ChannelRms::of(selection.final_model.errors.iter().flatten()).pos_m,
            params: effects
                .into_iter()
                .map(|(e, p)| (e, p.into_iter().map(|(k, v)| (k, v.value)).collect()))
                .collect(),
        }
    };
    let gain = |new: &Selection, reference: &Selection| {
        let c = fitter.compare(&new.final_model, &reference.final_model);
        PairedGain {
            improvement_pct: c.improvement_pct,
            t_stat: c.t_stat,
            significant: c.significant,
        }
    };
    TimingDecision::between(
        outcome(CommandTiming::Held, held),
        outcome(CommandTiming::Sampled, sampled),
        [gain(sampled, held), gain(held, sampled)],
        fitter.options.min_improvement_pct,
    )
}

/// Where the mismatch is before and after the chosen model, what is left unexplained, and
/// the report.
fn diagnose(
    reading: &Reading,
    fitter: &Fitter,
    selection: Selection,
    decision: TimingDecision,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<Outcome> {
    let (recordings, split) = (&reading.recordings, &reading.split);
    progress("locating the mismatch");
    let short_errors = |f: &Fit| evaluate(f, &fitter.short, split.short.len(), &fitter.plain);
    let baseline_short = short_errors(&selection.baseline.fit);
    let final_short = short_errors(&selection.final_model.fit);
    let period = split.heldout[0].period;
    let mismatch_of = |e: &Evaluated, short: &[Vec<StepError>]| {
        locate(recordings, &e.errors, period, &split.short, short)
    };
    let noise = NoiseLevels::estimate(&[split.train.as_slice(), &split.heldout].concat());
    let excess_before = regime_excess(recordings, &noise, &split.short, &baseline_short);
    let excess_after = regime_excess(recordings, &noise, &split.short, &final_short);
    let diagnosis = Diagnosis {
        before: mismatch_of(&selection.baseline, &baseline_short),
        after: mismatch_of(&selection.final_model, &final_short),
        unexplained: Unexplained::assess(
            recordings,
            noise,
            &split.heldout,
            &selection.final_model.errors,
            &split.short,
            &final_short,
        ),
    };
    let report = Report::new(
        recordings,
        fitter.options,
        [&split.train, &split.heldout],
        &selection,
        diagnosis,
        decision,
    );
    Ok(Outcome {
        report,
        heldout: split.heldout.clone(),
        baseline: selection.baseline,
        final_model: selection.final_model,
        excess_before,
        excess_after,
    })
}

/// Fits candidates on the training windows and scores them on the held-out ones.
struct Fitter<'a> {
    split: &'a Split,
    options: &'a Sim2RealOptions,
    train: Vec<WindowBatch>,
    heldout: Vec<WindowBatch>,
    short: Vec<WindowBatch>,
    plain: Device,
    autodiff: Device,
}

impl<'a> Fitter<'a> {
    fn new(split: &'a Split, options: &'a Sim2RealOptions) -> Result<Self> {
        let plain = Backend::NdArray.device(false)?;
        Ok(Self {
            split,
            options,
            train: batches(&split.train, &plain),
            heldout: batches(&split.heldout, &plain),
            short: batches(&split.short, &plain),
            autodiff: Backend::NdArray.device(true)?,
            plain,
        })
    }

    /// The held-out errors of a fitted (or unfitted) model.
    fn score(&self, fit: Fit) -> Evaluated {
        let errors = evaluate(&fit, &self.heldout, self.split.heldout.len(), &self.plain);
        Evaluated { fit, errors }
    }

    /// Fits `candidate` by gradient descent and scores it.
    fn fit_and_score(&self, candidate: &Candidate) -> Evaluated {
        self.score(fit(
            candidate,
            &self.train,
            &self.autodiff,
            &self.options.fit,
        ))
    }

    /// [`Self::fit_and_score`] with the standard errors of its parameters, for the report.
    fn fit_with_errors(&self, candidate: &Candidate) -> Evaluated {
        let mut out = self.fit_and_score(candidate);
        self.add_standard_errors(&mut out);
        out
    }

    fn add_standard_errors(&self, evaluated: &mut Evaluated) {
        standard_errors(
            &mut evaluated.fit,
            &self.train,
            &self.split.train,
            &self.plain,
        );
    }

    /// Paired held-out comparison of `new` against `reference` under the parsimony rule.
    fn compare(&self, new: &Evaluated, reference: &Evaluated) -> Comparison {
        Comparison::paired(
            &self.split.heldout,
            &reference.errors,
            &new.errors,
            self.options,
        )
    }
}

/// The models that model selection fitted and what it chose.
pub struct Selection {
    /// The nominal bicycle with the declared wheelbase.
    pub baseline: Evaluated,
    /// The nominal bicycle with the wheelbase fitted.
    pub refit: Evaluated,
    /// The catalogue effects tried (those identifiable from these recordings).
    pub tried: Vec<Effect>,
    /// One fit per tried effect, in `tried` order.
    pub singles: Vec<Evaluated>,
    /// Indices into `singles`, best held-out error first, each against the reference.
    pub ranked: Vec<(usize, Comparison)>,
    /// The sparse regression's equations, and their fit when they were allowed to compete.
    pub discovery: Discovery,
    pub discovered: Option<(Evaluated, Comparison)>,
    /// The findings in the order they were kept, each against the model before it.
    pub chosen: Vec<(Evaluated, Comparison)>,
    /// The last finding, or the reference nominal model when nothing was kept.
    pub final_model: Evaluated,
}

/// Baseline, nominal refit, one fit per catalogue effect, the discovered equation, and the
/// findings kept under the parsimony rule.
fn select(fitter: &Fitter, recordings: &Recordings, progress: &(dyn Fn(&str) + Sync)) -> Selection {
    let options = fitter.options;
    let nominal = |fit_wheelbase| Candidate {
        fit_wheelbase,
        ..Candidate::with_effects(Vec::new())
    };
    progress("baseline: nominal bicycle, declared wheelbase");
    let baseline = fitter.score(Fit::unfitted(nominal(false)));
    progress("nominal refit: wheelbase by gradient descent");
    let refit = fitter.fit_with_errors(&nominal(true));
    // Every finding must beat the better of the declared and the refitted nominal model, so
    // none makes held-out error worse than the declared model's (a refit can lose to it when
    // gradient descent is cut short, e.g. `--iterations 1`).
    let held_out_rmse = |e: &Evaluated| ChannelRms::of(e.errors.iter().flatten()).pos_m;
    let reference = if held_out_rmse(&refit) <= held_out_rmse(&baseline) {
        &refit
    } else {
        &baseline
    };

    let tried: Vec<Effect> = options
        .effects
        .iter()
        .copied()
        .filter(|e| !(options.commands_inferred && e.acts_on_commands()))
        .collect();
    progress(&format!("fitting {} candidate effects", tried.len()));
    let singles: Vec<Evaluated> = tried
        .par_iter()
        .map(|&e| {
            let out = fitter.fit_with_errors(&Candidate::with_effects(vec![e]));
            progress(&format!("  fitted {e}"));
            out
        })
        .collect();
    let mut ranked: Vec<(usize, Comparison)> = singles
        .iter()
        .enumerate()
        .map(|(k, s)| (k, fitter.compare(s, reference)))
        .collect();
    ranked.sort_by(|a, b| a.1.rmse_after_m.total_cmp(&b.1.rmse_after_m));

    progress("discovery: sparse regression of the derivative residuals on the library");
    let discovery = discover(
        recordings,
        &fitter.split.train_tracks,
        &fitter.split.heldout_tracks,
        options.default_wheelbase_m,
        refit.fit.values[0],
        options.commands_inferred,
    );
    let discovered = (options.discover && !discovery.terms().is_empty()).then(|| {
        let out = fitter.fit_with_errors(&Candidate {
            discovered: discovery.terms(),
            wheelbase_start: discovery.wheelbase_scale,
            ..Candidate::with_effects(Vec::new())
        });
        let comparison = fitter.compare(&out, reference);
        (out, comparison)
    });

    let chosen = choose(fitter, &singles, &ranked, &discovery, &discovered, progress);
    let final_model = match chosen.last() {
        Some((e, _)) => e.clone(),
        None => reference.clone(),
    };
    Selection {
        baseline,
        refit,
        tried,
        singles,
        ranked,
        discovery,
        discovered,
        chosen,
        final_model,
    }
}

/// The findings to keep: the best significant catalogue effect, unless a discovered equation
/// beats it by the same parsimony rule (named hypotheses win ties); then the best significant
/// pair of it with a runner-up effect or with the discovered terms.
fn choose(
    fitter: &Fitter,
    singles: &[Evaluated],
    ranked: &[(usize, Comparison)],
    discovery: &Discovery,
    discovered: &Option<(Evaluated, Comparison)>,
    progress: &(dyn Fn(&str) + Sync),
) -> Vec<(Evaluated, Comparison)> {
    let best_single = ranked
        .first()
        .filter(|(_, c)| c.significant)
        .map(|(k, c)| (&singles[*k], c.clone()));
    let first = match (best_single, discovered) {
        (Some((single, c)), Some((found, _))) if !fitter.compare(found, single).significant => {
            Some((single, c))
        }
        (_, Some((found, c))) if c.significant => Some((found, c.clone())),
        (Some((single, c)), _) => Some((single, c)),
        _ => None,
    };
    let Some((first, comparison)) = first else {
        return Vec::new();
    };
    let base = first.fit.candidate.clone();
    // Pairs: the first with each runner-up effect that helped on its own, and with the
    // discovered terms.
    let mut partners: Vec<Candidate> = ranked
        .iter()
        .filter(|(_, c)| c.significant)
        .map(|(k, _)| singles[*k].fit.candidate.effects[0])
        .filter(|e| !base.effects.contains(e))
        .take(2)
        .map(|e| Candidate {
            effects: [base.effects.clone(), vec![e]].concat(),
            ..base.clone()
        })
        .collect();
    if base.discovered.is_empty() && discovered.is_some() {
        partners.push(Candidate {
            discovered: discovery.terms(),
            wheelbase_start: first.fit.values[0],
            ..base.clone()
        });
    }
    if !partners.is_empty() {
        progress(&format!("{} helps; trying it in pairs", base.label()));
    }
    let best_pair = partners
        .par_iter()
        .map(|c| fitter.fit_and_score(c))
        .collect::<Vec<_>>()
        .into_iter()
        .map(|p| {
            let c = fitter.compare(&p, first);
            (p, c)
        })
        .filter(|(_, c)| c.significant)
        .min_by(|a, b| a.1.rmse_after_m.total_cmp(&b.1.rmse_after_m));
    let mut chosen = vec![(first.clone(), comparison)];
    if let Some((mut pair, c)) = best_pair {
        fitter.add_standard_errors(&mut pair);
        chosen.push((pair, c));
    }
    chosen
}
