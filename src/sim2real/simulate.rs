//! Batched simulation of windows under a candidate model: the nominal bicycle with a
//! wheelbase scale plus a set of catalogue effects, all parameters as (possibly autodiff)
//! tensors so the same code serves fitting and evaluation.

use burn::prelude::*;
use burn::tensor::TensorData;

use super::windows::Window;
use crate::sim::catalogue::{Effect, ParamSpec, bounded};
use crate::sim::library::{Equation, Feature, LibraryTerm};
use crate::sim::{Controls, Dynamics, Integrator, VehicleState};

/// The wheelbase is fitted as a scale on the declared one, within +-30 %.
pub const WHEELBASE_SCALE: ParamSpec = ParamSpec {
    name: "wheelbase_scale",
    unit: "",
    min: 0.7,
    max: 1.3,
    start: 1.0,
};

/// Longest integrator step (s): midpoint at 0.1 s keeps integration error at millimetres
/// over 5 s of highway driving, far below any effect worth reporting.
const MAX_SUBSTEP_S: f64 = 0.1;

/// Weights of the channels in the fitting loss, turning each into metres: heading errors
/// count as the lateral offset they make over 10 m, speed errors over 1 s.
pub const HEADING_WEIGHT_M: f64 = 10.0;
pub const SPEED_WEIGHT_S: f64 = 1.0;

/// A model to fit: the nominal bicycle, optionally with its wheelbase free, plus catalogue
/// effects and discovered library terms (each started at its regression coefficient).
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub effects: Vec<Effect>,
    pub fit_wheelbase: bool,
    /// Where the wheelbase scale starts (1 = as declared).
    pub wheelbase_start: f64,
    pub discovered: Vec<(Equation, Feature, f64)>,
}

impl Candidate {
    /// The nominal bicycle plus `effects`, wheelbase free.
    pub fn with_effects(effects: Vec<Effect>) -> Self {
        Self {
            effects,
            fit_wheelbase: true,
            wheelbase_start: WHEELBASE_SCALE.start,
            discovered: Vec::new(),
        }
    }

    /// Specs of the raw parameter vector: wheelbase scale first, then each effect's, then
    /// each discovered term's coefficient (free to shrink to zero, change sign or triple).
    pub fn specs(&self) -> Vec<ParamSpec> {
        let wheelbase = ParamSpec {
            start: self.wheelbase_start,
            ..WHEELBASE_SCALE
        };
        std::iter::once(wheelbase)
            .chain(self.effects.iter().flat_map(|e| e.params().iter().copied()))
            .chain(
                self.discovered
                    .iter()
                    .map(|&(_, feature, start)| ParamSpec {
                        name: feature.name(),
                        unit: "",
                        min: start - 2.0 * start.abs(),
                        max: start + 2.0 * start.abs(),
                        start,
                    }),
            )
            .collect()
    }

    /// Display name: effects joined by `+` (discovered terms as `discovered`), or `nominal`.
    pub fn label(&self) -> String {
        let mut names: Vec<&str> = self.effects.iter().map(|e| e.name()).collect();
        if !self.discovered.is_empty() {
            names.push("discovered");
        }
        if names.is_empty() {
            "nominal".into()
        } else {
            names.join("+")
        }
    }
}

/// Windows of one sampling period as tensors `[W, 1]` / `[W, steps]`.
pub struct WindowBatch {
    pub period: f64,
    pub steps: usize,
    /// Indices into the window list this batch was built from.
    pub windows: Vec<usize>,
    initial: [Tensor<2>; 4],
    applied: (Tensor<2>, Tensor<2>),
    past: Vec<(Tensor<2>, Tensor<2>)>,
    commands: (Tensor<2>, Tensor<2>),
    wheelbase: Tensor<2>,
    /// Recorded x, y, heading, speed `[W, steps]`.
    recorded: [Tensor<2>; 4],
}

/// Simulated x, y, heading, speed, each `[W, steps]`.
pub struct Trajectory {
    pub channels: [Tensor<2>; 4],
}

fn column(values: Vec<f32>, w: usize, cols: usize, device: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(values, [w, cols]), device)
}

/// Groups windows by sampling period and horizon into batches.
pub fn batches(windows: &[Window], device: &Device) -> Vec<WindowBatch> {
    let mut groups: Vec<((u64, usize), Vec<usize>)> = Vec::new();
    for (i, w) in windows.iter().enumerate() {
        let key = ((w.period * 1e9).round() as u64, w.steps());
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    groups
        .into_iter()
        .map(|(_, members)| WindowBatch::new(windows, members, device))
        .collect()
}

impl WindowBatch {
    fn new(all: &[Window], members: Vec<usize>, device: &Device) -> Self {
        let ws: Vec<&Window> = members.iter().map(|&i| &all[i]).collect();
        let (n, steps) = (ws.len(), ws[0].steps());
        let col = |f: &dyn Fn(&Window) -> f64| {
            column(ws.iter().map(|w| f(w) as f32).collect(), n, 1, device)
        };
        let past_len = ws.iter().map(|w| w.past.len()).max().unwrap_or(0);
        let past = (0..past_len)
            .map(|k| {
                // Windows near a track's start have less history: repeat their oldest.
                let at = |w: &Window| *w.past.get(k).or(w.past.last()).unwrap_or(&w.commands[0]);
                (col(&|w| at(w).0), col(&|w| at(w).1))
            })
            .collect();
        let grid = |f: &dyn Fn(&Window, usize) -> f64| {
            let v = ws
                .iter()
                .flat_map(|w| (0..steps).map(move |k| f(w, k) as f32))
                .collect();
            column(v, n, steps, device)
        };
        Self {
            period: ws[0].period,
            steps,
            initial: [
                col(&|w| w.initial[0]),
                col(&|w| w.initial[1]),
                col(&|w| w.initial[2]),
                col(&|w| w.initial[3]),
            ],
            applied: (col(&|w| w.applied.0), col(&|w| w.applied.1)),
            past,
            commands: (grid(&|w, k| w.commands[k].0), grid(&|w, k| w.commands[k].1)),
            wheelbase: col(&|w| w.wheelbase),
            recorded: [
                grid(&|w, k| w.recorded[k][0]),
                grid(&|w, k| w.recorded[k][1]),
                grid(&|w, k| w.recorded[k][2]),
                grid(&|w, k| w.recorded[k][3]),
            ],
            windows: members,
        }
    }

    pub fn len(&self) -> usize {
        self.windows.len()
    }

    pub fn is_empty(&self) -> bool {
        self.windows.is_empty()
    }

    /// The simulator for this batch's period.
    fn dynamics(&self, candidate: &Candidate, params: &[Tensor<2>]) -> Dynamics {
        let mut dynamics = Dynamics::bicycle(self.period);
        dynamics.limits = None;
        dynamics.integrator = Integrator::Midpoint;
        dynamics.substeps = (self.period / MAX_SUBSTEP_S).ceil().max(1.0) as usize;
        let mut at = 0;
        for effect in &candidate.effects {
            let n = effect.params().len();
            dynamics = dynamics.with_term(effect.term(&params[at..at + n], self.period));
            at += n;
        }
        if !candidate.discovered.is_empty() {
            let terms = candidate
                .discovered
                .iter()
                .zip(&params[at..])
                .map(|(&(equation, feature, _), c)| (equation, feature, c.clone()))
                .collect();
            dynamics = dynamics.with_term(Box::new(LibraryTerm { terms }));
        }
        dynamics
    }

    /// Rolls every window out under `candidate` with raw parameters `raw` (see
    /// [`Candidate::specs`]).
    pub fn simulate(&self, candidate: &Candidate, raw: &Tensor<1>) -> Trajectory {
        let values = physical(candidate, raw);
        let dynamics = self.dynamics(candidate, &values[1..]);
        let wheelbase = if candidate.fit_wheelbase {
            self.wheelbase.clone() * values[0].clone()
        } else {
            self.wheelbase.clone()
        };
        let controls = |(a, s): &(Tensor<2>, Tensor<2>)| Controls {
            accel: a.clone(),
            steer: s.clone(),
        };
        let [x, y, heading, speed] = self.initial.clone();
        let start = VehicleState {
            x,
            y,
            heading,
            speed,
            aux: Vec::new(),
        };
        let past: Vec<Controls> = self.past.iter().map(controls).collect();
        let mut state = dynamics.init_with_history(start, &controls(&self.applied), &past);
        let n = self.len();
        let mut out: [Vec<Tensor<2>>; 4] = Default::default();
        for k in 0..self.steps {
            let command = Controls {
                accel: self.commands.0.clone().narrow(1, k, 1),
                steer: self.commands.1.clone().narrow(1, k, 1),
            };
            state = dynamics.step(&state, &command, &wheelbase);
            for (channel, value) in
                out.iter_mut()
                    .zip([&state.x, &state.y, &state.heading, &state.speed])
            {
                channel.push(value.clone().reshape([n, 1]));
            }
        }
        Trajectory {
            channels: out.map(|c| Tensor::cat(c, 1)),
        }
    }

    /// Sum over windows and steps of the squared errors, each channel in metres (see the
    /// weights above), and the number of terms summed.
    pub fn loss_sum(&self, trajectory: &Trajectory) -> (Tensor<1>, usize) {
        let [x, y, h, v] = trajectory.channels.clone();
        let [rx, ry, rh, rv] = self.recorded.clone();
        let sq = |a: Tensor<2>, b: Tensor<2>| (a - b).powi_scalar(2).sum();
        let total = sq(x, rx)
            + sq(y, ry)
            + sq(h, rh).mul_scalar(HEADING_WEIGHT_M * HEADING_WEIGHT_M)
            + sq(v, rv).mul_scalar(SPEED_WEIGHT_S * SPEED_WEIGHT_S);
        (total, self.len() * self.steps)
    }

    /// Per-window, per-step errors on the host: (x, y, heading, speed) simulated minus
    /// recorded, and the recorded heading (to split position errors along/across track).
    pub fn errors(&self, trajectory: &Trajectory) -> Vec<Vec<StepError>> {
        let host = |t: Tensor<2>| -> Vec<f64> {
            t.to_data()
                .convert::<f64>()
                .try_into_vec::<f64>()
                .expect("f64 data")
        };
        let sim: Vec<Vec<f64>> = trajectory.channels.clone().map(host).into();
        let rec: Vec<Vec<f64>> = self.recorded.clone().map(host).into();
        (0..self.len())
            .map(|w| {
                (0..self.steps)
                    .map(|k| {
                        let i = w * self.steps + k;
                        let (dx, dy) = (sim[0][i] - rec[0][i], sim[1][i] - rec[1][i]);
                        let (sin, cos) = rec[2][i].sin_cos();
                        StepError {
                            along: dx * cos + dy * sin,
                            across: -dx * sin + dy * cos,
                            heading: sim[2][i] - rec[2][i],
                            speed: sim[3][i] - rec[3][i],
                            simulated: (sim[0][i], sim[1][i]),
                        }
                    })
                    .collect()
            })
            .collect()
    }
}

/// One step's error, position split along and across the recorded heading.
#[derive(Debug, Clone, Copy)]
pub struct StepError {
    pub along: f64,
    pub across: f64,
    pub heading: f64,
    pub speed: f64,
    /// Simulated position relative to the window's origin.
    pub simulated: (f64, f64),
}

impl StepError {
    pub fn position_sq(&self) -> f64 {
        self.along * self.along + self.across * self.across
    }
}

/// Raw vector → physical values `[1, 1]` each, in [`Candidate::specs`] order.
pub fn physical(candidate: &Candidate, raw: &Tensor<1>) -> Vec<Tensor<2>> {
    candidate
        .specs()
        .iter()
        .enumerate()
        .map(|(k, spec)| bounded(raw.clone().narrow(0, k, 1), spec).reshape([1, 1]))
        .collect()
}
