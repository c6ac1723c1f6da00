//! From a finished rollout to per-scene tallies ([`SceneTally`]). Everything here is host
//! code over plain arrays: the rollout tensors are read once, then each scene is measured
//! against its log (the [`Scene`]'s states are the logged box-centre poses).

use burn::prelude::*;
use burn::tensor::Bool;

use super::collisions::hit_only_by_log;
use super::features::{Feature, lane_deviation, lead_gap};
use super::histogram::Histogram;
use super::metrics::SceneTally;
use super::reconstruction::{LoggedPath, displacement};
use crate::driver::AgentView;
use crate::error::{Error, Result};
use crate::scene::{AgentRole, Scene};
use crate::sim::Rollout;

/// The rollout's per-step arrays on the host, row-major `[B][N][T + 1]`.
struct HostRollout {
    n: usize,
    steps: usize,
    /// `[.., 4]`: centre x, y, heading, speed.
    poses: Vec<f32>,
    present: Vec<bool>,
    simulated: Vec<bool>,
    /// `[B][N][T]`.
    collision: Vec<bool>,
    offroad: Vec<bool>,
}

/// A tensor's values on the host as `f32`, row-major.
pub(super) fn floats<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default()
}

/// A boolean tensor's values on the host, row-major.
pub(super) fn bools<const D: usize>(t: Tensor<D, Bool>) -> Vec<bool> {
    t.into_data().try_into_vec_as::<bool>().unwrap_or_default()
}

impl HostRollout {
    fn new(out: &Rollout) -> Self {
        let [_, n, t1, _] = out.poses.dims();
        Self {
            n,
            steps: t1 - 1,
            poses: floats(out.poses.clone()),
            present: bools(out.present.clone()),
            simulated: bools(out.simulated.clone()),
            collision: bools(out.collision.clone()),
            offroad: bools(out.offroad.clone()),
        }
    }

    fn at(&self, b: usize, i: usize, t: usize) -> usize {
        (b * self.n + i) * (self.steps + 1) + t
    }

    /// Agent `i` of scene `b` at step `t` as simulated.
    fn view(&self, b: usize, i: usize, t: usize, scene: &Scene) -> AgentView {
        let k = self.at(b, i, t) * 4;
        let p = &self.poses[k..k + 4];
        let agent = &scene.agents[i];
        AgentView {
            x: p[0] as f64,
            y: p[1] as f64,
            heading: p[2] as f64,
            speed: p[3] as f64,
            length: agent.length,
            width: agent.width,
            present: self.present[self.at(b, i, t)],
        }
    }

    /// Every agent of scene `b` at step `t` as simulated.
    fn views(&self, b: usize, t: usize, scene: &Scene) -> Vec<AgentView> {
        (0..self.agents(scene))
            .map(|i| self.view(b, i, t, scene))
            .collect()
    }

    fn agents(&self, scene: &Scene) -> usize {
        scene.agents.len().min(self.n)
    }

    fn any_flag(&self, flags: &[bool], b: usize, i: usize) -> bool {
        let row = (b * self.n + i) * self.steps;
        flags[row..row + self.steps].iter().any(|&f| f)
    }
}

/// Agent `i` of `scene` at `step` as logged (`present` = the log has it then).
pub(crate) fn logged_view(scene: &Scene, i: usize, step: usize) -> AgentView {
    let agent = &scene.agents[i];
    let present = agent.valid.get(step).copied().unwrap_or(false);
    let s = if present {
        agent.states[step]
    } else {
        Default::default()
    };
    AgentView {
        x: s.x,
        y: s.y,
        heading: s.heading,
        speed: s.speed,
        length: agent.length,
        width: agent.width,
        present,
    }
}

/// The features ([`Feature::ALL`] order) of vehicle `i`: `all[i]` its pose now, `before` its
/// pose one step earlier (for the acceleration), `all` everybody now (for the leader).
pub fn features_of(
    scene: &Scene,
    i: usize,
    before: Option<AgentView>,
    all: &[AgentView],
) -> StepFeatures {
    let pose = &all[i];
    Feature::ALL.map(|f| match f {
        Feature::Acceleration => before.map(|b| (pose.speed - b.speed) / scene.dt),
        Feature::Speed => Some(pose.speed),
        Feature::LaneDeviation => lane_deviation(&scene.map, pose),
        Feature::LeadDistance => lead_gap(i, all),
    })
}

fn add_features(hist: &mut [Histogram], features: StepFeatures) {
    for (h, v) in hist.iter_mut().zip(features) {
        if let Some(v) = v {
            h.add(v);
        }
    }
}

/// Tallies each scene of a rollout over `scenes` (the batch's scenes, in order).
///
/// - Infractions: a controlled agent counts once if any step of the rollout flags it, except
///   that an agent whose every collision was a log-replayed vehicle running into it from
///   behind counts in `hit_by_log` instead ([`super::collisions::hit_only_by_log`]).
/// - With `with_log` (real scenes, whose controlled agents have logged futures): FDE and its
///   along-/cross-track split (ATE, CTE) at step `fde_step`, for agents simulated and logged
///   then;
///   features of the simulated and of the logged agent-steps over the rollout's steps.
pub fn tally_rollout(
    scenes: &[&Scene],
    out: &Rollout,
    fde_step: usize,
    with_log: bool,
) -> Result<Vec<SceneTally>> {
    let host = HostRollout::new(out);
    if host.poses.len() != scenes.len() * host.n * (host.steps + 1) * 4 {
        return Err(Error::InvalidArgument(format!(
            "rollout of shape {:?} does not match {} scenes",
            out.poses.dims(),
            scenes.len()
        )));
    }
    refuse_non_finite(&host, scenes)?;
    let hit_by_log = hit_only_by_log(scenes, out);
    Ok(scenes
        .iter()
        .zip(&hit_by_log)
        .enumerate()
        .map(|(b, (scene, hit))| tally_scene(&host, b, scene, hit, fde_step, with_log))
        .collect())
}

/// Refuses a rollout that put a present agent at a non-finite pose: every metric of it would
/// be NaN, and the cause is the policy (weights that have diverged), not the scene.
fn refuse_non_finite(host: &HostRollout, scenes: &[&Scene]) -> Result<()> {
    for (b, scene) in scenes.iter().enumerate() {
        for i in 0..host.agents(scene) {
            for t in 0..=host.steps {
                let k = host.at(b, i, t);
                if host.present[k] && host.poses[k * 4..k * 4 + 4].iter().any(|v| !v.is_finite()) {
                    return Err(Error::InvalidArgument(format!(
                        "scene {}: agent {i} has a non-finite pose {:.1} s into the rollout; the \
                         policy's outputs are not finite (weights from a diverged run?), so no \
                         metric of it means anything",
                        scene.id,
                        t as f64 * scene.dt
                    )));
                }
            }
        }
    }
    Ok(())
}

fn tally_scene(
    host: &HostRollout,
    b: usize,
    scene: &Scene,
    hit_by_log: &[bool],
    fde_step: usize,
    with_log: bool,
) -> SceneTally {
    let mut tally = SceneTally::default();
    let now = scene.current_step();
    let controlled: Vec<usize> = (0..host.agents(scene))
        .filter(|&i| scene.agents[i].role == AgentRole::Controlled)
        .collect();
    for &i in &controlled {
        tally.agents += 1.0;
        let hit_only_by_log = hit_by_log.get(i).copied().unwrap_or(false);
        let collided = host.any_flag(&host.collision, b, i) && !hit_only_by_log;
        tally.hit_by_log += f64::from(u8::from(hit_only_by_log));
        let offroad = host.any_flag(&host.offroad, b, i);
        tally.collided += f64::from(u8::from(collided));
        tally.offroad += f64::from(u8::from(offroad));
        tally.infracted += f64::from(u8::from(collided || offroad));
    }
    if !with_log {
        return tally;
    }

    let simulated = scene_simulated_features(host, b, scene);
    let logged = logged_features(scene, host.steps);
    for &i in &controlled {
        for f in simulated[i].iter().flatten() {
            add_features(&mut tally.simulated, *f);
        }
        for f in logged[i].iter().flatten() {
            add_features(&mut tally.logged, *f);
        }
    }

    // FDE and its split along / across the logged path (from the current step on).
    let t = fde_step;
    if t == 0 || t > host.steps {
        return tally;
    }
    for &i in &controlled {
        let (l, sim) = (logged_view(scene, i, now + t), host.view(b, i, t, scene));
        if !(l.present && host.simulated[host.at(b, i, t)]) {
            continue;
        }
        let last = (now + host.steps).min(scene.steps() - 1);
        let points: Vec<[f64; 2]> = (now..=last)
            .map(|s| logged_view(scene, i, s))
            .filter(|v| v.present)
            .map(|v| [v.x, v.y])
            .collect();
        let Some(path) = LoggedPath::new(&points, logged_view(scene, i, now).heading) else {
            continue;
        };
        let (ate, cte) = path.errors([sim.x, sim.y], [l.x, l.y]);
        tally.fde_sum += displacement([sim.x, sim.y], [l.x, l.y]);
        tally.ate_sum += ate;
        tally.cte_sum += cte;
        tally.fde_agents += 1.0;
    }
    tally
}

/// One agent-step's features in [`Feature::ALL`] order; `None` where undefined (no leader).
pub type StepFeatures = [Option<f64>; 4];
/// Per agent, per step 1..=T: the step's features, or `None` where the agent was not there.
pub type AgentFeatureRows = Vec<Vec<Option<StepFeatures>>>;

/// Per scene of a rollout, per agent (controlled ones; empty for others), per simulated step
/// 1..=T: the simulated features ([`features_of`]); `None` where the agent was not simulated.
pub fn simulated_features(scenes: &[&Scene], out: &Rollout) -> Vec<AgentFeatureRows> {
    let host = HostRollout::new(out);
    scenes
        .iter()
        .enumerate()
        .map(|(b, scene)| scene_simulated_features(&host, b, scene))
        .collect()
}

fn scene_simulated_features(host: &HostRollout, b: usize, scene: &Scene) -> AgentFeatureRows {
    let mut per_agent = vec![Vec::new(); host.agents(scene)];
    for t in 1..=host.steps {
        let all = host.views(b, t, scene);
        for (i, row) in per_agent.iter_mut().enumerate() {
            if scene.agents[i].role != AgentRole::Controlled {
                continue;
            }
            let simulated = |t: usize| host.simulated[host.at(b, i, t)];
            let before = simulated(t - 1).then(|| host.view(b, i, t - 1, scene));
            row.push(simulated(t).then(|| features_of(scene, i, before, &all)));
        }
    }
    per_agent
}

/// The logged counterpart of [`simulated_features`] for one scene over `steps` steps.
pub fn logged_features(scene: &Scene, steps: usize) -> AgentFeatureRows {
    let now = scene.current_step();
    let agents = scene.agents.len();
    let mut per_agent = vec![Vec::new(); agents];
    for t in 1..=steps {
        let step = now + t;
        let all: Vec<AgentView> = (0..agents).map(|i| logged_view(scene, i, step)).collect();
        for (i, row) in per_agent.iter_mut().enumerate() {
            if scene.agents[i].role != AgentRole::Controlled {
                continue;
            }
            let before = Some(logged_view(scene, i, step - 1)).filter(|v| v.present);
            row.push(all[i].present.then(|| features_of(scene, i, before, &all)));
        }
    }
    per_agent
}
