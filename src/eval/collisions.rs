//! Who collides with whom: each controlled agent's first collision in an evaluation rollout,
//! classified by the other vehicle's role (a scripted hero, another controlled agent, a
//! replayed one) and where it was in the agent's frame (ahead: the agent ran into it;
//! behind: it ran into the agent; beside: a side contact, e.g. a cut-in or a lane change).
//!
//! The collision rate alone cannot tell a policy that fails to brake for a cut-in from one
//! that squeezes its neighbours or leaves its lane; this breakdown can, and it is what a
//! reward or a scenario family should be judged against.

use serde::{Deserialize, Serialize};

use super::tally::{bools, floats};
use crate::geometry::{BoxMotion, OrientedBox};
use crate::scene::{AgentRole, Scene};
use crate::sim::Rollout;
use crate::sim::infractions::in_rear_quarter;

/// Where the other vehicle was, in the colliding agent's frame, one step before the first
/// contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Contact {
    /// Ahead within +-45 degrees of the agent's heading: the agent drove into it.
    Ahead,
    /// Behind within +-45 degrees: it drove into the agent.
    Behind,
    /// To one side.
    Beside,
}

impl Contact {
    pub const ALL: [Contact; 3] = [Contact::Ahead, Contact::Behind, Contact::Beside];

    pub fn name(self) -> &'static str {
        match self {
            Contact::Ahead => "ahead",
            Contact::Behind => "behind",
            Contact::Beside => "beside",
        }
    }

    /// From the other vehicle's centre relative to the agent's, rotated into the agent's frame.
    pub fn from_offset(longitudinal: f64, lateral: f64) -> Self {
        if lateral.abs() > longitudinal.abs() {
            Self::Beside
        } else if longitudinal >= 0.0 {
            Self::Ahead
        } else {
            Self::Behind
        }
    }
}

/// One agent's first collision.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FirstCollision {
    pub scene: String,
    pub agent: usize,
    /// Time of the contact after the current step (s).
    pub time_s: f64,
    /// The other vehicle: its role, and where it was.
    pub with: AgentRole,
    pub contact: Contact,
    /// The agent had already left the road before the contact.
    pub after_offroad: bool,
    /// Speeds at the step before the contact (m/s).
    pub speed: f64,
    pub other_speed: f64,
    /// Speeds at the start of the rollout (m/s): with the above, how much each had slowed.
    pub start_speed: f64,
    pub other_start_speed: f64,
}

/// Every measured agent's first collision, summarised as shares by the other vehicle's role
/// and the contact side.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CollisionBreakdown {
    /// Controlled agents measured.
    pub agents: usize,
    pub collisions: Vec<FirstCollision>,
}

impl CollisionBreakdown {
    /// Percent of agents whose first collision is with `with` on side `contact`.
    pub fn share(&self, with: AgentRole, contact: Contact) -> f64 {
        let n = self
            .collisions
            .iter()
            .filter(|c| c.with == with && c.contact == contact)
            .count();
        100.0 * n as f64 / self.agents.max(1) as f64
    }

    /// Percent of agents whose first collision came after they had left the road.
    pub fn after_offroad_pct(&self) -> f64 {
        let n = self.collisions.iter().filter(|c| c.after_offroad).count();
        100.0 * n as f64 / self.agents.max(1) as f64
    }

    /// `{hero: {ahead, behind, beside}, controlled: {..}, replayed: {..}, after_offroad}`,
    /// each the percent of agents.
    pub fn json(&self) -> serde_json::Value {
        let mut o = serde_json::Map::new();
        for (role, name) in ROLES {
            let sides: serde_json::Map<String, serde_json::Value> = Contact::ALL
                .iter()
                .map(|&c| (c.name().to_string(), serde_json::json!(self.share(role, c))))
                .collect();
            o.insert(name.to_string(), serde_json::Value::Object(sides));
        }
        o.insert(
            "after_offroad".into(),
            serde_json::json!(self.after_offroad_pct()),
        );
        serde_json::Value::Object(o)
    }

    /// Mean speeds (m/s) of the first collisions of each role and side, at the start of the
    /// rollout and one step before the contact, of the agent and of the other vehicle:
    /// `{controlled: {ahead: {count, speed, other_speed, start_speed, other_start_speed}}}`,
    /// groups without a collision left out. Whether a rear-end comes from a car that slowed
    /// down or from one that did not brake for it is in these speeds, not in the rate.
    pub fn speeds_json(&self) -> serde_json::Value {
        let mut o = serde_json::Map::new();
        for (role, name) in ROLES {
            let mut sides = serde_json::Map::new();
            for contact in Contact::ALL {
                let group: Vec<&FirstCollision> = self
                    .collisions
                    .iter()
                    .filter(|c| c.with == role && c.contact == contact)
                    .collect();
                if group.is_empty() {
                    continue;
                }
                let mean = |f: fn(&FirstCollision) -> f64| {
                    group.iter().map(|c| f(c)).sum::<f64>() / group.len() as f64
                };
                sides.insert(
                    contact.name().to_string(),
                    serde_json::json!({
                        "count": group.len(),
                        "speed": mean(|c| c.speed),
                        "other_speed": mean(|c| c.other_speed),
                        "start_speed": mean(|c| c.start_speed),
                        "other_start_speed": mean(|c| c.other_start_speed),
                    }),
                );
            }
            if !sides.is_empty() {
                o.insert(name.to_string(), serde_json::Value::Object(sides));
            }
        }
        serde_json::Value::Object(o)
    }
}

/// The other vehicle's roles, by their JSON and table names.
pub const ROLES: [(AgentRole, &str); 3] = [
    (AgentRole::Hero, "hero"),
    (AgentRole::Controlled, "controlled"),
    (AgentRole::Replayed, "replayed"),
];

/// The rollout's boxes on the host: each agent's footprint and its motion over a step.
struct HostBoxes {
    n: usize,
    t1: usize,
    poses: Vec<f32>,
    present: Vec<bool>,
    collision: Vec<bool>,
    offroad: Vec<bool>,
}

impl HostBoxes {
    fn new(out: &Rollout) -> Self {
        let [_, n, t1, _] = out.poses.dims();
        Self {
            n,
            t1,
            poses: floats(out.poses.clone()),
            present: bools(out.present.clone()),
            collision: bools(out.collision.clone()),
            offroad: bools(out.offroad.clone()),
        }
    }

    fn steps(&self) -> usize {
        self.t1 - 1
    }

    /// Centre x, y, heading, speed of agent `i` of scene `b` at step `t`.
    fn pose(&self, b: usize, i: usize, t: usize) -> [f64; 4] {
        let k = ((b * self.n + i) * self.t1 + t) * 4;
        std::array::from_fn(|c| self.poses[k + c] as f64)
    }

    /// Index of agent `i`'s first transition flag in `[B][N][T]` arrays.
    fn row(&self, b: usize, i: usize) -> usize {
        (b * self.n + i) * self.steps()
    }

    fn present(&self, b: usize, j: usize, t: usize) -> bool {
        self.present[(b * self.n + j) * self.t1 + t]
    }

    /// Agent `j`'s box over the transition into step `t + 1` (still where it appeared then).
    fn motion(&self, scene: &Scene, b: usize, j: usize, t: usize) -> BoxMotion {
        let a = &scene.agents[j];
        let footprint = |t: usize| {
            let p = self.pose(b, j, t);
            OrientedBox::new([p[0], p[1]], p[2], a.length, a.width)
        };
        let to = footprint(t + 1);
        if self.present(b, j, t) {
            BoxMotion {
                from: footprint(t),
                to,
            }
        } else {
            BoxMotion::still(to)
        }
    }

    /// The vehicles agent `i` touched during the transition into step `t + 1`, each with the
    /// fraction of the step at the first contact.
    fn contacts(&self, scene: &Scene, b: usize, i: usize, t: usize) -> Vec<(usize, f64)> {
        let agents = scene.agents.len().min(self.n);
        let me = self.motion(scene, b, i, t);
        (0..agents)
            .filter(|&j| j != i && self.present(b, j, t + 1))
            .filter_map(|j| {
                me.first_contact(&self.motion(scene, b, j, t))
                    .map(|s| (j, s))
            })
            .collect()
    }

    /// The controlled agents of scene `b`.
    fn controlled(&self, scene: &Scene) -> Vec<usize> {
        (0..scene.agents.len().min(self.n))
            .filter(|&i| scene.agents[i].role == AgentRole::Controlled)
            .collect()
    }
}

/// Per scene of the batch, its controlled agents' first collisions.
pub(super) fn first_collisions(
    scenes: &[&Scene],
    out: &Rollout,
    dt: f64,
) -> Vec<Vec<FirstCollision>> {
    let host = HostBoxes::new(out);
    scenes
        .iter()
        .enumerate()
        .map(|(b, scene)| {
            host.controlled(scene)
                .into_iter()
                .filter_map(|i| first_collision(&host, scene, b, i, dt))
                .collect()
        })
        .collect()
}

fn first_collision(
    host: &HostBoxes,
    scene: &Scene,
    b: usize,
    i: usize,
    dt: f64,
) -> Option<FirstCollision> {
    let row = host.row(b, i);
    // The flag at t is the transition into step t + 1: the boxes touched during it.
    let t = (0..host.steps()).find(|&t| host.collision[row + t])?;
    let (j, _) = *host.contacts(scene, b, i, t).first()?;
    // Where the other was one step before the contact: at the contact a fast closing vehicle
    // may already have passed the other's centre.
    let (p, q) = (host.pose(b, i, t), host.pose(b, j, t));
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let (sin, cos) = p[2].sin_cos();
    Some(FirstCollision {
        scene: scene.id.clone(),
        agent: i,
        time_s: (t + 1) as f64 * dt,
        with: scene.agents[j].role,
        contact: Contact::from_offset(cos * dx + sin * dy, -sin * dx + cos * dy),
        after_offroad: (0..t).any(|s| host.offroad[row + s]),
        speed: p[3],
        other_speed: q[3],
        start_speed: host.pose(b, i, 0)[3],
        other_start_speed: host.pose(b, j, 0)[3],
    })
}

/// Per scene of the batch and per agent: it collided, and every vehicle it touched was a
/// log-replayed one running into it from behind (its centre in the agent's rear quarter at
/// their first contact, the simulator's at-fault rule).
///
/// The paper's policy controls every vehicle of a scene. Ours also replay, unchanged, the
/// vehicles that enter the road after the start; a replayed car cannot brake, so a policy
/// car slower than the log is run into by recordings. That is a collision the paper's
/// setting cannot produce, and evaluation reports it apart (`hit_by_log_pct`), not as one.
pub(super) fn hit_only_by_log(scenes: &[&Scene], out: &Rollout) -> Vec<Vec<bool>> {
    let host = HostBoxes::new(out);
    scenes
        .iter()
        .enumerate()
        .map(|(b, scene)| {
            let mut hit = vec![false; scene.agents.len().min(host.n)];
            for i in host.controlled(scene) {
                hit[i] = collided_only_with_replays_from_behind(&host, scene, b, i);
            }
            hit
        })
        .collect()
}

fn collided_only_with_replays_from_behind(
    host: &HostBoxes,
    scene: &Scene,
    b: usize,
    i: usize,
) -> bool {
    let row = host.row(b, i);
    // Each vehicle touched is judged where it first touched: a replayed car drives on through
    // the car it struck, and its later overlap is the same collision.
    let mut judged: Vec<usize> = Vec::new();
    for t in (0..host.steps()).filter(|&t| host.collision[row + t]) {
        let contacts = host.contacts(scene, b, i, t);
        // A flag whose contact this scan cannot find stays the agent's collision.
        if contacts.is_empty() && !judged.iter().any(|&j| host.present(b, j, t + 1)) {
            return false;
        }
        let me = host.motion(scene, b, i, t);
        for (j, s) in contacts {
            if judged.contains(&j) {
                continue;
            }
            let from_behind = in_rear_quarter(&me.at(s), &host.motion(scene, b, j, t).at(s));
            if scene.agents[j].role != AgentRole::Replayed || !from_behind {
                return false;
            }
            judged.push(j);
        }
    }
    !judged.is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_side_follows_the_agents_frame() {
        assert_eq!(Contact::from_offset(5.0, 1.0), Contact::Ahead);
        assert_eq!(Contact::from_offset(-5.0, -1.0), Contact::Behind);
        assert_eq!(Contact::from_offset(1.0, -2.0), Contact::Beside);
    }

    fn rear_end(speed: f64, other_speed: f64, start: f64, other_start: f64) -> FirstCollision {
        FirstCollision {
            scene: "s".into(),
            agent: 0,
            time_s: 2.0,
            with: AgentRole::Controlled,
            contact: Contact::Ahead,
            after_offroad: false,
            speed,
            other_speed,
            start_speed: start,
            other_start_speed: other_start,
        }
    }

    #[test]
    fn collision_speeds_are_means_per_role_and_side_and_empty_groups_are_left_out() {
        let breakdown = CollisionBreakdown {
            agents: 10,
            collisions: vec![
                rear_end(20.0, 10.0, 30.0, 28.0),
                rear_end(24.0, 6.0, 32.0, 30.0),
            ],
        };
        let json = breakdown.speeds_json();
        let group = &json["controlled"]["ahead"];
        assert_eq!(group["count"], 2);
        assert_eq!(group["speed"], 22.0);
        assert_eq!(group["other_speed"], 8.0);
        assert_eq!(group["start_speed"], 31.0);
        assert_eq!(group["other_start_speed"], 29.0);
        assert!(json["controlled"].get("behind").is_none());
        assert!(json.get("hero").is_none());
        assert_eq!(breakdown.share(AgentRole::Controlled, Contact::Ahead), 20.0);
    }
}
