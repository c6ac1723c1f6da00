//! What evaluation drives the controlled agents with: a trained policy network (its mean
//! action, or samples with seeded host noise for the realism score) or the IDM reference.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::driver::{IdmDriver, IdmParams};
use crate::model::{ActionMode, NetworkPolicy, PolicyNetwork};
use crate::scene::{Scene, SceneBatch};
use crate::sim::{ActionLimits, Controls, Observation, Policy};

/// Something that drives the controlled agents of a batch: a trained network or a baseline.
pub trait EvalPolicy: Sync {
    /// The deterministic policy (`noise = None`: the mean action), or one that samples its
    /// actions with host noise seeded by `noise` (deterministic policies ignore it).
    fn policy<'a>(
        &'a self,
        scenes: &[&Scene],
        batch: &SceneBatch,
        noise: Option<u64>,
    ) -> Box<dyn Policy + 'a>;
}

impl EvalPolicy for PolicyNetwork {
    fn policy<'a>(
        &'a self,
        _: &[&Scene],
        batch: &SceneBatch,
        noise: Option<u64>,
    ) -> Box<dyn Policy + 'a> {
        let mean = NetworkPolicy::new(self, batch, ActionMode::Mean);
        match noise {
            None => Box::new(mean),
            Some(seed) => Box::new(SampledPolicy {
                network: mean,
                rng: ChaCha8Rng::seed_from_u64(seed),
            }),
        }
    }
}

/// A network policy sampling mean + sigma * eps with eps from a seeded host generator, so
/// sampled evaluations repeat exactly however batches run in parallel.
struct SampledPolicy<'n> {
    network: NetworkPolicy<'n>,
    rng: ChaCha8Rng,
}

impl Policy for SampledPolicy<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let d = self.network.distribution(obs);
        let dims = d.mean.dims();
        let eps: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|_| StandardNormal.sample(&mut self.rng))
            .collect();
        let eps = burn::prelude::Tensor::<3>::from_data(
            burn::tensor::TensorData::new(eps, dims),
            &d.mean.device(),
        );
        Controls::from_stacked(d.mean + d.log_std.exp() * eps)
    }
}

/// The IDM + pure-pursuit lane keeper (a hand-written reference, not a learned method).
pub struct IdmBaseline {
    pub params: IdmParams,
    pub limits: ActionLimits,
}

impl EvalPolicy for IdmBaseline {
    fn policy<'a>(
        &'a self,
        scenes: &[&Scene],
        _: &SceneBatch,
        _: Option<u64>,
    ) -> Box<dyn Policy + 'a> {
        Box::new(IdmDriver::new(scenes, self.params, self.limits))
    }
}
