//! The host-side picture of one step that rule-based drivers work from: every agent's box
//! centre, heading, speed and size, read back from the observation once per step.

pub use crate::agent_view::AgentView;
use crate::sim::Observation;

/// Every agent of every scene of a batch at the current step: `agents[b * n + i]`.
#[derive(Debug, Clone)]
pub struct Snapshot {
    pub batch: usize,
    pub agents_per_scene: usize,
    pub agents: Vec<AgentView>,
}

/// A tensor's values on the host as f64 (one read-back).
pub fn host_f64<const D: usize>(t: burn::Tensor<D>) -> Vec<f64> {
    t.to_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap_or_default()
}

impl Snapshot {
    /// Reads the newest frame of `obs` (one device read-back per tensor).
    pub fn from_observation(obs: &Observation) -> Snapshot {
        let [b, n, _] = obs.batch.agent_size.dims();
        let frame = obs
            .frames
            .last()
            .expect("a rollout always starts with the logged history");
        let poses = host_f64(frame.poses.clone());
        let size = host_f64(obs.batch.agent_size.clone());
        let present: Vec<bool> = frame
            .present
            .to_data()
            .try_into_vec_as::<bool>()
            .unwrap_or_default();
        let agents = (0..b * n)
            .map(|i| AgentView {
                x: poses[i * 4],
                y: poses[i * 4 + 1],
                heading: poses[i * 4 + 2],
                speed: poses[i * 4 + 3],
                length: size[i * 2],
                width: size[i * 2 + 1],
                present: present.get(i).copied().unwrap_or(false),
            })
            .collect();
        Snapshot {
            batch: b,
            agents_per_scene: n,
            agents,
        }
    }

    /// The agents of scene `b`.
    pub fn scene(&self, b: usize) -> &[AgentView] {
        let n = self.agents_per_scene;
        &self.agents[b * n..(b + 1) * n]
    }
}
