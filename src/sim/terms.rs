//! The physics catalogue: terms the kinematic bicycle leaves out, each a [`DynamicsTerm`].
//!
//! Parameters are tensors (shape `[1, 1]`, broadcast over `[batch, agents]`), so sim-to-real
//! fits them by gradient descent through an unrolled rollout and training can load fitted
//! values as constants. Actuation terms are discretised exactly for a command held over the
//! control step; kinematic terms change the time derivative.

use burn::prelude::*;
use burn::tensor::activation::relu;

use super::dynamics::{Derivative, DynamicsTerm, TermInput};
use super::state::Controls;

/// A `[1, 1]` parameter tensor from a value.
pub fn parameter(value: f64, device: &Device) -> Tensor<2> {
    Tensor::from_data(
        burn::tensor::TensorData::new(vec![value as f32], [1, 1]),
        device,
    )
}

/// First-order lag with time constant `tau` on a control held at `u` over `dt`, starting
/// from `previous`: the value at the end of the step and the step average (what moves the
/// vehicle over the step). Exact for any `dt / tau`, so a small `tau` is never stiff.
fn first_order_lag(
    u: Tensor<2>,
    previous: Tensor<2>,
    tau: &Tensor<2>,
    dt: f64,
) -> (Tensor<2>, Tensor<2>) {
    let decay = tau.clone().recip().mul_scalar(-dt).exp();
    let gap = previous - u.clone();
    let end = u.clone() + gap.clone() * decay.clone();
    let mean_share = tau.clone() * (decay.neg().add_scalar(1.0)).div_scalar(dt);
    (end, u + gap * mean_share)
}

/// Which control a term acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    Accel,
    Steer,
}

impl Channel {
    fn of(self, controls: &Controls) -> Tensor<2> {
        match self {
            Channel::Accel => controls.accel.clone(),
            Channel::Steer => controls.steer.clone(),
        }
    }

    fn replaced(self, controls: Controls, value: Tensor<2>) -> Controls {
        match self {
            Channel::Accel => Controls {
                accel: value,
                ..controls
            },
            Channel::Steer => Controls {
                steer: value,
                ..controls
            },
        }
    }
}

/// Actuator response: the applied control follows the command with a first-order lag, time
/// constant `tau_s` (`accel_lag`: powertrain and brakes; `steer_lag`: steering actuator).
#[derive(Debug, Clone)]
pub struct FirstOrderLag {
    pub channel: Channel,
    pub tau_s: Tensor<2>,
}

impl DynamicsTerm for FirstOrderLag {
    fn name(&self) -> &str {
        match self.channel {
            Channel::Accel => "accel_lag",
            Channel::Steer => "steer_lag",
        }
    }
    fn memory_channels(&self) -> usize {
        1
    }
    fn init_memory(&self, applied: &Controls, _past: &[Controls]) -> Vec<Tensor<2>> {
        vec![self.channel.of(applied)]
    }
    fn actuate(
        &self,
        controls: Controls,
        memory: &[Tensor<2>],
        dt: f64,
    ) -> (Controls, Vec<Tensor<2>>) {
        let command = self.channel.of(&controls);
        let (end, mean) = first_order_lag(command, memory[0].clone(), &self.tau_s, dt);
        (self.channel.replaced(controls, mean), vec![end])
    }
}

/// Pure input delay of `delay_s` on both controls (sensing, computation, bus latency).
///
/// The delayed command held over a step is the average of the held commands over the
/// delayed interval, i.e. a linear interpolation between the two commands it straddles, so
/// the step is exact for held commands and differentiable in the delay.
#[derive(Debug, Clone)]
pub struct DeadTime {
    pub delay_s: Tensor<2>,
    /// Commands remembered (the longest delay representable is `slots * dt`).
    pub slots: usize,
}

impl DeadTime {
    /// A dead time able to represent delays up to `max_delay_s` at control step `dt`.
    pub fn new(delay_s: Tensor<2>, max_delay_s: f64, dt: f64) -> Self {
        Self {
            delay_s,
            slots: (max_delay_s / dt).ceil().max(1.0) as usize,
        }
    }
}

impl DynamicsTerm for DeadTime {
    fn name(&self) -> &str {
        "dead_time"
    }
    fn memory_channels(&self) -> usize {
        2 * self.slots
    }
    fn init_memory(&self, applied: &Controls, past: &[Controls]) -> Vec<Tensor<2>> {
        let at = |k: usize| past.get(k).or(past.last()).unwrap_or(applied);
        let accel = (0..self.slots).map(|k| at(k).accel.clone());
        let steer = (0..self.slots).map(|k| at(k).steer.clone());
        accel.chain(steer).collect()
    }
    fn actuate(
        &self,
        controls: Controls,
        memory: &[Tensor<2>],
        dt: f64,
    ) -> (Controls, Vec<Tensor<2>>) {
        let (accel_past, steer_past) = memory.split_at(self.slots);
        let position = self.delay_s.clone().div_scalar(dt);
        let weights: Vec<Tensor<2>> = (0..=self.slots)
            .map(|m| {
                relu(
                    position
                        .clone()
                        .sub_scalar(m as f64)
                        .abs()
                        .neg()
                        .add_scalar(1.0),
                )
            })
            .collect();
        let delayed = |now: Tensor<2>, past: &[Tensor<2>]| {
            let mut sum = now.clone() * weights[0].clone();
            for (m, value) in past.iter().enumerate() {
                sum = sum + value.clone() * weights[m + 1].clone();
            }
            let mut history = vec![now];
            history.extend(past[..self.slots - 1].iter().cloned());
            (sum, history)
        };
        let (accel, accel_memory) = delayed(controls.accel, accel_past);
        let (steer, steer_memory) = delayed(controls.steer, steer_past);
        let memory = accel_memory.into_iter().chain(steer_memory).collect();
        (Controls { accel, steer }, memory)
    }
}

/// Steering rate limit: per control step the road-wheel angle moves towards the command by
/// at most `rate_rad_s * dt` (smoothly saturated, `r tanh(x / r)`, so gradients never vanish).
#[derive(Debug, Clone)]
pub struct SteerRateLimit {
    pub rate_rad_s: Tensor<2>,
}

impl DynamicsTerm for SteerRateLimit {
    fn name(&self) -> &str {
        "steer_rate_limit"
    }
    fn memory_channels(&self) -> usize {
        1
    }
    fn init_memory(&self, applied: &Controls, _past: &[Controls]) -> Vec<Tensor<2>> {
        vec![applied.steer.clone()]
    }
    fn actuate(
        &self,
        controls: Controls,
        memory: &[Tensor<2>],
        dt: f64,
    ) -> (Controls, Vec<Tensor<2>>) {
        let previous = memory[0].clone();
        let reach = self.rate_rad_s.clone().mul_scalar(dt);
        let wanted = controls.steer - previous.clone();
        let steer = previous + (wanted / reach.clone()).tanh() * reach;
        let applied = Controls {
            accel: controls.accel,
            steer: steer.clone(),
        };
        (applied, vec![steer])
    }
}

/// Aerodynamic and rolling resistance: v' -= c_d v|v| + c_r sign(v).
#[derive(Debug, Clone)]
pub struct Drag {
    /// Aerodynamic coefficient (1/m).
    pub c_d: Tensor<2>,
    /// Rolling resistance (m/s^2).
    pub c_r: Tensor<2>,
}

impl DynamicsTerm for Drag {
    fn name(&self) -> &str {
        "drag"
    }
    fn derivative(&self, mut d: Derivative, input: &TermInput) -> Derivative {
        let v = input.state.speed.clone();
        let resistance =
            v.clone().abs() * v.clone() * self.c_d.clone() + v.sign() * self.c_r.clone();
        d.speed = d.speed - resistance;
        d
    }
}

/// Understeer: yaw rate = v tan(phi) / (L + k_us v^2), with k_us the understeer gradient in
/// rad per m/s^2 of lateral acceleration (steady-state cornering: phi = L / R + k_us a_y).
#[derive(Debug, Clone)]
pub struct Understeer {
    pub k_us: Tensor<2>,
}

impl DynamicsTerm for Understeer {
    fn name(&self) -> &str {
        "understeer"
    }
    fn derivative(&self, mut d: Derivative, input: &TermInput) -> Derivative {
        let v = input.state.speed.clone();
        let l = input.wheelbase.clone();
        let effective = l.clone() + v.clone() * v * self.k_us.clone();
        d.heading = d.heading * l / effective;
        d
    }
}

/// Sideslip of the reference point: the state is the centre of gravity, `lr_m` ahead of the
/// rear axle, so its velocity points at heading + beta, beta = atan(lr tan(phi) / L), and the
/// yaw rate is v cos(beta) tan(phi) / L (kinematic bicycle at the centre of gravity).
#[derive(Debug, Clone)]
pub struct Sideslip {
    pub lr_m: Tensor<2>,
}

impl DynamicsTerm for Sideslip {
    fn name(&self) -> &str {
        "sideslip"
    }
    fn derivative(&self, mut d: Derivative, input: &TermInput) -> Derivative {
        let tan = input.controls.steer.clone().tan();
        let beta = (tan * self.lr_m.clone() / input.wheelbase.clone()).atan();
        let direction = input.state.heading.clone() + beta.clone();
        let v = input.state.speed.clone();
        d.x = v.clone() * direction.clone().cos();
        d.y = v * direction.sin();
        d.heading = d.heading * beta.cos();
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::dynamics::{Dynamics, Integrator};
    use crate::sim::state::VehicleState;

    fn device() -> Device {
        crate::backend::Backend::reference_device(false)
    }

    fn scalar(v: f64) -> Tensor<2> {
        parameter(v, &device())
    }

    fn value(t: &Tensor<2>) -> f64 {
        t.to_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .expect("f64")[0]
    }

    fn state(speed: f64) -> VehicleState {
        VehicleState {
            x: scalar(0.0),
            y: scalar(0.0),
            heading: scalar(0.0),
            speed: scalar(speed),
            aux: Vec::new(),
        }
    }

    fn controls(accel: f64, steer: f64) -> Controls {
        Controls {
            accel: scalar(accel),
            steer: scalar(steer),
        }
    }

    fn plain(dt: f64) -> Dynamics {
        let mut d = Dynamics::bicycle(dt);
        d.limits = None;
        d
    }

    /// Speed after `steps` steps of `accel` held, from 20 m/s with no acceleration applied.
    fn speed_after(dynamics: &Dynamics, accel: f64, steps: usize) -> f64 {
        let w = scalar(2.8);
        let mut s = dynamics.init_aux(state(20.0), &controls(0.0, 0.0));
        for _ in 0..steps {
            s = dynamics.step(&s, &controls(accel, 0.0), &w);
        }
        value(&s.speed)
    }

    #[test]
    fn accel_lag_is_exact_for_a_held_step_at_any_dt() {
        let tau = 0.4;
        // Exact: v(t) = v0 + u (t - tau (1 - e^{-t/tau})).
        let exact = 20.0 + 2.0 * (1.0 - tau * (1.0 - (-1.0f64 / tau).exp()));
        for (dt, steps) in [(0.5, 2), (0.1, 10), (0.02, 50)] {
            let d = plain(dt).with_term(Box::new(FirstOrderLag {
                channel: Channel::Accel,
                tau_s: scalar(tau),
            }));
            let v = speed_after(&d, 2.0, steps);
            assert!((v - exact).abs() < 1e-4, "dt {dt}: {v} vs {exact}");
        }
    }

    #[test]
    fn dead_time_shifts_the_command_by_the_delay() {
        // 0.25 s delay at dt 0.1: the step accel arrives 2.5 steps late.
        let d = plain(0.1).with_term(Box::new(DeadTime::new(scalar(0.25), 1.0, 0.1)));
        let v = speed_after(&d, 1.0, 10);
        assert!((v - (20.0 + 1.0 * (1.0 - 0.25))).abs() < 1e-4, "{v}");
        assert_eq!(d.terms()[0].memory_channels(), 20);
    }

    #[test]
    fn steer_rate_limit_caps_the_angle_change_per_step() {
        let d = plain(0.1).with_term(Box::new(SteerRateLimit {
            rate_rad_s: scalar(0.2),
        }));
        let w = scalar(2.8);
        let mut s = d.init_aux(state(10.0), &controls(0.0, 0.0));
        s = d.step(&s, &controls(0.0, 0.3), &w);
        // Far beyond the reach of 0.02 rad: saturated at ~0.02.
        assert!((value(&s.aux[0]) - 0.02).abs() < 1e-4);
        // A tiny command passes almost unchanged.
        let mut s = d.init_aux(state(10.0), &controls(0.0, 0.0));
        s = d.step(&s, &controls(0.0, 0.001), &w);
        assert!((value(&s.aux[0]) - 0.001).abs() < 1e-5);
    }

    #[test]
    fn understeer_and_sideslip_change_the_turn_as_their_formulas_say() {
        let w = scalar(2.8);
        let (v, phi) = (20.0, 0.05);
        let yaw = |d: &Dynamics| {
            let s = d.step(
                &d.init_aux(state(v), &controls(0.0, phi)),
                &controls(0.0, phi),
                &w,
            );
            value(&s.heading) / d.dt
        };
        let under = plain(0.01).with_term(Box::new(Understeer {
            k_us: scalar(0.003),
        }));
        let expected = v * phi.tan() / (2.8 + 0.003 * v * v);
        assert!((yaw(&under) - expected).abs() < 1e-3 * expected);
        let slip = plain(0.01).with_term(Box::new(Sideslip { lr_m: scalar(1.4) }));
        let beta = (1.4 * phi.tan() / 2.8).atan();
        assert!((yaw(&slip) - v * beta.cos() * phi.tan() / 2.8).abs() < 1e-4);
        // The velocity points beta off the heading.
        let s = slip.step(
            &slip.init_aux(state(v), &controls(0.0, phi)),
            &controls(0.0, phi),
            &w,
        );
        assert!((value(&s.y).atan2(value(&s.x)) - beta).abs() < 2e-3);
    }

    #[test]
    fn midpoint_substeps_converge_on_a_circle() {
        // Constant steer: a circle of radius L / tan(phi); after a quarter turn the position
        // is (R, R). Euler at 0.5 s misses by metres, midpoint with substeps by millimetres.
        let (l, phi, v) = (2.8, 0.1f64, 10.0);
        let r = l / phi.tan();
        let quarter = std::f64::consts::FRAC_PI_2 * r / v;
        let error = |mut d: Dynamics, dt: f64| {
            d.dt = dt;
            let steps = (quarter / dt).round() as usize;
            let mut s = d.init_aux(state(v), &controls(0.0, phi));
            for _ in 0..steps {
                s = d.step(&s, &controls(0.0, phi), &scalar(l));
            }
            let t = steps as f64 * dt;
            let (ex, ey) = (r * (v * t / r).sin(), r * (1.0 - (v * t / r).cos()));
            ((value(&s.x) - ex).powi(2) + (value(&s.y) - ey).powi(2)).sqrt()
        };
        let euler = error(plain(0.5), 0.5);
        let mut mid = plain(0.1);
        mid.integrator = Integrator::Midpoint;
        mid.substeps = 2;
        let midpoint = error(mid, 0.1);
        assert!(
            euler > 0.5 && midpoint < 0.01,
            "euler {euler}, midpoint {midpoint}"
        );
    }
}
