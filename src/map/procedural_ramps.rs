//! Generated one-way highway maps with ramps and a lane drop (parameters are validated by
//! [`ProceduralMap::build`](super::ProceduralMap::build)). The main road runs along +x from
//! the origin; ramps join or leave on the right.
//!
//! Road ids: "1" main road upstream of the junction, "3" downstream, "2" the ramp,
//! "10"/"20" the junction's through connection and "11"/"21" its ramp connection.

use super::opendrive::{
    Connection, ContactPoint, GeometryKind, Junction, Lane, LaneType, OpenDrive, RoadMark,
};
use super::procedural::{JUNCTION_LENGTH, SHOULDER_WIDTH};
use super::procedural_parts::{
    carriageway, chain, constant, junction_link, lane, road, road_link, section, taper,
};

/// Ramp shape: leaves the main direction by `RAMP_ANGLE` through an arc of `RAMP_RADIUS`,
/// plus a straight part of `RAMP_LINE`.
const RAMP_ANGLE: f64 = 0.2;
const RAMP_RADIUS: f64 = 250.0;
const RAMP_LINE: f64 = 80.0;

fn id(k: usize) -> i32 {
    -(k as i32)
}

/// Driving lanes -1..-n, all with broken outer marks (a lane runs outside them).
fn inner_lanes(n: usize, w: f64) -> Vec<Lane> {
    (1..=n)
        .map(|k| lane(id(k), LaneType::Driving, constant(w), RoadMark::Broken))
        .collect()
}

/// A one-lane ramp road: `kind` lane -1 and a shoulder.
fn ramp_lanes(kind: LaneType, w: f64) -> Vec<Lane> {
    vec![
        lane(-1, kind, constant(w), RoadMark::Solid),
        lane(
            -2,
            LaneType::Shoulder,
            constant(SHOULDER_WIDTH),
            RoadMark::None,
        ),
    ]
}

/// A straight connecting road of the junction from x0 at lateral y, lanes as given.
fn connecting(
    id_: &str,
    junction: &str,
    x0: f64,
    y: f64,
    lanes: Vec<Lane>,
) -> super::opendrive::Road {
    let mut r = road(
        id_,
        JUNCTION_LENGTH,
        chain([x0, y, 0.0], &[(JUNCTION_LENGTH, GeometryKind::Line)]),
        vec![section(0.0, RoadMark::Solid, lanes)],
    );
    r.junction = Some(junction.to_string());
    r
}

fn link_through(lanes: &mut [Lane], pred: bool, succ: bool) {
    for l in lanes {
        if pred {
            l.predecessors = vec![l.id];
        }
        if succ {
            l.successors = vec![l.id];
        }
    }
}

pub(super) fn on_ramp_map(
    n: usize,
    w: f64,
    length: f64,
    merge_s: f64,
    accel: f64,
    taper_len: f64,
) -> OpenDrive {
    let j = "100";
    let x3 = merge_s + JUNCTION_LENGTH;
    let mut up = road(
        "1",
        merge_s,
        chain([0.0, 0.0, 0.0], &[(merge_s, GeometryKind::Line)]),
        vec![section(0.0, RoadMark::Solid, carriageway(n, w, 0))],
    );
    up.successor = junction_link(j);

    // Downstream: acceleration lane -(n+1), its taper, then the plain carriageway.
    let with_entry = |widths| {
        let mut l = inner_lanes(n, w);
        l.push(lane(id(n + 1), LaneType::Entry, widths, RoadMark::Solid));
        l.push(lane(
            id(n + 2),
            LaneType::Shoulder,
            constant(SHOULDER_WIDTH),
            RoadMark::None,
        ));
        l
    };
    let s0 = section(0.0, RoadMark::Solid, with_entry(constant(w)));
    let mut s1 = section(accel, RoadMark::Solid, with_entry(taper(w, 0.0, taper_len)));
    // The tapered lane merges into the rightmost main lane; the shoulder moves inward.
    s1.right[n].successors = vec![id(n)];
    s1.right[n + 1].successors = vec![id(n + 1)];
    let s2 = section(accel + taper_len, RoadMark::Solid, carriageway(n, w, 0));
    let down_len = length - x3;
    let mut down = road(
        "3",
        down_len,
        chain([x3, 0.0, 0.0], &[(down_len, GeometryKind::Line)]),
        vec![s0, s1, s2],
    );
    down.predecessor = junction_link(j);

    // The ramp approaches at RAMP_ANGLE from the right and ends parallel at the junction.
    let pieces = [
        (RAMP_LINE, GeometryKind::Line),
        (
            RAMP_ANGLE * RAMP_RADIUS,
            GeometryKind::Arc {
                curvature: -1.0 / RAMP_RADIUS,
            },
        ),
    ];
    let probe = chain([0.0, 0.0, RAMP_ANGLE], &pieces);
    let end = probe[1].eval(probe[1].length);
    let ramp_y = -(n as f64) * w;
    let ramp_len = RAMP_LINE + RAMP_ANGLE * RAMP_RADIUS;
    let mut ramp = road(
        "2",
        ramp_len,
        chain([merge_s - end.x, ramp_y - end.y, RAMP_ANGLE], &pieces),
        vec![section(
            0.0,
            RoadMark::Solid,
            ramp_lanes(LaneType::OnRamp, w),
        )],
    );
    ramp.successor = junction_link(j);

    let mut through_lanes = inner_lanes(n, w);
    link_through(&mut through_lanes, true, true);
    let mut through = connecting("10", j, merge_s, 0.0, through_lanes);
    through.predecessor = road_link("1", ContactPoint::End);
    through.successor = road_link("3", ContactPoint::Start);
    let mut ramp_conn_lane = lane(-1, LaneType::OnRamp, constant(w), RoadMark::Solid);
    ramp_conn_lane.predecessors = vec![-1];
    ramp_conn_lane.successors = vec![id(n + 1)];
    let mut ramp_conn = connecting("11", j, merge_s, ramp_y, vec![ramp_conn_lane]);
    ramp_conn.predecessor = road_link("2", ContactPoint::End);
    ramp_conn.successor = road_link("3", ContactPoint::Start);

    let junction = Junction {
        id: j.to_string(),
        name: "on-ramp merge".to_string(),
        connections: vec![
            Connection {
                id: "0".into(),
                incoming_road: "1".into(),
                connecting_road: "10".into(),
                contact_point: ContactPoint::Start,
                lane_links: (1..=n).map(|k| (id(k), id(k))).collect(),
            },
            Connection {
                id: "1".into(),
                incoming_road: "2".into(),
                connecting_road: "11".into(),
                contact_point: ContactPoint::Start,
                lane_links: vec![(-1, -1)],
            },
        ],
    };
    OpenDrive {
        roads: vec![up, ramp, down, through, ramp_conn],
        junctions: vec![junction],
    }
}

pub(super) fn off_ramp_map(
    n: usize,
    w: f64,
    length: f64,
    diverge_s: f64,
    decel: f64,
    taper_len: f64,
) -> OpenDrive {
    let j = "200";
    let x3 = diverge_s + JUNCTION_LENGTH;
    let open_s = diverge_s - decel - taper_len;
    let with_exit = |widths| {
        let mut l = inner_lanes(n, w);
        l.push(lane(id(n + 1), LaneType::Exit, widths, RoadMark::Solid));
        l.push(lane(
            id(n + 2),
            LaneType::Shoulder,
            constant(SHOULDER_WIDTH),
            RoadMark::None,
        ));
        l
    };
    let mut s0 = section(0.0, RoadMark::Solid, carriageway(n, w, 0));
    // The rightmost lane forks into itself and the opening exit lane.
    s0.right[n - 1].successors = vec![id(n), id(n + 1)];
    s0.right[n].successors = vec![id(n + 2)];
    let mut s1 = section(open_s, RoadMark::Solid, with_exit(taper(0.0, w, taper_len)));
    s1.right[n].predecessors = vec![id(n)];
    let s2 = section(diverge_s - decel, RoadMark::Solid, with_exit(constant(w)));
    let mut up = road(
        "1",
        diverge_s,
        chain([0.0, 0.0, 0.0], &[(diverge_s, GeometryKind::Line)]),
        vec![s0, s1, s2],
    );
    up.successor = junction_link(j);

    let down_len = length - x3;
    let mut down = road(
        "3",
        down_len,
        chain([x3, 0.0, 0.0], &[(down_len, GeometryKind::Line)]),
        vec![section(0.0, RoadMark::Solid, carriageway(n, w, 0))],
    );
    down.predecessor = junction_link(j);

    let ramp_y = -(n as f64) * w;
    let pieces = [
        (
            RAMP_ANGLE * RAMP_RADIUS,
            GeometryKind::Arc {
                curvature: -1.0 / RAMP_RADIUS,
            },
        ),
        (RAMP_LINE, GeometryKind::Line),
    ];
    let mut ramp = road(
        "2",
        RAMP_LINE + RAMP_ANGLE * RAMP_RADIUS,
        chain([x3, ramp_y, 0.0], &pieces),
        vec![section(
            0.0,
            RoadMark::Solid,
            ramp_lanes(LaneType::OffRamp, w),
        )],
    );
    ramp.predecessor = junction_link(j);

    let mut through_lanes = inner_lanes(n, w);
    link_through(&mut through_lanes, true, true);
    let mut through = connecting("20", j, diverge_s, 0.0, through_lanes);
    through.predecessor = road_link("1", ContactPoint::End);
    through.successor = road_link("3", ContactPoint::Start);
    let mut exit_lane = lane(-1, LaneType::OffRamp, constant(w), RoadMark::Solid);
    exit_lane.predecessors = vec![id(n + 1)];
    exit_lane.successors = vec![-1];
    let mut exit_conn = connecting("21", j, diverge_s, ramp_y, vec![exit_lane]);
    exit_conn.predecessor = road_link("1", ContactPoint::End);
    exit_conn.successor = road_link("2", ContactPoint::Start);

    let junction = Junction {
        id: j.to_string(),
        name: "off-ramp fork".to_string(),
        connections: vec![
            Connection {
                id: "0".into(),
                incoming_road: "1".into(),
                connecting_road: "20".into(),
                contact_point: ContactPoint::Start,
                lane_links: (1..=n).map(|k| (id(k), id(k))).collect(),
            },
            Connection {
                id: "1".into(),
                incoming_road: "1".into(),
                connecting_road: "21".into(),
                contact_point: ContactPoint::Start,
                lane_links: vec![(id(n + 1), -1)],
            },
        ],
    };
    OpenDrive {
        roads: vec![up, ramp, down, through, exit_conn],
        junctions: vec![junction],
    }
}

pub(super) fn lane_drop_map(
    n: usize,
    w: f64,
    length: f64,
    drop_s: f64,
    taper_len: f64,
) -> OpenDrive {
    let s0 = section(0.0, RoadMark::Solid, carriageway(n, w, 0));
    let mut s1 = section(drop_s, RoadMark::Solid, carriageway(n, w, 0));
    s1.right[n - 1].widths = taper(w, 0.0, taper_len);
    // The dropped lane ends; the shoulder moves inward (declared on both sides so the
    // same-id default cannot join the dropped lane to the shoulder).
    s1.right[n].successors = vec![id(n)];
    let mut s2 = section(
        drop_s + taper_len,
        RoadMark::Solid,
        carriageway(n - 1, w, 0),
    );
    s2.right[n - 1].predecessors = vec![id(n + 1)];
    OpenDrive {
        roads: vec![road(
            "0",
            length,
            chain([0.0, 0.0, 0.0], &[(length, GeometryKind::Line)]),
            vec![s0, s1, s2],
        )],
        junctions: vec![],
    }
}
