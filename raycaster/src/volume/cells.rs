//! Value ranges of the small cells inside each brick: what empty-space skipping
//! tests inside a brick that is not empty as a whole (the thesis's `EmptyIndex`).
//!
//! A brick's owned voxels (`step` per axis) are split into `m³` cells of
//! `cell_step` voxels; a cell's range spans its voxels plus the voxel after, so the
//! trilinear reads of any sample it owns lie within it. [`CellShape`] is the rule
//! that gives `m` and `cell_step` for a grid; [`CellShape::scan_brick`] computes one
//! brick's cells. The renderer computes them lazily the first time a frame visits a
//! brick (`render::CellRanges`); writers store them in the file's pyramid block
//! ([`CellTable`], docs/format.md "Cell-range tables"), so a renderer of a file
//! written by this build reads them instead of scanning.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::sync::Arc;

use memmap2::Mmap;
use rayon::prelude::*;

use super::grid::BlockGrid;
use super::header::{Header, Layout, SampleType};
use super::ranges::LINEAR_RANGE_SIDE;
use super::sample::Sample;
use super::storage::Access;
use super::view::BrickView;

/// Smallest cell size aimed at, in voxel steps per axis.
pub const TARGET_CELL_STEP: u32 = 4;

/// Cells beyond which larger cells are used, to bound the work per brick.
pub const MAX_CELLS: u64 = 1 << 24;

/// Bricks of the [`LINEAR_RANGE_SIDE`] grid beyond which linear volumes are rendered
/// with larger bricks: per-frame scheduling and ray–brick clipping grow with the
/// brick count (2000³, 700², step 0.2, 2 threads: 1.32 s with 16-voxel bricks,
/// 0.91 s with 32), while up to about 800³ the two sides are equally fast.
pub const LARGE_LINEAR_BRICKS: u64 = 1 << 18;

const TABLE_MAGIC: [u8; 4] = *b"RCCR";
/// Bytes of a cell table's head, before its entries.
pub const CELL_TABLE_HEAD_LEN: u64 = 40;

/// The cell step aimed at for a volume of `dims`: [`TARGET_CELL_STEP`], or larger
/// when the volume would need more than [`MAX_CELLS`] cells.
pub fn target_cell_step(dims: [u32; 3]) -> u32 {
    let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
    let bound = (voxels as f64 / MAX_CELLS as f64).cbrt().ceil() as u32;
    bound.max(TARGET_CELL_STEP)
}

/// The default logical brick side of a linear volume of `dims`: [`LINEAR_RANGE_SIDE`]
/// (16), or for volumes whose 16-grid has more than [`LARGE_LINEAR_BRICKS`] bricks,
/// bricks spanning two of those per axis (side 31), whose ranges merge from the
/// file's table without a scan.
pub fn default_linear_brick_side(dims: [u32; 3]) -> u32 {
    let fine = BlockGrid::new(dims, LINEAR_RANGE_SIDE);
    if fine.block_count() > LARGE_LINEAR_BRICKS {
        2 * fine.step() + 1
    } else {
        LINEAR_RANGE_SIDE
    }
}

/// How the bricks of a grid are cut into cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellShape {
    grid: BlockGrid,
    per_axis: u32,
    cell_step: u32,
}

impl CellShape {
    /// The cells of `grid`'s bricks: about [`target_cell_step`] voxels each.
    pub fn of_grid(grid: &BlockGrid) -> Self {
        let per_axis = grid.step().div_ceil(target_cell_step(grid.dims())).max(1);
        CellShape {
            grid: *grid,
            per_axis,
            cell_step: grid.step().div_ceil(per_axis),
        }
    }

    /// The cells of the grid a renderer uses by default for a volume with
    /// `header`: its stored bricks, or for linear files logical bricks of
    /// [`default_linear_brick_side`].
    pub fn default_for(header: &Header) -> Self {
        let side = match header.layout {
            Layout::Bricked { side } => u32::from(side),
            Layout::Linear => default_linear_brick_side(header.dims),
        };
        Self::of_grid(&BlockGrid::new(header.dims, side))
    }

    /// The brick grid.
    pub fn grid(&self) -> &BlockGrid {
        &self.grid
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
        (self.per_axis as usize).pow(3)
    }

    /// Bytes of one brick's stored cells in a volume of `sample`s: a `[min, max]`
    /// pair per cell, each bound a sample.
    pub fn brick_bytes(&self, sample: SampleType) -> u64 {
        self.per_brick() as u64 * 2 * sample.size()
    }

    /// Bytes of the stored table of these cells for a volume of `sample`s, head
    /// included (`None`: beyond 64 bits).
    pub fn table_len(&self, sample: SampleType) -> Option<u64> {
        self.grid
            .block_count()
            .checked_mul(self.brick_bytes(sample))?
            .checked_add(CELL_TABLE_HEAD_LEN)
    }

    /// The head of the stored table of these cells for a volume of `sample`s.
    pub fn encode_head(&self, sample: SampleType) -> Vec<u8> {
        let mut out = Vec::with_capacity(CELL_TABLE_HEAD_LEN as usize);
        out.extend_from_slice(&TABLE_MAGIC);
        out.extend_from_slice(&self.grid.side().to_le_bytes());
        for d in self.grid.dims() {
            out.extend_from_slice(&d.to_le_bytes());
        }
        out.extend_from_slice(&self.grid.block_count().to_le_bytes());
        out.extend_from_slice(&self.per_axis.to_le_bytes());
        out.extend_from_slice(&self.cell_step.to_le_bytes());
        out.extend_from_slice(&(sample.size() as u32).to_le_bytes());
        debug_assert_eq!(out.len() as u64, CELL_TABLE_HEAD_LEN);
        out
    }

    /// Computes the cells of one brick, `view` (a brick of this shape's grid),
    /// into `out` (`per_brick` entries, x slowest). A cell past an edge brick's
    /// voxels owns no sample and gets the empty range `[u16::MAX, 0]`; a brick of
    /// one value gives that value to every cell.
    ///
    /// Min and max are separable: the brick is reduced axis by axis, x first
    /// (whole planes element by element, which vectorises), then y (rows), then z,
    /// so each voxel is read about once and cheaply rather than once per cell that
    /// shares it.
    pub fn scan_brick<T: Sample>(&self, view: &BrickView<'_, T>, out: &mut [[u16; 2]]) {
        const EMPTY: [u16; 2] = [u16::MAX, 0];
        let (m, cs) = (self.per_axis as usize, self.cell_step as usize);
        let e = view.extent().map(|v| v as usize);
        // Per axis, the voxels of each cell that starts inside the brick: its own
        // and the one after, cut at the edge (start, end exclusive).
        let spans = e.map(|extent| {
            (0..extent.div_ceil(cs).min(m))
                .map(|c| (c * cs, (c * cs + cs + 1).min(extent)))
                .collect::<Vec<_>>()
        });
        let n = spans.each_ref().map(Vec::len);
        // Constant bricks (empty space, mostly) are common: a check that stops at
        // the first other value spares them the scan.
        let first = view.get([0, 0, 0]);
        let constant = (0..e[0] as u32)
            .all(|x| (0..e[1] as u32).all(|y| view.row(x, y).iter().all(|&v| v == first)));
        if constant {
            out.fill([first.to_u16(); 2]);
            return;
        }
        let copy;
        let dense = match view.contiguous() {
            Some(samples) => samples,
            None => {
                let mut rows = Vec::with_capacity(e[0] * e[1] * e[2]);
                for x in 0..e[0] {
                    for y in 0..e[1] {
                        rows.extend_from_slice(view.row(x as u32, y as u32));
                    }
                }
                copy = rows;
                &copy[..]
            }
        };
        // [x, y, z] → [x cell, y, z] → [x cell, y cell, z] → [x cell, y cell, z cell].
        let (lo, hi) = (
            reduce_axis(dense, [1, e[0], e[1] * e[2]], &spans[0], T::min),
            reduce_axis(dense, [1, e[0], e[1] * e[2]], &spans[0], T::max),
        );
        let (lo, hi) = (
            reduce_axis(&lo, [n[0], e[1], e[2]], &spans[1], T::min),
            reduce_axis(&hi, [n[0], e[1], e[2]], &spans[1], T::max),
        );
        let (lo, hi) = (
            reduce_axis(&lo, [n[0] * n[1], e[2], 1], &spans[2], T::min),
            reduce_axis(&hi, [n[0] * n[1], e[2], 1], &spans[2], T::max),
        );
        out.fill(EMPTY);
        for (i, (&l, &h)) in lo.iter().zip(&hi).enumerate() {
            let (cx, cy, cz) = (i / (n[1] * n[2]), i / n[2] % n[1], i % n[2]);
            out[(cx * m + cy) * m + cz] = [l.to_u16(), h.to_u16()];
        }
    }

    /// The cells of bricks `bricks` (file-order indices), whose views `brick`
    /// gives, in order (in parallel).
    pub fn scan_bricks<'a, T: Sample>(
        &self,
        bricks: std::ops::Range<u64>,
        brick: impl Fn([u32; 3]) -> BrickView<'a, T> + Sync,
    ) -> Vec<[u16; 2]> {
        let per_brick = self.per_brick();
        let mut out = vec![[0u16; 2]; (bricks.end - bricks.start) as usize * per_brick];
        out.par_chunks_mut(per_brick)
            .enumerate()
            .for_each(|(i, cells)| {
                let b = self.grid.coords(bricks.start + i as u64);
                self.scan_brick(&brick(b), cells);
            });
        out
    }

    /// Scans the bricks of columns `columns` (their x index), whose views `brick`
    /// gives, and writes their cells into the table at byte `offset` of `file`.
    pub(crate) fn write_columns<'a, T: Sample>(
        &self,
        file: &File,
        offset: u64,
        columns: std::ops::Range<u32>,
        brick: impl Fn([u32; 3]) -> BrickView<'a, T> + Sync,
    ) -> std::io::Result<()> {
        let [_, ny, nz] = self.grid.counts();
        let per_x = u64::from(ny) * u64::from(nz);
        let bricks = u64::from(columns.start) * per_x..u64::from(columns.end) * per_x;
        let first = bricks.start;
        self.write_cells::<T>(file, offset, first, &self.scan_bricks(bricks, brick))
    }

    /// Writes `cells`, those of the bricks from number `first` on, into the table
    /// at byte `offset` of `file` (a volume of `T`s: [`encode_cells`]).
    pub(crate) fn write_cells<T: Sample>(
        &self,
        file: &File,
        offset: u64,
        first: u64,
        cells: &[[u16; 2]],
    ) -> std::io::Result<()> {
        let at = offset + CELL_TABLE_HEAD_LEN + first * self.brick_bytes(T::TYPE);
        file.write_all_at(&encode_cells(cells, T::TYPE), at)
    }
}

/// Cell ranges as a table stores them for a volume of `sample`s: each bound as a
/// little-endian sample (u8 volumes: one byte; the empty range `[65535, 0]`
/// becomes `[255, 0]`, which no range of u8 values is).
fn encode_cells(cells: &[[u16; 2]], sample: SampleType) -> Vec<u8> {
    match sample {
        SampleType::U8 => cells
            .iter()
            .flat_map(|&[lo, hi]| [lo.min(255) as u8, hi.min(255) as u8])
            .collect(),
        SampleType::U16 => cells
            .iter()
            .flat_map(|&[lo, hi]| [lo.to_le_bytes(), hi.to_le_bytes()])
            .flatten()
            .collect(),
    }
}

/// The cell ranges of [`encode_cells`]'s bytes (without a branch per cell:
/// a brick's are decoded each time a frame's task marches it).
fn decode_cells<C: FromIterator<[u16; 2]>>(bytes: &[u8], sample: SampleType) -> C {
    match sample {
        SampleType::U8 => bytes
            .as_chunks::<2>()
            .0
            .iter()
            .map(|&[lo, hi]| {
                let empty = lo > hi;
                [
                    if empty { u16::MAX } else { u16::from(lo) },
                    if empty { 0 } else { u16::from(hi) },
                ]
            })
            .collect(),
        SampleType::U16 => bytes
            .as_chunks::<4>()
            .0
            .iter()
            .map(|&[a, b, c, d]| [u16::from_le_bytes([a, b]), u16::from_le_bytes([c, d])])
            .collect(),
    }
}

/// `data` seen as `[outer][len][inner]`, reduced with `f` over each span of the
/// middle axis: `[outer][spans.len()][inner]`.
fn reduce_axis<T: Sample>(
    data: &[T],
    [outer, len, inner]: [usize; 3],
    spans: &[(usize, usize)],
    f: impl Fn(T, T) -> T + Copy,
) -> Vec<T> {
    let mut out = Vec::with_capacity(outer * spans.len() * inner);
    if inner == 1 {
        for block in data.chunks_exact(len).take(outer) {
            for &(start, end) in spans {
                let run = &block[start..end];
                out.push(run[1..].iter().fold(run[0], |a, &v| f(a, v)));
            }
        }
        return out;
    }
    for block in data.chunks_exact(len * inner).take(outer) {
        for &(start, end) in spans {
            let at = out.len();
            out.extend_from_slice(&block[start * inner..][..inner]);
            for j in start + 1..end {
                fold_lanes(&mut out[at..], &block[j * inner..][..inner], f);
            }
        }
    }
    out
}

/// `acc[i] = f(acc[i], row[i])` over the shorter of the two, 16 lanes at a time.
#[inline]
fn fold_lanes<T: Sample>(acc: &mut [T], row: &[T], f: impl Fn(T, T) -> T) {
    const LANES: usize = 16;
    let len = acc.len().min(row.len());
    let (acc, row) = (&mut acc[..len], &row[..len]);
    let mut acc_chunks = acc.chunks_exact_mut(LANES);
    let mut row_chunks = row.chunks_exact(LANES);
    for (a, r) in (&mut acc_chunks).zip(&mut row_chunks) {
        let (a, r): (&mut [T; LANES], &[T; LANES]) = (
            a.try_into().expect("a chunk"),
            r.try_into().expect("a chunk"),
        );
        for j in 0..LANES {
            a[j] = f(a[j], r[j]);
        }
    }
    for (a, &r) in acc_chunks
        .into_remainder()
        .iter_mut()
        .zip(row_chunks.remainder())
    {
        *a = f(*a, r);
    }
}

/// The stored cell ranges of every brick of one level, as a file holds them.
#[derive(Clone, Debug)]
pub struct CellTable {
    shape: CellShape,
    /// The volume's sample type: the width of each stored bound.
    sample: SampleType,
    entries: Entries,
}

/// Where a table's entries live (as stored: [`encode_cells`]).
#[derive(Clone, Debug)]
enum Entries {
    /// Read into memory.
    Owned(Vec<u8>),
    /// In a read-only mapping of exactly the entries, shared by clones.
    Mapped(Arc<Mmap>),
}

impl CellTable {
    /// The table of `shape` for a volume of `sample`s at byte `offset` of `file`
    /// (at most `len` bytes), its entries mapped read-only where `access` maps
    /// and the file allows it, else read. `Ok(None)` when the bytes are not a
    /// table of exactly that shape.
    pub fn read_from(
        file: &File,
        offset: u64,
        len: u64,
        shape: &CellShape,
        sample: SampleType,
        access: Access,
    ) -> std::io::Result<Option<Self>> {
        let Some(table_len) = shape.table_len(sample) else {
            return Ok(None);
        };
        if len < table_len {
            return Ok(None);
        }
        let mut head = [0u8; CELL_TABLE_HEAD_LEN as usize];
        file.read_exact_at(&mut head, offset)?;
        if head[..] != shape.encode_head(sample)[..] {
            return Ok(None);
        }
        let body = table_len - CELL_TABLE_HEAD_LEN;
        let start = offset + CELL_TABLE_HEAD_LEN;
        let mapped = match access {
            Access::Mapped => super::pyramid::map_region(file, start, body).ok(),
            Access::Ram => None,
        };
        let entries = match mapped {
            Some(map) => {
                // A frame reads the cells of the bricks it marches, scattered over
                // the table: read-ahead would fetch the cells of bricks it skips.
                let _ = map.advise(memmap2::Advice::Random);
                Entries::Mapped(Arc::new(map))
            }
            None => {
                let mut bytes = vec![0u8; body as usize];
                file.read_exact_at(&mut bytes, start)?;
                Entries::Owned(bytes)
            }
        };
        Ok(Some(CellTable {
            shape: *shape,
            sample,
            entries,
        }))
    }

    fn bytes(&self) -> &[u8] {
        match &self.entries {
            Entries::Owned(v) => v,
            Entries::Mapped(map) => &map[..],
        }
    }

    /// How the bricks are cut into cells.
    pub fn shape(&self) -> &CellShape {
        &self.shape
    }

    /// The cells of brick number `index` (file order), x slowest.
    pub fn brick(&self, index: u64) -> Arc<[[u16; 2]]> {
        let bytes = self.shape.brick_bytes(self.sample) as usize;
        decode_cells(
            &self.bytes()[index as usize * bytes..][..bytes],
            self.sample,
        )
    }

    /// Every brick's cells, in brick order.
    pub fn to_vec(&self) -> Vec<[u16; 2]> {
        decode_cells(self.bytes(), self.sample)
    }

    /// Asks the OS to read the cells of brick `index` ahead (mapped tables; the
    /// table is advised for random access, so nothing else is read).
    pub fn prefetch(&self, index: u64) {
        if let Entries::Mapped(map) = &self.entries {
            let bytes = self.shape.brick_bytes(self.sample) as usize;
            let start = (index as usize * bytes).min(map.len());
            let len = bytes.min(map.len() - start);
            if len > 0 {
                let _ = map.advise_range(memmap2::Advice::WillNeed, start, len);
            }
        }
    }

    /// Whether the entries are read through a mapping of the file.
    pub fn is_mapped(&self) -> bool {
        matches!(self.entries, Entries::Mapped(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{SampleType, TypedVolume};

    #[test]
    fn a_written_table_reads_back_mapped_and_equals_a_scan() {
        let dims = [40, 33, 20];
        let samples: Vec<u8> = (0..40 * 33 * 20).map(|i| (i * 53 % 241) as u8).collect();
        let vol = TypedVolume::new(&samples, dims, Layout::Linear);
        let shape = CellShape::of_grid(&BlockGrid::new(dims, 9));
        let dir = tempfile::tempdir().unwrap();
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(dir.path().join("cells"))
            .unwrap();
        file.write_all_at(&shape.encode_head(SampleType::U8), 64)
            .unwrap();
        shape
            .write_columns(&file, 64, 0..shape.grid().counts()[0], |b| {
                vol.brick(shape.grid(), b)
            })
            .unwrap();
        let len = shape.table_len(SampleType::U8).unwrap();
        let table = CellTable::read_from(&file, 64, len, &shape, SampleType::U8, Access::Mapped)
            .unwrap()
            .unwrap();
        assert!(table.is_mapped());
        let all = shape.scan_bricks(0..shape.grid().block_count(), |b| {
            vol.brick(shape.grid(), b)
        });
        assert_eq!(table.to_vec(), all);
        // A volume held in RAM reads its table too (nothing of it stays mapped).
        let read = CellTable::read_from(&file, 64, len, &shape, SampleType::U8, Access::Ram)
            .unwrap()
            .unwrap();
        assert!(!read.is_mapped());
        assert_eq!(read.to_vec(), all);
        // Each bound takes a byte in a u8 volume; the empty range survives.
        assert_eq!(
            len,
            40 + shape.grid().block_count() * shape.per_brick() as u64 * 2
        );
        assert!(
            all.contains(&[u16::MAX, 0]),
            "edge bricks have cells past the edge"
        );
        let wide = [[3, 60000], [u16::MAX, 0], [7, 7]];
        for sample in [SampleType::U8, SampleType::U16] {
            let narrow = [[3, 200], [u16::MAX, 0], [7, 7]];
            let cells = if sample == SampleType::U8 {
                &narrow
            } else {
                &wide
            };
            assert_eq!(
                decode_cells::<Vec<_>>(&encode_cells(cells, sample), sample),
                cells
            );
        }
        // Cut short, or read for another shape: no table.
        assert!(
            CellTable::read_from(&file, 64, len - 1, &shape, SampleType::U8, Access::Mapped)
                .unwrap()
                .is_none()
        );
        let other = CellShape::of_grid(&BlockGrid::new(dims, 5));
        assert!(
            CellTable::read_from(&file, 64, len, &other, SampleType::U8, Access::Mapped)
                .unwrap()
                .is_none()
        );
        // The default shape follows the layout.
        let header = Header::new(
            dims,
            [1.0; 3],
            Layout::Bricked { side: 9 },
            SampleType::U8,
            crate::volume::Content::Scalar,
            crate::volume::Format::Extended,
        );
        assert_eq!(CellShape::default_for(&header), shape);
    }
}
