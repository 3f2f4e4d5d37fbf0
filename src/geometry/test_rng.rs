//! A tiny deterministic random source for tests: Marsaglia's xorshift64,
//! so a test's "random" cases are the same on every run and machine
//! without a dependency.

/// Uniform values in `[0, 1)` from xorshift64 started at `seed` (not 0).
pub(crate) fn unit_rng(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed;
    move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}
