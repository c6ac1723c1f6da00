//! RL-Shaped's reward term (paper appendix "Shaped reward"): 0.5 (C - delta) / C with
//! delta = |speed - speed limit|, C = 30 m/s, and the agent's episode ends once delta >= C.
//! The speed limit is the one of the lane the agent is on (the map's OpenDRIVE `<speed>`).

use super::config::ShapingConfig;
use crate::scene::Scene;

/// Speed limit (m/s) assumed where an agent is on no lane (off the map, between carriageways).
const FALLBACK_LIMIT: f64 = 130.0 / 3.6;

/// Per agent and transition t -> t+1, row-major `[B*N][T]`: the bonus and whether it ends the
/// episode. `speeds` is `[B, N, T+1]`, `poses` `[B, N, T+1, 3]` (centre x, y, heading); the
/// term is evaluated at the state reached, t + 1.
pub fn speed_shaping(
    scenes: &[&Scene],
    agents: usize,
    steps: usize,
    speeds: &[f32],
    poses: &[f32],
    config: &ShapingConfig,
) -> Vec<(f64, bool)> {
    let mut out = Vec::with_capacity(scenes.len() * agents * steps);
    for (b, scene) in scenes.iter().enumerate() {
        for i in 0..agents {
            let row = b * agents + i;
            for t in 0..steps {
                let k = row * (steps + 1) + t + 1;
                let p = &poses[k * 3..k * 3 + 3];
                let limit = scene
                    .map
                    .lane_projection([p[0] as f64, p[1] as f64], p[2] as f64)
                    .map_or(FALLBACK_LIMIT, |l| scene.map.lanes()[l.lane].speed_limit);
                out.push(shaping_term(speeds[k] as f64, limit, config));
            }
        }
    }
    out
}

/// The bonus at `speed` under `limit`, and whether it ends the episode.
pub fn shaping_term(speed: f64, limit: f64, config: &ShapingConfig) -> (f64, bool) {
    let delta = (speed - limit).abs();
    let c = config.tolerance;
    (config.weight * (c - delta) / c, delta >= c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bonus_is_half_at_the_limit_and_ends_thirty_off() {
        let c = ShapingConfig::default();
        assert_eq!(shaping_term(33.0, 33.0, &c), (0.5, false));
        let (bonus, end) = shaping_term(18.0, 33.0, &c);
        assert!((bonus - 0.25).abs() < 1e-12 && !end);
        assert_eq!(shaping_term(3.0, 33.0, &c), (0.0, true));
    }
}
