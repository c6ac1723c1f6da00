//! Shared fixtures for the integration tests: the shipped A9 dataset, loaded once per test
//! binary.

use std::sync::{Arc, OnceLock};

use rtr::data::{A9Dataset, AgentState, SceneConfig, SceneSplit, VehicleClass, a9};
use rtr::map::{LaneGraph, Map, ProceduralMap};
use rtr::scene::{AgentRole, Scene, SceneAgent};

pub fn a9() -> &'static A9Dataset {
    static DATA: OnceLock<A9Dataset> = OnceLock::new();
    DATA.get_or_init(|| A9Dataset::load(&a9::default_dir()).expect("the shipped A9 data loads"))
}

#[allow(dead_code)] // not every test binary uses scenes
pub fn a9_scenes() -> &'static SceneSplit {
    static SCENES: OnceLock<SceneSplit> = OnceLock::new();
    SCENES.get_or_init(|| a9().scenes(&SceneConfig::default()).expect("scenes build"))
}

/// A one-way straight road (2 lanes of 3.75 m, 400 m) and a scene of hand-placed agents with
/// one history step and `future` steps, each agent constant-speed in the log.
#[allow(dead_code)] // not every test binary uses hand-built scenes
pub fn straight_scene(agents: &[(f64, f64, f64, f64)], future: usize) -> Scene {
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
