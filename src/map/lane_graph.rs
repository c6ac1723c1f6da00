//! The paper's lane graph: graph-lane centerlines cut into nodes of about `node_length` metres,
//! with successor / predecessor edges along and across lanes and left / right edges to the
//! neighbouring lanes. Node features describe the lane piece only (length, width, curvature,
//! speed limit, boundary marks); poses are kept separate so features do not depend on the
//! global frame.

use std::ops::Range;

use super::lanes::{Lane, Map};
use super::opendrive::RoadMark;
use crate::geometry::wrap_angle;

/// Number of entries of [`LaneNode::features`].
pub const LANE_NODE_FEATURES: usize = 12;

/// Names of the [`LaneNode::features`] entries, in order.
pub const LANE_NODE_FEATURE_NAMES: [&str; LANE_NODE_FEATURES] = [
    "length_m",
    "width_m",
    "curvature_per_m",
    "speed_limit_mps",
    "left_mark_none",
    "left_mark_solid",
    "left_mark_broken",
    "left_mark_other",
    "right_mark_none",
    "right_mark_solid",
    "right_mark_broken",
    "right_mark_other",
];

/// A compact categorisation of road marks by what they allow:
/// 0 none (no paint), 1 solid (do not cross: solid, solid solid, curb, grass, edge),
/// 2 broken (may cross: broken, broken broken, botts dots), 3 other (one-sided double marks
/// such as solid broken, custom and unknown types).
pub fn mark_category(m: &RoadMark) -> usize {
    match m {
        RoadMark::None => 0,
        RoadMark::Solid
        | RoadMark::SolidSolid
        | RoadMark::Curb
        | RoadMark::Grass
        | RoadMark::Edge => 1,
        RoadMark::Broken | RoadMark::BrokenBroken | RoadMark::BottsDots => 2,
        RoadMark::SolidBroken | RoadMark::BrokenSolid | RoadMark::Custom | RoadMark::Other(_) => 3,
    }
}

/// A piece of a lane centerline.
#[derive(Clone, Debug, PartialEq)]
pub struct LaneNode {
    /// Index into [`Map::lanes`].
    pub lane: usize,
    /// Arc-length range along the lane centerline (m).
    pub s_start: f64,
    pub s_end: f64,
    /// Centerline point and heading at the middle of the piece.
    pub center: [f64; 2],
    pub heading: f64,
    pub start: [f64; 2],
    pub end: [f64; 2],
    pub length: f64,
    /// Mean lane width (m).
    pub width: f64,
    /// Heading change over the piece divided by its length (1/m, positive turning left).
    pub curvature: f64,
    pub speed_limit: f64,
    pub left_mark: RoadMark,
    pub right_mark: RoadMark,
}

impl LaneNode {
    /// Frame-independent features, named by [`LANE_NODE_FEATURE_NAMES`].
    pub fn features(&self) -> [f32; LANE_NODE_FEATURES] {
        let mut f = [0.0f32; LANE_NODE_FEATURES];
        f[0] = self.length as f32;
        f[1] = self.width as f32;
        f[2] = self.curvature as f32;
        f[3] = self.speed_limit as f32;
        f[4 + mark_category(&self.left_mark)] = 1.0;
        f[8 + mark_category(&self.right_mark)] = 1.0;
        f
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct LaneGraph {
    pub node_length: f64,
    pub nodes: Vec<LaneNode>,
    /// Next node of the same lane, or the first node of each successor lane.
    pub successors: Vec<Vec<usize>>,
    pub predecessors: Vec<Vec<usize>>,
    /// The node of the left / right neighbour lane whose centre is nearest, when that choice
    /// is mutual (so left and right edges mirror each other); at most one.
    pub left: Vec<Vec<usize>>,
    pub right: Vec<Vec<usize>>,
    /// Node index range of each lane of the map (empty for non-graph lanes).
    pub lane_nodes: Vec<Range<usize>>,
}

/// Fixed-width padded neighbour lists for batched gathers.
#[derive(Clone, Debug, PartialEq)]
pub struct NeighbourTable {
    pub width: usize,
    /// nodes x width, row-major, padded with 0.
    pub index: Vec<i64>,
    /// nodes x width: true where `index` holds a real neighbour.
    pub mask: Vec<bool>,
}

/// Pads `lists` to the longest list (at least 1 column).
pub fn neighbour_table(lists: &[Vec<usize>]) -> NeighbourTable {
    let width = lists.iter().map(Vec::len).max().unwrap_or(0).max(1);
    let mut index = vec![0i64; lists.len() * width];
    let mut mask = vec![false; lists.len() * width];
    for (i, list) in lists.iter().enumerate() {
        for (k, &j) in list.iter().enumerate() {
            index[i * width + k] = j as i64;
            mask[i * width + k] = true;
        }
    }
    NeighbourTable { width, index, mask }
}

/// Centerline values at arc length `q`, interpolated between samples.
struct At {
    point: [f64; 2],
    heading: f64,
    width: f64,
    sample: usize,
}

fn at(lane: &Lane, q: f64) -> At {
    let n = lane.s.len();
    let j = lane.s.partition_point(|&s| s <= q).clamp(1, n.max(2) - 1);
    let (s0, s1) = (lane.s[j - 1], lane.s[j]);
    let u = if s1 > s0 {
        ((q - s0) / (s1 - s0)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (a, b) = (lane.centerline[j - 1], lane.centerline[j]);
    let (h0, h1) = (lane.headings[j - 1], lane.headings[j]);
    At {
        point: [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])],
        heading: wrap_angle(h0 + u * wrap_angle(h1 - h0)),
        width: lane.widths[j - 1] + u * (lane.widths[j] - lane.widths[j - 1]),
        sample: if u < 0.5 { j - 1 } else { j },
    }
}

/// Cut points of a lane of length `len`: every `node_length`, the last piece merged into the
/// previous one when shorter than half `node_length`.
fn cuts(len: f64, node_length: f64) -> Vec<f64> {
    let full = (len / node_length).floor() as usize;
    let rest = len - full as f64 * node_length;
    let pieces = if full == 0 || rest >= 0.5 * node_length {
        full + 1
    } else {
        full
    };
    let mut c: Vec<f64> = (0..pieces).map(|k| k as f64 * node_length).collect();
    c.push(len);
    c
}

impl LaneGraph {
    /// Cuts every graph lane of `map` into nodes. A `node_length` that is not a positive
    /// number falls back to 10 m, the paper's value.
    pub fn build(map: &Map, node_length: f64) -> LaneGraph {
        let node_length = if node_length.is_finite() && node_length > 0.0 {
            node_length
        } else {
            10.0
        };
        let lanes = map.lanes();
        let mut nodes = Vec::new();
        let mut lane_nodes = Vec::with_capacity(lanes.len());
        for (i, lane) in lanes.iter().enumerate() {
            let first = nodes.len();
            if lane.is_graph_lane() && lane.centerline.len() >= 2 {
                let c = cuts(lane.length(), node_length);
                for w in c.windows(2) {
                    let (a, b) = (at(lane, w[0]), at(lane, w[1]));
                    let mid = at(lane, 0.5 * (w[0] + w[1]));
                    let length = w[1] - w[0];
                    // Mean width by the trapezoid rule on the samples inside the piece.
                    let inside: Vec<f64> = lane
                        .s
                        .iter()
                        .zip(&lane.widths)
                        .filter(|(s, _)| **s > w[0] && **s < w[1])
                        .map(|(_, w)| *w)
                        .collect();
                    let width = (a.width + b.width + inside.iter().sum::<f64>() * 2.0)
                        / (2.0 + 2.0 * inside.len() as f64);
                    nodes.push(LaneNode {
                        lane: i,
                        s_start: w[0],
                        s_end: w[1],
                        center: mid.point,
                        heading: mid.heading,
                        start: a.point,
                        end: b.point,
                        length,
                        width,
                        curvature: if length > 0.0 {
                            wrap_angle(b.heading - a.heading) / length
                        } else {
                            0.0
                        },
                        speed_limit: lane.speed_limit,
                        left_mark: lane.left_marks[mid.sample].clone(),
                        right_mark: lane.right_marks[mid.sample].clone(),
                    });
                }
            }
            lane_nodes.push(first..nodes.len());
        }

        let n = nodes.len();
        let mut successors = vec![Vec::new(); n];
        for (i, lane) in lanes.iter().enumerate() {
            let range = lane_nodes[i].clone();
            let Some(last) = range.clone().last() else {
                continue;
            };
            for (k, succ) in successors
                .iter_mut()
                .enumerate()
                .take(last)
                .skip(range.start)
            {
                succ.push(k + 1);
            }
            for &next in &lane.successors {
                if !lane_nodes[next].is_empty() {
                    successors[last].push(lane_nodes[next].start);
                }
            }
            successors[last].sort_unstable();
            successors[last].dedup();
        }
        let mut predecessors = vec![Vec::new(); n];
        for (i, succ) in successors.iter().enumerate() {
            for &j in succ {
                predecessors[j].push(i);
            }
        }

        let mut left = vec![Vec::new(); n];
        let mut right = vec![Vec::new(); n];
        for (i, lane) in lanes.iter().enumerate() {
            let Some(j) = lane.left_neighbour else {
                continue;
            };
            let (ours, theirs) = (lane_nodes[i].clone(), lane_nodes[j].clone());
            for a in ours.clone() {
                let Some(b) = nearest(&nodes, theirs.clone(), nodes[a].center) else {
                    continue;
                };
                if nearest(&nodes, ours.clone(), nodes[b].center) == Some(a) {
                    left[a].push(b);
                    right[b].push(a);
                }
            }
        }
        LaneGraph {
            node_length,
            nodes,
            successors,
            predecessors,
            left,
            right,
            lane_nodes,
        }
    }

    /// The node of lane `lane` containing centerline arc length `s` (clamped to the lane).
    pub fn node_at(&self, lane: usize, s: f64) -> Option<usize> {
        let range = self.lane_nodes.get(lane)?.clone();
        let nodes = &self.nodes[range.clone()];
        let k = nodes
            .partition_point(|n| n.s_end <= s)
            .min(nodes.len().checked_sub(1)?);
        Some(range.start + k)
    }
}

fn nearest(nodes: &[LaneNode], range: Range<usize>, p: [f64; 2]) -> Option<usize> {
    range.min_by(|&a, &b| {
        let da = (nodes[a].center[0] - p[0]).hypot(nodes[a].center[1] - p[1]);
        let db = (nodes[b].center[0] - p[0]).hypot(nodes[b].center[1] - p[1]);
        da.total_cmp(&db)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::test_maps::a9;

    fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1])
    }

    #[test]
    fn cuts_merge_a_short_last_piece() {
        assert_eq!(cuts(24.9, 10.0), vec![0.0, 10.0, 24.9]);
        assert_eq!(cuts(25.0, 10.0), vec![0.0, 10.0, 20.0, 25.0]);
        assert_eq!(cuts(26.0, 10.0), vec![0.0, 10.0, 20.0, 26.0]);
        assert_eq!(cuts(20.0, 10.0), vec![0.0, 10.0, 20.0]);
        assert_eq!(cuts(3.0, 10.0), vec![0.0, 3.0]);
    }

    #[test]
    fn a9_lane_graph() {
        let map = a9();
        let g = LaneGraph::build(&map, 10.0);
        assert!(
            (156..=162).contains(&g.nodes.len()),
            "{} nodes",
            g.nodes.len()
        );
        for (i, node) in g.nodes.iter().enumerate() {
            let lane = &map.lanes()[node.lane];
            assert!(lane.is_graph_lane());
            assert!(node.length >= 5.0 && node.length < 15.0);
            assert!((dist(node.start, node.end) - node.length).abs() < 1e-3);
            // Every node but the lane's last has exactly one successor, about one node ahead.
            if g.successors[i].is_empty() {
                assert_eq!(Some(i), g.lane_nodes[node.lane].clone().last());
                continue;
            }
            assert_eq!(g.successors[i].len(), 1);
            let next = &g.nodes[g.successors[i][0]];
            let d = dist(node.center, next.center);
            assert!((d - 0.5 * (node.length + next.length)).abs() < 1e-3);
            if next.length == 10.0 {
                assert!((d - 10.0).abs() < 1.0, "centres {d} m apart");
            }
            let dir = (next.center[1] - node.center[1]).atan2(next.center[0] - node.center[0]);
            assert!(wrap_angle(dir - node.heading).abs() < 3f64.to_radians());
            assert_eq!(g.predecessors[g.successors[i][0]], vec![i]);
            let f = node.features();
            assert!(f.iter().all(|x| x.is_finite()));
            assert_eq!(f[4..8].iter().sum::<f32>(), 1.0);
            assert_eq!(f[8..12].iter().sum::<f32>(), 1.0);
            assert!((f[3] - (100.0 / 3.6) as f32).abs() < 1e-4);
        }
        let mut pairs = 0;
        for (a, lefts) in g.left.iter().enumerate() {
            assert!(lefts.len() <= 1 && g.right[a].len() <= 1);
            for &b in lefts {
                pairs += 1;
                assert_eq!(g.right[b], vec![a]);
                let (na, nb) = (&g.nodes[a], &g.nodes[b]);
                assert!(
                    wrap_angle(na.heading - nb.heading).abs() < 0.01,
                    "same travel direction"
                );
                assert!(dist(na.center, nb.center) < 5.0);
            }
        }
        // 2 lane pairs per carriageway, ~27 nodes each.
        assert!(pairs >= 4 * 25, "{pairs} left edges");
    }

    #[test]
    fn neighbour_table_pads_with_masked_zeros() {
        let t = neighbour_table(&[vec![2], vec![], vec![0, 1]]);
        assert_eq!(t.width, 2);
        assert_eq!(t.index, vec![2, 0, 0, 0, 0, 1]);
        assert_eq!(t.mask, vec![true, false, false, false, true, true]);
        let t = neighbour_table(&[vec![], vec![]]);
        assert_eq!((t.width, t.index.len()), (1, 2));
        assert!(t.mask.iter().all(|m| !m));
    }

    #[test]
    fn features_ignore_the_global_frame() {
        let map = a9();
        let g = LaneGraph::build(&map, 10.0);
        let mut moved = g.nodes[3].clone();
        moved.center = [1e5, -3e4];
        moved.heading += 1.0;
        moved.start = [0.0, 0.0];
        assert_eq!(moved.features(), g.nodes[3].features());
        assert_eq!(LANE_NODE_FEATURE_NAMES.len(), LANE_NODE_FEATURES);
    }
}
