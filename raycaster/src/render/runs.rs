//! The non-empty sample runs of a ray inside one brick: what every compositor's
//! loop walks.
//!
//! A brick's owned cells are split into small cells with known value ranges
//! ([`super::cells`]). [`SampleRuns`] walks a ray's samples in a brick cell by
//! cell: the samples of a cell whose range is empty under the frame's compositor
//! ([`Compositor::range_empty`], the same rule that drops whole bricks from the
//! frame plan) are skipped without being read; every other cell yields one run of
//! consecutive samples with the cell's largest value, so the loop can still skip
//! it for a state-dependent reason ([`Compositor::below_interest`]).

use glam::Vec3;

use super::cells::BrickCells;
use super::compositor::Compositor;
use super::ownership::slab;
use super::pixel::PixelRay;
use super::truncate::truncate_clamped;

/// Consecutive samples `first..end` of a ray, all in one non-empty small cell
/// (or, without empty-space skipping, all the samples asked for).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SampleRun {
    /// First sample index.
    pub first: u32,
    /// One past the last sample index.
    pub end: u32,
    /// The largest raw value any sample of the run can have.
    pub hi: u16,
}

impl SampleRun {
    /// Samples in the run.
    #[inline]
    pub fn len(&self) -> u32 {
        self.end - self.first
    }
}

/// A brick's small cells as the run walker sees them.
#[derive(Clone, Debug)]
pub(crate) struct CellGrid {
    /// Value range per cell, `per_axis³`, x slowest.
    pub ranges: BrickCells,
    /// Cells per axis.
    pub per_axis: u32,
    /// Cell side in voxels.
    pub cell_step: f32,
    /// `1 / cell_step`.
    pub inv_cell_step: f32,
    /// The brick's first voxel (volume voxel coordinates).
    pub origin: Vec3,
    /// The box of positions the brick owns ([`super::geometry::VolumeGeometry::owner`]):
    /// lower and upper corner, infinite on the volume's outer faces.
    pub owned: [Vec3; 2],
    /// The smallest extent of a cell of the volume's bricks along an axis (a
    /// brick's last cell may be shorter): samples closer than that along every
    /// axis lie in cells that touch.
    pub min_extent: f32,
}

/// Iterator over the [`SampleRun`]s of samples `first..=last` of a ray in one brick.
///
/// It walks the brick's cells along the ray with a 3D DDA (Amanatides & Woo): the
/// cell of the first sample from its position, then from each cell to the
/// neighbour across the face the ray leaves it by. A cell's samples are those
/// whose index lies before the ray's exit from it (in sample-index units: the
/// face's crossing `(face − start) / step`, computed afresh for each face, so
/// nothing drifts). A sample within rounding of a face may fall to the cell on
/// the other side: its trilinear reads lie in that cell's range too when it is a
/// hair past an exit face (a cell's range covers the voxel after it), and within
/// a rounding error of it otherwise.
///
/// For a compositor whose samples stand for segments
/// ([`Compositor::composites_segments`]) a run is skipped only when the cells the
/// ray crosses between it and the samples around it are empty too: the walk
/// starts where the ray enters the brick (past the sample before), notes each
/// non-empty cell it crosses without a sample, and before skipping the visit's
/// last run looks at the cells up to the brick's exit. Every value on a segment
/// between two skipped samples then lies in an empty cell's range (the field is
/// continuous along the ray), so the segment is empty; a skipped sample's
/// segment to a marched one is composited by the marched one.
pub(crate) struct SampleRuns<'r, C> {
    compositor: &'r C,
    cells: Option<&'r CellGrid>,
    next: u32,
    end: u32,
    /// The current cell per axis.
    cell: [u32; 3],
    /// Per axis: +1 or −1 cell per face crossed, 0 where the ray does not move
    /// along it.
    direction: [i32; 3],
    /// Per axis: the crossing of the current cell's exit face, in sample-index
    /// units (`∞` where the ray does not leave the cell along it).
    exit: [f32; 3],
    /// What the exit faces are computed from.
    start: [f32; 3],
    inv_step: [f32; 3],
    /// The compositor's samples stand for segments.
    segments: bool,
    /// A non-empty cell was crossed since the last cell with a sample, and that
    /// cell's samples were skipped.
    gap_visible: bool,
    /// The last sample before the walk's position was skipped (or lies before
    /// the visit: not known, so taken as skipped).
    previous_skipped: bool,
    /// The ray's sample count (no segment follows its last sample).
    ray_samples: u32,
    /// Samples skipped so far (in empty cells).
    pub skipped: u64,
}

impl<'r, C: Compositor> SampleRuns<'r, C> {
    /// Whether the walk skips empty cells (else it yields one run of every
    /// sample).
    #[inline]
    pub(crate) fn skips_cells(&self) -> bool {
        self.cells.is_some()
    }

    /// The runs of samples `first..=last` of `ray`; with `cells` `None` (no
    /// empty-space skipping) one run of them all.
    #[inline(always)]
    pub fn new(
        compositor: &'r C,
        ray: &'r PixelRay,
        cells: Option<&'r CellGrid>,
        last_voxel: Vec3,
        first: u32,
        last: u32,
    ) -> Self {
        let mut runs = SampleRuns {
            compositor,
            cells,
            next: first,
            end: last.saturating_add(1),
            cell: [0; 3],
            direction: [0; 3],
            exit: [f32::INFINITY; 3],
            start: ray.start.to_array(),
            inv_step: ray.inv_step.to_array(),
            // Consecutive samples less than a cell apart along every axis lie in
            // cells that share voxels, so their ranges overlap: then no cell
            // between them matters (with a margin for rounding).
            segments: compositor.composites_segments()
                && cells.is_some_and(|g| ray.step.abs().max_element() * 1.01 >= g.min_extent),
            gap_visible: false,
            previous_skipped: true,
            ray_samples: ray.samples,
            skipped: 0,
        };
        if let Some(grid) = cells {
            // With segments, from where the ray enters the brick after the sample
            // before (when the ray takes one): the cells in between count.
            let p = if runs.segments && first > ray.first {
                entry_after(ray, grid, first - 1, last_voxel)
            } else {
                ray.position(first, last_voxel)
            };
            let local = ((p - grid.origin) * grid.inv_cell_step).to_array();
            let step = ray.step.to_array();
            let m = grid.per_axis - 1;
            for a in 0..3 {
                // Positions inside the brick are ≥ its origin: truncation floors
                // (`(x as u32).min(m)` in one instruction).
                runs.cell[a] = truncate_clamped(local[a], m as f32);
                runs.direction[a] = if step[a] > 0.0 {
                    1
                } else if step[a] < 0.0 {
                    -1
                } else {
                    0
                };
                runs.exit[a] = runs.exit_along(grid, a);
            }
        }
        runs
    }

    /// The crossing of the current cell's exit face along `axis`, in sample-index
    /// units; `∞` when the ray does not move along the axis or the cell is the
    /// brick's last that way (its samples end with the brick's).
    #[inline]
    fn exit_along(&self, grid: &CellGrid, axis: usize) -> f32 {
        self.exit_of(grid, self.cell[axis], axis)
    }

    /// [`Self::exit_along`] for cell coordinate `c` along `axis`.
    #[inline]
    fn exit_of(&self, grid: &CellGrid, c: u32, axis: usize) -> f32 {
        let face = match self.direction[axis] {
            1 if c + 1 < grid.per_axis => c + 1,
            -1 if c > 0 => c,
            _ => return f32::INFINITY,
        };
        let origin = grid.origin.to_array()[axis];
        (origin + face as f32 * grid.cell_step - self.start[axis]) * self.inv_step[axis]
    }
}

/// Where `ray` enters the box `grid`'s brick owns after sample `before` (or at
/// the sample after it, whichever comes first).
#[cold]
#[inline(never)]
fn entry_after(ray: &PixelRay, grid: &CellGrid, before: u32, last_voxel: Vec3) -> Vec3 {
    let [lower, upper] = grid.owned.map(|v| v.to_array());
    let (enter, _) = slab(
        ray,
        |a| (lower[a], upper[a]),
        (before as f32, f32::INFINITY),
    );
    let t = enter.min((before + 1) as f32);
    (ray.start + ray.step * t).clamp(Vec3::ZERO, last_voxel)
}

/// The axis whose face the ray leaves a cell by first, given its exits along
/// each.
#[inline]
fn first_exit([ex, ey, ez]: [f32; 3]) -> usize {
    if ex <= ey && ex <= ez {
        0
    } else if ey <= ez {
        1
    } else {
        2
    }
}

/// `⌈x⌉` for `x ≥ 0`, saturating (negative and NaN give 0), without a libm call:
/// the first sample index at or after sample-index position `x`.
#[inline]
pub(crate) fn ceil(x: f32) -> u32 {
    let whole = x as u32;
    if (whole as f32) < x {
        whole.saturating_add(1)
    } else {
        whole
    }
}

impl<C: Compositor> Iterator for SampleRuns<'_, C> {
    type Item = SampleRun;

    // Always inlined into the kernels' loops: as a call (the compiler's choice
    // with `#[inline]`) it took 9 instructions per sample more in shaded DVR
    // (369.1 against 360.3, docs/bench/instructions-per-sample.sh), a save and
    // restore of six registers for fewer than two cells per call.
    #[inline(always)]
    fn next(&mut self) -> Option<SampleRun> {
        let Some(grid) = self.cells else {
            let run = (self.next < self.end).then_some(SampleRun {
                first: self.next,
                end: self.end,
                hi: u16::MAX,
            });
            self.next = self.end;
            return run;
        };
        while self.next < self.end {
            let k = self.next;
            let axis = first_exit(self.exit);
            let run_end = ceil(self.exit[axis]).min(self.end);
            let index = grid.index(self.cell);
            // On to the neighbour (a cell the ray only grazes between two
            // samples yields nothing).
            let leaves = self.exit[axis].is_finite();
            if leaves {
                self.cell[axis] = self.cell[axis].wrapping_add_signed(self.direction[axis]);
                self.exit[axis] = self.exit_along(grid, axis);
            }
            if run_end <= k {
                // (A marched sample composites its own segment: the cells after
                // it do not matter.)
                if self.segments && self.previous_skipped && !self.gap_visible {
                    self.gap_visible = self.visible(grid, index);
                }
                continue;
            }
            self.next = run_end;
            let [lo, hi] = grid.ranges[index];
            // `lo > hi`: a cell past an edge brick's voxels (owns no sample).
            if (lo > hi || self.compositor.range_empty(lo, hi))
                && !(self.segments && self.segment_visible(grid, run_end, leaves))
            {
                self.skipped += u64::from(run_end - k);
                self.previous_skipped = true;
                continue;
            }
            self.gap_visible = false;
            // (A compositor that skips runs by its state may skip this one.)
            self.previous_skipped = C::STATE_SKIPS;
            return Some(SampleRun {
                first: k,
                end: run_end,
                hi,
            });
        }
        None
    }
}

impl<C: Compositor> SampleRuns<'_, C> {
    /// Whether cell `index` is non-empty.
    #[inline]
    fn visible(&self, grid: &CellGrid, index: usize) -> bool {
        let [lo, hi] = grid.ranges[index];
        lo <= hi && !self.compositor.range_empty(lo, hi)
    }

    /// Whether an empty run ending before sample `run_end` must be marched all
    /// the same (segments only): a non-empty cell lies between it and the sample
    /// before, or — for the visit's last run, whose cell the ray `leaves` for
    /// another of the brick — between it and the brick's exit, which the segment
    /// to the ray's next sample crosses. (The walk state is already past the
    /// run's cell.)
    #[cold]
    fn segment_visible(&mut self, grid: &CellGrid, run_end: u32, leaves: bool) -> bool {
        if self.gap_visible {
            self.gap_visible = false;
            return true;
        }
        if run_end < self.end || self.end >= self.ray_samples || !leaves {
            return false;
        }
        let (mut cell, mut exit) = (self.cell, self.exit);
        loop {
            if self.visible(grid, grid.index(cell)) {
                return true;
            }
            let axis = first_exit(exit);
            if !exit[axis].is_finite() {
                return false;
            }
            cell[axis] = cell[axis].wrapping_add_signed(self.direction[axis]);
            exit[axis] = self.exit_of(grid, cell[axis], axis);
        }
    }
}

impl CellGrid {
    /// The index of cell `[x, y, z]` in `ranges`.
    #[inline]
    fn index(&self, [x, y, z]: [u32; 3]) -> usize {
        ((x * self.per_axis + y) * self.per_axis + z) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::cells::CellRanges;
    use crate::render::clip::ClipRegion;
    use crate::render::compositor::SamplePoint;
    use crate::render::geometry::VolumeGeometry;
    use crate::render::ownership::owned_samples;
    use crate::render::ray::Ray;
    use crate::render::sampler::BrickSampler;
    use crate::volume::{BlockGrid, Layout, Sample, TypedVolume};

    /// Values below 100 are empty.
    struct Threshold;

    impl Compositor for Threshold {
        type State = ();
        fn start(&self) {}
        fn range_empty(&self, _lo: u16, hi: u16) -> bool {
            hi < 100
        }
        fn sample<T: Sample>(&self, _state: &mut (), _sample: &SamplePoint<'_, T>) {}
        fn resolve(&self, _state: &()) -> [f32; 4] {
            [0.0; 4]
        }
    }

    #[test]
    fn ceil_is_the_libm_ceiling_saturated_into_u32() {
        for x in [
            0.0,
            -0.0,
            0.2,
            1.0,
            1.000_000_1,
            2.5,
            1_023.999_94,
            16_777_215.0,
            16_777_216.0,
            33_554_432.0,
            4.0e9,
            5.0e9,
        ] {
            assert_eq!(ceil(x), x.ceil().min(u32::MAX as f32) as u32, "{x}");
        }
        for x in [-0.5, -3.0, f32::NEG_INFINITY, f32::NAN] {
            assert_eq!(ceil(x), 0, "{x}");
        }
        assert_eq!(ceil(f32::INFINITY), u32::MAX);
        let mut x = 0.0f32;
        while x < 3000.0 {
            assert_eq!(ceil(x), x.ceil() as u32, "{x}");
            x += 0.173;
        }
    }

    #[test]
    fn runs_cover_every_sample_that_is_not_empty_in_order() {
        let dims = [30, 26, 33];
        // Blobs of high values in a low background.
        let samples: Vec<u8> = (0..30 * 26 * 33u32)
            .map(|i| {
                let (x, y, z) = (i / (26 * 33), (i / 33) % 26, i % 33);
                let d = (x as i32 - 12).pow(2) + (y as i32 - 14).pow(2) + (z as i32 - 20).pow(2);
                if d < 30 || (x + 2 * y + z) % 61 == 0 {
                    200
                } else {
                    (i % 50) as u8
                }
            })
            .collect();
        let volume = TypedVolume::new(&samples, dims, Layout::Linear);
        let grid = BlockGrid::new(dims, 13);
        let cells = CellRanges::compute(&grid, |b| volume.brick(&grid, b));
        let geometry = VolumeGeometry::new(grid, [1.0, 1.0, 1.0]);
        let last = geometry.last_voxel();
        let (mut marched, mut skipped_total) = (0u64, 0u64);
        for i in 0..200u32 {
            let f = |s: u32| ((i * s) % 97) as f32 / 97.0;
            let origin = Vec3::new(-20.0 + 60.0 * f(7), -15.0 + 50.0 * f(13), -25.0 * f(29));
            let target = Vec3::new(30.0 * f(31), 26.0 * f(17), 33.0 * f(11));
            let ray = Ray {
                origin,
                direction: (target - origin).normalize_or(Vec3::Z),
            };
            let Some(pixel) = PixelRay::new(
                &ray,
                &geometry,
                0.37,
                (i % 5) as f32 * 0.2,
                &ClipRegion::default(),
            ) else {
                continue;
            };
            for b in grid.iter() {
                let Some((first, last_k)) = owned_samples(&pixel, &geometry, b) else {
                    continue;
                };
                let sampler = BrickSampler::new(volume.brick(&grid, b));
                let cell_grid = CellGrid {
                    ranges: cells.cached(grid.index(b)).unwrap(),
                    per_axis: cells.per_axis(),
                    cell_step: cells.cell_step() as f32,
                    inv_cell_step: 1.0 / cells.cell_step() as f32,
                    origin: sampler.origin(),
                    owned: crate::render::ownership::owned_box(&geometry, b),
                    min_extent: 1.0,
                };
                let mut runs =
                    SampleRuns::new(&Threshold, &pixel, Some(&cell_grid), last, first, last_k);
                let mut covered = Vec::new();
                let mut expect = first;
                for run in runs.by_ref() {
                    assert!(run.first >= expect && run.first < run.end && run.end <= last_k + 1);
                    // Everything between runs is empty.
                    for k in expect..run.first {
                        assert!(sampler.value(pixel.position(k, last)) < 100.0, "sample {k}");
                    }
                    for k in run.first..run.end {
                        assert!(sampler.value(pixel.position(k, last)) <= f32::from(run.hi));
                    }
                    covered.extend(run.first..run.end);
                    expect = run.end;
                }
                for k in expect..=last_k {
                    assert!(sampler.value(pixel.position(k, last)) < 100.0, "sample {k}");
                }
                let total = u64::from(last_k - first + 1);
                assert_eq!(covered.len() as u64 + runs.skipped, total);
                marched += covered.len() as u64;
                skipped_total += runs.skipped;
            }
        }
        assert!(
            marched > 1000 && skipped_total > 1000,
            "{marched} {skipped_total}"
        );
    }
}
