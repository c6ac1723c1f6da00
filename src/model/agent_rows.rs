//! Which agent rows the networks compute.
//!
//! A padded `[B, N]` batch holds every agent that any frame of its window has, and N is the
//! largest such count in the batch. At one step most of those slots are empty: agents that
//! have not entered yet, have left, or were ended by an infraction, and the padding of smaller
//! scenes. The networks' cost grows with N (the agent <- agent edges with N^2), so they compute
//! only the agents present now, packed to the front of each scene (`[B, N']`, N' the most
//! present in one scene), and hand their outputs back in the padded layout. Packing keeps the
//! agents' order, so nearest-neighbour choices and every output are those of the padded
//! computation.

use burn::prelude::*;
use burn::tensor::{Bool, Int, TensorData};

/// The rows to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AgentRows {
    /// The agents present now, packed (the default).
    Present,
    /// Every padded slot: the reference computation the packed one must equal.
    All,
}

/// The map between a batch's padded agent slots `[B, N]` and its packed rows `[B, N']`.
#[derive(Debug, Clone)]
pub struct AgentPacking {
    batch: usize,
    padded: usize,
    packed: usize,
    /// `[B * N']`: the padded slot (b * N + n) each packed row reads; `None` for the identity.
    gather: Option<Tensor<1, Int>>,
    /// `[B * N]`: the packed row each padded slot's output comes from; B * N' (a zero row
    /// appended for the purpose) for slots without one.
    scatter: Option<Tensor<1, Int>>,
    /// `[B, N']`: a present agent.
    mask: Tensor<2, Bool>,
}

impl AgentPacking {
    /// The packing of the agents in `present` (`[B, N]`).
    pub fn new(present: &Tensor<2, Bool>, rows: AgentRows) -> Self {
        let [batch, padded] = present.dims();
        if rows == AgentRows::All {
            return Self {
                batch,
                padded,
                packed: padded,
                gather: None,
                scatter: None,
                mask: present.clone(),
            };
        }
        let device = present.device();
        let flags: Vec<bool> = present
            .clone()
            .into_data()
            .try_into_vec_as::<bool>()
            .expect("a boolean mask");
        let per_scene: Vec<Vec<usize>> = flags
            .chunks(padded.max(1))
            .map(|scene| (0..scene.len()).filter(|&n| scene[n]).collect())
            .collect();
        // At least one row, so every tensor keeps a non-empty agent axis.
        let packed = per_scene.iter().map(Vec::len).max().unwrap_or(0).max(1);
        let mut gather = vec![0i64; batch * packed];
        let mut scatter = vec![(batch * packed) as i64; batch * padded];
        let mut mask = vec![false; batch * packed];
        for (b, agents) in per_scene.iter().enumerate() {
            for (row, &n) in agents.iter().enumerate() {
                gather[b * packed + row] = (b * padded + n) as i64;
                scatter[b * padded + n] = (b * packed + row) as i64;
                mask[b * packed + row] = true;
            }
            // Empty rows read the scene's first slot; they are masked and never scattered.
            for row in agents.len()..packed {
                gather[b * packed + row] = (b * padded) as i64;
            }
        }
        let int = |v: Vec<i64>| {
            Tensor::<1, Int>::from_data(TensorData::new(v.clone(), [v.len()]), &device)
        };
        Self {
            batch,
            padded,
            packed,
            gather: Some(int(gather)),
            scatter: Some(int(scatter)),
            mask: Tensor::from_data(TensorData::new(mask, [batch, packed]), &device),
        }
    }

    /// `[B, N']`: the packed rows that hold a present agent.
    pub fn mask(&self) -> &Tensor<2, Bool> {
        &self.mask
    }

    /// N', the packed rows per scene.
    pub fn rows(&self) -> usize {
        self.packed
    }

    /// `[B, N, ...]` -> `[B, N', ...]`: the present agents' entries.
    pub fn pack<const D: usize>(&self, x: Tensor<D>) -> Tensor<D> {
        let Some(gather) = &self.gather else {
            return x;
        };
        let dims = x.dims();
        let rest: usize = dims[2..].iter().product();
        let mut shape = dims;
        shape[1] = self.packed;
        x.reshape([self.batch * self.padded, rest])
            .select(0, gather.clone())
            .reshape(shape)
    }

    /// `[B, N', C]` -> `[B, N, C]`: each agent's row back in its padded slot, zeros where no
    /// agent is present. Gradients flow back to the packed rows.
    pub fn unpack(&self, x: Tensor<3>) -> Tensor<3> {
        let Some(scatter) = &self.scatter else {
            return x;
        };
        let [b, n, c] = x.dims();
        let zero = Tensor::zeros([1, c], &x.device());
        Tensor::cat(vec![x.reshape([b * n, c]), zero], 0)
            .select(0, scatter.clone())
            .reshape([self.batch, self.padded, c])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_keeps_the_present_agents_in_order_and_unpacking_restores_their_slots() {
        let device = crate::backend::Backend::reference_device(false);
        // Scene 0: agents 1 and 3 present; scene 1: agent 0 only; scene 2: none.
        let present = Tensor::<2, Bool>::from_data(
            TensorData::new(
                vec![
                    false, true, false, true, //
                    true, false, false, false, //
                    false, false, false, false,
                ],
                [3, 4],
            ),
            &device,
        );
        let packing = AgentPacking::new(&present, AgentRows::Present);
        assert_eq!(packing.rows(), 2);
        let values: Vec<f32> = (0..12).map(|v| v as f32 + 1.0).collect();
        let x = Tensor::<3>::from_data(TensorData::new(values, [3, 4, 1]), &device);
        let packed = packing.pack(x.clone());
        let mask: Vec<bool> = packing.mask().clone().into_data().try_into_vec().unwrap();
        assert_eq!(mask, [true, true, true, false, false, false]);
        let packed_values: Vec<f32> = packed.clone().into_data().try_into_vec().unwrap();
        assert_eq!(&packed_values[..3], &[2.0, 4.0, 5.0]);
        let back: Vec<f32> = packing.unpack(packed).into_data().try_into_vec().unwrap();
        assert_eq!(
            back,
            [0.0, 2.0, 0.0, 4.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        );
        let all = AgentPacking::new(&present, AgentRows::All);
        assert_eq!(all.rows(), 4);
        assert_eq!(all.unpack(all.pack(x.clone())).into_data(), x.into_data());
    }
}
