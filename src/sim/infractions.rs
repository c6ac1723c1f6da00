//! Per-step infraction checks for a batch of scenes: collision (oriented boxes overlap at any
//! time of the step) and off-road (the box leaves the drivable road polygon), plus exits through an open road end.
//!
//! These flags are not differentiated, so they run as plain Rust on the CPU: scenes in
//! parallel (rayon), a bounding-circle broad phase and the separating-axis narrow phase of
//! [`OrientedBox::overlaps`] (equal to parry2d's answer, see `geometry.rs`), and the map's
//! grid-cached point queries ([`RoadRaster`]). Measured in `rtr bench sim`.

use std::collections::HashMap;
use std::sync::Arc;

use rayon::prelude::*;

use crate::geometry::{BoxMotion, OrientedBox};
use crate::map::{BoxOnRoad, Map, PointLocation, RoadRaster};

/// A map with its query cache.
#[derive(Debug, Clone)]
pub struct MapCache {
    pub map: Arc<Map>,
    pub raster: Arc<RoadRaster>,
}

/// Maps whose cache entries are kept at once (a batch touches at most a few dozen). The raster
/// itself lives with its map ([`Map::raster`]) and is filled only where vehicles drive, so an
/// entry dropped here loses nothing.
const MAX_CACHED_MAPS: usize = 16;

/// One [`MapCache`] per distinct map of recent batches (scenes of one recording share one); the
/// least recently used is dropped beyond [`MAX_CACHED_MAPS`].
#[derive(Debug, Default)]
pub struct MapCaches {
    /// Keyed by the map's address (an integer, so the cache can move between threads); the
    /// cache holds the `Arc`, so the address stays taken while its entry lives. The counter
    /// is when the entry was last used.
    by_map: HashMap<usize, (MapCache, u64)>,
    uses: u64,
}

impl MapCaches {
    pub fn get(&mut self, map: &Arc<Map>) -> MapCache {
        self.uses += 1;
        let key = Arc::as_ptr(map) as usize;
        if !self.by_map.contains_key(&key) && self.by_map.len() >= MAX_CACHED_MAPS {
            let oldest = self.by_map.iter().min_by_key(|(_, (_, used))| *used);
            if let Some(&oldest) = oldest.map(|(k, _)| k) {
                self.by_map.remove(&oldest);
            }
        }
        let (cache, used) = self.by_map.entry(key).or_insert_with(|| {
            (
                MapCache {
                    map: map.clone(),
                    raster: map.raster(),
                },
                0,
            )
        });
        *used = self.uses;
        cache.clone()
    }

    /// Maps cached now.
    pub fn len(&self) -> usize {
        self.by_map.len()
    }

    pub fn is_empty(&self) -> bool {
        self.by_map.is_empty()
    }
}

/// Boxes of one step, `[B * N]` row-major, box centres.
pub struct StepBoxes<'a> {
    pub agents: usize,
    pub cx: &'a [f32],
    pub cy: &'a [f32],
    pub heading: &'a [f32],
    pub length: &'a [f32],
    pub width: &'a [f32],
    /// Present on the road at this step (padding, absent and removed agents are false).
    pub present: &'a [bool],
}

/// Flags of one step, `[B * N]` row-major.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepInfractions {
    pub collision: Vec<bool>,
    pub offroad: Vec<bool>,
    /// The box centre has passed an open road end: the agent has left the map.
    pub exited: Vec<bool>,
    /// Collided, and only with boxes in its rear quarter: struck from behind, not at fault
    /// (nuPlan's rule for at-fault collisions counts a rear collision against the striker).
    pub struck_from_behind: Vec<bool>,
}

/// `other`'s centre lies in `own`'s rear quarter: behind it, less to the side than behind.
pub(crate) fn in_rear_quarter(own: &OrientedBox, other: &OrientedBox) -> bool {
    let (dx, dy) = (
        other.center[0] - own.center[0],
        other.center[1] - own.center[1],
    );
    let (cos, sin) = (own.heading.cos(), own.heading.sin());
    let (ahead, side) = (dx * cos + dy * sin, -dx * sin + dy * cos);
    ahead < 0.0 && side.abs() < -ahead
}

/// Checks every present box against its scene's map and every other present box. With the
/// step's start (`previous`), two boxes collide when they overlap at any time of the step
/// ([`BoxMotion::first_contact`]), not only at its end: at highway speeds a car moves several
/// car lengths per step and would otherwise pass through a stopped one unseen. A box absent
/// at the start is checked where it ends.
pub fn check_step(
    boxes: &StepBoxes,
    previous: Option<&StepBoxes>,
    maps: &[MapCache],
) -> StepInfractions {
    let n = boxes.agents;
    let total = boxes.present.len();
    let mut out = StepInfractions {
        collision: vec![false; total],
        offroad: vec![false; total],
        exited: vec![false; total],
        struck_from_behind: vec![false; total],
    };
    let footprint = |step: &StepBoxes, i: usize| {
        OrientedBox::new(
            [step.cx[i] as f64, step.cy[i] as f64],
            step.heading[i] as f64,
            step.length[i] as f64,
            step.width[i] as f64,
        )
    };
    let motion = |i: usize| {
        let to = footprint(boxes, i);
        match previous {
            Some(before) if before.present[i] => BoxMotion {
                from: footprint(before, i),
                to,
            },
            _ => BoxMotion::still(to),
        }
    };
    out.collision
        .par_chunks_mut(n)
        .zip(out.offroad.par_chunks_mut(n))
        .zip(out.exited.par_chunks_mut(n))
        .zip(out.struck_from_behind.par_chunks_mut(n))
        .enumerate()
        .for_each(
            |(b, (((collision, offroad), exited), struck_from_behind))| {
                let cache = &maps[b];
                let scene: Vec<(usize, BoxMotion)> = (0..n)
                    .filter(|&a| boxes.present[b * n + a])
                    .map(|a| (a, motion(b * n + a)))
                    .collect();
                for &(a, BoxMotion { to: fp, .. }) in &scene {
                    if cache.raster.point_location(&cache.map, fp.center)
                        == PointLocation::BeyondRoadEnd
                    {
                        exited[a] = true;
                    } else {
                        offroad[a] =
                            cache.raster.box_on_road(&cache.map, &fp) == BoxOnRoad::OffRoad;
                    }
                }
                let mut at_fault = vec![false; n];
                for (i, &(a, fa)) in scene.iter().enumerate() {
                    if exited[a] {
                        continue;
                    }
                    for &(c, fc) in &scene[i + 1..] {
                        if exited[c] {
                            continue;
                        }
                        if let Some(s) = fa.first_contact(&fc) {
                            let (fa, fc) = (fa.at(s), fc.at(s));
                            collision[a] = true;
                            collision[c] = true;
                            at_fault[a] |= !in_rear_quarter(&fa, &fc);
                            at_fault[c] |= !in_rear_quarter(&fc, &fa);
                        }
                    }
                }
                for a in 0..n {
                    struck_from_behind[a] = collision[a] && !at_fault[a];
                }
            },
        );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{Map, ProceduralMap};
    use crate::test_rng::uniform;

    /// A run visiting many maps keeps at most [`MAX_CACHED_MAPS`] rasters; the least recently
    /// used goes first, and a map in use is served from its entry, not rebuilt.
    #[test]
    fn map_caches_stay_bounded_and_keep_recent_maps() {
        let od = ProceduralMap::preset("straight")
            .and_then(|p| p.build())
            .expect("map");
        let maps: Vec<Arc<Map>> = (0..MAX_CACHED_MAPS + 4)
            .map(|_| Arc::new(Map::from_opendrive(&od, "straight").expect("map")))
            .collect();
        let mut caches = MapCaches::default();
        let first = caches.get(&maps[0]);
        for map in &maps[1..] {
            caches.get(map);
            // The first map stays the most recently used.
            let again = caches.get(&maps[0]);
            assert!(Arc::ptr_eq(&again.raster, &first.raster));
        }
        assert_eq!(caches.len(), MAX_CACHED_MAPS);
        // Map 1 was used least recently of all: it was evicted and is rebuilt.
        let map1 = caches.get(&maps[1]);
        assert!(Arc::ptr_eq(&map1.map, &maps[1]));
        assert_eq!(caches.len(), MAX_CACHED_MAPS);
    }

    /// A rear-end blames the striker only; cars side by side and head-on both are at fault.
    #[test]
    fn only_a_car_struck_from_behind_is_not_at_fault() {
        let od = ProceduralMap::preset("straight")
            .and_then(|p| p.build())
            .expect("map");
        let map = Arc::new(Map::from_opendrive(&od, "straight").expect("map"));
        let mut caches = MapCaches::default();
        let maps = vec![caches.get(&map); 3];
        // Scene 0: a follower's nose 0.5 m into a leader's tail (slightly offset sideways).
        // Scene 1: two cars side by side, 1.5 m apart centre to centre. Scene 2: head-on.
        let cx = [150.0, 154.1, 150.0, 150.5, 150.0, 154.0];
        let cy = [-5.0, -4.6, -5.0, -3.5, -5.0, -5.0];
        let heading = [0.0, 0.05, 0.0, 0.0, 0.0, std::f32::consts::PI];
        let flags = check_step(
            &StepBoxes {
                agents: 2,
                cx: &cx,
                cy: &cy,
                heading: &heading,
                length: &[4.6; 6],
                width: &[1.9; 6],
                present: &[true; 6],
            },
            None,
            &maps,
        );
        assert_eq!(flags.collision, [true; 6]);
        assert_eq!(
            flags.struck_from_behind,
            [false, true, false, false, false, false]
        );
    }

    #[test]
    fn batched_collisions_equal_parry2d_pairwise() {
        use parry2d::math::{Pose, Vector};
        use parry2d::query::intersection_test;
        use parry2d::shape::Cuboid;

        let od = ProceduralMap::preset("straight")
            .and_then(|p| p.build())
            .expect("map");
        let map = Arc::new(Map::from_opendrive(&od, "straight").expect("map"));
        let mut caches = MapCaches::default();
        let (b, n) = (40, 24);
        let maps: Vec<_> = (0..b).map(|_| caches.get(&map)).collect();
        let mut rng = 11u64;
        let mut col = |lo, hi| uniform(&mut rng, lo, hi) as f32;
        let cx: Vec<f32> = (0..b * n).map(|_| col(150.0, 190.0)).collect();
        let cy: Vec<f32> = (0..b * n).map(|_| col(-12.0, 1.0)).collect();
        let heading: Vec<f32> = (0..b * n).map(|_| col(-3.1, 3.1)).collect();
        let length: Vec<f32> = (0..b * n).map(|_| col(3.5, 16.0)).collect();
        let width: Vec<f32> = (0..b * n).map(|_| col(1.5, 2.6)).collect();
        let present: Vec<bool> = (0..b * n).map(|i| i % 7 != 3).collect();
        let flags = check_step(
            &StepBoxes {
                agents: n,
                cx: &cx,
                cy: &cy,
                heading: &heading,
                length: &length,
                width: &width,
                present: &present,
            },
            None,
            &maps,
        );
        let shape = |i: usize| {
            (
                Pose::new(Vector::new(cx[i] as f64, cy[i] as f64), heading[i] as f64),
                Cuboid::new(Vector::new(0.5 * length[i] as f64, 0.5 * width[i] as f64)),
            )
        };
        let (mut pairs, mut hits) = (0, 0);
        for s in 0..b {
            for a in 0..n {
                let i = s * n + a;
                let mut expected = false;
                for c in (0..n).filter(|&c| c != a) {
                    let j = s * n + c;
                    if !(present[i] && present[j]) {
                        continue;
                    }
                    let ((pa, ca), (pb, cb)) = (shape(i), shape(j));
                    pairs += 1;
                    expected |= intersection_test(&pa, &ca, &pb, &cb)
                        .expect("cuboids")
                        .intersecting;
                }
                assert_eq!(flags.collision[i], expected, "scene {s} agent {a}");
                hits += usize::from(expected);
            }
        }
        assert!(pairs >= 10_000, "{pairs} pairs");
        assert!(hits > 50 && hits < b * n, "{hits} colliding agents");
        // Absent agents are never flagged.
        assert!((0..b * n).all(|i| present[i] || !(flags.collision[i] || flags.offroad[i])));
    }
}
