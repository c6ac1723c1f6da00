//! Sim-to-real, proven blind on concealed effects: recordings come from a plant with one
//! hidden catalogue effect under sensor noise, and the tool must name it first, fit its
//! parameter within 10 %, and cut held-out 5 s position error; with no effect it must report
//! nothing and sit at the noise floor, and a wrong declared wheelbase must be fitted, not
//! reported as understeer. The generated drives stop, crawl and start at rest. Physics outside
//! the catalogue must be flagged as unexplained, then named as an equation by discovery.

use burn::prelude::*;
use rtr::sim::catalogue::{DynamicsFile, Effect};
use rtr::sim::library::Feature;
use rtr::sim2real::fit::Fit;
use rtr::sim2real::generator::typical;
use rtr::sim2real::simulate::{Candidate, batches};
use rtr::sim2real::windows::{Starts, windows};
use rtr::sim2real::{GeneratorConfig, Report, Sim2RealOptions, Uncatalogued, generate, identify};

fn device() -> Device {
    rtr::backend::Backend::reference_device(false)
}

fn run_blind(config: &GeneratorConfig) -> Report {
    let recordings = generate(config, &device());
    identify(&recordings, &Sim2RealOptions::default(), &|_| {})
        .expect("identification runs")
        .report
}

/// The effect is named first, each parameter is within 10 % of the truth, and held-out
/// error falls by at least `min_drop_pct` from the baseline.
fn names_and_fits(effect: Effect, min_drop_pct: f64) {
    names_and_fits_at(effect, typical(effect), min_drop_pct);
}

/// [`names_and_fits`] with the effect's parameters at `truths`.
fn names_and_fits_at(effect: Effect, truths: Vec<f64>, min_drop_pct: f64) {
    let mut config = GeneratorConfig::with_effect(Some(effect), 7);
    config.effect = Some((effect, truths.clone()));
    let report = run_blind(&config);
    let summary = report.summary().join("\n");
    let first = report
        .findings
        .first()
        .unwrap_or_else(|| panic!("nothing found:\n{summary}"));
    assert_eq!(first.effect, Some(effect), "{summary}");
    for (spec, truth) in effect.params().iter().zip(truths) {
        let fitted = report.final_model.terms[0].params[spec.name];
        assert!(
            (fitted - truth).abs() <= 0.1 * truth,
            "{effect}.{} = {fitted}, truth {truth}\n{summary}",
            spec.name
        );
    }
    assert!(
        report.final_model.improvement_vs_baseline_pct >= min_drop_pct,
        "{summary}"
    );
    // Significant on held-out tracks, by the parsimony rule: at least 10 % better, and
    // consistently so (t >= 2.5, or every sign pattern but a few beaten).
    let candidate = report
        .candidates
        .iter()
        .find(|c| c.effect == effect)
        .expect("the effect was tried");
    let consistent = candidate.t_stat >= 2.5 || candidate.sign_flip_p.is_some_and(|p| p <= 0.005);
    assert!(
        consistent && first.improvement_pct >= 10.0 && candidate.significant,
        "{summary}"
    );
    // What was identified loads into the training simulator.
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("dynamics.toml");
    report.dynamics().save(&path).expect("saved");
    let loaded = DynamicsFile::load(&path).expect("loads");
    assert_eq!(loaded, report.dynamics());
    let dynamics = loaded.apply(rtr::sim::Dynamics::bicycle(0.5), &device());
    assert_eq!(dynamics.terms()[0].name(), effect.name());
}

#[test]
fn accel_lag_is_found() {
    names_and_fits(Effect::AccelLag, 50.0);
}

#[test]
fn steer_lag_is_found() {
    names_and_fits(Effect::SteerLag, 50.0);
}

#[test]
fn dead_time_is_found() {
    names_and_fits(Effect::DeadTime, 50.0);
}

#[test]
fn drag_is_found() {
    names_and_fits(Effect::Drag, 50.0);
}

#[test]
fn understeer_is_found() {
    names_and_fits(Effect::Understeer, 50.0);
}

#[test]
fn steer_rate_limit_is_found() {
    names_and_fits(Effect::SteerRateLimit, 50.0);
}

#[test]
fn sideslip_is_found() {
    // Sideslip only moves the recorded point by about lr x (heading change): a clear,
    // significant drop, not a halving, is what it can show.
    names_and_fits(Effect::Sideslip, 10.0);
}

/// Weak effects, each lifting the baseline's held-out error only some tens of percent above
/// the noise floor: sideslip with the recorded point 0.3 m ahead of the rear axle (a fifth
/// of the typical 1.4 m), and a steering rate limit of 0.6 rad/s (2.4 times the typical
/// 0.25 rad/s, reached only in brisk steering).
#[test]
fn weak_sideslip_and_a_weak_steering_rate_limit_are_found() {
    names_and_fits_at(Effect::Sideslip, vec![0.3], 10.0);
    names_and_fits_at(Effect::SteerRateLimit, vec![0.6], 10.0);
}

#[test]
fn no_effect_reports_nothing() {
    let report = run_blind(&GeneratorConfig::with_effect(None, 7));
    assert!(
        report.findings.is_empty(),
        "{}",
        report.summary().join("\n")
    );
    assert_eq!(report.final_model.model, "nominal");
    assert!(report.dynamics().terms.is_empty());
    // The recordings have stops, crawling queues and tracks that start at rest; the nominal
    // model's held-out error sits at the noise floor estimated from the recordings.
    let u = &report.unexplained;
    assert!(u.at_floor, "{}", report.summary().join("\n"));
    assert!(report.still_open.is_none(), "{:?}", report.still_open);
    assert!(
        (u.ratio - 1.0).abs() <= 0.1,
        "{}",
        report.summary().join("\n")
    );
    for (estimated, truth) in [(u.noise.position_m, 0.1), (u.noise.speed_m_s, 0.1)] {
        assert!((estimated / truth - 1.0).abs() < 0.1, "{:?}", u.noise);
    }
}

#[test]
fn the_generator_drives_with_stops_queues_and_starts_at_rest() {
    let recordings = generate(&GeneratorConfig::with_effect(None, 7), &device());
    let at_rest = |speeds: &[f64]| speeds.iter().filter(|&&v| v.abs() < 0.3).count();
    let stopping = recordings
        .tracks
        .iter()
        .filter(|t| at_rest(&t.speed) >= 10)
        .count();
    let starting_at_rest = recordings
        .tracks
        .iter()
        .filter(|t| t.speed[0].abs() < 0.3)
        .count();
    assert!(
        stopping >= 6,
        "{stopping} of 24 tracks stop for a second or more"
    );
    assert!(starting_at_rest >= 1, "no track starts at rest");
    // Speeds span queues to motorways; none reverses.
    let speeds: Vec<f64> = recordings
        .tracks
        .iter()
        .flat_map(|t| t.speed.clone())
        .collect();
    let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
    let fastest = speeds.iter().copied().fold(0.0, f64::max);
    assert!(slowest > -0.5 && fastest > 25.0, "{slowest} .. {fastest}");
}

/// Physics outside the catalogue: flagged as unexplained with the catalogue alone (and, when
/// nothing is kept, the report's last line says what was tried and names `channel` among the
/// two furthest above their floors), and named as an equation by the open-ended stage
/// ([`discovered_and_kept`]).
fn uncatalogued_is_flagged_then_discovered(
    physics: Uncatalogued,
    feature: Feature,
    coefficient: f64,
    channel: &str,
) {
    let recordings = generate(&GeneratorConfig::with_uncatalogued(physics, 7), &device());
    let options = Sim2RealOptions {
        discover: false,
        ..Default::default()
    };
    let catalogue = identify(&recordings, &options, &|_| {})
        .expect("identification runs")
        .report;
    let summary = catalogue.summary().join("\n");
    assert!(!catalogue.unexplained.at_floor, "{summary}");
    assert!(
        catalogue.findings.iter().all(|f| f.effect.is_some()),
        "{summary}"
    );
    assert!(summary.contains("unexplained:"), "{summary}");
    let open_line = catalogue
        .still_open
        .clone()
        .expect("a line on what is still open");
    assert_eq!(summary.lines().last(), Some(open_line.as_str()));
    assert!(open_line.contains("--catalogue-only"), "{open_line}");
    if catalogue.findings.is_empty() {
        assert!(
            open_line.contains("none kept") && open_line.contains(&format!("{channel} (")),
            "{open_line}"
        );
    }
    discovered_and_kept(&recordings, feature, coefficient);
}

/// Discovery names the physics as an equation (feature, coefficient within 20 %), keeps it
/// first, and cuts held-out error by at least 40 %; the dynamics file it writes loads.
fn discovered_and_kept(recordings: &rtr::data::Recordings, feature: Feature, coefficient: f64) {
    let open = identify(recordings, &Sim2RealOptions::default(), &|_| {})
        .expect("identification runs")
        .report;
    let summary = open.summary().join("\n");
    let first = open.findings.first().expect("a finding");
    assert_eq!(first.name, "discovered", "{summary}");
    let term = first
        .discovered
        .iter()
        .find(|t| t.feature.name() == feature.name())
        .unwrap_or_else(|| panic!("{feature:?} not found\n{summary}"));
    if let (
        Feature::PowerLimit {
            specific_power_w_kg: found,
        },
        Feature::PowerLimit {
            specific_power_w_kg: truth,
        },
    ) = (term.feature, feature)
    {
        assert!(
            (found / truth - 1.0).abs() <= 0.1,
            "{found} vs {truth}\n{summary}"
        );
    }
    assert!(
        (term.coefficient.value / coefficient - 1.0).abs() <= 0.2,
        "{} vs {coefficient}\n{summary}",
        term.coefficient.value
    );
    assert!(
        open.final_model.improvement_vs_baseline_pct >= 40.0,
        "{summary}"
    );
    assert!(open.unexplained.at_floor, "{summary}");
    // What was discovered loads into the training simulator.
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("dynamics.toml");
    open.dynamics().save(&path).expect("saved");
    assert_eq!(DynamicsFile::load(&path).expect("loads"), open.dynamics());
    assert!(!open.dynamics().discovered.is_empty());
}

#[test]
fn a_speed_dependent_steering_ratio_is_flagged_then_discovered() {
    // The steering quickens with speed (k < 0): out of the catalogue's reach.
    let k = -0.006;
    uncatalogued_is_flagged_then_discovered(
        Uncatalogued::SpeedDependentSteering { k_per_m_s: k },
        Feature::KappaV,
        -k / 2.8,
        "heading",
    );
}

#[test]
fn an_asymmetric_brake_gain_is_flagged_then_discovered() {
    uncatalogued_is_flagged_then_discovered(
        Uncatalogued::BrakeGain { gain: 1.3 },
        Feature::UBrake,
        0.3,
        "along",
    );
}

/// The engine's power capping the acceleration at P / v, a limit that tightens with speed:
/// discovery picks the limit from the data and the cap (coefficient -1) through the rollout.
/// (Flagged without discovery as the two above are; only the discovery run here, on 16
/// tracks instead of 24, to keep the suite's time.)
#[test]
fn a_power_limit_is_discovered_and_kept() {
    let specific_power_w_kg = 20.0;
    let physics = Uncatalogued::PowerLimit {
        specific_power_w_kg,
    };
    let config = GeneratorConfig {
        tracks: 16,
        ..GeneratorConfig::with_uncatalogued(physics, 7)
    };
    let recordings = generate(&config, &device());
    discovered_and_kept(
        &recordings,
        Feature::PowerLimit {
            specific_power_w_kg,
        },
        -1.0,
    );
}

#[test]
fn a_wrong_wheelbase_is_fitted_not_reported_as_understeer() {
    let mut config = GeneratorConfig::with_effect(None, 7);
    config.true_wheelbase_m = 3.1;
    let report = run_blind(&config);
    let summary = report.summary().join("\n");
    assert!(report.findings.is_empty(), "{summary}");
    let scale = report.nominal_refit.wheelbase_scale.value;
    assert!(
        (scale * 2.8 - 3.1).abs() < 0.05,
        "fitted wheelbase {}\n{summary}",
        scale * 2.8
    );
    assert!(report.final_model.heldout_pos_rmse_m < report.baseline.heldout_pos_rmse_m);
}

#[test]
fn every_term_has_gradients_that_match_finite_differences() {
    // The loss through a 3 s rollout of 2 tracks, differentiated by burn autodiff in the raw
    // parameters, against central differences (f32, so a loose but telling tolerance).
    let mut config = GeneratorConfig::with_effect(None, 5);
    config.tracks = 2;
    config.duration_s = 12.0;
    let recordings = generate(&config, &device());
    let ws = windows(&recordings, &[0, 1], 3.0, 3.0, 1.0, 2.8, Starts::Regular);
    let plain = batches(&ws, &device());
    let autodiff = device().autodiff();
    for effect in Effect::ALL {
        let candidate = Candidate::with_effects(vec![effect]);
        let raw = Fit::unfitted(candidate.clone()).raw;
        let loss_at = |raw: &[f64], device: &Device, differentiate: bool| {
            let values: Vec<f32> = raw.iter().map(|&v| v as f32).collect();
            let mut leaf =
                Tensor::<1>::from_data(burn::tensor::TensorData::new(values, [raw.len()]), device);
            if differentiate {
                leaf = leaf.require_grad();
            }
            let total = plain
                .iter()
                .map(|b| b.loss_sum(&b.simulate(&candidate, &leaf)).0)
                .reduce(|a, b| a + b)
                .expect("windows");
            (leaf, total)
        };
        let (leaf, total) = loss_at(&raw, &autodiff, true);
        let grads = total.backward();
        let analytic: Vec<f64> = leaf
            .grad(&grads)
            .expect("gradient")
            .to_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .expect("f64");
        for k in 0..raw.len() {
            let eps = 1e-2;
            let at = |shift: f64| {
                let mut r = raw.clone();
                r[k] += shift;
                loss_at(&r, &device(), false).1.into_scalar::<f64>()
            };
            let numeric = (at(eps) - at(-eps)) / (2.0 * eps);
            let scale = analytic[k].abs().max(numeric.abs()).max(1e-3);
            assert!(
                (analytic[k] - numeric).abs() <= 0.05 * scale,
                "{effect} parameter {k}: autodiff {} vs finite differences {numeric}",
                analytic[k]
            );
        }
    }
}

#[test]
fn a_run_file_names_a_dynamics_file_relative_to_itself() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("dynamics.toml");
    std::fs::write(
        &path,
        "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 0.4 }\n",
    )
    .expect("written");
    let run = dir.path().join("run.toml");
    std::fs::write(&run, "method = \"IL\"\ndynamics = \"dynamics.toml\"\n").expect("written");
    let config = rtr::train::TrainConfig::from_toml_file(&run).expect("run file");
    assert_eq!(config.dynamics.as_deref(), Some(path.as_path()));
    let dynamics = DynamicsFile::load(&path)
        .expect("loads")
        .apply(rtr::sim::Dynamics::bicycle(0.5), &device());
    assert_eq!(dynamics.terms()[0].name(), "accel_lag");
    // Out of range: the file, the term and the parameter are named.
    std::fs::write(
        &path,
        "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 40.0 }\n",
    )
    .expect("written");
    let message = DynamicsFile::load(&path)
        .expect_err("out of range")
        .to_string();
    assert!(
        message.contains("dynamics.toml") && message.contains("tau_s"),
        "{message}"
    );
    // An unknown key in a term is a typo, named with its line, never silently dropped.
    std::fs::write(
        &path,
        "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 0.4 }\nenabled = false\n",
    )
    .expect("written");
    let message = DynamicsFile::load(&path)
        .expect_err("unknown key")
        .to_string();
    assert!(
        message.contains("dynamics.toml")
            && message.contains("enabled")
            && message.contains("line 4"),
        "{message}"
    );
    // A discovered term loads; one outside its equation's library or not finite is named.
    std::fs::write(
        &path,
        "[[discovered]]\nequation = \"speed\"\nfeature = \"u_brake\"\ncoefficient = 0.3\n",
    )
    .expect("written");
    let loaded = DynamicsFile::load(&path).expect("loads");
    let dynamics = loaded.apply(rtr::sim::Dynamics::bicycle(0.5), &device());
    assert_eq!(dynamics.terms()[0].name(), "discovered");
    for (bad, expected) in [
        (
            "feature = \"kappa_v\"\ncoefficient = 0.3",
            "not in the dv/dt library",
        ),
        (
            "feature = \"u_brake\"\ncoefficient = nan",
            "expected a finite value",
        ),
        ("feature = \"u_squared\"\ncoefficient = 0.3", "u_squared"),
        (
            "feature = { power_limit = { specific_power_w_kg = -3.0 } }\ncoefficient = -1.0",
            "specific_power_w_kg",
        ),
        (
            "feature = { power_limit = { specific_power_w_kg = nan } }\ncoefficient = -1.0",
            "expected a limit > 0",
        ),
        (
            "feature = { brake_limit = { decel_m_s2 = 0.0 } }\ncoefficient = -1.0",
            "brake_limit.decel_m_s2",
        ),
    ] {
        std::fs::write(
            &path,
            format!("[[discovered]]\nequation = \"speed\"\n{bad}\n"),
        )
        .expect("written");
        let message = DynamicsFile::load(&path).expect_err(bad).to_string();
        assert!(
            message.contains("dynamics.toml") && message.contains(expected),
            "{message}"
        );
    }
    std::fs::write(
        &path,
        "[[discovered]]\nequation = \"heading_rate\"\ncoefficient = -1.0\n\
         feature = { power_limit = { specific_power_w_kg = 20.0 } }\n",
    )
    .expect("written");
    let message = DynamicsFile::load(&path).expect_err("heading").to_string();
    assert!(
        message.contains("dtheta/dt library") && message.contains("steer_limit"),
        "{message}"
    );
}

#[test]
fn on_the_real_a9_recording_only_what_the_data_can_show_is_tried() {
    // Commands are inferred from the drone tracks: effects on the commands, and discovered
    // terms in them, cannot be told from the commands themselves.
    let dataset =
        rtr::data::A9Dataset::load(&rtr::data::a9::default_dir()).expect("shipped A9 data");
    let recordings = rtr::sim2real::a9::a9_recordings(&dataset, 0.1, 7.0);
    let mut options = Sim2RealOptions {
        commands_inferred: true,
        ..Default::default()
    };
    // Honesty of what is tried is the point here, not the quality of the fits.
    options.fit.iterations = 20;
    let report = identify(&recordings, &options, &|_| {})
        .expect("identification runs")
        .report;
    let summary = report.summary().join("\n");
    for effect in Effect::ALL.into_iter().filter(|e| e.acts_on_commands()) {
        assert!(
            report.not_identifiable.iter().any(|(e, _)| *e == effect),
            "{effect} should not be identifiable\n{summary}"
        );
        assert!(report.candidates.iter().all(|c| c.effect != effect));
    }
    assert!(
        report
            .discovery
            .terms()
            .iter()
            .all(|(_, feature, _)| !feature.involves_commands()),
        "{summary}"
    );
    // The along-track mismatch of the tracked acceleration is reported, not hidden.
    assert!(report.baseline.heldout_pos_rmse_m > 0.5, "{summary}");
    assert!(!report.unexplained.at_floor, "{summary}");
}

/// However short the fit, no finding and no final model is worse on held-out tracks than the
/// declared nominal model. (With `--iterations 1` on these recordings, the one-step wheelbase
/// refit ended at 0.489 m against the declared model's 0.204 m and was reported as the final
/// model; elsewhere a finding 18 % worse was reported and `dynamics.toml` held it.)
#[test]
fn no_finding_makes_held_out_error_worse_whatever_the_iterations() {
    let recordings = generate(&GeneratorConfig::with_effect(None, 11), &device());
    for iterations in [1, 3] {
        let mut options = Sim2RealOptions::default();
        options.fit.iterations = iterations;
        let report = identify(&recordings, &options, &|_| {})
            .expect("identification runs")
            .report;
        let baseline = report.baseline.heldout_pos_rmse_m;
        assert!(
            report.final_model.heldout_pos_rmse_m <= baseline,
            "{iterations} iterations: {}",
            report.summary().join("\n")
        );
        for finding in &report.findings {
            assert!(
                finding.heldout_pos_rmse_m < baseline,
                "{iterations} iterations: {}",
                report.summary().join("\n")
            );
        }
    }
}

/// The report of `effect` alone (no discovery) fitted to `recordings` with the commands read
/// as `declared` (from the data when `None`), and its summary; `effect` must be found first.
fn effect_alone(
    recordings: &rtr::data::Recordings,
    effect: Effect,
    declared: Option<rtr::sim2real::CommandTiming>,
    case: &str,
) -> (Report, String) {
    let options = Sim2RealOptions {
        effects: vec![effect],
        discover: false,
        command_timing: declared,
        ..Sim2RealOptions::default()
    };
    let report = identify(recordings, &options, &|_| {})
        .expect("identification runs")
        .report;
    let summary = report.summary().join("\n");
    let first = report
        .findings
        .first()
        .unwrap_or_else(|| panic!("{case}: nothing found\n{summary}"));
    assert_eq!(first.effect, Some(effect), "{case}\n{summary}");
    (report, summary)
}

/// On recordings whose noise, sample rate and command timing differ from the generator's
/// defaults (commands held per period, or sampled from a controller ten times faster than the
/// log), the reported interval of each lag and dead time covers the truth whatever the
/// timing; when the data decides the timing it decides right and the value is within 10 %;
/// declared, the timing gives the value within 10 %; and sampled commands declared as held
/// make the time constant about half a period short.
#[test]
fn time_constants_hold_under_other_rates_noise_and_command_timing() {
    use rtr::sim2real::{CommandTiming, TimingEvidence};
    let settings = [
        (Effect::AccelLag, CommandTiming::Sampled, 0.1, 1.0),
        (Effect::SteerLag, CommandTiming::Held, 0.05, 0.5),
        (Effect::DeadTime, CommandTiming::Sampled, 0.2, 1.5),
    ];
    for (effect, timing, period, noise) in settings {
        let mut config = GeneratorConfig::with_effect(Some(effect), 5);
        config.tracks = 16;
        config.period_s = period;
        config.command_timing = timing;
        config.noise.position_m *= noise;
        config.noise.heading_rad *= noise;
        config.noise.speed_m_s *= noise;
        let recordings = generate(&config, &device());
        let truth = typical(effect)[0];
        let name = effect.params()[0].name;
        let case = format!("{effect} at {period} s, noise x{noise}, commands {timing:?}");
        let fitted = |declared: Option<CommandTiming>| {
            let (report, summary) = effect_alone(&recordings, effect, declared, &case);
            let first = &report.findings[0];
            let (value, interval) = (first.params[name], first.params_interval[name]);
            (value, interval, report, summary)
        };

        let (value, [low, high], report, summary) = fitted(None);
        assert!(
            low <= truth && truth <= high,
            "{case}: interval {low} .. {high} misses {truth}\n{summary}"
        );
        if report.command_timing.decided_by != TimingEvidence::Ambiguous {
            assert_eq!(report.command_timing.reading, timing, "{case}\n{summary}");
            assert!(
                (value - truth).abs() <= 0.1 * truth,
                "{case}: {value}, truth {truth}\n{summary}"
            );
        }

        let (value, _, _, summary) = fitted(Some(timing));
        assert!(
            (value - truth).abs() <= 0.1 * truth,
            "{case}, declared: {value}, truth {truth}\n{summary}"
        );
        if timing == CommandTiming::Sampled {
            let (as_held, _, _, _) = fitted(Some(CommandTiming::Held));
            let short = truth - as_held;
            assert!(
                (0.25 * period..=0.75 * period).contains(&short),
                "{case}, declared held: {as_held}, truth {truth}: expected about half of \
                 {period} s short"
            );
        }
    }
}

/// Sideslip's lateral offset leads the rear-axle path by `lr / v`, so a steering command that
/// acts earlier than the reading assumes is fitted as extra rear-axle distance: commands
/// sampled from a fast controller but read as held come out about `v T / 2` long. Read from
/// the data (`auto`), they are read as sampled and the distance is within 10 %.
#[test]
fn sideslip_under_sampled_commands_is_not_fitted_long() {
    use rtr::sim2real::{CommandTiming, TimingEvidence};
    let mut config = GeneratorConfig::with_effect(Some(Effect::Sideslip), 5);
    config.tracks = 16;
    config.command_timing = CommandTiming::Sampled;
    let recordings = generate(&config, &device());
    let truth = typical(Effect::Sideslip)[0];
    let fitted = |declared: Option<CommandTiming>| {
        let (report, summary) = effect_alone(&recordings, Effect::Sideslip, declared, "sideslip");
        (report.findings[0].params["lr_m"], report, summary)
    };
    let (lr, report, summary) = fitted(None);
    assert_eq!(
        (
            report.command_timing.reading,
            report.command_timing.decided_by
        ),
        (CommandTiming::Sampled, TimingEvidence::HeldOutError),
        "{summary}"
    );
    assert!(
        (lr - truth).abs() <= 0.1 * truth,
        "lr {lr}, truth {truth}\n{summary}"
    );
    let [low, high] = report.findings[0].params_interval["lr_m"];
    assert!(
        low <= truth && truth <= high,
        "interval {low} .. {high}\n{summary}"
    );
    let (as_held, _, summary) = fitted(Some(CommandTiming::Held));
    assert!(
        as_held > 1.05 * truth,
        "read as held: lr {as_held}\n{summary}"
    );
}
