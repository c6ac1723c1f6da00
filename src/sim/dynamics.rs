//! The kinematic bicycle model (paper appendix) as burn tensor ops, with a list of composable
//! physics terms on top, stepped by forward Euler at dt = 0.5 s.
//!
//!   x' = v cos(theta),  y' = v sin(theta),  theta' = v / L tan(phi),  v' = u
//!
//! Every operation is differentiable, so imitation gradients flow through an unrolled
//! rollout. Terms (drag, actuator lag, understeer, ...) change the controls before the
//! kinematics and/or the time derivative after it, and may keep extra state channels; the
//! rollout never needs to know which terms are present.

use std::fmt::Debug;

use burn::prelude::*;

use super::limits::ActionLimits;
use super::state::{Controls, VehicleState};

/// Time derivative of a [`VehicleState`].
#[derive(Debug, Clone)]
pub struct Derivative {
    pub x: Tensor<2>,
    pub y: Tensor<2>,
    pub heading: Tensor<2>,
    pub speed: Tensor<2>,
}

/// What a term sees of the current step.
pub struct TermInput<'a> {
    pub state: &'a VehicleState,
    /// Controls after limits and after the terms before this one.
    pub controls: &'a Controls,
    pub wheelbase: &'a Tensor<2>,
    /// This term's own extra state channels.
    pub aux: &'a [Tensor<2>],
    pub dt: f64,
}

/// A physics term added to the bicycle model.
pub trait DynamicsTerm: Debug + Send + Sync {
    /// Short name, used in reports (e.g. `drag`).
    fn name(&self) -> &str;

    /// Number of extra state channels the term keeps.
    fn aux_channels(&self) -> usize {
        0
    }

    /// Initial values of this term's extra state channels (`aux_channels` of them).
    fn init_aux(&self, _state: &VehicleState, _controls: &Controls) -> Vec<Tensor<2>> {
        Vec::new()
    }

    /// The controls the vehicle actually applies (actuator lag, dead time, ...).
    fn controls(&self, input: &TermInput) -> Controls {
        input.controls.clone()
    }

    /// Changes to the time derivative (drag, understeer, ...), and the derivative of this
    /// term's own channels (same order as `init_aux`).
    fn derivative(&self, d: Derivative, _input: &TermInput) -> (Derivative, Vec<Tensor<2>>) {
        (d, Vec::new())
    }
}

/// Bicycle model + limits + terms.
#[derive(Debug)]
pub struct Dynamics {
    pub dt: f64,
    pub limits: ActionLimits,
    terms: Vec<Box<dyn DynamicsTerm>>,
}

impl Dynamics {
    /// The paper's model: plain kinematic bicycle at `dt`.
    pub fn bicycle(dt: f64) -> Self {
        Self {
            dt,
            limits: ActionLimits::default(),
            terms: Vec::new(),
        }
    }

    pub fn with_term(mut self, term: Box<dyn DynamicsTerm>) -> Self {
        self.terms.push(term);
        self
    }

    pub fn terms(&self) -> &[Box<dyn DynamicsTerm>] {
        &self.terms
    }

    /// Adds every term's extra channels to a fresh state.
    pub fn init_aux(&self, mut state: VehicleState, controls: &Controls) -> VehicleState {
        state.aux.clear();
        let mut aux = Vec::new();
        for term in &self.terms {
            aux.extend(term.init_aux(&state, controls));
        }
        state.aux = aux;
        state
    }

    /// One Euler step under the commanded (raw, unlimited) controls.
    pub fn step(
        &self,
        state: &VehicleState,
        command: &Controls,
        wheelbase: &Tensor<2>,
    ) -> VehicleState {
        let mut controls = self.limits.apply(command);
        // Each term owns a contiguous slice of the aux channels, in order.
        let mut offsets = Vec::with_capacity(self.terms.len());
        let mut at = 0;
        for term in &self.terms {
            let n = term.aux_channels();
            offsets.push(at..at + n);
            at += n;
        }
        for (term, range) in self.terms.iter().zip(&offsets) {
            controls = term.controls(&TermInput {
                state,
                controls: &controls,
                wheelbase,
                aux: &state.aux[range.clone()],
                dt: self.dt,
            });
        }
        let (sin, cos) = (state.heading.clone().sin(), state.heading.clone().cos());
        let mut d = Derivative {
            x: state.speed.clone() * cos,
            y: state.speed.clone() * sin,
            heading: state.speed.clone() * controls.steer.clone().tan() / wheelbase.clone(),
            speed: controls.accel.clone(),
        };
        let mut daux = Vec::with_capacity(state.aux.len());
        for (term, range) in self.terms.iter().zip(&offsets) {
            let (next, own) = term.derivative(
                d,
                &TermInput {
                    state,
                    controls: &controls,
                    wheelbase,
                    aux: &state.aux[range.clone()],
                    dt: self.dt,
                },
            );
            d = next;
            daux.extend(own);
        }
        let dt = self.dt;
        VehicleState {
            x: state.x.clone() + d.x.mul_scalar(dt),
            y: state.y.clone() + d.y.mul_scalar(dt),
            heading: state.heading.clone() + d.heading.mul_scalar(dt),
            speed: state.speed.clone() + d.speed.mul_scalar(dt),
            aux: state
                .aux
                .iter()
                .zip(daux)
                .map(|(a, da)| a.clone() + da.mul_scalar(dt))
                .collect(),
        }
    }
}

/// Aerodynamic and rolling resistance: v' -= c_d v^2 + c_r (for forward motion).
#[derive(Debug, Clone)]
pub struct Drag {
    pub c_d: f64,
    pub c_r: f64,
}

impl DynamicsTerm for Drag {
    fn name(&self) -> &str {
        "drag"
    }

    fn derivative(&self, mut d: Derivative, input: &TermInput) -> (Derivative, Vec<Tensor<2>>) {
        let v = input.state.speed.clone();
        let resistance = v.clone().abs() * v.mul_scalar(self.c_d)
            + input.state.speed.clone().sign().mul_scalar(self.c_r);
        d.speed = d.speed - resistance;
        (d, Vec::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::state::VehicleState;

    #[allow(deprecated)]
    fn device() -> Device {
        Device::ndarray()
    }

    fn scalar(v: f64) -> Tensor<2> {
        Tensor::from_data(
            burn::tensor::TensorData::new(vec![v as f32], [1, 1]),
            &device(),
        )
    }

    fn value(t: &Tensor<2>) -> f64 {
        t.to_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .expect("f64")[0]
    }

    fn state(heading: f64, speed: f64) -> VehicleState {
        VehicleState {
            x: scalar(0.0),
            y: scalar(0.0),
            heading: scalar(heading),
            speed: scalar(speed),
            aux: Vec::new(),
        }
    }

    #[test]
    fn euler_step_matches_the_bicycle_equations() {
        let dynamics = Dynamics::bicycle(0.5);
        let s = state(0.3, 20.0);
        let c = Controls {
            accel: scalar(1.0),
            steer: scalar(0.05),
        };
        let next = dynamics.step(&s, &c, &scalar(2.8));
        let (u, phi) = (4.0 * (1.0f64 / 4.0).tanh(), 0.6 * (0.05f64 / 0.6).tanh());
        assert!((value(&next.x) - 20.0 * 0.3f64.cos() * 0.5).abs() < 1e-4);
        assert!((value(&next.y) - 20.0 * 0.3f64.sin() * 0.5).abs() < 1e-4);
        assert!((value(&next.heading) - (0.3 + 20.0 / 2.8 * phi.tan() * 0.5)).abs() < 1e-5);
        assert!((value(&next.speed) - (20.0 + u * 0.5)).abs() < 1e-5);
    }

    #[test]
    fn terms_compose_without_touching_the_rollout() {
        let plain = Dynamics::bicycle(0.5);
        let with_drag = Dynamics::bicycle(0.5).with_term(Box::new(Drag {
            c_d: 0.0004,
            c_r: 0.1,
        }));
        let s = state(0.0, 30.0);
        let c = Controls {
            accel: scalar(0.0),
            steer: scalar(0.0),
        };
        let w = scalar(2.8);
        let dv = value(&plain.step(&s, &c, &w).speed) - value(&with_drag.step(&s, &c, &w).speed);
        assert!((dv - (0.0004 * 900.0 + 0.1) * 0.5).abs() < 1e-5, "{dv}");
        assert_eq!(with_drag.terms()[0].name(), "drag");
    }
}
