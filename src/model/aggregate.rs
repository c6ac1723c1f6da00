//! Graph plumbing on padded, batched tensors: gathering neighbour rows through fixed-width
//! index tables, and max aggregation over masked neighbours.
//!
//! Max aggregation is a dense masked max over the neighbour axis, not burn's scatter with
//! `IndexingUpdateOp::Max`: the scatter's gradient is wrong when several edges reach the same
//! node (every loser gets gradient too, see `shared/notes/burn-0.22.md`). The max is a tree of
//! `max_pair` (an elementwise select) rather than `max_dim`, which on burn-ndarray took ~50 ms
//! for a `[32, 162, 2, 128]` tensor against ~3 ms for the tree; both route the gradient to the
//! single winner, as `tests/gradients.rs` checks against finite differences.

use burn::prelude::*;
use burn::tensor::{Bool, Int};

/// Value that masked-out entries take before the max; any real message is far above it.
const MASKED: f64 = -1e9;

/// Rows of `nodes` (`[B, M, C]`) picked per batch by `index` (`[B, R, K]`, values in `0..M`):
/// `[B, R, K, C]`. Gradients flow back to `nodes` (a select, whose backward adds).
pub fn gather_neighbours(nodes: Tensor<3>, index: Tensor<3, Int>) -> Tensor<4> {
    let [b, m, c] = nodes.dims();
    let [_, r, k] = index.dims();
    let device = nodes.device();
    let offset = Tensor::<1, Int>::arange(0..b as i64, &device)
        .mul_scalar(m as i64)
        .reshape([b, 1, 1]);
    let flat = (index + offset).reshape([b * r * k]);
    nodes
        .reshape([b * m, c])
        .select(0, flat)
        .reshape([b, r, k, c])
}

/// Max over the neighbour axis (dim 2) of `messages` (`[B, R, K, C]`) where `mask`
/// (`[B, R, K]`) is true; rows with no neighbour get 0.
pub fn masked_max(messages: Tensor<4>, mask: Tensor<3, Bool>) -> Tensor<3> {
    let [b, r, mut k, c] = messages.dims();
    let any = mask.clone().any_dim(2).reshape([b, r, 1]);
    let mut x = messages.mask_fill(mask.bool_not().unsqueeze_dim::<4>(3), MASKED);
    // Halve the neighbour axis until one entry is left; an odd last entry is carried along.
    while k > 1 {
        let half = k / 2;
        let paired = x
            .clone()
            .narrow(2, 0, half)
            .max_pair(x.clone().narrow(2, half, half));
        x = if k % 2 == 1 {
            Tensor::cat(vec![paired, x.narrow(2, 2 * half, 1)], 2)
        } else {
            paired
        };
        k = half + k % 2;
    }
    x.reshape([b, r, c]).mask_fill(any.bool_not(), 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn vec_of<const D: usize>(t: Tensor<D>) -> Vec<f64> {
        t.into_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .unwrap()
    }

    #[test]
    fn gathers_rows_per_scene() {
        #[allow(deprecated)]
        let device = Device::ndarray();
        let nodes = Tensor::<3>::from_data(
            TensorData::new((0..12).map(|v| v as f32).collect(), [2, 3, 2]),
            &device,
        );
        let index =
            Tensor::<3, Int>::from_data(TensorData::new(vec![2i64, 0, 1, 1], [2, 1, 2]), &device);
        let got = vec_of(gather_neighbours(nodes, index));
        assert_eq!(got, vec![4.0, 5.0, 0.0, 1.0, 8.0, 9.0, 8.0, 9.0]);
    }

    #[test]
    fn masked_max_ignores_masked_entries_and_empties_to_zero() {
        #[allow(deprecated)]
        let device = Device::ndarray();
        let messages = Tensor::<4>::from_data(
            TensorData::new(vec![1.0f32, -5.0, 7.0, 3.0, -2.0, -4.0], [1, 2, 3, 1]),
            &device,
        );
        let mask = Tensor::<3, Bool>::from_data(
            TensorData::new(vec![true, true, false, false, false, false], [1, 2, 3]),
            &device,
        );
        assert_eq!(vec_of(masked_max(messages, mask)), vec![1.0, 0.0]);
    }
}
