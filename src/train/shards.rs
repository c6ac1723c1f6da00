//! Data parallelism on one machine: a minibatch's parts are cut into buckets of scenes of
//! similar size, the buckets are spread over the devices (one worker thread each), and every
//! worker runs its buckets one after another.
//!
//! Why buckets: a batch is padded to its largest scene, and the agent-agent messages grow with
//! the square of the padded agent count. A9 training scenes hold 4-33 agents (mean 13.5), so a
//! random minibatch of 32 padded to its largest wastes about half of the agent work; sorted
//! buckets of a few scenes waste little. Every scene keeps its draw slot (which seeds its
//! action noise), so sampled actions and losses do not depend on how scenes are grouped.

use super::sources::Part;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::sim::MapCaches;

/// Scenes per bucket at most: small enough that padding stays low, large enough that each
/// tensor op still has work for the whole batch (op overhead is per call, not per scene).
pub const BUCKET_SCENES: usize = 8;

/// Relative cost of one padded lane node against one padded agent in a policy step: the lane
/// rounds of the HeteroGNN cost about a tenth per node of what the history encoder and agent
/// rounds cost per agent (from the layer widths of the paper-size network).
const LANE_NODE_COST: f64 = 0.1;

/// Estimated work of a batch of `scenes`: its padded size.
fn bucket_cost(scenes: &[&Scene]) -> f64 {
    let agents = scenes.iter().map(|s| s.agents.len()).max().unwrap_or(0);
    let lanes = scenes
        .iter()
        .map(|s| s.lane_graph.nodes.len())
        .max()
        .unwrap_or(0);
    scenes.len() as f64 * (agents as f64 + LANE_NODE_COST * lanes as f64)
}

/// Cuts `part` into buckets of at most `max_scenes` scenes of similar size (sorted by lane
/// nodes, then agents; equal sizes keep their draw order), as evenly filled as possible.
fn buckets<'a>(part: Part<'a>, max_scenes: usize) -> Vec<Part<'a>> {
    let n = part.scenes.len();
    if n == 0 {
        return Vec::new();
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| {
        let s = part.scenes[i];
        (s.lane_graph.nodes.len(), s.agents.len())
    });
    let count = n.div_ceil(max_scenes.max(1));
    let (base, extra) = (n / count, n % count);
    let mut out = Vec::with_capacity(count);
    let mut start = 0;
    for k in 0..count {
        let len = base + usize::from(k < extra);
        let picked = &order[start..start + len];
        start += len;
        out.push(Part {
            scenes: picked.iter().map(|&i| part.scenes[i]).collect(),
            scenarios: if part.scenarios.is_empty() {
                Vec::new()
            } else {
                picked.iter().map(|&i| part.scenarios[i]).collect()
            },
            slots: picked.iter().map(|&i| part.slots[i]).collect(),
        });
    }
    out
}

/// Buckets every part and spreads the buckets over `devices` workers, largest first onto the
/// least loaded one (LPT scheduling). Workers left without work are dropped, so the result has
/// between 1 and `devices` entries (none when there are no scenes).
pub fn plan<'a>(parts: Vec<Part<'a>>, devices: usize, max_scenes: usize) -> Vec<Vec<Part<'a>>> {
    let mut all: Vec<(f64, Part<'a>)> = parts
        .into_iter()
        .flat_map(|p| buckets(p, max_scenes))
        .map(|b| (bucket_cost(&b.scenes), b))
        .collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0));
    let devices = devices.max(1);
    let mut load = vec![0.0f64; devices];
    let mut out: Vec<Vec<Part<'a>>> = (0..devices).map(|_| Vec::new()).collect();
    for (cost, bucket) in all {
        let k = (0..devices)
            .min_by(|&a, &b| load[a].total_cmp(&load[b]))
            .unwrap_or(0);
        load[k] += cost;
        out[k].push(bucket);
    }
    out.retain(|w| !w.is_empty());
    out
}

/// Runs `f` once per (work item, cache), in parallel when there are several.
///
/// The workers are rayon tasks, not plain threads: Flex parallelises its own ops with rayon, and
/// from inside the pool those nested splits are work-stolen by the other worker's thread when
/// it is idle instead of being injected into the pool from outside at every op.
pub fn per_device<W: Send, T: Send>(
    work: Vec<W>,
    caches: &mut [MapCaches],
    f: impl Fn(usize, W, &mut MapCaches) -> Result<T> + Sync,
) -> Result<Vec<T>> {
    if work.len() == 1 {
        let w = work.into_iter().next().expect("one work item");
        return Ok(vec![f(0, w, &mut caches[0])?]);
    }
    work.into_par_iter()
        .zip(caches.par_iter_mut())
        .enumerate()
        .map(|(k, (w, cache))| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(k, w, cache)))
                .unwrap_or_else(|_| Err(Error::InvalidArgument("a device worker panicked".into())))
        })
        .collect()
}

/// Worker threads for data parallelism when a run names none: one per core the process may
/// use on the CPU backends, one on a GPU (its kernels are parallel already).
pub fn default_devices(backend: crate::backend::Backend) -> usize {
    match backend {
        crate::backend::Backend::Wgpu => 1,
        _ => std::thread::available_parallelism().map_or(1, |n| n.get()),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::map::{LaneGraph, Map, ProceduralMap};
    use crate::scene::synthetic_scene;

    /// Scenes on a straight procedural road with the given agent counts.
    fn scenes_with(agents: &[usize]) -> Vec<Scene> {
        let od = ProceduralMap::preset("straight")
            .and_then(|p| p.build())
            .expect("map");
        let map = Arc::new(Map::from_opendrive(&od, "straight").expect("map"));
        let graph = Arc::new(LaneGraph::build(&map, 10.0));
        agents
            .iter()
            .enumerate()
            .map(|(k, &n)| synthetic_scene(&map, &graph, n, k, 4, 1))
            .collect()
    }

    #[test]
    fn buckets_sort_by_size_and_keep_every_scene_with_its_slot_once() {
        let scenes = scenes_with(&[5, 1, 9, 3, 7, 2, 8, 4, 6, 10]);
        let part = Part {
            scenes: scenes.iter().collect(),
            scenarios: Vec::new(),
            slots: (0..scenes.len()).map(|k| 100 + k).collect(),
        };
        let workers = plan(vec![part], 2, 3);
        assert_eq!(workers.len(), 2);
        let buckets: Vec<&Part> = workers.iter().flatten().collect();
        // 10 scenes in buckets of at most 3: four buckets of 3, 3, 2, 2.
        let mut sizes: Vec<usize> = buckets.iter().map(|b| b.scenes.len()).collect();
        sizes.sort();
        assert_eq!(sizes, vec![2, 2, 3, 3]);
        let mut seen: Vec<(usize, usize)> = Vec::new();
        for b in &buckets {
            let agents: Vec<usize> = b.scenes.iter().map(|s| s.agents.len()).collect();
            assert!(agents.windows(2).all(|w| w[0] <= w[1]), "{agents:?}");
            for (s, &slot) in b.scenes.iter().zip(&b.slots) {
                seen.push((slot, s.agents.len()));
            }
        }
        seen.sort();
        let expected: Vec<(usize, usize)> = scenes
            .iter()
            .enumerate()
            .map(|(k, s)| (100 + k, s.agents.len()))
            .collect();
        assert_eq!(seen, expected);
        // Sorted buckets never mix the smallest and the largest scenes.
        assert!(
            buckets
                .iter()
                .all(|b| !(b.scenes.iter().any(|s| s.agents.len() == 1)
                    && b.scenes.iter().any(|s| s.agents.len() == 10)))
        );
    }

    #[test]
    fn the_plan_balances_padded_work_over_devices() {
        let scenes = scenes_with(&(1..=16).collect::<Vec<_>>());
        let part = Part {
            scenes: scenes.iter().collect(),
            scenarios: Vec::new(),
            slots: (0..16).collect(),
        };
        let workers = plan(vec![part], 2, 4);
        let load = |w: &Vec<Part>| w.iter().map(|b| bucket_cost(&b.scenes)).sum::<f64>();
        let (a, b) = (load(&workers[0]), load(&workers[1]));
        assert!((a - b).abs() <= 0.25 * a.max(b), "{a} vs {b}");
        assert_eq!(plan(Vec::new(), 2, 4).len(), 0);
    }
}
