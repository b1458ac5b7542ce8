//! The marching loop: one ray through one brick into one pixel's state, with any
//! compositor.
//!
//! Both the sequential and the parallel renderer call [`march_brick`] (engineering
//! guide, invariant 1); they differ only in the order they hand it bricks. A brick
//! handles the samples whose positions it owns
//! ([`super::ownership::owned_samples`]), so a ray's
//! samples are processed exactly once, in order, however the volume is cut.

use std::cell::OnceCell;

use glam::Vec3;

use super::cell_cache::CellCache;
use super::compositor::{Compositor, SamplePoint, SampleSite};
use super::counters::Counters;
use super::ownership::owned_box;
use super::pixel::{PixelRay, PixelState, SamplePositions};
use super::prepared::{FramePlan, RenderVolume};
use super::runs::{CellGrid, SampleRuns};
use super::sampler::{BrickSampler, VolumeSampler};
use crate::volume::{BrickView, Sample, TypedVolume, VolumeData};

/// A brick ready to be marched.
#[derive(Clone, Debug)]
pub(crate) struct BrickContext<'a, T: Sample> {
    /// Local trilinear reads.
    pub sampler: BrickSampler<'a, T>,
    /// Smallest and largest voxel value in the brick.
    pub range: [u16; 2],
    /// The transfer function makes every value in the brick transparent.
    pub transparent: bool,
    /// The brick's small cells, with empty-space skipping (and a brick that some
    /// ray may need).
    cells: Option<CellGrid>,
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
        let sampler = BrickSampler::new(volume.brick_view(data, b));
        let range = volume.brick_range(b);
        let transparent = plan.range_empty(range[0], range[1]);
        // A brick every ray skips is never read, not even for its cells.
        let cells = (plan.empty_space_skipping && !transparent && !plan.brick_cut_away(volume, b))
            .then(|| {
                let cells = volume.cells();
                let cell_step = cells.cell_step() as f32;
                CellGrid {
                    ranges: volume.cells_of(data, b),
                    visible: OnceCell::new(),
                    per_axis: cells.per_axis(),
                    cell_step,
                    inv_cell_step: 1.0 / cell_step,
                    origin: sampler.origin(),
                    owned: owned_box(volume.geometry(), b),
                    min_extent: volume.min_cell_extent(),
                }
            });
        BrickContext {
            sampler,
            range,
            transparent,
            cells,
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
}

/// Marches samples `first..=last` of `ray` (all owned by `brick`) into `state`
/// with compositor `c`: the one compositing loop of every mode and renderer.
///
/// With empty-space skipping, the brick is skipped when no sample in it can
/// change the pixel ([`Compositor::range_empty`], or [`Compositor::below_interest`]
/// of the pixel's state), and inside it the loop walks only the non-empty
/// [`SampleRuns`]. The ray stops at the opacity threshold or when the compositor
/// is finished (a first hit).
///
/// `cell` caches the last voxel cell a ray entered: one cache serves the visits
/// of one brick (its cells are the brick's), never two bricks.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn march_brick<T: Sample, C: Compositor>(
    c: &C,
    plan: &FramePlan,
    volume: &VolumeSampler<'_, T>,
    brick: &BrickContext<'_, T>,
    cell: &CellCache,
    ray: &PixelRay,
    first: u32,
    last: u32,
    state: &mut PixelState<C::State>,
    counters: &mut Counters,
) {
    let visit = BrickVisit {
        plan,
        volume,
        brick,
        ray,
    };
    visit.march(c, first, last, state, counters, || SampleLoop {
        c,
        visit,
        cell,
        positions: ray.positions(volume.last()),
    });
}

/// One ray's visit of one brick: what the marching of its runs reads.
pub(crate) struct BrickVisit<'v, 'b, T: Sample> {
    /// The frame.
    pub plan: &'v FramePlan,
    /// Reads anywhere in the volume (gradients across the brick's faces).
    pub volume: &'v VolumeSampler<'b, T>,
    /// The brick.
    pub brick: &'v BrickContext<'b, T>,
    /// The ray.
    pub ray: &'v PixelRay,
}

// By hand: a derive would ask `T: Clone` of the sample type, which holds only
// references here.
impl<T: Sample> Clone for BrickVisit<'_, '_, T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T: Sample> Copy for BrickVisit<'_, '_, T> {}

/// What folds the samples of a run into a pixel's state: the generic loop
/// ([`SampleLoop`]) or a compositor's own kernel ([`super::packet`]).
pub(crate) trait RunMarcher<S> {
    /// Folds samples `first..end` of the ray into `acc`, front to back;
    /// `Some(k)` when the ray stopped (opacity threshold, a finished compositor)
    /// with sample `k − 1` the last it took.
    fn march_run(&mut self, acc: &mut S, first: u32, end: u32) -> Option<u32>;

    /// Folds every run of `runs` into `acc` (skipping, with `ess`, the runs
    /// `c`'s state says cannot change the pixel): the samples taken, the
    /// samples skipped before the ray stopped or ended (`runs`' own and the
    /// runs skipped here), and `Some(k)` when the ray stopped before sample
    /// `k`. One run at a time ([`march_each_run`]) unless a kernel marches
    /// samples of several runs together.
    #[inline(always)]
    fn march_runs<C: Compositor<State = S>>(
        &mut self,
        c: &C,
        ess: bool,
        acc: &mut S,
        runs: &mut SampleRuns<'_, C>,
    ) -> (u64, u64, Option<u32>)
    where
        Self: Sized,
    {
        march_each_run(self, c, ess, acc, runs)
    }
}

/// [`RunMarcher::march_runs`] one run at a time.
#[inline(always)]
pub(crate) fn march_each_run<S, C: Compositor<State = S>>(
    marcher: &mut impl RunMarcher<S>,
    c: &C,
    ess: bool,
    acc: &mut S,
    runs: &mut SampleRuns<'_, C>,
) -> (u64, u64, Option<u32>) {
    let (mut taken, mut skipped) = (0u64, 0u64);
    while let Some(run) = runs.next() {
        if C::STATE_SKIPS && ess && c.below_interest(acc, run.hi) {
            skipped += u64::from(run.len());
            continue;
        }
        if let Some(next) = marcher.march_run(acc, run.first, run.end) {
            taken += u64::from(next - run.first);
            return (taken, skipped + runs.skipped, Some(next));
        }
        taken += u64::from(run.len());
    }
    (taken, skipped + runs.skipped, None)
}

impl<T: Sample> BrickVisit<'_, '_, T> {
    /// Marches samples `first..=last` into `state` with `c`'s emptiness rules,
    /// the runs folded by the marcher `start` makes (only if the brick is not
    /// skipped): the visit's skipping, counting and ending, shared by every
    /// kernel.
    #[inline(always)]
    pub(crate) fn march<C: Compositor, M: RunMarcher<C::State>>(
        &self,
        c: &C,
        first: u32,
        last: u32,
        state: &mut PixelState<C::State>,
        counters: &mut Counters,
        start: impl FnOnce() -> M,
    ) {
        if state.done || first > last {
            return;
        }
        let (plan, brick, ray) = (self.plan, self.brick, self.ray);
        let ess = plan.empty_space_skipping && c.skips_anything();
        if ess && (brick.transparent || c.below_interest(&state.acc, brick.range[1])) {
            counters.samples_skipped_empty += u64::from(last - first + 1);
            counters.brick_visits_skipped += 1;
        } else {
            counters.brick_visits += 1;
            let mut acc = state.acc;
            let cells = if ess { brick.cells.as_ref() } else { None };
            let mut runs = SampleRuns::new(c, ray, cells, self.volume.last(), first, last);
            let (taken, skipped, stopped_before) = start().march_runs(c, ess, &mut acc, &mut runs);
            state.acc = acc;
            counters.samples += taken;
            counters.samples_skipped_empty += skipped;
            if let Some(k) = stopped_before {
                stop_ray(c, state, k, counters);
                return;
            }
        }
        end_visit(c, state, ray, last + 1);
    }
}

/// The generic loop: every sample through [`Compositor::sample`], its value
/// from the ray's [`CellCache`].
struct SampleLoop<'v, 'b, T: Sample, C> {
    c: &'v C,
    visit: BrickVisit<'v, 'b, T>,
    cell: &'v CellCache,
    positions: SamplePositions,
}

impl<T: Sample, C: Compositor> RunMarcher<C::State> for SampleLoop<'_, '_, T, C> {
    #[inline(always)]
    fn march_run(&mut self, acc: &mut C::State, first: u32, end: u32) -> Option<u32> {
        let (c, cell, positions) = (self.c, self.cell, self.positions);
        let (plan, brick) = (self.visit.plan, self.visit.brick);
        let site = self.visit.site(cell);
        for k in first..end {
            let position = positions.at(k);
            let value = cell.value(&brick.sampler, position);
            if fold_sample(c, acc, &site, k, position.into(), value, plan.ert_threshold) {
                return Some(k + 1);
            }
        }
        None
    }
}

/// Folds sample `k` of the ray, of value `value` at voxel position `position`,
/// into `acc` with `c`; whether the ray stops after it (its opacity reached
/// `ert_threshold`, or `c` is finished). The ray's last sample stands for its
/// fraction of a step. Every kernel that hands samples to
/// [`Compositor::sample`] folds them here, whatever reads their values.
#[inline(always)]
pub(crate) fn fold_sample<T: Sample, C: Compositor>(
    c: &C,
    acc: &mut C::State,
    site: &SampleSite<'_, T>,
    k: u32,
    position: Vec3,
    value: f32,
    ert_threshold: f32,
) -> bool {
    fold_point(c, acc, &site.point(k, position, value), ert_threshold)
}

/// [`fold_sample`] of a sample built already (one whose gradient a kernel
/// computed, or comes from elsewhere: [`SamplePoint::gradient`]).
#[inline(always)]
pub(crate) fn fold_point<T: Sample, C: Compositor>(
    c: &C,
    acc: &mut C::State,
    sample: &SamplePoint<'_, T>,
    ert_threshold: f32,
) -> bool {
    c.sample(acc, sample);
    c.opacity(acc) >= ert_threshold || c.finished(acc)
}

impl<'v, T: Sample> BrickVisit<'v, '_, T> {
    /// What the visit's samples share, with `cell` the ray's cell cache.
    #[inline(always)]
    pub(crate) fn site(&self, cell: &'v CellCache) -> SampleSite<'v, T> {
        SampleSite {
            ray: self.ray,
            brick: self.brick,
            volume: self.volume,
            cell,
            gradient_scale: self.plan.gradient_scale,
        }
    }
}

/// Ends a ray's visit of a brick with sample `next` the next it expects; past its
/// last sample the ray is done and `c` closes it.
#[inline]
pub(crate) fn end_visit<C: Compositor>(
    c: &C,
    state: &mut PixelState<C::State>,
    ray: &PixelRay,
    next: u32,
) {
    state.next_sample = next;
    if next >= ray.samples {
        state.done = true;
        c.close(&mut state.acc);
    }
}

/// Stops a ray early (opacity threshold or a first hit) before sample `next`.
#[inline]
pub(crate) fn stop_ray<C: Compositor>(
    c: &C,
    state: &mut PixelState<C::State>,
    next: u32,
    counters: &mut Counters,
) {
    c.close(&mut state.acc);
    state.done = true;
    state.next_sample = next;
    counters.rays_terminated += 1;
}
