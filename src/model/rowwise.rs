//! A `Linear` layer over the last axis of a tensor of any rank, as one 2D matmul.
//!
//! Why not `Linear::forward` directly: on burn-ndarray a rank > 2 input becomes a batched
//! matmul that slices out and multiplies every leading index separately (thousands of tiny
//! products for `[B, R, K, P]` edge features); folding the leading axes into rows first made
//! the whole network several times faster (measured with `rtr bench model`).

use burn::nn::Linear;
use burn::prelude::*;

pub fn rowwise<const D: usize>(layer: &Linear, x: Tensor<D>) -> Tensor<D> {
    let dims = x.dims();
    let rows: usize = dims[..D - 1].iter().product();
    let y = layer.forward(x.reshape([rows, dims[D - 1]]));
    let mut out = dims;
    out[D - 1] = y.dims()[1];
    y.reshape(out)
}
