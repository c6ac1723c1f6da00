//! The road and lane topology of a parsed OpenDRIVE document, checked before it becomes a
//! map: linked road ends meet, every linked lane exists, no lane is wider than the radius it
//! bends around, and no reference line crosses itself. Each would otherwise give a map that
//! loads and is wrong (a car driving on through a gap or a fold, a link dropped in silence).
//! A problem names its element; the parser turns that into the element's line.

use super::lateral::{for_each_span, section_end, section_index};
use super::opendrive::{Connection, ContactPoint, ElementType, Junction, OpenDrive, Road};
use super::reference_line::eval_road;

/// How far apart (m) two linked ends may lie: joined roads touch up to the rounding of the
/// file's coordinates.
pub(super) const LINK_TOLERANCE: f64 = 0.1;

/// Spacing (m) of the samples along a reference line that the bend and crossing checks use.
const CHECK_SPACING: f64 = 0.5;

/// The element a problem is about.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Place {
    Road(String),
    /// A road's `<predecessor>` or `<successor>` link (`which` is the tag name).
    Link {
        road: String,
        which: &'static str,
    },
    /// Lane section `section` (in order) of a road.
    Lane {
        road: String,
        section: usize,
        lane: i32,
    },
    Connection {
        junction: String,
        id: String,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub(super) struct Problem {
    pub place: Place,
    pub message: String,
}

/// The first topology problem of `od`, if any.
pub(super) fn check(od: &OpenDrive) -> Option<Problem> {
    ids_are_unique(od)
        .or_else(|| references_exist(od))
        .or_else(|| links_meet(od))
        .or_else(|| connections_meet(od))
        .or_else(|| linked_lanes_exist(od))
        .or_else(|| linked_lane_edges_meet(od))
        .or_else(|| lanes_fit_their_bends(od))
        .or_else(|| reference_lines_do_not_cross(od))
}

/// No two roads, and no two junctions, share an id: a link to it would name either.
fn ids_are_unique(od: &OpenDrive) -> Option<Problem> {
    let repeated = |ids: Vec<&String>| {
        ids.iter()
            .enumerate()
            .find(|(k, id)| ids[..*k].contains(id))
            .map(|(_, id)| (*id).clone())
    };
    if let Some(id) = repeated(od.roads.iter().map(|r| &r.id).collect()) {
        let count = od.roads.iter().filter(|r| r.id == id).count();
        return Some(Problem {
            place: Place::Road(id.clone()),
            message: format!(
                "road id \"{id}\" is given to {count} roads; expected each road's id once"
            ),
        });
    }
    repeated(od.junctions.iter().map(|j| &j.id).collect()).map(|id| Problem {
        place: Place::Road(String::new()),
        message: format!("junction id \"{id}\" is given to more than one junction; expected each junction's id once"),
    })
}

/// Every road and junction a link or connection names is in the document.
fn references_exist(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        for (link, which) in [
            (&road.predecessor, "predecessor"),
            (&road.successor, "successor"),
        ] {
            let Some(link) = link else { continue };
            let (exists, kind) = match link.element_type {
                ElementType::Road => (od.road(&link.element_id).is_some(), "road"),
                ElementType::Junction => (
                    od.junctions.iter().any(|j| j.id == link.element_id),
                    "junction",
                ),
            };
            if !exists {
                return Some(Problem {
                    place: Place::Link {
                        road: road.id.clone(),
                        which,
                    },
                    message: format!(
                        "road {}: its {which} link refers to {kind} {:?}, which does not exist",
                        road.id, link.element_id
                    ),
                });
            }
        }
    }
    for junction in &od.junctions {
        for c in &junction.connections {
            for id in [&c.incoming_road, &c.connecting_road] {
                if od.road(id).is_none() {
                    return Some(Problem {
                        place: Place::Connection {
                            junction: junction.id.clone(),
                            id: c.id.clone(),
                        },
                        message: format!(
                            "junction {} connection {} refers to road {id:?}, which does not \
                             exist",
                            junction.id, c.id
                        ),
                    });
                }
            }
        }
    }
    None
}

/// The point of `road` at its `end`.
fn end_point(road: &Road, end: ContactPoint) -> [f64; 2] {
    let p = eval_road(
        road,
        if end == ContactPoint::Start {
            0.0
        } else {
            road.length
        },
    );
    [p.x, p.y]
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The cross-section of `road` at its `end`: the segment across it from its rightmost to its
/// leftmost lane boundary (the reference point included).
fn end_cross_section(road: &Road, end: ContactPoint) -> [[f64; 2]; 2] {
    let s = if end == ContactPoint::Start {
        0.0
    } else {
        road.length
    };
    let section = &road.lane_sections[section_index(road, s)];
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for_each_span(road, section, s, |_, span| {
        lo = lo.min(span.inner).min(span.outer);
        hi = hi.max(span.inner).max(span.outer);
    });
    let p = eval_road(road, s);
    [p.offset(lo), p.offset(hi)]
}

/// Distance from `p` to the segment `ab`.
fn to_segment(p: [f64; 2], [a, b]: [[f64; 2]; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    let u = if length2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    distance(p, [a[0] + u * dx, a[1] + u * dy])
}

/// How far the `a_end` of road `a` and the `b_end` of road `b` are from touching: roads meet
/// where one's end point lies on the other's end cross-section (a road in a junction often
/// joins another at one of its lanes, not at its reference line).
fn end_gap(a: &Road, a_end: ContactPoint, b: &Road, b_end: ContactPoint) -> f64 {
    let onto_b = to_segment(end_point(a, a_end), end_cross_section(b, b_end));
    let onto_a = to_segment(end_point(b, b_end), end_cross_section(a, a_end));
    onto_b.min(onto_a)
}

/// A road linked to a road touches it at the linked end (a road that is its own successor
/// must close on itself).
fn links_meet(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        let links = [
            (&road.predecessor, ContactPoint::Start, "predecessor"),
            (&road.successor, ContactPoint::End, "successor"),
        ];
        for (link, own_end, which) in links {
            let Some(link) = link
                .as_ref()
                .filter(|l| l.element_type == ElementType::Road)
            else {
                continue;
            };
            let Some(other) = od.road(&link.element_id) else {
                continue;
            };
            let contact = link.contact_point.unwrap_or(ContactPoint::Start);
            let gap = end_gap(road, own_end, other, contact);
            if gap > LINK_TOLERANCE {
                return Some(Problem {
                    place: Place::Link {
                        road: road.id.clone(),
                        which,
                    },
                    message: format!(
                        "road {} links its {} to the {} of road {}, but the two ends lie \
                         {gap:.2} m apart; expected them to meet (one's end on the other's end \
                         cross-section, within {LINK_TOLERANCE} m)",
                        road.id,
                        end_name(own_end),
                        end_name(contact),
                        other.id
                    ),
                });
            }
        }
    }
    None
}

fn end_name(end: ContactPoint) -> &'static str {
    match end {
        ContactPoint::Start => "start",
        ContactPoint::End => "end",
    }
}

/// Every junction connection with its incoming and connecting roads (those whose roads
/// exist; [`references_exist`] reports the others).
fn connections(od: &OpenDrive) -> impl Iterator<Item = (&Junction, &Connection, &Road, &Road)> {
    od.junctions.iter().flat_map(move |junction| {
        junction.connections.iter().filter_map(move |c| {
            let incoming = od.road(&c.incoming_road)?;
            let connecting = od.road(&c.connecting_road)?;
            Some((junction, c, incoming, connecting))
        })
    })
}

/// A junction connection's connecting road touches one end of its incoming road.
fn connections_meet(od: &OpenDrive) -> Option<Problem> {
    for (junction, c, incoming, connecting) in connections(od) {
        let gap = [ContactPoint::Start, ContactPoint::End]
            .map(|end| end_gap(incoming, end, connecting, c.contact_point))
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        if gap > LINK_TOLERANCE {
            return Some(Problem {
                place: Place::Connection {
                    junction: junction.id.clone(),
                    id: c.id.clone(),
                },
                message: format!(
                    "connecting road {} starts {gap:.2} m from either end of its incoming \
                     road {}; expected it to touch one (within {LINK_TOLERANCE} m)",
                    connecting.id, incoming.id
                ),
            });
        }
    }
    None
}

/// Every lane id a lane link names exists where it points: in the next or previous section of
/// the road, in the touching section of a linked road, or at the ends a junction connection
/// joins.
fn linked_lanes_exist(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        let last = road.lane_sections.len() - 1;
        for (k, section) in road.lane_sections.iter().enumerate() {
            for lane in section.lanes() {
                let place = || Place::Lane {
                    road: road.id.clone(),
                    section: k,
                    lane: lane.id,
                };
                let ends = [
                    (
                        &lane.predecessors,
                        "predecessor",
                        k.checked_sub(1),
                        &road.predecessor,
                        0,
                    ),
                    (
                        &lane.successors,
                        "successor",
                        (k < last).then_some(k + 1),
                        &road.successor,
                        1,
                    ),
                ];
                for (ids, which, neighbour, link, side) in ends {
                    let target = match (neighbour, link) {
                        (Some(n), _) => Some((road, n)),
                        (None, Some(l)) if l.element_type == ElementType::Road => {
                            od.road(&l.element_id).map(|other| {
                                let at_end = l.contact_point == Some(ContactPoint::End);
                                (
                                    other,
                                    if at_end {
                                        other.lane_sections.len() - 1
                                    } else {
                                        0
                                    },
                                )
                            })
                        }
                        // Into a junction: its connections say where lanes go.
                        (None, Some(_)) => continue,
                        (None, None) => None,
                    };
                    for &id in ids {
                        let exists =
                            target.is_some_and(|(r, n)| r.lane_sections[n].lane(id).is_some());
                        if !exists {
                            return Some(Problem {
                                place: place(),
                                message: missing_lane(road, lane.id, which, id, target, side),
                            });
                        }
                    }
                }
            }
        }
    }
    junction_lanes_exist(od)
}

fn missing_lane(
    road: &Road,
    lane: i32,
    which: &str,
    id: i32,
    target: Option<(&Road, usize)>,
    side: usize,
) -> String {
    let head = format!("lane {lane} of road {} names {which} lane {id}", road.id);
    match target {
        Some((r, n)) if r.id == road.id => {
            format!(
                "{head}, which lane section {n} of road {} does not have",
                r.id
            )
        }
        Some((r, _)) => format!(
            "{head}, which the touching lane section of road {} does not have",
            r.id
        ),
        None => format!(
            "{head}, but this is the road's {} lane section and the road has no {which} link",
            ["first", "last"][side]
        ),
    }
}

/// The lanes a junction connection links exist at the ends it joins.
fn junction_lanes_exist(od: &OpenDrive) -> Option<Problem> {
    for (junction, c, incoming, connecting) in connections(od) {
        let near_end = end_gap(incoming, ContactPoint::Start, connecting, c.contact_point)
            > end_gap(incoming, ContactPoint::End, connecting, c.contact_point);
        let incoming_section = if near_end {
            &incoming.lane_sections[incoming.lane_sections.len() - 1]
        } else {
            &incoming.lane_sections[0]
        };
        let connecting_section = match c.contact_point {
            ContactPoint::Start => &connecting.lane_sections[0],
            ContactPoint::End => &connecting.lane_sections[connecting.lane_sections.len() - 1],
        };
        for &(from, to) in &c.lane_links {
            let missing = if incoming_section.lane(from).is_none() {
                Some(format!("lane {from} of incoming road {}", incoming.id))
            } else if connecting_section.lane(to).is_none() {
                Some(format!("lane {to} of connecting road {}", connecting.id))
            } else {
                None
            };
            if let Some(what) = missing {
                return Some(Problem {
                    place: Place::Connection {
                        junction: junction.id.clone(),
                        id: c.id.clone(),
                    },
                    message: format!(
                        "a <laneLink> names {what}, which does not exist at the end the \
                         connection joins"
                    ),
                });
            }
        }
    }
    None
}

/// How far apart (m) the boundaries of two linked lanes may lie where they join: more, and a
/// car crossing the link would jump sideways or leave its lane.
pub(super) const EDGE_TOLERANCE: f64 = 0.5;

/// Lanes linked across roads (a road's lane links, a junction's lane links) join edge to
/// edge: both boundaries of one lane meet those of the other where the roads touch.
fn linked_lane_edges_meet(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        for (link, end, last) in [
            (&road.predecessor, ContactPoint::Start, false),
            (&road.successor, ContactPoint::End, true),
        ] {
            let Some(link) = link
                .as_ref()
                .filter(|l| l.element_type == ElementType::Road)
            else {
                continue;
            };
            let (Some(other), Some(other_end)) = (od.road(&link.element_id), link.contact_point)
            else {
                continue;
            };
            let section = if last {
                road.lane_sections.len() - 1
            } else {
                0
            };
            for lane in road.lane_sections[section].lanes().filter(|l| l.id != 0) {
                let ids = if last {
                    &lane.successors
                } else {
                    &lane.predecessors
                };
                for &to in ids {
                    if let Some(message) = edge_gap(road, end, lane.id, other, other_end, to) {
                        return Some(Problem {
                            place: Place::Lane {
                                road: road.id.clone(),
                                section,
                                lane: lane.id,
                            },
                            message,
                        });
                    }
                }
            }
        }
    }
    for (junction, c, incoming, connecting) in connections(od) {
        let near_end = if end_gap(incoming, ContactPoint::Start, connecting, c.contact_point)
            > end_gap(incoming, ContactPoint::End, connecting, c.contact_point)
        {
            ContactPoint::End
        } else {
            ContactPoint::Start
        };
        for &(from, to) in &c.lane_links {
            let gap = edge_gap(incoming, near_end, from, connecting, c.contact_point, to);
            if let Some(message) = gap {
                return Some(Problem {
                    place: Place::Connection {
                        junction: junction.id.clone(),
                        id: c.id.clone(),
                    },
                    message,
                });
            }
        }
    }
    None
}

/// Why lane `a_lane` at end `a_end` of road `a` and lane `b_lane` at end `b_end` of road `b`
/// do not join edge to edge, if they do not.
fn edge_gap(
    a: &Road,
    a_end: ContactPoint,
    a_lane: i32,
    b: &Road,
    b_end: ContactPoint,
    b_lane: i32,
) -> Option<String> {
    let ([a_inner, a_outer], [b_inner, b_outer]) =
        (lane_edges(a, a_end, a_lane)?, lane_edges(b, b_end, b_lane)?);
    let gap = distance(a_inner, b_inner).max(distance(a_outer, b_outer));
    (gap > EDGE_TOLERANCE).then(|| {
        format!(
            "lane {a_lane} of road {} and lane {b_lane} of road {}, linked, have edges {gap:.2} \
             m apart where they join (widths {:.2} and {:.2} m); expected their edges to meet \
             (within {EDGE_TOLERANCE} m)",
            a.id,
            b.id,
            distance(a_inner, a_outer),
            distance(b_inner, b_outer)
        )
    })
}

/// World positions of the inner and outer boundary of lane `id` at end `end` of `road`.
fn lane_edges(road: &Road, end: ContactPoint, id: i32) -> Option<[[f64; 2]; 2]> {
    let (section, s) = match end {
        ContactPoint::Start => (0, 0.0),
        ContactPoint::End => (road.lane_sections.len() - 1, road.length),
    };
    let mut span = None;
    for_each_span(road, &road.lane_sections[section], s, |lane, lane_span| {
        if lane.id == id {
            span = Some(lane_span);
        }
    });
    let span = span?;
    let point = eval_road(road, s);
    Some([point.offset(span.inner), point.offset(span.outer)])
}

/// The samples `s` of section `k` of `road` the geometric checks use (both ends included).
fn section_samples(road: &Road, k: usize) -> impl Iterator<Item = f64> {
    let s0 = road.lane_sections[k].s;
    let s1 = section_end(road, k).min(road.length);
    let n = ((s1 - s0) / CHECK_SPACING).ceil().max(1.0) as usize;
    (0..=n).map(move |j| s0 + (s1 - s0) * j as f64 / n as f64)
}

/// No lane boundary lies beyond the centre of the bend it follows: at curvature `k`, a
/// boundary `t` to the left of the reference line folds over itself once `t * k >= 1`.
fn lanes_fit_their_bends(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        for (k, section) in road.lane_sections.iter().enumerate() {
            for s in section_samples(road, k) {
                let curvature = eval_road(road, s).curvature;
                let mut problem = None;
                for_each_span(road, section, s, |lane, span| {
                    if problem.is_none() && span.width() > 0.0 && span.outer * curvature >= 1.0 {
                        problem = Some(Problem {
                            place: Place::Lane {
                                road: road.id.clone(),
                                section: k,
                                lane: lane.id,
                            },
                            message: format!(
                                "lane {} of road {} at s = {s:.1} m: its outer edge lies \
                                 {:.2} m from the reference line, beyond the {:.2} m radius of \
                                 the bend there; the lane would fold over itself",
                                lane.id,
                                road.id,
                                span.outer.abs(),
                                1.0 / curvature.abs()
                            ),
                        });
                    }
                });
                if problem.is_some() {
                    return problem;
                }
            }
        }
    }
    None
}

/// No road's reference line crosses itself (a loop drawn by its geometry).
fn reference_lines_do_not_cross(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        let n = (road.length / CHECK_SPACING).ceil().max(1.0) as usize;
        let points: Vec<[f64; 2]> = (0..=n)
            .map(|j| {
                let p = eval_road(road, road.length * j as f64 / n as f64);
                [p.x, p.y]
            })
            .collect();
        if let Some((a, b)) = first_crossing(&points) {
            return Some(Problem {
                place: Place::Road(road.id.clone()),
                message: format!(
                    "road {}: its reference line crosses itself near ({:.1}, {:.1}) (at s = \
                     {:.1} m and s = {:.1} m); expected a line that does not loop over itself",
                    road.id,
                    points[a][0],
                    points[a][1],
                    road.length * a as f64 / n as f64,
                    road.length * b as f64 / n as f64
                ),
            });
        }
    }
    None
}

/// The first pair of non-adjacent segments of the polyline `points` that properly cross, by
/// their first indices. Segments are bucketed on a grid so that long roads stay linear.
fn first_crossing(points: &[[f64; 2]]) -> Option<(usize, usize)> {
    use std::collections::HashMap;
    const CELL: f64 = 4.0 * CHECK_SPACING;
    let cell = |p: [f64; 2]| ((p[0] / CELL).floor() as i64, (p[1] / CELL).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    let segments = points.len().saturating_sub(1);
    let closed = segments > 2 && distance(points[0], points[segments]) < 1e-9;
    for i in 0..segments {
        let (a, b) = (cell(points[i]), cell(points[i + 1]));
        let mut candidates: Vec<usize> = Vec::new();
        for x in a.0.min(b.0)..=a.0.max(b.0) {
            for y in a.1.min(b.1)..=a.1.max(b.1) {
                let bucket = grid.entry((x, y)).or_default();
                candidates.extend(bucket.iter().copied());
                bucket.push(i);
            }
        }
        for j in candidates {
            let adjacent = i - j <= 1 || (closed && j == 0 && i == segments - 1);
            if !adjacent && cross(points[j], points[j + 1], points[i], points[i + 1]) {
                return Some((j, i));
            }
        }
    }
    None
}

/// Whether segments pq and rs cross at a point inside both.
fn cross(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> bool {
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let (d1, d2) = (orient(r, s, p), orient(r, s, q));
    let (d3, d4) = (orient(p, q, r), orient(p, q, s));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}
