//! Where eight consecutive samples of a ray lie in a brick's small cells, in
//! SIMD lanes: [`CellLocator::coordinates`] computed with AVX2 (the same
//! operations in the same order, so the same cells), the cells' visibility bits
//! gathered. The gather kernels take the visible samples from it
//! ([`LaneClassifier::append_visible`]); the run walker ([`super::runs`]) its
//! runs ([`LaneClassifier::classify`]). Elsewhere than on x86-64 with AVX2
//! there is none ([`LaneClassifier::new`] is `None`) and the walker places
//! samples by scalar code.

use super::gather::{GATHER_LANES, GatherBrick};
use super::runs::CellLocator;

/// Eight consecutive samples `k..k + 8` of a ray, classified.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LaneCells {
    /// The index of each sample's cell (in the grid's order).
    pub index: [u32; GATHER_LANES],
    /// Bit `j`: sample `k + j` lies in a visible cell.
    pub visible: u32,
    /// Bit `j`: sample `k + j` lies in another cell than sample `k + j − 1`
    /// (bit 0 always set).
    pub changes: u32,
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x86::LaneClassifier;

/// Off x86-64: none exists.
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Copy, Debug)]
pub(crate) struct LaneClassifier<'v> {
    never: std::convert::Infallible,
    _visible: std::marker::PhantomData<&'v [u32]>,
}

#[cfg(not(target_arch = "x86_64"))]
impl<'v> LaneClassifier<'v> {
    /// None off x86-64.
    #[inline(always)]
    pub(crate) fn new(_locator: &CellLocator, _visible: &'v [u32]) -> Option<Self> {
        None
    }

    /// No gather layout exists off x86-64.
    pub(crate) fn with_layout(
        layout: &GatherBrick<'_>,
        _locator: &CellLocator,
        _visible: &'v [u32],
    ) -> Self {
        let _ = layout;
        unreachable!("no gather layout off x86-64")
    }

    /// Never called: no classifier exists.
    pub(crate) fn classify(&self, _k: u32, _count: u32) -> LaneCells {
        match self.never {}
    }

    /// Never called: no classifier exists.
    pub(crate) fn append_visible(
        &self,
        _k: u32,
        _count: u32,
        _samples: &mut [u32; 2 * GATHER_LANES],
        _n: usize,
    ) -> usize {
        match self.never {}
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // measured: docs/benchmarks.md §5, twenty-fourth step
mod x86 {
    use std::arch::x86_64::*;

    use super::{CellLocator, GATHER_LANES, GatherBrick, LaneCells};

    /// The lane indices of each eight-bit mask's set bits, in order (the rest
    /// 0).
    static SET_BITS: [[u8; 8]; 256] = {
        let mut table = [[0u8; 8]; 256];
        let mut mask = 0;
        while mask < 256 {
            let (mut i, mut bit) = (0, 0);
            while bit < 8 {
                if mask & (1 << bit) != 0 {
                    table[mask][i] = bit as u8;
                    i += 1;
                }
                bit += 1;
            }
            mask += 1;
        }
        table
    };

    /// A ray's [`CellLocator`] in lanes, with its grid's visibility bits. It
    /// exists only on a CPU with AVX2. (It holds the locator's numbers, not
    /// their broadcasts: a walk's state is moved about, and eight `__m256`s
    /// made it a copy of 256 bytes per visit.)
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct LaneClassifier<'v> {
        visible: &'v [u32],
        locator: CellLocator,
    }

    impl<'v> LaneClassifier<'v> {
        /// The classifier of `locator`'s samples in the cells whose visibility
        /// bits are `visible` (one per cell); `None` where this CPU lacks AVX2.
        #[inline(always)]
        pub(crate) fn new(locator: &CellLocator, visible: &'v [u32]) -> Option<Self> {
            std::is_x86_feature_detected!("avx2").then(|| Self::made(locator, visible))
        }

        /// [`Self::new`] where a gather layout (which exists only on a CPU with
        /// AVX2) stands for the check.
        #[inline(always)]
        pub(crate) fn with_layout(
            _layout: &GatherBrick<'_>,
            locator: &CellLocator,
            visible: &'v [u32],
        ) -> Self {
            Self::made(locator, visible)
        }

        /// The classifier; only where the CPU has AVX2.
        #[inline(always)]
        fn made(locator: &CellLocator, visible: &'v [u32]) -> Self {
            debug_assert!(visible.len() * 32 >= (locator.per_axis as usize).pow(3));
            LaneClassifier {
                visible,
                locator: *locator,
            }
        }

        /// Samples `k..k + count` (`count ≤ 8`; the lanes past them are
        /// left out of `visible` and `changes`) classified.
        #[inline(always)]
        pub(crate) fn classify(&self, k: u32, count: u32) -> LaneCells {
            debug_assert!(count as usize <= GATHER_LANES);
            let mut cells = LaneCells::default();
            let lanes = (1u32 << count) - 1;
            // SAFETY: the CPU has AVX2 (this type exists); an unaligned store
            // of eight `u32`s into `cells.index`.
            unsafe {
                let (index, visible) = self.lanes(k);
                _mm256_storeu_si256(cells.index.as_mut_ptr().cast(), index);
                // Each lane against the one before (lane 0 against itself).
                let before =
                    _mm256_permutevar8x32_epi32(index, _mm256_setr_epi32(0, 0, 1, 2, 3, 4, 5, 6));
                let same = _mm256_cmpeq_epi32(index, before);
                let changes = !(_mm256_movemask_ps(_mm256_castsi256_ps(same)) as u32);
                cells.visible = visible & lanes;
                cells.changes = (changes | 1) & lanes;
            }
            cells
        }

        /// Appends to `samples[n..]` the samples of `k..k + count` (`count ≤ 8`,
        /// `n < 8`) that lie in visible cells, in order; how many.
        #[inline(always)]
        pub(crate) fn append_visible(
            &self,
            k: u32,
            count: u32,
            samples: &mut [u32; 2 * GATHER_LANES],
            n: usize,
        ) -> usize {
            debug_assert!(count as usize <= GATHER_LANES && n < GATHER_LANES);
            let n = n.min(GATHER_LANES);
            // SAFETY: the CPU has AVX2 (this type exists); the store writes
            // `samples[n..n + 8]`, a slice of eight.
            unsafe {
                let bits = self.lanes(k).1 & ((1u32 << count) - 1);
                let set = SET_BITS[bits as usize & 0xff];
                let lanes = _mm_loadl_epi64(set.as_ptr().cast());
                let at = _mm256_add_epi32(_mm256_cvtepu8_epi32(lanes), _mm256_set1_epi32(k as i32));
                _mm256_storeu_si256(samples[n..n + GATHER_LANES].as_mut_ptr().cast(), at);
                bits.count_ones() as usize
            }
        }

        /// The cell indices of samples `k..k + 8`, and bit `j` set where
        /// sample `k + j`'s cell is visible.
        ///
        /// # Safety
        /// The CPU has AVX2.
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn lanes(&self, k: u32) -> (__m256i, u32) {
            // `(k + j) as f32`, as `CellLocator` converts (exact below 2^24,
            // rounded alike above: sample indices are below 2^31).
            let kf = _mm256_cvtepi32_ps(_mm256_add_epi32(
                _mm256_set1_epi32(k as i32),
                _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            ));
            let l = &self.locator;
            let zero = _mm256_setzero_ps();
            let last_cell = _mm256_set1_ps(l.last_cell);
            let per_axis = _mm256_set1_epi32(l.per_axis as i32);
            let mut index = _mm256_setzero_si256();
            for a in 0..3 {
                let (base, slope) = (_mm256_set1_ps(l.base[a]), _mm256_set1_ps(l.slope[a]));
                let local = _mm256_add_ps(base, _mm256_mul_ps(slope, kf));
                // `truncate_clamped`: NaN and below 0 to 0 (`max` returns its
                // second operand for NaN), above the last cell to it.
                let clamped = _mm256_min_ps(_mm256_max_ps(local, zero), last_cell);
                let c = _mm256_cvttps_epi32(clamped);
                index = _mm256_add_epi32(_mm256_mullo_epi32(index, per_axis), c);
            }
            // SAFETY: every index is a cell of the grid (each coordinate
            // clamped into it), and `visible` holds a bit per cell.
            let words = unsafe {
                _mm256_i32gather_epi32::<4>(
                    self.visible.as_ptr().cast(),
                    _mm256_srli_epi32::<5>(index),
                )
            };
            let bits = _mm256_srlv_epi32(words, _mm256_and_si256(index, _mm256_set1_epi32(31)));
            let visible = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_slli_epi32::<31>(bits)));
            (index, visible as u32)
        }
    }
}
