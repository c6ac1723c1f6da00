//! History encoder (paper appendix): a 1D residual CNN over each agent's past frames captures
//! local temporal patterns, a GRU aggregates them into one feature h_a per agent.

use burn::module::Module;
use burn::nn::{Gru, GruConfig, Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;

use super::gru_last_state::gru_last_state;
use super::rowwise::rowwise;

/// A 1D convolution over time with "same" zero padding, `[batch, time, channels]` in and out,
/// written as one matmul over the stacked shifted sequences (im2col).
///
/// Why not `burn::nn::conv::Conv1d`: its backward on burn-ndarray goes through a naive
/// `conv_transpose2d` that took ~75% of the networks' forward + backward time at the paper's
/// size (B = 32 x N = 32 agents, H = 5, 128 channels); as a matmul the same convolution is a
/// negligible share.
#[derive(Module, Debug)]
struct TemporalConv {
    weights: Linear,
    #[module(skip)]
    kernel: usize,
}

impl TemporalConv {
    fn new(input: usize, output: usize, kernel: usize, device: &Device) -> Self {
        Self {
            weights: LinearConfig::new(kernel * input, output).init(device),
            kernel,
        }
    }

    fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let [b, t, c] = x.dims();
        let pad = self.kernel / 2;
        let zeros = Tensor::<3>::zeros([b, pad, c], &x.device());
        let padded = Tensor::cat(vec![zeros.clone(), x, zeros], 1);
        let taps: Vec<Tensor<3>> = (0..self.kernel)
            .map(|k| padded.clone().narrow(1, k, t))
            .collect();
        rowwise(&self.weights, Tensor::cat(taps, 2))
    }
}

/// conv -> relu -> conv, added to its input, then relu.
#[derive(Module, Debug)]
struct ResidualBlock {
    first: TemporalConv,
    second: TemporalConv,
}

impl ResidualBlock {
    fn new(channels: usize, kernel: usize, device: &Device) -> Self {
        Self {
            first: TemporalConv::new(channels, channels, kernel, device),
            second: TemporalConv::new(channels, channels, kernel, device),
        }
    }

    /// `[batch, time, channels]` -> same.
    fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let y = self.second.forward(relu(self.first.forward(x.clone())));
        relu(x + y)
    }
}

#[derive(Module, Debug)]
pub struct HistoryEncoder {
    stem: TemporalConv,
    blocks: Vec<ResidualBlock>,
    gru: Gru,
}

impl HistoryEncoder {
    pub fn new(input: usize, hidden: usize, blocks: usize, kernel: usize, device: &Device) -> Self {
        Self {
            stem: TemporalConv::new(input, hidden, kernel, device),
            blocks: (0..blocks)
                .map(|_| ResidualBlock::new(hidden, kernel, device))
                .collect(),
            gru: GruConfig::new(hidden, hidden, true).init(device),
        }
    }

    /// `[B, N, H, F]` -> `[B, N, hidden]`: the GRU state after the current (last) frame.
    pub fn forward(&self, history: Tensor<4>) -> Tensor<3> {
        let [b, n, h, f] = history.dims();
        let mut x = relu(self.stem.forward(history.reshape([b * n, h, f])));
        for block in &self.blocks {
            x = block.forward(x);
        }
        let last = gru_last_state(&self.gru, x);
        let hidden = last.dims()[1];
        last.reshape([b, n, hidden])
    }
}
