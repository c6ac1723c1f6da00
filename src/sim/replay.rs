//! Log replay in closed loop: the inverse model's controls drive every controlled agent from
//! its kinematically consistent initial state through the simulator, and the result is
//! compared with the log. It checks the dynamics, the inverse model and the infraction
//! checks together on real data (human drivers neither collide nor leave the road).

use burn::prelude::*;
use burn::tensor::TensorData;

use super::dynamics::Dynamics;
use super::infractions::MapCaches;
use super::inverse::inverse_actions;
use super::limits::ActionLimits;
use super::rollout::{Observation, Rollout, RolloutConfig, rollout_from};
use super::state::{Controls, VehicleState, wheelbase_of};
use crate::error::Result;
use crate::scene::{AgentRole, Scene, SceneBatch};

#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ReplayReport {
    pub scenes: usize,
    /// Controlled agent-steps compared with the log.
    pub agent_steps: usize,
    pub mean_position_error_m: f64,
    pub max_position_error_m: f64,
    /// Controlled agents flagged for a collision / off-road at some step.
    pub collisions: usize,
    pub offroad: usize,
}

/// Replays `scenes` (one batch) on `device` and measures the position error against the log
/// where the inverse model had a full step.
pub fn replay_logs(
    scenes: &[&Scene],
    dynamics: &Dynamics,
    device: &Device,
) -> Result<(ReplayReport, Rollout)> {
    let batch = SceneBatch::from_scenes(scenes, device)?;
    let [b, n, t_total, _] = batch.agent_states.dims();
    let h = batch.history_steps;
    let mut init = vec![[0f32; 4]; b * n];
    let mut commands = vec![0f32; b * n * t_total * 2];
    let mut exact = vec![false; b * n];
    for (bi, scene) in scenes.iter().enumerate() {
        for (ai, agent) in scene.agents.iter().enumerate() {
            if agent.role != AgentRole::Controlled {
                continue;
            }
            let inv = inverse_actions(
                agent,
                scene.dt,
                &dynamics.limits.unwrap_or_else(ActionLimits::unbounded),
            );
            let slot = bi * n + ai;
            init[slot] = match inv.states[h] {
                Some(k) => {
                    exact[slot] = true;
                    [k.x as f32, k.y as f32, k.heading as f32, k.speed as f32]
                }
                // No logged next step to be consistent with: start from the log itself.
                None => {
                    let s = agent.states[h];
                    let half = 0.5 * wheelbase_of(agent.length);
                    [
                        (s.x - half * s.heading.cos()) as f32,
                        (s.y - half * s.heading.sin()) as f32,
                        s.heading as f32,
                        s.speed as f32,
                    ]
                }
            };
            for t in 0..t_total {
                commands[(slot * t_total + t) * 2] = inv.raw_accel[t] as f32;
                commands[(slot * t_total + t) * 2 + 1] = inv.raw_steer[t] as f32;
            }
        }
    }
    let commands = Tensor::<4>::from_data(TensorData::new(commands, [b, n, t_total, 2]), device);
    let channel = |c: usize| {
        let v: Vec<f32> = init.iter().map(|s| s[c]).collect();
        Tensor::<2>::from_data(TensorData::new(v, [b, n]), device)
    };
    let initial = VehicleState {
        x: channel(0),
        y: channel(1),
        heading: channel(2),
        speed: channel(3),
        aux: Vec::new(),
    };
    let mut replay = |obs: &Observation| {
        let step = (h + obs.step).min(t_total - 1);
        Controls::from_stacked(commands.clone().narrow(2, step, 1).reshape([b, n, 2]))
    };
    let out = rollout_from(
        scenes,
        &batch,
        dynamics,
        &mut replay,
        &mut MapCaches::default(),
        &RolloutConfig::default(),
        Some(initial),
    )?;

    let poses: Vec<f64> = out
        .poses
        .to_data()
        .convert::<f64>()
        .try_into_vec()
        .unwrap_or_default();
    let flags = |t: &Tensor<3, burn::tensor::Bool>| {
        t.to_data().try_into_vec_as::<bool>().unwrap_or_default()
    };
    let (collision, offroad) = (flags(&out.collision), flags(&out.offroad));
    let steps = out.steps;
    let mut report = ReplayReport {
        scenes: scenes.len(),
        ..Default::default()
    };
    let mut sum = 0.0;
    for (bi, scene) in scenes.iter().enumerate() {
        for (ai, agent) in scene.agents.iter().enumerate() {
            let slot = bi * n + ai;
            if agent.role != AgentRole::Controlled {
                continue;
            }
            report.collisions += usize::from(
                collision[slot * steps..(slot + 1) * steps]
                    .iter()
                    .any(|&c| c),
            );
            report.offroad +=
                usize::from(offroad[slot * steps..(slot + 1) * steps].iter().any(|&c| c));
            if !exact[slot] {
                continue;
            }
            for k in 1..=steps {
                let t = h + k;
                // The inverse model defines the state at t from the log at t and t + 1.
                if t + 1 >= t_total || !(agent.valid[t] && agent.valid[t + 1]) {
                    break;
                }
                let o = (slot * (steps + 1) + k) * 4;
                let e = (poses[o] - agent.states[t].x).hypot(poses[o + 1] - agent.states[t].y);
                sum += e;
                report.agent_steps += 1;
                report.max_position_error_m = report.max_position_error_m.max(e);
            }
        }
    }
    report.mean_position_error_m = sum / report.agent_steps.max(1) as f64;
    Ok((report, out))
}
