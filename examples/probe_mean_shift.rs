//! `cargo run --release --example probe_mean_shift`: is the brake probe's answer within local
//! reach of the warm start? Collisions and off-road on 64 held-out brake draws when
//! `models/il_ff` drives its mean action with a constant added to the acceleration (0, -1, -2,
//! -3, -5 m/s^2). If small shifts do not lower the collisions, a sparse reward is flat around
//! the warm start and PPO's local search has nothing to climb. The same for recover with a
//! steering term -gain x (heading error to the nearest lane) added (gain 0 to 0.4).
use burn::prelude::*;
use rtr::data::{A9Dataset, TrafficStatistics, a9};
use rtr::model::{ActionMode, NetworkPolicy};
use rtr::sim::{Controls, Observation, Policy};
use rtr::train::probe::measure::{parts, rollout_outcomes};
use rtr::train::probe::{ProbeTask, probe_scenarios};
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

fn main() -> rtr::Result<()> {
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
        measure(task, &variants)?;
    }
    Ok(())
}

/// Per (acceleration shift, heading gain): collisions and off-road on 64 held-out draws.
fn measure(task: ProbeTask, variants: &[(f32, f64)]) -> rtr::Result<()> {
    let data = A9Dataset::load(&a9::default_dir()).unwrap();
    let stats = TrafficStatistics::from_recording(&data.recording, &data.map, 1.0);
    let sets = probe_scenarios(task, &stats, 1, 64, 7).unwrap();
    let scenes: Vec<_> = sets.eval.iter().map(|s| s.to_scene().unwrap()).collect();
    let config =
        TrainConfig::from_toml_file(std::path::Path::new("models/il_ff/config.toml")).unwrap();
    let device = rtr::backend::Backend::reference_device(false);
    let policy = load_policy(
        std::path::Path::new("models/il_ff/policy.bpk"),
        &config.model,
        &device,
    )
    .unwrap();
    let dynamics = config.dynamics(&device).unwrap();
    let eval = parts(&sets.eval, &scenes);
    for &(accel, heading_gain) in variants {
        let outcomes = rollout_outcomes(&eval, &dynamics, &device, |part, batch| {
            Box::new(Shifted {
                inner: NetworkPolicy::new(&policy, batch, ActionMode::Mean),
                accel,
                heading_gain,
                maps: part.scenes.iter().map(|s| s.map.clone()).collect(),
            })
        })
        .unwrap();
        rtr::outln!(
            "{task:?} accel shift {accel}, heading gain {heading_gain}: cars {}, collision {:.1} %, off-road {:.1} %",
            outcomes.cars,
            outcomes.pct(outcomes.collided),
            outcomes.pct(outcomes.offroad)
        )?;
    }
    rtr::io::console::check_stdout()
}
