//! Every random draw of a run is reproducible from its seed: a stream per (seed, iteration,
//! purpose), a generator per scene, and the devices' global generator taken under one lock
//! while modules initialise.

use burn::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A seed for stream `stream` of iteration `iteration` (SplitMix64 of the three).
pub fn stream_seed(seed: u64, iteration: usize, stream: u64) -> u64 {
    let mut z = seed
        ^ (iteration as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `change` applied to each of `scenes` with a generator of its own, seeded by `seed`,
/// `iteration` and stream `stream + slot` (`slots`: each scene's position in its draw), so a
/// scene draws the same however its draw is batched, and a resumed run draws the same again.
pub fn seeded_per_scene<S, T>(
    scenes: &[&S],
    slots: &[usize],
    seed: u64,
    iteration: usize,
    stream: u64,
    change: impl Fn(&S, &mut ChaCha8Rng) -> T,
) -> Vec<T> {
    scenes
        .iter()
        .zip(slots)
        .map(|(scene, &slot)| {
            let mut rng =
                ChaCha8Rng::seed_from_u64(stream_seed(seed, iteration, stream + slot as u64));
            change(scene, &mut rng)
        })
        .collect()
}

/// Serialises seeding and initialisation through the devices' global RNG within a process.
pub(crate) static DEVICE_RNG: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs `make` (which should initialise modules and [`Materialise`] them) with `device`'s
/// global RNG seeded with `seed`, under a process lock, so parallel threads cannot interleave
/// their draws.
pub fn with_seeded_device<T>(device: &Device, seed: u64, make: impl FnOnce() -> T) -> T {
    let _guard = DEVICE_RNG.lock().unwrap_or_else(|p| p.into_inner());
    device.seed(seed);
    make()
}

/// Touches every parameter, so lazily initialised ones draw their values now.
pub struct Materialise;

impl burn::module::ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
        let _ = param.val();
    }
}
