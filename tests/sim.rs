//! The closed-loop simulator: gradients through the rollout, log replay on the real A9 data,
//! and infraction timing on hand-built scenes.

mod common;

use burn::prelude::*;
use burn::tensor::{Bool, TensorData};
use rtr::map::BoxOnRoad;
use rtr::scene::{AgentRole, Scene, SceneBatch};
use rtr::sim::{
    Controls, Dynamics, MapCaches, Observation, Policy, Rollout, RolloutConfig, Scripted, coast,
    replay_logs, rollout,
};

fn cpu() -> Device {
    rtr::backend::Backend::reference_device(false)
}

fn values(t: Tensor<3>) -> Vec<f64> {
    t.into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .expect("floats")
}

fn flags(t: &Tensor<3, burn::tensor::Bool>) -> Vec<bool> {
    t.to_data().try_into_vec_as::<bool>().expect("bools")
}

#[test]
fn inverse_model_replays_the_real_logs() {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().collect();
    let (report, out) = replay_logs(&scenes, &Dynamics::bicycle(0.5), &cpu()).expect("replay");
    println!("log replay: {report:?}");
    assert!(report.agent_steps > 2000, "{report:?}");
    assert!(
        report.mean_position_error_m < 0.05 && report.max_position_error_m < 0.5,
        "{report:?}"
    );
    // Replayed human driving has no infractions.
    assert_eq!((report.collisions, report.offroad), (0, 0), "{report:?}");
    // Every compared agent-step was still simulated (nothing terminated or exited early).
    let simulated = flags(&out.simulated);
    assert!(simulated.iter().filter(|&&s| s).count() >= report.agent_steps);
}

/// `scene` rolled out with `script` driving the agents in `mask` and a coasting policy the rest.
fn scripted_rollout(
    scene: &Scene,
    batch: &SceneBatch,
    script: &mut dyn Policy,
    mask: Tensor<2, Bool>,
) -> Rollout {
    let mut policy = coast;
    let mut mixed = Scripted {
        policy: &mut policy,
        script,
        mask,
    };
    rollout(
        &[scene],
        batch,
        &Dynamics::bicycle(0.5),
        &mut mixed,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
    )
    .expect("rollout")
}

#[test]
fn scripted_agents_take_the_script_and_others_the_policy() {
    let y = -1.875;
    let scene = common::straight_scene(&[(100.0, y, 0.0, 20.0), (200.0, y, 0.0, 20.0)], 4);
    let batch = SceneBatch::from_scenes(&[&scene], &cpu()).expect("batch");
    let mask = Tensor::<2>::from_data(TensorData::new(vec![1.0f32, 0.0], [1, 2]), &cpu())
        .greater_elem(0.5);
    let mut script = |obs: &Observation| Controls {
        accel: Tensor::ones(obs.state.speed.dims(), &obs.state.speed.device()).mul_scalar(2.0),
        steer: Tensor::zeros(obs.state.speed.dims(), &obs.state.speed.device()),
    };
    let out = scripted_rollout(&scene, &batch, &mut script, mask);
    let poses = values(out.poses.reshape([1, 2, 20]));
    let speed = |agent: usize, k: usize| poses[agent * 20 + k * 4 + 3];
    let limited = 4.0 * (2.0f64 / 4.0).tanh();
    assert!((speed(0, 4) - (20.0 + 4.0 * 0.5 * limited)).abs() < 1e-3);
    assert!((speed(1, 4) - 20.0).abs() < 1e-4);
}

/// A scripted hero is driven through the dynamics but is never one of the policy's simulated
/// agents, from the first step on (PPO takes its samples and counts its agents where
/// `simulated` holds).
#[test]
fn heroes_are_never_simulated_policy_agents() {
    let y = -1.875;
    let mut scene = common::straight_scene(&[(100.0, y, 0.0, 20.0), (200.0, y, 0.0, 20.0)], 4);
    scene.agents[1].role = AgentRole::Hero;
    let batch = SceneBatch::from_scenes(&[&scene], &cpu()).expect("batch");
    let out = scripted_rollout(&scene, &batch, &mut coast, batch.agent_hero.clone());
    let simulated = flags(&out.simulated);
    let steps = simulated.len() / 2;
    assert!(simulated[..steps].iter().all(|&s| s), "{simulated:?}");
    assert!(simulated[steps..].iter().all(|&s| !s), "{simulated:?}");
    // The hero still moved: driven by its script through the dynamics.
    let poses = values(out.poses.reshape([1, 2, 4 * (steps)]));
    assert!(poses[4 * steps + 4 * (steps - 1)] > 200.0 + 20.0 * 0.5 * (steps - 2) as f64);
}

fn run(scene: &Scene) -> rtr::sim::Rollout {
    let batch = SceneBatch::from_scenes(&[scene], &cpu()).expect("batch");
    rollout(
        &[scene],
        &batch,
        &Dynamics::bicycle(0.5),
        &mut coast,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
    )
    .expect("rollout")
}

#[test]
fn head_on_agents_collide_at_the_right_step() {
    // Lane -1 centre is at y = -1.875. Fronts 60 - 4.5 = 55.5 m apart, closing at 20 m/s:
    // they touch at 2.775 s, so the boxes first overlap at step 6 (3.0 s), i.e. on the
    // transition with index 5.
    let y = -1.875;
    let scene = common::straight_scene(
        &[
            (100.0, y, 0.0, 10.0),
            (160.0, y, std::f64::consts::PI, 10.0),
        ],
        10,
    );
    let out = run(&scene);
    let collision = flags(&out.collision);
    let t = out.steps;
    for agent in 0..2 {
        let first = (0..t).find(|&k| collision[agent * t + k]);
        assert_eq!(first, Some(5), "agent {agent}");
    }
    let rewards = values(out.rewards.clone());
    assert_eq!(rewards[5], -1.0);
    assert_eq!(rewards[..5].iter().sum::<f64>(), 0.0);
    // Early termination: neither is on the road after the collision step.
    let present = flags(&out.present);
    assert!(
        present[6] && !present[7],
        "present at the infraction step, gone after"
    );
}

#[test]
fn a_car_that_passes_through_a_stopped_one_within_a_step_collides() {
    // 30 m/s, 10 m behind a stopped car (centres): after one 0.5 s step it is 5 m past it, so
    // the boxes (4.5 m long) overlap neither at the start nor at the end of the step, only
    // during it.
    let y = -1.875;
    let scene = common::straight_scene(&[(100.0, y, 0.0, 30.0), (110.0, y, 0.0, 0.0)], 4);
    let out = run(&scene);
    let collision = flags(&out.collision);
    let t = out.steps;
    for agent in 0..2 {
        let first = (0..t).find(|&k| collision[agent * t + k]);
        assert_eq!(first, Some(0), "agent {agent}");
    }
    let poses = values(out.poses.clone().reshape([1, 2 * (t + 1), 4]));
    let x_after = |agent: usize| poses[(agent * (t + 1) + 1) * 4];
    assert!(
        x_after(0) - x_after(1) > 4.5,
        "the ends of the step do not overlap"
    );
}

#[test]
fn a_car_steered_off_the_road_is_flagged_at_the_right_step_and_leaving_the_end_is_not() {
    // Heading 0.12 rad to the right of the road, 20 m/s, no control: the box drifts right
    // 1.2 m per step. The expected first off-road step comes from the exact map query on the
    // analytically moved box.
    let heading = -0.12;
    let (x0, y0, v) = (100.0, -1.875, 20.0);
    let scene = common::straight_scene(&[(x0, y0, heading, v)], 10);
    let expected = (1..=10).find(|&k| {
        let d = v * 0.5 * k as f64;
        let b = rtr::geometry::OrientedBox::new(
            [x0 + d * heading.cos(), y0 + d * heading.sin()],
            heading,
            4.5,
            1.8,
        );
        scene.map.box_on_road(&b) == BoxOnRoad::OffRoad
    });
    let out = run(&scene);
    let offroad = flags(&out.offroad);
    let first = (0..out.steps).find(|&k| offroad[k]).map(|k| k + 1);
    assert!(expected.is_some());
    assert_eq!(first, expected);

    // Along the lane towards the end at 400 m: leaves the map, never off-road.
    let scene = common::straight_scene(&[(385.0, -1.875, 0.0, 20.0)], 10);
    let out = run(&scene);
    assert!(!flags(&out.offroad).iter().any(|&f| f));
    assert!(!flags(&out.collision).iter().any(|&f| f));
    let present = flags(&out.present);
    assert!(
        present[0] && !present[out.steps],
        "removed after leaving through the end"
    );
}

#[test]
fn heroes_are_simulated_without_a_log_and_their_infractions_are_not_the_policys() {
    // Head-on as above, but agent 1 is a scripted hero whose log ends at the current step.
    let y = -1.875;
    let mut scene = common::straight_scene(
        &[
            (100.0, y, 0.0, 10.0),
            (160.0, y, std::f64::consts::PI, 10.0),
        ],
        10,
    );
    let now = scene.current_step();
    let hero = &mut scene.agents[1];
    hero.role = AgentRole::Hero;
    for k in now + 1..hero.valid.len() {
        hero.valid[k] = false;
    }
    let out = run(&scene);
    let t = out.steps;
    let collision = flags(&out.collision);
    assert_eq!(
        (0..t).find(|&k| collision[k]),
        Some(5),
        "the policy's agent"
    );
    assert!(
        collision[t..].iter().all(|&c| !c),
        "a hero's crash is not flagged"
    );
    let rewards = values(out.rewards.clone());
    assert!(rewards[t..].iter().all(|&r| r == 0.0));
    // The hero drove on through the dynamics (no log to replay) until it collided.
    let present = flags(&out.present);
    assert!(present[(t + 1) + 3], "hero still on the road at step 3");
    let [b, n, steps, f] = out.poses.dims();
    let poses = values(out.poses.clone().reshape([b, n, steps * f]));
    let hero_x = |k: usize| poses[((t + 1) + k) * 4];
    assert!((hero_x(3) - (160.0 - 15.0)).abs() < 0.1, "{}", hero_x(3));
}
