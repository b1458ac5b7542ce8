//! A tiny deterministic generator for the render module's unit tests.

/// Marsaglia's 32-bit xorshift from `seed` (non-zero): the same sequence on
/// every run and machine, so a failing case can be replayed.
pub(crate) fn xorshift32(mut seed: u32) -> impl FnMut() -> u32 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed
    }
}
