//! A lane centerline ahead of a vehicle, continued through successor lanes, as one polyline
//! with a station coordinate (0 at the vehicle). Lane keeping aims at points on it; leader
//! search projects other vehicles onto it, which stays right on curves where a straight
//! "ahead of my heading" test would not.

use crate::geometry::wrap_angle;
use crate::map::{Lane, Map};

/// Spacing of the path's points (m): the lane's 0.5 m samples thinned, plenty for curves of
/// motorway radius and 4x fewer segments to search.
const PATH_SPACING: f64 = 2.0;
/// Successor hops followed at most (junction connectors are short).
const MAX_HOPS: usize = 8;

/// A point of the path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    pub xy: [f64; 2],
    pub heading: f64,
}

#[derive(Debug, Clone)]
pub struct LanePath {
    points: Vec<[f64; 2]>,
    headings: Vec<f64>,
    stations: Vec<f64>,
    /// Lanes the path runs through, first the one it starts on.
    pub lanes: Vec<usize>,
    /// Half the width of the starting lane at the vehicle (m).
    pub half_width: f64,
}

/// The point of `lane` nearest `p`, and its arc length there: `(lane, s, lateral)`, lateral
/// positive to the left. When `p` lies past the lane's end the search continues in the
/// successor that carries straight on, so a vehicle that has driven into the next section
/// is found there.
pub fn locate_on_lane(map: &Map, mut lane: usize, p: [f64; 2]) -> (usize, f64, f64) {
    for _ in 0..MAX_HOPS {
        let l = &map.lanes()[lane];
        let near = nearest_on_polyline(&l.centerline, &l.s, p);
        match (near.past_end, continuation(map, lane)) {
            (true, Some(next)) => lane = next,
            _ => return (lane, near.s, near.lateral),
        }
    }
    let l = &map.lanes()[lane];
    let near = nearest_on_polyline(&l.centerline, &l.s, p);
    (lane, near.s, near.lateral)
}

/// The successor lane that continues most straight (smallest heading change), if any.
pub(crate) fn continuation(map: &Map, lane: usize) -> Option<usize> {
    let lanes = map.lanes();
    let l = &lanes[lane];
    let end_heading = *l.headings.last()?;
    l.successors
        .iter()
        .copied()
        .filter(|&k| lanes[k].is_graph_lane() && !lanes[k].centerline.is_empty())
        .min_by(|&a, &b| {
            let turn = |k: usize| wrap_angle(lanes[k].headings[0] - end_heading).abs();
            turn(a).total_cmp(&turn(b))
        })
}

/// The point of a polyline nearest some query point.
struct Nearest {
    /// Arc length there.
    s: f64,
    /// Signed distance, positive to the left.
    lateral: f64,
    /// The query point lies before the first point or past the last one.
    before_start: bool,
    past_end: bool,
}

/// The nearest point to `p` on the polyline `pts` with arc lengths `s`.
fn nearest_on_polyline(pts: &[[f64; 2]], s: &[f64], p: [f64; 2]) -> Nearest {
    let mut best_dist2 = f64::INFINITY;
    let mut best = Nearest {
        s: 0.0,
        lateral: 0.0,
        before_start: false,
        past_end: false,
    };
    let segments = pts.len().saturating_sub(1);
    for k in 0..segments {
        let (a, b) = (pts[k], pts[k + 1]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = (d[0] * d[0] + d[1] * d[1]).max(1e-12);
        let raw = ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2;
        let u = raw.clamp(0.0, 1.0);
        let foot = [a[0] + u * d[0], a[1] + u * d[1]];
        let dist2 = (p[0] - foot[0]).powi(2) + (p[1] - foot[1]).powi(2);
        if dist2 < best_dist2 {
            best_dist2 = dist2;
            let cross = d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0]);
            best = Nearest {
                s: s[k] + u * (s[k + 1] - s[k]),
                lateral: dist2.sqrt().copysign(cross),
                before_start: k == 0 && raw < 0.0,
                past_end: k + 1 == segments && raw > 1.0,
            };
        }
    }
    best
}

/// Linear interpolation of `(point, heading)` at arc length `at` on one lane.
fn lane_point(lane: &Lane, at: f64) -> ([f64; 2], f64) {
    let s = &lane.s;
    let k = s.partition_point(|&v| v <= at).clamp(1, s.len() - 1) - 1;
    let span = (s[k + 1] - s[k]).max(1e-9);
    let u = ((at - s[k]) / span).clamp(0.0, 1.0);
    let (a, b) = (lane.centerline[k], lane.centerline[k + 1]);
    let h = lane.headings[k] + u * wrap_angle(lane.headings[k + 1] - lane.headings[k]);
    ([a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])], h)
}

impl LanePath {
    /// The centerline of `lane` from arc length `s - behind` (not before the lane's start) to
    /// `ahead` metres past `s`, continued through [`continuation`] successors.
    pub fn new(map: &Map, lane: usize, s: f64, behind: f64, ahead: f64) -> LanePath {
        let lanes = map.lanes();
        let s = s.clamp(0.0, lanes[lane].length());
        let mut path = LanePath {
            points: Vec::new(),
            headings: Vec::new(),
            stations: Vec::new(),
            lanes: vec![lane],
            half_width: 0.5 * width_at(&lanes[lane], s),
        };
        let first = &lanes[lane];
        let start = (s - behind).max(0.0);
        let mut offset = -(s - start); // station of `start`
        let mut current = lane;
        let mut from = start;
        for _ in 0..MAX_HOPS {
            let l = &lanes[current];
            if l.centerline.len() < 2 {
                break;
            }
            let end = l.length();
            let mut at = from;
            loop {
                let (xy, h) = lane_point(l, at);
                path.push(xy, h, offset + (at - from));
                if at >= end || offset + (at - from) >= ahead {
                    break;
                }
                at = (at + PATH_SPACING).min(end);
            }
            offset += end - from;
            if offset >= ahead {
                break;
            }
            match continuation(map, current) {
                Some(next) => {
                    current = next;
                    from = 0.0;
                    path.lanes.push(next);
                }
                None => break,
            }
        }
        if path.points.len() < 2 {
            // A degenerate lane: a short straight stub along its heading keeps callers simple.
            let (xy, h) = lane_point(first, s.clamp(0.0, first.length()));
            path = LanePath {
                points: vec![xy, [xy[0] + h.cos(), xy[1] + h.sin()]],
                headings: vec![h, h],
                stations: vec![0.0, 1.0],
                lanes: vec![lane],
                half_width: path.half_width,
            };
        }
        path
    }

    fn push(&mut self, xy: [f64; 2], heading: f64, station: f64) {
        // Successor lanes start where the previous one ended: skip the repeated point.
        if let Some(&last) = self.stations.last()
            && station - last < 1e-6
        {
            return;
        }
        self.points.push(xy);
        self.headings.push(heading);
        self.stations.push(station);
    }

    /// Station of the path's last point (m).
    pub fn end_station(&self) -> f64 {
        self.stations.last().copied().unwrap_or(0.0)
    }

    /// `(station, lateral)` of the point of the path nearest `p`; `None` when `p` projects
    /// before the path's start or past its end.
    pub fn project(&self, p: [f64; 2]) -> Option<(f64, f64)> {
        let near = nearest_on_polyline(&self.points, &self.stations, p);
        (!near.before_start && !near.past_end).then_some((near.s, near.lateral))
    }

    /// The point at `station`, shifted `lateral` metres to the left; past the path's end it
    /// extends straight along the last heading.
    pub fn point_at(&self, station: f64, lateral: f64) -> PathPoint {
        let n = self.stations.len();
        let k = self
            .stations
            .partition_point(|&v| v <= station)
            .clamp(1, n - 1)
            - 1;
        let span = (self.stations[k + 1] - self.stations[k]).max(1e-9);
        let u = (station - self.stations[k]) / span;
        let (a, b) = (self.points[k], self.points[k + 1]);
        let h0 = self.headings[k];
        let heading = h0 + u.clamp(0.0, 1.0) * wrap_angle(self.headings[k + 1] - h0);
        let base = [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])];
        PathPoint {
            xy: [
                base[0] - lateral * heading.sin(),
                base[1] + lateral * heading.cos(),
            ],
            heading,
        }
    }
}

fn width_at(lane: &Lane, s: f64) -> f64 {
    let k = lane
        .s
        .partition_point(|&v| v <= s)
        .clamp(1, lane.s.len().max(1))
        - 1;
    lane.widths.get(k).copied().unwrap_or(3.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{ProceduralMap, straight};

    fn lane_with_id(map: &Map, id: i32) -> usize {
        map.lanes()
            .iter()
            .position(|l| l.id == id && l.is_graph_lane())
            .unwrap()
    }

    #[test]
    fn path_on_a_straight_lane_projects_and_interpolates() {
        let map = Map::from_opendrive(&straight(3, 3.75, 300.0).unwrap(), "t").unwrap();
        let lane = lane_with_id(&map, -2);
        let path = LanePath::new(&map, lane, 100.0, 10.0, 80.0);
        assert!((path.end_station() - 80.0).abs() < 1e-6);
        assert!((path.half_width - 1.875).abs() < 1e-9);
        // Lane -2's centre is at y = -1.5 * 3.75.
        let p = path.point_at(20.0, 0.0);
        assert!((p.xy[0] - 120.0).abs() < 1e-6 && (p.xy[1] + 5.625).abs() < 1e-6);
        let left = path.point_at(20.0, 3.75);
        assert!((left.xy[1] + 1.875).abs() < 1e-6);
        let (station, lateral) = path.project([150.0, -4.0]).unwrap();
        assert!((station - 50.0).abs() < 1e-6 && (lateral - 1.625).abs() < 1e-6);
        assert!(path.project([50.0, -5.6]).is_none(), "behind the path");
        let (found, s, lateral) = locate_on_lane(&map, lane, [150.0, -4.0]);
        assert_eq!(found, lane);
        assert!((s - 150.0).abs() < 1e-6 && (lateral - 1.625).abs() < 1e-6);
    }

    #[test]
    fn path_continues_through_a_junction_into_the_next_road() {
        let od = ProceduralMap::preset("on_ramp_merge")
            .unwrap()
            .build()
            .unwrap();
        let map = Map::from_opendrive(&od, "t").unwrap();
        // Lane -1 of the upstream road "1" ends at the junction (merge_s = 150 m).
        let lane = map
            .lanes()
            .iter()
            .position(|l| l.road_id == "1" && l.id == -1)
            .unwrap();
        let path = LanePath::new(&map, lane, 100.0, 0.0, 150.0);
        assert!(
            path.lanes.len() >= 3,
            "upstream, connector, downstream: {:?}",
            path.lanes
        );
        // The last point may overshoot by up to one spacing.
        assert!((150.0..152.0).contains(&path.end_station()));
        let end = path.point_at(150.0, 0.0);
        assert!((end.xy[0] - 250.0).abs() < 0.5, "{:?}", end.xy);
        let (found, _, _) = locate_on_lane(&map, lane, [240.0, -1.875]);
        assert_eq!(map.lanes()[found].road_id, "3");
    }
}
