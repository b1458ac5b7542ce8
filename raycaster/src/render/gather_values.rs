//! The kernel of the compositors that read a sample's value and where it
//! lies on its ray, and a gradient at most now and then (maximum, average,
//! X-ray, first hit, Sabella's, and two-level scenes): eight samples of one
//! ray at a time, their positions, cells, corner reads and trilinear values in
//! SIMD lanes with hardware gathers ([`GatherBrick::chunk_values`], the scalar
//! kernel's bits), then each sample folded in order by the compositor's own
//! [`Compositor::sample`], with the stopping rule of the scalar loop.
//! Whatever else a compositor asks of a sample (the value before it, a
//! gradient at a refined hit, a two-level object's gradient at the sample:
//! [`SampleGradient::AtPosition`]) is read as the scalar loop reads it, a
//! function of the position, so the frames are bit-identical to the scalar
//! kernel's, which `tests/packet_kernel.rs` checks on every level.

use super::cell_cache::CellCache;
use super::compositor::{Compositor, SampleGradient};
use super::gather::{ChunkFolder, Chunked, GATHER_LANES, GatherBrick, LineAligned};
use super::march::{BrickVisit, fold_point};
use super::packet::PacketWork;
use super::pixel::SamplePositions;
use super::simd::SimdLevel;
use crate::volume::Sample;

/// Marches `work`'s rays with the value kernel at `level` when it has one
/// there (AVX2 or AVX-512, with gathers that can address the brick): `false`
/// leaves them to the scalar loop. Any compositor gets the scalar loop's
/// results; it pays for those whose [`Compositor::sample`] reads mostly the
/// sample's value, position, index, fraction and ray (a gradient at the
/// sample is read through the cell cache, which the gathers did not fill).
pub(crate) fn march_values<T: Sample, C: Compositor>(
    c: &C,
    work: &mut PacketWork<'_, '_, T, C::State>,
    level: SimdLevel,
) -> bool {
    let Some(gather) = GatherBrick::at_level(level, &work.brick.sampler, work.volume) else {
        return false;
    };
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
    unsafe {
        march_values_avx2(c, work, &gather)
    };
    #[cfg(not(target_arch = "x86_64"))]
    march_values_in_chunks(c, work, &gather);
    true
}

/// [`march_values_in_chunks`] compiled for AVX2.
///
/// # Safety
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2")]
unsafe fn march_values_avx2<T: Sample, C: Compositor>(
    c: &C,
    work: &mut PacketWork<'_, '_, T, C::State>,
    gather: &GatherBrick<'_>,
) {
    march_values_in_chunks(c, work, gather)
}

/// Each of the task's rays through the brick, its samples in chunks of
/// gathered values.
#[inline(always)]
fn march_values_in_chunks<T: Sample, C: Compositor>(
    c: &C,
    work: &mut PacketWork<'_, '_, T, C::State>,
    gather: &GatherBrick<'_>,
) {
    // For what a compositor reads beside the value (a gradient at a hit).
    let cell = CellCache::default();
    work.for_each_visit(
        #[inline(always)]
        |visit, item, state, counters| {
            visit.march(c, item.first, item.last, state, counters, || {
                Chunked(ValueRay {
                    c,
                    visit,
                    gather,
                    cell: &cell,
                    positions: visit.ray.positions(visit.volume.last()),
                })
            });
        },
    );
}

/// One ray's visit of a brick, its values gathered.
struct ValueRay<'v, 'b, T: Sample, C> {
    c: &'v C,
    visit: BrickVisit<'v, 'b, T>,
    gather: &'v GatherBrick<'b>,
    cell: &'v CellCache,
    positions: SamplePositions,
}

impl<T: Sample, C: Compositor> ChunkFolder<C::State> for ValueRay<'_, '_, T, C> {
    #[inline(always)]
    fn layout(&self) -> &GatherBrick<'_> {
        self.gather
    }

    /// Stops at the opacity threshold, or when the compositor is finished.
    #[inline(always)]
    fn chunk(&self, acc: &mut C::State, samples: &[u32; GATHER_LANES], n: usize) -> Option<usize> {
        let (plan, brick) = (self.visit.plan, self.visit.brick);
        let mut values = LineAligned([0f32; GATHER_LANES]);
        self.gather
            .chunk_values(&brick.sampler, &self.positions, samples, n, &mut values.0);
        let site = self.visit.site(self.cell);
        for (j, (&k, &value)) in samples.iter().zip(&values.0).take(n).enumerate() {
            let mut point = site.point(k, self.positions.at(k).into(), value);
            // (The cell cache never read this value.)
            point.gradient = SampleGradient::AtPosition;
            if fold_point(self.c, acc, &point, plan.ert_threshold) {
                return Some(j);
            }
        }
        None
    }
}
