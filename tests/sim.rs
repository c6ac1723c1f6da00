//! The closed-loop simulator: gradients through the rollout, log replay on the real A9 data,
//! and infraction timing on hand-built scenes.

mod common;

use std::sync::Arc;

use burn::prelude::*;
use burn::tensor::TensorData;
use rtr::data::{AgentState, VehicleClass};
use rtr::map::{BoxOnRoad, LaneGraph, Map, ProceduralMap};
use rtr::scene::{AgentRole, Scene, SceneAgent, SceneBatch};
use rtr::sim::{
    ActionLimits, Controls, Dynamics, MapCaches, Observation, RolloutConfig, VehicleState,
    inverse_actions, rollout, rollout_from,
};

#[allow(deprecated)]
fn cpu() -> Device {
    Device::ndarray()
}

fn values(t: Tensor<3>) -> Vec<f64> {
    t.into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .expect("floats")
}

fn flags(t: &Tensor<3, burn::tensor::Bool>) -> Vec<bool> {
    t.to_data().try_into_vec::<bool>().expect("bools")
}

#[test]
fn inverse_model_replays_the_real_logs() {
    let split = common::a9_scenes();
    let scenes: Vec<&Scene> = split.test.iter().collect();
    let device = cpu();
    let batch = SceneBatch::from_scenes(&scenes, &device).expect("batch");
    let [b, n, t_total, _] = batch.agent_states.dims();
    let h = batch.history_steps;
    let limits = ActionLimits::default();
    // Kinematic initial states and raw commands per agent, from the inverse model.
    let mut init = vec![[0f32; 4]; b * n];
    let mut commands = vec![0f32; b * n * t_total * 2];
    let mut initial_given = vec![false; b * n];
    for (bi, scene) in scenes.iter().enumerate() {
        for (ai, agent) in scene.agents.iter().enumerate() {
            if agent.role != AgentRole::Controlled {
                continue;
            }
            let inv = inverse_actions(agent, scene.dt, &limits);
            let slot = bi * n + ai;
            if let Some(k) = inv.states[h] {
                init[slot] = [k.x as f32, k.y as f32, k.heading as f32, k.speed as f32];
                initial_given[slot] = true;
            } else {
                // No logged next step to be consistent with: start from the log itself.
                let s = agent.states[h];
                let half = 0.5 * rtr::sim::wheelbase_of(agent.length);
                init[slot] = [
                    (s.x - half * s.heading.cos()) as f32,
                    (s.y - half * s.heading.sin()) as f32,
                    s.heading as f32,
                    s.speed as f32,
                ];
            }
            for t in 0..t_total {
                commands[(slot * t_total + t) * 2] = inv.raw_accel[t] as f32;
                commands[(slot * t_total + t) * 2 + 1] = inv.raw_steer[t] as f32;
            }
        }
    }
    let commands = Tensor::<4>::from_data(TensorData::new(commands, [b, n, t_total, 2]), &device);
    let channel = |c: usize| {
        let v: Vec<f32> = init.iter().map(|s| s[c]).collect();
        Tensor::<2>::from_data(TensorData::new(v, [b, n]), &device)
    };
    let initial = VehicleState {
        x: channel(0),
        y: channel(1),
        heading: channel(2),
        speed: channel(3),
        aux: Vec::new(),
    };
    let mut replay = |obs: &Observation| {
        let step = commands
            .clone()
            .narrow(2, h + obs.step, 1)
            .reshape([b, n, 2]);
        Controls::from_stacked(step)
    };
    let out = rollout_from(
        &scenes,
        &batch,
        &Dynamics::bicycle(0.5),
        &mut replay,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
        Some(initial),
    )
    .expect("rollout");
    // Position error where the log has the agent and the inverse model had a full step.
    let poses = out
        .poses
        .clone()
        .into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap();
    let simulated = flags(&out.simulated);
    let (mut sum, mut count, mut worst) = (0.0, 0usize, 0f64);
    for (bi, scene) in scenes.iter().enumerate() {
        for (ai, agent) in scene.agents.iter().enumerate() {
            let slot = bi * n + ai;
            if agent.role != AgentRole::Controlled || !initial_given[slot] {
                continue;
            }
            for k in 1..=out.steps {
                let t = h + k;
                // The inverse model needs the log at t + 1 to define the state at t.
                if t + 1 >= t_total
                    || !(agent.valid[t] && agent.valid[t + 1])
                    || !agent.valid[t - 1]
                {
                    break;
                }
                assert!(
                    simulated[slot * (out.steps + 1) + k],
                    "{} agent {ai} step {k}",
                    scene.id
                );
                let o = (slot * (out.steps + 1) + k) * 4;
                let e = (poses[o] - agent.states[t].x).hypot(poses[o + 1] - agent.states[t].y);
                sum += e;
                count += 1;
                worst = worst.max(e);
            }
        }
    }
    let mean = sum / count as f64;
    println!(
        "log replay: {count} agent-steps, mean position error {mean:.4} m, worst {worst:.4} m"
    );
    assert!(count > 2000, "{count}");
    assert!(mean < 0.05 && worst < 0.5, "mean {mean} m, worst {worst} m");
    // Replayed human driving has no infractions.
    let collision = flags(&out.collision);
    assert!(!collision.iter().any(|&c| c), "a replayed log collided");
    assert!(
        !flags(&out.offroad).iter().any(|&c| c),
        "a replayed log went off-road"
    );
}

/// A one-way straight road (2 lanes of 3.75 m, 400 m) and a scene of hand-placed agents with
/// one history step and `future` steps, each agent constant-speed in the log.
fn straight_scene(agents: &[(f64, f64, f64, f64)], future: usize) -> Scene {
    let od = ProceduralMap::Straight {
        lanes: 2,
        lane_width: 3.75,
        length: 400.0,
        layout: Default::default(),
    }
    .build()
    .expect("map");
    let map = Arc::new(Map::from_opendrive(&od, "test-straight").expect("map"));
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let dt = 0.5;
    let steps = 1 + 1 + future;
    let agents = agents
        .iter()
        .enumerate()
        .map(|(i, &(x, y, heading, speed))| {
            let states = (0..steps)
                .map(|k| {
                    let t = (k as f64 - 1.0) * dt;
                    AgentState {
                        x: x + speed * t * heading.cos(),
                        y: y + speed * t * heading.sin(),
                        heading,
                        speed,
                        accel: 0.0,
                    }
                })
                .collect();
            SceneAgent {
                track_id: i,
                class: VehicleClass::Car,
                length: 4.5,
                width: 1.8,
                role: AgentRole::Controlled,
                states,
                valid: vec![true; steps],
            }
        })
        .collect();
    Scene {
        id: "hand-built".into(),
        t0: 0.0,
        dt,
        history_steps: 1,
        future_steps: future,
        map,
        lane_graph: graph,
        agents,
    }
}

fn zero_policy(obs: &Observation) -> Controls {
    let dims = obs.state.speed.dims();
    let device = obs.state.speed.device();
    Controls {
        accel: Tensor::zeros(dims, &device),
        steer: Tensor::zeros(dims, &device),
    }
}

fn run(scene: &Scene) -> rtr::sim::Rollout {
    let batch = SceneBatch::from_scenes(&[scene], &cpu()).expect("batch");
    rollout(
        &[scene],
        &batch,
        &Dynamics::bicycle(0.5),
        &mut zero_policy,
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
    let scene = straight_scene(
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
fn a_car_steered_off_the_road_is_flagged_at_the_right_step_and_leaving_the_end_is_not() {
    // Heading 0.12 rad to the right of the road, 20 m/s, no control: the box drifts right
    // 1.2 m per step. The expected first off-road step comes from the exact map query on the
    // analytically moved box.
    let heading = -0.12;
    let (x0, y0, v) = (100.0, -1.875, 20.0);
    let scene = straight_scene(&[(x0, y0, heading, v)], 10);
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
    let scene = straight_scene(&[(385.0, -1.875, 0.0, 20.0)], 10);
    let out = run(&scene);
    assert!(!flags(&out.offroad).iter().any(|&f| f));
    assert!(!flags(&out.collision).iter().any(|&f| f));
    let present = flags(&out.present);
    assert!(
        present[0] && !present[out.steps],
        "removed after leaving through the end"
    );
}
