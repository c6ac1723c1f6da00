//! The downstream study's pieces on real A9 data: examples are in the agent's frame, the
//! logs replayed through the simulator give the real examples back (where the log has the
//! agent), a multimodal predictor
//! separates a fork that one mode can only average, and a study repeats with its seeds.

mod common;

use burn::prelude::*;
use rtr::eval::evaluate::rollout_scenes;
use rtr::eval::study::Entry;
use rtr::eval::{EvalConfig, EvalScenes};
use rtr::predict::sample::{HORIZON_STEPS, INPUT_SIZE};
use rtr::predict::{FitConfig, PredictionSample, PredictorConfig, fit, scene_samples, score};
use rtr::scene::Scene;
use rtr::sim::{Dynamics, replay_logs};
use rtr::studies::downstream::{DownstreamConfig, downstream};

fn cpu() -> Device {
    rtr::backend::Backend::reference_device(false)
}

#[test]
fn real_examples_are_in_the_agent_frame() {
    let split = common::a9_scenes();
    let samples: Vec<PredictionSample> =
        split.test.iter().take(20).flat_map(scene_samples).collect();
    assert!(samples.len() > 50, "{} examples", samples.len());
    for s in &samples {
        assert_eq!(s.input.len(), INPUT_SIZE);
        assert_eq!(s.future.len(), HORIZON_STEPS);
        // The anchor itself: origin, zero relative heading, present.
        assert_eq!(&s.input[..4], &[0.0, 0.0, 1.0, 0.0]);
        assert_eq!(s.input[5], 1.0);
        assert!((s.input[4] * 10.0 - s.speed).abs() < 1e-4);
        // Highway traffic moves forward along x, and stays within about a lane of it in 0.5 s.
        let [x, y] = s.future[0];
        assert!(
            (x - 0.5 * s.speed).abs() < 1.5 && y.abs() < 1.0,
            "first step {x}, {y} at {} m/s",
            s.speed
        );
    }
}

#[test]
fn replayed_logs_give_the_real_examples() {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().take(12).collect();
    let (_, out) = replay_logs(&scenes, &Dynamics::bicycle(0.5), &cpu()).expect("replay");
    let mut simulated = rollout_scenes(&scenes, &out);
    let real: Vec<PredictionSample> = scenes.iter().flat_map(|s| scene_samples(s)).collect();
    let longer: usize = simulated.iter().map(|s| scene_samples(s).len()).sum();
    // The simulator keeps driving an agent whose log ends before it leaves the map, so the
    // replay has more examples; where the log has the agent, they are the real ones.
    assert!(longer > real.len(), "{longer} vs {}", real.len());
    for (sim, log) in simulated.iter_mut().zip(&scenes) {
        for (a, b) in sim.agents.iter_mut().zip(&log.agents) {
            for (v, &logged) in a.valid.iter_mut().zip(&b.valid) {
                *v &= logged;
            }
        }
    }
    let replayed: Vec<PredictionSample> = simulated.iter().flat_map(scene_samples).collect();
    assert_eq!(real.len(), replayed.len());
    // Compared by distance from the anchor: the frame turns with the anchor's heading, whose
    // small logged-vs-simulated difference swings points 50 m ahead sideways.
    let worst = real
        .iter()
        .zip(&replayed)
        .flat_map(|(a, b)| {
            a.future
                .iter()
                .zip(&b.future)
                .map(|(p, q)| (p[0].hypot(p[1]) - q[0].hypot(q[1])).abs())
        })
        .fold(0.0f32, f32::max);
    assert!(worst < 0.3, "replayed futures differ by up to {worst} m");
}

/// Identical inputs; half the futures bend 4 m left over the horizon, half 4 m right.
fn fork(count: usize) -> Vec<PredictionSample> {
    (0..count)
        .map(|k| {
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let mut input = vec![0.0; INPUT_SIZE];
            input[4] = 2.0;
            PredictionSample {
                input,
                future: (1..=HORIZON_STEPS)
                    .map(|t| {
                        let u = t as f32 / HORIZON_STEPS as f32;
                        [10.0 * t as f32, side * 4.0 * u * u]
                    })
                    .collect(),
                speed: 20.0,
            }
        })
        .collect()
}

#[test]
fn two_modes_capture_a_fork_that_one_mode_averages() {
    let device = cpu().autodiff();
    let data = fork(256);
    let fitted = |modes: usize| {
        let config = FitConfig {
            model: PredictorConfig {
                hidden: vec![32, 32],
                modes,
                dt: 0.5,
            },
            epochs: 150,
            minibatch: 64,
            learning_rate: 3e-3,
            ..FitConfig::default()
        };
        let (predictor, losses) = fit(&data, &config, &device, 7).expect("fit");
        assert!(losses.last() < losses.first(), "{losses:?}");
        score(&predictor, &data, &device)
    };
    let (one, two) = (fitted(1), fitted(2));
    // One mode can at best predict the middle, 4 m from either branch.
    assert!(one.min_fde_m > 3.0, "{one:?}");
    assert!(two.min_fde_m < 1.0, "{two:?}");
    assert!(two.min_cte_m < one.min_cte_m, "{one:?} vs {two:?}");
}

#[test]
fn a_study_repeats_with_its_seeds() {
    let split = common::a9_scenes();
    let train = EvalScenes::real(split.train.iter().take(12).cloned().collect());
    let test = EvalScenes::real(split.test.iter().take(10).cloned().collect());
    let device = cpu().autodiff();
    let il = rtr::eval::TrainedPolicy::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/il"),
        &device.clone().inner(),
    )
    .expect("shipped IL loads");
    let entries = [Entry::Trained(Box::new(il)), Entry::idm()];
    let config = DownstreamConfig {
        seeds: 2,
        fit: FitConfig {
            epochs: 3,
            ..FitConfig::default()
        },
        ..DownstreamConfig::default()
    };
    let eval = EvalConfig {
        batch: 4,
        ..EvalConfig::default()
    };
    let run = |config: &DownstreamConfig| {
        downstream(
            &entries,
            &train,
            &test,
            &device,
            config,
            &eval,
            &indicatif::ProgressBar::hidden(),
        )
        .expect("downstream")
    };
    let rows = run(&config);
    let names: Vec<&str> = rows.iter().map(|r| r.data.as_str()).collect();
    assert_eq!(names, ["Real logs", "IL", "IDM"]);
    for r in &rows {
        assert_eq!(r.scores.len(), 2);
        assert!(r.train_examples.iter().all(|&n| n > 10), "{r:?}");
        for s in &r.scores {
            assert!(
                s.examples > 10 && s.min_fde_m.is_finite() && s.min_fde_m > 0.0,
                "{s:?}"
            );
            assert!(s.min_cte_m <= s.min_fde_m + 1e-9, "{s:?}");
        }
    }
    // Seeds differ (new data, new initialisation); the whole study repeats exactly.
    assert_ne!(rows[1].scores[0], rows[1].scores[1]);
    assert_eq!(rows, run(&config));

    // With mean actions IL's data is one dataset for every seed and differs from its sampled
    // data; IDM, deterministic either way, gives the same row.
    let mean = run(&DownstreamConfig {
        mean_actions: true,
        ..config.clone()
    });
    assert_eq!(mean[1].train_examples[0], mean[1].train_examples[1]);
    assert_ne!(mean[1].scores, rows[1].scores);
    assert_eq!((&mean[0], &mean[2]), (&rows[0], &rows[2]));
}
