//! Not in the paper: a steering feed-forward from the lane each agent drives on, added to the
//! policy's steering mean (`ModelConfig::lane_steer_feedforward`).
//!
//! Why: under the kinematic bicycle model a car follows a lane of curvature k exactly when it
//! steers `atan(L k)` (L its wheelbase); any other steering turns its heading away from the
//! lane at `v (tan(phi) / L - k)`. A policy that outputs the whole steering angle must learn
//! that angle from the lane graph, and the recorded roads show it two curvatures (the A9's
//! carriageways, +-0.0003 1/m): the converged IL policies learned to steer like the A9 and
//! left the generated roads (0.0007-0.0028 1/m) in a third to a half of the long-tail agents
//! (`experiments/recipe/agent_dropout/`, `road_bend/`). With the feed-forward the network
//! outputs the correction to it (lateral and heading error to the lane, lane changes), which
//! is the same on a road of any curvature: the residual-policy idea (Silver et al. 2018) with
//! the bicycle model's own steady-state steering as the base controller.
//!
//! The lane is the one at the middle of the coming control step: the lane node closest (by
//! centre distance) to the point [`PREVIEW_TIME_S`] ahead of the agent at its speed, among the
//! nodes whose heading is within [`MAX_HEADING_GAP_RAD`] of the agent's, so the opposite
//! carriageway and crossing ramps are never taken; with no such node the feed-forward is 0.
//! Choosing the node is discrete and the curvature is a map constant, so the feed-forward
//! carries no gradient: the policy's distribution keeps its parameters' gradients exactly,
//! only its mean is shifted.

use burn::prelude::*;
use burn::tensor::Bool;

use crate::sim::WHEELBASE_RATIO;

/// How far ahead (s at the agent's speed) the lane is looked up: half the paper's control step
/// of 0.5 s, so a lane whose curvature changes (a clothoid into a bend) is followed with the
/// curvature the car meets over the step rather than the one it leaves (measured on a
/// generated bend: without it cars entering the clothoid end 2 m off their lane centre in 5 s).
pub const PREVIEW_TIME_S: f64 = 0.25;

/// Largest heading difference (rad) between an agent and a lane node it may follow.
pub const MAX_HEADING_GAP_RAD: f64 = std::f64::consts::FRAC_PI_4;

/// Cost of a node that may not be followed (padding, wrong direction).
const EXCLUDED: f64 = 1e9;

/// `[B, N]` feed-forward steering (rad) of agents at `agent_pose` (`[B, N, 4]`: centre x,
/// y, heading, speed) with box `length` (`[B, N]`, m), on lane nodes at `lane_pose`
/// (`[B, L, 3]`) of curvature `lane_curvature` (`[B, L]`, 1/m, positive to the left);
/// `lane_mask` (`[B, L]`) marks the real nodes. The wheelbase is the simulator's
/// (`WHEELBASE_RATIO` x length, at least 1 m, as in the rollout). Detached.
pub fn lane_steer_feedforward(
    agent_pose: &Tensor<3>,
    length: &Tensor<2>,
    lane_pose: &Tensor<3>,
    lane_curvature: &Tensor<2>,
    lane_mask: &Tensor<2, Bool>,
) -> Tensor<2> {
    let [b, n, _] = agent_pose.dims();
    let l = lane_pose.dims()[1];
    if l == 0 {
        return Tensor::zeros([b, n], &agent_pose.device());
    }
    let agent = agent_pose.clone().detach();
    let heading = agent.clone().narrow(2, 2, 1);
    let preview = agent.clone().narrow(2, 3, 1).mul_scalar(PREVIEW_TIME_S);
    let agent = Tensor::cat(
        vec![
            agent.clone().narrow(2, 0, 1) + preview.clone() * heading.clone().cos(),
            agent.narrow(2, 1, 1) + preview * heading.clone().sin(),
            heading,
        ],
        2,
    );
    let lanes = lane_pose.clone().detach();
    // Channel c of every agent (along dim 2) against every lane node (along dim 1): [B, N, L].
    let agent_channel = |c: usize| agent.clone().narrow(2, c, 1).expand([b, n, l]);
    let lane_channel = |c: usize| {
        lanes
            .clone()
            .narrow(2, c, 1)
            .reshape([b, 1, l])
            .expand([b, n, l])
    };
    let dx = agent_channel(0) - lane_channel(0);
    let dy = agent_channel(1) - lane_channel(1);
    let distance = (dx.powi_scalar(2) + dy.powi_scalar(2)).sqrt();
    let aligned = (agent_channel(2) - lane_channel(2))
        .cos()
        .greater_equal_elem(MAX_HEADING_GAP_RAD.cos());
    let real_node = lane_mask.clone().unsqueeze_dim::<3>(1).expand([b, n, l]);
    let allowed = aligned.bool_and(real_node);
    let cost = distance.mask_fill(allowed.bool_not(), EXCLUDED);
    let nearest = cost.clone().argmin(2);
    let none_allowed = cost.min_dim(2).greater_equal_elem(EXCLUDED).reshape([b, n]);
    let curvature = lane_curvature
        .clone()
        .detach()
        .unsqueeze_dim::<3>(1)
        .expand([b, n, l])
        .gather(2, nearest)
        .reshape([b, n]);
    let wheelbase = length
        .clone()
        .detach()
        .mul_scalar(WHEELBASE_RATIO)
        .clamp_min(1.0);
    (wheelbase * curvature).atan().mask_fill(none_allowed, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tensor2(values: &[f32], shape: [usize; 2]) -> Tensor<2> {
        Tensor::from_data(
            burn::tensor::TensorData::new(values.to_vec(), shape),
            &Default::default(),
        )
    }

    fn tensor3(values: &[f32], shape: [usize; 3]) -> Tensor<3> {
        Tensor::from_data(
            burn::tensor::TensorData::new(values.to_vec(), shape),
            &Default::default(),
        )
    }

    fn values(t: Tensor<2>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .expect("floats")
    }

    /// Two lanes side by side heading east (curving 0.002 and -0.001) with the first one's next
    /// node 20 m on (0.003), one westbound (0.004) beside them, and a padding node of curvature
    /// 0.5 on top of the first agent.
    fn lanes() -> (Tensor<3>, Tensor<2>, Tensor<2, Bool>) {
        let pose = tensor3(
            &[
                0.0,
                0.0,
                0.0, //
                0.0,
                3.5,
                0.0, //
                0.0,
                -3.5,
                std::f32::consts::PI, //
                0.0,
                0.0,
                0.0, //
                20.0,
                0.0,
                0.0,
            ],
            [1, 5, 3],
        );
        let curvature = tensor2(&[0.002, -0.001, 0.004, 0.5, 0.003], [1, 5]);
        let mask = Tensor::<2>::from_data(
            burn::tensor::TensorData::new(vec![1.0f32, 1.0, 1.0, 0.0, 1.0], [1, 5]),
            &Default::default(),
        )
        .greater_elem(0.5);
        (pose, curvature, mask)
    }

    #[test]
    fn steers_the_curvature_of_the_nearest_aligned_lane_ahead() {
        let (lane_pose, curvature, mask) = lanes();
        // At rest: on the first lane; nearer the westbound lane than the second but heading
        // east; on the second lane turned 30 degrees; heading north (no lane within 45
        // degrees). Then 8 m behind the first lane's next node at 32 m/s: the point a quarter
        // second ahead is nearer that node than the one the car is on.
        let agents = tensor3(
            &[
                1.0, 0.2, 0.05, 0.0, //
                0.0, -2.0, 0.0, 0.0, //
                2.0, 3.4, 0.52, 0.0, //
                0.0, 0.0, 1.57, 0.0, //
                8.0, 0.2, 0.0, 32.0,
            ],
            [1, 5, 4],
        );
        let length = tensor2(&[5.0, 5.0, 10.0, 5.0, 5.0], [1, 5]);
        let ff = values(lane_steer_feedforward(
            &agents, &length, &lane_pose, &curvature, &mask,
        ));
        let expected = [
            (3.0f32 * 0.002).atan(),
            (3.0f32 * 0.002).atan(),
            (6.0f32 * -0.001).atan(),
            0.0,
            (3.0f32 * 0.003).atan(),
        ];
        for (got, want) in ff.iter().zip(expected) {
            assert!((got - want).abs() < 1e-7, "{ff:?} against {expected:?}");
        }
    }

    #[test]
    fn no_lane_nodes_give_no_feedforward() {
        let agents = tensor3(&[0.0, 0.0, 0.0, 20.0], [1, 1, 4]);
        let length = tensor2(&[5.0], [1, 1]);
        let none = Tensor::<3>::zeros([1, 0, 3], &Default::default());
        let mask = Tensor::<2>::zeros([1, 0], &Default::default()).greater_elem(0.5);
        let ff = lane_steer_feedforward(
            &agents,
            &length,
            &none,
            &Tensor::zeros([1, 0], &Default::default()),
            &mask,
        );
        assert_eq!(values(ff), vec![0.0]);
    }
}
