//! Open-ended discovery (SINDy): what the catalogue lacks, found as a sparse equation.
//!
//! At every sample of a track where no command jumps within the denoising span, local
//! quadratic fits give the speed, its rate and the yaw rate. Their residuals against the
//! nominal bicycle (`dv/dt - u`, `dtheta/dt - v tan(phi) / L`) are regressed on the library
//! of [`crate::sim::library`] by sequentially thresholded least squares (Brunton et al.,
//! PNAS 2016). The threshold is chosen on held-out tracks: the sparsest selection whose
//! held-out error is within 2 % of the best. The selection then becomes a simulator term
//! whose coefficients are refitted through the rollout ([`super::identify`]).

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::windows::{DENOISE_HALF_WIDTH_S, command_changed, quadratic_at_zero, unwrap};
use crate::data::Recordings;
use crate::sim::library::{Equation, Feature};

/// Samples slower than this (m/s) are left out: at rest the derivatives carry no physics
/// beyond the standstill the simulator already has.
const MIN_SPEED_M_S: f64 = 1.0;

/// Thresholds tried, as a share of the residual's RMS: a term is kept only if its typical
/// contribution is at least this large.
const THRESHOLDS: [f64; 8] = [0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5];

/// Regression needs at least this many training samples per library column.
const MIN_SAMPLES_PER_TERM: usize = 20;

/// A selection must cut the held-out residual's mean square by this share to count.
const MIN_GAIN: f64 = 0.05;

/// One sample's regression data.
#[derive(Debug, Clone, Copy)]
struct Sample {
    track: usize,
    v: f64,
    u: f64,
    phi: f64,
    /// dv/dt - u.
    speed_residual: f64,
    /// dtheta/dt - v tan(phi) / L.
    heading_residual: f64,
}

/// What was selected for one equation.
#[derive(Debug, Clone, Serialize)]
pub struct EquationFit {
    pub equation: Equation,
    /// Selected features and their least-squares coefficients.
    pub terms: Vec<(Feature, f64)>,
    /// Threshold chosen (share of the residual's RMS).
    pub threshold: f64,
    /// Held-out mean square of the residual before and after the selection.
    pub heldout_ms_before: f64,
    pub heldout_ms_after: f64,
    pub training_samples: usize,
    pub heldout_samples: usize,
}

/// Sparse regressions of both equations.
#[derive(Debug, Clone, Serialize)]
pub struct Discovery {
    pub equations: Vec<EquationFit>,
    /// The wheelbase scale the heading regression implies. Its `v tan(phi)` column (always
    /// kept, never a discovered term) absorbs what the refitted wheelbase got wrong while
    /// the missing physics was unmodelled; the rollout refit starts from this value.
    pub wheelbase_scale: f64,
}

impl Discovery {
    /// Every selected (equation, feature, coefficient).
    pub fn terms(&self) -> Vec<(Equation, Feature, f64)> {
        self.equations
            .iter()
            .flat_map(|e| e.terms.iter().map(|&(f, c)| (e.equation, f, c)))
            .collect()
    }
}

/// Runs the regression on `train` tracks and chooses sparsity on `heldout` tracks; the
/// nominal model's wheelbase is each track's declared one times `wheelbase_scale`. With
/// `commands_inferred`, terms in the commands are left out of the library: whatever the
/// actuators did is already in commands inferred from the motion.
pub fn discover(
    recordings: &Recordings,
    train: &[usize],
    heldout: &[usize],
    default_wheelbase: f64,
    wheelbase_scale: f64,
    commands_inferred: bool,
) -> Discovery {
    let all: Vec<usize> = train.iter().chain(heldout).copied().collect();
    let samples = samples(recordings, &all, default_wheelbase, wheelbase_scale);
    let (fit_set, check_set): (Vec<Sample>, Vec<Sample>) =
        samples.into_iter().partition(|s| train.contains(&s.track));
    let library = |equation| -> Vec<Feature> {
        Feature::library(equation)
            .iter()
            .copied()
            .filter(|f| !(commands_inferred && f.involves_commands()))
            .collect()
    };
    let with_limits = |equation| -> Vec<Feature> {
        let mut features = library(equation);
        if !commands_inferred {
            let limits: Vec<Feature> = Feature::limit_grids(equation)
                .iter()
                .filter_map(|grid| best_limit(equation, &features, grid, &fit_set))
                .collect();
            features.extend(limits);
        }
        features
    };
    let (speed, _) = select(
        Equation::Speed,
        &with_limits(Equation::Speed),
        &fit_set,
        &check_set,
    );
    let (heading, kappa) = select(
        Equation::HeadingRate,
        &with_limits(Equation::HeadingRate),
        &fit_set,
        &check_set,
    );
    // dtheta/dt = v tan(phi) (1 / L + c): the wheelbase becomes L / (1 + c L).
    let wheelbase = default_wheelbase * wheelbase_scale;
    Discovery {
        equations: vec![speed, heading],
        wheelbase_scale: wheelbase_scale / (1.0 + kappa * wheelbase).max(0.5),
    }
}

fn samples(
    recordings: &Recordings,
    tracks: &[usize],
    default_wheelbase: f64,
    wheelbase_scale: f64,
) -> Vec<Sample> {
    let mut out = Vec::new();
    for &index in tracks {
        let track = &recordings.tracks[index];
        let half = ((DENOISE_HALF_WIDTH_S / track.period).round() as usize).max(2);
        if track.len() < 2 * half + 1 {
            continue;
        }
        let wheelbase = track.wheelbase.unwrap_or(default_wheelbase) * wheelbase_scale;
        let heading = unwrap(&track.heading);
        for k in half..track.len() - half {
            if (k + 1 - half..=k + half).any(|j| command_changed(track, j)) {
                continue;
            }
            let span = k - half..k + half + 1;
            let times: Vec<f64> = track.t[span.clone()]
                .iter()
                .map(|t| t - track.t[k])
                .collect();
            let speed = quadratic_at_zero(&times, &track.speed[span.clone()]);
            if speed.value < MIN_SPEED_M_S {
                continue;
            }
            let yaw = quadratic_at_zero(&times, &heading[span]);
            let (u, phi) = (track.accel_cmd[k], track.steer_cmd[k]);
            out.push(Sample {
                track: index,
                v: speed.value,
                u,
                phi,
                speed_residual: speed.slope - u,
                heading_residual: yaw.slope - speed.value * phi.tan() / wheelbase,
            });
        }
    }
    out
}

/// The limit of `grid`'s kind (one of [`Feature::limit_grids`]) whose column, beside
/// `library`'s, fits `equation`'s residual on `train` best by least squares; none when no
/// limit tried is exceeded by enough samples to estimate it. A limit enters its term
/// non-linearly, so it is found here by a search (the grid, then a golden-section refinement
/// between the best point's neighbours: a limit off by part of a grid step would leave a
/// residual that small spurious terms then absorb) and the selection then treats the column
/// like any other.
fn best_limit(
    equation: Equation,
    library: &[Feature],
    grid: &[Feature],
    train: &[Sample],
) -> Option<Feature> {
    let (x, y) = design(equation, library, train);
    let misfit = |limit: Feature| -> Option<f64> {
        let column: Vec<f64> = train.iter().map(|s| limit.value(s.v, s.u, s.phi)).collect();
        if column.iter().filter(|c| **c != 0.0).count() < MIN_SAMPLES_PER_TERM {
            return None;
        }
        let mut with = x.clone().insert_column(x.ncols(), 0.0);
        with.set_column(x.ncols(), &DVector::from_vec(column));
        let coef = stlsq(&with, &y, 0.0, 0);
        Some((&y - &with * DVector::from_vec(coef)).norm_squared())
    };
    let (best, _) = grid
        .iter()
        .enumerate()
        .filter_map(|(k, &limit)| Some((k, misfit(limit)?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let value = |k: usize| grid[k].limit().map_or(f64::NAN, |(_, _, v)| v);
    let (low, high) = (
        value(best.saturating_sub(1)),
        value((best + 1).min(grid.len() - 1)),
    );
    let at = |v: f64| grid[best].with_limit(v);
    let refined = golden_section(low, high, |v| misfit(at(v)).unwrap_or(f64::INFINITY));
    Some(at(refined))
}

/// The minimum of `f` on [low, high] by golden-section search (f unimodal there), to a
/// relative width of 1e-4.
fn golden_section(mut low: f64, mut high: f64, f: impl Fn(f64) -> f64) -> f64 {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (high - ratio * (high - low), low + ratio * (high - low));
    let (mut fa, mut fb) = (f(a), f(b));
    while high - low > 1e-4 * high.abs().max(1e-9) {
        if fa <= fb {
            high = b;
            (b, fb) = (a, fa);
            a = high - ratio * (high - low);
            fa = f(a);
        } else {
            low = a;
            (a, fa) = (b, fb);
            b = low + ratio * (high - low);
            fb = f(b);
        }
    }
    (low + high) / 2.0
}

/// Nuisance columns ahead of the library: the heading equation's `v tan(phi)` (a wheelbase
/// correction, see [`Discovery::wheelbase_scale`]).
fn nuisance(equation: Equation) -> usize {
    match equation {
        Equation::Speed => 0,
        Equation::HeadingRate => 1,
    }
}

fn design(
    equation: Equation,
    library: &[Feature],
    samples: &[Sample],
) -> (DMatrix<f64>, DVector<f64>) {
    let extra = nuisance(equation);
    let x = DMatrix::from_fn(samples.len(), extra + library.len(), |r, c| {
        let s = &samples[r];
        match c.checked_sub(extra) {
            Some(c) => library[c].value(s.v, s.u, s.phi),
            None => s.v * s.phi.tan(),
        }
    });
    let y = DVector::from_iterator(
        samples.len(),
        samples.iter().map(|s| match equation {
            Equation::Speed => s.speed_residual,
            Equation::HeadingRate => s.heading_residual,
        }),
    );
    (x, y)
}

/// The equation's selection, and the nuisance coefficient (0 for the speed equation).
fn select(
    equation: Equation,
    library: &[Feature],
    train: &[Sample],
    heldout: &[Sample],
) -> (EquationFit, f64) {
    if train.len() < MIN_SAMPLES_PER_TERM * (library.len() + 1) || heldout.is_empty() {
        // Too few samples (slow or short tracks, commands changing all the time) to select
        // anything from.
        let fit = EquationFit {
            equation,
            terms: Vec::new(),
            threshold: f64::NAN,
            heldout_ms_before: f64::NAN,
            heldout_ms_after: f64::NAN,
            training_samples: train.len(),
            heldout_samples: heldout.len(),
        };
        return (fit, 0.0);
    }
    let (x, y) = design(equation, library, train);
    let (xh, yh) = design(equation, library, heldout);
    let ms = |r: DVector<f64>| r.norm_squared() / r.len().max(1) as f64;
    let extra = nuisance(equation);
    // The baseline: nuisance columns only.
    let base = stlsq(&x.columns(0, extra).into_owned(), &y, 0.0, extra);
    let before = ms(&yh - xh.columns(0, extra) * DVector::from_column_slice(&base));
    let mut best: Option<(f64, Vec<f64>, f64)> = None;
    let mut candidates = Vec::new();
    for &threshold in &THRESHOLDS {
        let coef = stlsq(&x, &y, threshold, extra);
        let after = ms(&yh - &xh * DVector::from_column_slice(&coef));
        if best.as_ref().is_none_or(|b| after < b.0) {
            best = Some((after, coef.clone(), threshold));
        }
        candidates.push((threshold, coef, after));
    }
    let empty = EquationFit {
        equation,
        terms: Vec::new(),
        threshold: f64::NAN,
        heldout_ms_before: before,
        heldout_ms_after: before,
        training_samples: train.len(),
        heldout_samples: heldout.len(),
    };
    let base_nuisance = base.first().copied().unwrap_or(0.0);
    let Some((best_ms, _, _)) = best else {
        return (empty, base_nuisance);
    };
    // The sparsest selection within 2 % of the best held-out error (thresholds ascend).
    let Some((threshold, coef, after)) = candidates
        .into_iter()
        .rev()
        .find(|(_, _, after)| *after <= best_ms * 1.02)
    else {
        return (empty, base_nuisance);
    };
    let (nuisance_coef, coef) = coef.split_at(extra);
    if after > before * (1.0 - MIN_GAIN) || coef.iter().all(|&c| c == 0.0) {
        return (empty, base_nuisance);
    }
    let fit = EquationFit {
        terms: library
            .iter()
            .zip(coef)
            .filter(|(_, c)| **c != 0.0)
            .map(|(&f, &c)| (f, c))
            .collect(),
        threshold,
        heldout_ms_after: after,
        ..empty
    };
    (fit, nuisance_coef.first().copied().unwrap_or(0.0))
}

/// Sequentially thresholded least squares on columns scaled to unit RMS: terms whose typical
/// contribution falls below `threshold` x RMS(y) are dropped and the rest refitted, until
/// the selection stops changing; the first `keep` columns are never dropped. Coefficients
/// are returned in the original units.
fn stlsq(x: &DMatrix<f64>, y: &DVector<f64>, threshold: f64, keep: usize) -> Vec<f64> {
    let n = x.nrows().max(1) as f64;
    let scale: Vec<f64> = (0..x.ncols())
        .map(|c| (x.column(c).norm_squared() / n).sqrt().max(1e-12))
        .collect();
    let cut = threshold * (y.norm_squared() / n).sqrt();
    let mut active: Vec<usize> = (0..x.ncols()).collect();
    let mut coef = vec![0.0; x.ncols()];
    for _ in 0..10 {
        if active.is_empty() {
            break;
        }
        let z = DMatrix::from_fn(x.nrows(), active.len(), |r, c| {
            x[(r, active[c])] / scale[active[c]]
        });
        let Ok(beta) = z.clone().svd(true, true).solve(y, 1e-10) else {
            break;
        };
        coef = vec![0.0; x.ncols()];
        for (k, &c) in active.iter().enumerate() {
            coef[c] = beta[k] / scale[c];
        }
        let kept: Vec<usize> = active
            .iter()
            .enumerate()
            .filter(|(k, c)| **c < keep || beta[*k].abs() >= cut)
            .map(|(_, &c)| c)
            .collect();
        if kept.len() == active.len() {
            break;
        }
        for (c, value) in coef.iter_mut().enumerate() {
            if !kept.contains(&c) {
                *value = 0.0;
            }
        }
        active = kept;
    }
    coef
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 400 samples over varied v and u on 4 tracks, with `residual(v, u, i)` as the speed
    /// residual; the speed equation selected with track 3 held out.
    fn select_speed(residual: impl Fn(f64, f64, usize) -> f64) -> EquationFit {
        let (train, heldout) = speed_samples(residual);
        let library = Feature::library(Equation::Speed);
        select(Equation::Speed, library, &train, &heldout).0
    }

    /// [`select_speed`] with each kind's best limit added to the library, as [`discover`] does.
    fn select_speed_with_limit(residual: impl Fn(f64, f64, usize) -> f64) -> EquationFit {
        let (train, heldout) = speed_samples(residual);
        select_with_limits(Equation::Speed, &train, &heldout)
    }

    fn select_with_limits(equation: Equation, train: &[Sample], heldout: &[Sample]) -> EquationFit {
        let mut library = Feature::library(equation).to_vec();
        let limits: Vec<Feature> = Feature::limit_grids(equation)
            .iter()
            .filter_map(|grid| best_limit(equation, &library, grid, train))
            .collect();
        library.extend(limits);
        select(equation, &library, train, heldout).0
    }

    /// 400 samples over varied v and phi on 4 tracks (wheelbase 2.8 m), with
    /// `residual(v, phi, i)` as the heading-rate residual; selected with track 3 held out.
    fn select_heading(residual: impl Fn(f64, f64, usize) -> f64) -> EquationFit {
        let (train, heldout): (Vec<Sample>, Vec<Sample>) = (0..400)
            .map(|i| {
                let v = 2.0 + (i % 37) as f64;
                let phi = ((i * 7919) % 101) as f64 / 101.0 * 0.12 - 0.06;
                Sample {
                    track: i % 4,
                    v,
                    u: 0.0,
                    phi,
                    speed_residual: 0.0,
                    heading_residual: residual(v, phi, i),
                }
            })
            .partition(|s| s.track != 3);
        select_with_limits(Equation::HeadingRate, &train, &heldout)
    }

    /// The one term of `fit`, or a failure naming what was selected.
    fn single_term(fit: &EquationFit) -> (Feature, f64) {
        match fit.terms[..] {
            [term] => term,
            _ => panic!("one term expected: {fit:?}"),
        }
    }

    /// The training and held-out samples of [`select_speed`].
    fn speed_samples(residual: impl Fn(f64, f64, usize) -> f64) -> (Vec<Sample>, Vec<Sample>) {
        let samples: Vec<Sample> = (0..400)
            .map(|i| {
                let v = 2.0 + (i % 37) as f64;
                let u = ((i * 7919) % 101) as f64 / 101.0 * 6.0 - 3.5;
                Sample {
                    track: i % 4,
                    v,
                    u,
                    phi: 0.0,
                    speed_residual: residual(v, u, i),
                    heading_residual: 0.0,
                }
            })
            .collect();
        samples.into_iter().partition(|s| s.track != 3)
    }

    /// Deterministic noise in [-0.5, 0.5) x `scale`, independent across samples (a hash of `i`).
    fn noise(i: usize, scale: f64) -> f64 {
        let mut state = i as u64;
        crate::test_rng::uniform(&mut state, -0.5, 0.5) * scale
    }

    #[test]
    fn stlsq_keeps_the_true_terms_and_drops_the_rest() {
        let fit = select_speed(|v, u, i| 0.3 * u.min(0.0) - 0.0005 * v * v + noise(i, 0.02));
        let terms: Vec<Feature> = fit.terms.iter().map(|t| t.0).collect();
        assert_eq!(terms, vec![Feature::V2, Feature::UBrake], "{fit:?}");
        assert!((fit.terms[1].1 - 0.3).abs() < 0.01, "{fit:?}");
        assert!((fit.terms[0].1 + 0.0005).abs() < 5e-5, "{fit:?}");
    }

    #[test]
    fn pure_noise_selects_nothing() {
        // Twenty noise draws: the limits' searches fit each draw's noise as well as they can,
        // and the held-out rule must still keep nothing.
        for draw in 0..20 {
            let at = |i: usize| i + 400 * draw;
            let fit = select_speed(|_, _, i| noise(at(i), 0.2));
            assert!(fit.terms.is_empty(), "draw {draw}: {fit:?}");
            let fit = select_speed_with_limit(|_, _, i| noise(at(i), 0.2));
            assert!(fit.terms.is_empty(), "draw {draw}: {fit:?}");
            let fit = select_heading(|_, _, i| noise(at(i), 0.002));
            assert!(fit.terms.is_empty(), "draw {draw}: {fit:?}");
        }
    }

    /// An acceleration capped at 20 / v: the limit is found within the grid's 5 % step and
    /// selected alone, with the cap's coefficient -1.
    #[test]
    fn a_power_limit_is_found_with_its_limit_and_selected_alone() {
        let fit = select_speed_with_limit(|v, u, i| -(u - 20.0 / v).max(0.0) + noise(i, 0.02));
        let (feature, coefficient) = single_term(&fit);
        let Feature::PowerLimit {
            specific_power_w_kg,
        } = feature
        else {
            panic!("{feature:?}");
        };
        assert!((specific_power_w_kg / 20.0 - 1.0).abs() <= 0.05, "{fit:?}");
        assert!((coefficient + 1.0).abs() <= 0.1, "{fit:?}");
    }

    /// Throttle capped at 1.5 m/s^2 and braking at 2.5: each saturation is found with its
    /// limit and selected alone, with coefficient -1.
    #[test]
    fn command_saturations_are_found_with_their_limits() {
        let fit = select_speed_with_limit(|_, u, i| -(u - 1.5).max(0.0) + noise(i, 0.02));
        let (Feature::AccelLimit { accel_m_s2 }, coefficient) = single_term(&fit) else {
            panic!("a throttle cap expected: {fit:?}");
        };
        assert!((accel_m_s2 / 1.5 - 1.0).abs() <= 0.05, "{fit:?}");
        assert!((coefficient + 1.0).abs() <= 0.1, "{fit:?}");

        let fit = select_speed_with_limit(|_, u, i| -(u + 2.5).min(0.0) + noise(i, 0.02));
        let (Feature::BrakeLimit { decel_m_s2 }, coefficient) = single_term(&fit) else {
            panic!("a brake cap expected: {fit:?}");
        };
        assert!((decel_m_s2 / 2.5 - 1.0).abs() <= 0.05, "{fit:?}");
        assert!((coefficient + 1.0).abs() <= 0.1, "{fit:?}");
    }

    /// A steering command biased by 0.01 rad (yaw rate v tan(phi + 0.01) / L) is a term in v;
    /// road wheels that stop at 0.03 rad are a steering limit there, with coefficient -1 / L.
    #[test]
    fn a_steering_bias_and_a_steering_stop_are_told_apart() {
        let wheelbase = 2.8;
        let fit = select_heading(|v, phi, i| {
            v * ((phi + 0.01).tan() - phi.tan()) / wheelbase + noise(i, 0.002)
        });
        let (feature, coefficient) = single_term(&fit);
        assert_eq!(feature, Feature::V, "{fit:?}");
        assert!(
            (coefficient * wheelbase / 0.01 - 1.0).abs() < 0.05,
            "{fit:?}"
        );

        let fit = select_heading(|v, phi, i| {
            v * (phi.clamp(-0.03, 0.03).tan() - phi.tan()) / wheelbase + noise(i, 0.002)
        });
        let (Feature::SteerLimit { angle_rad }, coefficient) = single_term(&fit) else {
            panic!("a steering stop expected: {fit:?}");
        };
        assert!((angle_rad / 0.03 - 1.0).abs() <= 0.05, "{fit:?}");
        assert!((coefficient * wheelbase + 1.0).abs() < 0.1, "{fit:?}");
    }

    #[test]
    fn too_few_samples_select_nothing_without_failing() {
        let fit = select(
            Equation::HeadingRate,
            Feature::library(Equation::HeadingRate),
            &[],
            &[],
        )
        .0;
        assert!(fit.terms.is_empty() && fit.training_samples == 0, "{fit:?}");
    }
}
