//! Ray packets: the rays of one (tile, brick) task marched through the brick
//! [`LANES`] at a time, each sample's reconstruction, classification, shading and
//! compositing computed in SIMD lanes.
//!
//! A lane holds one ray's walk through the brick: its [`SampleRuns`] (cell
//! skipping stays per ray), its next sample and its accumulated colour. Each step
//! takes one sample in every busy lane; a lane whose ray leaves the brick or
//! terminates takes the task's next ray, so lanes stay full until the task's rays
//! run out. Per step, the loads (the trilinear cell, the gradient's
//! neighbourhood, the transfer-table entry) are gathered lane by lane into arrays,
//! and the arithmetic runs over the arrays — loops of [`LANES`] that the compiler
//! turns into vector instructions of the level the kernel was compiled for
//! ([`SimdLevel`]; chosen once per frame, the function for it compiled with that
//! instruction set enabled).
//!
//! The arithmetic is the scalar kernel's, operation for operation (no fused
//! multiply-adds: Rust does not contract `a * b + c`), so a packet composites the
//! same samples to the same bits as [`super::march::march_brick`] with
//! [`super::local`]'s `Dvr` — which the tests check on every level this machine has.

// Lane loops index several per-lane arrays by the lane number: written as
// `for l in 0..LANES`, which is also the shape the vectoriser expects.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

use super::counters::Counters;
use super::local::Accumulation;
use super::march::{BrickContext, end_visit, stop_ray};
use super::optics::{partial_step, specular_power};
use super::pixel::{PixelRay, PixelState};
use super::prepared::FramePlan;
use super::runs::SampleRuns;
use super::sampler::{Neighbourhood, VolumeSampler};
use super::shading::{Light, Shading};
use super::simd::SimdLevel;
use super::transfer::TransferTable;
use crate::volume::Sample;

/// Rays per packet.
pub(crate) const LANES: usize = 8;

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

/// A task's rays, ready for a packet march.
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

/// Emission–absorption DVR with a 1D transfer table, shaded or not: the
/// compositor the packet kernel runs.
pub(crate) struct DvrLanes<'t> {
    /// The frame's table (opacities corrected for the step).
    pub table: &'t TransferTable,
    /// Blinn-Phong, if shading.
    pub shading: Option<Shading>,
    /// The compositor, for its emptiness rule and closing.
    pub runs_compositor: &'t super::local::Dvr,
}

/// Marches `work`'s rays in packets at `level` (not [`SimdLevel::Scalar`]).
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
        _ => march_dvr_lanes::<T, LaneLoads>(dvr, work),
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx2,fma,sse4.1")]
unsafe fn march_dvr_avx512<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes::<T, gather::Avx2Gathers>(dvr, work)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2,fma,sse4.1")]
unsafe fn march_dvr_avx2<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes::<T, gather::Avx2Gathers>(dvr, work)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "sse4.1")]
unsafe fn march_dvr_sse41<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes::<T, LaneLoads>(dvr, work)
}

/// Per lane: `[f32; LANES]`.
type Lanes = [f32; LANES];

/// One busy lane: a ray in the brick.
struct Lane<'r> {
    /// Index into the task's items.
    item: usize,
    ray: &'r PixelRay,
    runs: SampleRuns<'r, super::local::Dvr>,
    /// Next sample and one past the current run's last.
    k: u32,
    end: u32,
    taken: u64,
}

/// What a step needs of each lane, gathered into arrays.
#[derive(Default)]
struct StepInput {
    /// Sample positions (voxel coordinates, clamped into the volume).
    p: [Lanes; 3],
    /// The part of a step each sample stands for.
    fraction: Lanes,
    /// Unit view directions.
    view: [Lanes; 3],
}

/// `[f(0), f(1), …]`, written as a plain loop: `std::array::from_fn` calls its
/// closure through a function the compiler does not always inline, which keeps
/// lane loops from vectorising.
#[inline(always)]
fn each<U: Copy + Default, const N: usize>(f: impl Fn(usize) -> U) -> [U; N] {
    let mut out = [U::default(); N];
    for (i, o) in out.iter_mut().enumerate() {
        *o = f(i);
    }
    out
}

#[inline(always)]
fn lerp(a: Lanes, b: Lanes, t: Lanes) -> Lanes {
    each(|i| a[i] + (b[i] - a[i]) * t[i])
}

/// The packet march, compiled once per level through the wrappers above.
#[inline(always)]
fn march_dvr_lanes<T: Sample, G: Gather>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    let plan = work.plan;
    let brick = work.brick;
    let ess = plan.empty_space_skipping;
    let cells = if ess { brick.cell_grid() } else { None };
    let last_voxel = work.volume.last();
    let c = dvr.runs_compositor;
    let mut lanes: [Option<Lane<'_>>; LANES] = Default::default();
    // Accumulated colour and opacity per lane.
    let mut acc: [Lanes; 4] = [[0.0; LANES]; 4];
    let mut next_item = 0;
    loop {
        // Give every lane a run to take a sample from.
        for l in 0..LANES {
            loop {
                if let Some(lane) = &mut lanes[l] {
                    if lane.k < lane.end {
                        break;
                    }
                    if let Some(run) = lane.runs.next() {
                        (lane.k, lane.end) = (run.first, run.end);
                        continue;
                    }
                    // The ray leaves the brick.
                    let lane = lanes[l].take().expect("lane is busy");
                    let pixel = retire(work, &lane, &acc, l);
                    let next = work.items[lane.item].last + 1;
                    end_visit(c, &mut work.states[pixel], lane.ray, next);
                }
                let Some(&item) = work.items.get(next_item) else {
                    break;
                };
                next_item += 1;
                let state = &mut work.states[item.pixel];
                let Some(ray) = &work.rays[item.pixel] else {
                    continue;
                };
                if state.done || item.first > item.last {
                    continue;
                }
                if ess && brick.transparent {
                    work.counters.samples_skipped_empty += u64::from(item.last - item.first + 1);
                    work.counters.brick_visits_skipped += 1;
                    end_visit(c, state, ray, item.last + 1);
                    continue;
                }
                work.counters.brick_visits += 1;
                acc[0][l] = state.acc.color[0];
                acc[1][l] = state.acc.color[1];
                acc[2][l] = state.acc.color[2];
                acc[3][l] = state.acc.alpha;
                lanes[l] = Some(Lane {
                    item: next_item - 1,
                    ray,
                    runs: SampleRuns::new(c, ray, cells, last_voxel, item.first, item.last),
                    k: 0,
                    end: 0,
                    taken: 0,
                });
            }
        }
        if lanes.iter().all(Option::is_none) {
            break;
        }
        // Gather the step's inputs; an idle lane samples the brick's origin and
        // its result is thrown away.
        let mut input = StepInput::default();
        let origin = brick.sampler.origin();
        for l in 0..LANES {
            let (p, fraction, view) = match &lanes[l] {
                Some(lane) => {
                    let ray = lane.ray;
                    let fraction = if lane.k == ray.samples - 1 {
                        ray.last_fraction
                    } else {
                        1.0
                    };
                    (ray.position(lane.k, last_voxel), fraction, ray.view_dir)
                }
                None => (origin, 1.0, Vec3::Z),
            };
            for a in 0..3 {
                input.p[a][l] = p.to_array()[a];
                input.view[a][l] = view.to_array()[a];
            }
            input.fraction[l] = fraction;
        }
        let busy: [bool; LANES] = each(|l| lanes[l].is_some());
        step::<T, G>(dvr, plan, work.volume, brick, &input, busy, &mut acc);
        // Advance; stop lanes whose ray reached the opacity threshold.
        for l in 0..LANES {
            let Some(lane) = &mut lanes[l] else { continue };
            lane.taken += 1;
            lane.k += 1;
            if acc[3][l] >= plan.ert_threshold {
                let lane = lanes[l].take().expect("lane is busy");
                let pixel = retire(work, &lane, &acc, l);
                stop_ray(c, &mut work.states[pixel], lane.k, work.counters);
            }
        }
    }
}

/// Writes lane `l`'s accumulated colour and opacity and its counts back to its
/// ray's pixel; returns the pixel's index in the tile.
#[inline(always)]
fn retire<T: Sample>(
    work: &mut PacketWork<'_, '_, T, Accumulation>,
    lane: &Lane<'_>,
    acc: &[Lanes; 4],
    l: usize,
) -> usize {
    let pixel = work.items[lane.item].pixel;
    let state = &mut work.states[pixel];
    state.acc.color = [acc[0][l], acc[1][l], acc[2][l]];
    state.acc.alpha = acc[3][l];
    work.counters.samples += lane.taken;
    work.counters.samples_skipped_empty += lane.runs.skipped;
    pixel
}

/// One sample in every lane: trilinear value, classification, gradient and
/// shading where visible, and the "over" step into `acc` for busy lanes.
#[inline(always)]
fn step<T: Sample, G: Gather>(
    dvr: &DvrLanes<'_>,
    plan: &FramePlan,
    volume: &VolumeSampler<'_, T>,
    brick: &BrickContext<'_, T>,
    input: &StepInput,
    busy: [bool; LANES],
    acc: &mut [Lanes; 4],
) {
    let sampler = &brick.sampler;
    let geometry = sampler.cell_geometry();
    let origin = sampler.origin().to_array();
    // Local positions, cells and fractions (the scalar `value_local`).
    let local: [Lanes; 3] = each(|a| each(|i| input.p[a][i] - origin[a]));
    let cell: [[u32; LANES]; 3] = each(|a| {
        // `as i32` then 0 at least: the scalar `as u32` for every finite value
        // (and NaN), but a conversion the vector units have.
        each(|i| ((local[a][i] as i32).max(0) as u32).min(geometry.max_cell[a]))
    });
    let frac: [Lanes; 3] = each(|a| each(|i| local[a][i] - cell[a][i] as f32));
    // Gather the eight corners.
    let samples = sampler.samples();
    let [ox, oy, oz] = geometry.corner_stride;
    let [sx, sy, _] = geometry.strides;
    let base: [usize; LANES] =
        each(|i| cell[0][i] as usize * sx + cell[1][i] as usize * sy + cell[2][i] as usize);
    let offsets = [0, oz, oy, oy + oz, ox, ox + oz, ox + oy, ox + oy + oz];
    let base = G::base(samples, &base, ox + oy + oz + 1);
    let corner: [Lanes; 8] = each(|c| G::samples(samples, &base, offsets[c]));
    let [fx, fy, fz] = frac;
    let c00 = lerp(corner[0], corner[1], fz);
    let c01 = lerp(corner[2], corner[3], fz);
    let c10 = lerp(corner[4], corner[5], fz);
    let c11 = lerp(corner[6], corner[7], fz);
    let value = lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx);
    // Classification (the table's nearest entry, as `TransferTable::index`).
    let (offset, scale, top) = dvr.table.index_parameters();
    let entries = dvr.table.entries();
    let index: [usize; LANES] =
        each(|i| ((value[i] - offset) * scale + 0.5).max(0.0).min(top) as usize);
    let rgba: [Lanes; 4] = each(|ch| G::entries(entries, &index, ch));
    let visible: [bool; LANES] = each(|i| busy[i] && rgba[3][i] > 0.0);
    if !visible.iter().any(|&v| v) {
        return;
    }
    let mut color = [rgba[0], rgba[1], rgba[2]];
    if let Some(shading) = &dvr.shading {
        let gradient = gradients::<T, G>(plan, volume, brick, input, &local, visible);
        color = shade(shading, color, &gradient, &input.view);
    }
    // Opacity of a partial last step, then "over".
    let alpha: Lanes = each(|i| {
        if input.fraction[i] < 1.0 {
            partial_step(rgba[3][i], input.fraction[i])
        } else {
            rgba[3][i]
        }
    });
    let w: Lanes = each(|i| (1.0 - acc[3][i]) * alpha[i]);
    for ch in 0..3 {
        for i in 0..LANES {
            let next = acc[ch][i] + w[i] * color[ch][i];
            acc[ch][i] = if visible[i] { next } else { acc[ch][i] };
        }
    }
    for i in 0..LANES {
        let next = acc[3][i] + w[i];
        acc[3][i] = if visible[i] { next } else { acc[3][i] };
    }
}

/// The scaled gradient of every visible lane: from the brick's 4×4×4
/// neighbourhood in lanes where it lies inside the brick (the arithmetic of the
/// scalar `corner_differences` and `gradient_from_differences`), else one lane
/// at a time through the volume sampler.
#[inline(always)]
fn gradients<T: Sample, G: Gather>(
    plan: &FramePlan,
    volume: &VolumeSampler<'_, T>,
    brick: &BrickContext<'_, T>,
    input: &StepInput,
    local: &[Lanes; 3],
    visible: [bool; LANES],
) -> [Lanes; 3] {
    let sampler = &brick.sampler;
    let geometry = sampler.cell_geometry();
    let extent = geometry.extent;
    let [sx, sy, _] = geometry.strides;
    let samples = sampler.samples();
    let mut interior = [false; LANES];
    let mut fallback: [Vec3; LANES] = [Vec3::ZERO; LANES];
    let mut cell_frac = [[0.0f32; LANES]; 3];
    // The neighbourhood's first voxel per lane; lanes without an interior
    // neighbourhood read an interior lane's (their values are not used).
    let mut base = [usize::MAX; LANES];
    for i in 0..LANES {
        if !visible[i] {
            continue;
        }
        let l = [local[0][i], local[1][i], local[2][i]];
        let inside = l[0] >= 1.0 && l[1] >= 1.0 && l[2] >= 1.0 && {
            let (ix, iy, iz) = (l[0] as u32, l[1] as u32, l[2] as u32);
            ix + 2 < extent[0] && iy + 2 < extent[1] && iz + 2 < extent[2]
        };
        if !inside {
            let p = Vec3::new(input.p[0][i], input.p[1][i], input.p[2][i]);
            fallback[i] = volume.gradient(sampler, p);
            continue;
        }
        interior[i] = true;
        let (ix, iy, iz) = (l[0] as u32, l[1] as u32, l[2] as u32);
        cell_frac[0][i] = l[0] - ix as f32;
        cell_frac[1][i] = l[1] - iy as f32;
        cell_frac[2][i] = l[2] - iz as f32;
        base[i] = (ix - 1) as usize * sx + (iy - 1) as usize * sy + (iz - 1) as usize;
    }
    let scale = plan.gradient_scale.to_array();
    // Every lane's gradient scaled, from `raw` (halved) where the lane is
    // interior, else from its fallback.
    let scaled = |raw: &[Lanes; 3]| -> [Lanes; 3] {
        each(|a| {
            each(|i| {
                let g = if interior[i] {
                    raw[a][i] * 0.5
                } else {
                    fallback[i].to_array()[a]
                };
                g * scale[a]
            })
        })
    };
    let Some(&any) = base.iter().find(|&&b| b != usize::MAX) else {
        return scaled(&[[0.0; LANES]; 3]);
    };
    for b in &mut base {
        if *b == usize::MAX {
            *b = any;
        }
    }
    // The neighbourhood gathered lane by lane (written-out loops: gathers
    // through closures are not inlined and cost a tenth more per sample), and
    // its corner differences by the scalar kernel's definition.
    let base = G::base(samples, &base, 3 * sx + 3 * sy + 4);
    // Runs (1,1) (1,2) (2,1) (2,2) whole; the outer columns' middle pairs.
    const WHOLE: [(usize, usize); 4] = [(1, 1), (1, 2), (2, 1), (2, 2)];
    const MID: [(usize, usize); 8] = [
        (0, 1),
        (0, 2),
        (3, 1),
        (3, 2),
        (1, 0),
        (2, 0),
        (1, 3),
        (2, 3),
    ];
    let mut whole = [[[0.0f32; LANES]; 4]; 4];
    let mut mid = [[[0.0f32; LANES]; 2]; 8];
    for (r, &(x, y)) in WHOLE.iter().enumerate() {
        for z in 0..4 {
            whole[r][z] = G::samples(samples, &base, x * sx + y * sy + z);
        }
    }
    for (r, &(x, y)) in MID.iter().enumerate() {
        for z in 0..2 {
            mid[r][z] = G::samples(samples, &base, x * sx + y * sy + 1 + z);
        }
    }
    let d = Neighbourhood {
        inner: [[whole[0], whole[1]], [whole[2], whole[3]]],
        x_below: [mid[0], mid[1]],
        x_above: [mid[2], mid[3]],
        y_below: [mid[4], mid[5]],
        y_above: [mid[6], mid[7]],
    }
    .differences_by(|a: Lanes, b: Lanes| each(|i| a[i] - b[i]));
    let [fx, fy, fz] = cell_frac;
    let tri = |c: &[Lanes; 8]| {
        let c00 = lerp(c[0], c[1], fz);
        let c01 = lerp(c[2], c[3], fz);
        let c10 = lerp(c[4], c[5], fz);
        let c11 = lerp(c[6], c[7], fz);
        lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx)
    };
    scaled(&[tri(&d[0]), tri(&d[1]), tri(&d[2])])
}

/// Blinn-Phong in lanes: `Shading::shade`, operation for operation.
#[inline(always)]
fn shade(
    shading: &Shading,
    color: [Lanes; 3],
    gradient: &[Lanes; 3],
    view: &[Lanes; 3],
) -> [Lanes; 3] {
    let [gx, gy, gz] = gradient;
    let magnitude: Lanes = each(|i| (gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]).sqrt());
    let normal: [Lanes; 3] = each(|a| each(|i| gradient[a][i] / magnitude[i]));
    let dot = |u: &[Lanes; 3], v: &[Lanes; 3]| -> Lanes {
        each(|i| u[0][i] * v[0][i] + u[1][i] * v[1][i] + u[2][i] * v[2][i])
    };
    let (to_light, half): ([Lanes; 3], [Lanes; 3]) = match shading.light {
        Light::Headlight => {
            let l = each(|a| each(|i| -view[a][i]));
            (l, l)
        }
        Light::Fixed(d) => {
            let l = (-d.normalize_or_zero()).to_array();
            let mut to_light = [[0.0; LANES]; 3];
            let mut half = [[0.0; LANES]; 3];
            for i in 0..LANES {
                let v = Vec3::new(view[0][i], view[1][i], view[2][i]);
                let h = (Vec3::from(l) - v).normalize_or_zero().to_array();
                for a in 0..3 {
                    to_light[a][i] = l[a];
                    half[a][i] = h[a];
                }
            }
            (to_light, half)
        }
    };
    let nl = dot(&normal, &to_light);
    let nh = dot(&normal, &half);
    let mut out = color;
    for i in 0..LANES {
        let specular = shading.specular * specular_power(nh[i].abs(), shading.shininess);
        let k = shading.ambient + shading.diffuse * nl[i].abs();
        let lit = magnitude[i] > shading.gradient_threshold;
        for ch in 0..3 {
            let shaded = (color[ch][i] * k + specular).min(1.0);
            out[ch][i] = if lit { shaded } else { color[ch][i] };
        }
    }
    out
}

/// How a kernel reads one value per lane from scattered places.
trait Gather {
    /// Per-lane starting points prepared for several reads at offsets below a
    /// reach.
    type Base: Copy;
    /// Prepares `base` for reads `samples[base[i] + offset]`, `offset < reach`
    /// (every such index in bounds).
    fn base<T: Sample>(samples: &[T], base: &[usize; LANES], reach: usize) -> Self::Base;
    /// `samples[base[i] + offset]` per lane, as `f32`.
    fn samples<T: Sample>(samples: &[T], base: &Self::Base, offset: usize) -> Lanes;
    /// Channel `ch` of `entries[index[i]]` per lane (every index in bounds).
    fn entries(entries: &[[f32; 4]], index: &[usize; LANES], ch: usize) -> Lanes;
}

/// One load per lane (SSE4.1, NEON, and the fallback of the gathers).
struct LaneLoads;

impl Gather for LaneLoads {
    type Base = [usize; LANES];
    #[inline(always)]
    fn base<T: Sample>(_samples: &[T], base: &[usize; LANES], _reach: usize) -> [usize; LANES] {
        *base
    }
    #[inline(always)]
    fn samples<T: Sample>(samples: &[T], base: &[usize; LANES], offset: usize) -> Lanes {
        each(|i| f32::from(samples[base[i] + offset].to_u16()))
    }
    #[inline(always)]
    fn entries(entries: &[[f32; 4]], index: &[usize; LANES], ch: usize) -> Lanes {
        each(|i| entries[index[i]][ch])
    }
}

#[cfg(target_arch = "x86_64")]
mod gather {
    //! AVX2 gathers: eight loads in one instruction.
    #![allow(unsafe_code)]

    use std::arch::x86_64::{
        __m256i, _mm256_add_epi32, _mm256_and_si256, _mm256_cvtepi32_ps, _mm256_i32gather_epi32,
        _mm256_i32gather_ps, _mm256_loadu_si256, _mm256_set1_epi32, _mm256_storeu_ps,
    };

    use super::{Gather, LANES, LaneLoads, Lanes, each};
    use crate::volume::Sample;

    /// Hardware gathers (AVX2 and AVX-512 levels only).
    pub(super) struct Avx2Gathers;

    /// Where eight lanes read: byte offsets from a common first sample, or
    /// plain indices when the words would leave the slice.
    #[derive(Clone, Copy)]
    pub(super) enum Words {
        /// The lanes' byte offsets from sample `first`.
        Gather { first: usize, bytes: __m256i },
        /// One load per lane.
        Lanes([usize; LANES]),
    }

    impl Gather for Avx2Gathers {
        type Base = Words;

        #[inline(always)]
        fn base<T: Sample>(samples: &[T], base: &[usize; LANES], reach: usize) -> Words {
            let size = size_of::<T>();
            let (mut first, mut last) = (base[0], base[0]);
            for &b in base {
                first = first.min(b);
                last = last.max(b);
            }
            let last = last + reach.saturating_sub(1);
            // Each read takes the 4-byte word at its sample: the words must lie
            // in the slice and the byte offsets from `first` fit an i32.
            let words_fit = last * size + 4 <= size_of_val(samples);
            let span_fits = (last - first + 1) * size < i32::MAX as usize;
            if !(words_fit && span_fits) {
                return Words::Lanes(*base);
            }
            let bytes: [i32; LANES] = each(|i| ((base[i] - first) * size) as i32);
            // SAFETY: AVX2 is present (see `samples`); an unaligned load of the
            // 32 bytes of `bytes`.
            let bytes = unsafe { load(&bytes) };
            Words::Gather { first, bytes }
        }

        #[inline(always)]
        fn samples<T: Sample>(samples: &[T], base: &Words, offset: usize) -> Lanes {
            match *base {
                Words::Lanes(base) => LaneLoads::samples(samples, &base, offset),
                Words::Gather { first, bytes } => {
                    let size = size_of::<T>();
                    let mask = if size == 1 { 0xff } else { 0xffff };
                    // SAFETY: only the AVX2 and AVX-512 kernels use this type,
                    // and the frame plan picks them only where `simd::available`
                    // detected AVX2. `base` checked that every word from
                    // `samples[first]` plus a lane's byte offset plus
                    // `offset·size` (offset below the reach) lies in `samples`.
                    unsafe {
                        gather_words(
                            samples.as_ptr().add(first).cast::<u8>(),
                            bytes,
                            (offset * size) as i32,
                            mask,
                        )
                    }
                }
            }
        }

        #[inline(always)]
        fn entries(entries: &[[f32; 4]], index: &[usize; LANES], ch: usize) -> Lanes {
            let len = entries.len() * 4;
            let mut last = 0;
            for &i in index {
                last = last.max(i);
            }
            if ch >= 4 || last * 4 + ch >= len || len > i32::MAX as usize {
                return LaneLoads::entries(entries, index, ch);
            }
            let floats: [i32; LANES] = each(|i| (index[i] * 4 + ch) as i32);
            // SAFETY: AVX2 is present (as above); every float index is inside
            // `entries` viewed as `len` floats (checked above).
            unsafe { gather_floats(entries.as_ptr().cast::<f32>(), &floats) }
        }
    }

    /// Eight i32 as a vector.
    ///
    /// # Safety
    /// AVX2 must be available.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load(values: &[i32; LANES]) -> __m256i {
        // SAFETY: `values` is 32 readable bytes; the load is unaligned.
        unsafe { _mm256_loadu_si256(values.as_ptr().cast::<__m256i>()) }
    }

    /// The 32-bit words at `base + bytes[i] + offset`, masked with `mask`, as
    /// floats.
    ///
    /// # Safety
    /// AVX2 must be available, and each word `base + bytes[i] + offset .. + 4`
    /// readable.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gather_words(base: *const u8, bytes: __m256i, offset: i32, mask: i32) -> Lanes {
        // SAFETY: the gather reads only the words the caller vouches for.
        unsafe {
            let index = _mm256_add_epi32(bytes, _mm256_set1_epi32(offset));
            let words = _mm256_i32gather_epi32::<1>(base.cast::<i32>(), index);
            let values = _mm256_cvtepi32_ps(_mm256_and_si256(words, _mm256_set1_epi32(mask)));
            let mut out = [0.0f32; LANES];
            _mm256_storeu_ps(out.as_mut_ptr(), values);
            out
        }
    }

    /// The floats `base[floats[i]]`.
    ///
    /// # Safety
    /// AVX2 must be available, and each `base[floats[i]]` readable.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gather_floats(base: *const f32, floats: &[i32; LANES]) -> Lanes {
        // SAFETY: as `gather_words`.
        unsafe {
            let index = _mm256_loadu_si256(floats.as_ptr().cast::<__m256i>());
            let values = _mm256_i32gather_ps::<4>(base, index);
            let mut out = [0.0f32; LANES];
            _mm256_storeu_ps(out.as_mut_ptr(), values);
            out
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<T: Sample + From<u8>>() {
        let samples: Vec<T> = (0..300u32).map(|i| T::from((i * 37 % 251) as u8)).collect();
        let mut seed = 7u32;
        let mut next = |n: usize| {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as usize % n
        };
        for round in 0..400 {
            // Near the end of the slice in some rounds: the gathers fall back.
            let reach = 1 + next(20);
            let top = if round % 3 == 0 {
                samples.len() - reach
            } else {
                200
            };
            let base: [usize; LANES] = each(|_| 0);
            let base = base.map(|_| next(top + 1));
            let plain_base = LaneLoads::base(&samples, &base, reach);
            for offset in 0..reach {
                let expected = LaneLoads::samples(&samples, &plain_base, offset);
                #[cfg(target_arch = "x86_64")]
                if SimdLevel::Avx2.is_available() {
                    let wide = gather::Avx2Gathers::base(&samples, &base, reach);
                    assert_eq!(
                        gather::Avx2Gathers::samples(&samples, &wide, offset),
                        expected
                    );
                }
                for (i, &e) in expected.iter().enumerate() {
                    assert_eq!(e, f32::from(samples[base[i] + offset].to_u16()));
                }
            }
        }
        let entries: Vec<[f32; 4]> = (0..1024)
            .map(|i| [i as f32, 1.0, 2.0, -(i as f32)])
            .collect();
        let index: [usize; LANES] = [0, 1023, 5, 77, 1023, 0, 512, 9];
        for ch in 0..4 {
            let expected = LaneLoads::entries(&entries, &index, ch);
            #[cfg(target_arch = "x86_64")]
            if SimdLevel::Avx2.is_available() {
                assert_eq!(gather::Avx2Gathers::entries(&entries, &index, ch), expected);
            }
            assert_eq!(expected[1], entries[1023][ch]);
        }
    }

    #[test]
    fn gathers_read_what_lane_loads_read_up_to_the_slice_end() {
        check::<u8>();
        check::<u16>();
    }
}
