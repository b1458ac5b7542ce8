//! Value ranges of small cells inside each brick: the fine level of empty-space
//! skipping (the thesis's `EmptyIndex` for linear volumes, here for every layout).
//!
//! Each brick's owned cells (`step` per axis) are split into `m³` cells of about
//! [`target_cell_step`] voxels; a cell spans its cells plus the voxel after, so the
//! trilinear reads of any sample it owns lie within its range.
//!
//! Files written by this build store the cells of their default grid (their
//! pyramid block: `volume::CellTable`); a frame reads a brick's cells from there.
//! Otherwise nothing is scanned when a volume is opened: a brick's cells are
//! computed the first time a frame marches a ray through it and kept for later
//! frames, up to a memory budget ([`CELL_CACHE_BYTES`]; beyond it they are computed
//! again for each visit, which costs one pass over a brick the task then marches
//! anyway). Bricks that no
//! frame visits (empty under every transfer function used, or never in view) are
//! never read; a brick whose stored range is a single value needs no read at all.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use parking_lot::RwLock;

use crate::volume::{BlockGrid, BrickView, CellShape, CellTable, Sample};

pub use crate::volume::{MAX_CELLS, TARGET_CELL_STEP, target_cell_step};

/// Memory the cache of computed cell ranges may take, per prepared volume.
pub const CELL_CACHE_BYTES: usize = 48 << 20;

/// The ranges of one brick's cells, `per_axis³` of them, x slowest.
pub type BrickCells = Arc<[[u16; 2]]>;

/// Per-brick cell ranges of a brick grid: read from the file's stored table where
/// it has one for this grid, else computed lazily brick by brick.
#[derive(Debug)]
pub struct CellRanges {
    /// How bricks are cut into cells.
    shape: CellShape,
    /// The file's table of these cells, if it stores one.
    stored: Option<CellTable>,
    /// Computed bricks by file-order index, while within the budget.
    cache: RwLock<HashMap<u64, BrickCells>>,
    /// Bricks the cache may hold.
    capacity: usize,
    /// Bricks whose cells were computed by reading samples.
    scanned: AtomicU64,
}

impl CellRanges {
    /// The (not yet computed) cell ranges of the bricks of `grid`.
    pub fn lazy(grid: &BlockGrid) -> Self {
        let shape = CellShape::of_grid(grid);
        // The ranges, their Arc's counts and a map entry.
        let entry = shape.per_brick() * 4 + 64;
        CellRanges {
            shape,
            stored: None,
            cache: RwLock::new(HashMap::new()),
            capacity: CELL_CACHE_BYTES / entry,
            scanned: AtomicU64::new(0),
        }
    }

    /// The cell ranges of the bricks of `grid`, read from `stored` (a file's table)
    /// when it is a table of exactly these cells, else computed lazily.
    pub fn stored_or_lazy(grid: &BlockGrid, stored: Option<&CellTable>) -> Self {
        let mut cells = Self::lazy(grid);
        cells.stored = stored.filter(|t| t.shape() == &cells.shape).cloned();
        cells
    }

    /// Asks the OS to read the stored cells of brick `index` ahead, if they are
    /// stored (see [`CellTable::prefetch`]).
    pub(crate) fn prefetch(&self, index: u64) {
        if let Some(table) = &self.stored {
            table.prefetch(index);
        }
    }

    /// Whether the ranges come from the file's stored table.
    pub fn is_stored(&self) -> bool {
        self.stored.is_some()
    }

    /// Scans every brick of `grid`, whose views `brick` gives (in parallel); what a
    /// renderer computes lazily, all at once (for tests and tools).
    pub fn compute<'a, T: Sample>(
        grid: &BlockGrid,
        brick: impl Fn([u32; 3]) -> BrickView<'a, T> + Sync,
    ) -> Self {
        use rayon::prelude::*;
        let mut cells = Self::lazy(grid);
        cells.capacity = usize::MAX;
        (0..grid.block_count()).into_par_iter().for_each(|i| {
            cells.of_brick(i, None, || brick(grid.coords(i)));
        });
        cells
    }

    /// Cells per brick and axis.
    pub fn per_axis(&self) -> u32 {
        self.shape.per_axis()
    }

    /// Cell step in voxels.
    pub fn cell_step(&self) -> u32 {
        self.shape.cell_step()
    }

    /// Cells per brick.
    pub fn per_brick(&self) -> usize {
        self.shape.per_brick()
    }

    /// The ranges of brick number `index` (file order), computed from the view
    /// `view` gives unless cached. `known` is the brick's exact value range when the
    /// caller has it: a brick of one value needs no read.
    pub fn of_brick<'a, T: Sample>(
        &self,
        index: u64,
        known: Option<[u16; 2]>,
        view: impl FnOnce() -> BrickView<'a, T>,
    ) -> BrickCells {
        if let Some(table) = &self.stored {
            return table.brick(index);
        }
        if let Some(cells) = self.cache.read().get(&index) {
            return cells.clone();
        }
        let cells: BrickCells = match known {
            Some([lo, hi]) if lo == hi => vec![[lo, hi]; self.per_brick()].into(),
            _ => {
                self.scanned.fetch_add(1, Ordering::Relaxed);
                let mut out = vec![[0u16; 2]; self.per_brick()];
                self.shape.scan_brick(&view(), &mut out);
                out.into()
            }
        };
        let mut cache = self.cache.write();
        if cache.len() < self.capacity {
            cache.insert(index, cells.clone());
        }
        cells
    }

    /// The ranges of brick number `index` if they are cached.
    pub fn cached(&self, index: u64) -> Option<BrickCells> {
        self.cache.read().get(&index).cloned()
    }

    /// Bricks whose cells are cached.
    pub fn bricks_known(&self) -> u64 {
        self.cache.read().len() as u64
    }

    /// Bricks whose cells were computed by reading their samples (cached or not).
    pub fn bricks_scanned(&self) -> u64 {
        self.scanned.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Layout, TypedVolume};

    #[test]
    fn beyond_the_cache_budget_cells_are_computed_again_and_equal() {
        let dims = [40, 33, 20];
        let samples: Vec<u8> = (0..40 * 33 * 20).map(|i| (i * 53 % 241) as u8).collect();
        let vol = TypedVolume::new(&samples, dims, Layout::Linear);
        let grid = BlockGrid::new(dims, 9);
        let all = CellRanges::compute(&grid, |b| vol.brick(&grid, b));
        let mut small = CellRanges::lazy(&grid);
        small.capacity = 3;
        for round in 0..2 {
            for b in grid.iter() {
                let i = grid.index(b);
                let cells = small.of_brick(i, None, || vol.brick(&grid, b));
                assert_eq!(cells, all.cached(i).unwrap(), "round {round} brick {b:?}");
            }
        }
        assert_eq!(small.bricks_known(), 3);
        // The three cached bricks were read once, every other brick twice.
        assert_eq!(small.bricks_scanned(), 2 * grid.block_count() - 3);
    }

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
