//! Value ranges of small cells inside each brick: the fine level of empty-space
//! skipping (the thesis's `EmptyIndex` for linear volumes, here for every layout).
//!
//! Each brick's owned cells (`step` per axis) are split into `m³` cells of about
//! [`target_cell_step`] voxels; a cell spans its cells plus the voxel after, so the
//! trilinear reads of any sample it owns lie within its range.
//!
//! Nothing is scanned when a volume is opened: a brick's cells are computed the first
//! time a frame marches a ray through it and cached for later frames. Bricks that no
//! frame visits (empty under every transfer function used, or never in view) are
//! never read; a brick whose stored range is a single value needs no read at all.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::volume::{BlockGrid, BrickView, Sample};

/// Smallest cell size aimed at, in voxel steps per axis.
pub const TARGET_CELL_STEP: u32 = 4;

/// Cells beyond which larger cells are used, to bound the index's memory
/// (4 bytes of range per cell: about 64 MB if every brick were visited).
pub const MAX_CELLS: u64 = 1 << 24;

/// The cell step aimed at for a volume of `dims`: [`TARGET_CELL_STEP`], or larger
/// when the volume would need more than [`MAX_CELLS`] cells.
pub fn target_cell_step(dims: [u32; 3]) -> u32 {
    let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
    let bound = (voxels as f64 / MAX_CELLS as f64).cbrt().ceil() as u32;
    bound.max(TARGET_CELL_STEP)
}

/// Per-brick cell ranges of a brick grid, computed lazily brick by brick.
#[derive(Debug)]
pub struct CellRanges {
    /// Cells per brick and axis.
    per_axis: u32,
    /// Cell step in voxels.
    cell_step: u32,
    /// Per brick (file order): its `per_axis³` ranges, cells x-slowest, once known.
    bricks: Vec<OnceLock<Box<[[u16; 2]]>>>,
    /// Bricks whose cells were computed by reading samples.
    scanned: AtomicU64,
}

impl CellRanges {
    /// The (not yet computed) cell ranges of the bricks of `grid`.
    pub fn lazy(grid: &BlockGrid) -> Self {
        let per_axis = grid.step().div_ceil(target_cell_step(grid.dims())).max(1);
        let cell_step = grid.step().div_ceil(per_axis);
        CellRanges {
            per_axis,
            cell_step,
            bricks: (0..grid.block_count()).map(|_| OnceLock::new()).collect(),
            scanned: AtomicU64::new(0),
        }
    }

    /// Scans every brick of `grid`, whose views `brick` gives (in parallel); what a
    /// renderer computes lazily, all at once (for tests and tools).
    pub fn compute<'a, T: Sample>(
        grid: &BlockGrid,
        brick: impl Fn([u32; 3]) -> BrickView<'a, T> + Sync,
    ) -> Self {
        use rayon::prelude::*;
        let cells = Self::lazy(grid);
        (0..grid.block_count()).into_par_iter().for_each(|i| {
            cells.of_brick(i, None, || brick(grid.coords(i)));
        });
        cells
    }

    /// Cells per brick and axis.
    pub fn per_axis(&self) -> u32 {
        self.per_axis
    }

    /// Cell step in voxels.
    pub fn cell_step(&self) -> u32 {
        self.cell_step
    }

    /// Cells per brick.
    pub fn per_brick(&self) -> usize {
        (self.per_axis * self.per_axis * self.per_axis) as usize
    }

    /// The ranges of brick number `index` (file order), computed from the view
    /// `view` gives on first use. `known` is the brick's exact value range when the
    /// caller has it: a brick of one value needs no read.
    pub fn of_brick<'a, T: Sample>(
        &self,
        index: u64,
        known: Option<[u16; 2]>,
        view: impl FnOnce() -> BrickView<'a, T>,
    ) -> &[[u16; 2]] {
        self.bricks[index as usize].get_or_init(|| {
            let mut out = vec![[0u16; 2]; self.per_brick()].into_boxed_slice();
            match known {
                Some([lo, hi]) if lo == hi => out.fill([lo, hi]),
                _ => {
                    self.scanned.fetch_add(1, Ordering::Relaxed);
                    brick_cells(&view(), self.per_axis, self.cell_step, &mut out);
                }
            }
            out
        })
    }

    /// The ranges of brick number `index` if some frame already computed them.
    pub fn cached(&self, index: u64) -> Option<&[[u16; 2]]> {
        self.bricks[index as usize].get().map(|b| &b[..])
    }

    /// Bricks whose cells are known.
    pub fn bricks_known(&self) -> u64 {
        self.bricks.iter().filter(|b| b.get().is_some()).count() as u64
    }

    /// Bricks whose cells were computed by reading their samples.
    pub fn bricks_scanned(&self) -> u64 {
        self.scanned.load(Ordering::Relaxed)
    }
}

fn brick_cells<T: Sample>(
    view: &BrickView<'_, T>,
    per_axis: u32,
    cell_step: u32,
    out: &mut [[u16; 2]],
) {
    let extent = view.extent();
    let (lo, hi) = view.value_range();
    if lo == hi {
        out.fill([lo.to_u16(), hi.to_u16()]);
        return;
    }
    let mut i = 0;
    for cx in 0..per_axis {
        for cy in 0..per_axis {
            for cz in 0..per_axis {
                let c = [cx, cy, cz];
                let start = c.map(|v| v * cell_step);
                if (0..3).any(|a| start[a] >= extent[a]) {
                    // A cell past an edge brick's voxels owns no sample.
                    out[i] = [u16::MAX, 0];
                } else {
                    let size = [0, 1, 2].map(|a| (cell_step + 1).min(extent[a] - start[a]));
                    let (l, h) = view.sub(start, size).value_range();
                    out[i] = [l.to_u16(), h.to_u16()];
                }
                i += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Layout, TypedVolume};

    #[test]
    fn huge_volumes_get_larger_cells() {
        assert_eq!(target_cell_step([256; 3]), 4);
        assert_eq!(target_cell_step([2000; 3]), 8);
        let cells = |d: u32| (u64::from(d) / u64::from(target_cell_step([d; 3]))).pow(3);
        assert!(cells(5120) <= MAX_CELLS * 2);
    }

    #[test]
    fn cells_cover_their_voxels_and_the_overlap() {
        let dims = [20, 17, 9];
        let samples: Vec<u8> = (0..20 * 17 * 9).map(|i| (i * 37 % 251) as u8).collect();
        let vol = TypedVolume::new(&samples, dims, Layout::Linear);
        let grid = BlockGrid::new(dims, 16);
        let cells = CellRanges::compute(&grid, |b| vol.brick(&grid, b));
        assert_eq!((cells.per_axis(), cells.cell_step()), (4, 4));
        for b in grid.iter() {
            let ranges = cells.cached(grid.index(b)).unwrap();
            let o = grid.origin(b);
            let e = grid.extent(b);
            for x in 0..e[0] {
                for y in 0..e[1] {
                    for z in 0..e[2] {
                        let v = u16::from(vol.voxel([o[0] + x, o[1] + y, o[2] + z]));
                        // Every cell whose span [c·4, c·4 + 4] holds the voxel.
                        for cx in 0..4u32 {
                            for cy in 0..4u32 {
                                for cz in 0..4u32 {
                                    let holds = [(x, cx), (y, cy), (z, cz)]
                                        .iter()
                                        .all(|&(l, c)| l >= c * 4 && l <= c * 4 + 4);
                                    if holds {
                                        let [lo, hi] = ranges[((cx * 4 + cy) * 4 + cz) as usize];
                                        assert!(lo <= v && v <= hi);
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}
