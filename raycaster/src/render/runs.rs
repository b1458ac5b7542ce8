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
//!
//! Which cell a sample lies in is one rule, [`CellLocator`], for the compositors
//! that skip by emptiness alone: the walker and the gather kernels apply it
//! eight samples at a time in lanes ([`super::cell_lanes`]; the walker by each
//! axis's next change where the CPU has no AVX2), so every kernel skips the
//! same samples. Compositors that skip runs by their state, and samples that
//! stand for segments across cells, keep the walk from face to face.

use std::cell::OnceCell;

use glam::Vec3;

use super::cell_lanes::{LaneCells, LaneClassifier};
use super::cells::BrickCells;
use super::compositor::Compositor;
use super::gather::GATHER_LANES;
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
    /// One bit per cell, in `ranges`' order (bit `i % 32` of word `i / 32`):
    /// the cell is not empty under the frame's compositor
    /// ([`Self::visible_bits`], made at its first walk placing samples).
    pub visible: OnceCell<Box<[u32]>>,
}

/// Where a ray's samples lie in a brick's small cells: sample `k`'s cell
/// coordinate along axis `a` is `⌊base[a] + slope[a]·k⌋` clamped into the
/// brick's cells, `base` and `slope` being the ray's start (relative to the
/// brick's first voxel) and step in cells. The one rule of
/// [`SampleRuns`] and of the gather kernels' lane classifier, which compute the
/// same operations in the same order, so both find the same cell for every
/// sample.
///
/// The sample positions the kernels read are computed otherwise (`start +
/// step·k` in voxels, clamped to the volume), so a sample within a rounding
/// error of a face may be placed in the cell on its other side. Its trilinear
/// reads then lie in that cell's range but for a weight of that rounding error
/// on one voxel (a cell's range covers the voxel after it): what it skips is
/// empty within that error.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CellLocator {
    /// Sample 0's position in cells of the brick, per axis.
    pub base: [f32; 3],
    /// Cells per sample, per axis.
    pub slope: [f32; 3],
    /// The last cell coordinate, `per_axis − 1`.
    pub last_cell: f32,
    /// Cells per axis (the lanes' cell index; off x86-64 only tests read it).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub per_axis: u32,
}

impl CellLocator {
    /// The cells of `grid` along `ray`.
    #[inline]
    pub fn new(ray: &PixelRay, grid: &CellGrid) -> Self {
        let (start, step) = (ray.start.to_array(), ray.step.to_array());
        let origin = grid.origin.to_array();
        CellLocator {
            base: std::array::from_fn(|a| (start[a] - origin[a]) * grid.inv_cell_step),
            slope: std::array::from_fn(|a| step[a] * grid.inv_cell_step),
            last_cell: (grid.per_axis - 1) as f32,
            per_axis: grid.per_axis,
        }
    }

    /// Sample `k`'s position along `axis`, in cells (unclamped).
    #[inline(always)]
    fn local(&self, axis: usize, k: u32) -> f32 {
        self.base[axis] + self.slope[axis] * k as f32
    }

    /// The coordinate along `axis` of the cell sample `k` lies in.
    #[inline(always)]
    fn coordinate(&self, axis: usize, k: u32) -> u32 {
        truncate_clamped(self.local(axis, k), self.last_cell)
    }

    /// The coordinates of the cell sample `k` lies in.
    #[inline(always)]
    pub fn coordinates(&self, k: u32) -> [u32; 3] {
        std::array::from_fn(|a| self.coordinate(a, k))
    }

    /// The index (in the grid's order) of the cell sample `k` lies in.
    #[cfg(test)]
    pub fn cell(&self, k: u32) -> usize {
        let [x, y, z] = self.coordinates(k);
        ((x * self.per_axis + y) * self.per_axis + z) as usize
    }

    /// The first sample after `k`, whose coordinate along `axis` is `c`, that
    /// lies in another cell along `axis`; `limit` if none before it. Exact:
    /// the crossing of the face estimated, then moved to the first sample
    /// that [`Self::coordinates`] places beyond it (positions move
    /// monotonically with `k`, each operation being monotonic).
    #[inline(always)]
    fn leaves(&self, axis: usize, c: u32, k: u32, limit: u32) -> u32 {
        let slope = self.slope[axis];
        // The coordinate changes where the position reaches `c + 1` going up
        // (unless `c` is the last), falls below `c` going down (unless 0).
        let (face, up) = if slope > 0.0 && (c as f32) < self.last_cell {
            ((c + 1) as f32, true)
        } else if slope < 0.0 && c > 0 {
            (c as f32, false)
        } else {
            return limit;
        };
        let crossed = |j: u32| {
            let local = self.local(axis, j);
            if up { local >= face } else { local < face }
        };
        let first = k + 1;
        if first >= limit {
            return limit;
        }
        let estimate = ceil((face - self.base[axis]) / slope);
        let mut e = estimate.clamp(first, limit);
        while e > first && crossed(e - 1) {
            e -= 1;
        }
        while e < limit && !crossed(e) {
            e += 1;
        }
        e
    }
}

/// Iterator over the [`SampleRun`]s of samples `first..=last` of a ray in one brick.
///
/// Each sample's cell is [`CellLocator::coordinates`]; a run is the samples up
/// to the next one in another cell. (Walking the cells from face to face cost
/// the gather kernels more per sample where a visit takes a few samples:
/// docs/benchmarks.md, twenty-fourth step.)
///
/// For a compositor that skips runs by its state ([`Compositor::STATE_SKIPS`]:
/// the walk costs it less), and where the samples stand for segments and a step
/// spans cells (the cells between samples matter then), the walk goes from cell
/// to cell with a 3D
/// DDA (Amanatides & Woo): the cell of the first sample from its position, then
/// from each cell to the neighbour across the face the ray leaves it by. A
/// cell's samples are those whose index lies before the ray's exit from it (in
/// sample-index units: the face's crossing `(face − start) / step`, computed
/// afresh for each face, so nothing drifts). A sample within rounding of a face
/// may fall to the cell on the other side: its trilinear reads lie in that
/// cell's range too when it is a hair past an exit face (a cell's range covers
/// the voxel after it), and within a rounding error of it otherwise.
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
    /// The ray (for a walk placing samples by [`CellLocator`]).
    ray: &'r PixelRay,
    /// A walk placing samples by [`CellLocator`]: its state, made at its
    /// first run (kernels that classify samples themselves take none).
    placed: Option<PlacedWalk<'r>>,
    /// Samples skipped so far (in empty cells).
    pub skipped: u64,
}

/// The state of a walk placing samples by [`CellLocator`].
struct PlacedWalk<'r> {
    locator: CellLocator,
    /// The grid's visible cells.
    visible: &'r [u32],
    /// Without lanes: the current cell, and per axis the first sample past
    /// it along that axis ([`CellLocator::leaves`]).
    cell: [u32; 3],
    leaves: [u32; 3],
    /// The locator in lanes, where the CPU has them.
    lanes: Option<LaneClassifier<'r>>,
    /// With lanes: the samples classified last.
    group: LaneGroup,
}

/// Samples `k..k + n` of a ray, classified in lanes.
struct LaneGroup {
    cells: LaneCells,
    k: u32,
    n: u32,
}

impl<'r, C: Compositor> SampleRuns<'r, C> {
    /// Whether the walk skips empty cells (else it yields one run of every
    /// sample).
    #[inline]
    pub(crate) fn skips_cells(&self) -> bool {
        self.cells.is_some()
    }

    /// Whether the walk places samples by [`CellLocator`] (else it goes from
    /// cell to cell by their faces): unless samples stand for segments, or the
    /// compositor skips runs by its state. Those walks keep the face-to-face
    /// walk, which costs them less (docs/benchmarks.md, twenty-fourth step);
    /// each compositor's samples are placed by one rule in every kernel.
    #[inline(always)]
    fn by_samples(&self) -> bool {
        !self.segments && !C::STATE_SKIPS
    }

    /// The samples left to walk, where they lie and which cells are visible,
    /// when the walk skips cells and places samples by [`CellLocator`]
    /// ([`Self::by_samples`]): for kernels that classify samples in lanes
    /// themselves. `None` otherwise.
    #[inline(always)]
    pub(crate) fn sample_walk(&self) -> Option<SampleWalk<'r>> {
        let grid = self.cells?;
        self.by_samples().then(|| SampleWalk {
            locator: CellLocator::new(self.ray, grid),
            visible: grid.visible_bits(self.compositor),
            first: self.next,
            end: self.end,
        })
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
            ray,
            placed: None,
        };
        if let Some(grid) = cells.filter(|_| !runs.by_samples()) {
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
/// each (crossings, or first samples past the cell).
#[inline]
fn first_exit<T: PartialOrd>([ex, ey, ez]: [T; 3]) -> usize {
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

impl<'r, C: Compositor> Iterator for SampleRuns<'r, C> {
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
        if self.by_samples() {
            return self.next_by_samples(grid);
        }
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
                hi: grid.ranges[index][1],
            });
        }
        None
    }
}

impl<'r, C: Compositor> SampleRuns<'r, C> {
    /// [`Iterator::next`] placing samples by [`CellLocator`]: a run is the
    /// samples up to the first that lies in another cell, found eight samples
    /// at a time in lanes, else by the walk moving from cell to cell along
    /// the axis the ray leaves by first, each axis's next change found exactly
    /// ([`CellLocator::leaves`]). The same runs either way.
    #[inline(always)]
    fn next_by_samples(&mut self, grid: &'r CellGrid) -> Option<SampleRun> {
        if self.placed.is_none() {
            self.placed = Some(self.start_placed(grid, true));
        }
        let SampleRuns {
            placed: Some(walk),
            next,
            end,
            skipped,
            ..
        } = self
        else {
            return None;
        };
        match &walk.lanes {
            Some(lanes) => next_in_lanes(lanes, &mut walk.group, grid, next, *end, skipped),
            None => walk.next_by_axes(grid, next, *end, skipped),
        }
    }

    /// The state of a walk placing samples, with lanes where the CPU has them
    /// and `lanes` allows.
    fn start_placed(&self, grid: &'r CellGrid, lanes: bool) -> PlacedWalk<'r> {
        let locator = CellLocator::new(self.ray, grid);
        let visible = grid.visible_bits(self.compositor);
        let lanes = if lanes {
            LaneClassifier::new(&locator, visible)
        } else {
            None
        };
        let (first, end) = (self.next, self.end);
        let cell = locator.coordinates(first);
        let leaves = if lanes.is_none() {
            std::array::from_fn(|a| locator.leaves(a, cell[a], first, end))
        } else {
            [end; 3]
        };
        PlacedWalk {
            locator,
            visible,
            cell,
            leaves,
            lanes,
            group: LaneGroup {
                cells: LaneCells::default(),
                k: first,
                n: 0,
            },
        }
    }

    /// The walk without lanes, on any CPU (what a CPU without them walks).
    #[cfg(test)]
    pub(crate) fn without_lanes(mut self) -> Self {
        if let Some(grid) = self.cells.filter(|_| self.by_samples()) {
            self.placed = Some(self.start_placed(grid, false));
        }
        self
    }

    /// Whether cell `index` is non-empty (the face-to-face walk's test; the
    /// same rule as [`CellGrid::visible_bits`]).
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

/// Whether bit `index` of `bits` is set ([`CellGrid::visible`]'s form).
#[inline(always)]
pub(crate) fn bit_set(bits: &[u32], index: usize) -> bool {
    bits[index / 32] >> (index % 32) & 1 != 0
}

impl<'r> PlacedWalk<'r> {
    /// The next run after `next` without lanes.
    #[inline(always)]
    fn next_by_axes(
        &mut self,
        grid: &CellGrid,
        next: &mut u32,
        end: u32,
        skipped: &mut u64,
    ) -> Option<SampleRun> {
        while *next < end {
            let k = *next;
            let axis = first_exit(self.leaves);
            let run_end = self.leaves[axis];
            let index = grid.index(self.cell);
            if run_end < end {
                // On along the axis (another may change at the same sample:
                // then this cell holds none, and the next pass moves it on).
                let c = self.locator.coordinate(axis, run_end);
                self.cell[axis] = c;
                self.leaves[axis] = self.locator.leaves(axis, c, run_end, end);
            }
            if run_end <= k {
                continue;
            }
            *next = run_end;
            if !bit_set(self.visible, index) {
                *skipped += u64::from(run_end - k);
                continue;
            }
            return Some(SampleRun {
                first: k,
                end: run_end,
                hi: grid.ranges[index][1],
            });
        }
        None
    }
}

/// The next run after `next` of a walk placing samples, the samples
/// classified eight at a time in lanes, `group` the last eight.
#[inline(always)]
fn next_in_lanes(
    lanes: &LaneClassifier<'_>,
    group: &mut LaneGroup,
    grid: &CellGrid,
    next: &mut u32,
    end: u32,
    skipped: &mut u64,
) -> Option<SampleRun> {
    while *next < end {
        if *next >= group.k + group.n {
            group.classify(lanes, *next, end);
        }
        let p = *next - group.k;
        // Past the group's samples in invisible cells at once (their runs
        // yield nothing: only how many they are counts).
        let ahead = group.cells.visible >> p;
        if ahead == 0 {
            let group_end = group.k + group.n;
            *skipped += u64::from(group_end - *next);
            *next = group_end;
            continue;
        }
        let p = p + ahead.trailing_zeros();
        *skipped += u64::from(group.k + p - *next);
        let k = group.k + p;
        let index = group.cells.index[p as usize];
        // The lanes after `p` where the cell changes.
        let mut later = group.cells.changes & !((2u32 << p) - 1);
        while later == 0 && group.k + group.n < end {
            // The run may go on into the next eight samples.
            group.classify(lanes, group.k + group.n, end);
            later = if group.cells.index[0] != index {
                1
            } else {
                group.cells.changes & !1
            };
        }
        let run_end = group.k
            + if later != 0 {
                later.trailing_zeros()
            } else {
                group.n
            };
        *next = run_end;
        return Some(SampleRun {
            first: k,
            end: run_end,
            hi: grid.ranges[index as usize][1],
        });
    }
    None
}

impl LaneGroup {
    /// Classifies samples `k..` (up to eight, before `end`) in lanes.
    #[inline(always)]
    fn classify(&mut self, lanes: &LaneClassifier<'_>, k: u32, end: u32) {
        let count = (end - k).min(GATHER_LANES as u32);
        self.cells = lanes.classify(k, count);
        self.k = k;
        self.n = count;
    }
}

/// [`CellGrid::visible`] of cells with value ranges `ranges`: a bit per cell,
/// set where the range is not empty (`lo ≤ hi`: a cell past an edge brick's
/// voxels owns no sample) and `range_empty` does not hold.
pub(crate) fn visible_cells(
    ranges: &[[u16; 2]],
    range_empty: impl Fn(u16, u16) -> bool,
) -> Box<[u32]> {
    let mut bits = vec![0u32; ranges.len().div_ceil(32)];
    for (i, &[lo, hi]) in ranges.iter().enumerate() {
        if lo <= hi && !range_empty(lo, hi) {
            bits[i / 32] |= 1 << (i % 32);
        }
    }
    bits.into()
}

/// What [`SampleRuns::sample_walk`] gives.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleWalk<'g> {
    /// Where the ray's samples lie in the brick's cells.
    pub locator: CellLocator,
    /// [`CellGrid::visible`].
    pub visible: &'g [u32],
    /// The first sample left.
    pub first: u32,
    /// One past the last sample.
    pub end: u32,
}

impl CellGrid {
    /// [`Self::visible`], made under `c` at the first call (the compositor
    /// of every walk of the grid: the frame's).
    #[inline(always)]
    pub fn visible_bits(&self, c: &impl Compositor) -> &[u32] {
        self.visible
            .get_or_init(|| visible_cells(&self.ranges, |lo, hi| c.range_empty(lo, hi)))
    }

    /// The index of cell `[x, y, z]` in `ranges`.
    #[inline]
    fn index(&self, [x, y, z]: [u32; 3]) -> usize {
        ((x * self.per_axis + y) * self.per_axis + z) as usize
    }
}

#[cfg(test)]
pub(crate) mod tests {
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
    pub(crate) struct Threshold;

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
                let ranges = cells.cached(grid.index(b)).unwrap();
                let cell_grid = CellGrid {
                    visible: OnceCell::new(),
                    ranges,
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
