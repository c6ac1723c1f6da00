//! Graph plumbing on padded, batched tensors: gathering neighbour rows through fixed-width
//! index tables, and max aggregation over masked neighbours.
//!
//! Max aggregation is a dense masked max over the neighbour axis, not burn's scatter with
//! `IndexingUpdateOp::Max`: the scatter's gradient is wrong when several edges reach the same
//! node (every loser gets gradient too, see `shared/notes/burn-0.22.md`). Which dense max is
//! fastest depends on the backend and the neighbour count (forward + backward, measured on
//! `[16, R, K, 128]` messages, see `max_by_tree`). On burn-flex, the default, a fused kernel with
//! its own backward (`fused_max`, f32) beats every composition of burn ops. burn-ndarray's
//! `max_dim` loses badly on the narrow lane-graph neighbour lists (K <= 8) and wins on the dense
//! agent-agent ones (K = 32), so there a tree of elementwise `max_pair`s is used below
//! [`NDARRAY_TREE_BELOW`] neighbours. All route the gradient to the single winner, as
//! `tests/gradients.rs` (NdArray) and `tests/backends.rs` (Flex) check.

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

/// Neighbour counts below which burn-ndarray takes the max as a tree of `max_pair`s.
const NDARRAY_TREE_BELOW: usize = 16;

/// Max over the neighbour axis (dim 2) of `messages` (`[B, R, K, C]`) where `mask`
/// (`[B, R, K]`) is true; rows with no neighbour get 0.
pub fn masked_max(messages: Tensor<4>, mask: Tensor<3, Bool>) -> Tensor<3> {
    #[cfg(feature = "flex")]
    if on_flex(&messages.device()) && messages.dtype() == burn::tensor::DType::F32 {
        return super::fused_max::masked_max(messages, mask);
    }
    let [b, r, k, c] = messages.dims();
    let any = mask.clone().any_dim(2).reshape([b, r, 1]);
    let filled = messages.mask_fill(mask.bool_not().unsqueeze_dim::<4>(3), MASKED);
    let max = if k < NDARRAY_TREE_BELOW && on_ndarray(&filled.device()) {
        max_by_tree(filled)
    } else {
        filled.max_dim(2)
    };
    max.reshape([b, r, c]).mask_fill(any.bool_not(), 0.0)
}

/// Whether `device` (autodiff or not) runs on burn-ndarray.
fn on_ndarray(device: &Device) -> bool {
    let ndarray = crate::backend::Backend::reference_device(false);
    device.clone().inner() == ndarray
}

/// Whether `device` (autodiff or not) runs on burn-flex.
#[cfg(feature = "flex")]
fn on_flex(device: &Device) -> bool {
    device.clone().inner() == Device::flex()
}

/// Max over dim 2 as a tree of elementwise maxima: `[B, R, K, C]` -> `[B, R, 1, C]`.
///
/// Forward + backward at C = 128, `[B, R, K]` = `[16, 162, 4]` / `[16, 32, 8]` /
/// `[16, 32, 32]`, in ms (one quiet run on the 2-core VM): burn-ndarray tree 11.2 / 3.4 / 39.0
/// against `max_dim` 48.3 / 10.7 / 22.8; burn-flex tree 10.3 / 3.7 / 14.7 against `max_dim`
/// 9.9 / 2.4 / 14.7.
fn max_by_tree(mut x: Tensor<4>) -> Tensor<4> {
    let mut k = x.dims()[2];
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
    x
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
        let device = crate::backend::Backend::reference_device(false);
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
        let device = crate::backend::Backend::reference_device(false);
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
