//! Recorded scenes on a bent copy of their road (`crate::map::RoadBend`): the same drivers,
//! keeping their lanes, offsets and relative headings, on a road of another curvature. Not in
//! the paper; a data augmentation for imitation on a recording of one nearly straight road.

use std::sync::Arc;

use super::a9::LANE_NODE_LENGTH;
use super::track::AgentState;
use crate::error::{Error, Result};
use crate::map::{LaneGraph, Map, RoadBend};
use crate::scene::{Scene, SceneAgent};

/// `scenes` with `added_curvature` (1/m) added to their road. Every scene must lie on the same
/// one-road OpenDRIVE map (one bent map and lane graph are built and shared); ids get a
/// `~bend{curvature}` suffix.
pub fn bend_scenes(scenes: &[Scene], added_curvature: f64) -> Result<Vec<Scene>> {
    let Some(first) = scenes.first() else {
        return Ok(Vec::new());
    };
    let map = &first.map;
    let od = map.opendrive().ok_or_else(|| {
        Error::invalid(
            map.source(),
            "map",
            "a lanelet map; bending needs an OpenDRIVE road",
        )
    })?;
    let bend = RoadBend::new(od, map.source(), added_curvature)?;
    let name = format!("{} bent by {added_curvature} 1/m", map.source());
    let bent_map = Arc::new(Map::from_opendrive(bend.bent_opendrive(), &name)?);
    let bent_graph = Arc::new(LaneGraph::build(&bent_map, LANE_NODE_LENGTH));
    scenes
        .iter()
        .map(|scene| {
            if !Arc::ptr_eq(&scene.map, map) {
                return Err(Error::invalid(
                    &scene.id,
                    "map",
                    format!(
                        "not the map of {}; bend one map's scenes at a time",
                        first.id
                    ),
                ));
            }
            let agents = scene
                .agents
                .iter()
                .map(|agent| bend_agent(agent, &bend))
                .collect::<Result<Vec<_>>>()
                .map_err(|e| Error::invalid(&scene.id, "agents", e.to_string()))?;
            Ok(Scene {
                id: format!("{}~bend{added_curvature}", scene.id),
                map: bent_map.clone(),
                lane_graph: bent_graph.clone(),
                agents,
                ..scene.clone()
            })
        })
        .collect()
}

fn bend_agent(agent: &SceneAgent, bend: &RoadBend) -> Result<SceneAgent> {
    let states = agent
        .states
        .iter()
        .zip(&agent.valid)
        .map(|(state, &valid)| {
            if !valid {
                return Ok(*state);
            }
            let pose = bend.pose([state.x, state.y], state.heading)?;
            // The logged speed and acceleration are along the vehicle's heading; scaling the
            // acceleration like the speed leaves out the change of the scale over time (the
            // lateral drift of a lane change, a few 1e-4 of it per second).
            Ok(AgentState {
                x: pose.x,
                y: pose.y,
                heading: pose.heading,
                speed: state.speed * pose.speed_scale,
                accel: state.accel * pose.speed_scale,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(SceneAgent {
        states,
        ..agent.clone()
    })
}
