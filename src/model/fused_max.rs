//! Masked max over the neighbour axis as one burn-flex kernel with its own backward pass.
//!
//! Composed from burn ops, a masked max costs five passes over the `[B, R, K, C]` messages
//! forward and backward: the mask fill and its gradient, `max_dim_with_indices` (a strided scalar
//! walk per output element), and a zeros tensor plus an index scatter for the gradient. On Flex,
//! the default CPU backend, that was about a quarter of the policy's forward + backward. No crate
//! fuses it, so this does by hand: forward is one vectorisable pass that keeps each channel's
//! winning neighbour (`[B, R, C]` as i32), backward writes the output gradient straight to the
//! winners. It routes gradient exactly as the composed op does (to the single winner, nothing to
//! the empty rows that output 0); `tests/backends.rs` checks outputs and gradients against
//! NdArray's composed path, which `tests/gradients.rs` checks against finite differences.

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind, unary};
use burn::backend::flex::{FlexTensor, Layout};
use burn::backend::tensor::{BoolTensor, FloatTensor};
use burn::backend::{Autodiff, Backend, Flex, TensorMetadata, backend_extension};
use burn::prelude::*;
use burn::tensor::{Bool, Bytes, DType, Shape};
use rayon::prelude::*;

/// Rows (receivers) per rayon task: one row is only `K x C` floats.
const ROWS_PER_TASK: usize = 32;

/// The extension burn's dispatch routes to the backend a tensor lives on.
#[backend_extension(Flex, Autodiff)]
pub trait FusedMaskedMax: Backend {
    /// `messages` `[B, R, K, C]` (f32), `mask` `[B, R, K]` -> `[B, R, C]`: the max over the
    /// masked-in neighbours, 0 where a receiver has none.
    fn fused_masked_max(messages: FloatTensor<Self>, mask: BoolTensor<Self>) -> FloatTensor<Self>;
}

/// [`FusedMaskedMax`] on a `Tensor`: the caller checks the device is Flex and the dtype f32.
pub fn masked_max(messages: Tensor<4>, mask: Tensor<3, Bool>) -> Tensor<3> {
    let out = <burn::backend::Dispatch as FusedMaskedMax>::fused_masked_max(
        messages.into_dispatch(),
        mask.into_dispatch(),
    );
    Tensor::from_dispatch(out)
}

impl FusedMaskedMax for Flex {
    fn fused_masked_max(messages: FlexTensor, mask: FlexTensor) -> FlexTensor {
        forward(&messages, &mask).0
    }
}

impl<C: CheckpointStrategy> FusedMaskedMax for Autodiff<Flex, C> {
    fn fused_masked_max(messages: FloatTensor<Self>, mask: FlexTensor) -> FloatTensor<Self> {
        let neighbours = messages.shape()[2];
        let guard = messages.node();
        let (values, winners) = forward(&messages.into_primitive(), &mask);
        match ToWinners.prepare::<C>([guard]).compute_bound().stateful() {
            OpsKind::Tracked(prep) => prep.finish((winners, neighbours), values),
            OpsKind::UnTracked(prep) => prep.finish(values),
        }
    }
}

/// Backward of the fused max: the output gradient goes to each channel's winning neighbour.
#[derive(Debug)]
struct ToWinners;

impl Backward<Flex, 1> for ToWinners {
    /// The winners (`[B, R, C]`, i32, -1 for empty rows) and the neighbour count K.
    type State = (FlexTensor, usize);

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let (winners, neighbours) = ops.state;
        unary::<Flex, _>(ops.parents, ops.node, grads, |grad| {
            backward(&grad, &winners, neighbours)
        });
    }
}

/// A contiguous tensor's elements, from its start offset.
fn elements<E: burn::tensor::Element + bytemuck::Pod>(tensor: &FlexTensor) -> &[E] {
    let start = tensor.layout().start_offset();
    &tensor.storage::<E>()[start..start + tensor.layout().num_elements()]
}

/// Values (`[B, R, C]`, f32) and winners (`[B, R, C]`, i32, -1 where no neighbour is in).
fn forward(messages: &FlexTensor, mask: &FlexTensor) -> (FlexTensor, FlexTensor) {
    let [b, r, k, c] = dims4(messages);
    let messages = messages.to_contiguous();
    let mask = mask.to_contiguous();
    let x: &[f32] = elements(&messages);
    let m: &[u8] = elements(&mask);
    let mut values = vec![0f32; b * r * c];
    let mut winners = vec![-1i32; b * r * c];
    values
        .par_chunks_mut(c)
        .zip(winners.par_chunks_mut(c))
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each(|(row, (value, winner))| {
            let messages = &x[row * k * c..(row + 1) * k * c];
            max_of_row(messages, &m[row * k..(row + 1) * k], value, winner);
        });
    let shape = [b, r, c];
    (
        flex_tensor(values, &shape, DType::F32),
        flex_tensor(winners, &shape, DType::I32),
    )
}

/// One receiver: the elementwise max over its masked-in neighbours' messages (rows of
/// `value.len()` channels), and which neighbour won each channel. A NaN wins and stays, as in
/// burn's `max_dim`. Rows with no neighbour keep the zeros and -1s they came with.
fn max_of_row(messages: &[f32], mask: &[u8], value: &mut [f32], winner: &mut [i32]) {
    let mut first = true;
    for (j, message) in messages.chunks_exact(value.len()).enumerate() {
        if mask[j] == 0 {
            continue;
        }
        let j = j as i32;
        if first {
            value.copy_from_slice(message);
            winner.fill(j);
            first = false;
            continue;
        }
        for ((v, w), &x) in value.iter_mut().zip(winner.iter_mut()).zip(message) {
            if x > *v || x.is_nan() {
                *v = x;
                *w = j;
            }
        }
    }
}

/// Gradient of the messages `[B, R, K, C]`: `grad` (`[B, R, C]`) at each winner, 0 elsewhere.
fn backward(grad: &FlexTensor, winners: &FlexTensor, neighbours: usize) -> FlexTensor {
    let [b, r, c] = grad.layout().shape().dims::<3>();
    let grad = grad.to_contiguous();
    let g: &[f32] = elements(&grad);
    let w: &[i32] = elements(winners);
    let row_len = neighbours * c;
    let mut out = vec![0f32; b * r * row_len];
    out.par_chunks_mut(row_len)
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each(|(row, out)| {
            let span = row * c..(row + 1) * c;
            for (channel, (&winner, &g)) in w[span.clone()].iter().zip(&g[span]).enumerate() {
                if winner >= 0 {
                    out[winner as usize * c + channel] = g;
                }
            }
        });
    flex_tensor(out, &[b, r, neighbours, c], DType::F32)
}

fn dims4(tensor: &FlexTensor) -> [usize; 4] {
    tensor.layout().shape().dims::<4>()
}

fn flex_tensor<E: burn::tensor::Element>(
    data: Vec<E>,
    shape: &[usize],
    dtype: DType,
) -> FlexTensor {
    FlexTensor::new(
        Bytes::from_elems(data),
        Layout::contiguous(Shape::from(shape.to_vec())),
        dtype,
    )
}
