//! Float-to-integer truncation of values already clamped into a small range, in
//! one instruction.
//!
//! Rust's `as` casts saturate and map NaN to 0, which costs seven to thirteen
//! instructions on x86-64 (the range checks are emitted even where the value was
//! clamped just before: LLVM does not carry the range through `max`/`min`). Per
//! sample, the transfer table's index alone was 17 of the kernel's instructions
//! (callgrind, `docs/benchmarks.md` §5).

/// The largest bound [`truncate_clamped`] accepts: every integer up to it is an
/// `f32` and fits an `i32`.
pub(crate) const MAX_TRUNCATED: f32 = 16_777_216.0;

/// `x` clamped into `[0, hi]`, truncated toward zero: `x as u32` for `x` in that
/// range, 0 for NaN and below, `hi` above. `hi` must lie in `[0, MAX_TRUNCATED]`.
#[inline(always)]
#[allow(unsafe_code)] // measured: 1 instruction instead of 7-13; SAFETY note inside
pub(crate) fn truncate_clamped(x: f32, hi: f32) -> u32 {
    debug_assert!((0.0..=MAX_TRUNCATED).contains(&hi), "bound {hi}");
    // `max` returns the other operand for NaN, so `c` is a number in `[0, hi]`
    // (with an out-of-range `hi` still finite and below 2^31 after `min`).
    let c = x.max(0.0).min(hi.clamp(0.0, MAX_TRUNCATED));
    // SAFETY: `c` is finite and in `[0, 2^24]`, so its truncation is
    // representable as an `i32` — `to_int_unchecked`'s precondition.
    unsafe { c.to_int_unchecked::<i32>() as u32 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncation_equals_the_saturating_cast_inside_the_range_and_clamps_outside() {
        let hi = 4095.0;
        for x in [
            0.0,
            0.25,
            0.999_999_94,
            1.0,
            1.5,
            2047.5,
            4_094.999_8,
            4095.0,
            -0.0,
        ] {
            assert_eq!(truncate_clamped(x, hi), x as u32, "{x}");
        }
        assert_eq!(truncate_clamped(-3.5, hi), 0);
        assert_eq!(truncate_clamped(f32::NEG_INFINITY, hi), 0);
        assert_eq!(truncate_clamped(f32::NAN, hi), 0);
        assert_eq!(truncate_clamped(4095.5, hi), 4095);
        assert_eq!(truncate_clamped(f32::INFINITY, hi), 4095);
        assert_eq!(truncate_clamped(1e30, MAX_TRUNCATED), 16_777_216);
        let mut x = 0.0f32;
        while x < 5000.0 {
            assert_eq!(truncate_clamped(x, hi), (x as u32).min(4095), "{x}");
            x += 0.37;
        }
    }
}
