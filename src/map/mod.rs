//! Road maps: an OpenDRIVE subset (parse, write, procedural generation), its lanes sampled
//! into polylines with topology, on-road and lane queries, and the paper's lane graph.

mod opendrive;
mod reference_line;
mod xodr_parse;
mod xodr_write;

pub use opendrive::Lane as OdLane;
pub use opendrive::{
    Connection, ContactPoint, ElementType, Geometry, GeometryKind, Junction, LaneSection,
    LaneSpeed, LaneType, OpenDrive, PRange, Poly3Record, Road, RoadLink, RoadMark,
    RoadMarkRecord, RoadType,
};
pub use reference_line::{RefPoint, eval_road};
pub use xodr_parse::parse_xodr;
pub use xodr_write::to_xodr;
