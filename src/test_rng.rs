//! A tiny deterministic random source for unit tests (SplitMix64), so tests need no extra
//! dependency and always draw the same numbers.

/// Uniform in [lo, hi), advancing `state`.
pub(crate) fn uniform(state: &mut u64, lo: f64, hi: f64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    lo + (hi - lo) * (z >> 11) as f64 / (1u64 << 53) as f64
}
