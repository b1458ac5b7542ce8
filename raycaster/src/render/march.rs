//! The marching loop: one ray through one brick into one pixel's state, with any
//! compositor.
//!
//! Both the sequential and the parallel renderer call [`march_brick`] (engineering
//! guide, invariant 1); they differ only in the order they hand it bricks. A brick
//! handles the samples whose positions it owns ([`owned_samples`]), so a ray's
//! samples are processed exactly once, in order, however the volume is cut.

use std::sync::Arc;

use glam::Vec3;

use super::cells::BrickCells;
use super::compositor::{Compositor, SamplePoint};
use super::counters::Counters;
use super::geometry::VolumeGeometry;
use super::pixel::{PixelRay, PixelState};
use super::prepared::{FramePlan, RenderVolume};
use super::ray::Ray;
use super::sampler::{BrickSampler, VolumeSampler};
use crate::volume::{BrickView, Sample, TypedVolume, VolumeData};

/// Slack around a brick's box when estimating its samples: ownership, not this
/// box, decides, so the estimate only has to be generous.
const BOX_SLACK: f32 = 1e-3;

/// A brick ready to be marched.
#[derive(Clone, Debug)]
pub(crate) struct BrickContext<'a, T: Sample> {
    /// Local trilinear reads.
    pub sampler: BrickSampler<'a, T>,
    /// Smallest and largest voxel value in the brick.
    pub range: [u16; 2],
    /// The transfer function makes every value in the brick transparent.
    pub transparent: bool,
    /// Value ranges of the brick's small cells.
    cells: BrickCells,
    /// Per small cell: empty under the frame's compositor.
    cell_empty: Vec<bool>,
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
        let ranges: BrickCells = if plan.brick_droppable(index as usize) {
            Arc::new([])
        } else {
            volume.cells_of(data, b)
        };
        BrickContext {
            sampler: BrickSampler::new(volume.brick_view(data, b)),
            range,
            transparent: plan.transparent[index as usize],
            cell_empty: ranges
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
    pub(crate) fn label_at(&self, p: Vec3) -> u16 {
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
pub(crate) fn owned_samples(
    ray: &PixelRay,
    geometry: &VolumeGeometry,
    b: [u32; 3],
) -> Option<(u32, u32)> {
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

/// Marches samples `first..=last` of `ray` (all owned by `brick`) into `state`
/// with compositor `c`: the one compositing loop of every mode and renderer.
///
/// With empty-space skipping, the brick — or a small cell of it — is skipped when
/// no sample in it can change the pixel ([`Compositor::range_empty`], or
/// [`Compositor::below_interest`] of the pixel's state). The ray stops at the
/// opacity threshold or when the compositor is finished (a first hit).
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn march_brick<T: Sample, C: Compositor>(
    c: &C,
    plan: &FramePlan,
    volume: &VolumeSampler<'_, T>,
    brick: &BrickContext<'_, T>,
    ray: &PixelRay,
    first: u32,
    last: u32,
    state: &mut PixelState<C::State>,
    counters: &mut Counters,
) {
    if state.done || first > last {
        return;
    }
    let ess = plan.empty_space_skipping;
    if ess && (brick.transparent || c.below_interest(&state.acc, brick.range[1])) {
        counters.samples_skipped_empty += u64::from(last - first + 1);
        counters.brick_visits_skipped += 1;
    } else {
        counters.brick_visits += 1;
        let last_voxel = volume.last();
        let last_sample = ray.samples - 1;
        let mut acc = state.acc;
        let (mut taken, mut skipped) = (0u64, 0u64);
        let mut terminated = false;
        let mut k = first;
        while k <= last {
            let p = ray.position(k, last_voxel);
            if ess {
                let cell = brick.cell_of(p);
                if brick.cell_empty[cell]
                    || (C::STATE_SKIPS && c.below_interest(&acc, brick.cells[cell][1]))
                {
                    let next = brick.cell_exit(ray, p, k).min(last + 1);
                    skipped += u64::from(next - k);
                    k = next;
                    continue;
                }
            }
            let sample = SamplePoint {
                value: brick.sampler.value(p),
                position: p,
                index: k,
                fraction: if k == last_sample {
                    ray.last_fraction
                } else {
                    1.0
                },
                ray,
                brick,
                volume,
                gradient_scale: plan.gradient_scale,
            };
            c.sample(&mut acc, &sample);
            taken += 1;
            k += 1;
            if c.opacity(&acc) >= plan.ert_threshold || c.finished(&acc) {
                terminated = true;
                break;
            }
        }
        state.acc = acc;
        counters.samples += taken;
        counters.samples_skipped_empty += skipped;
        if terminated {
            c.close(&mut state.acc);
            state.done = true;
            state.next_sample = k;
            counters.rays_terminated += 1;
            return;
        }
    }
    state.next_sample = last + 1;
    if state.next_sample >= ray.samples {
        state.done = true;
        c.close(&mut state.acc);
    }
}
