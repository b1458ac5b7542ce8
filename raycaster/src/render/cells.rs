//! Value ranges of small cells inside each brick: the fine level of empty-space
//! skipping (the thesis's `EmptyIndex` for linear volumes, here for every layout).
//!
//! Each brick's owned cells (`step` per axis) are split into `m³` cells of about
//! [`target_cell_step`] voxels; a cell spans its cells plus the voxel after, so the
//! trilinear reads of any sample it owns lie within its range.

use rayon::prelude::*;

use crate::volume::{BlockGrid, BrickView, Sample};

/// Smallest cell size aimed at, in voxel steps per axis.
pub const TARGET_CELL_STEP: u32 = 4;

/// Cells beyond which larger cells are used, to bound the index's memory
/// (4 bytes of range and 1 byte of flag per cell: about 80 MB).
pub const MAX_CELLS: u64 = 1 << 24;

/// The cell step aimed at for a volume of `dims`: [`TARGET_CELL_STEP`], or larger
/// when the volume would need more than [`MAX_CELLS`] cells.
pub fn target_cell_step(dims: [u32; 3]) -> u32 {
    let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
    let bound = (voxels as f64 / MAX_CELLS as f64).cbrt().ceil() as u32;
    bound.max(TARGET_CELL_STEP)
}

/// Per-brick cell ranges of a whole brick grid.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CellRanges {
    /// Cells per brick and axis.
    per_axis: u32,
    /// Cell step in voxels.
    cell_step: u32,
    /// `per_axis³` ranges per brick, bricks in file order, cells x-slowest.
    ranges: Vec<[u16; 2]>,
}

impl CellRanges {
    /// No cells (a placeholder before a scan).
    pub fn empty() -> Self {
        CellRanges {
            per_axis: 1,
            cell_step: 1,
            ranges: Vec::new(),
        }
    }

    /// Scans every brick of `grid`, whose views `brick` gives (in parallel).
    pub fn compute<'a, T: Sample>(
        grid: &BlockGrid,
        brick: impl Fn([u32; 3]) -> BrickView<'a, T> + Sync,
    ) -> Self {
        let per_axis = grid.step().div_ceil(target_cell_step(grid.dims())).max(1);
        let cell_step = grid.step().div_ceil(per_axis);
        let cells = (per_axis * per_axis * per_axis) as usize;
        let mut ranges = vec![[0u16; 2]; grid.block_count() as usize * cells];
        ranges
            .par_chunks_mut(cells)
            .enumerate()
            .for_each(|(i, out)| {
                let view = brick(grid.coords(i as u64));
                brick_cells(&view, per_axis, cell_step, out);
            });
        CellRanges {
            per_axis,
            cell_step,
            ranges,
        }
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

    /// The ranges of brick number `index` (file order).
    pub fn of_brick(&self, index: u64) -> &[[u16; 2]] {
        let n = self.per_brick();
        &self.ranges[index as usize * n..(index as usize + 1) * n]
    }

    /// All ranges, brick by brick.
    pub fn as_slice(&self) -> &[[u16; 2]] {
        &self.ranges
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
            let ranges = cells.of_brick(grid.index(b));
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
