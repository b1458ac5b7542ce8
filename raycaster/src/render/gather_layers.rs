//! The kernel of two-level scenes of value layers composited directly
//! ([`TwoLevel`] with every visible object plain, shaded DVR with a 1D
//! table): the plain DVR gather kernel's chunks
//! ([`GatherRay::chunk_shaded_with`]: positions, values, table indices and
//! the visible samples' gradients in SIMD lanes, Blinn-Phong in lanes, "over"
//! in order), each visible lane's colour and opacity taken from the table of
//! the layer its value lies in. The scalar loop folds the same samples
//! through [`TwoLevel`]'s `sample` (the layer's object's `Dvr`, the same
//! operations), so the frames are bit-identical to it, which
//! `tests/packet_kernel.rs` checks.

use std::cell::Cell;

use super::gather::{ChunkFolder, Chunked, GATHER_LANES, GatherBrick, GatherRay, GatherShading};
use super::packet::PacketWork;
use super::shading::Shading;
use super::simd::SimdLevel;
use super::transfer::{TABLE_SIZE, TransferTable};
use super::two_level::{NO_OBJECT, SegmentedState, TwoLevel};
use crate::volume::Sample;

/// Marches `work`'s rays of layer scene `scene` with `shading`, its samples
/// visible under `visible` (visible where any object's table is, or a
/// superset where the tables map values apart) in lanes, when `level` has
/// gathers that can address the brick: `false` leaves them to the scalar
/// loop.
pub(crate) fn march_shaded_layers<T: Sample>(
    scene: &TwoLevel,
    visible: &TransferTable,
    shading: Shading,
    work: &mut PacketWork<'_, '_, T, SegmentedState>,
    level: SimdLevel,
) -> bool {
    if visible.entries().len() != TABLE_SIZE {
        return false;
    }
    let Some(gather) = GatherBrick::at_level(level, &work.brick.sampler, work.volume) else {
        return false;
    };
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
    unsafe {
        march_layers_avx2(scene, visible, shading, work, &gather)
    };
    #[cfg(not(target_arch = "x86_64"))]
    march_layers_in_chunks(scene, visible, shading, work, &gather);
    true
}

/// [`march_layers_in_chunks`] compiled for AVX2.
///
/// # Safety
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2")]
unsafe fn march_layers_avx2<T: Sample>(
    scene: &TwoLevel,
    visible: &TransferTable,
    shading: Shading,
    work: &mut PacketWork<'_, '_, T, SegmentedState>,
    gather: &GatherBrick<'_>,
) {
    march_layers_in_chunks(scene, visible, shading, work, gather)
}

/// Each of the task's rays through the brick, its samples in chunks.
#[inline(always)]
fn march_layers_in_chunks<T: Sample>(
    scene: &TwoLevel,
    visible: &TransferTable,
    shading: Shading,
    work: &mut PacketWork<'_, '_, T, SegmentedState>,
    gather: &GatherBrick<'_>,
) {
    let shade = GatherShading::of_task(shading, work);
    work.for_each_visit(
        #[inline(always)]
        |visit, item, state, counters| {
            let ray = visit.ray;
            visit.march(scene, item.first, item.last, state, counters, || {
                Chunked(LayerRay {
                    scene,
                    shade: &shade,
                    lanes: GatherRay {
                        brick: gather,
                        sampler: &visit.brick.sampler,
                        table: visible,
                        positions: ray.positions(visit.volume.last()),
                        last_sample: ray.samples - 1,
                        last_fraction: ray.last_fraction,
                        ert_threshold: visit.plan.ert_threshold,
                        shade: Some(&shade),
                        lights: shading.ray_lights(ray.view_dir),
                    },
                })
            });
        },
    );
}

/// One ray's visit of a brick in a layer scene.
struct LayerRay<'v, 'a, T: Sample> {
    scene: &'v TwoLevel,
    shade: &'v GatherShading<'v, 'a, T>,
    /// The gathers of the ray's samples.
    lanes: GatherRay<'v, 'a, T>,
}

impl<T: Sample> ChunkFolder<SegmentedState> for LayerRay<'_, '_, T> {
    #[inline(always)]
    fn layout(&self) -> &GatherBrick<'_> {
        self.lanes.brick
    }

    /// Stops at the opacity threshold (the ray's one segment holds all it
    /// composited).
    #[inline(always)]
    fn chunk(
        &self,
        acc: &mut SegmentedState,
        samples: &[u32; GATHER_LANES],
        n: usize,
    ) -> Option<usize> {
        // Consecutive samples mostly lie in one layer: the last lane's is
        // tried first.
        let last = Cell::new(NO_OBJECT);
        let segment = acc.direct_segment();
        if self.scene.layers_per_lane() {
            // Objects of domains of their own: each lane's index, gradient
            // factor and fade.
            return self.lanes.chunk_shaded_per_lane(
                self.shade,
                segment,
                samples,
                n,
                |lanes, j| {
                    let (layer, entry, look) =
                        self.scene.layer_entry_own(lanes.values[j], last.get());
                    last.set(layer);
                    (entry, look)
                },
            );
        }
        self.lanes
            .chunk_shaded_with(self.shade, segment, samples, n, |lanes, j| {
                let (layer, entry) =
                    self.scene
                        .layer_entry(lanes.values[j], last.get(), lanes.indices[j] as usize);
                last.set(layer);
                entry
            })
    }
}
