//! The last hidden state of burn's `Gru` over a whole sequence, computed with its own weights
//! in fewer, larger operations.
//!
//! Why not `Gru::forward`: per time step it runs six matmuls and six bias additions (one per
//! gate and input), and writes every step's state into a `[batch, time, hidden]` tensor with
//! `slice_assign`, which under autodiff copies that whole tensor per step forward and backward.
//! The history encoder needs only the last state. Here the three gates' input products of all
//! steps are one matmul, each step's hidden products one more (none at the first step, whose
//! state is zero), and only the last state is kept: the same function of the same parameters
//! (burn's GRU with `reset_after`, sigmoid gates and tanh candidate, no clip, as
//! `GruConfig::new(.., .., true)` builds it), so trained checkpoints load and act as before.

use burn::nn::Linear;
use burn::nn::gru::Gru;
use burn::prelude::*;
use burn::tensor::activation::{sigmoid, tanh};

/// `x` `[batch, time, input]` -> the state after the last step, `[batch, hidden]`, from a zero
/// initial state.
pub fn gru_last_state(gru: &Gru, x: Tensor<3>) -> Tensor<2> {
    debug_assert!(
        gru.reset_after && gru.clip.is_none(),
        "GruConfig's defaults"
    );
    let [batch, time, input] = x.dims();
    let c = gru.d_hidden;
    let gates = [&gru.update_gate, &gru.reset_gate, &gru.new_gate];
    let input_products = stacked_product(
        gates.map(|g| &g.input_transform),
        x.reshape([batch * time, input]),
    )
    .reshape([batch, time, 3 * c]);
    let hidden_weights = stacked_weights(gates.map(|g| &g.hidden_transform));
    let hidden_biases = stacked_biases(gates.map(|g| &g.hidden_transform));

    let mut state: Option<Tensor<2>> = None;
    for t in 0..time {
        let from_input = input_products
            .clone()
            .narrow(1, t, 1)
            .reshape([batch, 3 * c]);
        // `[batch, 3 hidden]`, or `[1, 3 hidden]` (broadcast) while the state is zero.
        let from_state = match &state {
            Some(h) => h.clone().matmul(hidden_weights.clone()) + hidden_biases.clone(),
            None => hidden_biases.clone(),
        };
        let gate = |k: usize, products: &Tensor<2>| products.clone().narrow(1, k * c, c);
        let update = sigmoid(gate(0, &from_input) + gate(0, &from_state));
        let reset = sigmoid(gate(1, &from_input) + gate(1, &from_state));
        let candidate = tanh(gate(2, &from_input) + reset * gate(2, &from_state));
        // h' = (1 - z) n + z h, with h = 0 before the first step.
        let keep = update.clone().neg().add_scalar(1.0);
        state = Some(match state {
            Some(h) => candidate * keep + update * h,
            None => candidate * keep,
        });
    }
    state.unwrap_or_else(|| Tensor::zeros([batch, c], &input_products.device()))
}

/// `x W + b` for the three gates at once: `[rows, 3 hidden]`, gates side by side.
fn stacked_product(layers: [&Linear; 3], x: Tensor<2>) -> Tensor<2> {
    x.matmul(stacked_weights(layers)) + stacked_biases(layers)
}

/// The layers' weights side by side, `[inputs, 3 hidden]`.
fn stacked_weights(layers: [&Linear; 3]) -> Tensor<2> {
    Tensor::cat(layers.map(|l| l.weight.val()).to_vec(), 1)
}

/// The layers' biases side by side (zero where a layer has none), `[1, 3 hidden]` to broadcast
/// over rows.
fn stacked_biases(layers: [&Linear; 3]) -> Tensor<2> {
    let bias = |l: &Linear| match &l.bias {
        Some(b) => b.val(),
        None => Tensor::zeros([l.weight.dims()[1]], &l.weight.device()),
    };
    let biases = Tensor::cat(layers.map(bias).to_vec(), 0);
    biases.unsqueeze()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::gru::GruConfig;
    use burn::tensor::{Distribution, Tolerance};

    /// Same state and same parameter gradients as burn's `Gru::forward`'s last step.
    #[test]
    fn matches_burns_gru_forward_and_backward() {
        let device = crate::backend::Backend::reference_device(true);
        let gru = GruConfig::new(5, 6, true).init(&device);
        let x = Tensor::<3>::random([7, 4, 5], Distribution::Normal(0.0, 1.0), &device);
        let ours = gru_last_state(&gru, x.clone());
        let theirs = gru.forward(x, None).narrow(1, 3, 1).reshape([7, 6]);
        ours.clone()
            .into_data()
            .assert_approx_eq::<f32>(&theirs.clone().into_data(), Tolerance::absolute(1e-5));

        // A weighted sum so that every state entry's gradient differs.
        let weights = Tensor::<2>::random([7, 6], Distribution::Normal(0.0, 1.0), &device);
        let ours = (ours * weights.clone()).sum().backward();
        let theirs = (theirs * weights).sum().backward();
        let params = [
            &gru.update_gate.input_transform,
            &gru.update_gate.hidden_transform,
            &gru.reset_gate.input_transform,
            &gru.reset_gate.hidden_transform,
            &gru.new_gate.input_transform,
            &gru.new_gate.hidden_transform,
        ];
        for layer in params {
            let grad = |grads: &_| layer.weight.val().grad(grads).expect("weight gradient");
            grad(&ours)
                .into_data()
                .assert_approx_eq::<f32>(&grad(&theirs).into_data(), Tolerance::absolute(1e-5));
            let bias = layer.bias.as_ref().expect("bias").val();
            bias.grad(&ours)
                .expect("bias gradient")
                .into_data()
                .assert_approx_eq::<f32>(
                    &bias.grad(&theirs).expect("bias gradient").into_data(),
                    Tolerance::absolute(1e-5),
                );
        }
    }
}
