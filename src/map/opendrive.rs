//! The OpenDRIVE 1.4-1.6 subset rtr reads: plain data, one struct per XML element, lengths in
//! metres, angles in radians and speeds already converted to m/s. Parsing lives in
//! `xodr_parse.rs`, writing in `xodr_write.rs`; geometry is computed from these records by
//! `reference_line.rs` and `lanes.rs`.

/// A whole map: its roads and the junctions that join them.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct OpenDrive {
    pub roads: Vec<Road>,
    pub junctions: Vec<Junction>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Road {
    pub id: String,
    pub name: String,
    /// Length of the reference line (m).
    pub length: f64,
    /// Id of the junction this road belongs to (a connecting road), `None` for "-1".
    pub junction: Option<String>,
    pub predecessor: Option<RoadLink>,
    pub successor: Option<RoadLink>,
    /// `<type>` records, sorted by `s`.
    pub types: Vec<RoadType>,
    /// `<planView>` geometries, sorted by `s`.
    pub geometries: Vec<Geometry>,
    /// `<laneOffset>` records, sorted by `s`.
    pub lane_offsets: Vec<Poly3Record>,
    /// `<laneSection>`s, sorted by `s`.
    pub lane_sections: Vec<LaneSection>,
}

/// Whether a link points to a road or to a junction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElementType {
    Road,
    Junction,
}

/// Which end of the linked road touches this one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactPoint {
    Start,
    End,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RoadLink {
    pub element_type: ElementType,
    pub element_id: String,
    /// Required for road links, absent for junction links.
    pub contact_point: Option<ContactPoint>,
}

/// A `<type>` record: the road class from `s` on and its speed limit, if given.
#[derive(Clone, Debug, PartialEq)]
pub struct RoadType {
    pub s: f64,
    pub kind: String,
    /// m/s; `None` when absent or "no limit" / "undefined".
    pub speed: Option<f64>,
}

/// One `<geometry>` of the plan view.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    pub s: f64,
    pub x: f64,
    pub y: f64,
    pub hdg: f64,
    pub length: f64,
    pub kind: GeometryKind,
}

#[derive(Clone, Debug, PartialEq)]
pub enum GeometryKind {
    Line,
    Arc {
        curvature: f64,
    },
    /// Clothoid: curvature changes linearly from `curv_start` to `curv_end`.
    Spiral {
        curv_start: f64,
        curv_end: f64,
    },
    /// Local v = a + b u + c u^2 + d u^3 in the frame at (x, y, hdg).
    Poly3 {
        a: f64,
        b: f64,
        c: f64,
        d: f64,
    },
    /// Local u(p), v(p) cubics; p runs over [0, length] or [0, 1] depending on `p_range`.
    ParamPoly3 {
        u: [f64; 4],
        v: [f64; 4],
        p_range: PRange,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PRange {
    ArcLength,
    Normalized,
}

/// A cubic a + b ds + c ds^2 + d ds^3 starting at `s` (laneOffset) or at `s_offset` from the
/// section start (lane width).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Poly3Record {
    pub s: f64,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub d: f64,
}

impl Poly3Record {
    pub fn value(&self, ds: f64) -> f64 {
        self.a + ds * (self.b + ds * (self.c + ds * self.d))
    }

    pub fn derivative(&self, ds: f64) -> f64 {
        self.b + ds * (2.0 * self.c + ds * 3.0 * self.d)
    }
}

/// Picks the record in effect at `s` from records sorted by start: the last one starting at or
/// before `s`, or the first one when `s` lies before all of them.
pub fn record_at<T>(records: &[T], s: f64, start: impl Fn(&T) -> f64) -> Option<&T> {
    let after = records.partition_point(|r| start(r) <= s);
    records.get(after.saturating_sub(1))
}

#[derive(Clone, Debug, PartialEq)]
pub struct LaneSection {
    pub s: f64,
    /// Positive ids, sorted 1, 2, 3... (innermost first).
    pub left: Vec<Lane>,
    /// The id-0 lane: carries the centre road mark, has no width.
    pub center: Option<Lane>,
    /// Negative ids, sorted -1, -2, -3... (innermost first).
    pub right: Vec<Lane>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Lane {
    pub id: i32,
    pub kind: LaneType,
    /// `<width>` records; `s` holds the record's sOffset from the section start.
    pub widths: Vec<Poly3Record>,
    pub road_marks: Vec<RoadMarkRecord>,
    pub speeds: Vec<LaneSpeed>,
    pub predecessors: Vec<i32>,
    pub successors: Vec<i32>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LaneType {
    Driving,
    Shoulder,
    None,
    Border,
    Stop,
    Restricted,
    Parking,
    Median,
    Biking,
    Sidewalk,
    Entry,
    Exit,
    OnRamp,
    OffRamp,
    ConnectingRamp,
    Other(String),
}

const LANE_TYPE_NAMES: [(LaneType, &str); 15] = [
    (LaneType::Driving, "driving"),
    (LaneType::Shoulder, "shoulder"),
    (LaneType::None, "none"),
    (LaneType::Border, "border"),
    (LaneType::Stop, "stop"),
    (LaneType::Restricted, "restricted"),
    (LaneType::Parking, "parking"),
    (LaneType::Median, "median"),
    (LaneType::Biking, "biking"),
    (LaneType::Sidewalk, "sidewalk"),
    (LaneType::Entry, "entry"),
    (LaneType::Exit, "exit"),
    (LaneType::OnRamp, "onRamp"),
    (LaneType::OffRamp, "offRamp"),
    (LaneType::ConnectingRamp, "connectingRamp"),
];

/// The other lane types of OpenDRIVE 1.4 to 1.8, which rtr keeps verbatim as
/// [`LaneType::Other`] (none of them is driven).
pub const OTHER_LANE_TYPES: [&str; 16] = [
    "bidirectional",
    "special1",
    "special2",
    "special3",
    "roadWorks",
    "tram",
    "rail",
    "bus",
    "taxi",
    "HOV",
    "mwyEntry",
    "mwyExit",
    "walking",
    "slipLane",
    "curb",
    "shared",
];

impl LaneType {
    /// Whether `name` is a lane type of the OpenDRIVE standard (a misspelt one would turn a
    /// driving lane into something else in silence).
    pub fn is_standard(name: &str) -> bool {
        LANE_TYPE_NAMES.iter().any(|(_, n)| *n == name) || OTHER_LANE_TYPES.contains(&name)
    }

    /// The standard's names, for messages.
    pub fn standard_names() -> Vec<&'static str> {
        LANE_TYPE_NAMES
            .iter()
            .map(|(_, n)| *n)
            .chain(OTHER_LANE_TYPES)
            .collect()
    }

    /// OpenDRIVE spelling; anything unknown is kept verbatim.
    pub fn from_name(name: &str) -> LaneType {
        LANE_TYPE_NAMES
            .iter()
            .find(|(_, n)| *n == name)
            .map(|(t, _)| t.clone())
            .unwrap_or_else(|| LaneType::Other(name.to_string()))
    }

    pub fn name(&self) -> &str {
        match self {
            LaneType::Other(s) => s,
            known => LANE_TYPE_NAMES
                .iter()
                .find(|(t, _)| t == known)
                .map_or("none", |(_, n)| n),
        }
    }
}

/// Lane marking type of a `<roadMark>`.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum RoadMark {
    #[default]
    None,
    Solid,
    Broken,
    SolidSolid,
    SolidBroken,
    BrokenSolid,
    BrokenBroken,
    BottsDots,
    Grass,
    Curb,
    Edge,
    Custom,
    Other(String),
}

const ROAD_MARK_NAMES: [(RoadMark, &str); 12] = [
    (RoadMark::None, "none"),
    (RoadMark::Solid, "solid"),
    (RoadMark::Broken, "broken"),
    (RoadMark::SolidSolid, "solid solid"),
    (RoadMark::SolidBroken, "solid broken"),
    (RoadMark::BrokenSolid, "broken solid"),
    (RoadMark::BrokenBroken, "broken broken"),
    (RoadMark::BottsDots, "botts dots"),
    (RoadMark::Grass, "grass"),
    (RoadMark::Curb, "curb"),
    (RoadMark::Edge, "edge"),
    (RoadMark::Custom, "custom"),
];

/// The `color` values of a `<roadMark>` in OpenDRIVE 1.4 to 1.8.
pub const ROAD_MARK_COLORS: [&str; 9] = [
    "standard", "blue", "green", "red", "white", "yellow", "orange", "violet", "black",
];

impl RoadMark {
    /// The standard's `type` values.
    pub fn standard_names() -> Vec<&'static str> {
        ROAD_MARK_NAMES.iter().map(|(_, n)| *n).collect()
    }

    pub fn from_name(name: &str) -> RoadMark {
        ROAD_MARK_NAMES
            .iter()
            .find(|(_, n)| *n == name)
            .map(|(t, _)| t.clone())
            .unwrap_or_else(|| RoadMark::Other(name.to_string()))
    }

    pub fn name(&self) -> &str {
        match self {
            RoadMark::Other(s) => s,
            known => ROAD_MARK_NAMES
                .iter()
                .find(|(t, _)| t == known)
                .map_or("none", |(_, n)| n),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct RoadMarkRecord {
    /// From the section start (m).
    pub s_offset: f64,
    pub kind: RoadMark,
    pub color: Option<String>,
    /// Painted line width (m).
    pub width: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneSpeed {
    /// From the section start (m).
    pub s_offset: f64,
    /// m/s; `None` for "no limit" / "undefined".
    pub max: Option<f64>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Junction {
    pub id: String,
    pub name: String,
    pub connections: Vec<Connection>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Connection {
    pub id: String,
    pub incoming_road: String,
    pub connecting_road: String,
    /// The end of the connecting road that touches the incoming road.
    pub contact_point: ContactPoint,
    /// (lane of the incoming road, lane of the connecting road).
    pub lane_links: Vec<(i32, i32)>,
}

impl OpenDrive {
    pub fn road(&self, id: &str) -> Option<&Road> {
        self.roads.iter().find(|r| r.id == id)
    }
}

impl LaneSection {
    /// Left, center and right lanes in one iterator.
    pub fn lanes(&self) -> impl Iterator<Item = &Lane> {
        self.left
            .iter()
            .chain(self.center.iter())
            .chain(self.right.iter())
    }

    pub fn lane(&self, id: i32) -> Option<&Lane> {
        self.lanes().find(|l| l.id == id)
    }

    /// The lanes of this end section of a road (its last one when `at_end`) joined across a
    /// road link to the `other` road's end section (its last when `other_at_end`), as (id
    /// here, id there): the lane links either side declares toward the other (`successors` at
    /// a road's end, `predecessors` at its start). Where neither declares one, the lanes
    /// continue into the other road's lanes on the same side of traffic: the same id when the
    /// roads run the same way (one's end meets the other's start), the opposite id when they
    /// meet head-on. Pairs may repeat (declared on both sides).
    pub fn links_across(
        &self,
        at_end: bool,
        other: &LaneSection,
        other_at_end: bool,
    ) -> Vec<(i32, i32)> {
        let toward = |lane: &Lane, end: bool| -> Vec<i32> {
            if end {
                lane.successors.clone()
            } else {
                lane.predecessors.clone()
            }
        };
        let mut declared: Vec<(i32, i32)> = Vec::new();
        for lane in self.lanes() {
            declared.extend(toward(lane, at_end).into_iter().map(|to| (lane.id, to)));
        }
        for lane in other.lanes() {
            declared.extend(
                toward(lane, other_at_end)
                    .into_iter()
                    .map(|from| (from, lane.id)),
            );
        }
        if !declared.is_empty() {
            return declared;
        }
        let same_direction = at_end != other_at_end;
        self.lanes()
            .filter(|lane| lane.id != 0)
            .map(|lane| {
                let to = if same_direction { lane.id } else { -lane.id };
                (lane.id, to)
            })
            .filter(|&(_, to)| other.lane(to).is_some())
            .collect()
    }

    /// The lanes of this section joined to those of the `next` one of the same road, as (id
    /// here, id there): each lane's declared successors, the lanes of `next` that declare a
    /// predecessor, and, where neither side declares a link, the lane with the same id.
    /// Pairs may repeat (declared on both sides).
    pub fn links_to(&self, next: &LaneSection) -> Vec<(i32, i32)> {
        let mut out = Vec::new();
        for lane in self.lanes() {
            out.extend(lane.successors.iter().map(|&to| (lane.id, to)));
            let undeclared = next.lane(lane.id).is_none_or(|l| l.predecessors.is_empty());
            if lane.successors.is_empty() && undeclared && next.lane(lane.id).is_some() {
                out.push((lane.id, lane.id));
            }
        }
        for lane in next.lanes() {
            out.extend(lane.predecessors.iter().map(|&from| (from, lane.id)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(lanes: &[(i32, &[i32], &[i32])]) -> LaneSection {
        let lane = |&(id, predecessors, successors): &(i32, &[i32], &[i32])| Lane {
            id,
            kind: LaneType::Driving,
            widths: Vec::new(),
            road_marks: Vec::new(),
            speeds: Vec::new(),
            predecessors: predecessors.to_vec(),
            successors: successors.to_vec(),
        };
        LaneSection {
            s: 0.0,
            left: lanes.iter().filter(|l| l.0 > 0).map(lane).collect(),
            center: None,
            right: lanes.iter().filter(|l| l.0 < 0).map(lane).collect(),
        }
    }

    #[test]
    fn lanes_join_across_a_road_link_as_declared_on_either_side_else_by_side_of_traffic() {
        let plain = section(&[(-1, &[], &[]), (-2, &[], &[]), (1, &[], &[])]);
        // Nothing declared: the same id one after the other, the opposite id head-on.
        assert_eq!(
            plain.links_across(true, &plain, false),
            vec![(1, 1), (-1, -1), (-2, -2)]
        );
        assert_eq!(
            plain.links_across(true, &plain, true),
            vec![(1, -1), (-1, 1)]
        );
        // Declared on the other road only (its lane -1 starts from lane -2 here): that is
        // the join, and no lane is joined by its id as well.
        let shifted = section(&[(-1, &[-2], &[]), (-2, &[], &[])]);
        assert_eq!(plain.links_across(true, &shifted, false), vec![(-2, -1)]);
        // Declared here: used as declared.
        let own = section(&[(-1, &[], &[-2]), (-2, &[], &[])]);
        assert_eq!(own.links_across(true, &plain, false), vec![(-1, -2)]);
    }

    #[test]
    fn record_at_picks_last_started_record() {
        let r = [0.0, 10.0, 20.0];
        assert_eq!(record_at(&r, -1.0, |x| *x), Some(&0.0));
        assert_eq!(record_at(&r, 10.0, |x| *x), Some(&10.0));
        assert_eq!(record_at(&r, 19.9, |x| *x), Some(&10.0));
        assert_eq!(record_at(&r, 99.0, |x| *x), Some(&20.0));
        assert_eq!(record_at::<f64>(&[], 1.0, |x| *x), None);
    }

    #[test]
    fn names_round_trip() {
        for (t, n) in LANE_TYPE_NAMES.iter() {
            assert_eq!(&LaneType::from_name(n), t);
            assert_eq!(t.name(), *n);
        }
        assert_eq!(LaneType::from_name("tram").name(), "tram");
        for (m, n) in ROAD_MARK_NAMES.iter() {
            assert_eq!(&RoadMark::from_name(n), m);
            assert_eq!(m.name(), *n);
        }
    }
}
