//! The kernel of the compositors that read a visible sample's value and
//! gradient (importance-aware, context-preserving, tone and silhouette, DVR
//! with a 2D transfer function, whose opacity depends on the gradient's
//! magnitude, and two-level scenes of shaded DVR objects): eight samples of
//! one ray at a time, their positions, cells, corner reads, trilinear values,
//! table indices and, for the visible ones, gradients in SIMD lanes with
//! hardware gathers ([`GatherRay::visible_gradients`], the scalar kernel's
//! bits, as DVR reads them); then each visible sample folded in order by the
//! compositor's own [`Compositor::sample`], its gradient handed over
//! ([`SampleGradient::Known`]), with the stopping rule of the scalar loop.
//!
//! A sample whose 1D table entry is transparent is left out: these
//! compositors composite nothing for it (with a 2D table too), leaving the
//! ray's state as it was (so the ray, below its threshold before, is below it
//! after). A two-level scene sees every sample
//! ([`march_gradients_every_sample`]). The frames are bit-identical to the
//! scalar kernel's, which `tests/packet_kernel.rs` checks on every level.

use glam::Vec3;

use super::cell_cache::CellCache;
use super::compositor::{Compositor, SampleGradient};
use super::gather::{ChunkFolder, Chunked, GATHER_LANES, GatherBrick, GatherRay, GradientLanes};
use super::march::{BrickVisit, fold_point};
use super::packet::PacketWork;
use super::simd::SimdLevel;
use super::transfer::{TABLE_SIZE, TransferTable};
use crate::volume::Sample;

/// Marches `work`'s rays with the gradient kernel at `level` when it has one
/// there (AVX2 or AVX-512, with gathers that can address the brick): `false`
/// leaves them to the scalar loop. For compositors whose
/// [`Compositor::sample`] composites nothing for a sample whose 1D entry in
/// `table` is transparent (a 2D table's opacity is that entry's scaled by
/// the gradient's factor, at most 1, so it is transparent too), and reads of
/// a visible one its value, position, index, fraction, ray and gradient
/// ([`SamplePoint::gradient`]), never the ray's cell cache as the last value
/// left it.
///
/// [`SamplePoint::gradient`]: super::compositor::SamplePoint::gradient
pub(crate) fn march_gradients<T: Sample, C: Compositor>(
    c: &C,
    table: &TransferTable,
    work: &mut PacketWork<'_, '_, T, C::State>,
    level: SimdLevel,
) -> bool {
    march_gradients_folding::<T, C, false>(c, table, work, level)
}

/// [`march_gradients`] for a compositor that must see every sample (a
/// two-level scene, where a transparent sample of another object closes a
/// segment): each is folded, the visible ones under `table` with their
/// gathered gradients, the others reading theirs through the cell cache if
/// they ask ([`SampleGradient::AtPosition`]).
pub(crate) fn march_gradients_every_sample<T: Sample, C: Compositor>(
    c: &C,
    table: &TransferTable,
    work: &mut PacketWork<'_, '_, T, C::State>,
    level: SimdLevel,
) -> bool {
    march_gradients_folding::<T, C, true>(c, table, work, level)
}

/// [`march_gradients`], folding every sample when `EVERY`.
fn march_gradients_folding<T: Sample, C: Compositor, const EVERY: bool>(
    c: &C,
    table: &TransferTable,
    work: &mut PacketWork<'_, '_, T, C::State>,
    level: SimdLevel,
) -> bool {
    if table.entries().len() != TABLE_SIZE {
        return false;
    }
    let Some(gather) = GatherBrick::at_level(level, &work.brick.sampler, work.volume) else {
        return false;
    };
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
    unsafe {
        march_gradients_avx2::<T, C, EVERY>(c, table, work, &gather)
    };
    #[cfg(not(target_arch = "x86_64"))]
    march_gradients_in_chunks::<T, C, EVERY>(c, table, work, &gather);
    true
}

/// [`march_gradients_in_chunks`] compiled for AVX2.
///
/// # Safety
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2")]
unsafe fn march_gradients_avx2<T: Sample, C: Compositor, const EVERY: bool>(
    c: &C,
    table: &TransferTable,
    work: &mut PacketWork<'_, '_, T, C::State>,
    gather: &GatherBrick<'_>,
) {
    march_gradients_in_chunks::<T, C, EVERY>(c, table, work, gather)
}

/// Each of the task's rays through the brick, its samples in chunks of
/// gathered values and gradients.
#[inline(always)]
fn march_gradients_in_chunks<T: Sample, C: Compositor, const EVERY: bool>(
    c: &C,
    table: &TransferTable,
    work: &mut PacketWork<'_, '_, T, C::State>,
    gather: &GatherBrick<'_>,
) {
    // For what a compositor reads beside the value and gradient.
    let cell = CellCache::default();
    work.for_each_visit(
        #[inline(always)]
        |visit, item, state, counters| {
            let ray = visit.ray;
            visit.march(c, item.first, item.last, state, counters, || {
                Chunked(GradientRay::<T, C, EVERY> {
                    c,
                    visit,
                    cell: &cell,
                    lanes: GatherRay {
                        brick: gather,
                        sampler: &visit.brick.sampler,
                        table,
                        positions: ray.positions(visit.volume.last()),
                        last_sample: ray.samples - 1,
                        last_fraction: ray.last_fraction,
                        ert_threshold: visit.plan.ert_threshold,
                        shade: None,
                        lights: (Vec3::ZERO, Vec3::ZERO),
                    },
                })
            });
        },
    );
}

/// One ray's visit of a brick, its values and gradients gathered.
struct GradientRay<'v, 'b, T: Sample, C, const EVERY: bool> {
    c: &'v C,
    visit: BrickVisit<'v, 'b, T>,
    cell: &'v CellCache,
    /// The gathers of the ray's samples (its chunks' lanes).
    lanes: GatherRay<'v, 'b, T>,
}

impl<T: Sample, C: Compositor, const EVERY: bool> ChunkFolder<C::State>
    for GradientRay<'_, '_, T, C, EVERY>
{
    #[inline(always)]
    fn layout(&self) -> &GatherBrick<'_> {
        self.lanes.brick
    }

    /// Stops at the opacity threshold, or when the compositor is finished.
    #[inline(always)]
    fn chunk(&self, acc: &mut C::State, samples: &[u32; GATHER_LANES], n: usize) -> Option<usize> {
        let mut lanes = GradientLanes::default();
        let visible = self
            .lanes
            .visible_gradients(self.visit.volume, samples, n, &mut lanes);
        let plan = self.visit.plan;
        let site = self.visit.site(self.cell);
        let g = &lanes.gradient;
        let gradient = |j: usize| {
            SampleGradient::Known(Vec3::new(g[0][j], g[1][j], g[2][j]) * plan.gradient_scale)
        };
        // Every sample in order, or the visible ones (the others composite
        // nothing).
        let mut lanes_left = if EVERY { (1u32 << n) - 1 } else { visible };
        while lanes_left != 0 {
            let j = lanes_left.trailing_zeros() as usize;
            lanes_left &= lanes_left - 1;
            let k = samples[j];
            let position = self.lanes.positions.at(k).into();
            let mut point = site.point(k, position, lanes.values[j]);
            point.gradient = if !EVERY || visible & (1 << j) != 0 {
                gradient(j)
            } else {
                SampleGradient::AtPosition
            };
            if fold_point(self.c, acc, &point, plan.ert_threshold) {
                return Some(j);
            }
        }
        None
    }
}
