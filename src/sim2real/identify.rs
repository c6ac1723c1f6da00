//! The identification pipeline: baseline, nominal refit, one fit per catalogue effect,
//! selection on held-out tracks with a parsimony rule, pairs when one effect is not enough.

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::discover::discover;
use super::fit::{Fit, FitOptions, evaluate, fit, standard_errors};
use super::locate::{ChannelRms, Mismatch, locate};
use super::noise::NoiseLevels;
use super::report::{Comparison, DiscoveredCandidate, Report};
use super::simulate::{Candidate, StepError, batches};
use super::unexplained::{RegimeExcess, Unexplained, regime_excess};
use super::windows::{Starts, Window, windows};
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
    /// ... and the per-track paired improvement has at least this t statistic.
    pub min_t_stat: f64,
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
            effects: Effect::ALL.to_vec(),
            default_wheelbase_m: 2.8,
            commands_inferred: false,
            discover: true,
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
pub struct Evaluated {
    pub fit: Fit,
    pub errors: Vec<Vec<StepError>>,
}

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
        return Ok(());
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
    let plain = Backend::NdArray.device(false)?;
    let autodiff = Backend::NdArray.device(true)?;
    let recordings = &at_most_100_hz(recordings);
    let split = split(recordings, options)?;
    let (train_b, held_b, short_b) = (
        batches(&split.train, &plain),
        batches(&split.heldout, &plain),
        batches(&split.short, &plain),
    );
    let heldout_errors = |f: &Fit| evaluate(f, &held_b, split.heldout.len(), &plain);
    let nominal = |fit_wheelbase| Candidate {
        fit_wheelbase,
        ..Candidate::with_effects(Vec::new())
    };
    let fit_one = |candidate: &Candidate| -> Evaluated {
        let fitted = fit(candidate, &train_b, &autodiff, &options.fit);
        let errors = heldout_errors(&fitted);
        Evaluated {
            fit: fitted,
            errors,
        }
    };

    progress("baseline: nominal bicycle, declared wheelbase");
    let baseline_fit = Fit::unfitted(nominal(false));
    let baseline = Evaluated {
        errors: heldout_errors(&baseline_fit),
        fit: baseline_fit,
    };
    progress("nominal refit: wheelbase by gradient descent");
    let mut refit = fit_one(&nominal(true));
    standard_errors(&mut refit.fit, &train_b, &split.train, &plain);
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
            let mut out = fit_one(&Candidate::with_effects(vec![e]));
            standard_errors(&mut out.fit, &train_b, &split.train, &plain);
            progress(&format!("  fitted {e}"));
            out
        })
        .collect();
    let compare = |new: &Evaluated, reference: &Evaluated| {
        Comparison::paired(&split.heldout, &reference.errors, &new.errors, options)
    };
    let mut ranked: Vec<(usize, Comparison)> = singles
        .iter()
        .enumerate()
        .map(|(k, s)| (k, compare(s, reference)))
        .collect();
    ranked.sort_by(|a, b| a.1.rmse_after_m.total_cmp(&b.1.rmse_after_m));

    progress("discovery: sparse regression of the derivative residuals on the library");
    let discovery = discover(
        recordings,
        &split.train_tracks,
        &split.heldout_tracks,
        options.default_wheelbase_m,
        refit.fit.values[0],
        options.commands_inferred,
    );
    let discovered = (options.discover && !discovery.terms().is_empty()).then(|| {
        let mut out = fit_one(&Candidate {
            discovered: discovery.terms(),
            wheelbase_start: discovery.wheelbase_scale,
            ..Candidate::with_effects(Vec::new())
        });
        standard_errors(&mut out.fit, &train_b, &split.train, &plain);
        let comparison = compare(&out, reference);
        (out, comparison)
    });

    // The first finding: the best significant catalogue effect, unless a discovered equation
    // beats it by the same parsimony rule (named hypotheses win ties).
    let best_single = ranked
        .first()
        .filter(|(_, c)| c.significant)
        .map(|(k, c)| (&singles[*k], c.clone()));
    let first = match (best_single, &discovered) {
        (Some((single, c)), Some((found, _))) if !compare(found, single).significant => {
            Some((single, c))
        }
        (_, Some((found, c))) if c.significant => Some((found, c.clone())),
        (Some((single, c)), _) => Some((single, c)),
        _ => None,
    };
    let mut chosen: Vec<(Evaluated, Comparison)> = Vec::new();
    if let Some((first, comparison)) = first {
        let first = Evaluated {
            fit: first.fit.clone(),
            errors: first.errors.clone(),
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
        let pairs: Vec<Evaluated> = partners.par_iter().map(fit_one).collect();
        let best_pair = pairs
            .into_iter()
            .map(|p| {
                let c = compare(&p, &first);
                (p, c)
            })
            .filter(|(_, c)| c.significant)
            .min_by(|a, b| a.1.rmse_after_m.total_cmp(&b.1.rmse_after_m));
        chosen.push((first, comparison));
        if let Some((mut pair, c)) = best_pair {
            standard_errors(&mut pair.fit, &train_b, &split.train, &plain);
            chosen.push((pair, c));
        }
    }

    progress("locating the mismatch");
    let short_errors = |f: &Fit| evaluate(f, &short_b, split.short.len(), &plain);
    let period = split.heldout[0].period;
    let baseline_short = short_errors(&baseline.fit);
    let before: Mismatch = locate(
        recordings,
        &baseline.errors,
        period,
        &split.short,
        &baseline_short,
    );
    let final_model = match chosen.last() {
        Some((e, _)) => Evaluated {
            fit: e.fit.clone(),
            errors: e.errors.clone(),
        },
        None => Evaluated {
            fit: reference.fit.clone(),
            errors: reference.errors.clone(),
        },
    };
    let final_short = short_errors(&final_model.fit);
    let after = locate(
        recordings,
        &final_model.errors,
        period,
        &split.short,
        &final_short,
    );
    let noise = NoiseLevels::estimate(&[split.train.as_slice(), &split.heldout].concat());
    let excess_before = regime_excess(recordings, &noise, &split.short, &baseline_short);
    let excess_after = regime_excess(recordings, &noise, &split.short, &final_short);
    let unexplained = Unexplained::assess(
        recordings,
        noise,
        &split.heldout,
        &final_model.errors,
        &split.short,
        &final_short,
    );
    let report = Report::new(
        recordings,
        options,
        &split.train,
        &split.heldout,
        &baseline,
        &refit,
        &singles,
        &ranked,
        &chosen,
        &final_model,
        tried,
        before,
        after,
        unexplained,
        discovery,
        discovered
            .as_ref()
            .map(|(e, c)| DiscoveredCandidate::new(e, c)),
    );
    Ok(Outcome {
        report,
        heldout: split.heldout,
        baseline,
        final_model,
        excess_before,
        excess_after,
    })
}
