//! Long-tail scenarios: the shipped families, seeded sampling, validation, error messages, and
//! the difficulty of the sets for the IDM reference driver compared with the real A9 scenes.

mod common;

use std::collections::BTreeSet;
use std::sync::OnceLock;

use burn::prelude::*;
use rayon::prelude::*;
use rtr::data::TrafficStatistics;
use rtr::driver::{IdmDriver, IdmParams};
use rtr::geometry::OrientedBox;
use rtr::map::BoxOnRoad;
use rtr::scenario::{
    ConcreteScenario, FamilySet, GenerateConfig, LogicalScenario, SamplingContext, ScenarioSet,
    builtin_families, family_seed, generate_sets, load_families, rollout_with_heroes,
    sample_scenario,
};
use rtr::scene::{Scene, SceneBatch};
use rtr::sim::{ActionLimits, Dynamics, MapCaches, RolloutConfig, rollout};

fn stats() -> &'static TrafficStatistics {
    static STATS: OnceLock<TrafficStatistics> = OnceLock::new();
    STATS.get_or_init(|| {
        let a9 = common::a9();
        TrafficStatistics::from_recording(&a9.recording, &a9.map, 1.0)
    })
}

fn families() -> &'static Vec<LogicalScenario> {
    static FAMILIES: OnceLock<Vec<LogicalScenario>> = OnceLock::new();
    FAMILIES.get_or_init(|| load_families(&builtin_families()).expect("shipped families load"))
}

fn ctx() -> SamplingContext<'static> {
    SamplingContext {
        stats: stats(),
        dt: 0.5,
        history_steps: 4,
    }
}

#[test]
fn a9_traffic_statistics_are_plausible_motorway_traffic() {
    let s = stats();
    assert_eq!(s.lanes.len(), 3, "three lanes per carriageway on the A9");
    for (rank, lane) in s.lanes.iter().enumerate() {
        let v = lane.median_speed();
        assert!(
            (15.0..45.0).contains(&v),
            "lane {rank}: median speed {v} m/s"
        );
        let h = lane.median_headway();
        assert!(
            (0.5..10.0).contains(&h),
            "lane {rank}: median headway {h} s"
        );
    }
    // The fast lane is faster than the slow lane.
    assert!(s.lanes[2].median_speed() > s.lanes[0].median_speed());
}

#[test]
fn shipped_families_cover_the_paper_sizes_and_ood_is_new() {
    let f = families();
    let train: Vec<_> = f.iter().filter(|f| f.set == FamilySet::Train).collect();
    let ood: Vec<_> = f.iter().filter(|f| f.set == FamilySet::Ood).collect();
    assert!(train.len() >= 25, "{} training families", train.len());
    assert!(ood.len() >= 11, "{} OOD families", ood.len());
    // The held-out families use map topologies the training ones never see.
    let train_maps: BTreeSet<&str> = train.iter().map(|f| f.map.preset.as_str()).collect();
    let new_maps: Vec<&str> = ood
        .iter()
        .map(|f| f.map.preset.as_str())
        .filter(|m| !train_maps.contains(m))
        .collect();
    assert!(new_maps.contains(&"off_ramp_fork") && new_maps.contains(&"lane_drop"));
}

/// Every concrete scenario's initial state is on the road and collision-free, and every hero
/// phase fired and completed in the reference run.
fn assert_valid(s: &ConcreteScenario) {
    let scene = s.to_scene().unwrap();
    let now = scene.current_step();
    let boxes: Vec<OrientedBox> = scene
        .agents
        .iter()
        .map(|a| a.footprint(now).unwrap())
        .collect();
    for (i, b) in boxes.iter().enumerate() {
        assert_eq!(
            scene.map.box_on_road(b),
            BoxOnRoad::OnRoad,
            "{}: agent {i}",
            s.id()
        );
        for other in &boxes[i + 1..] {
            assert!(!b.overlaps(other), "{}: overlapping start", s.id());
        }
    }
    assert!(!s.heroes.is_empty());
    for hero in &s.reference.phases {
        for p in hero {
            assert!(
                p.fired_step.is_some() && p.done_step.is_some() && p.failed.is_none(),
                "{}: {p:?}",
                s.id()
            );
        }
    }
}

#[test]
fn every_family_produces_valid_scenarios_that_round_trip_through_json() {
    let dir = tempfile::tempdir().unwrap();
    let failures: Vec<String> = families()
        .par_iter()
        .filter_map(|family| {
            let set = match family.set {
                FamilySet::Train => ScenarioSet::Eval,
                FamilySet::Ood => ScenarioSet::Ood,
            };
            let s = match sample_scenario(family, &ctx(), family_seed(11, &family.name, 0), set, 0)
            {
                Ok(s) => s,
                Err(e) => return Some(e.to_string()),
            };
            assert_eq!(s.family, family.name);
            // The family names every value its sampler draws, as the scenario records it.
            assert_eq!(
                s.parameters.keys().collect::<Vec<_>>(),
                family.drawn_ranges().keys().collect::<Vec<_>>(),
                "{}",
                family.name
            );
            assert_valid(&s);
            let path = dir.path().join(format!("{}.json", s.id()));
            s.write(&path).unwrap();
            let back = ConcreteScenario::from_json_file(&path).unwrap();
            assert_eq!(back.content_sha256, Some(s.content_digest().unwrap()));
            let unstamped = ConcreteScenario {
                content_sha256: None,
                ..back.clone()
            };
            assert_eq!(unstamped, s);
            // Without its digest the file is simulated again: its reference run is its own.
            unstamped
                .check_reference(&s.id())
                .expect("the reference run is the file's");
            None
        })
        .collect();
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn same_seed_gives_byte_identical_sets_and_other_seeds_differ() {
    let config = |seed| GenerateConfig {
        seed,
        in_distribution: 6,
        ood: 2,
        ..Default::default()
    };
    let json = |seed| {
        let sets = generate_sets(families(), stats(), &config(seed)).unwrap();
        assert_eq!(
            (sets.train.len(), sets.eval.len(), sets.ood.len()),
            (3, 3, 2)
        );
        ScenarioSet::ALL
            .iter()
            .flat_map(|&set| {
                sets.set(set)
                    .iter()
                    .map(|s| s.to_json().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    let a = json(5);
    assert_eq!(a, json(5));
    let b = json(6);
    assert!(
        a.iter().zip(&b).all(|(x, y)| x != y),
        "every scenario changes with the seed"
    );
    // Written files carry their family and are named by set.
    let dir = tempfile::tempdir().unwrap();
    let sets = generate_sets(families(), stats(), &config(5)).unwrap();
    assert_eq!(sets.write(dir.path()).unwrap(), 8);
    let eval = std::fs::read_dir(dir.path().join("eval")).unwrap().count();
    assert_eq!(eval, 3);
    let first = &sets.ood[0];
    let text = std::fs::read_to_string(dir.path().join("ood").join(format!("{}.json", first.id())))
        .unwrap();
    assert!(text.contains(&format!("\"family\": \"{}\"", first.family)));
}

#[test]
fn a_family_without_heroes_is_a_lone_target() {
    let text = GOOD.split("[[heroes]]").next().unwrap();
    let family = LogicalScenario::from_toml_str(text, "alone.toml").expect("valid");
    assert!(family.heroes.is_empty());
}

fn family_error(text: &str) -> String {
    LogicalScenario::from_toml_str(text, "bad.toml")
        .unwrap_err()
        .to_string()
}

const GOOD: &str = r#"
name = "probe"
description = "test"
set = "train"
[map]
preset = "straight"
length = 900
[target]
lane = 2
station = [250, 300]
[[heroes]]
lane_offset = -1
station_offset = [8, 20]
speed_offset = [-3, -1]
[[heroes.phases]]
trigger = { kind = "ahead_gap_below", metres = [5, 15] }
action = { kind = "change_lane", direction = "right", lateral_speed = [1, 2] }
"#;

#[test]
fn invalid_family_files_name_the_file_the_place_and_what_was_expected() {
    assert!(LogicalScenario::from_toml_str(GOOD, "good.toml").is_ok());
    let cases = [
        (
            GOOD.replace("length = 900", "lenght = 900"),
            "no parameter `lenght`",
        ),
        (
            GOOD.replace("station = [250, 300]", "station = \"far\""),
            "a number or a [low, high] range",
        ),
        (
            GOOD.replace("lateral_speed = [1, 2]", "lateral_speed = [2, 1]"),
            "low <= high",
        ),
        (
            GOOD.replace("lateral_speed = [1, 2]", "lateral_speed = [1, 40]"),
            "lateral_speed",
        ),
        (
            GOOD.replace("lane = 2", "lane = \"shoulder\""),
            "\"ramp\", \"accel\", \"exit\"",
        ),
        (
            GOOD.replace("lane_offset = -1", "lane = 1\nlane_offset = -1"),
            "exactly one of `lane` and `lane_offset`",
        ),
        (
            GOOD.replace("kind = \"change_lane\"", "kind = \"teleport\""),
            "teleport",
        ),
        (GOOD.replace("set = \"train\"", "set = \"test\""), "test"),
        (
            GOOD.replace(
                "station = [250, 300]",
                "station = [250, 300]\nlateral_offset = [0, 12]",
            ),
            "target.lateral_offset",
        ),
        (
            GOOD.replace("preset = \"straight\"", "preset = \"roundabout\""),
            "roundabout",
        ),
    ];
    for (text, expected) in cases {
        let err = family_error(&text);
        assert!(err.contains("bad.toml"), "{err}");
        assert!(err.contains(expected), "expected `{expected}` in: {err}");
    }
    // Syntax-level errors carry the line.
    let err = family_error(&GOOD.replace("station = [250, 300]", "station = [250, 300"));
    assert!(err.contains("line"), "{err}");
}

/// `scenes` rolled out under the IDM reference driver, with the scenarios' heroes scripted
/// when given; and the batch.
fn idm_rollout(
    scenes: &[&Scene],
    scenarios: Option<&[&ConcreteScenario]>,
) -> (rtr::sim::Rollout, SceneBatch) {
    let device = rtr::backend::Backend::reference_device(false);
    let batch = SceneBatch::from_scenes(scenes, &device).unwrap();
    let mut idm = IdmDriver::new(scenes, IdmParams::default(), ActionLimits::default());
    let mut caches = MapCaches::default();
    let dynamics = Dynamics::bicycle(0.5);
    let config = RolloutConfig::default();
    let result = rollout_with_heroes(
        scenarios.unwrap_or_default(),
        scenes,
        &batch,
        &dynamics,
        &mut idm,
        &mut caches,
        &config,
    );
    (result.unwrap(), batch)
}

/// Collision rate (% of policy-driven agents) of the IDM reference driver on `scenes`, and
/// the number of agents; with `targets_only`, only agent 0 of each scene (a scenario's target).
fn idm_collision_pct(
    scenes: &[&Scene],
    scenarios: Option<&[&ConcreteScenario]>,
    targets_only: bool,
) -> (f64, usize) {
    let (result, batch) = idm_rollout(scenes, scenarios);
    let [b, n, t] = result.collision.dims();
    let flags = result
        .collision
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap();
    let mut controlled = batch
        .agent_controlled
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap();
    if targets_only {
        for (i, c) in controlled.iter_mut().enumerate() {
            *c &= i % n == 0;
        }
    }
    let agents = controlled.iter().filter(|&&c| c).count();
    let collided = (0..b * n)
        .filter(|&i| controlled[i] && flags[i * t..(i + 1) * t].iter().any(|&f| f))
        .count();
    (100.0 * collided as f64 / agents as f64, agents)
}

#[test]
fn long_tail_scenarios_are_harder_than_real_scenes_for_the_idm_driver() {
    let nominal: Vec<&Scene> = common::a9_scenes().test.iter().collect();
    let (nominal_pct, nominal_agents) = idm_collision_pct(&nominal, None, false);

    let sets = generate_sets(
        families(),
        stats(),
        &GenerateConfig {
            in_distribution: 50,
            ood: 0,
            ..Default::default()
        },
    )
    .unwrap();
    let scenarios: Vec<&ConcreteScenario> = sets.train.iter().chain(&sets.eval).collect();
    let scenes: Vec<Scene> = scenarios.iter().map(|s| s.to_scene().unwrap()).collect();
    // Batches share one window shape: group by horizon.
    let (mut total, mut targets) = ((0.0, 0usize), (0.0, 0usize));
    let horizons: BTreeSet<usize> = scenes.iter().map(|s| s.future_steps).collect();
    for h in horizons {
        let idx: Vec<usize> = (0..scenes.len())
            .filter(|&i| scenes[i].future_steps == h)
            .collect();
        let group: Vec<&Scene> = idx.iter().map(|&i| &scenes[i]).collect();
        let group_sc: Vec<&ConcreteScenario> = idx.iter().map(|&i| scenarios[i]).collect();
        let (pct, agents) = idm_collision_pct(&group, Some(&group_sc), false);
        total = (total.0 + pct * agents as f64, total.1 + agents);
        let (pct, agents) = idm_collision_pct(&group, Some(&group_sc), true);
        targets = (targets.0 + pct * agents as f64, targets.1 + agents);
    }
    let long_tail_pct = total.0 / total.1 as f64;
    let target_pct = targets.0 / targets.1 as f64;
    println!(
        "IDM reference driver collision rate: nominal A9 test scenes {nominal_pct:.2} % of {nominal_agents} agents; \
         long-tail ({} scenarios) {long_tail_pct:.2} % of {} agents, {target_pct:.1} % of the targets",
        scenarios.len(),
        total.1
    );
    assert!(
        long_tail_pct > 2.0 * nominal_pct.max(0.5),
        "{long_tail_pct} vs {nominal_pct}"
    );
    // The heroes act on the targets: most of the difficulty is theirs.
    assert!(
        target_pct > 10.0 * nominal_pct.max(0.5),
        "{target_pct} vs {nominal_pct}"
    );
}

/// Speeds and forward travel (along each agent's initial heading) per step of a rollout, for
/// the simulated agents (not replayed from a log) while on the road.
fn speeds_and_travel(out: &rtr::sim::Rollout, batch: &SceneBatch) -> Vec<Vec<(f64, f64)>> {
    let [b, n, t1, _] = out.poses.dims();
    let poses = out
        .poses
        .to_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap();
    let present = out.present.to_data().try_into_vec_as::<bool>().unwrap();
    let simulated = batch
        .agent_controlled
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap()
        .into_iter()
        .zip(
            batch
                .agent_hero
                .to_data()
                .try_into_vec_as::<bool>()
                .unwrap(),
        )
        .map(|(controlled, hero)| controlled || hero);
    (0..b * n)
        .zip(simulated)
        .filter(|&(_, simulated)| simulated)
        .map(|(i, _)| {
            let at = |k: usize, c: usize| poses[(i * t1 + k) * 4 + c];
            let (sin, cos) = at(0, 2).sin_cos();
            (0..t1)
                .filter(|&k| present[i * t1 + k])
                .map(|k| {
                    let travel = (at(k, 0) - at(0, 0)) * cos + (at(k, 1) - at(0, 1)) * sin;
                    (at(k, 3), travel)
                })
                .collect()
        })
        .collect()
}

/// Rolls `scenes` out twice: under IDM with the scenarios' heroes scripted (when given), and
/// with every agent braking as hard as the limits allow. Checks that no speed is negative and
/// that no braked vehicle travels backwards; returns (agents that reached rest, agents).
fn check_standstill(scenes: &[&Scene], heroes: Option<&[&ConcreteScenario]>) -> (usize, usize) {
    let device = rtr::backend::Backend::reference_device(false);
    let (driven, batch) = idm_rollout(scenes, heroes);
    let dynamics = Dynamics::bicycle(0.5);
    let config = RolloutConfig::default();
    let mut caches = MapCaches::default();
    let mut full_brake = |obs: &rtr::sim::Observation| rtr::sim::Controls {
        accel: Tensor::ones(obs.state.speed.dims(), &device).mul_scalar(-20.0),
        steer: Tensor::zeros(obs.state.speed.dims(), &device),
    };
    let braked = rollout(
        scenes,
        &batch,
        &dynamics,
        &mut full_brake,
        &mut caches,
        &config,
    )
    .unwrap();
    let (mut at_rest, mut agents) = (0, 0);
    for agent in speeds_and_travel(&driven, &batch) {
        assert!(
            agent.iter().all(|&(v, _)| v >= 0.0),
            "negative speed: {agent:?}"
        );
        agents += 1;
        at_rest += agent.iter().any(|&(v, _)| v == 0.0) as usize;
    }
    for agent in speeds_and_travel(&braked, &batch) {
        assert!(
            agent.iter().all(|&(v, _)| v >= 0.0),
            "negative speed: {agent:?}"
        );
        for pair in agent.windows(2) {
            assert!(
                pair[1].1 >= pair[0].1 - 1e-3,
                "a braked vehicle rolled back: {pair:?}"
            );
        }
        agents += 1;
        at_rest += agent.iter().any(|&(v, _)| v == 0.0) as usize;
    }
    (at_rest, agents)
}

#[test]
fn braked_vehicles_stop_and_stay_stopped_on_real_scenes_and_stop_families() {
    let a9: Vec<&Scene> = common::a9_scenes().test.iter().take(20).collect();
    check_standstill(&a9, None);

    let sets = generate_sets(
        families(),
        stats(),
        &GenerateConfig {
            in_distribution: 0,
            ood: 24,
            ..Default::default()
        },
    )
    .unwrap();
    let stop_families = ["sudden_stop", "stopped_vehicle_in_lane", "stop_and_go"];
    let stops: Vec<&ConcreteScenario> = sets
        .ood
        .iter()
        .filter(|s| stop_families.contains(&s.family.as_str()))
        .collect();
    assert!(stops.len() >= 3, "{} stop scenarios", stops.len());
    let scenes: Vec<Scene> = stops.iter().map(|s| s.to_scene().unwrap()).collect();
    let (mut at_rest, mut agents) = (0, 0);
    let horizons: BTreeSet<usize> = scenes.iter().map(|s| s.future_steps).collect();
    for h in horizons {
        let idx: Vec<usize> = (0..scenes.len())
            .filter(|&i| scenes[i].future_steps == h)
            .collect();
        let group: Vec<&Scene> = idx.iter().map(|&i| &scenes[i]).collect();
        let group_sc: Vec<&ConcreteScenario> = idx.iter().map(|&i| stops[i]).collect();
        let (r, a) = check_standstill(&group, Some(&group_sc));
        (at_rest, agents) = (at_rest + r, agents + a);
    }
    println!("stop families: {at_rest} of {agents} agent rollouts reached rest");
    // The heroes stop, and vehicles behind them or braking hard from town speeds come to rest.
    assert!(at_rest >= stops.len(), "{at_rest} of {agents} reached rest");
}

/// A scenario file with nonsense in it is refused naming the file and the field: a heading in
/// degrees, a 100 m vehicle, a negative speed, an unknown key, a map parameter out of range.
#[test]
fn scenario_files_with_nonsense_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let family = &families()[0];
    let s = sample_scenario(
        family,
        &ctx(),
        family_seed(11, &family.name, 0),
        ScenarioSet::Eval,
        0,
    )
    .expect("a scenario");
    let path = dir.path().join("bad.json");
    let refused = |edit: &dyn Fn(&mut serde_json::Value), expected: &[&str]| {
        let mut json = serde_json::to_value(&s).expect("json");
        edit(&mut json);
        std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
        let err = ConcreteScenario::from_json_file(&path)
            .expect_err("refused")
            .to_string();
        assert!(err.contains("bad.json"), "{err}");
        for part in expected {
            assert!(err.contains(part), "`{part}` not in {err}");
        }
    };
    let last = s.history_steps;
    refused(
        &|j| j["agents"][0]["states"][last][2] = 90.0.into(),
        &["agents[0].states", "degrees"],
    );
    refused(
        &|j| j["agents"][1]["length"] = 100.0.into(),
        &["agents[1].length", "1-25 m"],
    );
    refused(
        &|j| j["agents"][0]["states"][last][3] = (-5.0).into(),
        &["agents[0].states", "speed -5"],
    );
    refused(&|j| j["colour"] = "red".into(), &["colour"]);
    refused(&|j| j["map"]["lane_width"] = 1e9.into(), &["map", "lane"]);
    refused(&|j| j["map"]["banking"] = 0.1.into(), &["banking"]);
    // A history state moved 1 km (a teleport), and a zeroed speed column under moving
    // positions: the motion says otherwise.
    refused(
        &|j| {
            let x = j["agents"][0]["states"][1][0].as_f64().unwrap();
            j["agents"][0]["states"][1][0] = (x + 1000.0).into();
        },
        &["agents[0]", "states[1] moves", "a jump"],
    );
    refused(
        &|j| {
            for k in 0..=last {
                j["agents"][0]["states"][k][3] = 0.0.into();
            }
        },
        &["agents[0].states", "times the speed of the positions"],
    );
    // Labels that a draw of the shipped family cannot have.
    let other = &families()[1];
    refused(
        &|j| j["family"] = other.name.clone().into(),
        &["shipped family", &other.name],
    );
    refused(
        &|j| j["description"] = "a quiet drive".into(),
        &["description", "a quiet drive", &family.name],
    );
    refused(
        &|j| j["parameters"]["target.station"] = 1e5.into(),
        &["parameters.target.station", "outside"],
    );
    refused(
        &|j| j["future_steps"] = (s.future_steps + 3).into(),
        &["future_steps", "per step"],
    );
}

/// Share (%) of `agents` (scene, agent index) with a leader whose time to collision at the
/// scene's current step is below `horizon_s`, and how many had a leader.
fn short_ttc_share(agents: &[(&Scene, usize)], horizon_s: f64) -> (f64, usize) {
    let (mut led, mut short) = (0usize, 0usize);
    for &(scene, i) in agents {
        let t = scene.current_step();
        let views: Vec<rtr::driver::AgentView> = scene
            .agents
            .iter()
            .map(|a| {
                let s = a.states[t];
                rtr::driver::AgentView {
                    x: s.x,
                    y: s.y,
                    heading: s.heading,
                    speed: s.speed,
                    length: a.length,
                    width: a.width,
                    present: a.valid[t],
                }
            })
            .collect();
        if !views[i].present {
            continue;
        }
        let Some((j, gap)) = rtr::eval::features::leader(i, &views) else {
            continue;
        };
        led += 1;
        let closing = views[i].speed - views[j].speed * (views[j].heading - views[i].heading).cos();
        if closing > 0.0 && gap < horizon_s * closing {
            short += 1;
        }
    }
    (100.0 * short as f64 / led.max(1) as f64, led)
}

/// Background traffic follows its leader as the recorded traffic does: drawn per vehicle,
/// speeds put fast cars seconds behind slow trucks (8.5 % of the followers started less than
/// 5 s from a rear-end, against 0.4 % in the logs) and the long-tail collisions were mostly
/// those rear-ends, not the scenarios' manoeuvres.
#[test]
fn background_followers_close_in_no_faster_than_recorded_ones() {
    let logged: Vec<(&Scene, usize)> = common::a9_scenes()
        .train
        .iter()
        .flat_map(|s| {
            (0..s.agents.len())
                .filter(|&i| s.agents[i].role == rtr::scene::AgentRole::Controlled)
                .map(move |i| (s, i))
        })
        .collect();
    let sets = generate_sets(
        families(),
        stats(),
        &GenerateConfig {
            in_distribution: 60,
            ood: 0,
            ..Default::default()
        },
    )
    .unwrap();
    let scenes: Vec<Scene> = sets.eval.iter().map(|s| s.to_scene().unwrap()).collect();
    // Controlled agents after the first (the target) are the background.
    let background: Vec<(&Scene, usize)> = scenes
        .iter()
        .flat_map(|s| {
            (1..s.agents.len())
                .filter(|&i| s.agents[i].role == rtr::scene::AgentRole::Controlled)
                .map(move |i| (s, i))
        })
        .collect();
    let (logged_pct, logged_led) = short_ttc_share(&logged, 5.0);
    let (generated_pct, generated_led) = short_ttc_share(&background, 5.0);
    println!(
        "followers < 5 s from a rear-end: logs {logged_pct:.2} % of {logged_led}, \
         generated background {generated_pct:.2} % of {generated_led}"
    );
    assert!(logged_led > 200 && generated_led > 200);
    assert!(
        generated_pct <= 4.0 * logged_pct + 0.5,
        "{generated_pct} % vs {logged_pct} % in the logs"
    );
}

/// Drives every controlled agent straight on at its speed.
struct Coasting;

impl rtr::eval::EvalPolicy for Coasting {
    fn policy<'a>(
        &'a self,
        _: &[&Scene],
        _: &SceneBatch,
        _: Option<u64>,
    ) -> Box<dyn rtr::sim::Policy + 'a> {
        Box::new(rtr::sim::coast)
    }
}

/// Agents that never brake drive into the braking hero ahead of them: the breakdown says so,
/// every colliding agent's first collision is classified exactly once, and nothing hits a
/// coasting agent from behind but another coasting agent.
#[test]
fn first_collisions_name_the_other_vehicle_and_the_side() {
    let family = families()
        .iter()
        .find(|f| f.name == "hard_brake_lead")
        .expect("shipped family");
    let scenarios: Vec<ConcreteScenario> = (0..12)
        .map(|k| {
            sample_scenario(
                family,
                &ctx(),
                family_seed(5, &family.name, k),
                ScenarioSet::Eval,
                k,
            )
            .expect("scenario")
        })
        .collect();
    let set =
        rtr::eval::EvalScenes::generated(rtr::eval::EvalSet::Longtail, scenarios).expect("scenes");
    let device = rtr::backend::Backend::reference_device(false);
    let config = rtr::eval::EvalConfig {
        resamples: 100,
        ..Default::default()
    };
    let r = rtr::eval::evaluate(&Coasting, &Dynamics::bicycle(0.5), &set, &device, &config)
        .expect("evaluate");
    let c = r.collisions.as_ref().expect("breakdown");
    let collision_pct = r.get(rtr::eval::Metric::CollisionPct).expect("rate").value;
    use rtr::eval::collisions::{Contact, ROLES};
    let classified: f64 = ROLES
        .iter()
        .flat_map(|&(role, _)| Contact::ALL.map(|side| c.share(role, side)))
        .sum();
    println!(
        "collision {collision_pct:.1} %, classified {classified:.1} %: {}",
        c.json()
    );
    assert!((classified - collision_pct).abs() < 1e-9);
    assert!(c.share(rtr::scene::AgentRole::Hero, Contact::Ahead) > 0.0);
    assert_eq!(c.share(rtr::scene::AgentRole::Hero, Contact::Behind), 0.0);
}
