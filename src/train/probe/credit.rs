//! Which control PPO's gradient reaches, and which way: on collected experience, the gradient
//! of the trainer's clipped surrogate (its advantages, standardisation, log-densities and
//! masks) with respect to every agent-step's mean action. Its negative is the direction one
//! optimizer step moves that mean; summed per car (a car's steps share one return, so cars
//! are the independent units) it gives a t statistic per control.

use burn::prelude::*;
use burn::tensor::Bool;

use super::super::config::PpoConfig;
use super::super::experience::Experience;
use super::super::ppo::{AdvantageScale, clipped_surrogate};
use crate::model::{ActionDistribution, PolicyNetwork};

/// The push of PPO's gradient on one control's mean, over the cars of some experience.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ControlPush {
    /// Mean over cars of each car's summed descent direction (control units per unit loss).
    pub mean: f64,
    /// `mean` over its standard error (cars as independent units).
    pub t: f64,
    pub cars: usize,
}

/// The descent direction of the surrogate on the mean acceleration and mean steering of
/// every car in `experiences`, as the trainer would standardise its advantages.
pub fn mean_action_push(
    policy: &PolicyNetwork,
    experiences: &[Experience],
    ppo: &PpoConfig,
) -> [ControlPush; 2] {
    let advantages: Vec<f32> = experiences
        .iter()
        .flat_map(|e| AdvantageScale::alive_values(e.advantages.clone(), e.alive.clone()))
        .collect();
    let scale = if ppo.normalize_advantages {
        AdvantageScale::of(&advantages)
    } else {
        AdvantageScale::IDENTITY
    };
    let mut per_car: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for e in experiences {
        let pushes = car_pushes(policy, e, ppo, scale);
        for (k, car) in pushes.iter().enumerate() {
            per_car[k].extend(car);
        }
    }
    per_car.map(|v| summarise(&v))
}

/// Per control, each alive car's summed descent direction on its mean action.
fn car_pushes(
    policy: &PolicyNetwork,
    e: &Experience,
    ppo: &PpoConfig,
    scale: AdvantageScale,
) -> [Vec<f64>; 2] {
    let encoded = policy.encode_lanes(&e.lanes);
    let dists: Vec<ActionDistribution> = e
        .observations
        .iter()
        .enumerate()
        .map(|(t, agents)| e.as_sampled(t, policy.forward(agents, &e.lanes, &encoded)))
        .collect();
    let advantages = e
        .advantages
        .clone()
        .sub_scalar(scale.mean)
        .div_scalar(scale.std.max(1e-8));
    let descent = surrogate_descent(
        &dists,
        &e.actions,
        e.old_log_prob.clone(),
        advantages,
        e.alive.clone(),
        e.explored,
        ppo.clip,
    );
    let [b, n, _] = e.old_log_prob.dims();
    let mut sums = vec![[0.0f64; 2]; b * n];
    for step in descent {
        let d: Vec<f32> = step
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap_or_default();
        for (i, sum) in sums.iter_mut().enumerate() {
            sum[0] += d[2 * i] as f64;
            sum[1] += d[2 * i + 1] as f64;
        }
    }
    let acted: Vec<bool> = e
        .alive
        .clone()
        .any_dim(2)
        .reshape([b * n])
        .into_data()
        .try_into_vec_as::<bool>()
        .unwrap_or_default();
    let pick = |k: usize| -> Vec<f64> {
        sums.iter()
            .zip(&acted)
            .filter(|(_, a)| **a)
            .map(|(s, _)| s[k])
            .collect()
    };
    [pick(0), pick(1)]
}

/// Per step, `[B, N, 2]`: minus the gradient of the clipped surrogate (summed over `alive`)
/// with respect to each agent's mean action, the means taken as leaves (`dists[t]` the
/// policy's distribution at step t, `actions[t]` the sampled actions, `[B, N, T]` the rest).
fn surrogate_descent(
    dists: &[ActionDistribution],
    actions: &[Tensor<3>],
    old_log_prob: Tensor<3>,
    advantages: Tensor<3>,
    alive: Tensor<3, Bool>,
    explored: [bool; 2],
    clip: f64,
) -> Vec<Tensor<3>> {
    let plain = old_log_prob.device();
    let device = plain.clone().autodiff();
    let to_graph = |t: Tensor<3>| Tensor::<3>::from_data(t.into_data(), &device);
    let mut means = Vec::with_capacity(dists.len());
    let mut log_probs = Vec::with_capacity(dists.len());
    for (dist, action) in dists.iter().zip(actions) {
        let mean = to_graph(dist.mean.clone()).require_grad();
        let leaf = ActionDistribution {
            mean: mean.clone(),
            log_std: to_graph(dist.log_std.clone()),
        };
        log_probs.push(leaf.log_prob_of(to_graph(action.clone()), explored));
        means.push(mean);
    }
    let surrogate = clipped_surrogate(
        Tensor::stack::<3>(log_probs, 2),
        to_graph(old_log_prob),
        to_graph(advantages),
        Tensor::<3, Bool>::from_data(alive.into_data(), &device),
        clip,
    );
    let grads = surrogate.loss.sum.backward();
    means
        .iter()
        .map(|mean| match mean.grad(&grads) {
            Some(g) => Tensor::<3>::from_data(g.neg().into_data(), &plain),
            None => Tensor::zeros(mean.dims(), &plain),
        })
        .collect()
}

fn summarise(values: &[f64]) -> ControlPush {
    let n = values.len();
    if n < 2 {
        return ControlPush {
            mean: values.first().copied().unwrap_or(0.0),
            t: 0.0,
            cars: n,
        };
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let se = (var / n as f64).sqrt();
    ControlPush {
        mean,
        t: if se > 0.0 { mean / se } else { 0.0 },
        cars: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t3(v: &[f32], device: &Device) -> Tensor<3> {
        Tensor::from_data(burn::tensor::TensorData::new(v.to_vec(), [1, 2, 1]), device)
    }

    /// At the old policy (ratio 1, inside the clip) the surrogate -sum A r has gradient
    /// -A (a - mu) / sigma^2 with respect to each explored control's mean, so the descent
    /// direction is A (a - mu) / sigma^2; an unexplored control and a terminated step get none.
    #[test]
    fn the_descent_direction_is_the_score_times_the_advantage() {
        let device = crate::backend::Backend::reference_device(false);
        let mean = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(vec![0.5f32, 0.01, -1.0, 0.0], [1, 2, 2]),
            &device,
        );
        let log_std = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(
                vec![0.0f32, (0.02f32).ln(), (2.0f32).ln(), 0.0],
                [1, 2, 2],
            ),
            &device,
        );
        let dist = ActionDistribution { mean, log_std };
        let action = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(vec![-0.5f32, 0.03, 1.0, 3.0], [1, 2, 2]),
            &device,
        );
        let old = dist.log_prob(action.clone()).unsqueeze_dim::<3>(2);
        let advantages = t3(&[2.0, -1.0], &device);
        let alive = Tensor::<3, Bool>::from_data(
            burn::tensor::TensorData::new(vec![true, true], [1, 2, 1]),
            &device,
        );
        let both = surrogate_descent(
            std::slice::from_ref(&dist),
            std::slice::from_ref(&action),
            old.clone(),
            advantages.clone(),
            alive.clone(),
            [true, true],
            0.2,
        );
        let d: Vec<f32> = both[0]
            .clone()
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .unwrap();
        // Agent 0: A = 2, (a - mu) / sigma^2 = -1 and 0.02 / 0.0004 = 50.
        // Agent 1: A = -1, (a - mu) / sigma^2 = 2 / 4 = 0.5 and 3.
        let want = [-2.0, 100.0, -0.5, -3.0];
        for (g, w) in d.iter().zip(want) {
            assert!(
                (*g as f64 - w).abs() < 1e-3 * w.abs().max(1.0),
                "{d:?} vs {want:?}"
            );
        }
        let old_accel = dist
            .log_prob_of(action.clone(), [true, false])
            .unsqueeze_dim::<3>(2);
        let dead = Tensor::<3, Bool>::from_data(
            burn::tensor::TensorData::new(vec![true, false], [1, 2, 1]),
            &device,
        );
        let accel_only = surrogate_descent(
            std::slice::from_ref(&dist),
            std::slice::from_ref(&action),
            old_accel,
            advantages,
            dead,
            [true, false],
            0.2,
        );
        let d: Vec<f32> = accel_only[0]
            .clone()
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .unwrap();
        assert!((d[0] + 2.0).abs() < 1e-4, "{d:?}");
        assert_eq!(&d[1..], &[0.0, 0.0, 0.0], "{d:?}");
    }

    #[test]
    fn t_statistic_of_a_known_sample() {
        // mean 2, sample sd 1 over 4 values: t = 2 / (1 / 2) = 4.
        let p = summarise(&[1.0, 2.0, 3.0, 2.0]);
        let sd = (2.0f64 / 3.0).sqrt();
        assert!((p.mean - 2.0).abs() < 1e-12);
        assert!((p.t - 2.0 / (sd / 2.0)).abs() < 1e-9, "{p:?}");
        assert_eq!(summarise(&[]).cars, 0);
    }
}
