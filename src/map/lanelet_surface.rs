//! On-road queries for a lanelet map: a point is on the road when it lies in the polygon of a
//! drivable lane, and past a road end when it lies in the strip beyond an open lane end.
//!
//! Each drivable lane is cut into quadrilaterals between consecutive facing boundary samples
//! (at most [`SAMPLE_SPACING`](super::SAMPLE_SPACING) apart), plus a strip beyond each bound:
//! a narrow shoulder where no lane lies beside it ([`LANELET_SHOULDER_WIDTH`]), an overlap
//! into the neighbour where one does (closing slivers between two drawings of one line); a parry2d
//! bounding-volume hierarchy over them keeps a query logarithmic in the map size.

use parry2d::bounding_volume::{Aabb, BoundingVolume};
use parry2d::partitioning::{Bvh, BvhBuildStrategy};
use parry2d::utils::point_in_poly2d;

use super::lanelet::distance;
use super::lanes::Lane;
use super::query::{BEYOND_END_RANGE, PointLocation, segment_foot, side, v};

/// A lane end narrower than this (m) is a taper (a merge or a lane drop), not a road end:
/// vehicles continue in the lane beside it rather than leave the map there.
const MIN_OPEN_END_WIDTH: f64 = 1.0;

/// Tolerance (m) that closes the float gaps between the shared boundaries of adjacent lanes.
const EDGE_TOLERANCE: f64 = 1e-3;

/// Paved strip (m) counted as road beyond a lane bound with no neighbouring lane. Lanelet
/// networks describe lanes, not the paved surface: a motorway's outer edge lines have a
/// shoulder beyond them that the files leave out (US interstates: at least 1.2 m left, 3 m
/// right). Recorded vehicles do use it: on the committed NGSIM US-101 clips 31 of 291
/// logged boxes overhang the outer lane bounds, by up to 0.7 m. The strip is drivable (a
/// vehicle on it is not off the road) but not a lane to follow; 1 m keeps it narrower than
/// any real shoulder.
pub const LANELET_SHOULDER_WIDTH: f64 = 1.0;

/// Strip (m) added beyond a bound shared with a neighbouring lane. The two lanelets draw that
/// bound as two polylines with different vertices (US-101: 47 and 58 points), which leave
/// slivers of a few centimetres between them; the strip lies inside the neighbour and closes
/// them.
const SHARED_BOUND_OVERLAP: f64 = 0.5;

/// The strip beyond a lane end with no successor (or start with no predecessor).
#[derive(Clone, Debug)]
struct OpenEnd {
    /// End edge, its left then right point, seen looking out of the lane.
    left: [f64; 2],
    right: [f64; 2],
    /// Unit direction out of the lane.
    out: [f64; 2],
}

/// What a lanelet file puts beyond one bound of a lanelet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Beside {
    /// No adjacent lanelet: the edge of the lanes, with a shoulder beyond.
    Nothing,
    /// A drivable lanelet (either direction).
    Road,
    /// A lanelet vehicles may not use (sidewalk, bicycle lane, parking, ...).
    NotRoad,
}

#[derive(Clone, Debug)]
pub(super) struct LaneletSurface {
    /// Corners in order: left j, left j+1, right j+1, right j.
    quads: Vec<[[f64; 2]; 4]>,
    quad_index: Bvh,
    ends: Vec<OpenEnd>,
    end_index: Bvh,
}

impl LaneletSurface {
    /// `beside[k]`: what lies beyond lane k's left and right bound.
    pub(super) fn build(lanes: &[Lane], beside: &[[Beside; 2]]) -> Self {
        let mut quads = Vec::new();
        let mut ends = Vec::new();
        for (lane, beside) in lanes.iter().zip(beside).filter(|(l, _)| l.is_drivable()) {
            let (l, r) = (&lane.left_boundary, &lane.right_boundary);
            for j in 1..l.len() {
                quads.push([l[j - 1], l[j], r[j], r[j - 1]]);
            }
            quads.extend(shoulder(lane, Side::Left, beside[0]));
            quads.extend(shoulder(lane, Side::Right, beside[1]));
            let (n, c) = (l.len(), &lane.centerline);
            if lane.successors.is_empty() && n >= 2 {
                ends.push(OpenEnd::new(l[n - 1], r[n - 1], c[n - 2], c[n - 1]));
            }
            if lane.predecessors.is_empty() && n >= 2 {
                // Looking out of the start, the lane's right bound is on the left.
                ends.push(OpenEnd::new(r[0], l[0], c[1], c[0]));
            }
        }
        ends.retain(|e| {
            distance(e.left, e.right) >= MIN_OPEN_END_WIDTH + 2.0 * LANELET_SHOULDER_WIDTH
        });
        let quad_boxes: Vec<Aabb> = quads
            .iter()
            .map(|q| Aabb::from_points(q.iter().map(|&p| v(p))).loosened(EDGE_TOLERANCE))
            .collect();
        let end_boxes: Vec<Aabb> = ends.iter().map(OpenEnd::bounds).collect();
        LaneletSurface {
            quad_index: Bvh::from_leaves(BvhBuildStrategy::Binned, &quad_boxes),
            quads,
            end_index: Bvh::from_leaves(BvhBuildStrategy::Binned, &end_boxes),
            ends,
        }
    }

    pub(super) fn point_location(&self, p: [f64; 2]) -> PointLocation {
        if self
            .quad_index
            .leaves(|n| n.aabb().contains_local_point(v(p)))
            .any(|k| quad_contains(&self.quads[k as usize], p))
        {
            return PointLocation::OnRoad;
        }
        if self
            .end_index
            .leaves(|n| n.aabb().contains_local_point(v(p)))
            .any(|k| self.ends[k as usize].contains(p))
        {
            return PointLocation::BeyondRoadEnd;
        }
        PointLocation::OffRoad
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Side {
    Left,
    Right,
}

/// The strip outside the lane's `side` bound, as quadrilaterals in the order of the lane's
/// own: [`LANELET_SHOULDER_WIDTH`] wide where the file puts nothing beyond the bound,
/// [`SHARED_BOUND_OVERLAP`] into a drivable neighbour, none toward a lanelet vehicles may not
/// use.
fn shoulder(lane: &Lane, side: Side, beside: Beside) -> Vec<[[f64; 2]; 4]> {
    let (bound, sign) = match side {
        Side::Left => (&lane.left_boundary, 1.0),
        Side::Right => (&lane.right_boundary, -1.0),
    };
    let width = match beside {
        Beside::Nothing => LANELET_SHOULDER_WIDTH,
        Beside::Road => SHARED_BOUND_OVERLAP,
        Beside::NotRoad => return Vec::new(),
    };
    let outer: Vec<[f64; 2]> = bound
        .iter()
        .zip(&lane.headings)
        .map(|(p, h)| {
            let (sin, cos) = h.sin_cos();
            let w = sign * width;
            [p[0] - w * sin, p[1] + w * cos]
        })
        .collect();
    (1..bound.len())
        .map(|j| [outer[j - 1], outer[j], bound[j], bound[j - 1]])
        .collect()
}

impl OpenEnd {
    /// The end edge `left`-`right`, widened on both sides by the shoulder strip so that a
    /// vehicle leaving along the shoulder is leaving, not off the road; `inner` -> `last` is
    /// the centerline's last step.
    fn new(left: [f64; 2], right: [f64; 2], inner: [f64; 2], last: [f64; 2]) -> Self {
        let d = [last[0] - inner[0], last[1] - inner[1]];
        let len = d[0].hypot(d[1]).max(1e-12);
        let across = [left[0] - right[0], left[1] - right[1]];
        let span = across[0].hypot(across[1]).max(1e-12);
        let grow = |p: [f64; 2], sign: f64| {
            let w = sign * LANELET_SHOULDER_WIDTH / span;
            [p[0] + w * across[0], p[1] + w * across[1]]
        };
        OpenEnd {
            left: grow(left, 1.0),
            right: grow(right, -1.0),
            out: [d[0] / len, d[1] / len],
        }
    }

    fn far(&self, p: [f64; 2]) -> [f64; 2] {
        [
            p[0] + BEYOND_END_RANGE * self.out[0],
            p[1] + BEYOND_END_RANGE * self.out[1],
        ]
    }

    fn bounds(&self) -> Aabb {
        Aabb::from_points(
            [
                self.left,
                self.right,
                self.far(self.left),
                self.far(self.right),
            ]
            .into_iter()
            .map(v),
        )
    }

    /// Whether `p` is ahead of the end edge by at most [`BEYOND_END_RANGE`] and between the
    /// lines leaving the edge's two points along `out`.
    fn contains(&self, p: [f64; 2]) -> bool {
        // Signed distance ahead of the edge line (right -> left has the outside on its right).
        let ahead = -side(self.right, self.left, p) / distance(self.left, self.right).max(1e-12);
        ahead > 0.0
            && ahead <= BEYOND_END_RANGE
            && side(self.left, self.far(self.left), p) <= 0.0
            && side(self.right, self.far(self.right), p) >= 0.0
    }
}

/// Point in a (possibly slightly non-convex) quadrilateral, with points within
/// [`EDGE_TOLERANCE`] of its outline counted inside.
fn quad_contains(q: &[[f64; 2]; 4], p: [f64; 2]) -> bool {
    point_in_poly2d(v(p), &q.map(v))
        || (0..4).any(|i| segment_foot(q[i], q[(i + 1) % 4], p).1 <= EDGE_TOLERANCE)
}
