//! `cargo run --release --example probe_mean_shift`: is the brake probe's answer within local
//! reach of the warm start? Collisions and off-road on 64 held-out brake draws when
//! `models/il_ff` drives its mean action with a constant added to the acceleration (0, -1, -2,
//! -3, -5 m/s^2). If small shifts do not lower the collisions, a sparse reward is flat around
//! the warm start and PPO's local search has nothing to climb. The same for recover with a
//! steering term -gain x (heading error to the nearest lane) added (gain 0 to 0.4).
use burn::prelude::*;
use rtr::data::{A9Dataset, TrafficStatistics, a9};
use rtr::model::{ActionMode, NetworkPolicy};
use rtr::scenario::rollout_with_heroes;
use rtr::scene::SceneBatch;
use rtr::sim::{Controls, MapCaches, Observation, Policy, RolloutConfig};
use rtr::train::probe::{ProbeTask, measure::parts, probe_scenarios};
use rtr::train::{TrainConfig, load_policy};

/// The network's mean action plus a constant acceleration and a steering term that turns
/// each car towards its lane's heading.
struct Shifted<'a> {
    inner: NetworkPolicy<'a>,
    accel: f32,
    heading_gain: f64,
    maps: Vec<std::sync::Arc<rtr::map::Map>>,
}
impl Policy for Shifted<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let c = self.inner.act(obs);
        let [b, n] = c.steer.dims();
        let poses: Vec<f32> = obs
            .frames
            .last()
            .unwrap()
            .poses
            .clone()
            .into_data()
            .convert::<f32>()
            .try_into_vec()
            .unwrap();
        let turn: Vec<f32> = (0..b * n)
            .map(|k| {
                let p = &poses[4 * k..4 * k + 4];
                let error = self.maps[k / n]
                    .lane_projection([p[0] as f64, p[1] as f64], p[2] as f64)
                    .map_or(0.0, |l| l.heading_error);
                (-self.heading_gain * error) as f32
            })
            .collect();
        let turn = Tensor::<2>::from_data(
            burn::tensor::TensorData::new(turn, [b, n]),
            &c.steer.device(),
        );
        Controls {
            accel: c.accel.add_scalar(self.accel),
            steer: c.steer + turn,
        }
    }
}

fn main() {
    for (task, variants) in [
        (
            ProbeTask::Brake,
            vec![
                (0.0, 0.0),
                (-1.0, 0.0),
                (-2.0, 0.0),
                (-3.0, 0.0),
                (-5.0, 0.0),
            ],
        ),
        (
            ProbeTask::Recover,
            vec![(0.0, 0.0), (0.0, 0.05), (0.0, 0.1), (0.0, 0.2), (0.0, 0.4)],
        ),
    ] {
        measure(task, &variants);
    }
}

/// Per (acceleration shift, heading gain): collisions and off-road on 64 held-out draws.
fn measure(task: ProbeTask, variants: &[(f32, f64)]) {
    let data = A9Dataset::load(&a9::default_dir()).unwrap();
    let stats = TrafficStatistics::from_recording(&data.recording, &data.map, 1.0);
    let sets = probe_scenarios(task, &stats, 1, 64, 7).unwrap();
    let scenes: Vec<_> = sets.eval.iter().map(|s| s.to_scene().unwrap()).collect();
    let config =
        TrainConfig::from_toml_file(std::path::Path::new("models/il_ff/config.toml")).unwrap();
    #[allow(deprecated)]
    let device = Device::ndarray();
    let policy = load_policy(
        std::path::Path::new("models/il_ff/policy.bpk"),
        &config.model,
        &device,
    )
    .unwrap();
    let dynamics = config.dynamics(&device).unwrap();
    for &(accel, heading_gain) in variants {
        let mut caches = MapCaches::default();
        let (mut cars, mut col, mut off) = (0, 0, 0);
        for part in parts(&sets.eval, &scenes) {
            let batch = SceneBatch::from_scenes(&part.scenes, &device).unwrap();
            let mut p = Shifted {
                inner: NetworkPolicy::new(&policy, &batch, ActionMode::Mean),
                accel,
                heading_gain,
                maps: part.scenes.iter().map(|s| s.map.clone()).collect(),
            };
            let out = rollout_with_heroes(
                &part.scenarios,
                &part.scenes,
                &batch,
                &dynamics,
                &mut p,
                &mut caches,
                &RolloutConfig {
                    steps: None,
                    early_termination: true,
                },
            )
            .unwrap();
            let [b, n, _] = out.simulated.dims();
            let sim: Vec<bool> = out
                .simulated
                .clone()
                .narrow(2, 0, 1)
                .reshape([b * n])
                .into_data()
                .try_into_vec_as::<bool>()
                .unwrap();
            let c: Vec<i64> = out
                .collision
                .clone()
                .int()
                .sum_dim(2)
                .reshape([b * n])
                .into_data()
                .convert::<i64>()
                .try_into_vec()
                .unwrap();
            let o: Vec<i64> = out
                .offroad
                .clone()
                .int()
                .sum_dim(2)
                .reshape([b * n])
                .into_data()
                .convert::<i64>()
                .try_into_vec()
                .unwrap();
            for k in 0..b * n {
                if sim[k] {
                    cars += 1;
                    col += (c[k] > 0) as usize;
                    off += (o[k] > 0) as usize;
                }
            }
        }
        println!(
            "{task:?} accel shift {accel}, heading gain {heading_gain}: cars {cars}, collision {:.1} %, off-road {:.1} %",
            100.0 * col as f64 / cars as f64,
            100.0 * off as f64 / cars as f64
        );
    }
}
