//! The marching kernel: one ray through one brick into one pixel's state.
//!
//! Both the sequential and the parallel renderer call [`march_brick`] (engineering
//! guide, invariant 1); they differ only in the order they hand it bricks. A brick
//! handles the samples whose positions it owns ([`owned_samples`]), so a ray's
//! samples are processed exactly once, in order, however the volume is cut.

use std::sync::Arc;

use glam::Vec3;

use super::cells::BrickCells;
use super::counters::Counters;
use super::geometry::VolumeGeometry;
use super::pixel::{PixelRay, PixelState};
use super::prepared::{FramePlan, RenderVolume};
use super::ray::Ray;
use super::sampler::{BrickSampler, VolumeSampler};
use super::settings::Mode;
use super::two_level::{SampleContext, SegmentPlan, close_segment};
use crate::volume::{BrickView, Sample, TypedVolume, VolumeData};

/// Slack around a brick's box when estimating its samples: ownership, not this
/// box, decides, so the estimate only has to be generous.
const BOX_SLACK: f32 = 1e-3;

/// A brick ready to be marched.
#[derive(Clone, Debug)]
pub struct BrickContext<'a, T: Sample> {
    /// Brick coordinates in the grid.
    pub coords: [u32; 3],
    /// Local trilinear reads.
    pub sampler: BrickSampler<'a, T>,
    /// Smallest and largest voxel value in the brick.
    pub range: [u16; 2],
    /// The transfer function makes every value in the brick transparent.
    pub transparent: bool,
    /// Value ranges of the brick's small cells.
    cells: BrickCells,
    /// Per small cell: transparent under the frame's classification.
    cell_transparent: Vec<bool>,
    /// Cells per axis.
    cells_per_axis: u32,
    /// 1 / cell step.
    inv_cell_step: f32,
    /// The brick of the label volume (two-level scenes with labels).
    labels: Option<BrickView<'a, u8>>,
}

impl<'a, T: Sample> BrickContext<'a, T> {
    /// Brick `b` of `volume`'s grid; `data` is the volume's typed samples.
    pub fn new(
        data: &TypedVolume<'a, T>,
        volume: &'a RenderVolume<'_>,
        plan: &'a FramePlan,
        b: [u32; 3],
    ) -> Self {
        let grid = volume.geometry().grid();
        let index = grid.index(b);
        let cells = volume.cells();
        let range = volume.ranges().range(b);
        // A brick every ray skips is never read, not even for its cells.
        let ranges: BrickCells = if plan.brick_droppable(index as usize, range) {
            Arc::new([])
        } else {
            volume.cells_of(data, b)
        };
        BrickContext {
            coords: b,
            sampler: BrickSampler::new(volume.brick_view(data, b)),
            range,
            transparent: plan.transparent[index as usize],
            cell_transparent: ranges
                .iter()
                .map(|&[lo, hi]| plan.range_empty(lo, hi))
                .collect(),
            cells: ranges,
            cells_per_axis: cells.per_axis(),
            inv_cell_step: 1.0 / cells.cell_step() as f32,
            labels: volume.labels().map(|l| match l.data() {
                VolumeData::U8(ids) => volume.brick_view(&ids, b),
                VolumeData::U16(_) => unreachable!("label volumes are u8 (checked when attached)"),
            }),
        }
    }

    /// The label of the voxel nearest to volume position `p` (inside the brick).
    #[inline]
    fn label_at(&self, p: Vec3) -> u16 {
        let Some(view) = &self.labels else { return 0 };
        let e = view.extent();
        let l = (p - self.sampler.origin() + 0.5).max(Vec3::ZERO);
        let local = [
            (l.x as u32).min(e[0] - 1),
            (l.y as u32).min(e[1] - 1),
            (l.z as u32).min(e[2] - 1),
        ];
        u16::from(view.get(local))
    }

    /// The small cell of this brick owning volume position `p`.
    #[inline]
    fn cell_of(&self, p: Vec3) -> usize {
        let m = self.cells_per_axis;
        let c = (p - self.sampler.origin()) * self.inv_cell_step;
        let (cx, cy, cz) = (
            (c.x as u32).min(m - 1),
            (c.y as u32).min(m - 1),
            (c.z as u32).min(m - 1),
        );
        ((cx * m + cy) * m + cz) as usize
    }

    /// The first sample after `k` that may lie outside the cell holding sample `k`
    /// (at position `p`): every sample from `k` up to the returned index lies in that
    /// cell. Conservative by a sample, so rounding at the cell's faces never skips
    /// a sample of the next cell; always greater than `k`.
    #[inline]
    fn cell_exit(&self, ray: &PixelRay, p: Vec3, k: u32) -> u32 {
        let step = 1.0 / self.inv_cell_step;
        let m = (self.cells_per_axis - 1) as f32;
        let local = (p - self.sampler.origin()) * self.inv_cell_step;
        let lo = self.sampler.origin() + local.floor().min(Vec3::splat(m)) * step;
        let mut t_exit = f32::INFINITY;
        for a in 0..3 {
            let d = ray.direction[a];
            if d != 0.0 {
                let face = if d > 0.0 { lo[a] + step } else { lo[a] };
                t_exit = t_exit.min((face - ray.origin[a]) / d);
            }
        }
        let k_exit = ((t_exit - ray.t_enter) / ray.dt).floor() - 1.0;
        if k_exit > k as f32 + 1.0 {
            k_exit.min(u32::MAX as f32) as u32
        } else {
            k + 1
        }
    }
}

/// The first and last sample index of `ray` that brick `b` owns, if any.
pub fn owned_samples(ray: &PixelRay, geometry: &VolumeGeometry, b: [u32; 3]) -> Option<(u32, u32)> {
    let (lo, hi) = geometry.brick_voxel_box(b);
    let slack = Vec3::splat(BOX_SLACK);
    let voxel_ray = Ray {
        origin: ray.origin,
        direction: ray.direction,
    };
    // `intersect_box` clips t at 0; sample parameters start at t_enter ≥ 0.
    let (t0, t1) = voxel_ray.intersect_box(lo - slack, hi + slack)?;
    let last_index = ray.samples - 1;
    let k_of = |t: f32| (t - ray.t_enter) / ray.dt;
    let mut first = (k_of(t0).floor() - 1.0).max(0.0) as u32;
    let mut last = ((k_of(t1).ceil() + 1.0).max(0.0) as u32).min(last_index);
    let last_voxel = geometry.last_voxel();
    let owns = |k: u32| geometry.owner(ray.position(k, last_voxel)) == b;
    while first <= last && !owns(first) {
        first += 1;
    }
    while last > first && !owns(last) {
        last -= 1;
    }
    (first <= last && owns(first)).then_some((first, last))
}

/// Marches samples `first..=last` of `ray` (all owned by `brick`) into `state`.
///
/// Skips the brick when empty-space skipping is on and no sample in it can change
/// the pixel (transparent under the transfer function for DVR; no value above the
/// running maximum for MIP; none reaching the iso-value for first hit). Stops at
/// the opacity threshold or a first hit and marks the state done.
#[allow(clippy::too_many_arguments)]
pub fn march_brick<T: Sample>(
    plan: &FramePlan,
    volume: &VolumeSampler<'_, T>,
    brick: &BrickContext<'_, T>,
    ray: &PixelRay,
    first: u32,
    last: u32,
    state: &mut PixelState,
    counters: &mut Counters,
) {
    if state.done || first > last {
        return;
    }
    let count = u64::from(last - first + 1);
    let brick_max = f32::from(brick.range[1]);
    let skip = plan.empty_space_skipping
        && match (plan.mode, &plan.segments) {
            (_, Some(seg)) => seg.all_dvr && brick.transparent,
            (Mode::Dvr, None) => brick.transparent,
            (Mode::Mip, None) => brick_max <= state.value,
            (Mode::FirstHit, None) => brick_max < plan.iso_raw,
            (Mode::Average, None) => false,
        };
    if skip {
        counters.samples_skipped_empty += count;
        counters.brick_visits_skipped += 1;
    } else {
        counters.brick_visits += 1;
        let walk = Walk {
            plan,
            volume,
            brick,
            ray,
            first,
            last,
        };
        let ess = plan.empty_space_skipping;
        match plan.mode {
            _ if plan.segments.is_some() => {
                walk.two_level(state, counters, plan.segments.as_ref().expect("checked"))
            }
            Mode::Dvr => walk.dvr(state, counters),
            Mode::Mip => walk.values(state, counters, f32::max, |c, s| {
                ess && f32::from(brick.cells[c][1]) <= s.value
            }),
            Mode::Average => {
                state.count += last - first + 1;
                walk.values(state, counters, |a, b| a + b, |_, _| false)
            }
            Mode::FirstHit => walk.first_hit(state, counters),
        }
        if state.done {
            counters.rays_terminated += 1;
            return;
        }
    }
    state.next_sample = last + 1;
    if state.next_sample >= ray.samples {
        state.done = true;
        if let Some(seg) = &plan.segments {
            let PixelState {
                segment,
                color,
                alpha,
                ..
            } = state;
            close_segment(seg, segment, color, alpha, plan.step_ratio);
        }
    }
}

/// One ray's samples `first..=last` in one brick, with what marching them needs.
struct Walk<'w, 'v, T: Sample> {
    plan: &'w FramePlan,
    volume: &'w VolumeSampler<'v, T>,
    brick: &'w BrickContext<'v, T>,
    ray: &'w PixelRay,
    first: u32,
    last: u32,
}

impl<T: Sample> Walk<'_, '_, T> {
    /// Front-to-back emission–absorption.
    fn dvr(&self, state: &mut PixelState, counters: &mut Counters) {
        let Walk {
            plan,
            volume,
            brick,
            ray,
            first,
            last,
        } = *self;
        let table = &plan.table;
        let needs_gradient = plan.shading.is_some() || table.is_2d();
        let last_voxel = volume.last();
        let [mut r, mut g, mut b] = state.color;
        let mut alpha = state.alpha;
        let mut taken = 0;
        let mut skipped = 0;
        let last_sample = ray.samples - 1;
        let ess = plan.empty_space_skipping;
        let mut k = first;
        while k <= last {
            let p = ray.position(k, last_voxel);
            if ess && brick.cell_transparent[brick.cell_of(p)] {
                let next = brick.cell_exit(ray, p, k).min(last + 1);
                skipped += u64::from(next - k);
                k = next;
                continue;
            }
            let v = brick.sampler.value(p);
            taken += 1;
            k += 1;
            let [cr, cg, cb, a] = table.lookup(v);
            if a <= 0.0 {
                continue;
            }
            let (color, a) = if needs_gradient {
                let gradient = volume.gradient(&brick.sampler, p) * plan.gradient_scale;
                let a = if table.is_2d() {
                    table.lookup_2d(v, gradient.length(), plan.step_ratio)[3]
                } else {
                    a
                };
                let color = match &plan.shading {
                    Some(s) => s.shade([cr, cg, cb], gradient, ray.view_dir),
                    None => [cr, cg, cb],
                };
                (color, a)
            } else {
                ([cr, cg, cb], a)
            };
            // The last sample stands for a shorter segment: (1 − a)^f is the
            // transparency of the fraction f of a step.
            let a = if k - 1 == last_sample {
                1.0 - (1.0 - a).powf(ray.last_fraction)
            } else {
                a
            };
            // c += (1 − α)·αs·cs;  α += (1 − α)·αs
            let w = (1.0 - alpha) * a;
            r += w * color[0];
            g += w * color[1];
            b += w * color[2];
            alpha += w;
            if alpha >= plan.ert_threshold {
                state.done = true;
                state.next_sample = k;
                break;
            }
        }
        state.color = [r, g, b];
        state.alpha = alpha;
        counters.samples += taken;
        counters.samples_skipped_empty += skipped;
    }

    /// MIP or average: folds every sample's raw value into `state.value`, skipping
    /// the samples of cells for which `skip(cell, state)` holds.
    fn values(
        &self,
        state: &mut PixelState,
        counters: &mut Counters,
        fold: impl Fn(f32, f32) -> f32,
        skip: impl Fn(usize, &PixelState) -> bool,
    ) {
        let Walk {
            volume,
            brick,
            ray,
            first,
            last,
            ..
        } = *self;
        let last_voxel = volume.last();
        let mut skipped = 0;
        let mut k = first;
        while k <= last {
            let p = ray.position(k, last_voxel);
            if skip(brick.cell_of(p), state) {
                let next = brick.cell_exit(ray, p, k).min(last + 1);
                skipped += u64::from(next - k);
                k = next;
                continue;
            }
            state.value = fold(state.value, brick.sampler.value(p));
            k += 1;
        }
        counters.samples += u64::from(last - first + 1) - skipped;
        counters.samples_skipped_empty += skipped;
    }

    /// Two-level compositing: samples are folded into the open segment of their
    /// object; a change of object closes the segment (composited globally).
    fn two_level(&self, state: &mut PixelState, counters: &mut Counters, seg: &SegmentPlan) {
        let Walk {
            plan,
            volume,
            brick,
            ray,
            first,
            last,
        } = *self;
        let last_voxel = volume.last();
        let ess = plan.empty_space_skipping && seg.all_dvr;
        let shading = plan.shading.as_ref();
        // Normalise eye distance by where the ray leaves the volume.
        let exit = ray.t(ray.samples).max(1e-6);
        let mut taken = 0;
        let mut skipped = 0;
        // The open segment in a local (no aliasing with `state`): written back below.
        let mut segment = state.segment;
        let mut color = state.color;
        let mut alpha = state.alpha;
        let mut k = first;
        while k <= last {
            let p = ray.position(k, last_voxel);
            if ess && brick.cell_transparent[brick.cell_of(p)] {
                // Transparent for every object: nothing to add, the segment goes on.
                let next = brick.cell_exit(ray, p, k).min(last + 1);
                skipped += u64::from(next - k);
                k = next;
                continue;
            }
            let v = brick.sampler.value(p);
            taken += 1;
            let id = if seg.uses_labels() {
                brick.label_at(p)
            } else {
                seg.layer_of(v, segment.object)
            };
            if id != segment.object {
                close_segment(seg, &mut segment, &mut color, &mut alpha, plan.step_ratio);
                segment.object = id;
                if alpha >= plan.ert_threshold {
                    state.done = true;
                    state.next_sample = k;
                    break;
                }
            }
            if let Some(object) = seg.object(id) {
                let fraction = if k + 1 == ray.samples {
                    ray.last_fraction
                } else {
                    1.0
                };
                let gradient = || volume.gradient(&brick.sampler, p) * plan.gradient_scale;
                let fast = object.sample_dvr_1d(&mut segment, v, fraction, |c| match shading {
                    Some(s) => s.shade(c, gradient(), ray.view_dir),
                    None => c,
                });
                if fast == Some(false) {
                    // Transparent: nothing changed, no opacity test needed.
                    k += 1;
                    continue;
                }
                if fast.is_none() && !object.ignores(v) {
                    let sample = SampleContext {
                        value: v,
                        gradient: if object.needs_gradient(shading.is_some()) {
                            gradient()
                        } else {
                            Vec3::ZERO
                        },
                        view_dir: ray.view_dir,
                        depth: (ray.t(k) / exit).min(1.0),
                        step_ratio: plan.step_ratio,
                        fraction,
                    };
                    let had_hit = segment.hit;
                    object.sample(&mut segment, &sample, shading);
                    if segment.hit && !had_hit && state.depth.is_infinite() {
                        state.depth = ray.t(k);
                    }
                }
                // Emission–absorption segments: the open segment counts toward the
                // opacity that stops the ray.
                if seg.all_dvr && alpha + (1.0 - alpha) * segment.alpha >= plan.ert_threshold {
                    close_segment(seg, &mut segment, &mut color, &mut alpha, plan.step_ratio);
                    state.done = true;
                    state.next_sample = k + 1;
                    break;
                }
            }
            k += 1;
        }
        state.segment = segment;
        state.color = color;
        state.alpha = alpha;
        counters.samples += taken;
        counters.samples_skipped_empty += skipped;
    }

    /// First sample at or above the iso-value; the hit is refined linearly between it
    /// and the sample before, then shaded.
    fn first_hit(&self, state: &mut PixelState, counters: &mut Counters) {
        let Walk {
            plan,
            volume,
            brick,
            ray,
            first,
            last,
        } = *self;
        let last_voxel = volume.last();
        let iso = plan.iso_raw;
        let ess = plan.empty_space_skipping;
        let mut skipped = 0;
        let mut k = first;
        while k <= last {
            let p = ray.position(k, last_voxel);
            if ess && f32::from(brick.cells[brick.cell_of(p)][1]) < iso {
                let next = brick.cell_exit(ray, p, k).min(last + 1);
                skipped += u64::from(next - k);
                k = next;
                continue;
            }
            let v = brick.sampler.value(p);
            if v < iso {
                k += 1;
                continue;
            }
            let mut t_hit = ray.t(k);
            if k > 0 {
                let before = ray.position(k - 1, last_voxel);
                let v_before = if brick.sampler.contains(before) {
                    brick.sampler.value(before)
                } else {
                    volume.value(before)
                };
                if v_before < iso && v > v_before {
                    t_hit = ray.t(k - 1) + (iso - v_before) / (v - v_before) * ray.dt;
                }
            }
            let hit = (ray.origin + ray.direction * t_hit).clamp(Vec3::ZERO, last_voxel);
            let [cr, cg, cb, _] = plan.table.lookup(iso);
            let color = match &plan.shading {
                Some(s) => {
                    let gradient = volume.gradient(&brick.sampler, hit) * plan.gradient_scale;
                    s.shade([cr, cg, cb], gradient, ray.view_dir)
                }
                None => [cr, cg, cb],
            };
            state.color = color;
            state.alpha = 1.0;
            state.depth = t_hit;
            state.done = true;
            state.next_sample = k + 1;
            counters.samples += u64::from(k - first + 1) - skipped;
            counters.samples_skipped_empty += skipped;
            return;
        }
        counters.samples += u64::from(last - first + 1) - skipped;
        counters.samples_skipped_empty += skipped;
    }
}
