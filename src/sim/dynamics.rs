//! The kinematic bicycle model (paper appendix) as burn tensor ops, with a list of composable
//! physics terms on top.
//!
//!   x' = v cos(theta),  y' = v sin(theta),  theta' = v / L tan(phi),  v' = u
//!
//! Every operation is differentiable, so imitation gradients flow through an unrolled
//! rollout and sim-to-real can fit the terms' parameters by gradient descent. A term acts in
//! one or both of two places:
//! - **actuation**, once per control step: what the vehicle applies given the command (lags,
//!   dead time, rate limits), with memory channels carried in [`VehicleState::aux`]. These are
//!   discretised exactly for a command held over the step, so they stay right at any dt;
//! - **kinematics**, at every integrator evaluation: changes to the time derivative (drag,
//!   understeer, sideslip).
//!
//! **Standstill.** Speed never goes below zero: a vehicle braked to rest stays at rest instead
//! of integrating `v' = u` into reverse (no agent in traffic logs reverses). Every integrator
//! evaluation clamps the speed at 0, so the rule holds for policies, scripted heroes,
//! replayed logs and sim-to-real alike. Gradients through a moving vehicle are unchanged; at
//! rest under a braking command the speed's gradient is zero (more braking changes nothing),
//! and a pull-away command (`u > 0` from rest) gets the ordinary gradient.
//!
//! The paper steps forward Euler once per dt = 0.5 s ([`Dynamics::bicycle`]); sim-to-real
//! integrates with the midpoint rule and substeps, so integration error is not mistaken for
//! missing physics.

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

/// What a term sees when it changes the time derivative.
pub struct TermInput<'a> {
    pub state: &'a VehicleState,
    /// The controls applied over this control step (after limits and actuation terms).
    pub controls: &'a Controls,
    pub wheelbase: &'a Tensor<2>,
}

/// A physics term added to the bicycle model.
pub trait DynamicsTerm: Debug + Send + Sync {
    /// Short name, used in reports (e.g. `drag`).
    fn name(&self) -> &str;

    /// Number of memory channels the term keeps between control steps.
    fn memory_channels(&self) -> usize {
        0
    }

    /// Memory at the start: `applied` is the control the vehicle is applying now (estimated
    /// from its motion where known, else the first command); `past` the commands before the
    /// start, newest first (may be empty).
    fn init_memory(&self, _applied: &Controls, _past: &[Controls]) -> Vec<Tensor<2>> {
        Vec::new()
    }

    /// Once per control step: the controls passed on (held over the step) and the new
    /// memory, given the incoming controls and this term's memory.
    fn actuate(
        &self,
        controls: Controls,
        _memory: &[Tensor<2>],
        _dt: f64,
    ) -> (Controls, Vec<Tensor<2>>) {
        (controls, Vec::new())
    }

    /// Changes to the time derivative.
    fn derivative(&self, d: Derivative, _input: &TermInput) -> Derivative {
        d
    }
}

/// How the kinematics are integrated over one control step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrator {
    /// Forward Euler (the paper).
    Euler,
    /// Explicit midpoint rule (second order).
    Midpoint,
}

/// Bicycle model + limits + terms.
#[derive(Debug)]
pub struct Dynamics {
    /// Control step (s): commands are held for this long.
    pub dt: f64,
    /// Smooth command limits; `None` passes commands through (recorded vehicle commands).
    pub limits: Option<ActionLimits>,
    pub integrator: Integrator,
    /// Integrator steps per control step.
    pub substeps: usize,
    terms: Vec<Box<dyn DynamicsTerm>>,
}

impl Dynamics {
    /// The paper's model: plain kinematic bicycle, one Euler step per `dt`.
    pub fn bicycle(dt: f64) -> Self {
        Self {
            dt,
            limits: Some(ActionLimits::default()),
            integrator: Integrator::Euler,
            substeps: 1,
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

    /// Adds every term's memory channels to a fresh state, assuming `controls` were being
    /// applied and commanded before the start.
    pub fn init_aux(&self, state: VehicleState, controls: &Controls) -> VehicleState {
        self.init_with_history(state, controls, &[])
    }

    /// As [`Dynamics::init_aux`], with the commands before the start (newest first).
    pub fn init_with_history(
        &self,
        mut state: VehicleState,
        applied: &Controls,
        past: &[Controls],
    ) -> VehicleState {
        state.aux = self
            .terms
            .iter()
            .flat_map(|term| term.init_memory(applied, past))
            .collect();
        state
    }

    /// One control step under the commanded (raw) controls.
    pub fn step(
        &self,
        state: &VehicleState,
        command: &Controls,
        wheelbase: &Tensor<2>,
    ) -> VehicleState {
        let mut controls = match &self.limits {
            Some(limits) => limits.apply(command),
            None => command.clone(),
        };
        // Each term owns a contiguous slice of the memory channels, in order.
        let mut memory = Vec::with_capacity(state.aux.len());
        let mut at = 0;
        for term in &self.terms {
            let n = term.memory_channels();
            let (applied, own) = term.actuate(controls, &state.aux[at..at + n], self.dt);
            debug_assert_eq!(own.len(), n, "{} returned wrong memory", term.name());
            controls = applied;
            memory.extend(own);
            at += n;
        }
        let h = self.dt / self.substeps.max(1) as f64;
        let mut next = VehicleState {
            aux: Vec::new(),
            ..state.clone()
        };
        for _ in 0..self.substeps.max(1) {
            next = match self.integrator {
                Integrator::Euler => {
                    let d = self.derivative(&next, &controls, wheelbase);
                    advance(&next, &d, h)
                }
                Integrator::Midpoint => {
                    let d = self.derivative(&next, &controls, wheelbase);
                    let half = advance(&next, &d, h / 2.0);
                    let d = self.derivative(&half, &controls, wheelbase);
                    advance(&next, &d, h)
                }
            };
        }
        next.aux = memory;
        next
    }

    fn derivative(
        &self,
        state: &VehicleState,
        controls: &Controls,
        wheelbase: &Tensor<2>,
    ) -> Derivative {
        let (sin, cos) = (state.heading.clone().sin(), state.heading.clone().cos());
        let mut d = Derivative {
            x: state.speed.clone() * cos,
            y: state.speed.clone() * sin,
            heading: state.speed.clone() * controls.steer.clone().tan() / wheelbase.clone(),
            speed: controls.accel.clone(),
        };
        let input = TermInput {
            state,
            controls,
            wheelbase,
        };
        for term in &self.terms {
            d = term.derivative(d, &input);
        }
        d
    }
}

/// One explicit step of length `h`, with the standstill rule (speed clamped at 0).
fn advance(state: &VehicleState, d: &Derivative, h: f64) -> VehicleState {
    VehicleState {
        x: state.x.clone() + d.x.clone().mul_scalar(h),
        y: state.y.clone() + d.y.clone().mul_scalar(h),
        heading: state.heading.clone() + d.heading.clone().mul_scalar(h),
        speed: (state.speed.clone() + d.speed.clone().mul_scalar(h)).clamp_min(0.0),
        aux: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::state::VehicleState;
    use crate::sim::terms::Drag;
    use burn::tensor::TensorData;

    fn device() -> Device {
        crate::backend::Backend::reference_device(false)
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
            c_d: scalar(0.0004),
            c_r: scalar(0.1),
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

    fn braking(accel: f64) -> Controls {
        Controls {
            accel: scalar(accel),
            steer: scalar(0.0),
        }
    }

    #[test]
    fn a_vehicle_braked_to_rest_stays_at_rest() {
        // 3 m/s at 4 m/s^2 stops within 1.125 m; one Euler step per 0.5 s moves 1.5 + 0.5 m.
        for (integrator, substeps, stop_m) in [
            (Integrator::Euler, 1, 2.0),
            (Integrator::Midpoint, 5, 1.125),
        ] {
            let mut dynamics = Dynamics::bicycle(0.5);
            dynamics.limits = None;
            dynamics.integrator = integrator;
            dynamics.substeps = substeps;
            let mut s = state(0.0, 3.0);
            let mut last_x = 0.0;
            for step in 0..6 {
                s = dynamics.step(&s, &braking(-4.0), &scalar(2.8));
                let (x, v) = (value(&s.x), value(&s.speed));
                assert!(v >= 0.0, "{integrator:?} step {step}: speed {v}");
                assert!(
                    x >= last_x,
                    "{integrator:?} step {step}: rolled back {last_x} -> {x}"
                );
                last_x = x;
            }
            assert_eq!(value(&s.speed), 0.0);
            assert!((last_x - stop_m).abs() < 0.03, "{integrator:?}: {last_x}");
        }
    }

    #[test]
    fn gradients_through_moving_vehicles_are_unchanged_and_vanish_when_braking_at_rest() {
        let device = crate::backend::Backend::NdArray
            .device(true)
            .expect("ndarray device");
        let leaf = |v: f64| {
            Tensor::<2>::from_data(TensorData::new(vec![v as f32], [1, 1]), &device).require_grad()
        };
        let constant =
            |v: f64| Tensor::<2>::from_data(TensorData::new(vec![v as f32], [1, 1]), &device);
        let mut dynamics = Dynamics::bicycle(0.5);
        dynamics.limits = None;
        // d v' / d u = dt while moving, 0 when the command would reverse a vehicle at rest,
        // dt again for a pull-away from rest.
        for (speed, accel, expected) in [(10.0, -2.0, 0.5), (0.0, -2.0, 0.0), (0.0, 1.0, 0.5)] {
            let u = leaf(accel);
            let s = VehicleState {
                x: constant(0.0),
                y: constant(0.0),
                heading: constant(0.0),
                speed: constant(speed),
                aux: Vec::new(),
            };
            let c = Controls {
                accel: u.clone(),
                steer: constant(0.0),
            };
            let next = dynamics.step(&s, &c, &constant(2.8));
            let grads = next.speed.sum().backward();
            let g = u
                .grad(&grads)
                .expect("gradient")
                .into_data()
                .try_to_vec::<f32>()
                .unwrap()[0];
            assert!(
                (g as f64 - expected).abs() < 1e-6,
                "v {speed}, u {accel}: {g}"
            );
        }
    }
}
