//! `rtr data summary`: one JSON object describing the nominal dataset as rtr sees it.

use super::a9::A9Dataset;
use super::closing_events::{ClosingEvents, closing_events};
use super::logged_infractions::logged_infractions;
use super::windows::SceneConfig;
use crate::error::Result;

#[derive(Debug, Clone, serde::Serialize)]
pub struct DataSummary {
    pub vehicles: usize,
    pub cars: usize,
    pub trucks: usize,
    pub fps: f64,
    pub duration_s: f64,
    pub logged_samples: usize,
    pub road_length_m: f64,
    pub driving_lanes: usize,
    pub lane_graph_nodes: usize,
    pub dt_s: f64,
    pub history_s: f64,
    pub future_s: f64,
    pub split_time_s: f64,
    pub train_scenes: usize,
    pub test_scenes: usize,
    /// Mean number of controlled agents per scene (train and test together).
    pub mean_controlled_agents: f64,
    /// Share of logged vehicles whose box ever leaves the road polygon (%).
    pub logged_offroad_pct: f64,
    /// Share of logged vehicles whose box ever overlaps another's (%).
    pub logged_collision_pct: f64,
    pub logged_offroad_samples: usize,
    pub logged_exiting_samples: usize,
    pub logged_colliding_pairs: usize,
    /// Where a logged driver closes on the car ahead in its lane, and what it does next
    /// ([`super::closing_events`]): the demonstrations imitation has for braking.
    pub logged_closing: ClosingEvents,
}

pub fn summarize(dataset: &A9Dataset, config: &SceneConfig) -> Result<DataSummary> {
    use crate::data::VehicleClass;
    let rec = &dataset.recording;
    let split = dataset.scenes(config)?;
    let infractions = logged_infractions(rec, &dataset.map);
    let scenes = split.train.len() + split.test.len();
    let controlled: usize = split
        .train
        .iter()
        .chain(&split.test)
        .map(|s| s.controlled_count())
        .sum();
    let count = |c: VehicleClass| rec.tracks.iter().filter(|t| t.class == c).count();
    Ok(DataSummary {
        vehicles: rec.tracks.len(),
        cars: count(VehicleClass::Car),
        trucks: count(VehicleClass::Truck),
        fps: rec.fps,
        duration_s: rec.duration(),
        logged_samples: infractions.samples,
        road_length_m: dataset.map.road_length(),
        driving_lanes: dataset.map.driving_lane_count(),
        lane_graph_nodes: dataset.lane_graph.nodes.len(),
        dt_s: config.dt,
        history_s: config.history_s,
        future_s: config.future_s,
        split_time_s: split.split_time,
        train_scenes: split.train.len(),
        test_scenes: split.test.len(),
        mean_controlled_agents: if scenes == 0 {
            0.0
        } else {
            controlled as f64 / scenes as f64
        },
        logged_offroad_pct: infractions.offroad_pct(),
        logged_collision_pct: infractions.collision_pct(),
        logged_offroad_samples: infractions.offroad_samples,
        logged_exiting_samples: infractions.exiting_samples,
        logged_colliding_pairs: infractions.colliding_pairs,
        logged_closing: closing_events(rec),
    })
}
