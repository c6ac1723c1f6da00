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

/// Per scene of the batch, its controlled agents' first collisions.
pub(super) fn first_collisions(
    scenes: &[&Scene],
    out: &Rollout,
    dt: f64,
) -> Vec<Vec<FirstCollision>> {
    let [_, n, t1, _] = out.poses.dims();
    let steps = t1 - 1;
    let poses = floats(out.poses.clone());
    let (present, collision, offroad) = (
        bools(out.present.clone()),
        bools(out.collision.clone()),
        bools(out.offroad.clone()),
    );
    let pose = |b: usize, i: usize, t: usize| {
        let k = ((b * n + i) * t1 + t) * 4;
        [
            poses[k] as f64,
            poses[k + 1] as f64,
            poses[k + 2] as f64,
            poses[k + 3] as f64,
        ]
    };
    scenes
        .iter()
        .enumerate()
        .map(|(b, scene)| {
            let agents = scene.agents.len().min(n);
            let footprint = |i: usize, t: usize| {
                let p = pose(b, i, t);
                let a = &scene.agents[i];
                OrientedBox::new([p[0], p[1]], p[2], a.length, a.width)
            };
            let controlled: Vec<usize> = (0..agents)
                .filter(|&i| scene.agents[i].role == AgentRole::Controlled)
                .collect();
            let mut found = Vec::new();
            for &i in &controlled {
                let row = (b * n + i) * steps;
                let Some(t) = (0..steps).find(|&t| collision[row + t]) else {
                    continue;
                };
                // The flag at t is the transition into step t + 1: the boxes touched during it.
                let motion = |j: usize| {
                    let to = footprint(j, t + 1);
                    if present[(b * n + j) * t1 + t] {
                        BoxMotion {
                            from: footprint(j, t),
                            to,
                        }
                    } else {
                        BoxMotion::still(to)
                    }
                };
                let me = motion(i);
                let other = (0..agents).find(|&j| {
                    j != i
                        && present[(b * n + j) * t1 + t + 1]
                        && me.first_contact(&motion(j)).is_some()
                });
                let Some(j) = other else { continue };
                // Where the other was one step before the contact: at the contact a fast
                // closing vehicle may already have passed the other's centre.
                let (p, q) = (pose(b, i, t), pose(b, j, t));
                let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                let (sin, cos) = p[2].sin_cos();
                found.push(FirstCollision {
                    scene: scene.id.clone(),
                    agent: i,
                    time_s: (t + 1) as f64 * dt,
                    with: scene.agents[j].role,
                    contact: Contact::from_offset(cos * dx + sin * dy, -sin * dx + cos * dy),
                    after_offroad: (0..t).any(|s| offroad[row + s]),
                    speed: pose(b, i, t)[3],
                    other_speed: pose(b, j, t)[3],
                    start_speed: pose(b, i, 0)[3],
                    other_start_speed: pose(b, j, 0)[3],
                });
            }
            found
        })
        .collect()
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
