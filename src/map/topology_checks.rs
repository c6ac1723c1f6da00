//! The road and lane topology of a parsed OpenDRIVE document, checked before it becomes a
//! map: linked road ends meet and carry the direction of travel on, every junction connects
//! something, every linked lane exists and joins edge to edge; then each road's shape
//! ([`super::shape_checks`]). Each would otherwise give a map that loads and is wrong (a car
//! driving on through a gap, a link dropped in silence). A problem names its element; the
//! parser turns that into the element's line.

use super::lateral::{for_each_span, section_index};
use super::number_text::Num;
use super::opendrive::{Connection, ContactPoint, ElementType, Junction, OpenDrive, Road};
use super::reference_line::eval_road;

/// How far apart (m) two linked ends may lie: joined roads touch up to the rounding of the
/// file's coordinates.
pub(super) const LINK_TOLERANCE: f64 = 0.1;

/// Spacing (m) of the samples along a reference line that the bend and crossing checks use.
pub(super) const CHECK_SPACING: f64 = 0.5;

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
    Junction(String),
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
        .or_else(|| junctions_connect(od))
        .or_else(|| links_meet(od))
        .or_else(|| links_keep_direction(od))
        .or_else(|| connections_meet(od))
        .or_else(|| junction_members_agree(od))
        .or_else(|| links_are_mutual(od))
        .or_else(|| linked_lanes_exist(od))
        .or_else(|| linked_lane_edges_meet(od))
        .or_else(|| super::shape_checks::check(od))
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

pub(super) fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
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
    cross_section(road, s)
}

/// The segment across `road` at `s` from its rightmost to its leftmost lane boundary.
pub(super) fn cross_section(road: &Road, s: f64) -> [[f64; 2]; 2] {
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
pub(super) fn to_segment(p: [f64; 2], [a, b]: [[f64; 2]; 2]) -> f64 {
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

/// A road's link to another road: the road, its linked end, the link's tag, the other road
/// and the other's end it joins.
struct LinkedEnds<'a> {
    road: &'a Road,
    own_end: ContactPoint,
    which: &'static str,
    other: &'a Road,
    contact: ContactPoint,
}

impl LinkedEnds<'_> {
    /// A problem at this link's element, its message led by which ends it joins.
    fn problem(&self, finding: String) -> Problem {
        Problem {
            place: Place::Link {
                road: self.road.id.clone(),
                which: self.which,
            },
            message: format!(
                "road {} links its {} to the {} of road {}, but {finding}",
                self.road.id,
                end_name(self.own_end),
                end_name(self.contact),
                self.other.id
            ),
        }
    }
}

/// Every road-to-road link whose other road exists ([`references_exist`] reports the rest).
fn road_links(od: &OpenDrive) -> impl Iterator<Item = LinkedEnds<'_>> {
    od.roads.iter().flat_map(move |road| {
        [
            (&road.predecessor, ContactPoint::Start, "predecessor"),
            (&road.successor, ContactPoint::End, "successor"),
        ]
        .into_iter()
        .filter_map(move |(link, own_end, which)| {
            let link = link
                .as_ref()
                .filter(|l| l.element_type == ElementType::Road)?;
            Some(LinkedEnds {
                road,
                own_end,
                which,
                other: od.road(&link.element_id)?,
                contact: link.contact_point.unwrap_or(ContactPoint::Start),
            })
        })
    })
}

/// Two roads joined outside a junction name each other: a road's `successor` with contact
/// point `start` is answered by the other road's `predecessor` naming it with contact point
/// `end` (the standard's road linkage). A link one road states and the other denies or leaves
/// out is a file that disagrees with itself: which of the two was meant cannot be told.
/// Connecting roads inside a junction are linked one way by design (the incoming road links
/// to the junction), so only roads outside junctions are held to this.
fn links_are_mutual(od: &OpenDrive) -> Option<Problem> {
    road_links(od)
        .filter(|l| l.road.junction.is_none() && l.other.junction.is_none())
        .find_map(|l| {
            let (back, tag) = match l.contact {
                ContactPoint::Start => (&l.other.predecessor, "predecessor"),
                ContactPoint::End => (&l.other.successor, "successor"),
            };
            let answered = back.as_ref().is_some_and(|b| {
                b.element_type == ElementType::Road
                    && b.element_id == l.road.id
                    && b.contact_point.unwrap_or(ContactPoint::Start) == l.own_end
            });
            if answered {
                return None;
            }
            let found = match back {
                None => "has no link there".to_string(),
                Some(b) => format!(
                    "links it to {} {:?}{}",
                    match b.element_type {
                        ElementType::Road => "road",
                        ElementType::Junction => "junction",
                    },
                    b.element_id,
                    b.contact_point
                        .map(|c| format!(" at its {}", end_name(c)))
                        .unwrap_or_default()
                ),
            };
            Some(l.problem(format!(
                "road {}'s {tag} {found}; expected it to name road {} with contactPoint=\"{}\" \
                 (roads joined outside a junction link each other)",
                l.other.id,
                l.road.id,
                end_name(l.own_end)
            )))
        })
}

/// A road linked to a road touches it at the linked end (a road that is its own successor
/// must close on itself).
fn links_meet(od: &OpenDrive) -> Option<Problem> {
    road_links(od).find_map(|l| {
        let gap = end_gap(l.road, l.own_end, l.other, l.contact);
        (gap > LINK_TOLERANCE).then(|| {
            let gap = Num(gap);
            l.problem(format!(
                "the two ends lie {gap:.2} m apart; expected them to meet (one's end on the \
                 other's end cross-section, within {LINK_TOLERANCE} m)"
            ))
        })
    })
}

/// How far (rad) the direction of travel may turn where one road links to the next: the
/// link carries traffic on, so the two ends run the same way (up to a surveyed kink).
pub(super) const LINK_MAX_TURN_RAD: f64 = 0.5;

/// A road linked to a road carries on in its direction: out of one end and into the other
/// (an end joined to an end, or a start to a start, meets head-on and reverses the heading).
fn links_keep_direction(od: &OpenDrive) -> Option<Problem> {
    road_links(od).find_map(|l| {
        // Successor end -> start (or predecessor start -> end) continues the heading; the
        // other two pairings face each other.
        let facing = if l.own_end != l.contact {
            0.0
        } else {
            std::f64::consts::PI
        };
        let own = end_heading(l.road, l.own_end);
        let theirs = end_heading(l.other, l.contact);
        let turn = crate::geometry::wrap_angle(own - theirs - facing).abs();
        (turn > LINK_MAX_TURN_RAD).then(|| {
            let turn = Num(turn);
            l.problem(format!(
                "the roads turn by {turn:.2} rad there (a road drawn backwards, or the wrong \
                 contact point?); expected the direction of travel to carry on (within \
                 {LINK_MAX_TURN_RAD} rad)"
            ))
        })
    })
}

/// The heading of `road`'s reference line at its `end`.
fn end_heading(road: &Road, end: ContactPoint) -> f64 {
    let s = if end == ContactPoint::Start {
        0.0
    } else {
        road.length
    };
    eval_road(road, s).hdg
}

/// Every junction joins something: a junction without a connection leaves every road linked
/// to it leading nowhere.
fn junctions_connect(od: &OpenDrive) -> Option<Problem> {
    let junction = od.junctions.iter().find(|j| j.connections.is_empty())?;
    let linked: Vec<&str> = od
        .roads
        .iter()
        .filter(|r| {
            [&r.predecessor, &r.successor].iter().any(|l| {
                l.as_ref().is_some_and(|l| {
                    l.element_type == ElementType::Junction && l.element_id == junction.id
                })
            })
        })
        .map(|r| r.id.as_str())
        .collect();
    let roads = match linked.as_slice() {
        [] => "no road links to it either".to_string(),
        ids => format!("roads {} link to it and lead nowhere", ids.join(", ")),
    };
    Some(Problem {
        place: Place::Junction(junction.id.clone()),
        message: format!(
            "junction {} has no <connection> ({roads}); expected at least one connection from \
             an incoming road to a connecting road",
            junction.id
        ),
    })
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

/// A junction and its roads agree on membership: each connection's id is given once in its
/// junction, its connecting road carries the junction's id (`junction="..."`: a road outside
/// the junction would be held to road-to-road links), and its incoming road links to the
/// junction at one of its ends (otherwise the road ends in nothing at the junction's side).
fn junction_members_agree(od: &OpenDrive) -> Option<Problem> {
    for junction in &od.junctions {
        let ids: Vec<&String> = junction.connections.iter().map(|c| &c.id).collect();
        if let Some(k) = (0..ids.len()).find(|&k| ids[..k].contains(&ids[k])) {
            let c = &junction.connections[k];
            return Some(Problem {
                place: Place::Connection {
                    junction: junction.id.clone(),
                    id: c.id.clone(),
                },
                message: format!(
                    "junction {} gives connection id \"{}\" to more than one connection; \
                     expected each connection's id once",
                    junction.id, c.id
                ),
            });
        }
    }
    for (junction, c, incoming, connecting) in connections(od) {
        let place = Place::Connection {
            junction: junction.id.clone(),
            id: c.id.clone(),
        };
        if connecting.junction.as_deref() != Some(junction.id.as_str()) {
            return Some(Problem {
                place,
                message: format!(
                    "junction {} names road {} as a connecting road, but the road says \
                     junction=\"{}\"; expected junction=\"{}\" on a road inside the junction",
                    junction.id,
                    connecting.id,
                    connecting.junction.as_deref().unwrap_or("-1"),
                    junction.id
                ),
            });
        }
        let links_here = [&incoming.predecessor, &incoming.successor]
            .into_iter()
            .flatten()
            .any(|l| l.element_type == ElementType::Junction && l.element_id == junction.id);
        // An incoming road that is itself inside the junction joins its neighbours directly.
        if !links_here && incoming.junction.is_none() {
            return Some(Problem {
                place,
                message: format!(
                    "junction {} names road {} as an incoming road, but the road links to the \
                     junction at neither end; expected its <predecessor> or <successor> to be \
                     elementType=\"junction\" elementId=\"{}\"",
                    junction.id, incoming.id, junction.id
                ),
            });
        }
    }
    None
}

/// A junction connection's connecting road is another road, and touches one end of its
/// incoming road.
fn connections_meet(od: &OpenDrive) -> Option<Problem> {
    for (junction, c, incoming, connecting) in connections(od) {
        if incoming.id == connecting.id {
            return Some(Problem {
                place: Place::Connection {
                    junction: junction.id.clone(),
                    id: c.id.clone(),
                },
                message: format!(
                    "connects road {} to itself; expected a connecting road inside the \
                     junction that leads from the incoming road to another",
                    incoming.id
                ),
            });
        }
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
                    "connecting road {} starts {:.2} m from either end of its incoming \
                     road {}; expected it to touch one (within {LINK_TOLERANCE} m)",
                    connecting.id,
                    Num(gap),
                    incoming.id
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
                        if id == 0 {
                            return Some(Problem {
                                place: place(),
                                message: format!(
                                    "lane {} of road {} names {which} lane 0, the centre lane: \
                                     a reference line without width, no lane to drive into; \
                                     expected a lane id other than 0",
                                    lane.id, road.id
                                ),
                            });
                        }
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
            let missing = if from == 0 || to == 0 {
                Some("lane 0, the centre lane (a reference line without width)".to_string())
            } else if incoming_section.lane(from).is_none() {
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
            let other_section = match other_end {
                ContactPoint::Start => other.lane_sections.first(),
                ContactPoint::End => other.lane_sections.last(),
            };
            let Some(other_section) = other_section else {
                continue;
            };
            // The joins the lane topology makes (declared, else implied).
            let links = road.lane_sections[section].links_across(
                last,
                other_section,
                other_end == ContactPoint::End,
            );
            for (from, to) in links.into_iter().filter(|&(from, _)| from != 0) {
                if let Some(message) = edge_gap(road, end, from, other, other_end, to) {
                    return Some(Problem {
                        place: Place::Lane {
                            road: road.id.clone(),
                            section,
                            lane: from,
                        },
                        message,
                    });
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
            "lane {a_lane} of road {} and lane {b_lane} of road {}, linked, have edges {:.2} \
             m apart where they join (widths {:.2} and {:.2} m); expected their edges to meet \
             (within {EDGE_TOLERANCE} m)",
            a.id,
            b.id,
            Num(gap),
            Num(distance(a_inner, a_outer)),
            Num(distance(b_inner, b_outer))
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
