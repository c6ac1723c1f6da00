//! Lanelet networks (as CommonRoad files give them): lanes drawn directly as a left and a right
//! boundary polyline with explicit successor, predecessor and adjacency references. They become the
//! same [`Lane`]s an OpenDRIVE map samples into, so the lane graph, the simulator and every
//! query work on them unchanged; on-road queries use the lanelet polygons
//! ([`LaneletSurface`]).

use std::collections::HashMap;

use super::lanelet_surface::{Beside, LaneletSurface};
use super::lanes::{Lane, MAX_ROAD_LENGTH, Map, SAMPLE_SPACING};
use super::opendrive::{LaneType, RoadMark};
use super::query::Surface;
use crate::geometry::wrap_angle;
use crate::{Error, Result};

/// Widest lanelet accepted (m): a corrupt bound far from its partner would otherwise be
/// sampled into millions of points.
const MAX_LANE_WIDTH: f64 = 20.0;

/// A lanelet's neighbour across its left or right boundary.
#[derive(Clone, Debug, PartialEq)]
pub struct AdjacentLanelet {
    pub id: String,
    /// Whether the neighbour travels the same way (`drivingDir="same"`).
    pub same_direction: bool,
}

/// One lanelet as the file gives it. Both bounds run in the travel direction, with the same
/// number of points (point k of one faces point k of the other).
#[derive(Clone, Debug, PartialEq)]
pub struct Lanelet {
    pub id: String,
    pub left_bound: Vec<[f64; 2]>,
    pub right_bound: Vec<[f64; 2]>,
    pub left_mark: RoadMark,
    pub right_mark: RoadMark,
    pub predecessors: Vec<String>,
    pub successors: Vec<String>,
    pub adjacent_left: Option<AdjacentLanelet>,
    pub adjacent_right: Option<AdjacentLanelet>,
    pub kind: LaneType,
    /// m/s, when the file gives one.
    pub speed_limit: Option<f64>,
}

impl Map {
    /// A map from a lanelet network. Lanes without a speed limit take `default_speed_limit`
    /// (m/s). `source_name` names the file in errors, which name the lanelet and what is
    /// wrong: a bound with fewer than two points, bounds of different lengths, a coordinate
    /// that is not finite, a bound longer than [`MAX_ROAD_LENGTH`], bounds more than 20 m
    /// apart, zero length, swapped bounds, an id used twice, a reference to a lanelet the
    /// network does not define, or no drivable lanelet at all.
    pub fn from_lanelets(
        lanelets: &[Lanelet],
        default_speed_limit: f64,
        source_name: &str,
    ) -> Result<Map> {
        let index = check_lanelets(lanelets, source_name)?;
        let mut lanes: Vec<Lane> = lanelets
            .iter()
            .enumerate()
            .map(|(k, l)| sample_lanelet(k, l, default_speed_limit))
            .collect();
        connect(lanelets, &index, &mut lanes);
        let beside: Vec<[Beside; 2]> = lanelets
            .iter()
            .map(|l| [&l.adjacent_left, &l.adjacent_right].map(|a| beside(a, lanelets, &index)))
            .collect();
        let surface = Surface::Lanelets(LaneletSurface::build(&lanes, &beside));
        Ok(Map::assemble(source_name, surface, lanes))
    }
}

/// Validates the network; returns the position of each lanelet id.
fn check_lanelets<'a>(lanelets: &'a [Lanelet], source: &str) -> Result<HashMap<&'a str, usize>> {
    let mut index = HashMap::with_capacity(lanelets.len());
    for (k, l) in lanelets.iter().enumerate() {
        let place = format!("lanelet {}", l.id);
        if index.insert(l.id.as_str(), k).is_some() {
            return Err(Error::invalid(source, place, "lanelet id is used twice"));
        }
        if l.left_bound.len() < 2 || l.left_bound.len() != l.right_bound.len() {
            return Err(Error::invalid(
                source,
                place,
                format!(
                    "left and right bound need the same number of points, at least 2 \
                     (found {} and {})",
                    l.left_bound.len(),
                    l.right_bound.len()
                ),
            ));
        }
        if let Some(p) = l
            .left_bound
            .iter()
            .chain(&l.right_bound)
            .find(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(Error::invalid(
                source,
                place,
                format!("bound point ({}, {}) is not finite", p[0], p[1]),
            ));
        }
        check_shape(l, source, &place)?;
    }
    if !lanelets.iter().any(|l| l.kind.is_drivable()) {
        return Err(Error::invalid(
            source,
            "lanelet network",
            "has no drivable lanelet (driving, ramp or shoulder): nothing to drive on",
        ));
    }
    for l in lanelets {
        let adjacent = l.adjacent_left.iter().chain(&l.adjacent_right);
        let references = l
            .predecessors
            .iter()
            .map(|id| ("predecessor", id))
            .chain(l.successors.iter().map(|id| ("successor", id)))
            .chain(adjacent.map(|a| ("adjacent lanelet", &a.id)));
        for (relation, id) in references {
            if !index.contains_key(id.as_str()) {
                return Err(Error::invalid(
                    source,
                    format!("lanelet {}", l.id),
                    format!("its {relation} {id} is not a lanelet of this file"),
                ));
            }
        }
    }
    Ok(index)
}

/// What the sampler and the road surface rely on: bounds of sane length, a lane of sane
/// width that has some length, and the left bound on the left of the travel direction.
fn check_shape(l: &Lanelet, source: &str, place: &str) -> Result<()> {
    let length =
        |bound: &[[f64; 2]]| -> f64 { bound.windows(2).map(|w| distance(w[0], w[1])).sum() };
    let longest = length(&l.left_bound).max(length(&l.right_bound));
    if longest > MAX_ROAD_LENGTH {
        return Err(Error::invalid(
            source,
            place,
            format!("a bound is {longest:.0} m long, at most {MAX_ROAD_LENGTH} m expected"),
        ));
    }
    let widest = l
        .left_bound
        .iter()
        .zip(&l.right_bound)
        .map(|(&a, &b)| distance(a, b))
        .fold(0.0, f64::max);
    if widest > MAX_LANE_WIDTH {
        return Err(Error::invalid(
            source,
            place,
            format!("the bounds are {widest:.1} m apart, at most {MAX_LANE_WIDTH} m expected"),
        ));
    }
    let center: Vec<[f64; 2]> = l
        .left_bound
        .iter()
        .zip(&l.right_bound)
        .map(|(&a, &b)| midpoint(a, b))
        .collect();
    if length(&center) < 1e-6 {
        return Err(Error::invalid(source, place, "has zero length"));
    }
    // Signed side of the left bound, summed along the lanelet: positive when it is on the left.
    let left_side: f64 = (1..center.len())
        .map(|j| {
            let (a, b, p) = (center[j - 1], center[j], l.left_bound[j]);
            (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        })
        .sum();
    if left_side < 0.0 {
        return Err(Error::invalid(
            source,
            place,
            "the left bound lies on the right of the travel direction (bounds swapped?)",
        ));
    }
    Ok(())
}

/// The lanelet's bounds, each segment split into pieces of at most [`SAMPLE_SPACING`], as a
/// lane: centerline midway between facing bound points, travel direction along the bounds.
fn sample_lanelet(k: usize, l: &Lanelet, default_speed_limit: f64) -> Lane {
    let (mut left, mut right) = (vec![l.left_bound[0]], vec![l.right_bound[0]]);
    for j in 1..l.left_bound.len() {
        let (a0, a1) = (l.left_bound[j - 1], l.left_bound[j]);
        let (b0, b1) = (l.right_bound[j - 1], l.right_bound[j]);
        let span = distance(a0, a1).max(distance(b0, b1));
        let center_step = distance(midpoint(a0, b0), midpoint(a1, b1));
        if center_step < 1e-9 && span < 1e-9 {
            continue; // a repeated point pair
        }
        let pieces = (span / SAMPLE_SPACING).ceil().max(1.0) as usize;
        for i in 1..=pieces {
            let u = i as f64 / pieces as f64;
            left.push(lerp(a0, a1, u));
            right.push(lerp(b0, b1, u));
        }
    }
    let centerline: Vec<[f64; 2]> = left
        .iter()
        .zip(&right)
        .map(|(&a, &b)| midpoint(a, b))
        .collect();
    let mut s = Vec::with_capacity(centerline.len());
    let mut along = 0.0;
    for (j, p) in centerline.iter().enumerate() {
        if j > 0 {
            along += distance(centerline[j - 1], *p);
        }
        s.push(along);
    }
    let headings = centerline_headings(&centerline, &left, &right);
    let widths = left.iter().zip(&right).map(|(&a, &b)| distance(a, b));
    let n = centerline.len();
    Lane {
        road: k,
        road_id: l.id.clone(),
        section: 0,
        id: -1,
        kind: l.kind.clone(),
        headings,
        road_s: s.clone(),
        s,
        widths: widths.collect(),
        left_boundary: left,
        right_boundary: right,
        left_marks: vec![l.left_mark.clone(); n],
        right_marks: vec![l.right_mark.clone(); n],
        left_mark: l.left_mark.clone(),
        right_mark: l.right_mark.clone(),
        speed_limit: l.speed_limit.unwrap_or(default_speed_limit),
        centerline,
        successors: Vec::new(),
        predecessors: Vec::new(),
        left_neighbour: None,
        right_neighbour: None,
    }
}

/// Heading at each centerline sample: of the chord through its neighbours (central
/// difference), one-sided at the ends. Where the centerline does not move (a lanelet of zero
/// length), the direction from the right to the left bound turned a quarter clockwise.
fn centerline_headings(center: &[[f64; 2]], left: &[[f64; 2]], right: &[[f64; 2]]) -> Vec<f64> {
    let n = center.len();
    (0..n)
        .map(|j| {
            let (a, b) = (center[j.saturating_sub(1)], center[(j + 1).min(n - 1)]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let heading = if d[0].hypot(d[1]) > 1e-9 {
                d[1].atan2(d[0])
            } else {
                let across = [left[j][0] - right[j][0], left[j][1] - right[j][1]];
                across[1].atan2(across[0]) - std::f64::consts::FRAC_PI_2
            };
            wrap_angle(heading)
        })
        .collect()
}

/// What the file puts beyond one bound of a lanelet.
fn beside(
    adjacent: &Option<AdjacentLanelet>,
    lanelets: &[Lanelet],
    index: &HashMap<&str, usize>,
) -> Beside {
    match adjacent {
        None => Beside::Nothing,
        Some(a) if lanelets[index[a.id.as_str()]].kind.is_drivable() => Beside::Road,
        Some(_) => Beside::NotRoad,
    }
}

/// Successors and predecessors from the references of both ends (a file may give a link on
/// one side only), and same-direction neighbours between graph lanes.
fn connect(lanelets: &[Lanelet], index: &HashMap<&str, usize>, lanes: &mut [Lane]) {
    let mut links = Vec::new();
    for (k, l) in lanelets.iter().enumerate() {
        links.extend(l.successors.iter().map(|id| (k, index[id.as_str()])));
        links.extend(l.predecessors.iter().map(|id| (index[id.as_str()], k)));
    }
    links.sort_unstable();
    links.dedup();
    for (from, to) in links {
        lanes[from].successors.push(to);
        lanes[to].predecessors.push(from);
    }
    for (k, l) in lanelets.iter().enumerate() {
        let neighbour = |adjacent: &Option<AdjacentLanelet>| {
            adjacent
                .as_ref()
                .filter(|a| a.same_direction)
                .map(|a| index[a.id.as_str()])
                .filter(|&j| lanes[j].is_graph_lane() && lanes[k].is_graph_lane())
        };
        let (left, right) = (neighbour(&l.adjacent_left), neighbour(&l.adjacent_right));
        lanes[k].left_neighbour = left;
        lanes[k].right_neighbour = right;
    }
}

pub(super) fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

fn midpoint(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    lerp(a, b, 0.5)
}

fn lerp(a: [f64; 2], b: [f64; 2], u: f64) -> [f64; 2] {
    [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])]
}
