//! Evaluation on the real A9 data: the logged drivers replayed through the simulator score as
//! the log does (no infractions, FDE and CTE near zero, near-zero JSDs), a policy that ignores
//! the road scores worse on every realism metric, and the metrics do not depend on how scenes
//! are batched.

mod common;

use burn::prelude::*;
use rtr::eval::bootstrap::{estimate, resampled_totals, total};
use rtr::eval::{
    EvalConfig, EvalScenes, Feature, Metric, SceneTally, evaluate_tallies, summarise, tally_rollout,
};
use rtr::scene::{AgentRole, Scene, SceneBatch};
use rtr::sim::{Dynamics, MapCaches, RolloutConfig, coast, replay_logs, rollout};

fn cpu() -> Device {
    rtr::backend::Backend::reference_device(false)
}

fn metric(tallies: &[SceneTally], m: Metric) -> f64 {
    m.value(&total(tallies).expect("scenes")).expect("defined")
}

#[test]
fn replayed_logs_score_as_the_log() {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().take(40).collect();
    let (_, out) = replay_logs(&scenes, &Dynamics::bicycle(0.5), &cpu()).expect("replay");
    let tallies = tally_rollout(&scenes, &out, 10, true).expect("tally");
    let t = total(&tallies).expect("scenes");
    println!(
        "replay: agents {} fde {:?} ate {:?} cte {:?} jsd {:?}",
        t.agents,
        Metric::FdeM.value(&t),
        Metric::AteM.value(&t),
        Metric::CteM.value(&t),
        Feature::ALL.map(|f| Metric::Jsd(f).value(&t))
    );
    assert!(
        t.agents > 200.0 && t.fde_agents > 50.0,
        "{} agents, {} at 5 s",
        t.agents,
        t.fde_agents
    );
    assert_eq!(Metric::CollisionPct.value(&t), Some(0.0));
    assert_eq!(Metric::OffroadPct.value(&t), Some(0.0));
    assert!(Metric::FdeM.value(&t).unwrap() < 0.2);
    assert!(Metric::CteM.value(&t).unwrap() < 0.1);
    assert!(Metric::AteM.value(&t).unwrap() < 0.1);
    // The inverse model reproduces positions; the logged speed channel (the tracker's) and
    // the speed implied by positions differ a little, which the 0.25 m/s^2 acceleration bins
    // see: its floor is higher.
    for f in Feature::ALL {
        let jsd = Metric::Jsd(f).value(&t).unwrap();
        let floor = if f == Feature::Acceleration {
            0.1
        } else {
            0.02
        };
        assert!(jsd < floor, "JSD {} = {jsd}", f.name());
    }
    // Every feature was measured on both sides.
    for k in 0..Feature::ALL.len() {
        let (sim, log) = (t.simulated[k].total(), t.logged[k].total());
        assert!(
            sim > 100.0 && log > 100.0,
            "feature {k}: {sim} / {log} samples"
        );
    }
}

#[test]
fn coasting_agents_score_worse_than_the_log() {
    // Zero controls from the logged state: no braking, no steering along the curved A9.
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().take(24).collect();
    let (_, replay) = replay_logs(&scenes, &Dynamics::bicycle(0.5), &cpu()).expect("replay");
    let batch = SceneBatch::from_scenes(&scenes, &cpu()).expect("batch");
    let config = RolloutConfig {
        steps: None,
        early_termination: false,
    };
    let mut policy = coast;
    let coasting = rollout(
        &scenes,
        &batch,
        &Dynamics::bicycle(0.5),
        &mut policy,
        &mut MapCaches::default(),
        &config,
    )
    .expect("rollout");
    let logged = tally_rollout(&scenes, &replay, 10, true).expect("tally");
    let coasted = tally_rollout(&scenes, &coasting, 10, true).expect("tally");
    for m in [
        Metric::FdeM,
        Metric::CteM,
        Metric::Jsd(Feature::Acceleration),
    ] {
        let (a, b) = (metric(&logged, m), metric(&coasted, m));
        assert!(b > a + 0.01, "{}: coasting {b} vs log {a}", m.key());
    }
    // Coasting has exactly zero acceleration: its histogram is one bin.
    let t = total(&coasted).unwrap();
    let acc = &t.simulated[0];
    assert_eq!(acc.counts.iter().filter(|&&c| c > 0.0).count(), 1);
}

/// Collision and hit-by-log rates of one coasting rollout of a straight-road scene of
/// constant-speed agents `(x, speed, role)` in one lane.
fn rear_end_rates(agents: &[(f64, f64, AgentRole)]) -> (f64, f64) {
    let y = -1.875;
    let placed: Vec<(f64, f64, f64, f64)> =
        agents.iter().map(|&(x, v, _)| (x, y, 0.0, v)).collect();
    // 4 s: long enough for a replayed car to drive on through the car it struck.
    let mut scene = common::straight_scene(&placed, 8);
    for (agent, &(_, _, role)) in scene.agents.iter_mut().zip(agents) {
        agent.role = role;
    }
    let batch = SceneBatch::from_scenes(&[&scene], &cpu()).expect("batch");
    let out = rollout(
        &[&scene],
        &batch,
        &Dynamics::bicycle(0.5),
        &mut coast,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
    )
    .expect("rollout");
    let tallies = tally_rollout(&[&scene], &out, 8, false).expect("tally");
    (
        metric(&tallies, Metric::CollisionPct),
        metric(&tallies, Metric::HitByLogPct),
    )
}

/// A log-replayed car cannot brake: when one runs into a slower policy car from behind, the
/// policy car is counted as hit by the log, not as colliding. A policy car that drives into a
/// replayed one, or is run into by another policy car, still collides.
#[test]
fn a_rear_end_by_a_replayed_car_is_not_the_policy_cars_collision() {
    use AgentRole::{Controlled, Replayed};
    let struck_by_log = rear_end_rates(&[(100.0, 10.0, Controlled), (80.0, 30.0, Replayed)]);
    assert_eq!(struck_by_log, (0.0, 100.0));
    let drove_into_log = rear_end_rates(&[(80.0, 30.0, Controlled), (100.0, 10.0, Replayed)]);
    assert_eq!(drove_into_log, (100.0, 0.0));
    let policy_pair = rear_end_rates(&[(100.0, 10.0, Controlled), (80.0, 30.0, Controlled)]);
    assert_eq!(policy_pair, (100.0, 0.0));
    let apart = rear_end_rates(&[(100.0, 30.0, Controlled), (40.0, 10.0, Replayed)]);
    assert_eq!(apart, (0.0, 0.0));
}

#[test]
fn metrics_do_not_depend_on_batching_and_carry_intervals() {
    let split = common::a9_scenes();
    let set = EvalScenes {
        set: rtr::eval::EvalSet::Nominal,
        scenes: split.test.iter().take(12).cloned().collect(),
        scenarios: Vec::new(),
    };
    let driver = rtr::eval::IdmBaseline {
        params: Default::default(),
        limits: Default::default(),
    };
    let mut dynamics = Dynamics::bicycle(0.5);
    dynamics.limits = Some(Default::default());
    let run = |batch| {
        let config = EvalConfig {
            batch,
            resamples: 200,
            ..EvalConfig::default()
        };
        evaluate_tallies(&driver, &dynamics, &set, &cpu(), &config).expect("evaluate")
    };
    let (one, four) = (run(1), run(4));
    assert_eq!(one.len(), 12);
    for (a, b) in one.iter().zip(&four) {
        assert!((a.fde_sum - b.fde_sum).abs() < 1e-3 * (1.0 + a.fde_sum));
        assert_eq!(a.agents, b.agents);
        assert_eq!(a.simulated[1].total(), b.simulated[1].total());
    }
    let config = EvalConfig::default();
    let row = summarise(set.set, &one, &config);
    let fde = row.get(Metric::FdeM).expect("fde");
    assert!(
        fde.value > 0.0 && fde.ci > 0.0 && fde.ci < fde.value,
        "{fde:?}"
    );
    // The summary's interval is the bootstrap of the same tallies.
    let full = total(&one).unwrap();
    let again = estimate(
        &full,
        &resampled_totals(&one, config.resamples, config.seed),
        |t| Metric::FdeM.value(t),
    );
    assert_eq!(again, Some(fde));
}

#[test]
fn sampled_realism_repeats_with_its_seed_and_is_a_likelihood() {
    let split = common::a9_scenes();
    let set = EvalScenes {
        set: rtr::eval::EvalSet::Nominal,
        scenes: split.test.iter().take(6).cloned().collect(),
        scenarios: Vec::new(),
    };
    let device = cpu();
    device.seed(5);
    let network = rtr::model::PolicyNetwork::new(&rtr::model::ModelConfig::small(), &device);
    let dynamics = Dynamics::bicycle(0.5);
    let config = EvalConfig {
        batch: 3,
        realism_samples: 3,
        resamples: 100,
        ..EvalConfig::default()
    };
    let run = || {
        rtr::eval::evaluate::realism_tallies(&network, &dynamics, &set, &device, &config)
            .expect("realism")
    };
    let (a, b) = (run(), run());
    assert_eq!(a, b, "same seed, same samples");
    let scores = rtr::eval::evaluate::summarise_realism(&a, &config);
    let composite = scores[3].expect("composite").value;
    assert!(composite > 0.0 && composite <= 1.0, "{composite}");
    for s in scores.iter().flatten() {
        assert!(s.value > 0.0 && s.value <= 1.0 && s.ci >= 0.0, "{s:?}");
    }
}

#[test]
fn every_shipped_model_loads_with_its_method_and_card() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let models = root.join("models");
    let main_table = std::fs::read_to_string(root.join("experiments/main/results.json"))
        .expect("experiments/main/results.json");
    let main_table: serde_json::Value = serde_json::from_str(&main_table).expect("JSON");
    let expected = [
        ("bc", "BC"),
        ("il", "IL"),
        ("rl", "RL"),
        ("rl_shaped", "RL-Shaped"),
        ("bc_rl", "BC+RL"),
        ("rtr", "RTR"),
    ];
    for (folder, method) in expected {
        // The small-budget model, then the main comparison's (`experiments/main/results.md`).
        let small = models.join(folder);
        let main = models.join(format!("{folder}_main"));
        for (dir, table) in [
            (&small, "experiments/main/small/results.json"),
            (&main, "experiments/main/results.json"),
        ] {
            let policy = rtr::eval::TrainedPolicy::load(dir, &cpu())
                .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
            assert_eq!(policy.method, method, "{}", dir.display());
            let card = std::fs::read_to_string(dir.join("CARD.md")).expect("card");
            assert!(card.contains(table), "{} cites {table}", dir.display());
        }
        // The main table's row of this method was measured on exactly this model.
        assert_eq!(
            main_table["checkpoints"][method].as_str(),
            Some(format!("models/{folder}_main/policy.bpk").as_str()),
            "{method}"
        );
        let small_card = std::fs::read_to_string(small.join("CARD.md")).expect("card");
        assert!(small_card.contains(&format!("experiments/main/small/{folder}.toml")));
    }
}

/// PPO alone at the field's budget: the model its study's table was measured on, and held out
/// below IL's long-tail infraction rate (the claim of `experiments/rl_at_scale/`).
#[test]
fn the_rl_at_scale_model_is_the_one_its_study_measured() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("models/rl_at_scale");
    let policy = rtr::eval::TrainedPolicy::load(&dir, &cpu()).expect("models/rl_at_scale loads");
    assert_eq!(policy.method, "RL");
    let card = std::fs::read_to_string(dir.join("CARD.md")).expect("card");
    assert!(card.contains("experiments/rl_at_scale/results.json"));
    let read = |path: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(root.join(path)).expect(path)).expect(path)
    };
    let study = read("experiments/rl_at_scale/results.json");
    assert_eq!(
        study["checkpoints"]["RL"].as_str(),
        Some("models/rl_at_scale/policy.bpk")
    );
    let il = read("experiments/main/results.json")["methods"]["IL"]["longtail"]["infraction_pct"]
        .as_f64()
        .expect("IL long-tail");
    let rl = study["methods"]["RL"]["longtail"]["infraction_pct"]
        .as_f64()
        .expect("RL long-tail");
    assert!(rl < il, "long-tail infractions: RL {rl} %, IL {il} %");
}

/// The README's verdict on the paper's headline is the one the example prints: the same rule
/// (`HeadlineVerdict`) applied to the committed main table.
#[test]
fn the_readme_states_the_headline_verdict_of_the_main_table() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let table: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("experiments/main/results.json")).expect("table"),
    )
    .expect("JSON");
    let value = |method: &str, set: &str, metric: &str| {
        let v = &table["methods"][method][set];
        rtr::eval::Estimate {
            value: v[metric].as_f64().expect(metric),
            ci: v[format!("{metric}_ci")].as_f64().expect(metric),
        }
    };
    let verdict = rtr::eval::HeadlineVerdict::of(&rtr::eval::HeadlineNumbers {
        il_longtail_collision_pct: value("IL", "longtail", "collision_pct"),
        rtr_longtail_collision_pct: value("RTR", "longtail", "collision_pct"),
        il_nominal_fde_m: value("IL", "nominal", "fde_m").value,
        rtr_nominal_fde_m: value("RTR", "nominal", "fde_m").value,
        rtr_nominal_offroad_pct: value("RTR", "nominal", "offroad_pct").value,
    });
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let stated = format!("**Verdict: the paper's headline {}.**", verdict.summary());
    assert!(readme.contains(&stated), "README.md should say {stated}");
}

/// Every shipped model's card records its weights' sha256, and the weights still match: a
/// changed `policy.bpk` is refused wherever it loads, and a model added without the record
/// fails here.
#[test]
fn every_shipped_models_card_records_its_weights() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut checked = 0;
    for entry in std::fs::read_dir(&root).expect("models/") {
        let dir = entry.expect("entry").path();
        if !dir.join("policy.bpk").is_file() {
            continue;
        }
        let card = std::fs::read_to_string(dir.join("CARD.md")).expect("card");
        let recorded = card
            .split(rtr::train::recorded_weights::CARD_WEIGHTS)
            .nth(1)
            .and_then(|rest| rest.split('`').next())
            .unwrap_or_else(|| panic!("{}: no weights line", dir.display()));
        let bytes = std::fs::read(dir.join("policy.bpk")).expect("weights");
        assert_eq!(
            recorded,
            rtr::data::automatum::sha256_hex(&bytes),
            "{}",
            dir.display()
        );
        checked += 1;
    }
    assert!(checked >= 10, "{checked} models");
}
