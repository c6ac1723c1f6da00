//! The lane nodes a step's HeteroGNN lane rounds must update, and those rounds' edges in that
//! node set.
//!
//! The fused agent features read lane nodes only through each agent's nearest nodes; the last
//! lane round is read there, each earlier round one lane hop further out, and the first round
//! starts from the lane encoding (computed once per rollout over the whole graph). So with R
//! interaction rounds (R - 1 lane rounds) the agents' outputs depend on lane-round outputs only
//! within R - 2 hops of their nearest nodes: updating those nodes alone gives the same agent
//! features and gradients as updating the whole graph, for a fraction of the work when a scene
//! holds few agents on a large map (a handful of cars on the A9's 162 nodes, one car on a probe
//! road). Nodes at the crop's edge lose neighbours outside it, which only changes outputs no
//! agent reads.
//!
//! Which nodes those are is decided on the host from the (detached, discrete) nearest-node
//! choice; the crop is then fixed data, like the rest of [`super::InteractionEdges`], so the
//! PPO update re-evaluates a stored step with the crop it was collected with.

use burn::prelude::*;
use burn::tensor::{Bool, Int, TensorData};

use super::input::LaneRelation;
use crate::scene::HostNeighbours;

/// A per-scene subset of lane nodes, all scenes' in one flat list of M nodes (scene by scene,
/// ascending within each): no padding, whatever the spread of crop sizes in a batch. Tensors
/// over the crop have a leading batch dimension of 1.
#[derive(Debug, Clone)]
pub struct LaneCrop {
    /// `[M]`: the flat lane slot (scene x L + node) of each cropped node.
    nodes: Tensor<1, Int>,
    /// Per lane relation, in [`super::LaneInput::relations`]' order: `[1, M, K]` the crop
    /// position of each neighbour and whether that edge is kept (it exists and its sender is
    /// cropped).
    relations: Vec<(Tensor<3, Int>, Tensor<3, Bool>)>,
    /// `[1, B x N, K]`: each agent's nearest lane nodes as crop positions (0 where an absent
    /// agent's node was not cropped; its output is masked anyway).
    agent_lane_index: Tensor<3, Int>,
}

/// What [`LaneCrop::build`] reads, all row-major on the host.
pub struct CropInputs<'a> {
    /// `[B, N, K]` each agent's nearest lane nodes and which of them exist.
    pub agent_lane_index: &'a [i64],
    pub agent_lane_mask: &'a [bool],
    /// `[B, N]`: the agents whose outputs are kept.
    pub agent_mask: &'a [bool],
    /// `[B, N, K]`.
    pub shape: [usize; 3],
    /// Lane node slots per scene.
    pub lane_nodes: usize,
    /// The batch's lane relations, in [`super::LaneInput::relations`]' order.
    pub relations: &'a [&'a HostNeighbours],
    pub scope: CropScope,
}

/// Which nodes a crop keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CropScope {
    /// The agents' nearest nodes and everything within this many lane hops of them
    /// (interaction rounds - 2: what the agents' outputs depend on).
    Hops(usize),
    /// Every node slot: the uncropped computation, to compare against.
    WholeGraph,
}

impl LaneCrop {
    pub fn build(inputs: &CropInputs, device: &Device) -> Self {
        let [b, n, k] = inputs.shape;
        let l = inputs.lane_nodes;
        // Per scene its cropped nodes; per flat lane slot its crop position (-1: not cropped).
        let mut members: Vec<Vec<usize>> = Vec::with_capacity(b);
        let mut position = vec![-1i64; b * l];
        let mut next = 0i64;
        for scene in 0..b {
            let nodes = scene_crop(inputs, scene);
            for &node in &nodes {
                position[scene * l + node] = next;
                next += 1;
            }
            members.push(nodes);
        }
        let mut nodes: Vec<i64> = members
            .iter()
            .enumerate()
            .flat_map(|(scene, list)| list.iter().map(move |&node| (scene * l + node) as i64))
            .collect();
        if nodes.is_empty() {
            // No agent anywhere: one node keeps every tensor non-empty (nothing reads it).
            nodes.push(0);
            position[0] = 0;
        }
        let m = nodes.len();
        let relations = inputs
            .relations
            .iter()
            .map(|table| {
                let w = table.width;
                let mut index = vec![0i64; m * w];
                let mut mask = vec![false; m * w];
                for (c, &slot) in nodes.iter().enumerate() {
                    let scene = slot as usize / l;
                    for kk in 0..w {
                        let from = slot as usize * w + kk;
                        let sender = position[scene * l + table.index[from] as usize];
                        if table.mask[from] && sender >= 0 {
                            index[c * w + kk] = sender;
                            mask[c * w + kk] = true;
                        }
                    }
                }
                (
                    Tensor::from_data(TensorData::new(index, [1, m, w]), device),
                    Tensor::from_data(TensorData::new(mask, [1, m, w]), device),
                )
            })
            .collect();
        let agent_lane_index: Vec<i64> = inputs
            .agent_lane_index
            .iter()
            .enumerate()
            .map(|(i, &node)| position[i / (n * k) * l + node as usize].max(0))
            .collect();
        Self {
            nodes: Tensor::from_data(TensorData::new(nodes, [m]), device),
            relations,
            agent_lane_index: Tensor::from_data(
                TensorData::new(agent_lane_index, [1, b * n, k]),
                device,
            ),
        }
    }

    /// Cropped nodes over the whole batch (M).
    pub fn len(&self) -> usize {
        self.nodes.dims()[0]
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `[1, B x N, K]`: the agents' nearest lane nodes as crop positions.
    pub fn agent_lane_index(&self) -> Tensor<3, Int> {
        self.agent_lane_index.clone()
    }

    /// The crop's rows of a per-node tensor `[B, L, ...]`: `[1, M, ...]`.
    pub fn rows<const D: usize>(&self, t: Tensor<D>) -> Tensor<D> {
        let dims = t.dims();
        let width = dims[2..].iter().product::<usize>();
        let mut out = dims;
        out[0] = 1;
        out[1] = self.len();
        t.reshape([dims[0] * dims[1], width])
            .select(0, self.nodes.clone())
            .reshape(out)
    }

    /// The crop's rows of a per-node `[B, L, K]` Int tensor: `[1, M, K]`.
    pub fn rows_int(&self, t: Tensor<3, Int>) -> Tensor<3, Int> {
        let [b, l, k] = t.dims();
        t.reshape([b * l, k])
            .select(0, self.nodes.clone())
            .reshape([1, self.len(), k])
    }

    /// The crop's rows of a per-node `[B, L, K]` Bool tensor: `[1, M, K]`.
    pub fn rows_bool(&self, t: Tensor<3, Bool>) -> Tensor<3, Bool> {
        self.rows_int(t.int()).equal_elem(1)
    }

    /// The lane relations among cropped nodes: each relation's relative poses from
    /// `relations` (the whole graph's), its indices and mask in crop positions.
    pub fn relations(&self, relations: &[LaneRelation]) -> Vec<LaneRelation> {
        relations
            .iter()
            .zip(&self.relations)
            .map(|(full, (index, mask))| LaneRelation {
                index: index.clone(),
                mask: mask.clone(),
                pose: self.rows(full.pose.clone()),
            })
            .collect()
    }
}

/// One scene's cropped nodes, ascending.
fn scene_crop(inputs: &CropInputs, scene: usize) -> Vec<usize> {
    let [_, n, k] = inputs.shape;
    let l = inputs.lane_nodes;
    let hops = match inputs.scope {
        CropScope::Hops(hops) => hops,
        CropScope::WholeGraph => return (0..l).collect(),
    };
    let mut chosen = vec![false; l];
    let mut frontier = Vec::new();
    for agent in 0..n {
        if !inputs.agent_mask[scene * n + agent] {
            continue;
        }
        for kk in 0..k {
            let i = (scene * n + agent) * k + kk;
            let node = inputs.agent_lane_index[i] as usize;
            if inputs.agent_lane_mask[i] && !chosen[node] {
                chosen[node] = true;
                frontier.push(node);
            }
        }
    }
    for _ in 0..hops {
        let mut next = Vec::new();
        for &node in &frontier {
            for table in inputs.relations {
                for neighbour in table.of(scene, l, node) {
                    if !chosen[neighbour] {
                        chosen[neighbour] = true;
                        next.push(neighbour);
                    }
                }
            }
        }
        frontier = next;
    }
    (0..l).filter(|&node| chosen[node]).collect()
}
