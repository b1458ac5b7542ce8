//! The DVR kernel with hardware gathers (AVX2 and AVX-512, x86-64): eight
//! samples of one ray at a time (filled across its runs), their positions,
//! cells, corner reads, trilinear values and transfer-table indices in eight
//! SIMD lanes; when shading, the visible samples' gradients too (the central
//! differences at their cells' corners from the 32-voxel neighbourhood,
//! gathered, then interpolated) and Blinn-Phong in lanes; then the "over"
//! steps in order.
//!
//! The 4-lane kernel ([`super::packet`]) shares each voxel cell's corners and
//! differences between the samples in it through the
//! [`super::cell_cache::CellCache`]; its bookkeeping (finding the samples of one
//! cell, entering a cell) costs more than the reads it saves. Here every lane
//! reads its own cell with one gather per voxel (`vpgatherdd`: four bytes at
//! each lane's byte offset, the voxel in their low bytes), so a chunk has no
//! branch per cell. Samples whose cell's neighbourhood leaves the brick take
//! the scalar kernel's gradient, lane by lane.
//!
//! Every operation is the scalar kernel's, in its order (positions as
//! [`super::pixel::SamplePositions::at`], the value as
//! [`super::sampler::trilinear`], the index as
//! [`super::transfer::TransferTable::index`], no fused multiply-adds), so the
//! frames are bit-identical to the scalar kernel's, which
//! `tests/packet_kernel.rs` checks on every level.

// The gathers run on x86-64 only: elsewhere `GatherBrick::new` returns `None`,
// so this module is compiled and type-checked there but never reached, and
// the branches that call into `x86` are `unreachable!`.
#![cfg_attr(
    not(target_arch = "x86_64"),
    allow(
        dead_code,
        unused_imports,
        unused_mut,
        unused_variables,
        unreachable_code,
        clippy::diverging_sub_expression
    )
)]

use glam::{Vec3, Vec3A, Vec4};

use super::cell_lanes::LaneClassifier;
use super::compositor::Compositor;
use super::local::Accumulation;
use super::march::{RunMarcher, march_each_run};
use super::optics::{over, over_sample, whole_exponent};
use super::packet::PacketWork;
use super::pixel::SamplePositions;
use super::runs::{SampleRuns, SampleWalk};
use super::sampler::{BrickSampler, CornerDifferences, VolumeSampler, gradient_from_differences};
use super::shading::Shading;
use super::simd::SimdLevel;
use super::transfer::TransferTable;
use crate::volume::Sample;

/// The kernel reads the table's visibility bits as four 256-bit registers.
const _: () = assert!(super::transfer::TABLE_SIZE == 1024);

/// Samples per chunk.
pub(crate) const GATHER_LANES: usize = 8;

/// The most bytes a gather addresses from one base (a source's length, its
/// shift, a read's reach above a cell), so that every sum of them stays far
/// inside `i32` (three of them: under 2^31). Bricks beyond it take the 4-lane
/// kernel.
const MAX_GATHER_BYTES: usize = 1 << 29;

/// Bytes the gathers read: a slice, where a brick-local byte offset lies in
/// it, and the last offset a four-byte read may start at.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GatherSource<'a> {
    bytes: &'a [u8],
    /// Added to a brick-local byte offset to address `bytes`.
    shift: i32,
    /// Offsets (into `bytes`) above this read past its end as four bytes.
    last_whole_read: i32,
}

impl<'a> GatherSource<'a> {
    /// `bytes` addressed from byte `shift` on; `None` for over
    /// [`MAX_GATHER_BYTES`] or under eight bytes.
    fn new(bytes: &'a [u8], shift: usize) -> Option<Self> {
        if !(8..=MAX_GATHER_BYTES).contains(&bytes.len()) || shift > MAX_GATHER_BYTES {
            return None;
        }
        Some(GatherSource {
            bytes,
            shift: shift as i32,
            last_whole_read: bytes.len() as i32 - 4,
        })
    }
}

/// What the gathers address in one brick: its samples as bytes, the byte
/// offsets of a cell's corners, and where the 4×4×4 neighbourhoods of cells for
/// gradients are read.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GatherBrick<'a> {
    /// The brick's samples, from its first voxel to its last.
    samples: GatherSource<'a>,
    /// Byte strides per axis.
    strides: [i32; 3],
    /// Byte offsets of a cell's eight corners from its lower one, in
    /// [`super::sampler::Corners`] order.
    corners: [i32; 8],
    origin: [f32; 3],
    max_cell: [f32; 3],
    /// The samples around the brick's cells, for gradients: the volume's
    /// around the brick (so that only the volume's face cells lack a
    /// neighbourhood), or the brick's own (a logical sub-brick of bricked
    /// storage, or more than a gather addresses around it).
    neighbourhoods: GatherSource<'a>,
    /// Per axis, what a read one voxel beyond the brick's upper face adds to
    /// its in-brick byte offset, and one below its lower face takes away: 0
    /// for linear storage, the brick stride less `side − 1` voxel strides for
    /// stored bricks.
    wrap: [i32; 3],
    /// The farthest a neighbourhood read lies above its cell's lower corner,
    /// in bytes: two voxels per axis and the wraps.
    reach: i32,
    /// The lower cell corners (brick-local) whose neighbourhood lies in
    /// `neighbourhoods`, per axis from `interior[0]` to `interior[1]`.
    interior: [[f32; 3]; 2],
}

impl<'a> GatherBrick<'a> {
    /// The gather layout of `sampler`'s brick of `volume`, or `None` where a
    /// gather cannot address it (offsets beyond `i32`, a brick of under eight
    /// bytes) or this CPU lacks AVX2.
    pub(crate) fn new<T: Sample>(
        sampler: &BrickSampler<'a, T>,
        volume: &VolumeSampler<'a, T>,
    ) -> Option<Self> {
        if !has_avx2() {
            return None;
        }
        let size = std::mem::size_of::<T>();
        let (samples, strides, corner_strides, extent) = sampler.addressing();
        let to_i32 = |v: usize| i32::try_from(v).ok();
        let byte_strides = strides.map(|s| s * size);
        // z is the samples' fastest axis, one sample apart: the kernel reads
        // two or four z-neighbours with one gather.
        if byte_strides[2] != size {
            return None;
        }
        // From the first voxel to the last (a linear volume's view runs on to
        // the volume's end).
        let last_voxel: usize = (0..3)
            .map(|a| (extent[a] as usize - 1) * byte_strides[a])
            .sum();
        let bytes: &[u8] = bytemuck::cast_slice(samples);
        let brick_bytes = bytes.get(..last_voxel + size)?;
        let brick_source = GatherSource::new(brick_bytes, 0)?;
        let [ox, oy, oz] = corner_strides.map(|s| s * size);
        let corners = [0, oz, oy, oy + oz, ox, ox + oz, ox + oy, ox + oy + oz];
        let max_cell = sampler.max_cell_lanes().to_array();
        let origin = sampler.origin_voxel();
        // The volume's samples around the brick: where the brick starts in
        // them, how far a neighbourhood read reaches beyond it (one voxel, or
        // into the next stored brick, per axis), and the wrap across faces.
        let around = match (volume.whole(), volume.stored_brick_layout(sampler)) {
            (Some(whole), _) => {
                let at: usize = (0..3).map(|a| origin[a] as usize * strides[a]).sum();
                Some((whole.addressing().0, at, strides, [0; 3]))
            }
            (None, Some((samples, at, wrap))) => {
                let reach = [0, 1, 2].map(|a| wrap[a] + extent[a] as usize * strides[a]);
                Some((samples, at, reach, wrap))
            }
            (None, None) => None,
        };
        // The source of the volume around the brick, where a gather can
        // address it.
        let volume_source = around.and_then(|(samples, at, reach, wrap)| {
            let all: &[u8] = bytemuck::cast_slice(samples);
            let (at, reach) = (at * size, reach.iter().sum::<usize>() * size);
            let start = at.saturating_sub(reach);
            let end = (at + last_voxel + size + reach).min(all.len());
            let source = GatherSource::new(&all[start..end], at - start)?;
            let wrap = [
                to_i32(wrap[0] * size)?,
                to_i32(wrap[1] * size)?,
                to_i32(wrap[2] * size)?,
            ];
            Some((source, wrap))
        });
        let (neighbourhoods, wrap, interior) = match volume_source {
            Some((source, wrap)) => {
                let inner = volume.last_inner_cell();
                let lo = origin.map(|o| 1.0 - o as f32);
                let hi = [0, 1, 2].map(|a| inner[a] as f32 - origin[a] as f32);
                (source, wrap, [lo, hi])
            }
            // A sub-brick of bricked storage, or a volume too large around
            // the brick: the cells whose neighbourhood the brick holds.
            None => (brick_source, [0; 3], [[1.0; 3], max_cell.map(|m| m - 1.0)]),
        };
        Some(GatherBrick {
            samples: brick_source,
            strides: [
                to_i32(byte_strides[0])?,
                to_i32(byte_strides[1])?,
                to_i32(byte_strides[2])?,
            ],
            corners: corners.map(|c| c as i32),
            origin: origin.map(|o| o as f32),
            max_cell,
            neighbourhoods,
            wrap,
            reach: {
                let reach = 2 * byte_strides.iter().sum::<usize>()
                    + wrap.iter().map(|&w| w as usize).sum::<usize>();
                (reach <= MAX_GATHER_BYTES).then_some(reach as i32)?
            },
            interior,
        })
    }
}

/// A chunk's lane arrays on the stack, each on its own cache lines: a store
/// of eight lanes that straddles two lines stalls the kernel, and where the
/// stack lies follows the callers' frames (a change anywhere up the call chain
/// moved the unshaded kernel's speed by 14 %).
#[repr(align(64))]
pub(crate) struct LineAligned<T>(pub(crate) T);

/// A chunk's lanes as the gather kernels fill them: table indices, values,
/// brick-local positions and gradients (per axis), each eight lanes.
/// Aligned to a cache line, so that no 32-byte array straddles two lines
/// (as [`LineAligned`] says).
#[derive(Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct GradientLanes {
    /// The samples' transfer-table indices.
    pub(crate) indices: [i32; GATHER_LANES],
    /// The samples' trilinear values.
    pub(crate) values: [f32; GATHER_LANES],
    /// The samples' brick-local positions, per axis.
    pub(crate) local: [[f32; GATHER_LANES]; 3],
    /// The samples' gradients before the frame's gradient scale, per axis.
    pub(crate) gradient: [[f32; GATHER_LANES]; 3],
}

impl<'a> GatherBrick<'a> {
    /// [`Self::new`] for a task marched at `level`: `None` too unless the
    /// level has hardware gathers (AVX2, AVX-512). What the kernels that
    /// gather only (values, gradients) ask before they take a task.
    pub(crate) fn at_level<T: Sample>(
        level: SimdLevel,
        sampler: &BrickSampler<'a, T>,
        volume: &VolumeSampler<'a, T>,
    ) -> Option<Self> {
        if !level.has_gathers() {
            return None;
        }
        GatherBrick::new(sampler, volume)
    }
}

impl GatherBrick<'_> {
    /// The trilinear values of samples `samples[..n]` of the ray at
    /// `positions` in `sampler`'s brick into `values`, with the scalar
    /// kernel's operations (so its bits): gathered, or for the samples that
    /// lie on none of the brick's cells (its upper faces) read by
    /// [`BrickSampler::value_local`], as the scalar kernel reads them.
    /// Returns the latter lanes.
    #[inline(always)]
    pub(crate) fn chunk_values<T: Sample>(
        &self,
        sampler: &BrickSampler<'_, T>,
        positions: &SamplePositions,
        samples: &[u32; GATHER_LANES],
        n: usize,
        values: &mut [f32; GATHER_LANES],
    ) -> u32 {
        let mut local = LineAligned([[0f32; GATHER_LANES]; 3]);
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
        let outside =
            unsafe { x86::chunk_values::<T>(self, positions, samples, n, values, &mut local.0) };
        #[cfg(not(target_arch = "x86_64"))]
        let outside: u32 = unreachable!("no gather layout off x86-64");
        let mut lanes = outside;
        while lanes != 0 {
            let j = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let l = Vec3::new(local.0[0][j], local.0[1][j], local.0[2][j]);
            values[j] = sampler.value_local(l);
        }
        outside
    }
}

/// Whether this CPU has AVX2 (detected once per process by `std`).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One ray's visit of a brick, marched by gathers.
pub(crate) struct GatherRay<'v, 'a, T: Sample> {
    /// The brick's layout.
    pub brick: &'v GatherBrick<'a>,
    /// The brick, for the samples outside its cells.
    pub sampler: &'v BrickSampler<'a, T>,
    /// The frame's table.
    pub table: &'v TransferTable,
    /// The ray's sample positions.
    pub positions: SamplePositions,
    /// The ray's last sample and the fraction of a step it stands for.
    pub last_sample: u32,
    /// See `last_sample`.
    pub last_fraction: f32,
    /// The frame's opacity threshold.
    pub ert_threshold: f32,
    /// Blinn-Phong, when shading (the task's).
    pub shade: Option<&'v GatherShading<'v, 'a, T>>,
    /// The ray's light vectors ([`Shading::ray_lights`]) when shading.
    pub lights: (Vec3, Vec3),
}

/// What shading a task's samples take.
pub(crate) struct GatherShading<'v, 'a, T: Sample> {
    /// Blinn-Phong.
    pub shading: Shading,
    /// The frame's gradient scale (voxel differences to normalised units).
    pub gradient_scale: Vec3,
    /// Reads anywhere in the volume (gradients at the brick's faces).
    pub volume: &'v VolumeSampler<'a, T>,
}

impl<'v, 'a, T: Sample> GatherShading<'v, 'a, T> {
    /// `shading` of the samples of `work`'s task.
    pub(crate) fn of_task<S>(shading: Shading, work: &PacketWork<'v, 'a, T, S>) -> Self {
        GatherShading {
            shading,
            gradient_scale: work.plan.gradient_scale,
            volume: work.volume,
        }
    }
}

/// A [`ChunkFolder`] as the marcher of a ray's visit: eight samples per
/// chunk, across runs ([`march_runs_in_chunks`]) unless the compositor skips
/// runs by its state (each run is then asked before it is marched) or the
/// visit skips no cells (it is one run).
pub(crate) struct Chunked<F>(pub(crate) F);

impl<S, F: ChunkFolder<S>> RunMarcher<S> for Chunked<F> {
    /// Samples `first..end` into `acc`, front to back; `Some(k)` when the ray
    /// stopped with sample `k − 1`.
    #[inline(always)]
    fn march_run(&mut self, acc: &mut S, first: u32, end: u32) -> Option<u32> {
        march_run_in_chunks(&self.0, acc, first, end)
    }

    #[inline(always)]
    fn march_runs<C: Compositor<State = S>>(
        &mut self,
        c: &C,
        ess: bool,
        acc: &mut S,
        runs: &mut SampleRuns<'_, C>,
    ) -> (u64, u64, Option<u32>) {
        if C::STATE_SKIPS || !runs.skips_cells() {
            return march_each_run(self, c, ess, acc, runs);
        }
        match runs.sample_walk() {
            Some(walk) => march_samples_in_chunks(&self.0, acc, &walk),
            None => march_runs_in_chunks(&self.0, acc, runs),
        }
    }
}

/// A kernel that folds a ray's samples into its state eight at a time.
pub(crate) trait ChunkFolder<S> {
    /// Samples `samples[..n]` (ascending) into `acc`, in order; `Some(j)` when
    /// the ray stopped at `samples[j]`. (A trait method rather than a closure,
    /// so that the kernel is inlined into the loops that call it.)
    fn chunk(&self, acc: &mut S, samples: &[u32; GATHER_LANES], n: usize) -> Option<usize>;

    /// The brick's gather layout (which exists only on a CPU with AVX2).
    fn layout(&self) -> &GatherBrick<'_>;
}

/// Samples `first..end` of one run into `acc`, eight per chunk folded by
/// `folder`; `Some(k)` when the ray stopped before sample `k`, as
/// [`RunMarcher::march_run`].
#[inline(always)]
fn march_run_in_chunks<S>(
    folder: &impl ChunkFolder<S>,
    acc: &mut S,
    first: u32,
    end: u32,
) -> Option<u32> {
    let mut k = first;
    while k < end {
        let n = (end - k).min(GATHER_LANES as u32) as usize;
        let samples = std::array::from_fn(|j| k + j as u32);
        if let Some(j) = folder.chunk(acc, &samples, n) {
            return Some(samples[j] + 1);
        }
        k += n as u32;
    }
    None
}

/// Every run of `runs` into `acc`, eight samples per chunk whatever run they
/// belong to (a chunk of one run would end at every empty cell and brick
/// face), folded by `folder`: the samples taken, the samples skipped, and
/// `Some(k)` when the ray stopped before sample `k`, as
/// [`RunMarcher::march_runs`]. A ray that stops counts the samples skipped
/// before its last sample's run only, as one run at a time does.
#[inline(always)]
fn march_runs_in_chunks<S, C: Compositor>(
    folder: &impl ChunkFolder<S>,
    acc: &mut S,
    runs: &mut SampleRuns<'_, C>,
) -> (u64, u64, Option<u32>) {
    // A chunk's samples and room for a run's next eight written after
    // them (the lanes past the run's end are overwritten by the next
    // run's or left out of the chunk).
    let mut samples = [0u32; 2 * GATHER_LANES];
    // The samples skipped before each lane's run, for chunks that gather
    // lanes of several runs.
    let mut skipped = [0u64; 2 * GATHER_LANES];
    let (mut n, mut taken) = (0, 0u64);
    while let Some(run) = runs.next() {
        let skipped_before = runs.skipped;
        let mut k = run.first;
        while k < run.end {
            let more = ((run.end - k) as usize).min(GATHER_LANES - n);
            let next: [u32; GATHER_LANES] = std::array::from_fn(|j| k.wrapping_add(j as u32));
            samples[n..n + GATHER_LANES].copy_from_slice(&next);
            skipped[n..n + GATHER_LANES].fill(skipped_before);
            n += more;
            k += more as u32;
            if n == GATHER_LANES {
                n = 0;
                let chunk_samples = samples[..GATHER_LANES].try_into().expect("a chunk");
                if let Some(j) = folder.chunk(acc, chunk_samples, GATHER_LANES) {
                    return (taken + j as u64 + 1, skipped[j], Some(samples[j] + 1));
                }
                taken += GATHER_LANES as u64;
            }
        }
    }
    if n > 0 {
        let chunk_samples = samples[..GATHER_LANES].try_into().expect("a chunk");
        if let Some(j) = folder.chunk(acc, chunk_samples, n) {
            return (taken + j as u64 + 1, skipped[j], Some(samples[j] + 1));
        }
        taken += n as u64;
    }
    (taken, runs.skipped, None)
}

/// The samples of `walk` into `acc`, eight per chunk folded by `folder`: those
/// in visible cells, found eight at a time by the lane classifier, whatever
/// cell they lie in. The samples taken, the samples skipped (before the sample
/// the ray stopped at, when it stopped), and `Some(k)` when the ray stopped
/// before sample `k`, as [`RunMarcher::march_runs`]: the samples and counts of
/// [`march_runs_in_chunks`] over [`SampleRuns`], which places samples by the
/// same rule.
#[inline(always)]
fn march_samples_in_chunks<S>(
    folder: &impl ChunkFolder<S>,
    acc: &mut S,
    walk: &SampleWalk<'_>,
) -> (u64, u64, Option<u32>) {
    // The chunk's samples, and room for the eight lanes of a classification
    // written after them.
    let mut samples = [0u32; 2 * GATHER_LANES];
    let (mut n, mut taken) = (0, 0u64);
    // The samples skipped before the chunk's sample `j`: those before it not
    // taken.
    let stopped = |samples: &[u32; 2 * GATHER_LANES], taken: u64, j: usize| {
        let skipped = u64::from(samples[j] - walk.first) - (taken + j as u64);
        (taken + j as u64 + 1, skipped, Some(samples[j] + 1))
    };
    let classifier = LaneClassifier::with_layout(folder.layout(), &walk.locator, walk.visible);
    let mut k = walk.first;
    while k < walk.end {
        let count = (walk.end - k).min(GATHER_LANES as u32);
        n += classifier.append_visible(k, count, &mut samples, n);
        if n >= GATHER_LANES {
            let chunk = samples[..GATHER_LANES].try_into().expect("a chunk");
            if let Some(j) = folder.chunk(acc, chunk, GATHER_LANES) {
                return stopped(&samples, taken, j);
            }
            taken += GATHER_LANES as u64;
            samples.copy_within(GATHER_LANES.., 0);
            n -= GATHER_LANES;
        }
        k += count;
    }
    if n > 0 {
        let chunk = samples[..GATHER_LANES].try_into().expect("a chunk");
        if let Some(j) = folder.chunk(acc, chunk, n) {
            return stopped(&samples, taken, j);
        }
        taken += n as u64;
    }
    (taken, u64::from(walk.end - walk.first) - taken, None)
}

impl<T: Sample> ChunkFolder<Accumulation> for GatherRay<'_, '_, T> {
    #[inline(always)]
    fn layout(&self) -> &GatherBrick<'_> {
        self.brick
    }

    /// Stops at the opacity threshold.
    #[inline(always)]
    fn chunk(
        &self,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
    ) -> Option<usize> {
        match self.shade {
            Some(shade) => self.chunk_shaded(shade, acc, samples, n),
            None => self.chunk_unshaded(acc, samples, n),
        }
    }
}

/// Whether [`GatherRay::chunk_shaded_per_lane`] can shade with `shading`:
/// on x86-64 (the gather kernels' AVX2) with a whole shininess exponent.
pub(crate) fn shades_per_lane(shading: &Shading) -> bool {
    cfg!(target_arch = "x86_64") && whole_exponent(shading.shininess).is_some()
}

impl<T: Sample> GatherRay<'_, '_, T> {
    /// [`Self::chunk`] without shading.
    #[inline(always)]
    fn chunk_unshaded(
        &self,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
    ) -> Option<usize> {
        let entries = self.table.entries();
        let mut lanes = GradientLanes::default();
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
        let (outside, mut visible) =
            unsafe { x86::chunk_indices(self, samples, n, &mut lanes.indices, &mut lanes.local) };
        #[cfg(not(target_arch = "x86_64"))]
        let (outside, mut visible): (u32, u32) = unreachable!("no gather layout off x86-64");
        if outside != 0 {
            visible |= self.indices_outside_cells(outside, &mut lanes);
        }
        let indices = &lanes.indices;
        // The visible samples (opacity above 0: what the scalar `Dvr`
        // composites), in order.
        let ends_ray = samples[n - 1] == self.last_sample;
        while visible != 0 {
            let j = visible.trailing_zeros() as usize;
            visible &= visible - 1;
            let [r, g, b, a] = entries[indices[j] as usize];
            if self.over(acc, ([r, g, b], a), samples[j], ends_ray) {
                return Some(j);
            }
        }
        None
    }

    /// [`Self::chunk`] with shading: the scalar `Dvr`'s colour, shaded as the
    /// 4-lane kernel shades it (`Shading::shade_lanes`, the bits of
    /// `Shading::shade`), for the visible samples.
    #[inline(always)]
    fn chunk_shaded(
        &self,
        shade: &GatherShading<'_, '_, T>,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
    ) -> Option<usize> {
        let entries = self.table.entries();
        self.chunk_shaded_with(shade, acc, samples, n, |lanes, j| {
            entries[lanes.indices[j] as usize]
        })
    }

    /// [`Self::chunk_shaded`] with each visible lane's entry (colour and
    /// step-corrected opacity) given by `entry` from the chunk's lanes and the
    /// lane: the frame table's at the lane's index, or (a two-level scene
    /// composited directly) that of the table of the object the lane's value
    /// belongs to. Lanes visible under `self.table` whose entry is
    /// transparent composite nothing ("over" adds zeros).
    #[inline(always)]
    pub(crate) fn chunk_shaded_with(
        &self,
        shade: &GatherShading<'_, '_, T>,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
        entry: impl Fn(&GradientLanes, usize) -> [f32; 4],
    ) -> Option<usize> {
        self.chunk_shaded_lanes::<false>(shade, acc, samples, n, |lanes, j| {
            (entry(lanes, j), [1.0, 0.0])
        })
    }

    /// [`Self::chunk_shaded_with`] where each visible lane's entry comes with
    /// its own gradient factor and shading fade rate (`[factor, rate]`: a
    /// two-level scene's objects whose functions have domains of their own,
    /// whose gradients `Dvr` reads times the factor and fades in at the
    /// rate). Only with AVX2 and a whole shininess exponent
    /// ([`shades_per_lane`]).
    #[inline(always)]
    pub(crate) fn chunk_shaded_per_lane(
        &self,
        shade: &GatherShading<'_, '_, T>,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
        entry: impl Fn(&GradientLanes, usize) -> ([f32; 4], [f32; 2]),
    ) -> Option<usize> {
        self.chunk_shaded_lanes::<true>(shade, acc, samples, n, entry)
    }

    /// The shaded chunk, each lane's factor and rate its own when
    /// `PER_LANE` (else the frame's).
    #[inline(always)]
    fn chunk_shaded_lanes<const PER_LANE: bool>(
        &self,
        shade: &GatherShading<'_, '_, T>,
        acc: &mut Accumulation,
        samples: &[u32; GATHER_LANES],
        n: usize,
        entry: impl Fn(&GradientLanes, usize) -> ([f32; 4], [f32; 2]),
    ) -> Option<usize> {
        let mut lanes = GradientLanes::default();
        let mut visible = self.visible_gradients(shade.volume, samples, n, &mut lanes);
        if visible == 0 {
            return None;
        }
        let gradient = &lanes.gradient;
        // Colours and gradients per channel and axis in lanes, shaded four at
        // a time; each lane's entry is asked once (opacities kept for "over").
        let mut rgb = LineAligned([[0f32; GATHER_LANES]; 3]);
        let mut alpha = LineAligned([0f32; GATHER_LANES]);
        // Per lane (`PER_LANE`): the gradient factor and the fade rate.
        let mut looks = LineAligned([[1f32; GATHER_LANES]; 2]);
        let mut bits = visible;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let ([r, g, b, a], [factor, rate]) = entry(&lanes, j);
            (rgb.0[0][j], rgb.0[1][j], rgb.0[2][j], alpha.0[j]) = (r, g, b, a);
            if PER_LANE {
                (looks.0[0][j], looks.0[1][j]) = (factor, rate);
            }
        }
        let scale = shade.gradient_scale.to_array();
        #[cfg(target_arch = "x86_64")]
        if let Some(n) = whole_exponent(shade.shading.shininess) {
            #[allow(unsafe_code)]
            // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
            unsafe {
                x86::shade::<PER_LANE>(
                    &shade.shading,
                    n,
                    &mut rgb.0,
                    gradient,
                    scale,
                    self.lights,
                    &looks.0,
                )
            };
        } else {
            assert!(!PER_LANE, "per-lane shading needs a whole exponent");
            self.shade_quads(shade, visible, &mut rgb.0, gradient);
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            assert!(!PER_LANE, "per-lane shading needs AVX2");
            self.shade_quads(shade, visible, &mut rgb.0, gradient);
        }
        let ends_ray = samples[n - 1] == self.last_sample;
        while visible != 0 {
            let j = visible.trailing_zeros() as usize;
            visible &= visible - 1;
            let color = [rgb.0[0][j], rgb.0[1][j], rgb.0[2][j]];
            if self.over(acc, (color, alpha.0[j]), samples[j], ends_ray) {
                return Some(j);
            }
        }
        None
    }

    /// The visible samples of `samples[..n]` (a bit per lane) with their
    /// table indices, values, brick-local positions and gradients (per axis,
    /// before the gradient scale: the scalar kernel's bits) in `lanes`;
    /// gathered, or lane by lane where a sample lies on none of the brick's
    /// cells or its cell's neighbourhood leaves the brick (read from
    /// `volume`). Only the visible lanes' entries hold.
    #[inline(always)]
    pub(crate) fn visible_gradients(
        &self,
        volume: &VolumeSampler<'_, T>,
        samples: &[u32; GATHER_LANES],
        n: usize,
        lanes: &mut GradientLanes,
    ) -> u32 {
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
        let (outside, mut visible, mut fallback) = unsafe {
            x86::chunk_gradients(
                self,
                samples,
                n,
                &mut lanes.indices,
                &mut lanes.values,
                &mut lanes.local,
                &mut lanes.gradient,
            )
        };
        #[cfg(not(target_arch = "x86_64"))]
        let (outside, mut visible, mut fallback): (u32, u32, u32) =
            unreachable!("no gather layout off x86-64");
        if outside != 0 {
            let seen = self.indices_outside_cells(outside, lanes);
            visible |= seen;
            fallback |= seen;
        }
        if visible != 0 && fallback != 0 {
            self.gradients_by_lane(volume, samples, fallback, outside, lanes);
        }
        visible
    }

    /// Blinn-Phong of the visible lanes' colours `rgb` (per channel) at their
    /// gradients (per axis, before the gradient scale), four lanes at a time
    /// (`Shading::shade_lanes`): for exponents that are not whole numbers.
    #[cold]
    fn shade_quads(
        &self,
        shade: &GatherShading<'_, '_, T>,
        visible: u32,
        rgb: &mut [[f32; GATHER_LANES]; 3],
        gradient: &[[f32; GATHER_LANES]; 3],
    ) {
        let scale = shade.gradient_scale.to_array();
        for half in 0..2 {
            if visible >> (4 * half) & 0xf == 0 {
                continue;
            }
            let quad = |v: &[f32; GATHER_LANES]| Vec4::from_slice(&v[4 * half..4 * half + 4]);
            let g = [0, 1, 2].map(|a| quad(&gradient[a]) * scale[a]);
            let shaded = shade
                .shading
                .shade_lanes(rgb.each_ref().map(quad), g, self.lights);
            for c in 0..3 {
                shaded[c].write_to_slice(&mut rgb[c][4 * half..4 * half + 4]);
            }
        }
    }

    /// Composites visible sample `k` of colour and opacity `sample`; whether
    /// the ray reached the opacity threshold. `ends_ray`: the chunk holds the
    /// ray's last sample (else no sample is a partial step, and the check per
    /// sample is left out: `partial_step` of a whole step is the opacity).
    #[inline(always)]
    fn over(
        &self,
        acc: &mut Accumulation,
        (color, a): ([f32; 3], f32),
        k: u32,
        ends_ray: bool,
    ) -> bool {
        if !ends_ray {
            over(&mut acc.color, &mut acc.alpha, color, a);
            return acc.alpha >= self.ert_threshold;
        }
        let last = (self.last_sample, self.last_fraction);
        over_sample(
            &mut acc.color,
            &mut acc.alpha,
            (color, a),
            k,
            last,
            self.ert_threshold,
        )
    }

    /// The gradients of the lanes in `lanes` (visible samples whose cell's
    /// neighbourhood leaves the brick, or on no cell: those in `outside`) as
    /// the scalar kernel's cell cache computes them: from the volume's corner
    /// differences of the cell, else [`VolumeSampler::gradient`].
    #[cold]
    fn gradients_by_lane(
        &self,
        volume: &VolumeSampler<'_, T>,
        samples: &[u32; GATHER_LANES],
        lanes: u32,
        outside: u32,
        chunk: &mut GradientLanes,
    ) {
        let origin = self.sampler.origin_voxel();
        let mut cached: Option<([u32; 3], Option<CornerDifferences>)> = None;
        for j in 0..GATHER_LANES {
            if lanes & (1 << j) == 0 {
                continue;
            }
            let p = Vec3::from(self.positions.at(samples[j]));
            let local = &chunk.local;
            let l = Vec3A::new(local[0][j], local[1][j], local[2][j]);
            let differences = if outside & (1 << j) != 0 {
                None
            } else {
                let lower = l.floor();
                let cell = lower.to_array().map(|c| c as u32);
                let global = [0, 1, 2].map(|a| cell[a] + origin[a]);
                // Consecutive samples share cells.
                let d = match cached {
                    Some((at, d)) if at == global => d,
                    _ => {
                        let d = volume.corner_differences(self.sampler, global);
                        cached = Some((global, d));
                        d
                    }
                };
                d.map(|d| (d, l - lower))
            };
            let g = match differences {
                Some((d, f)) => gradient_from_differences(&d, f.to_array()),
                None => volume.gradient(self.sampler, p),
            };
            for a in 0..3 {
                chunk.gradient[a][j] = g[a];
            }
        }
    }

    /// The values and table indices of the lanes in `outside` (a bit per
    /// lane), whose positions lie on no cell of the brick (its upper face),
    /// into `lanes`: each from [`BrickSampler::value_local`], as the scalar
    /// kernel reads them. Returns those of them that are visible.
    #[cold]
    fn indices_outside_cells(&self, outside: u32, lanes: &mut GradientLanes) -> u32 {
        let mut visible = 0;
        for j in 0..GATHER_LANES {
            if outside & (1 << j) != 0 {
                let local = &lanes.local;
                let l = glam::Vec3::new(local[0][j], local[1][j], local[2][j]);
                let value = self.sampler.value_local(l);
                let i = self.table.index(value);
                lanes.values[j] = value;
                lanes.indices[j] = i as i32;
                if self.table.entries()[i][3] > 0.0 {
                    visible |= 1 << j;
                }
            }
        }
        visible
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    use std::arch::x86_64::*;

    use glam::Vec3;

    use super::{GATHER_LANES, GatherBrick, GatherRay, GatherSource, LineAligned};
    use crate::render::pixel::SamplePositions;
    use crate::render::shading::{Light, Shading};

    use crate::render::transfer::TABLE_SIZE;
    use crate::volume::Sample;

    /// A chunk's lanes: where its samples lie and what the table makes of them.
    struct ChunkLanes {
        /// Where the samples lie, their corners and values.
        cells: ChunkCells,
        /// In-cell lanes whose entry's opacity is above 0 (bits).
        visible: u32,
    }

    /// A chunk's cells: where its samples lie and their values.
    struct ChunkCells {
        /// In-cell fractions per axis.
        fraction: [__m256; 3],
        /// Lower cell corners per axis (local voxels, whole numbers).
        lower: [__m256; 3],
        /// Brick-local byte offsets of the lower corners (0 outside cells).
        offset: __m256i,
        /// Lanes below `n` on one of the brick's cells.
        in_cell: __m256,
        /// The corner values, in [`crate::render::sampler::Corners`] order.
        corners: [__m256; 8],
        /// The trilinear values (of in-cell lanes).
        value: __m256,
        /// Lanes below `n` on no cell (bits).
        outside: u32,
        /// Lanes on a cell (bits).
        in_cell_bits: u32,
    }

    /// `f` itself: a closure bound to a name can carry `#[inline(always)]`
    /// only as an argument (attributes on expressions are unstable).
    #[inline(always)]
    fn inlined<F>(f: F) -> F {
        f
    }

    /// Makes the calling function align its stack frame to a cache line (a
    /// [`LineAligned`] local it cannot optimise away), so that its 32-byte
    /// spill slots never straddle two lines, as [`LineAligned`] says.
    #[inline(always)]
    fn align_stack() {
        std::hint::black_box(&mut LineAligned(()));
    }

    /// `Shading::shade_lanes` of eight lanes for a whole exponent `n`
    /// (`specular_power` by repeated squaring): the colours `rgb` (per
    /// channel) at the gradients `gradient` (per axis) times `scale`, each lane
    /// with `Shading::shade`'s operations, so its bits. `PER_LANE`: each
    /// lane's gradient then times its factor (`looks[0]`) and its fade at its
    /// rate (`looks[1]`), as a two-level object of a domain of its own
    /// (`fold_rescaled`) shades; else `shading`'s rate.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn shade<const PER_LANE: bool>(
        shading: &Shading,
        n: u32,
        rgb: &mut [[f32; GATHER_LANES]; 3],
        gradient: &[[f32; GATHER_LANES]; 3],
        scale: [f32; 3],
        (to_light, half): (Vec3, Vec3),
        looks: &[[f32; GATHER_LANES]; 2],
    ) {
        // SAFETY: each array holds eight `f32`s; unaligned loads.
        let load = |v: &[f32; GATHER_LANES]| unsafe { _mm256_loadu_ps(v.as_ptr()) };
        let splat = _mm256_set1_ps;
        let scaled = |a: usize| {
            let g = _mm256_mul_ps(load(&gradient[a]), splat(scale[a]));
            if PER_LANE {
                _mm256_mul_ps(g, load(&looks[0]))
            } else {
                g
            }
        };
        let [gx, gy, gz] = [0, 1, 2].map(scaled);
        let rate = if PER_LANE {
            load(&looks[1])
        } else {
            splat(shading.fade_rate())
        };
        // `Vec3::length`: `(x·x + y·y) + z·z`, then the root.
        let magnitude = _mm256_sqrt_ps(_mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(gx, gx), _mm256_mul_ps(gy, gy)),
            _mm256_mul_ps(gz, gz),
        ));
        // Not `magnitude ≤ threshold` (NaN lit, as `!cmple`).
        let lit = _mm256_cmp_ps::<_CMP_NLE_UQ>(magnitude, splat(shading.gradient_threshold));
        // `Shading::shade`'s fade: `min((magnitude − threshold) · rate, 1)`.
        let weight = _mm256_min_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(magnitude, splat(shading.gradient_threshold)),
                rate,
            ),
            splat(1.0),
        );
        let abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        // `|gradient · v| / magnitude`, as `Shading::shade`.
        let dot = |v: Vec3| {
            let d = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(gx, splat(v.x)), _mm256_mul_ps(gy, splat(v.y))),
                _mm256_mul_ps(gz, splat(v.z)),
            );
            _mm256_and_ps(_mm256_div_ps(d, magnitude), abs_mask)
        };
        let diffuse = dot(to_light);
        let facing = match shading.light {
            Light::Headlight => diffuse,
            Light::Fixed(_) => dot(half),
        };
        // `power_by_squaring(facing, 1, n)`, multiplication for
        // multiplication.
        let (mut base, mut power, mut e) = (facing, splat(1.0), n);
        while e > 0 {
            if e & 1 == 1 {
                power = _mm256_mul_ps(power, base);
            }
            base = _mm256_mul_ps(base, base);
            e >>= 1;
        }
        let specular = _mm256_mul_ps(splat(shading.specular), power);
        let k = _mm256_add_ps(
            splat(shading.ambient),
            _mm256_mul_ps(splat(shading.diffuse), diffuse),
        );
        for channel in rgb.iter_mut() {
            let c = load(channel);
            let lit_colour =
                _mm256_min_ps(_mm256_add_ps(_mm256_mul_ps(c, k), specular), splat(1.0));
            let shaded = _mm256_add_ps(c, _mm256_mul_ps(_mm256_sub_ps(lit_colour, c), weight));
            // SAFETY: `channel` holds eight `f32`s; an unaligned store.
            unsafe { _mm256_storeu_ps(channel.as_mut_ptr(), _mm256_blendv_ps(c, shaded, lit)) };
        }
    }

    /// Whether a read of `source` within `far` bytes above the brick-local
    /// offsets `offset` may reach its last four bytes.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn near_end(source: &GatherSource<'_>, offset: __m256i, far: i32) -> bool {
        let limit = _mm256_set1_epi32(source.last_whole_read - source.shift - far);
        _mm256_movemask_epi8(_mm256_cmpgt_epi32(offset, limit)) != 0
    }

    /// One lane per sample: the sample of `size` bytes at brick-local byte
    /// offset `offset + relative` in `source`, for the lanes of `mask` (0 in
    /// the others).
    ///
    /// # Safety
    /// The CPU has AVX2, and each lane of `mask` addresses a sample of the
    /// source's slice; `near_end` when one of them may lie in its last four
    /// bytes ([`near_end`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn read(
        source: &GatherSource<'_>,
        size: i32,
        offset: __m256i,
        relative: i32,
        mask: __m256i,
        near_end: bool,
    ) -> __m256 {
        // SAFETY: this function's contract, for one sample.
        let words = unsafe { read_words(source, size, offset, relative, mask, near_end) };
        sample_to_float(words, size)
    }

    /// [`read`] of two consecutive samples (`size` bytes apart) with one
    /// gather: the sample at `offset + relative` and the next.
    ///
    /// # Safety
    /// The CPU has AVX2, and each lane of `mask` addresses two samples of the
    /// source's slice; `near_end` when one of them may lie in its last four
    /// bytes ([`near_end`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn read_pair(
        source: &GatherSource<'_>,
        size: i32,
        offset: __m256i,
        relative: i32,
        mask: __m256i,
        near_end: bool,
    ) -> [__m256; 2] {
        // SAFETY: this function's contract, for `2·size` bytes.
        let words = unsafe { read_words(source, 2 * size, offset, relative, mask, near_end) };
        let next = if size == 1 {
            _mm256_srli_epi32::<8>(words)
        } else {
            _mm256_srli_epi32::<16>(words)
        };
        [sample_to_float(words, size), sample_to_float(next, size)]
    }

    /// The four bytes at brick-local byte offset `offset + relative` in
    /// `source`, for the lanes of `mask` (0 in the others), shifted down so
    /// that the `span` bytes from there on are their lowest.
    ///
    /// # Safety
    /// The CPU has AVX2, `span` is 1 to 4, and each lane of `mask` addresses
    /// `span` bytes of the source's slice; `near_end` when one of them may lie
    /// in its last four bytes ([`near_end`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn read_words(
        source: &GatherSource<'_>,
        span: i32,
        offset: __m256i,
        relative: i32,
        mask: __m256i,
        near_end: bool,
    ) -> __m256i {
        let at = _mm256_add_epi32(offset, _mm256_set1_epi32(relative + source.shift));
        let (at, shift) = if near_end {
            // A four-byte read that would pass the slice's end reads the four
            // bytes ending with the `span` bytes instead (the slice holds at
            // least eight), those in the high bytes.
            let over = _mm256_cmpgt_epi32(at, _mm256_set1_epi32(source.last_whole_read));
            let back = _mm256_and_si256(over, _mm256_set1_epi32(4 - span));
            (_mm256_sub_epi32(at, back), _mm256_slli_epi32::<3>(back))
        } else {
            (at, _mm256_setzero_si256())
        };
        // SAFETY: each lane of `mask` reads four bytes at `bytes + at`, with
        // `0 ≤ at ≤ len − 4`: its `span` bytes lie in the slice (this
        // function's contract), and an `at` past `len − 4` was moved back by
        // `4 − span` bytes, still at or above 0 (the slice has at least 8
        // bytes, `at` is above 4 then). The CPU has AVX2.
        let words = unsafe {
            _mm256_mask_i32gather_epi32::<1>(
                _mm256_setzero_si256(),
                source.bytes.as_ptr().cast::<i32>(),
                at,
                mask,
            )
        };
        _mm256_srlv_epi32(words, shift)
    }

    /// The sample of `size` bytes in the low bytes of `words`, as a float.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn sample_to_float(words: __m256i, size: i32) -> __m256 {
        let value_mask = _mm256_set1_epi32(if size == 1 { 0xff } else { 0xffff });
        // The sample (below 2^16) as the mantissa of 2^23, less 2^23 (exact,
        // as a conversion; which the compiler would otherwise lower as an
        // unsigned one, blends and all).
        let value = _mm256_and_si256(words, value_mask);
        let biased = _mm256_or_si256(value, _mm256_set1_epi32(0x4b00_0000));
        _mm256_sub_ps(_mm256_castsi256_ps(biased), _mm256_set1_ps(8_388_608.0))
    }

    /// The lanes (bits) whose entry `index` (each below 1024) has its bit set
    /// in `bits` (bit `i % 32` of word `i / 32`): the table's 1024 bits in
    /// four registers, word `index / 32` by a permutation of each and a
    /// choice among the four, then bit `index % 32` of it. No gather, whose
    /// wait on the index would stall the chunk.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn table_bits(bits: &[u32; 32], index: __m256i) -> u32 {
        // SAFETY: `bits` holds 32 `u32`s, four registers' worth; unaligned
        // loads.
        let registers: [__m256i; 4] = std::array::from_fn(|r| unsafe {
            _mm256_loadu_si256(bits.as_ptr().add(8 * r).cast::<__m256i>())
        });
        let word_index = _mm256_srli_epi32::<5>(index);
        let words = registers.map(|r| _mm256_permutevar8x32_epi32(r, word_index));
        let register = _mm256_srli_epi32::<3>(word_index);
        let one = _mm256_set1_epi32(1);
        let odd = _mm256_cmpeq_epi32(_mm256_and_si256(register, one), one);
        let upper = _mm256_cmpgt_epi32(register, one);
        let word = _mm256_blendv_epi8(
            _mm256_blendv_epi8(words[0], words[1], odd),
            _mm256_blendv_epi8(words[2], words[3], odd),
            upper,
        );
        let bit = _mm256_and_si256(
            _mm256_srlv_epi32(word, _mm256_and_si256(index, _mm256_set1_epi32(31))),
            one,
        );
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(bit, one))) as u32
    }

    /// `a + (b − a)·t`, as the scalar `lerp`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lerp(a: __m256, b: __m256, t: __m256) -> __m256 {
        _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t))
    }

    /// `trilinear` of corner lanes `c` at fractions `[fx, fy, fz]`: z, then y,
    /// then x.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn trilinear(c: &[__m256; 8], [fx, fy, fz]: [__m256; 3]) -> __m256 {
        let c00 = lerp(c[0], c[1], fz);
        let c01 = lerp(c[2], c[3], fz);
        let c10 = lerp(c[4], c[5], fz);
        let c11 = lerp(c[6], c[7], fz);
        lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx)
    }

    /// The cells of samples `samples[..n]` of the ray at `positions` in
    /// `brick`: their positions (brick-local, stored into `local`), corners
    /// and trilinear values, each with the scalar kernel's operations.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn chunk_cells<T: Sample>(
        brick: &GatherBrick<'_>,
        positions: &SamplePositions,
        samples: &[u32; GATHER_LANES],
        n: usize,
        local: &mut [[f32; GATHER_LANES]; 3],
    ) -> ChunkCells {
        align_stack();
        let (start, step, last) = positions.parts();
        let zero = _mm256_setzero_ps();
        let lane_numbers = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        // Sample numbers as floats (exact: below 2^24), as `k as f32`.
        // SAFETY: `samples` holds eight `u32`s; an unaligned load.
        let ks = unsafe { _mm256_loadu_si256(samples.as_ptr().cast::<__m256i>()) };
        let kf = _mm256_cvtepi32_ps(ks);
        // Lanes below `n`.
        let used = _mm256_cmpgt_epi32(_mm256_set1_epi32(n as i32), lane_numbers);
        let mut in_cell = _mm256_castsi256_ps(used);
        let mut fraction = [zero; 3];
        let mut lower = [zero; 3];
        let mut offset = _mm256_setzero_si256();
        for a in 0..3 {
            // `(start + step·k).clamp(0, last)`, then local, floor and fraction.
            let p = _mm256_add_ps(
                _mm256_set1_ps(start[a]),
                _mm256_mul_ps(_mm256_set1_ps(step[a]), kf),
            );
            let p = _mm256_min_ps(_mm256_max_ps(p, zero), _mm256_set1_ps(last[a]));
            let l = _mm256_sub_ps(p, _mm256_set1_ps(brick.origin[a]));
            // SAFETY: `local[a]` holds eight `f32`s; an unaligned store.
            unsafe { _mm256_storeu_ps(local[a].as_mut_ptr(), l) };
            lower[a] = _mm256_floor_ps(l);
            fraction[a] = _mm256_sub_ps(l, lower[a]);
            let inside = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(lower[a], zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(lower[a], _mm256_set1_ps(brick.max_cell[a])),
            );
            in_cell = _mm256_and_ps(in_cell, inside);
            let cell = _mm256_cvttps_epi32(lower[a]);
            offset = _mm256_add_epi32(
                offset,
                _mm256_mullo_epi32(cell, _mm256_set1_epi32(brick.strides[a])),
            );
        }
        let in_cell_bits = _mm256_movemask_ps(in_cell) as u32;
        let outside = !in_cell_bits & ((1u32 << n) - 1);
        let mask = _mm256_castps_si256(in_cell);
        // Lanes not in a cell read nothing (masked), so their offsets need no
        // bound; the others' cells lie in the brick.
        let offset = _mm256_and_si256(offset, mask);
        let (source, size) = (&brick.samples, std::mem::size_of::<T>() as i32);
        // SAFETY: every lane of `mask` is on one of the brick's cells, whose
        // corners are samples of the brick's slice (as the scalar
        // `BrickSampler::corners` indexes them), all within `corners[7]` of its
        // lower corner. The CPU has AVX2. (Two copies, each with `near_end` a
        // constant.)
        let corners: [__m256; 8] = unsafe {
            let near = near_end(source, offset, brick.corners[7]);
            if brick.corners[1] == size {
                // Corners 2p and 2p + 1 differ in z alone, whose stride is
                // a sample: one gather reads both. (A read from corner 2p
                // starts below corner 7, so `near` covers it.)
                let pairs: [[__m256; 2]; 4] = if near {
                    std::array::from_fn(|p| {
                        read_pair(source, size, offset, brick.corners[2 * p], mask, true)
                    })
                } else {
                    std::array::from_fn(|p| {
                        read_pair(source, size, offset, brick.corners[2 * p], mask, false)
                    })
                };
                std::array::from_fn(|c| pairs[c / 2][c % 2])
            } else if near {
                std::array::from_fn(|c| read(source, size, offset, brick.corners[c], mask, true))
            } else {
                std::array::from_fn(|c| read(source, size, offset, brick.corners[c], mask, false))
            }
        };
        let value = trilinear(&corners, fraction);
        ChunkCells {
            fraction,
            lower,
            offset,
            in_cell,
            corners,
            value,
            outside,
            in_cell_bits,
        }
    }

    /// The trilinear values of samples `samples[..n]` of the ray at
    /// `positions` into `values` (the scalar kernel's bits), and their
    /// brick-local positions into `local`; returns the lanes (below `n`)
    /// whose position lies on none of the brick's cells, whose values are
    /// left to the caller.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_values<T: Sample>(
        brick: &GatherBrick<'_>,
        positions: &SamplePositions,
        samples: &[u32; GATHER_LANES],
        n: usize,
        values: &mut [f32; GATHER_LANES],
        local: &mut [[f32; GATHER_LANES]; 3],
    ) -> u32 {
        // SAFETY: the CPU has AVX2 (this function's contract).
        let cells = unsafe { chunk_cells::<T>(brick, positions, samples, n, local) };
        // SAFETY: `values` holds eight `f32`s; an unaligned store.
        unsafe { _mm256_storeu_ps(values.as_mut_ptr(), cells.value) };
        cells.outside
    }

    /// The lanes of samples `samples[..n]`, their table indices stored into
    /// `indices` and their brick-local positions into `local`.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn chunk_lanes<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        samples: &[u32; GATHER_LANES],
        n: usize,
        indices: &mut [i32; GATHER_LANES],
        local: &mut [[f32; GATHER_LANES]; 3],
    ) -> ChunkLanes {
        // SAFETY: the CPU has AVX2 (this function's contract).
        let cells = unsafe { chunk_cells::<T>(ray.brick, &ray.positions, samples, n, local) };
        let (zero, value) = (_mm256_setzero_ps(), cells.value);
        // `TransferTable::index`: `(v − offset)·scale + 0.5`, clamped, truncated.
        let (table_offset, table_scale) = ray.table.index_map();
        let x = _mm256_add_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(value, _mm256_set1_ps(table_offset)),
                _mm256_set1_ps(table_scale),
            ),
            _mm256_set1_ps(0.5),
        );
        // `max` first with `x` as its first operand: NaN becomes 0, as
        // `truncate_clamped`.
        let x = _mm256_min_ps(
            _mm256_max_ps(x, zero),
            _mm256_set1_ps((TABLE_SIZE - 1) as f32),
        );
        let index = _mm256_cvttps_epi32(x);
        // SAFETY: `indices` holds eight `i32`s; an unaligned store.
        unsafe { _mm256_storeu_si256(indices.as_mut_ptr().cast::<__m256i>(), index) };
        let visible = table_bits(ray.table.visible_bits(), index) & cells.in_cell_bits;
        ChunkLanes { cells, visible }
    }

    /// The table indices of samples `samples[..n]` into `indices` and
    /// their brick-local positions into `local`; returns the lanes (below `n`)
    /// whose position lies on none of the brick's cells, whose indices are
    /// left to the caller, and the other lanes below `n` whose entry's opacity
    /// is above 0.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_indices<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        samples: &[u32; GATHER_LANES],
        n: usize,
        indices: &mut [i32; GATHER_LANES],
        local: &mut [[f32; GATHER_LANES]; 3],
    ) -> (u32, u32) {
        // SAFETY: the CPU has AVX2 (this function's contract).
        let lanes = unsafe { chunk_lanes(ray, samples, n, indices, local) };
        (lanes.cells.outside, lanes.visible)
    }

    /// [`chunk_indices`] with the samples' values into `values` (of the lanes
    /// on cells), and the gradients of the visible samples whose cells'
    /// 4×4×4 neighbourhoods lie in the brick's neighbourhood source (the brick,
    /// or for linear storage the volume), per axis into `gradient`: the
    /// central differences at the cell's corners, interpolated as
    /// `gradient_from_differences`, halved (the scalar kernel's bits; the
    /// invisible lanes of such cells get gradients too, unused: see the
    /// mask). Returns the lanes outside cells, the visible ones, and the
    /// visible ones whose gradient is left to the caller (their neighbourhood
    /// leaves the source).
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_gradients<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        samples: &[u32; GATHER_LANES],
        n: usize,
        indices: &mut [i32; GATHER_LANES],
        values: &mut [f32; GATHER_LANES],
        local: &mut [[f32; GATHER_LANES]; 3],
        gradient: &mut [[f32; GATHER_LANES]; 3],
    ) -> (u32, u32, u32) {
        let brick = ray.brick;
        // SAFETY: the CPU has AVX2 (this function's contract).
        let lanes = unsafe { chunk_lanes(ray, samples, n, indices, local) };
        // SAFETY: `values` holds eight `f32`s; an unaligned store.
        unsafe { _mm256_storeu_ps(values.as_mut_ptr(), lanes.cells.value) };
        if lanes.visible == 0 {
            return (lanes.cells.outside, 0, 0);
        }
        let source = &brick.neighbourhoods;
        // Cells whose neighbourhood lies in the source.
        let mut interior = lanes.cells.in_cell;
        for a in 0..3 {
            let bounds = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(
                    lanes.cells.lower[a],
                    _mm256_set1_ps(brick.interior[0][a]),
                ),
                _mm256_cmp_ps::<_CMP_LE_OQ>(
                    lanes.cells.lower[a],
                    _mm256_set1_ps(brick.interior[1][a]),
                ),
            );
            interior = _mm256_and_ps(interior, bounds);
        }
        let interior_bits = _mm256_movemask_ps(interior) as u32;
        let computed = lanes.visible & interior_bits;
        let fallback = lanes.visible & !interior_bits;
        if computed == 0 {
            return (lanes.cells.outside, lanes.visible, fallback);
        }
        // The neighbourhoods of every interior lane, visible or not: a mask
        // that does not wait for the values, their table entries and the
        // visibility bits lets the gathers start with the value gathers.
        // (The other lanes' gradients are not used.)
        let mask = _mm256_castps_si256(interior);
        // The farthest read: the neighbourhood's voxel (3, 2, 2) and the like,
        // from the lower corner at (1, 1, 1).
        // SAFETY: the lanes of `mask` are on cells whose 4×4×4 neighbourhood
        // lies in the source's slice; the CPU has AVX2.
        unsafe {
            if near_end(source, lanes.cells.offset, brick.reach) {
                neighbourhood_gradient::<T, true>(ray, source, &lanes, mask, gradient)
            } else {
                neighbourhood_gradient::<T, false>(ray, source, &lanes, mask, gradient)
            }
        }
        (lanes.cells.outside, lanes.visible, fallback)
    }

    /// The gradients of the lanes of `mask` into `gradient`, per axis: the
    /// central differences at their cells' corners, from the 24 voxels of each
    /// cell's neighbourhood that are not its corners (`lanes.cells.corners`),
    /// interpolated as `gradient_from_differences`, halved. `NEAR`: a read may
    /// reach the source's last four bytes ([`near_end`]).
    ///
    /// # Safety
    /// The CPU has AVX2, and the lanes of `mask` are on cells whose 4×4×4
    /// neighbourhood lies in `source`'s slice.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn neighbourhood_gradient<T: Sample, const NEAR: bool>(
        ray: &GatherRay<'_, '_, T>,
        source: &GatherSource<'_>,
        lanes: &ChunkLanes,
        mask: __m256i,
        gradient: &mut [[f32; GATHER_LANES]; 3],
    ) {
        let brick = ray.brick;
        let [sx, sy, sz] = brick.strides;
        let size = std::mem::size_of::<T>() as i32;
        // Per axis, the lanes whose block coordinate 0 lies below the brick's
        // lower face (lower corner 0) or 3 beyond its upper face (lower
        // corner `max_cell`): what their offsets add.
        let zero = _mm256_setzero_ps();
        let fix = inlined(
            #[inline(always)]
            |a: usize, at: __m256, by: i32| {
                let crossing =
                    _mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(lanes.cells.lower[a], at));
                _mm256_and_si256(crossing, _mm256_set1_epi32(by))
            },
        );
        let below: [__m256i; 3] = std::array::from_fn(|a| fix(a, zero, -brick.wrap[a]));
        let above: [__m256i; 3] =
            std::array::from_fn(|a| fix(a, _mm256_set1_ps(brick.max_cell[a]), brick.wrap[a]));
        // Whether a lane of `mask` reads across a z face into another stored
        // brick (its z voxels 0 to 3 not consecutive then): any bit of its
        // wrap. (Not the bytes' sign bits, `movemask`: a wrap such as 61, a
        // brick of side 4, has none.)
        let wraps_in_z = _mm256_testz_si256(mask, _mm256_or_si256(below[2], above[2])) == 0;
        // Voxel (x, y, z) of the neighbourhood, the cell's lower corner at
        // (1, 1, 1).
        // SAFETY: every voxel of a lane of `mask` is a sample of the source's
        // slice (this function's contract: the wrap across a face addresses it
        // in the next stored brick); the CPU has AVX2.
        let at = inlined(
            #[inline(always)]
            |x: i32, y: i32, z: i32| {
                let relative = (x - 1) * sx + (y - 1) * sy + (z - 1) * sz;
                let mut offset = lanes.cells.offset;
                for (a, c) in [x, y, z].into_iter().enumerate() {
                    if c == 0 {
                        offset = _mm256_add_epi32(offset, below[a]);
                    } else if c == 3 {
                        offset = _mm256_add_epi32(offset, above[a]);
                    }
                }
                (offset, relative)
            },
        );
        let v = inlined(
            #[inline(always)]
            |x: i32, y: i32, z: i32| unsafe {
                let (offset, relative) = at(x, y, z);
                read(source, size, offset, relative, mask, NEAR)
            },
        );
        // Voxels (x, y, 1) and (x, y, 2): consecutive samples (z's stride is
        // one sample, `GatherBrick::new`; neither crosses a z face), one
        // gather.
        // SAFETY: as `v`'s, for both voxels; a read from (x, y, 1) starts
        // below the farthest, which `NEAR` covers.
        let pair = inlined(
            #[inline(always)]
            |x: i32, y: i32| unsafe {
                let (offset, relative) = at(x, y, 1);
                read_pair(source, size, offset, relative, mask, NEAR)
            },
        );
        let c = &lanes.cells.corners;
        let half = _mm256_set1_ps(0.5);
        let mut store = inlined(
            #[inline(always)]
            |axis: usize, d: [__m256; 8]| {
                let g = _mm256_mul_ps(trilinear(&d, lanes.cells.fraction), half);
                // SAFETY: `gradient[axis]` holds eight `f32`s; an unaligned store.
                unsafe { _mm256_storeu_ps(gradient[axis].as_mut_ptr(), g) };
            },
        );
        // Central differences at corner `i` (x = i >> 2, y = (i >> 1) & 1,
        // z = i & 1), one axis at a time; exact in any order (whole numbers).
        // Along x: the voxels below the lower x face and above the upper, at
        // (y, z) = i & 3.
        let ([b11, b12], [b21, b22]) = (pair(0, 1), pair(0, 2));
        let ([a11, a12], [a21, a22]) = (pair(3, 1), pair(3, 2));
        let below = [b11, b12, b21, b22];
        let above = [a11, a12, a21, a22];
        store(
            0,
            std::array::from_fn(|i| {
                let (x, yz) = (i >> 2, i & 3);
                if x == 0 {
                    _mm256_sub_ps(c[4 + yz], below[yz])
                } else {
                    _mm256_sub_ps(above[yz], c[yz])
                }
            }),
        );
        // Along y, at (x, z) = (i >> 2, i & 1).
        let ([b11, b12], [b21, b22]) = (pair(1, 0), pair(2, 0));
        let ([a11, a12], [a21, a22]) = (pair(1, 3), pair(2, 3));
        let below = [b11, b12, b21, b22];
        let above = [a11, a12, a21, a22];
        store(
            1,
            std::array::from_fn(|i| {
                let (x, y, z) = (i >> 2, (i >> 1) & 1, i & 1);
                if y == 0 {
                    _mm256_sub_ps(c[x * 4 + 2 + z], below[x * 2 + z])
                } else {
                    _mm256_sub_ps(above[x * 2 + z], c[x * 4 + z])
                }
            }),
        );
        // Along z, at (x, y) = i >> 1: the rows (1, 1), (1, 2), (2, 1) and
        // (2, 2), written out (closures passed to `array::map` were left
        // out of line once a second kernel read gradients: 6 % more
        // instructions per sample).
        let (below, above) = if size == 1 && !wraps_in_z {
            // One-byte samples: the four bytes from (x, y, 0) are z = 0 to 3.
            // SAFETY: as `v`'s: the four voxels lie in the source's slice, so
            // a four-byte read from the first never passes its end.
            let word = inlined(
                #[inline(always)]
                |x: i32, y: i32| unsafe {
                    let (offset, relative) = at(x, y, 0);
                    read_words(source, 4, offset, relative, mask, NEAR)
                },
            );
            let words = [word(1, 1), word(1, 2), word(2, 1), word(2, 2)];
            let high = |w: __m256i| _mm256_srli_epi32::<24>(w);
            (
                [
                    sample_to_float(words[0], 1),
                    sample_to_float(words[1], 1),
                    sample_to_float(words[2], 1),
                    sample_to_float(words[3], 1),
                ],
                [
                    sample_to_float(high(words[0]), 1),
                    sample_to_float(high(words[1]), 1),
                    sample_to_float(high(words[2]), 1),
                    sample_to_float(high(words[3]), 1),
                ],
            )
        } else {
            (
                [v(1, 1, 0), v(1, 2, 0), v(2, 1, 0), v(2, 2, 0)],
                [v(1, 1, 3), v(1, 2, 3), v(2, 1, 3), v(2, 2, 3)],
            )
        };
        store(
            2,
            std::array::from_fn(|i| {
                let (xy, z) = (i >> 1, i & 1);
                if z == 0 {
                    _mm256_sub_ps(c[xy * 2 + 1], below[xy])
                } else {
                    _mm256_sub_ps(above[xy], c[xy * 2])
                }
            }),
        );
    }
}

#[cfg(test)]
mod tests {
    use glam::{Vec3, Vec3A};

    use super::*;
    use crate::render::TransferFunction;
    use crate::render::cell_cache::CellCache;
    use crate::render::optics::{over, partial_step};
    use crate::render::sampler::tests::to_bricks;
    use crate::render::test_rng::xorshift32;
    use crate::volume::{Layout, TypedVolume};

    /// The scalar kernel's loop for samples `first..end`: the cell cache's
    /// value and gradient, the table, `Shading::shade`, `over`, the threshold.
    fn scalar_run<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        view_dir: Vec3,
        acc: &mut Accumulation,
        first: u32,
        end: u32,
    ) -> Option<u32> {
        let cache = CellCache::default();
        for k in first..end {
            let p = ray.positions.at(k);
            let value = cache.value(ray.sampler, p);
            let [r, g, b, a] = ray.table.lookup(value);
            if a <= 0.0 {
                continue;
            }
            let color = match &ray.shade {
                Some(shade) => {
                    let gradient = cache.gradient_here(shade.volume, ray.sampler, p.into());
                    shade
                        .shading
                        .shade([r, g, b], gradient * shade.gradient_scale, view_dir)
                }
                None => [r, g, b],
            };
            let fraction = if k == ray.last_sample {
                ray.last_fraction
            } else {
                1.0
            };
            over(
                &mut acc.color,
                &mut acc.alpha,
                color,
                partial_step(a, fraction),
            );
            if acc.alpha >= ray.ert_threshold {
                return Some(k + 1);
            }
        }
        None
    }

    /// Random rays through the bricks of a linear volume, shaded and not: from
    /// inside a brick or along its upper faces (samples on no cell), through
    /// the volume's last voxel (reads moved back from the slice's end), cells
    /// at the volume's faces (gradients by lane), partial chunks and last
    /// samples: the gathers give the scalar loop's bits.
    fn gathers_equal_the_scalar_loop<T: Sample>(to_sample: impl Fn(u32) -> T, type_max: u16) {
        let dims = [13u32, 11, 17];
        let mut next = xorshift32(0x9e37_79b9);
        let linear: Vec<T> = (0..dims.iter().product::<u32>())
            .map(|_| to_sample(next()))
            .collect();
        let tf = TransferFunction::preset("shapes").unwrap();
        let table = TransferTable::new(&tf, type_max, 0.4);
        let shadings = [
            None,
            Some(Shading::default()),
            Some(Shading {
                light: crate::render::Light::Fixed(Vec3::new(0.3, -1.0, -0.4)),
                shininess: 7.5,
                ..Shading::default()
            }),
        ];
        let mut unit = move || (next() % 1_000_001) as f32 / 1_000_000.0;
        let (mut compared, mut visible, mut stopped, mut on_no_cell) = (0, 0, 0, 0);
        // Logical bricks of a linear volume, and the stored bricks of bricked
        // files (gradients across their faces read the next stored brick).
        for layout in [
            Layout::Linear,
            Layout::Bricked { side: 4 },
            Layout::Bricked { side: 5 },
            Layout::Bricked { side: 8 },
        ] {
            let samples = match layout {
                Layout::Linear => linear.clone(),
                Layout::Bricked { side } => to_bricks(&linear, dims, u32::from(side)),
            };
            let data = TypedVolume::new(&samples, dims, layout);
            let volume = VolumeSampler::new(data);
            let grid = data.natural_grid(7);
            for b in grid.iter() {
                let sampler = BrickSampler::new(data.brick(&grid, b));
                let Some(brick) = GatherBrick::new(&sampler, &volume) else {
                    #[cfg(target_arch = "x86_64")]
                    assert!(
                        !std::is_x86_feature_detected!("avx2"),
                        "AVX2 but no gathers"
                    );
                    return;
                };
                let o = Vec3A::from(sampler.origin());
                let far = Vec3A::from(grid.extent(b).map(|e| (e - 1) as f32));
                for round in 0..300 {
                    // A start inside the brick, or on one of its upper faces.
                    let mut start = Vec3A::new(unit(), unit(), unit()) * far;
                    let mut dir = Vec3A::new(unit() - 0.5, unit() - 0.5, unit() - 0.5);
                    if round % 5 == 0 {
                        let axis = round / 5 % 3;
                        start[axis] = far[axis];
                        dir[axis] = 0.0;
                    }
                    if round % 7 == 0 {
                        // Towards the brick's last voxel.
                        dir = far - start;
                    }
                    let step = dir.normalize_or_zero() * (0.05 + unit() * 0.6);
                    // Samples while the position stays in the brick.
                    let count = (0..400u32)
                        .take_while(|&k| {
                            let p = start + step * k as f32;
                            p.cmpge(Vec3A::ZERO).all() && p.cmple(far).all()
                        })
                        .count() as u32;
                    if count == 0 {
                        continue;
                    }
                    let view_dir = Vec3::from(dir.normalize_or(Vec3A::Z));
                    let shading = shadings[round % 3];
                    let gather_shading = shading.map(|shading| GatherShading {
                        shading,
                        gradient_scale: Vec3::new(0.9, 1.1, 1.3),
                        volume: &volume,
                    });
                    let ray = GatherRay {
                        brick: &brick,
                        sampler: &sampler,
                        table: &table,
                        positions: SamplePositions::new(
                            start + o,
                            step,
                            Vec3A::from(volume.last()),
                        ),
                        last_sample: count - 1,
                        last_fraction: 0.25 + unit() * 0.5,
                        ert_threshold: if round % 2 == 0 { f32::INFINITY } else { 0.9 },
                        shade: gather_shading.as_ref(),
                        lights: shading
                            .map_or((Vec3::ZERO, Vec3::ZERO), |s| s.ray_lights(view_dir)),
                    };
                    let first = ((unit() * 11.0) as u32).min(count - 1);
                    let (mut a, mut b) = (
                        Accumulation::starting_at(0.0),
                        Accumulation::starting_at(0.0),
                    );
                    let gathered = march_run_in_chunks(&ray, &mut a, first, count);
                    let scalar = scalar_run(&ray, view_dir, &mut b, first, count);
                    assert_eq!(gathered, scalar, "round {round}");
                    assert_eq!(a.alpha.to_bits(), b.alpha.to_bits(), "round {round}");
                    assert_eq!(
                        a.color.map(f32::to_bits),
                        b.color.map(f32::to_bits),
                        "round {round}"
                    );
                    // The values alone (the value kernel's chunks).
                    let cache = CellCache::default();
                    let mut k = first;
                    while k < count {
                        let n = ((count - k) as usize).min(GATHER_LANES);
                        let chunk = std::array::from_fn(|j| k + j as u32);
                        let mut values = [f32::NAN; GATHER_LANES];
                        let outside =
                            brick.chunk_values(&sampler, &ray.positions, &chunk, n, &mut values);
                        on_no_cell += outside.count_ones();
                        for (j, &s) in chunk.iter().enumerate().take(n) {
                            let expected = cache.value(&sampler, ray.positions.at(s));
                            assert_eq!(
                                values[j].to_bits(),
                                expected.to_bits(),
                                "round {round} {s}"
                            );
                        }
                        k += n as u32;
                    }
                    compared += count - first;
                    visible += u32::from(b.alpha > 0.0);
                    stopped += u32::from(scalar.is_some());
                }
            }
        }
        assert!(
            compared > 25_000 && visible > 500 && stopped > 100 && on_no_cell > 100,
            "{compared} {visible} {stopped} {on_no_cell}"
        );
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn table_bits_read_every_entry_s_bit() {
        use std::arch::x86_64::{_mm256_loadu_si256, _mm256_set1_epi32};
        if !has_avx2() {
            return;
        }
        let mut random = xorshift32(0x2545_f491);
        for pattern in 0..8 {
            // Random words, and words alone set or clear among clear or set ones.
            let bits: [u32; 32] = std::array::from_fn(|w| match pattern {
                0 => u32::from(w == 0),
                1 => !0 ^ (1 << (w % 32)),
                2 => 1 << 31,
                _ => random(),
            });
            for first in (0..1024).step_by(8) {
                // Eight entries in a scrambled order.
                let index: [i32; 8] = std::array::from_fn(|l| ((first + l * 131) % 1024) as i32);
                // SAFETY: `index` holds eight `i32`s; the CPU has AVX2 (checked).
                let lanes =
                    unsafe { x86::table_bits(&bits, _mm256_loadu_si256(index.as_ptr().cast())) };
                for (l, &i) in index.iter().enumerate() {
                    let expected = bits[i as usize / 32] >> (i % 32) & 1 == 1;
                    assert_eq!(
                        lanes >> l & 1 == 1,
                        expected,
                        "entry {i}, pattern {pattern}"
                    );
                }
            }
            // SAFETY: the CPU has AVX2 (checked).
            let last = unsafe { x86::table_bits(&bits, _mm256_set1_epi32(1023)) };
            assert_eq!(last == 0xff, bits[31] >> 31 == 1);
        }
    }

    /// The gather kernels' lane classifier takes the samples the run walker
    /// takes (the scalar kernel's), and both those that
    /// `CellLocator::cell` places in visible cells; the walker's runs are the
    /// same with lanes and without, each the samples of one cell, for cell grids of every size up to 8³,
    /// rays in every direction (along an axis too) and sample indices past
    /// 2^24, where their conversion to `f32` rounds.
    #[test]
    fn the_lane_classifier_takes_the_samples_the_run_walker_takes() {
        use crate::render::pixel::PixelRay;
        use crate::render::runs::tests::Threshold;
        use crate::render::runs::{CellGrid, SampleRuns, bit_set};
        use std::sync::Arc;

        // A gather layout: what stands for this CPU's AVX2.
        let linear: Vec<u8> = (0..512u32).map(|i| i as u8).collect();
        let data = TypedVolume::new(&linear, [8, 8, 8], Layout::Linear);
        let volume = VolumeSampler::new(data);
        let sampler = BrickSampler::new(data.brick(&data.natural_grid(8), [0, 0, 0]));
        let Some(layout) = GatherBrick::new(&sampler, &volume) else {
            #[cfg(target_arch = "x86_64")]
            assert!(
                !std::is_x86_feature_detected!("avx2"),
                "AVX2 but no gathers"
            );
            return;
        };
        let mut next = xorshift32(0x5eed_ce11);
        let mut unit = move || (next() % 1_000_001) as f32 / 1_000_000.0;
        let (mut taken, mut skipped) = (0usize, 0usize);
        for round in 0..4000u32 {
            let per_axis = 1 + round % 8;
            let ranges: Arc<[[u16; 2]]> = (0..per_axis.pow(3))
                .map(|_| {
                    let lo = (unit() * 150.0) as u16;
                    // Some cells own no sample (`lo > hi`).
                    if unit() < 0.05 {
                        [lo + 1, lo]
                    } else {
                        [lo, lo + (unit() * 60.0) as u16]
                    }
                })
                .collect();
            let cell_step = [4.0, 3.0, 5.0, 8.0][(round / 8 % 4) as usize];
            let origin = Vec3::new(unit(), unit(), unit()) * 40.0;
            let grid = CellGrid {
                visible: std::cell::OnceCell::new(),
                ranges,
                per_axis,
                cell_step,
                inv_cell_step: 1.0 / cell_step,
                origin,
                owned: [Vec3::ZERO, Vec3::splat(f32::INFINITY)],
                min_extent: cell_step,
            };
            let mut step = Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 1.6;
            if round % 5 == 0 {
                step[(round / 5 % 3) as usize] = 0.0;
            }
            let side = cell_step * per_axis as f32;
            let first = if round % 3 == 0 {
                16_777_000 + round * 7
            } else {
                round % 50
            };
            // Sample `first` near the brick, or anywhere around it.
            let mut at_first = origin + Vec3::new(unit(), unit(), unit()) * side * 1.4 - side * 0.2;
            if round % 4 == 1 {
                // Samples on the cells' faces: a quarter of a cell per step
                // from a corner, along some axes.
                let corner = (Vec3::new(unit(), unit(), unit()) * per_axis as f32).floor();
                at_first = origin + corner * cell_step;
                step = Vec3::new(1.0, -1.0, 0.5).map(|s| if unit() < 0.6 { s } else { 0.0 })
                    * cell_step
                    * 0.25;
            }
            let start = at_first - step * first as f32;
            let ray = PixelRay {
                origin: Vec3::ZERO,
                direction: Vec3::X,
                view_dir: Vec3::X,
                t_enter: 0.0,
                dt: 1.0,
                first: 0,
                samples: u32::MAX,
                last_fraction: 1.0,
                start,
                step,
                inv_step: step.recip(),
            };
            let last = first + (unit() * 70.0) as u32;
            let far = Vec3::splat(1e9);
            let runs = SampleRuns::new(&Threshold, &ray, Some(&grid), far, first, last);
            let walk = runs
                .sample_walk()
                .expect("no segments: samples placed one by one");
            // The walker with lanes (where the CPU has them) and without.
            let with_lanes: Vec<_> = runs.collect();
            let by_axes: Vec<_> = SampleRuns::new(&Threshold, &ray, Some(&grid), far, first, last)
                .without_lanes()
                .collect();
            assert_eq!(with_lanes, by_axes, "round {round}");
            let expected: Vec<u32> = by_axes.iter().flat_map(|run| run.first..run.end).collect();
            // The walker finds the cells' ends exactly: its samples are those
            // placed one by one in visible cells, a run those of one cell.
            let one_by_one: Vec<u32> = (first..=last)
                .filter(|&k| bit_set(walk.visible, walk.locator.cell(k)))
                .collect();
            assert_eq!(expected, one_by_one, "round {round}");
            for run in &by_axes {
                let cell = walk.locator.cell(run.first);
                assert!((run.first..run.end).all(|k| walk.locator.cell(k) == cell));
                assert!(run.first == first || walk.locator.cell(run.first - 1) != cell);
                assert!(run.end > last || walk.locator.cell(run.end) != cell);
                assert_eq!(run.hi, grid.ranges[cell][1]);
            }

            #[cfg(target_arch = "x86_64")]
            {
                let classifier = LaneClassifier::with_layout(&layout, &walk.locator, walk.visible);
                // Appended after `n` earlier samples, which stay.
                let n = (round % 8) as usize;
                let mut got = Vec::new();
                let mut k = walk.first;
                while k < walk.end {
                    let count = (walk.end - k).min(GATHER_LANES as u32);
                    let mut buffer = [u32::MAX; 2 * GATHER_LANES];
                    let added = classifier.append_visible(k, count, &mut buffer, n);
                    assert!(
                        buffer[..n].iter().all(|&b| b == u32::MAX),
                        "earlier lanes kept"
                    );
                    got.extend_from_slice(&buffer[n..n + added]);
                    k += count;
                }
                assert_eq!(got, expected, "round {round}");
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = (&layout, &walk);
            taken += expected.len();
            skipped += (last - first + 1) as usize - expected.len();
        }
        assert!(taken > 20_000 && skipped > 20_000, "{taken} {skipped}");
    }

    #[test]
    fn u8_gathers_equal_the_scalar_loop() {
        gathers_equal_the_scalar_loop(|r| (r >> 7) as u8, 255);
    }

    #[test]
    fn u16_gathers_equal_the_scalar_loop() {
        gathers_equal_the_scalar_loop(|r| (r >> 5) as u16, u16::MAX);
    }
}
