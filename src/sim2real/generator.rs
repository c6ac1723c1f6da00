//! Recordings from a richer "true" plant with one concealed effect, to prove sim-to-real
//! blind: drivers follow speed targets and steer through lane changes, curves, low-speed
//! turns and brake events, stop at lights and crawl in stop-and-go queues (some tracks start
//! at rest), while the plant adds the hidden term and the recording adds sensor noise sized
//! so no single step gives the effect away. Ordinary recordings have stops; a generator
//! without them would not measure what users meet.

use burn::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::command_timing::CommandTiming;
use crate::data::{RecordedTrack, Recordings};
use crate::geometry::wrap_angle;
use crate::sim::catalogue::Effect;
use crate::sim::terms::parameter;
use crate::sim::{
    Controls, Derivative, Dynamics, DynamicsTerm, Integrator, TermInput, VehicleState,
};

/// Sensor noise (standard deviations): RTK-GNSS-grade position, IMU heading, wheel speed.
#[derive(Debug, Clone, Copy)]
pub struct SensorNoise {
    pub position_m: f64,
    pub heading_rad: f64,
    pub speed_m_s: f64,
}

impl Default for SensorNoise {
    fn default() -> Self {
        Self {
            position_m: 0.1,
            heading_rad: 0.003,
            speed_m_s: 0.1,
        }
    }
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct GeneratorConfig {
    pub seed: u64,
    pub tracks: usize,
    pub duration_s: f64,
    pub period_s: f64,
    /// Wheelbase written in the recordings.
    pub declared_wheelbase_m: f64,
    /// Wheelbase of the true plant (differs from the declared one to test that a wrong
    /// wheelbase is fitted, not reported as missing physics).
    pub true_wheelbase_m: f64,
    /// The concealed effect and its parameter values (catalogue order), if any.
    pub effect: Option<(Effect, Vec<f64>)>,
    /// Concealed physics outside the catalogue, if any (for the open-ended stage).
    pub uncatalogued: Option<Uncatalogued>,
    pub noise: SensorNoise,
    /// How the logged commands relate to the commands the plant received.
    pub command_timing: CommandTiming,
}

impl GeneratorConfig {
    /// 24 one-minute tracks at 10 Hz, with `effect` at its [`typical`] strength.
    pub fn with_effect(effect: Option<Effect>, seed: u64) -> Self {
        Self {
            seed,
            tracks: 24,
            duration_s: 60.0,
            period_s: 0.1,
            declared_wheelbase_m: 2.8,
            true_wheelbase_m: 2.8,
            effect: effect.map(|e| (e, typical(e))),
            uncatalogued: None,
            noise: SensorNoise::default(),
            command_timing: CommandTiming::Held,
        }
    }

    /// As [`GeneratorConfig::with_effect`], with physics the catalogue has no term for.
    pub fn with_uncatalogued(physics: Uncatalogued, seed: u64) -> Self {
        Self {
            uncatalogued: Some(physics),
            ..Self::with_effect(None, seed)
        }
    }
}

/// Physics no catalogue effect describes, to prove the open-ended stage on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Uncatalogued {
    /// The road-wheel angle changes with speed, phi_actual = phi (1 - k v). With k < 0 the
    /// steering quickens with speed, which neither the wheelbase (a constant scale) nor the
    /// catalogue's understeer (it only slows the yaw response, with v^2) can follow; with
    /// k > 0 understeer imitates it closely within a few per cent.
    SpeedDependentSteering { k_per_m_s: f64 },
    /// Braking acts `gain` times as strongly as commanded; throttle as commanded.
    BrakeGain { gain: f64 },
    /// The engine's power caps the acceleration at `specific_power_w_kg / v` (power over
    /// mass and speed): a limit that tightens with speed, which a loaded truck reaches on a
    /// motorway. Braking is not limited.
    PowerLimit { specific_power_w_kg: f64 },
}

impl Uncatalogued {
    pub const NAMES: [&'static str; 3] = ["speed_dependent_steering", "brake_gain", "power_limit"];

    /// By name, at a realistic strength.
    pub fn typical(name: &str) -> Option<Self> {
        match name {
            "speed_dependent_steering" => {
                Some(Uncatalogued::SpeedDependentSteering { k_per_m_s: -0.006 })
            }
            "brake_gain" => Some(Uncatalogued::BrakeGain { gain: 1.3 }),
            "power_limit" => Some(Uncatalogued::PowerLimit {
                specific_power_w_kg: 20.0,
            }),
            _ => None,
        }
    }

    fn term(self) -> Box<dyn DynamicsTerm> {
        Box::new(UncataloguedTerm(self))
    }
}

/// The plant's term for [`Uncatalogued`] physics.
#[derive(Debug)]
struct UncataloguedTerm(Uncatalogued);

impl DynamicsTerm for UncataloguedTerm {
    fn name(&self) -> &str {
        match self.0 {
            Uncatalogued::SpeedDependentSteering { .. } => "speed_dependent_steering",
            Uncatalogued::BrakeGain { .. } => "brake_gain",
            Uncatalogued::PowerLimit { .. } => "power_limit",
        }
    }

    fn derivative(&self, mut d: Derivative, input: &TermInput) -> Derivative {
        match self.0 {
            Uncatalogued::SpeedDependentSteering { k_per_m_s } => {
                let v = input.state.speed.clone();
                let phi = input.controls.steer.clone()
                    * (v.clone().mul_scalar(-k_per_m_s).add_scalar(1.0));
                d.heading = v * phi.tan() / input.wheelbase.clone();
            }
            Uncatalogued::BrakeGain { gain } => {
                let braking = input.controls.accel.clone().clamp_max(0.0);
                d.speed = d.speed + braking.mul_scalar(gain - 1.0);
            }
            Uncatalogued::PowerLimit {
                specific_power_w_kg,
            } => {
                let limit = input
                    .state
                    .speed
                    .clone()
                    .clamp_min(0.1)
                    .recip()
                    .mul_scalar(specific_power_w_kg);
                let excess = (input.controls.accel.clone() - limit).clamp_min(0.0);
                d.speed = d.speed - excess;
            }
        }
        d
    }
}

/// A realistic strength of each effect for a passenger car.
pub fn typical(effect: Effect) -> Vec<f64> {
    match effect {
        Effect::AccelLag => vec![0.5],
        Effect::SteerLag => vec![0.3],
        Effect::DeadTime => vec![0.3],
        Effect::Drag => vec![0.0006, 0.15],
        Effect::Understeer => vec![0.004],
        Effect::SteerRateLimit => vec![0.25],
        Effect::Sideslip => vec![1.4],
    }
}

/// Integrator steps per sample in the true plant (fine, so the plant is continuous-time to
/// well below the noise).
const PLANT_SUBSTEPS: usize = 10;

/// Controller steps per logged sample under [`CommandTiming::Sampled`]: a 100 Hz controller
/// under a 10 Hz log.
pub const CONTROLLER_STEPS_PER_SAMPLE: usize = 10;

/// The true plant for one controller step of `step_s`.
fn plant(config: &GeneratorConfig, step_s: f64, substeps: usize, device: &Device) -> Dynamics {
    let mut plant = Dynamics::bicycle(step_s);
    plant.limits = None;
    plant.integrator = Integrator::Midpoint;
    plant.substeps = substeps;
    if let Some((effect, values)) = &config.effect {
        let params: Vec<Tensor<2>> = values.iter().map(|&v| parameter(v, device)).collect();
        plant = plant.with_term(effect.term(&params, step_s));
    }
    if let Some(physics) = config.uncatalogued {
        plant = plant.with_term(physics.term());
    }
    plant
}

fn column(values: Vec<f64>, device: &Device) -> Tensor<2> {
    let n = values.len();
    let v: Vec<f32> = values.iter().map(|&x| x as f32).collect();
    Tensor::<2>::from_data(burn::tensor::TensorData::new(v, [n, 1]), device)
}

fn host(t: &Tensor<2>) -> Vec<f64> {
    t.to_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .expect("f64 data")
}

/// Generates the recordings on `device` (plain, no autodiff needed).
pub fn generate(config: &GeneratorConfig, device: &Device) -> Recordings {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let n = config.tracks;
    let dt = config.period_s;
    let samples = (config.duration_s / dt).round() as usize + 1;
    // Held: one controller step per sample, integrated finely. Sampled: the controller acts
    // at every plant step.
    let controller_steps = match config.command_timing {
        CommandTiming::Held => 1,
        CommandTiming::Sampled => CONTROLLER_STEPS_PER_SAMPLE,
    };
    let step_s = dt / controller_steps as f64;
    let plant = plant(config, step_s, PLANT_SUBSTEPS / controller_steps, device);
    let mut drivers: Vec<Driver> = (0..n).map(|_| Driver::new(&mut rng)).collect();
    let mut state = VehicleState {
        x: column(
            (0..n).map(|_| rng.random_range(-500.0..500.0)).collect(),
            device,
        ),
        y: column(
            (0..n).map(|_| rng.random_range(-500.0..500.0)).collect(),
            device,
        ),
        heading: column(
            (0..n).map(|_| rng.random_range(-3.0..3.0)).collect(),
            device,
        ),
        speed: column(drivers.iter().map(Driver::initial_speed).collect(), device),
        aux: Vec::new(),
    };
    let zero = Controls {
        accel: column(vec![0.0; n], device),
        steer: column(vec![0.0; n], device),
    };
    state = plant.init_aux(state, &zero);
    let wheelbase = column(vec![config.true_wheelbase_m; n], device);
    let mut log = Log::new(config);
    for k in 0..samples {
        for j in 0..controller_steps {
            let t = k as f64 * dt + j as f64 * step_s;
            // The log samples the true state at its own rate only.
            let observed = (j == 0).then(|| [&state.x, &state.y, &state.heading].map(host));
            let speeds = host(&state.speed);
            let mut commands = (Vec::with_capacity(n), Vec::with_capacity(n));
            for (i, driver) in drivers.iter_mut().enumerate() {
                let (accel, steer) = driver.command(t, speeds[i], &mut rng);
                if let Some([x, y, h]) = &observed {
                    let truth = [x[i], y[i], h[i], speeds[i]];
                    log.record(i, t, truth, (accel, steer), &mut rng);
                }
                commands.0.push(accel);
                commands.1.push(steer);
            }
            let command = Controls {
                accel: column(commands.0, device),
                steer: column(commands.1, device),
            };
            state = plant.step(&state, &command, &wheelbase);
        }
    }
    Recordings {
        source: format!("generator (seed {})", config.seed),
        tracks: log.tracks,
    }
}

/// The recordings being written: true states under sensor noise, and the logged commands.
struct Log {
    tracks: Vec<RecordedTrack>,
    noise: [Normal<f64>; 3],
}

impl Log {
    fn new(config: &GeneratorConfig) -> Self {
        let noise = |sigma: f64| Normal::new(0.0, sigma.max(1e-12)).expect("finite sigma");
        Self {
            tracks: (0..config.tracks)
                .map(|i| {
                    RecordedTrack::empty(
                        format!("{}", i + 1),
                        config.period_s,
                        Some(config.declared_wheelbase_m),
                    )
                })
                .collect(),
            noise: [
                noise(config.noise.position_m),
                noise(config.noise.heading_rad),
                noise(config.noise.speed_m_s),
            ],
        }
    }

    /// Track `i`'s sample at `t`: the true x, y, heading and speed under noise, and the
    /// commands.
    fn record(
        &mut self,
        i: usize,
        t: f64,
        truth: [f64; 4],
        (accel, steer): (f64, f64),
        rng: &mut ChaCha8Rng,
    ) {
        let [position, heading, speed] = self.noise;
        let track = &mut self.tracks[i];
        track.t.push(t);
        track.x.push(truth[0] + position.sample(rng));
        track.y.push(truth[1] + position.sample(rng));
        track
            .heading
            .push(wrap_angle(truth[2] + heading.sample(rng)));
        track.speed.push(truth[3] + speed.sample(rng));
        track.accel_cmd.push(accel);
        track.steer_cmd.push(steer);
    }
}

/// Speed band centres (m/s): a stop-and-go queue, town, rural road, highway.
const SPEED_BANDS: [f64; 4] = [4.0, 9.0, 20.0, 30.0];

/// Largest road-wheel angle a driver commands (rad).
const MAX_STEER_RAD: f64 = 0.5;

/// Lane changes and curves need at least this speed (m/s); slower, drivers go straight or turn.
const MIN_MANOEUVRE_SPEED: f64 = 6.0;

/// Below this speed (m/s) a stopping driver holds the brake: the vehicle is at rest.
const AT_REST_M_S: f64 = 0.05;

/// A stop in progress: at a light, at the end of a queue, or before the track starts.
#[derive(Debug, Clone, Copy)]
enum Stop {
    /// Braking at `decel` (m/s^2, negative) until at rest.
    Braking { decel: f64, stand_s: f64 },
    /// At rest with the brake held until `until`.
    Standing { until: f64 },
}

/// The steering manoeuvre in progress.
#[derive(Debug, Clone, Copy)]
enum Manoeuvre {
    Straight {
        until: f64,
    },
    /// Sinusoidal steering over `duration` for a 3.5 m lateral shift.
    LaneChange {
        start: f64,
        duration: f64,
        sign: f64,
    },
    /// Ramp in, hold, ramp out to a constant-radius curve.
    Curve {
        start: f64,
        hold: f64,
        steer: f64,
    },
    /// Low-speed turn: a fast steering step held for a quarter circle.
    Turn {
        start: f64,
        hold: f64,
        steer: f64,
    },
}

/// A driver: speed targets with proportional tracking, brake events and a sequence of
/// steering manoeuvres, all in commands (what a drive-by-wire log would record).
#[derive(Debug)]
struct Driver {
    /// Speed band centre for this track (urban, rural or highway).
    base: f64,
    target: f64,
    next_target_at: f64,
    brake_until: f64,
    brake: f64,
    stop: Option<Stop>,
    manoeuvre: Manoeuvre,
    wheelbase: f64,
}

impl Driver {
    fn new(rng: &mut ChaCha8Rng) -> Self {
        let base = SPEED_BANDS[rng.random_range(0..SPEED_BANDS.len())];
        // Some tracks start at rest, as a log started at a light or in a parked car would.
        let starts_at_rest = rng.random_bool(0.15);
        Self {
            base,
            target: base * rng.random_range(0.8..1.2),
            next_target_at: rng.random_range(3.0..8.0),
            brake_until: -1.0,
            brake: 0.0,
            stop: starts_at_rest.then(|| Stop::Standing {
                until: rng.random_range(1.0..4.0),
            }),
            manoeuvre: Manoeuvre::Straight {
                until: rng.random_range(1.0..4.0),
            },
            wheelbase: 2.8,
        }
    }

    fn initial_speed(&self) -> f64 {
        match self.stop {
            Some(_) => 0.0,
            None => self.target,
        }
    }

    fn command(&mut self, t: f64, v: f64, rng: &mut ChaCha8Rng) -> (f64, f64) {
        let accel = self.accel(t, v, rng);
        // A passenger car's road wheels turn at most about 0.5 rad (lane changes and curves
        // are planned for the speed at their start; a stop during one would ask for more).
        let steer = self
            .steer(t, v.max(1.0), rng)
            .clamp(-MAX_STEER_RAD, MAX_STEER_RAD);
        // Rounded to what a CAN log keeps.
        ((accel * 1e3).round() / 1e3, (steer * 1e5).round() / 1e5)
    }

    /// The longitudinal command: a stop in progress, a brake event, or tracking the target.
    fn accel(&mut self, t: f64, v: f64, rng: &mut ChaCha8Rng) -> f64 {
        match self.stop {
            Some(Stop::Braking { decel, stand_s }) if v <= AT_REST_M_S => {
                self.stop = Some(Stop::Standing { until: t + stand_s });
                return decel.max(-1.5);
            }
            Some(Stop::Braking { decel, .. }) => return decel,
            // At rest, a driver holds the brake pedal.
            Some(Stop::Standing { until }) if t < until => return -1.0,
            Some(Stop::Standing { .. }) => {
                self.stop = None;
                self.next_target_at = t + rng.random_range(4.0..10.0);
            }
            None => {}
        }
        if t >= self.next_target_at {
            // Drives pass from town to highway and back, so every track visits every regime.
            if rng.random_bool(0.3) {
                self.base = SPEED_BANDS[rng.random_range(0..SPEED_BANDS.len())];
            }
            self.target = (self.base * rng.random_range(0.6..1.3)).max(3.0);
            self.next_target_at = t + rng.random_range(4.0..10.0);
            // Stops are common in queues and town, rare on rural roads, absent on highways.
            let stop_chance = match self.base {
                b if b < 5.0 => 0.6,
                b if b < 10.0 => 0.35,
                b if b < 25.0 => 0.1,
                _ => 0.0,
            };
            if rng.random_bool(stop_chance) {
                self.stop = Some(Stop::Braking {
                    decel: -rng.random_range(1.0..3.5),
                    stand_s: rng.random_range(1.0..8.0),
                });
                return self.accel(t, v, rng);
            }
            if rng.random_bool(0.2) && v > 8.0 {
                self.brake_until = t + rng.random_range(1.0..2.0);
                self.brake = -rng.random_range(3.0..5.5);
            }
        }
        if t < self.brake_until {
            self.brake
        } else {
            (0.6 * (self.target - v)).clamp(-3.5, 2.5)
        }
    }

    fn steer(&mut self, t: f64, v: f64, rng: &mut ChaCha8Rng) -> f64 {
        let l = self.wheelbase;
        let done = match self.manoeuvre {
            Manoeuvre::Straight { until } => t >= until,
            Manoeuvre::LaneChange {
                start, duration, ..
            } => t >= start + duration,
            Manoeuvre::Curve { start, hold, .. } => t >= start + 4.0 + hold,
            Manoeuvre::Turn { start, hold, .. } => t >= start + hold + 1.0,
        };
        if done {
            self.manoeuvre = match rng.random_range(0..4) {
                0 => Manoeuvre::Straight {
                    until: t + rng.random_range(2.0..6.0),
                },
                1 | 2 if v < MIN_MANOEUVRE_SPEED => Manoeuvre::Straight {
                    until: t + rng.random_range(1.0..3.0),
                },
                1 => Manoeuvre::LaneChange {
                    start: t,
                    duration: rng.random_range(3.0..5.0),
                    sign: if rng.random_bool(0.5) { 1.0 } else { -1.0 },
                },
                2 => {
                    let lateral =
                        rng.random_range(1.0..3.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    Manoeuvre::Curve {
                        start: t,
                        hold: rng.random_range(3.0..8.0),
                        steer: (l * lateral / (v * v)).atan(),
                    }
                }
                _ if v < 13.0 => {
                    let steer: f64 = rng.random_range(0.15..0.35)
                        * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    // A quarter circle of radius L / tan(steer).
                    let hold = std::f64::consts::FRAC_PI_2 * l / (steer.abs().tan() * v);
                    Manoeuvre::Turn {
                        start: t,
                        hold,
                        steer,
                    }
                }
                _ => Manoeuvre::Straight {
                    until: t + rng.random_range(1.0..3.0),
                },
            };
        }
        match self.manoeuvre {
            Manoeuvre::Straight { .. } => 0.0,
            Manoeuvre::LaneChange {
                start,
                duration,
                sign,
            } => {
                let peak = std::f64::consts::TAU * 3.5 / (duration * duration);
                let lateral = peak * (std::f64::consts::TAU * (t - start) / duration).sin();
                (l * sign * lateral / (v * v)).atan()
            }
            Manoeuvre::Curve { start, hold, steer } => {
                let s = t - start;
                let ramp = (s / 2.0).min(1.0).min(((4.0 + hold - s) / 2.0).max(0.0));
                steer * ramp
            }
            Manoeuvre::Turn { start, hold, steer } => {
                let s = t - start;
                let ramp = (s / 0.4).min(1.0).min(((hold + 1.0 - s) / 0.4).max(0.0));
                steer * ramp
            }
        }
    }
}
