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
use super::march::BrickContext;
use super::optics::{partial_step, specular_power};
use super::pixel::{PixelRay, PixelState};
use super::prepared::FramePlan;
use super::runs::SampleRuns;
use super::sampler::VolumeSampler;
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
        _ => march_dvr_lanes(dvr, work),
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx2,fma,sse4.1")]
unsafe fn march_dvr_avx512<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes(dvr, work)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2,fma,sse4.1")]
unsafe fn march_dvr_avx2<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes(dvr, work)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "sse4.1")]
unsafe fn march_dvr_sse41<T: Sample>(
    dvr: &DvrLanes<'_>,
    work: &mut PacketWork<'_, '_, T, Accumulation>,
) {
    march_dvr_lanes(dvr, work)
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

#[inline(always)]
fn lerp(a: Lanes, b: Lanes, t: Lanes) -> Lanes {
    std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t[i])
}

/// The packet march, compiled once per level through the wrappers above.
#[inline(always)]
fn march_dvr_lanes<T: Sample>(dvr: &DvrLanes<'_>, work: &mut PacketWork<'_, '_, T, Accumulation>) {
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
                    let item = work.items[lane.item];
                    let state = &mut work.states[item.pixel];
                    state.acc.color = [acc[0][l], acc[1][l], acc[2][l]];
                    state.acc.alpha = acc[3][l];
                    work.counters.samples += lane.taken;
                    work.counters.samples_skipped_empty += lane.runs.skipped;
                    finish_visit(c, state, lane.ray, item.last + 1);
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
                    finish_visit(c, state, ray, item.last + 1);
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
        let busy: [bool; LANES] = std::array::from_fn(|l| lanes[l].is_some());
        step(dvr, plan, work.volume, brick, &input, busy, &mut acc);
        // Advance; stop lanes whose ray reached the opacity threshold.
        for l in 0..LANES {
            let Some(lane) = &mut lanes[l] else { continue };
            lane.taken += 1;
            lane.k += 1;
            if acc[3][l] >= plan.ert_threshold {
                let lane = lanes[l].take().expect("lane is busy");
                let item = work.items[lane.item];
                let state = &mut work.states[item.pixel];
                state.acc.color = [acc[0][l], acc[1][l], acc[2][l]];
                state.acc.alpha = acc[3][l];
                work.counters.samples += lane.taken;
                work.counters.samples_skipped_empty += lane.runs.skipped;
                work.counters.rays_terminated += 1;
                state.done = true;
                state.next_sample = lane.k;
                super::compositor::Compositor::close(c, &mut state.acc);
            }
        }
    }
}

/// Ends a ray's visit of the brick at sample `next` (as the scalar loop does).
#[inline(always)]
fn finish_visit(
    c: &super::local::Dvr,
    state: &mut PixelState<Accumulation>,
    ray: &PixelRay,
    next: u32,
) {
    state.next_sample = next;
    if next >= ray.samples {
        state.done = true;
        super::compositor::Compositor::close(c, &mut state.acc);
    }
}

/// One sample in every lane: trilinear value, classification, gradient and
/// shading where visible, and the "over" step into `acc` for busy lanes.
#[inline(always)]
fn step<T: Sample>(
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
    let local: [Lanes; 3] =
        std::array::from_fn(|a| std::array::from_fn(|i| input.p[a][i] - origin[a]));
    let cell: [[u32; LANES]; 3] = std::array::from_fn(|a| {
        std::array::from_fn(|i| (local[a][i] as u32).min(geometry.max_cell[a]))
    });
    let frac: [Lanes; 3] =
        std::array::from_fn(|a| std::array::from_fn(|i| local[a][i] - cell[a][i] as f32));
    // Gather the eight corners.
    let samples = sampler.samples();
    let [ox, oy, oz] = geometry.corner_stride;
    let [sx, sy, _] = geometry.strides;
    let mut corner = [[0.0f32; LANES]; 8];
    for i in 0..LANES {
        let base = cell[0][i] as usize * sx + cell[1][i] as usize * sy + cell[2][i] as usize;
        let s = &samples[base..][..=ox + oy + oz];
        let v = |o: usize| f32::from(s[o].to_u16());
        corner[0][i] = v(0);
        corner[1][i] = v(oz);
        corner[2][i] = v(oy);
        corner[3][i] = v(oy + oz);
        corner[4][i] = v(ox);
        corner[5][i] = v(ox + oz);
        corner[6][i] = v(ox + oy);
        corner[7][i] = v(ox + oy + oz);
    }
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
        std::array::from_fn(|i| ((value[i] - offset) * scale + 0.5).max(0.0).min(top) as usize);
    let mut rgba = [[0.0f32; LANES]; 4];
    for i in 0..LANES {
        let e = entries[index[i]];
        for (ch, v) in rgba.iter_mut().zip(e) {
            ch[i] = v;
        }
    }
    let visible: [bool; LANES] = std::array::from_fn(|i| busy[i] && rgba[3][i] > 0.0);
    if !visible.iter().any(|&v| v) {
        return;
    }
    let mut color = [rgba[0], rgba[1], rgba[2]];
    if let Some(shading) = &dvr.shading {
        let gradient = gradients(plan, volume, brick, input, &local, visible);
        color = shade(shading, color, &gradient, &input.view);
    }
    // Opacity of a partial last step, then "over".
    let alpha: Lanes = std::array::from_fn(|i| {
        if input.fraction[i] < 1.0 {
            partial_step(rgba[3][i], input.fraction[i])
        } else {
            rgba[3][i]
        }
    });
    let w: Lanes = std::array::from_fn(|i| (1.0 - acc[3][i]) * alpha[i]);
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
/// neighbourhood in lanes where it lies inside the brick (the scalar
/// `gradient_interior`'s arithmetic), else one lane at a time through the
/// volume sampler.
#[inline(always)]
fn gradients<T: Sample>(
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
    // Per lane: the neighbourhood's z-runs the six reads use, as in
    // `gradient_interior`: runs (1,1) (1,2) (2,1) (2,2) whole, the others'
    // middle pair.
    let mut whole_runs = [[[0.0f32; LANES]; 4]; 4];
    let mut mid_runs = [[[0.0f32; LANES]; 2]; 8];
    let mut interior = [false; LANES];
    let mut fallback: [Vec3; LANES] = [Vec3::ZERO; LANES];
    let mut cell_frac = [[0.0f32; LANES]; 3];
    const MID: [(usize, usize); 8] = [
        (0, 1),
        (0, 2),
        (1, 0),
        (1, 3),
        (2, 0),
        (2, 3),
        (3, 1),
        (3, 2),
    ];
    const WHOLE: [(usize, usize); 4] = [(1, 1), (1, 2), (2, 1), (2, 2)];
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
        let base = (ix - 1) as usize * sx + (iy - 1) as usize * sy + (iz - 1) as usize;
        let block = &samples[base..][..3 * sx + 3 * sy + 4];
        let f = |v: T| f32::from(v.to_u16());
        for (r, &(x, y)) in WHOLE.iter().enumerate() {
            let run = &block[x * sx + y * sy..][..4];
            for (z, &v) in run.iter().enumerate() {
                whole_runs[r][z][i] = f(v);
            }
        }
        for (r, &(x, y)) in MID.iter().enumerate() {
            let run = &block[x * sx + y * sy + 1..][..2];
            mid_runs[r][0][i] = f(run[0]);
            mid_runs[r][1][i] = f(run[1]);
        }
    }
    let [fx, fy, fz] = cell_frac;
    // z-lerp of a whole run for the cell below (0), itself (1), above (2).
    let zl = |r: &[Lanes; 4], k: usize| lerp(r[k], r[k + 1], fz);
    let zm = |r: &[Lanes; 2]| lerp(r[0], r[1], fz);
    let tri = |c00: Lanes, c01: Lanes, c10: Lanes, c11: Lanes| {
        lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx)
    };
    let [r11, r12, r21, r22] = &whole_runs;
    let (m01, m02) = (zm(&mid_runs[0]), zm(&mid_runs[1]));
    let (m10, m13) = (zm(&mid_runs[2]), zm(&mid_runs[3]));
    let (m20, m23) = (zm(&mid_runs[4]), zm(&mid_runs[5]));
    let (m31, m32) = (zm(&mid_runs[6]), zm(&mid_runs[7]));
    let (m11, m12, m21, m22) = (zl(r11, 1), zl(r12, 1), zl(r21, 1), zl(r22, 1));
    let sub = |a: Lanes, b: Lanes| -> Lanes { std::array::from_fn(|i| a[i] - b[i]) };
    let gx = sub(tri(m21, m22, m31, m32), tri(m01, m02, m11, m12));
    let gy = sub(tri(m12, m13, m22, m23), tri(m10, m11, m20, m21));
    let gz = sub(
        tri(zl(r11, 2), zl(r12, 2), zl(r21, 2), zl(r22, 2)),
        tri(zl(r11, 0), zl(r12, 0), zl(r21, 0), zl(r22, 0)),
    );
    let scale = plan.gradient_scale.to_array();
    let raw = [gx, gy, gz];
    std::array::from_fn(|a| {
        std::array::from_fn(|i| {
            let g = if interior[i] {
                raw[a][i] * 0.5
            } else {
                fallback[i].to_array()[a]
            };
            g * scale[a]
        })
    })
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
    let magnitude: Lanes =
        std::array::from_fn(|i| (gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]).sqrt());
    let normal: [Lanes; 3] =
        std::array::from_fn(|a| std::array::from_fn(|i| gradient[a][i] / magnitude[i]));
    let dot = |u: &[Lanes; 3], v: &[Lanes; 3]| -> Lanes {
        std::array::from_fn(|i| u[0][i] * v[0][i] + u[1][i] * v[1][i] + u[2][i] * v[2][i])
    };
    let (to_light, half): ([Lanes; 3], [Lanes; 3]) = match shading.light {
        Light::Headlight => {
            let l = std::array::from_fn(|a| std::array::from_fn(|i| -view[a][i]));
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
