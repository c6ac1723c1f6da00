//! Agent dropout for closed-loop imitation (`[imitation] agent_dropout`; not in the paper).
//!
//! Before an imitation rollout, each agent of the scene is removed with the configured
//! probability, whatever its role; if no controlled agent is left, one drawn at random stays.
//! The logged futures of the agents that remain are still the targets.
//!
//! Why: the imitation-trained policies steer by the traffic around them, not by the lane. Re-
//! simulating the A9 test agents with every other vehicle removed, they end 3.2 m from their
//! logs after 6 s against 1.5 m in their logged traffic, and a lone car started on a lane
//! centre is in another lane within 6 s in a third to half of the cases
//! (`examples/lane_keeping.rs`, `experiments/recipe/results.md`). On the A9 every agent has
//! recorded drivers around it who keep their lanes, so following them is the cheapest fit of
//! the logs; on generated roads the agents around are the policy's own, drifting together.
//! Removing neighbours leaves the lane graph as the cue that still predicts the logged path.
//! Dropping inputs so that a network cannot lean on one cue is common practice (dropout; "agent
//! dropout" in multi-agent prediction); its effect on lane keeping is measured in
//! `experiments/recipe/agent_dropout/`.

use rand::Rng;

use crate::scene::{AgentRole, Scene};
use crate::seeding::seeded_per_scene;

/// Seed streams above the trainer's own (0, 1, 2 + minibatch) and start perturbation's
/// (`1 << 32` + slot).
const AGENT_DROPOUT_STREAM: u64 = 2 << 32;

/// Copies of `scenes` with agents removed at `probability` each; `slots` (each scene's position
/// in its draw) and `iteration` seed the draws, so a resumed run drops the same agents.
pub fn drop_agents(
    scenes: &[&Scene],
    slots: &[usize],
    probability: f64,
    seed: u64,
    iteration: usize,
) -> Vec<Scene> {
    seeded_per_scene(
        scenes,
        slots,
        seed,
        iteration,
        AGENT_DROPOUT_STREAM,
        |scene, rng| drop_from_scene(scene, probability, rng),
    )
}

fn drop_from_scene(scene: &Scene, probability: f64, rng: &mut impl Rng) -> Scene {
    let mut keep: Vec<bool> = scene
        .agents
        .iter()
        .map(|_| !rng.random_bool(probability))
        .collect();
    let controlled: Vec<usize> = (0..scene.agents.len())
        .filter(|&i| scene.agents[i].role == AgentRole::Controlled)
        .collect();
    if !controlled.is_empty() && !controlled.iter().any(|&i| keep[i]) {
        keep[controlled[rng.random_range(0..controlled.len())]] = true;
    }
    let mut out = scene.clone();
    let mut kept = keep.into_iter();
    out.agents.retain(|_| kept.next().unwrap_or(true));
    out
}

/// Why `probability` is refused, if it is.
pub fn check(probability: f64) -> Option<String> {
    (!(probability.is_finite() && (0.0..1.0).contains(&probability))).then(|| {
        format!(
            "agent_dropout = {probability}: expected a probability in [0, 1) \
             (1 would remove every agent but one)"
        )
    })
}
