//! One scene as a policy drives it, to watch (`rtr render --animate`): evaluation's own rollout
//! (mean actions, every agent kept to the end, heroes on their scripts) put into the scene's
//! future, with each policy-driven agent's first collision and first off-road step.

use burn::prelude::Tensor;
use burn::tensor::Bool;

use super::evaluate::simulated_rollout;
use super::policy::EvalPolicy;
use super::sets::EvalScenes;
use crate::error::{Error, Result};
use crate::render::{Infraction, InfractionKind};
use crate::scene::Scene;
use crate::sim::Dynamics;

/// A scene with its simulated future, and the infractions in it.
#[derive(Debug, Clone)]
pub struct WatchedRollout {
    pub scene: Scene,
    /// Ordered by step, then agent.
    pub infractions: Vec<Infraction>,
}

/// Scene `index` of `set` driven by `policy` in `dynamics`, as evaluation rolls it out.
pub fn watch_rollout(
    policy: &dyn EvalPolicy,
    dynamics: &Dynamics,
    set: &EvalScenes,
    index: usize,
    device: &burn::prelude::Device,
) -> Result<WatchedRollout> {
    if index >= set.scenes.len() {
        return Err(Error::InvalidArgument(format!(
            "scene {index} is past the set's {} scenes",
            set.scenes.len()
        )));
    }
    let (scenes, out) = simulated_rollout(policy, dynamics, set, &[index], device)?;
    let scene = scenes.into_iter().next().ok_or_else(|| {
        Error::InvalidArgument(format!("scene {index}: the rollout returned no scene"))
    })?;
    let infractions = first_infractions(&out.collision, &out.offroad, scene.current_step());
    Ok(WatchedRollout { scene, infractions })
}

/// Per agent of the first scene of `[B, N, T]` flags (transition into rollout step t + 1), its
/// first collision and its first off-road step, as window steps (`now` + rollout step).
fn first_infractions(
    collision: &Tensor<3, Bool>,
    offroad: &Tensor<3, Bool>,
    now: usize,
) -> Vec<Infraction> {
    let [_, n, t] = collision.dims();
    let mut found = Vec::new();
    for (kind, flags) in [
        (InfractionKind::Collision, collision),
        (InfractionKind::Offroad, offroad),
    ] {
        let flags: Vec<bool> = flags
            .to_data()
            .try_into_vec_as::<bool>()
            .unwrap_or_default();
        for agent in 0..n {
            if let Some(k) = (0..t).find(|&k| flags.get(agent * t + k) == Some(&true)) {
                found.push(Infraction {
                    agent,
                    step: now + k + 1,
                    kind,
                });
            }
        }
    }
    found.sort_by_key(|f| (f.step, f.agent));
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    #[test]
    fn first_flags_become_window_steps() {
        let device = crate::backend::Backend::NdArray.device(false).unwrap();
        let flags =
            |v: Vec<bool>| Tensor::<3, Bool>::from_data(TensorData::new(v, [1, 2, 3]), &device);
        // Agent 0 collides in the transitions into steps 2 and 3; agent 1 leaves the road in
        // the first one.
        let collision = flags(vec![false, true, true, false, false, false]);
        let offroad = flags(vec![false, false, false, true, false, true]);
        let found = first_infractions(&collision, &offroad, 4);
        let expected = [
            (1, 5, InfractionKind::Offroad),
            (0, 6, InfractionKind::Collision),
        ];
        assert_eq!(found.len(), expected.len());
        for (f, (agent, step, kind)) in found.iter().zip(expected) {
            assert_eq!((f.agent, f.step, f.kind), (agent, step, kind));
        }
    }
}
