//! Start-state perturbation for closed-loop imitation (`[imitation.perturbation]`).
//!
//! Before an imitation rollout, each controlled agent's logged history is turned about its
//! current position by a small random angle and moved sideways by a small random distance; its
//! logged future stays the target. The imitation loss then asks the policy to steer back onto
//! the path the driver took, from a state the logs never show. Closed-loop IL only meets the
//! deviations its own policy makes within a 6 s window; on the A9's short stretch that taught
//! no lane centring: a lone car started on the lane centre with a straight history drifted
//! 1-2 m within 6 s, on the A9 and on generated roads alike. Perturbing the start state is how
//! ChauffeurNet (Bansal et al., 2018) taught its imitation policy to recover; whether it does
//! here is measured in `experiments/recipe/results.md`.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::scene::{AgentRole, Scene};
use crate::seeding::seeded_per_scene;

/// Largest perturbation each control may draw, uniformly in +-.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartPerturbation {
    /// Sideways displacement (m), perpendicular to the perturbed current heading.
    pub lateral_m: f64,
    /// Heading change (rad): the history is turned about the current position.
    pub heading_rad: f64,
}

/// Seed streams above the trainer's own (0, 1, 2 + minibatch).
const PERTURBATION_STREAM: u64 = 1 << 32;

impl StartPerturbation {
    /// Copies of `scenes` with every controlled agent's history perturbed; `slots` (each
    /// scene's position in its draw) and `iteration` seed the draws, so a resumed run draws
    /// the same perturbations.
    pub fn apply(
        &self,
        scenes: &[&Scene],
        slots: &[usize],
        seed: u64,
        iteration: usize,
    ) -> Vec<Scene> {
        seeded_per_scene(
            scenes,
            slots,
            seed,
            iteration,
            PERTURBATION_STREAM,
            |scene, rng| self.perturb_scene(scene, rng),
        )
    }

    fn perturb_scene(&self, scene: &Scene, rng: &mut impl Rng) -> Scene {
        let mut out = scene.clone();
        let now = scene.current_step();
        for agent in out.agents.iter_mut() {
            if agent.role != AgentRole::Controlled || !agent.valid[now] {
                continue;
            }
            let turn = self.heading_rad * rng.random_range(-1.0..=1.0);
            let shift = self.lateral_m * rng.random_range(-1.0..=1.0);
            let pivot = agent.states[now];
            let (sin, cos) = turn.sin_cos();
            let heading = pivot.heading + turn;
            let offset = [-heading.sin() * shift, heading.cos() * shift];
            for k in 0..=now {
                if !agent.valid[k] {
                    continue;
                }
                let s = &mut agent.states[k];
                let (dx, dy) = (s.x - pivot.x, s.y - pivot.y);
                s.x = pivot.x + cos * dx - sin * dy + offset[0];
                s.y = pivot.y + sin * dx + cos * dy + offset[1];
                s.heading += turn;
            }
        }
        out
    }

    /// Why the config is refused, if it is.
    pub fn check(&self) -> Option<String> {
        if !(self.lateral_m.is_finite() && (0.0..=2.0).contains(&self.lateral_m)) {
            return Some(format!(
                "lateral_m = {}: expected 0 to 2 m (a lane is about 3.75 m wide)",
                self.lateral_m
            ));
        }
        if !(self.heading_rad.is_finite() && (0.0..=0.2).contains(&self.heading_rad)) {
            return Some(format!(
                "heading_rad = {}: expected 0 to 0.2 rad",
                self.heading_rad
            ));
        }
        None
    }
}
