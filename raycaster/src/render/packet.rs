//! The SIMD kernels of DVR: on AVX2 and AVX-512 the gather kernel
//! ([`super::gather`]); on SSE4.1 and NEON (no gathers) the samples of one ray
//! marched [`LANES`] at a time, their positions, cells, values, shading and
//! opacity in SIMD lanes, described here.
//!
//! A chunk is up to [`LANES`] consecutive samples of one run of a ray (one brick
//! visit, one non-empty small cell: [`super::march::BrickVisit`] walks the runs
//! as for the scalar loop). Its samples' positions and cells come in lanes; the
//! samples that share a voxel cell (consecutive ones: a ray crosses a cell once)
//! take their values from the cell's corners in lanes, through the task's
//! [`CellCache`], which loads each cell's corners and corner differences once,
//! as for the scalar loop. Classification reads the transfer table per sample;
//! a visible sample's gradient comes from its cell's differences; Blinn-Phong
//! runs in lanes ([`Shading::shade_lanes`]); the "over" steps, which depend on
//! each other, run one sample after the other and stop at the opacity
//! threshold.
//!
//! Every operation is the scalar kernel's, in its order (no fused multiply-adds:
//! Rust does not contract `a * b + c`), so a chunk composites the same samples to
//! the same bits as [`super::march::march_brick`] with [`super::local`]'s `Dvr` —
//! which the tests check on every level this machine has.
//!
//! Rays in lanes (a packet of eight neighbouring rays, the first design) took
//! 1.6–2× the time of this kernel and about 2.3× the scalar one's: each lane's ray needs
//! its own cell, run and brick bookkeeping, and gathering eight cells and
//! neighbourhoods per step cost more than the lanes saved. This kernel is as
//! fast as the scalar one, not faster: what both share per ray, brick visit and
//! cell dominates (docs/benchmarks.md, section 5).

use glam::{Mat4, Vec3, Vec3A, Vec4};

use super::cell_cache::CellCache;
use super::compositor::Compositor;
use super::counters::Counters;
use super::gather::{Chunked, GatherBrick, GatherRay, GatherShading};
use super::local::{Accumulation, Dvr};
use super::march::{BrickContext, BrickVisit, RunMarcher};
use super::optics::over_sample;
use super::pixel::{PixelRay, PixelState, SamplePositions};
use super::prepared::FramePlan;
use super::sampler::VolumeSampler;
use super::shading::Shading;
use super::simd::SimdLevel;
use super::transfer::{TABLE_SIZE, TransferTable};
use crate::volume::Sample;

/// Samples per chunk.
pub(crate) const LANES: usize = 4;

/// One ray of a task: its pixel and the samples the brick owns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PacketItem {
    /// Index of the pixel in the tile.
    pub pixel: usize,
    /// First owned sample still to take.
    pub first: u32,
    /// Last owned sample.
    pub last: u32,
}

/// A task's rays, ready for the SIMD kernel.
pub(crate) struct PacketWork<'w, 'b, T: Sample, S> {
    /// The frame.
    pub plan: &'w FramePlan,
    /// Reads anywhere in the volume (gradients at the brick's faces).
    pub volume: &'w VolumeSampler<'b, T>,
    /// The brick.
    pub brick: &'w BrickContext<'b, T>,
    /// The tile's rays.
    pub rays: &'w [Option<PixelRay>],
    /// The tile's pixel states.
    pub states: &'w mut [PixelState<S>],
    /// The rays this task marches, in tile order.
    pub items: &'w [PacketItem],
    /// The task's counters.
    pub counters: &'w mut Counters,
}

impl<'w, 'b, T: Sample, S> PacketWork<'w, 'b, T, S> {
    /// Calls `march` for each of the task's rays (those with samples): its
    /// visit of the brick, its owned samples, its pixel state and the task's
    /// counters.
    #[inline(always)]
    pub(crate) fn for_each_visit(
        &mut self,
        mut march: impl FnMut(BrickVisit<'w, 'b, T>, &PacketItem, &mut PixelState<S>, &mut Counters),
    ) {
        for item in self.items {
            let (Some(ray), state) = (&self.rays[item.pixel], &mut self.states[item.pixel]) else {
                continue;
            };
            let visit = BrickVisit {
                plan: self.plan,
                volume: self.volume,
                brick: self.brick,
                ray,
            };
            march(visit, item, state, self.counters);
        }
    }

    /// Marches the task's rays with `c`'s packet kernel at `level` where it
    /// has one (never at [`SimdLevel::Scalar`]), counting the samples it took
    /// as in lanes; `false` leaves them to the scalar loop. What both
    /// renderers ask of a task before the scalar loop.
    pub(crate) fn march_in_lanes<C: Compositor<State = S>>(
        mut self,
        c: &C,
        level: SimdLevel,
    ) -> bool {
        let before = self.counters.samples;
        let marched = level != SimdLevel::Scalar && c.march_packets(&mut self, level);
        if marched {
            self.counters.samples_in_lanes += self.counters.samples - before;
        }
        marched
    }
}

/// Emission–absorption DVR with a 1D transfer table, shaded or not: the
/// compositor the SIMD kernel runs.
pub(crate) struct DvrLanes<'t> {
    /// The frame's table (opacities corrected for the step).
    pub table: &'t TransferTable,
    /// Blinn-Phong, if shading.
    pub shading: Option<Shading>,
    /// The compositor, for its emptiness rule and closing.
    pub runs_compositor: &'t Dvr,
}

/// Marches `work`'s rays with the SIMD kernel compiled for `level` (not
/// [`SimdLevel::Scalar`]).
pub(crate) fn march_dvr<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
    level: SimdLevel,
) {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 => {
            #[allow(unsafe_code)]
            // SAFETY: the frame plan only chooses a level `simd::available` lists,
            // which checked these features on this CPU.
            unsafe {
                march_dvr_avx512(dvr, work)
            }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 => {
            #[allow(unsafe_code)]
            // SAFETY: as above (AVX2 and FMA detected).
            unsafe {
                march_dvr_avx2(dvr, work)
            }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Sse41 => {
            #[allow(unsafe_code)]
            // SAFETY: as above (SSE4.1 detected).
            unsafe {
                march_dvr_sse41(dvr, work)
            }
        }
        // NEON is the aarch64 baseline; other levels never reach here.
        _ => march_dvr_chunks(dvr, work, false),
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx2,fma,sse4.1")]
unsafe fn march_dvr_avx512<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_chunks(dvr, work, true)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2,fma,sse4.1")]
unsafe fn march_dvr_avx2<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_chunks(dvr, work, true)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "sse4.1")]
unsafe fn march_dvr_sse41<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_chunks(dvr, work, false)
}

/// Each of the task's rays through the brick, its runs in chunks, with
/// hardware gathers where `gathers` ([`super::gather`]).
#[inline(always)]
fn march_dvr_chunks<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
    gathers: bool,
) {
    // One cell cache for the task: its cells are the brick's, whichever ray
    // enters them.
    let cell = CellCache::default();
    // (The gathers read table entries by clamped indices below `TABLE_SIZE`.)
    let gather_brick = if gathers && dvr.table.entries().len() == TABLE_SIZE {
        GatherBrick::new(&work.brick.sampler, work.volume)
    } else {
        None
    };
    let gather_shading = dvr.shading.map(|s| GatherShading::of_task(s, work));
    work.for_each_visit(
        #[inline(always)]
        |visit, item, state, counters| {
            let (c, first, last, ray) = (dvr.runs_compositor, item.first, item.last, visit.ray);
            let positions = || ray.positions(visit.volume.last());
            if let Some(brick) = &gather_brick {
                visit.march(c, first, last, state, counters, || {
                    Chunked(GatherRay {
                        brick,
                        sampler: &visit.brick.sampler,
                        table: dvr.table,
                        positions: positions(),
                        last_sample: ray.samples - 1,
                        last_fraction: ray.last_fraction,
                        ert_threshold: visit.plan.ert_threshold,
                        shade: gather_shading.as_ref(),
                        lights: dvr
                            .shading
                            .map_or((Vec3::ZERO, Vec3::ZERO), |s| s.ray_lights(ray.view_dir)),
                    })
                });
            } else {
                visit.march(c, first, last, state, counters, || DvrChunks {
                    dvr,
                    visit,
                    cell: &cell,
                    positions: positions(),
                    shade: dvr.shading.map(|s| (s, s.ray_lights(ray.view_dir))),
                });
            }
        },
    );
}

/// One ray's visit of a brick, marched in chunks.
struct DvrChunks<'v, 'b, T: Sample> {
    dvr: &'v DvrLanes<'v>,
    visit: BrickVisit<'v, 'b, T>,
    /// The last cell a ray of the task entered.
    cell: &'v CellCache,
    positions: SamplePositions,
    /// Blinn-Phong and the ray's light vectors ([`Shading::ray_lights`]), when
    /// shading.
    shade: Option<(Shading, (Vec3, Vec3))>,
}

impl<T: Sample> RunMarcher<Accumulation> for DvrChunks<'_, '_, T> {
    #[inline(always)]
    fn march_run(&mut self, acc: &mut Accumulation, first: u32, end: u32) -> Option<u32> {
        let mut k = first;
        while k < end {
            let n = (end - k).min(LANES as u32) as usize;
            if let Some(taken) = self.chunk(acc, k, n) {
                return Some(k + taken);
            }
            k += n as u32;
        }
        None
    }
}

impl<T: Sample> DvrChunks<'_, '_, T> {
    /// Samples `k..k + n` (`n ≤ LANES`) into `acc`; `Some(i)` when the ray
    /// reached the opacity threshold at the chunk's sample `i − 1`.
    #[inline(always)]
    fn chunk(&self, acc: &mut Accumulation, k: u32, n: usize) -> Option<u32> {
        let BrickVisit {
            plan,
            volume,
            brick,
            ray,
        } = self.visit;
        // Opacity changes only at visible samples, so checking the threshold
        // after those alone stops where the scalar loop's check after every
        // sample does (a ray starts below the threshold, which is above 0).
        debug_assert!(acc.alpha < plan.ert_threshold);
        let sampler = &brick.sampler;
        let table = self.dvr.table;
        // Positions, and where they lie in the brick's cells.
        let p = self.positions.at_lanes(k);
        let origin = sampler.origin_lanes();
        let local: [Vec4; 3] = [0, 1, 2].map(|a| p[a] - Vec4::splat(origin[a]));
        let lower = local.map(Vec4::floor);
        let fraction: [Vec4; 3] = [0, 1, 2].map(|a| local[a] - lower[a]);
        // Per lane (`Vec4` indexing by a variable is a branch per read).
        let arrays = |v: [Vec4; 3]| v.map(|v| v.to_array());
        let (p_at, local_at) = (arrays(p), arrays(local));
        let (lower_at, fraction_at) = (arrays(lower), arrays(fraction));
        let lane = |v: &[[f32; LANES]; 3], i: usize| Vec3A::new(v[0][i], v[1][i], v[2][i]);
        // Values: a cell's lanes from its corners (consecutive samples share
        // it), a sample outside the brick's cells (its upper face) on its own.
        let mut rgba = [Vec4::ZERO; LANES];
        let mut visible = [false; LANES];
        let mut any_visible = false;
        let mut gradient = [Vec4::ZERO; LANES];
        let mut i = 0;
        while i < n {
            let cell_lower = lane(&lower_at, i);
            let in_cell = CellCache::is_cell(sampler, cell_lower);
            let mut to = i + 1;
            if in_cell {
                while to < n && lane(&lower_at, to).cmpeq(cell_lower).all() {
                    to += 1;
                }
            }
            // The group's values at their lanes (the others' are not used).
            let value = if in_cell {
                let corners = self.cell.corners_of(sampler, cell_lower);
                corners.trilinear_lanes(fraction).to_array()
            } else {
                [sampler.value_local(lane(&local_at, i).into()); LANES]
            };
            // Classification, and the gradients of the visible samples.
            for j in i..to {
                rgba[j] = Vec4::from_array(table.lookup(value[j]));
                visible[j] = rgba[j].w > 0.0;
                if !visible[j] {
                    continue;
                }
                any_visible = true;
                if self.shade.is_none() {
                    continue;
                }
                let g = self.cell.gradient_in_cell(
                    volume,
                    sampler,
                    lane(&p_at, j).into(),
                    in_cell.then(|| lane(&fraction_at, j)),
                );
                gradient[j] = (g * plan.gradient_scale).extend(0.0);
            }
            i = to;
        }
        if !any_visible {
            return None;
        }
        // Blinn-Phong in lanes, channels and axes transposed into lanes.
        if let Some((shading, lights)) = &self.shade {
            let colors = Mat4::from_cols(rgba[0], rgba[1], rgba[2], rgba[3]).transpose();
            let g = Mat4::from_cols(gradient[0], gradient[1], gradient[2], gradient[3]).transpose();
            let [r, gr, b] = shading.shade_lanes(
                [colors.x_axis, colors.y_axis, colors.z_axis],
                [g.x_axis, g.y_axis, g.z_axis],
                *lights,
            );
            let shaded = Mat4::from_cols(r, gr, b, colors.w_axis).transpose();
            rgba = [shaded.x_axis, shaded.y_axis, shaded.z_axis, shaded.w_axis];
        }
        // "Over", sample after sample.
        let last_sample = ray.samples - 1;
        for j in 0..n {
            if !visible[j] {
                continue;
            }
            let [r, g, b, a] = rgba[j].to_array();
            let last = (last_sample, ray.last_fraction);
            let (color, alpha) = (&mut acc.color, &mut acc.alpha);
            if over_sample(
                color,
                alpha,
                ([r, g, b], a),
                k + j as u32,
                last,
                plan.ert_threshold,
            ) {
                return Some(j as u32 + 1);
            }
        }
        None
    }
}
