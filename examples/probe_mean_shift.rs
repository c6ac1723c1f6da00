//! `cargo run --release --example probe_mean_shift`: is the brake probe's answer within local
//! reach of the warm start? Collisions and off-road on 64 held-out brake draws when
//! `models/il_ff` drives its mean action with a constant added to the acceleration (0, -1, -2,
//! -3, -5 m/s^2). If small shifts do not lower the collisions, a sparse reward is flat around
//! the warm start and PPO's local search has nothing to climb.
use burn::prelude::*;
use rtr::data::{A9Dataset, TrafficStatistics, a9};
use rtr::model::{ActionMode, NetworkPolicy};
use rtr::scenario::rollout_with_heroes;
use rtr::scene::SceneBatch;
use rtr::sim::{Controls, MapCaches, Observation, Policy, RolloutConfig};
use rtr::train::probe::{ProbeTask, measure::parts, probe_scenarios};
use rtr::train::{TrainConfig, load_policy};

struct Shifted<'a> {
    inner: NetworkPolicy<'a>,
    shift: [f32; 2],
}
impl Policy for Shifted<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let c = self.inner.act(obs);
        Controls {
            accel: c.accel.add_scalar(self.shift[0]),
            steer: c.steer.add_scalar(self.shift[1]),
        }
    }
}

fn main() {
    let task = ProbeTask::Brake;
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
    let shifts: Vec<[f32; 2]> = vec![
        [0.0, 0.0],
        [-1.0, 0.0],
        [-2.0, 0.0],
        [-3.0, 0.0],
        [-5.0, 0.0],
    ];
    for shift in shifts {
        let mut caches = MapCaches::default();
        let (mut cars, mut col, mut off) = (0, 0, 0);
        for part in parts(&sets.eval, &scenes) {
            let batch = SceneBatch::from_scenes(&part.scenes, &device).unwrap();
            let mut p = Shifted {
                inner: NetworkPolicy::new(&policy, &batch, ActionMode::Mean),
                shift,
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
            "{task:?} shift {shift:?}: cars {cars}, collision {:.1} %, off-road {:.1} %",
            100.0 * col as f64 / cars as f64,
            100.0 * off as f64 / cars as f64
        );
    }
}
