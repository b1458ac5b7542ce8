//! Asking the system for memory before a large allocation, so that a refusal is
//! an error and not an abort in the allocator.

/// Allocations up to this size (bytes) are not asked for first: a refusal of
/// so little is the machine's end anyway, and freeing the probe makes glibc
/// serve later allocations up to its size from the heap, where zeroed memory
/// is zeroed by hand (about 2 instructions a pixel of a 256² frame).
const UNPROBED_BYTES: u64 = 64 << 20;

/// Whether the system gives `bytes` of memory: asked for and given back (for
/// sizes above 64 MiB; smaller ones count as given).
pub(crate) fn system_gives(bytes: u64) -> bool {
    if bytes <= UNPROBED_BYTES {
        return true;
    }
    usize::try_from(bytes).is_ok_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_sizes_are_given_and_impossible_ones_refused() {
        assert!(system_gives(1 << 20));
        assert!(system_gives(256 << 20));
        assert!(!system_gives(u64::MAX));
        assert!(!system_gives(1 << 62));
    }
}
