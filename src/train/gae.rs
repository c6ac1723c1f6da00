//! Generalised advantage estimation (Schulman et al. 2016) for one agent's (or one scene's)
//! episode inside a rollout of T steps, with the paper's early termination: a step whose
//! successor is not alive ended the episode (infraction, exit or shaping termination), so
//! nothing is bootstrapped past it; an episode still alive at T is bootstrapped with V(s_T).
//! An agent that drives off the end of the map is a truncation, not a termination, when
//! `ppo.bootstrap_exits` is set: the caller passes the value it would have had in
//! `truncation_values`, so leaving the map earns nothing over staying on it.
//!
//! Plain f64 on the host: it is not differentiated, and T is small.

/// Advantages and value targets of one sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimates {
    pub advantages: Vec<f64>,
    /// advantage + value: the value network's regression target.
    pub returns: Vec<f64>,
}

/// `rewards[t]` for the transition t -> t+1 (T entries), `values[t]` = V(s_t) (T + 1 entries),
/// `alive[t]` = the agent acts at step t (T + 1 entries; `alive[T]`: still alive at the end),
/// `truncation_values[t]` (T entries) = value added to the next state's after transition t for
/// episodes cut there without being terminated (0 where none was; see the module doc).
/// Steps where the agent is not alive get advantage and return 0.
pub fn gae(
    rewards: &[f64],
    values: &[f64],
    alive: &[bool],
    truncation_values: &[f64],
    gamma: f64,
    lambda: f64,
) -> Estimates {
    let t_max = rewards.len();
    assert!(
        values.len() == t_max + 1 && alive.len() == t_max + 1 && truncation_values.len() == t_max,
        "gae: rewards {} need values and alive of {} entries and truncation values of {}, got \
         {}, {} and {}",
        t_max,
        t_max + 1,
        t_max,
        values.len(),
        alive.len(),
        truncation_values.len()
    );
    let mut advantages = vec![0.0; t_max];
    let mut returns = vec![0.0; t_max];
    let mut running = 0.0;
    for t in (0..t_max).rev() {
        if !alive[t] {
            running = 0.0;
            continue;
        }
        let continues = alive[t + 1];
        let next_value = if continues { values[t + 1] } else { 0.0 } + truncation_values[t];
        let delta = rewards[t] + gamma * next_value - values[t];
        // The running sum restarts at the last step of the rollout (bootstrapped) and after
        // the end of the episode.
        let carry = if continues && t + 1 < t_max {
            running
        } else {
            0.0
        };
        running = delta + gamma * lambda * carry;
        advantages[t] = running;
        returns[t] = running + values[t];
    }
    Estimates {
        advantages,
        returns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The textbook definition: A_t = sum_l (gamma lambda)^l delta_{t+l}, written out for a
    /// fully alive sequence bootstrapped at T.
    fn reference(rewards: &[f64], values: &[f64], gamma: f64, lambda: f64) -> Vec<f64> {
        let t_max = rewards.len();
        let delta: Vec<f64> = (0..t_max)
            .map(|t| rewards[t] + gamma * values[t + 1] - values[t])
            .collect();
        (0..t_max)
            .map(|t| {
                (t..t_max)
                    .map(|k| (gamma * lambda).powi((k - t) as i32) * delta[k])
                    .sum()
            })
            .collect()
    }

    #[test]
    fn matches_the_reference_sum_when_always_alive() {
        let rewards = [0.0, -1.0, 0.5, 0.0, -0.25];
        let values = [0.3, -0.2, 0.1, 0.4, -0.6, 0.9];
        for (gamma, lambda) in [(0.79, 1.0), (0.99, 0.95), (0.5, 0.0)] {
            let got = gae(&rewards, &values, &[true; 6], &[0.0; 5], gamma, lambda);
            let want = reference(&rewards, &values, gamma, lambda);
            for (g, w) in got.advantages.iter().zip(&want) {
                assert!((g - w).abs() < 1e-12, "{g} vs {w} (gamma {gamma})");
            }
            for (t, v) in values.iter().take(5).enumerate() {
                assert!((got.returns[t] - got.advantages[t] - v).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn lambda_one_gives_discounted_monte_carlo_returns() {
        // gamma 0.79, lambda 1 (paper): return_t = sum_k gamma^k r_{t+k} + gamma^(T-t) V(s_T).
        let rewards = [0.0, 0.0, -1.0];
        let values = [0.1, 0.2, 0.3, 0.7];
        let got = gae(&rewards, &values, &[true; 4], &[0.0; 3], 0.79, 1.0);
        let expect0 = -0.79f64.powi(2) + 0.79f64.powi(3) * 0.7;
        assert!((got.returns[0] - expect0).abs() < 1e-12);
    }

    #[test]
    fn termination_cuts_the_bootstrap_and_later_steps_count_nothing() {
        // Collides on the transition 1 -> 2: not alive from step 2 on.
        let rewards = [0.0, -1.0, 0.0, 0.0];
        let values = [-0.5, -0.8, 5.0, 5.0, 5.0];
        let alive = [true, true, false, false, false];
        let got = gae(&rewards, &values, &alive, &[0.0; 4], 0.79, 1.0);
        // Step 1 is terminal: A = r - V = -1 + 0.8; the huge values after it never leak in.
        assert!((got.advantages[1] - (-1.0 + 0.8)).abs() < 1e-12);
        assert!((got.advantages[0] - (-0.79 + 0.5)).abs() < 1e-12);
        assert_eq!(&got.advantages[2..], &[0.0, 0.0]);
        assert_eq!(&got.returns[2..], &[0.0, 0.0]);
    }

    #[test]
    fn a_truncated_episode_is_bootstrapped_with_the_value_it_leaves() {
        // Leaves the map on the transition 1 -> 2 without an infraction; the caller bootstraps
        // with V(s_1) = -0.8.
        let rewards = [0.0, 0.0, 0.0, 0.0];
        let values = [-0.5, -0.8, 5.0, 5.0, 5.0];
        let alive = [true, true, false, false, false];
        let cut = gae(&rewards, &values, &alive, &[0.0, -0.8, 0.0, 0.0], 0.9, 1.0);
        assert!((cut.advantages[1] - (0.9 * -0.8 + 0.8)).abs() < 1e-12);
        assert!((cut.returns[0] - 0.81 * -0.8).abs() < 1e-12);
        // As a termination (no truncation value) leaving earns -V(s_1) = +0.8 at step 1.
        let ended = gae(&rewards, &values, &alive, &[0.0; 4], 0.9, 1.0);
        assert!((ended.advantages[1] - 0.8).abs() < 1e-12);
        assert_eq!(&cut.advantages[2..], &[0.0, 0.0]);
    }
}
