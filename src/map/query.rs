//! Geometric queries on a [`Map`]: is a point or a box on the road, and where is a pose
//! relative to the nearest lane.
//!
//! Lanelet maps answer the on-road query from their lane polygons (`lanelet_surface.rs`);
//! OpenDRIVE maps as below. parry2d bounding-volume hierarchies keep every query logarithmic
//! in the map size:
//! - "corridors": one box per 20 m chunk of reference line, grown by the road's lateral reach
//!   there, plus one box per open road end covering the strip beyond it. The boxes containing
//!   a point name its candidate roads.
//! - per road, its reference-line segments, searched best-first for the nearest one, which
//!   gives (s, t); t is compared with the lanes' lateral spans at s, evaluated exactly from
//!   the polynomials.
//! - graph-lane centerline segments, searched best-first for [`Map::lane_projection`].

use parry2d::bounding_volume::{Aabb, BoundingVolume};
use parry2d::math::Vector;
use parry2d::partitioning::{Bvh, BvhBuildStrategy};
use parry2d::query::PointQuery;

use super::lanelet_surface::LaneletSurface;
use super::lanes::{Lane, Map, RoadSamples};
use super::lateral::{for_each_span, section_index};
use super::opendrive::{OpenDrive, Road};
use crate::geometry::{OrientedBox, wrap_angle};

/// How far past an open road end a point still counts as leaving through that end (m).
pub const BEYOND_END_RANGE: f64 = 50.0;

/// Spacing of the points tested along a box outline (m); a box counts as on the road when
/// these points are, so it may overhang the road edge by up to this much between two points
/// only where the edge has a corner sharper than the box (never on a straight or gently
/// curved edge).
pub const BOX_OUTLINE_SPACING: f64 = 0.5;

/// Extra margin around each corridor box (m), covering the bulge of curved boundaries.
const CORRIDOR_MARGIN: f64 = 1.0;

/// Reference-line segments per corridor box.
const CHUNK: usize = 40;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointLocation {
    /// Inside a drivable lane (driving, shoulder, ramp lanes).
    OnRoad,
    /// Past an open road end, within the drivable width there: leaving the map, not an
    /// off-road infraction.
    BeyondRoadEnd,
    OffRoad,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxOnRoad {
    /// Every outline point is on the road.
    OnRoad,
    /// Some outline points are past an open road end, none off the road.
    Exiting,
    /// Some outline point is off the road.
    OffRoad,
}

/// A pose relative to a lane centerline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneProjection {
    /// Index into [`Map::lanes`].
    pub lane: usize,
    /// Arc length along the lane centerline (m).
    pub s: f64,
    /// Signed distance from the centerline, positive to the left of the travel direction.
    pub lateral: f64,
    /// wrap_angle(heading - lane heading) (rad).
    pub heading_error: f64,
    /// Distance to the centerline (m).
    pub distance: f64,
}

/// A box from its outline points: all on the road → OnRoad; otherwise none off the road →
/// Exiting; else OffRoad. `locate` is the point query (exact or grid-cached).
pub(super) fn classify_outline(
    b: &OrientedBox,
    mut locate: impl FnMut([f64; 2]) -> PointLocation,
) -> BoxOnRoad {
    let mut exiting = false;
    for p in b.outline(BOX_OUTLINE_SPACING) {
        match locate(p) {
            PointLocation::OnRoad => {}
            PointLocation::BeyondRoadEnd => exiting = true,
            PointLocation::OffRoad => return BoxOnRoad::OffRoad,
        }
    }
    if exiting {
        BoxOnRoad::Exiting
    } else {
        BoxOnRoad::OnRoad
    }
}

#[derive(Clone, Copy, Debug)]
enum Leaf {
    Chunk { road: usize },
    OpenEnd { road: usize, at_end: bool },
}

/// What answers "is this point on the road": an OpenDRIVE road network (reference lines and
/// lateral lane spans) or a lanelet network (lane polygons).
#[derive(Clone, Debug)]
pub(super) enum Surface {
    Roads(RoadSurface),
    Lanelets(LaneletSurface),
}

/// An OpenDRIVE network with its sampled reference lines and their spatial index.
#[derive(Clone, Debug)]
pub(super) struct RoadSurface {
    pub opendrive: OpenDrive,
    pub roads: Vec<RoadSamples>,
    index: RoadIndex,
}

#[derive(Clone, Debug)]
struct RoadIndex {
    corridor: Bvh,
    leaves: Vec<Leaf>,
    /// Per road: its reference-line segments.
    segments: Vec<Bvh>,
}

/// Graph-lane centerline segments, for [`Map::lane_projection`] on either kind of map.
#[derive(Clone, Debug)]
pub(super) struct CenterlineIndex {
    centerlines: Bvh,
    /// (lane, segment) of each centerline leaf.
    center_segments: Vec<(usize, usize)>,
}

pub(super) fn v(p: [f64; 2]) -> Vector {
    Vector::new(p[0], p[1])
}

/// Outermost |t| of any drivable lane boundary at `s`.
fn reach(road: &Road, s: f64) -> f64 {
    let sec = &road.lane_sections[section_index(road, s)];
    let mut r: f64 = 0.0;
    for_each_span(road, sec, s, |lane, span| {
        if lane.kind.is_drivable() && span.width() > 0.0 {
            r = r.max(span.inner.abs()).max(span.outer.abs());
        }
    });
    r
}

/// Foot of p on the line through a-b: the unclamped parameter (0 at a, 1 at b) and the
/// distance from p to the closest point of the segment.
pub(super) fn segment_foot(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> (f64, f64) {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let u = if len2 > 0.0 {
        ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2
    } else {
        0.0
    };
    let c = u.clamp(0.0, 1.0);
    let q = [a[0] + c * d[0], a[1] + c * d[1]];
    (u, (p[0] - q[0]).hypot(p[1] - q[1]))
}

/// Signed side of p relative to the directed segment a-b (positive on the left).
pub(super) fn side(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

impl RoadSurface {
    /// Indexes `roads` (the sampled reference lines of `opendrive`); `connected` says, per
    /// road, whether its start and end connect to anything.
    pub(super) fn new(
        opendrive: OpenDrive,
        roads: Vec<RoadSamples>,
        connected: &[[bool; 2]],
    ) -> Self {
        let index = RoadIndex::build(&opendrive, &roads, connected);
        RoadSurface {
            opendrive,
            roads,
            index,
        }
    }
}

impl RoadIndex {
    fn build(od: &OpenDrive, roads: &[RoadSamples], connected: &[[bool; 2]]) -> Self {
        let mut boxes = Vec::new();
        let mut leaves = Vec::new();
        let mut segments = Vec::with_capacity(od.roads.len());
        for (r, (road, samples)) in od.roads.iter().zip(roads).enumerate() {
            let pts: Vec<[f64; 2]> = samples.points.iter().map(|p| [p.x, p.y]).collect();
            let reaches: Vec<f64> = samples.s.iter().map(|&s| reach(road, s)).collect();
            let seg_boxes: Vec<Aabb> = pts
                .windows(2)
                .map(|w| Aabb::from_points([v(w[0]), v(w[1])]))
                .collect();
            for first in (0..seg_boxes.len()).step_by(CHUNK) {
                let last = (first + CHUNK).min(seg_boxes.len());
                let grow =
                    reaches[first..=last].iter().fold(0.0f64, |a, &b| a.max(b)) + CORRIDOR_MARGIN;
                let chunk = Aabb::from_points(pts[first..=last].iter().map(|&p| v(p)));
                boxes.push(chunk.loosened(grow));
                leaves.push(Leaf::Chunk { road: r });
            }
            segments.push(Bvh::from_leaves(BvhBuildStrategy::Binned, &seg_boxes));
            for (at_end, open) in [(false, !connected[r][0]), (true, !connected[r][1])] {
                let (Some(first), Some(last)) = (samples.points.first(), samples.points.last())
                else {
                    continue;
                };
                if !open {
                    continue;
                }
                let p = if at_end { last } else { first };
                let out = if at_end { 1.0 } else { -1.0 } * BEYOND_END_RANGE;
                let (sin, cos) = p.hdg.sin_cos();
                let far = [p.x + out * cos, p.y + out * sin];
                let w = reach(road, if at_end { road.length } else { 0.0 }) + CORRIDOR_MARGIN;
                boxes.push(Aabb::from_points([v([p.x, p.y]), v(far)]).loosened(w));
                leaves.push(Leaf::OpenEnd { road: r, at_end });
            }
        }
        let corridor = Bvh::from_leaves(BvhBuildStrategy::Binned, &boxes);
        RoadIndex {
            corridor,
            leaves,
            segments,
        }
    }
}

impl CenterlineIndex {
    pub(super) fn build(lanes: &[Lane]) -> Self {
        let mut seg_boxes = Vec::new();
        let mut center_segments = Vec::new();
        for (i, lane) in lanes.iter().enumerate().filter(|(_, l)| l.is_graph_lane()) {
            for (seg, w) in lane.centerline.windows(2).enumerate() {
                seg_boxes.push(Aabb::from_points([v(w[0]), v(w[1])]));
                center_segments.push((i, seg));
            }
        }
        let centerlines = Bvh::from_leaves(BvhBuildStrategy::Binned, &seg_boxes);
        CenterlineIndex {
            centerlines,
            center_segments,
        }
    }
}

impl Map {
    /// Where `p` lies: on a drivable lane, past an open road end, or off the road.
    pub fn point_location(&self, p: [f64; 2]) -> PointLocation {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return PointLocation::OffRoad;
        }
        match &self.surface {
            Surface::Roads(roads) => roads.point_location(p),
            Surface::Lanelets(lanelets) => lanelets.point_location(p),
        }
    }

    /// Classifies a vehicle footprint by its outline points, [`BOX_OUTLINE_SPACING`] apart.
    pub fn box_on_road(&self, b: &OrientedBox) -> BoxOnRoad {
        classify_outline(b, |p| self.point_location(p))
    }
}

impl RoadSurface {
    fn point_location(&self, p: [f64; 2]) -> PointLocation {
        let od = &self.opendrive;
        let mut candidates: Vec<usize> = Vec::new();
        let mut beyond = false;
        let idx = &self.index;
        for leaf in idx.corridor.leaves(|n| n.aabb().contains_local_point(v(p))) {
            match idx.leaves[leaf as usize] {
                Leaf::Chunk { road } => {
                    if !candidates.contains(&road) {
                        candidates.push(road);
                    }
                }
                Leaf::OpenEnd { road, at_end } => {
                    beyond = beyond || self.beyond_open_end(road, at_end, p);
                }
            }
        }
        // Nearest reference-line segment per candidate road: (road, segment, distance).
        let nearest = candidates.into_iter().filter_map(|road| {
            let pts = &self.roads[road].points;
            let (seg, d) = idx.segments[road].find_best(
                f64::MAX,
                |node, _| node.aabb().distance_to_local_point(v(p), true),
                |seg, _| {
                    let (a, b) = (&pts[seg as usize], &pts[seg as usize + 1]);
                    Some(segment_foot([a.x, a.y], [b.x, b.y], p).1)
                },
            )?;
            Some((road, seg as usize, d))
        });
        for (road, seg, dist) in nearest {
            let samples = &self.roads[road];
            let (pa, pb) = (&samples.points[seg], &samples.points[seg + 1]);
            let (a, b) = ([pa.x, pa.y], [pb.x, pb.y]);
            let (u, _) = segment_foot(a, b, p);
            // Before the first or after the last sample the point is past the road's end.
            if (seg == 0 && u < 0.0) || (seg + 2 == samples.s.len() && u > 1.0) {
                continue;
            }
            let u = u.clamp(0.0, 1.0);
            let s = samples.s[seg] + u * (samples.s[seg + 1] - samples.s[seg]);
            let t = dist.copysign(side(a, b, p));
            if self.on_drivable(&od.roads[road], s, t) {
                return PointLocation::OnRoad;
            }
        }
        if beyond {
            PointLocation::BeyondRoadEnd
        } else {
            PointLocation::OffRoad
        }
    }

    /// Whether lateral offset `t` at `s` of `road` falls in a drivable lane.
    fn on_drivable(&self, road: &Road, s: f64, t: f64) -> bool {
        let sec = &road.lane_sections[section_index(road, s)];
        let mut on = false;
        for_each_span(road, sec, s, |lane, span| {
            on = on || (lane.kind.is_drivable() && span.width() > 0.0 && span.contains(t));
        });
        on
    }

    /// Whether `p` is past the open start or end of `road`, within the drivable width there.
    fn beyond_open_end(&self, road: usize, at_end: bool, p: [f64; 2]) -> bool {
        let samples = &self.roads[road];
        let (Some(first), Some(last)) = (samples.points.first(), samples.points.last()) else {
            return false;
        };
        let e = if at_end { last } else { first };
        let (sin, cos) = e.hdg.sin_cos();
        let rel = [p[0] - e.x, p[1] - e.y];
        let along = (rel[0] * cos + rel[1] * sin) * if at_end { 1.0 } else { -1.0 };
        let t = -rel[0] * sin + rel[1] * cos;
        let od_road = &self.opendrive.roads[road];
        let s = if at_end { od_road.length } else { 0.0 };
        along > 0.0 && along <= BEYOND_END_RANGE && self.on_drivable(od_road, s, t)
    }
}

impl Map {
    /// The nearest graph-lane centerline to `p`, preferring lanes whose travel direction is
    /// within 90 degrees of `heading`. `None` when the map has no graph lanes.
    pub fn lane_projection(&self, p: [f64; 2], heading: f64) -> Option<LaneProjection> {
        if !(p[0].is_finite() && p[1].is_finite() && heading.is_finite()) {
            return None;
        }
        // Any aligned lane beats any opposed one; the penalty keeps the AABB distance a lower
        // bound of the cost, as the best-first search needs.
        const OPPOSED_PENALTY: f64 = 1e9;
        let idx = &self.centerlines;
        let (dir_x, dir_y) = (heading.cos(), heading.sin());
        let (leaf, _) = idx.centerlines.find_best(
            f64::MAX,
            |node, _| node.aabb().distance_to_local_point(v(p), true),
            |leaf, _| {
                let (lane, seg) = idx.center_segments[leaf as usize];
                let c = &self.lanes[lane].centerline;
                let (_, d) = segment_foot(c[seg], c[seg + 1], p);
                let along =
                    (c[seg + 1][0] - c[seg][0]) * dir_x + (c[seg + 1][1] - c[seg][1]) * dir_y;
                Some(if along >= 0.0 { d } else { d + OPPOSED_PENALTY })
            },
        )?;
        let (lane_idx, seg) = idx.center_segments[leaf as usize];
        let lane = &self.lanes[lane_idx];
        let (a, b) = (lane.centerline[seg], lane.centerline[seg + 1]);
        let (u, distance) = segment_foot(a, b, p);
        let u = u.clamp(0.0, 1.0);
        let (h0, h1) = (lane.headings[seg], lane.headings[seg + 1]);
        let lane_heading = h0 + u * wrap_angle(h1 - h0);
        Some(LaneProjection {
            lane: lane_idx,
            s: lane.s[seg] + u * (lane.s[seg + 1] - lane.s[seg]),
            lateral: distance.copysign(side(a, b, p)),
            heading_error: wrap_angle(heading - lane_heading),
            distance,
        })
    }
}
