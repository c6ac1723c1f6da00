//! Building blocks of the procedural maps: geometry chains, width polynomials, lanes with
//! their marks, carriageways, sections, roads and links.

use super::opendrive::{
    ContactPoint, ElementType, Geometry, GeometryKind, Lane, LaneSection, LaneType, Poly3Record,
    Road, RoadLink, RoadMark, RoadMarkRecord, RoadType,
};
use super::procedural::{PROCEDURAL_SPEED_LIMIT, SHOULDER_WIDTH};

/// Geometries laid end to end from `start` = [x, y, hdg].
pub(super) fn chain(start: [f64; 3], pieces: &[(f64, GeometryKind)]) -> Vec<Geometry> {
    let mut out: Vec<Geometry> = Vec::with_capacity(pieces.len());
    let (mut s, mut pose) = (0.0, start);
    for (length, kind) in pieces {
        let g = Geometry {
            s,
            x: pose[0],
            y: pose[1],
            hdg: pose[2],
            length: *length,
            kind: kind.clone(),
        };
        let end = g.eval(*length);
        pose = [end.x, end.y, end.hdg];
        s += length;
        out.push(g);
    }
    out
}

pub(super) fn constant(a: f64) -> Vec<Poly3Record> {
    vec![Poly3Record {
        s: 0.0,
        a,
        b: 0.0,
        c: 0.0,
        d: 0.0,
    }]
}

/// Cubic width from `from` to `to` over `len` with zero slope at both ends.
pub(super) fn taper(from: f64, to: f64, len: f64) -> Vec<Poly3Record> {
    let dw = to - from;
    vec![Poly3Record {
        s: 0.0,
        a: from,
        b: 0.0,
        c: 3.0 * dw / (len * len),
        d: -2.0 * dw / (len * len * len),
    }]
}

pub(super) fn lane(id: i32, kind: LaneType, widths: Vec<Poly3Record>, mark: RoadMark) -> Lane {
    let painted = mark != RoadMark::None;
    Lane {
        id,
        kind,
        widths,
        road_marks: vec![RoadMarkRecord {
            s_offset: 0.0,
            kind: mark,
            color: painted.then(|| "white".to_string()),
            width: painted.then_some(0.15),
        }],
        speeds: vec![],
        predecessors: vec![],
        successors: vec![],
    }
}

pub(super) fn center_lane(mark: RoadMark) -> Lane {
    let mut c = lane(0, LaneType::None, vec![], mark);
    c.widths.clear();
    c
}

/// `n` driving lanes (broken marks between them, solid outside) and a shoulder, right of the
/// reference line, ids starting after `first_id_offset` inner lanes.
pub(super) fn carriageway(n: usize, w: f64, first_id_offset: usize) -> Vec<Lane> {
    let mut lanes: Vec<Lane> = (1..=n)
        .map(|k| {
            let mark = if k == n {
                RoadMark::Solid
            } else {
                RoadMark::Broken
            };
            lane(
                -((k + first_id_offset) as i32),
                LaneType::Driving,
                constant(w),
                mark,
            )
        })
        .collect();
    lanes.push(lane(
        -((n + 1 + first_id_offset) as i32),
        LaneType::Shoulder,
        constant(SHOULDER_WIDTH),
        RoadMark::None,
    ));
    lanes
}

pub(super) fn section(s: f64, center_mark: RoadMark, right: Vec<Lane>) -> LaneSection {
    LaneSection {
        s,
        left: vec![],
        center: Some(center_lane(center_mark)),
        right,
    }
}

pub(super) fn road(
    id: &str,
    length: f64,
    geometries: Vec<Geometry>,
    lane_sections: Vec<LaneSection>,
) -> Road {
    Road {
        id: id.to_string(),
        name: format!("rtr road {id}"),
        length,
        junction: None,
        predecessor: None,
        successor: None,
        types: vec![RoadType {
            s: 0.0,
            kind: "motorway".to_string(),
            speed: Some(PROCEDURAL_SPEED_LIMIT),
        }],
        geometries,
        lane_offsets: vec![],
        lane_sections,
    }
}

pub(super) fn road_link(id: &str, contact: ContactPoint) -> Option<RoadLink> {
    Some(RoadLink {
        element_type: ElementType::Road,
        element_id: id.to_string(),
        contact_point: Some(contact),
    })
}

pub(super) fn junction_link(id: &str) -> Option<RoadLink> {
    Some(RoadLink {
        element_type: ElementType::Junction,
        element_id: id.to_string(),
        contact_point: None,
    })
}
