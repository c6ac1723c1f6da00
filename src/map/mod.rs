//! Road maps: an OpenDRIVE subset (parse, write, procedural generation), its lanes sampled
//! into polylines with topology, on-road and lane queries, and the paper's lane graph.
//!
//! Real and generated maps share one path: [`OpenDrive`] -> [`Map::from_opendrive`] ->
//! [`LaneGraph::build`]. Lanelet networks (CommonRoad) enter through [`Map::from_lanelets`]
//! into the same [`Lane`]s and lane graph.

mod bend;
mod lane_continuity;
mod lane_graph;
mod lanelet;
mod lanelet_surface;
mod lanes;
mod lateral;
mod number_text;
mod opendrive;
mod procedural;
mod procedural_parts;
mod procedural_ramps;
mod query;
mod raster;
mod reference_line;
mod shape_checks;
mod topology;
mod topology_checks;
mod xodr_parse;
mod xodr_schema;
mod xodr_write;

#[cfg(test)]
mod procedural_tests;
#[cfg(test)]
mod test_maps;
#[cfg(test)]
mod xodr_parse_tests;

pub use bend::{BentPose, MAX_BEND_CURVATURE, RoadBend, bend_curvature_problem};
pub use lane_graph::{
    LANE_NODE_FEATURE_NAMES, LANE_NODE_FEATURES, LaneGraph, LaneNode, NeighbourTable,
    mark_category, neighbour_table,
};
pub use lanelet::{AdjacentLanelet, Lanelet};
pub use lanelet_surface::LANELET_SHOULDER_WIDTH;
pub use lanes::{DEFAULT_SPEED_LIMIT, Lane, MAX_ROAD_LENGTH, Map, SAMPLE_SPACING};
pub use opendrive::Lane as OdLane;
pub use opendrive::{
    Connection, ContactPoint, ElementType, Geometry, GeometryKind, Junction, LaneSection,
    LaneSpeed, LaneType, OpenDrive, PRange, Poly3Record, Road, RoadLink, RoadMark, RoadMarkRecord,
    RoadType,
};
pub use procedural::{
    JUNCTION_LENGTH, Layout, PRESET_NAMES, PROCEDURAL_SPEED_LIMIT, ProceduralMap, SHOULDER_WIDTH,
    curve, lane_drop, off_ramp_fork, on_ramp_merge, straight,
};
pub use query::{BEYOND_END_RANGE, BOX_OUTLINE_SPACING, BoxOnRoad, LaneProjection, PointLocation};
pub use raster::{RASTER_CELL, RoadRaster};
pub use reference_line::{RefPoint, eval_road};
pub use xodr_parse::parse_xodr;
pub use xodr_write::{OPENDRIVE_FILE, to_xodr};
