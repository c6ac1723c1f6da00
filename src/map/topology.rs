//! Lane topology: successors, predecessors and left/right neighbours of the sampled lanes.
//!
//! OpenDRIVE states connectivity in several places: lane links between consecutive lane
//! sections, road links with lane links across roads, and junction connections. Any of them
//! may be written on one side only, so every statement is first turned into an undirected
//! join of two lane *ends* (the section-start or section-end of each lane); the union of all
//! joins is then oriented by travel direction (right lanes leave at the section end, left
//! lanes at the section start). A join whose ends do not fit a travel direction (exit to exit)
//! is inconsistent and dropped.

use std::collections::HashMap;

use super::lanes::Lane;
use super::opendrive::{ContactPoint, ElementType, OpenDrive, Road};
use super::reference_line::eval_road;
use crate::{Error, Result};

/// Which end of a lane section (in reference-line `s`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum End {
    Start,
    End,
}

/// Two lane ends (lane index, which end) that OpenDRIVE says touch.
type Join = ((usize, End), (usize, End));

impl From<ContactPoint> for End {
    fn from(c: ContactPoint) -> End {
        match c {
            ContactPoint::Start => End::Start,
            ContactPoint::End => End::End,
        }
    }
}

struct Lookup<'a> {
    od: &'a OpenDrive,
    source: &'a str,
    road_index: HashMap<&'a str, usize>,
    lane_index: HashMap<(usize, usize, i32), usize>,
    /// Sections that produced lanes, per road, in order.
    sections: Vec<Vec<usize>>,
}

impl Lookup<'_> {
    fn road(&self, id: &str, from: &Road, what: &str) -> Result<usize> {
        self.road_index.get(id).copied().ok_or_else(|| {
            Error::invalid(
                self.source,
                format!("road {}", from.id),
                format!("{what} refers to road {id:?}, which does not exist"),
            )
        })
    }

    /// The section of road `r` touching its `end`.
    fn end_section(&self, r: usize, end: End) -> Option<usize> {
        match end {
            End::Start => self.sections[r].first().copied(),
            End::End => self.sections[r].last().copied(),
        }
    }

    fn lane(&self, r: usize, section: Option<usize>, id: i32) -> Option<usize> {
        self.lane_index.get(&(r, section?, id)).copied()
    }
}

/// Fills `successors`, `predecessors` and the neighbours of `lanes`. Returns, per road, whether
/// its start and end connect to anything (a road or junction link, or any lane join); the
/// other ends are open ends where vehicles leave the map.
pub(super) fn connect(od: &OpenDrive, lanes: &mut [Lane], source: &str) -> Result<Vec<[bool; 2]>> {
    let mut lk = Lookup {
        od,
        source,
        road_index: od
            .roads
            .iter()
            .enumerate()
            .map(|(i, r)| (r.id.as_str(), i))
            .collect(),
        lane_index: HashMap::new(),
        sections: vec![Vec::new(); od.roads.len()],
    };
    for (i, l) in lanes.iter().enumerate() {
        lk.lane_index.insert((l.road, l.section, l.id), i);
        if lk.sections[l.road].last() != Some(&l.section) {
            lk.sections[l.road].push(l.section);
        }
    }
    let mut joins: Vec<Join> = Vec::new();
    section_joins(&lk, &mut joins);
    road_joins(&lk, &mut joins)?;
    junction_joins(&lk, &mut joins)?;

    let exit = |l: &Lane| {
        if l.along_reference() {
            End::End
        } else {
            End::Start
        }
    };
    for &((a, ea), (b, eb)) in &joins {
        let (from, to) = if ea == exit(&lanes[a]) && eb != exit(&lanes[b]) {
            (a, b)
        } else if ea != exit(&lanes[a]) && eb == exit(&lanes[b]) {
            (b, a)
        } else {
            continue;
        };
        lanes[from].successors.push(to);
        lanes[to].predecessors.push(from);
    }
    for l in lanes.iter_mut() {
        l.successors.sort_unstable();
        l.successors.dedup();
        l.predecessors.sort_unstable();
        l.predecessors.dedup();
    }
    neighbours(&lk, lanes);

    let mut connected: Vec<[bool; 2]> = od
        .roads
        .iter()
        .map(|r| [r.predecessor.is_some(), r.successor.is_some()])
        .collect();
    for &(a, b) in &joins {
        for (lane, end) in [a, b] {
            let l = &lanes[lane];
            if lk.end_section(l.road, end) == Some(l.section) {
                connected[l.road][usize::from(end == End::End)] = true;
            }
        }
    }
    Ok(connected)
}

/// Lane links between consecutive sections of a road
/// ([`super::opendrive::LaneSection::links_to`]).
fn section_joins(lk: &Lookup, joins: &mut Vec<Join>) {
    for (r, road) in lk.od.roads.iter().enumerate() {
        for pair in lk.sections[r].windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let (sa, sb) = (&road.lane_sections[a], &road.lane_sections[b]);
            for (from, to) in sa.links_to(sb) {
                if let (Some(la), Some(lb)) = (lk.lane(r, Some(a), from), lk.lane(r, Some(b), to)) {
                    joins.push(((la, End::End), (lb, End::Start)));
                }
            }
        }
    }
}

/// Road-to-road links, lane to lane ([`super::opendrive::LaneSection::links_across`]).
fn road_joins(lk: &Lookup, joins: &mut Vec<Join>) -> Result<()> {
    for (r, road) in lk.od.roads.iter().enumerate() {
        for (link, end) in [(&road.predecessor, End::Start), (&road.successor, End::End)] {
            let Some(link) = link else { continue };
            if link.element_type == ElementType::Junction {
                if !lk.od.junctions.iter().any(|j| j.id == link.element_id) {
                    return Err(Error::invalid(
                        lk.source,
                        format!("road {}", road.id),
                        format!(
                            "link refers to junction {:?}, which does not exist",
                            link.element_id
                        ),
                    ));
                }
                continue;
            }
            let other = lk.road(&link.element_id, road, "link")?;
            let other_end = End::from(link.contact_point.unwrap_or(ContactPoint::Start));
            let own_section = lk.end_section(r, end);
            let other_section = lk.end_section(other, other_end);
            let (Some(k), Some(m)) = (own_section, other_section) else {
                continue;
            };
            let links = road.lane_sections[k].links_across(
                end == End::End,
                &lk.od.roads[other].lane_sections[m],
                other_end == End::End,
            );
            for (from, to) in links {
                if let (Some(la), Some(lb)) = (
                    lk.lane(r, own_section, from),
                    lk.lane(other, other_section, to),
                ) {
                    joins.push(((la, end), (lb, other_end)));
                }
            }
        }
    }
    Ok(())
}

/// Junction connections: incoming road lane -> connecting road lane. The incoming road's end
/// is the one nearest to the connecting road's contact point, so the connection counts even
/// when the incoming road does not link to the junction itself.
fn junction_joins(lk: &Lookup, joins: &mut Vec<Join>) -> Result<()> {
    for j in &lk.od.junctions {
        for c in &j.connections {
            let place = format!("junction {} connection {}", j.id, c.id);
            let missing = |id: &str| {
                Error::invalid(
                    lk.source,
                    place.clone(),
                    format!("refers to road {id:?}, which does not exist"),
                )
            };
            let inc = *lk
                .road_index
                .get(c.incoming_road.as_str())
                .ok_or_else(|| missing(&c.incoming_road))?;
            let con = *lk
                .road_index
                .get(c.connecting_road.as_str())
                .ok_or_else(|| missing(&c.connecting_road))?;
            let con_end = End::from(c.contact_point);
            let (inc_road, con_road) = (&lk.od.roads[inc], &lk.od.roads[con]);
            let at = |road: &Road, end: End| {
                let p = eval_road(road, if end == End::Start { 0.0 } else { road.length });
                [p.x, p.y]
            };
            let target = at(con_road, con_end);
            let dist = |end| {
                let p = at(inc_road, end);
                (p[0] - target[0]).hypot(p[1] - target[1])
            };
            let inc_end = if dist(End::Start) <= dist(End::End) {
                End::Start
            } else {
                End::End
            };
            for &(from, to) in &c.lane_links {
                let a = lk.lane(inc, lk.end_section(inc, inc_end), from);
                let b = lk.lane(con, lk.end_section(con, con_end), to);
                if let (Some(a), Some(b)) = (a, b) {
                    joins.push(((a, inc_end), (b, con_end)));
                }
            }
        }
    }
    Ok(())
}

/// Adjacent lanes of the same section (skipping zero-width ones) on the same side, when both
/// are graph lanes. Toward the centre is the driver's left on either side.
fn neighbours(lk: &Lookup, lanes: &mut [Lane]) {
    for i in 0..lanes.len() {
        if !lanes[i].is_graph_lane() {
            continue;
        }
        let (r, k, id) = (lanes[i].road, lanes[i].section, lanes[i].id);
        let step = id.signum();
        let find = |dir: i32| {
            let mut other = id + dir;
            while other != 0 && other.signum() == step && other.abs() <= 1000 {
                if let Some(&j) = lk.lane_index.get(&(r, k, other)) {
                    return lanes[j].is_graph_lane().then_some(j);
                }
                other += dir;
            }
            None
        };
        let (left, right) = (find(-step), find(step));
        lanes[i].left_neighbour = left;
        lanes[i].right_neighbour = right;
    }
}
