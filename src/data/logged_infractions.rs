//! Infractions of the logged human drivers, measured with the same geometry the simulator
//! uses (the map's grid-cached road query and the oriented-box overlap test): a box leaving the road polygon, and two boxes overlapping at the same instant.
//! Real drivers essentially never do either, so a high count means the map, the box
//! conventions or the geometry are wrong, not the drivers.

use std::collections::{BTreeSet, HashMap};

use crate::data::Recording;
use crate::map::{BoxOnRoad, Map, RASTER_CELL, RoadRaster};

/// Counts over every logged sample of a recording (its native frame rate).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LoggedInfractions {
    pub vehicles: usize,
    pub samples: usize,
    /// Vehicles whose box is ever off the road (not counting leaving through a road end).
    pub offroad_vehicles: usize,
    pub offroad_samples: usize,
    /// Samples whose box is partly past an open road end (entering or leaving the map).
    pub exiting_samples: usize,
    /// Vehicles whose box ever overlaps another vehicle's box in the same frame.
    pub collision_vehicles: usize,
    /// Distinct vehicle pairs that ever overlap.
    pub colliding_pairs: usize,
}

impl LoggedInfractions {
    pub fn offroad_pct(&self) -> f64 {
        pct(self.offroad_vehicles, self.vehicles)
    }

    pub fn collision_pct(&self) -> f64 {
        pct(self.collision_vehicles, self.vehicles)
    }
}

fn pct(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        0.0
    } else {
        100.0 * part as f64 / whole as f64
    }
}

/// Checks every sample of every track against the map and against every other vehicle
/// present in the same video frame.
pub fn logged_infractions(recording: &Recording, map: &Map) -> LoggedInfractions {
    let mut out = LoggedInfractions {
        vehicles: recording.tracks.len(),
        ..Default::default()
    };
    // The simulator's grid-cached query: same answers as the exact one, much faster.
    let raster = RoadRaster::new(map, RASTER_CELL);
    // Boxes per video frame, for the pairwise test.
    let mut frames: HashMap<i64, Vec<(usize, crate::geometry::OrientedBox)>> = HashMap::new();
    for track in &recording.tracks {
        let mut offroad = false;
        for sample in &track.samples {
            out.samples += 1;
            let footprint = track.footprint(&sample.state);
            match raster.box_on_road(map, &footprint) {
                BoxOnRoad::OnRoad => {}
                BoxOnRoad::Exiting => out.exiting_samples += 1,
                BoxOnRoad::OffRoad => {
                    out.offroad_samples += 1;
                    offroad = true;
                }
            }
            let frame = (sample.t * recording.fps).round() as i64;
            frames.entry(frame).or_default().push((track.id, footprint));
        }
        out.offroad_vehicles += usize::from(offroad);
    }
    let mut pairs = BTreeSet::new();
    for boxes in frames.values() {
        for (i, (id_a, a)) in boxes.iter().enumerate() {
            for (id_b, b) in &boxes[i + 1..] {
                let reach = a.bounding_radius() + b.bounding_radius();
                let (dx, dy) = (a.center[0] - b.center[0], a.center[1] - b.center[1]);
                if dx * dx + dy * dy < reach * reach && a.overlaps(b) {
                    pairs.insert((*id_a.min(id_b), *id_a.max(id_b)));
                }
            }
        }
    }
    out.colliding_pairs = pairs.len();
    out.collision_vehicles = pairs
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .collect::<BTreeSet<_>>()
        .len();
    out
}
