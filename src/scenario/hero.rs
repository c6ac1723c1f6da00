//! Hero scripts at run time: a [`Policy`] that drives the heroes of a batch of long-tail
//! scenarios through their phases, reacting to the simulated state of their targets. Each
//! hero tracks a lane (pure pursuit) and a speed profile, so every manoeuvre goes through the
//! same bicycle dynamics and limits as the learned agents and is physically feasible.

use std::sync::Arc;

use super::behaviour::{Action, Direction, Phase, Trigger};
use crate::driver::{
    AgentView, ControlCommand, IdmParams, LanePath, Snapshot, find_leader, idm_accel,
    locate_on_lane, look_ahead, steer_along, to_controls,
};
use crate::map::Map;
use crate::sim::{ActionLimits, Controls, Observation, Policy};

/// How far ahead a hero's lane path reaches (m).
const PATH_AHEAD_M: f64 = 150.0;
/// A lane change is complete within this distance of the new lane's centre (m).
const LANE_CHANGE_DONE_M: f64 = 0.3;
/// A speed target counts as reached within this margin (m/s).
const SPEED_REACHED: f64 = 0.5;

/// Where one hero is and what it should do.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeroAssignment {
    /// Index of the scene in the batch.
    pub scene: usize,
    /// Agent index of the hero and of its target within the scene.
    pub agent: usize,
    pub target: usize,
    pub phases: Vec<Phase<f64>>,
}

/// What became of one phase during a rollout (steps count from the scene's current step).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhaseProgress {
    pub fired_step: Option<usize>,
    pub done_step: Option<usize>,
    /// Why the action could not be carried out (e.g. no lane on that side).
    pub failed: Option<String>,
}

#[derive(Debug, Clone)]
enum Lateral {
    Keep,
    Change {
        to: usize,
        lateral_speed: f64,
        phase: usize,
    },
    Swerve {
        sign: f64,
        amplitude: f64,
        period: f64,
        since: f64,
        phase: usize,
    },
}

#[derive(Debug, Clone)]
enum Longitudinal {
    Cruise {
        speed: f64,
    },
    Brake {
        decel: f64,
        jerk: f64,
        min_speed: f64,
        since: f64,
        phase: usize,
    },
    Accelerate {
        accel: f64,
        max_speed: f64,
    },
    Follow {
        time_gap: f64,
        max_speed: f64,
    },
}

#[derive(Debug, Clone)]
struct HeroState {
    assignment: HeroAssignment,
    next_phase: usize,
    lane: Option<usize>,
    last_xy: Option<[f64; 2]>,
    travelled: f64,
    lateral: Lateral,
    longitudinal: Option<Longitudinal>,
    progress: Vec<PhaseProgress>,
}

/// The hero script policy of a batch. It keeps each hero's progress, so it serves one
/// rollout: build a fresh one (e.g. with `scenario::hero_scripts`) for the next.
pub struct HeroScripts {
    maps: Vec<Arc<Map>>,
    heroes: Vec<HeroState>,
    pub limits: ActionLimits,
    pub idm: IdmParams,
    dt: f64,
}

/// Longitudinal relation of a hero to its target.
struct Relation {
    /// Target position along the hero's heading (m, positive = target ahead).
    along: f64,
    /// Bumper-to-bumper gap (m); negative when side by side.
    gap: f64,
    /// Rate at which the gap shrinks (m/s).
    closing: f64,
}

fn relation(hero: &AgentView, target: &AgentView) -> Relation {
    let d = hero.direction();
    let along = (target.x - hero.x) * d[0] + (target.y - hero.y) * d[1];
    let gap = along.abs() - 0.5 * (hero.length + target.length);
    let target_speed = target.speed * (target.heading - hero.heading).cos();
    let closing = if along > 0.0 {
        hero.speed - target_speed
    } else {
        target_speed - hero.speed
    };
    Relation {
        along,
        gap,
        closing,
    }
}

impl HeroScripts {
    /// `maps[b]` is scene b's map; `dt` the simulation step (s).
    pub fn new(maps: Vec<Arc<Map>>, assignments: Vec<HeroAssignment>, dt: f64) -> Self {
        let heroes = assignments
            .into_iter()
            .map(|a| HeroState {
                progress: vec![PhaseProgress::default(); a.phases.len()],
                assignment: a,
                next_phase: 0,
                lane: None,
                last_xy: None,
                travelled: 0.0,
                lateral: Lateral::Keep,
                longitudinal: None,
            })
            .collect();
        Self {
            maps,
            heroes,
            limits: ActionLimits::default(),
            idm: IdmParams::default(),
            dt,
        }
    }

    /// Per hero (in assignment order), what happened to each phase so far.
    pub fn progress(&self) -> Vec<Vec<PhaseProgress>> {
        self.heroes.iter().map(|h| h.progress.clone()).collect()
    }

    /// One hero's command at `step`.
    fn command(&mut self, k: usize, snapshot: &Snapshot, step: usize) -> Option<ControlCommand> {
        let clock = Clock {
            step,
            time: step as f64 * self.dt,
            dt: self.dt,
        };
        let hero = &mut self.heroes[k];
        let map = self.maps[hero.assignment.scene].clone();
        let agents = snapshot.scene(hero.assignment.scene);
        let me = *agents.get(hero.assignment.agent)?;
        if !me.present {
            return None;
        }
        let target = agents.get(hero.assignment.target).copied()?;
        let (lane, s) = hero.locate(&map, &me)?;
        hero.start_fired_phases(&map, lane, &me, &target, clock);
        let (path_lane, path_s, offset) = hero.lateral_target(&map, lane, s, &me, clock);
        let path = LanePath::new(&map, path_lane, path_s, 0.0, PATH_AHEAD_M);
        let steer = steer_along(&me, &path, offset);
        let accel = hero.longitudinal_accel(&self.idm, &path, agents, &target, clock);
        // Never command a reversal: at most stop within this step.
        let accel = accel.max(-me.speed / clock.dt);
        Some(ControlCommand { accel, steer })
    }
}

/// The time of the step a command is for.
#[derive(Debug, Clone, Copy)]
struct Clock {
    step: usize,
    /// `step * dt` (s).
    time: f64,
    dt: f64,
}

/// Whether `trigger` fires now; `since` is when the previous phase completed (s).
fn fires(
    trigger: &Trigger<f64>,
    hero: &HeroState,
    me: &AgentView,
    target: &AgentView,
    time: f64,
    since: f64,
) -> bool {
    let rel = || relation(me, target);
    match *trigger {
        Trigger::Start => true,
        Trigger::After { seconds } => time - since >= seconds - 1e-9,
        Trigger::Travelled { metres } => hero.travelled >= metres,
        _ if !target.present => false,
        Trigger::AheadGapBelow { metres } => {
            let r = rel();
            r.along < 0.0 && r.gap < metres
        }
        Trigger::AheadGapAbove { metres } => {
            let r = rel();
            r.along < 0.0 && r.gap > metres
        }
        Trigger::BehindGapBelow { metres } => {
            let r = rel();
            r.along > 0.0 && r.gap < metres
        }
        Trigger::TtcBelow { seconds } => {
            let r = rel();
            r.gap > 0.0 && r.closing > 0.0 && r.gap / r.closing < seconds
        }
    }
}

impl HeroState {
    /// Updates the distance travelled and returns the lane kept and the arc length along it,
    /// found once per step (the lane a hero starts on is the one it is projected onto).
    fn locate(&mut self, map: &Map, me: &AgentView) -> Option<(usize, f64)> {
        if let Some(last) = self.last_xy {
            self.travelled += ((me.x - last[0]).powi(2) + (me.y - last[1]).powi(2)).sqrt();
        }
        self.last_xy = Some([me.x, me.y]);
        let (lane, s) = match self.lane {
            Some(l) => {
                let (lane, s, _) = locate_on_lane(map, l, [me.x, me.y]);
                (lane, s)
            }
            None => {
                let p = map.lane_projection([me.x, me.y], me.heading)?;
                (p.lane, p.s)
            }
        };
        self.lane = Some(lane);
        if self.longitudinal.is_none() {
            self.longitudinal = Some(Longitudinal::Cruise { speed: me.speed });
        }
        Some((lane, s))
    }

    /// Starts every phase whose trigger fires, in order, each once the previous one has
    /// completed.
    fn start_fired_phases(
        &mut self,
        map: &Map,
        lane: usize,
        me: &AgentView,
        target: &AgentView,
        clock: Clock,
    ) {
        while let Some(phase) = self.assignment.phases.get(self.next_phase).cloned() {
            let since = match self.next_phase {
                0 => Some(0.0),
                p => self.progress[p - 1].done_step.map(|d| d as f64 * clock.dt),
            };
            let Some(since) = since else { break };
            if !fires(&phase.trigger, self, me, target, clock.time, since) {
                break;
            }
            let p = self.next_phase;
            self.progress[p].fired_step = Some(clock.step);
            self.next_phase += 1;
            self.start(p, &phase.action, map, lane, clock);
        }
    }

    /// Starts phase `p`'s action. Actions that only set a target (speed, gap) complete at once;
    /// manoeuvres complete when carried out.
    fn start(&mut self, p: usize, action: &Action<f64>, map: &Map, lane: usize, clock: Clock) {
        let done_now = match *action {
            Action::ChangeLane {
                direction,
                lateral_speed,
            } => {
                let l = &map.lanes()[lane];
                let side = match direction {
                    Direction::Left => l.left_neighbour,
                    Direction::Right => l.right_neighbour,
                };
                match side {
                    Some(to) => {
                        self.lateral = Lateral::Change {
                            to,
                            lateral_speed,
                            phase: p,
                        }
                    }
                    None => {
                        self.progress[p].failed = Some(format!(
                            "no lane to the {direction:?} at step {}",
                            clock.step
                        ))
                    }
                }
                false
            }
            Action::Swerve {
                direction,
                amplitude,
                period,
            } => {
                self.lateral = Lateral::Swerve {
                    sign: if direction == Direction::Left {
                        1.0
                    } else {
                        -1.0
                    },
                    amplitude,
                    period,
                    since: clock.time,
                    phase: p,
                };
                false
            }
            Action::Brake {
                decel,
                jerk,
                min_speed,
            } => {
                self.longitudinal = Some(Longitudinal::Brake {
                    decel,
                    jerk,
                    min_speed,
                    since: clock.time,
                    phase: p,
                });
                false
            }
            Action::Accelerate { accel, max_speed } => {
                self.longitudinal = Some(Longitudinal::Accelerate { accel, max_speed });
                true
            }
            Action::Cruise { speed } => {
                self.longitudinal = Some(Longitudinal::Cruise { speed });
                true
            }
            Action::FollowTarget {
                time_gap,
                max_speed,
            } => {
                self.longitudinal = Some(Longitudinal::Follow {
                    time_gap,
                    max_speed,
                });
                true
            }
        };
        if done_now {
            self.progress[p].done_step = Some(clock.step);
        }
    }

    /// The lane to track, the arc length along it and the offset from its centre; completes
    /// a lane change or swerve when it is carried out.
    fn lateral_target(
        &mut self,
        map: &Map,
        lane: usize,
        s: f64,
        me: &AgentView,
        clock: Clock,
    ) -> (usize, f64, f64) {
        let ld = look_ahead(me.speed);
        match self.lateral.clone() {
            Lateral::Keep => (lane, s, 0.0),
            Lateral::Change {
                to,
                lateral_speed,
                phase,
            } => {
                let (to, s_to, lateral) = locate_on_lane(map, to, [me.x, me.y]);
                if lateral.abs() < LANE_CHANGE_DONE_M {
                    self.lateral = Lateral::Keep;
                    self.lane = Some(to);
                    self.progress[phase].done_step.get_or_insert(clock.step);
                    (to, s_to, 0.0)
                } else {
                    self.lateral = Lateral::Change {
                        to,
                        lateral_speed,
                        phase,
                    };
                    // Aim so that the approach runs at about `lateral_speed`.
                    let remaining = lateral.abs() - lateral_speed * ld / me.speed.max(1.0);
                    (to, s_to, remaining.max(0.0).copysign(lateral))
                }
            }
            Lateral::Swerve {
                sign,
                amplitude,
                period,
                since,
                phase,
            } => {
                let tau = clock.time - since + ld / me.speed.max(1.0);
                if clock.time - since >= period {
                    self.lateral = Lateral::Keep;
                    self.progress[phase].done_step.get_or_insert(clock.step);
                }
                let wave = if tau < period {
                    sign * amplitude * (std::f64::consts::TAU * tau / period).sin()
                } else {
                    0.0
                };
                (lane, s, wave)
            }
        }
    }

    /// The acceleration of the current speed profile; completes a brake phase when its speed
    /// is reached.
    fn longitudinal_accel(
        &mut self,
        idm: &IdmParams,
        path: &LanePath,
        agents: &[AgentView],
        target: &AgentView,
        clock: Clock,
    ) -> f64 {
        let me = agents[self.assignment.agent];
        let dt = clock.dt;
        match self.longitudinal.clone() {
            None => 0.0,
            Some(Longitudinal::Cruise { speed }) => {
                let leader = find_leader(path, self.assignment.agent, agents);
                idm_accel(
                    idm,
                    me.speed,
                    speed,
                    leader.map(|l| (l.gap, me.speed - l.speed)),
                )
            }
            Some(Longitudinal::Brake {
                decel,
                jerk,
                min_speed,
                since,
                phase,
            }) => {
                if me.speed <= min_speed + SPEED_REACHED {
                    self.progress[phase].done_step.get_or_insert(clock.step);
                    // Hold the speed reached (a proportional hold, never below zero).
                    (min_speed - me.speed) / dt
                } else {
                    -(decel.min(jerk * (clock.time - since + dt)))
                }
            }
            Some(Longitudinal::Accelerate { accel, max_speed }) => {
                if me.speed >= max_speed - SPEED_REACHED {
                    (max_speed - me.speed) / dt
                } else {
                    accel
                }
            }
            Some(Longitudinal::Follow {
                time_gap,
                max_speed,
            }) => {
                let tailgater = IdmParams {
                    time_gap_s: time_gap,
                    min_gap_m: 1.0,
                    accel: 2.5,
                    ..*idm
                };
                let ahead = path
                    .project([target.x, target.y])
                    .filter(|(station, _)| target.present && *station > 0.0)
                    .map(|(station, _)| {
                        let gap = station - 0.5 * (me.length + target.length);
                        (gap, me.speed - target.speed)
                    });
                idm_accel(&tailgater, me.speed, max_speed, ahead)
            }
        }
    }
}

impl Policy for HeroScripts {
    fn act(&mut self, obs: &Observation) -> Controls {
        let snapshot = Snapshot::from_observation(obs);
        let n = snapshot.agents_per_scene;
        let mut commands = vec![ControlCommand::default(); snapshot.agents.len()];
        for k in 0..self.heroes.len() {
            let slot = self.heroes[k].assignment.scene * n + self.heroes[k].assignment.agent;
            if let Some(c) = self.command(k, &snapshot, obs.step) {
                commands[slot] = c;
            }
        }
        to_controls(
            &commands,
            &self.limits,
            [snapshot.batch, n],
            &obs.batch.agent_size.device(),
        )
    }
}
