//! Per-brick value ranges (min/max of the samples), the basis of empty-space skipping.
//!
//! Computed in one parallel streaming pass over the bricks and stored, so re-opening a
//! multi-GB file does not rescan it: files with the extended header carry the table
//! after their samples; thesis files get a sidecar `<file>.ranges` that records the
//! length and modification time of the file it describes.
//!
//! A table opened from a mapped file stays in the file: its entries are read through
//! a read-only mapping of the table (page cache, not this process's anonymous
//! memory), so a volume of millions of bricks costs no heap for its ranges.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::sync::Arc;
use std::time::SystemTime;

use memmap2::Mmap;
use rayon::prelude::*;

use super::grid::BlockGrid;
use super::sample::Sample;
use super::storage::Access;
use super::view::TypedVolume;

/// Side of the logical bricks whose ranges are kept for linear volumes.
pub const LINEAR_RANGE_SIDE: u32 = 16;
const TABLE_MAGIC: [u8; 4] = *b"RCRG";
const SIDECAR_MAGIC: [u8; 4] = *b"RCRS";
const SIDECAR_VERSION: u32 = 1;
const TABLE_HEADER_LEN: usize = 4 + 4 + 12 + 8;
const SIDECAR_HEADER_LEN: usize = 4 + 4 + 8 + 8 + 4;

/// The smallest and largest sample of every brick of a grid.
#[derive(Clone, Debug)]
pub struct BrickRanges {
    grid: BlockGrid,
    ranges: Entries,
}

/// Where a table's `[min, max]` entries live.
#[derive(Clone, Debug)]
enum Entries {
    /// Computed or decoded into memory.
    Owned(Vec<[u16; 2]>),
    /// In a read-only mapping of exactly the entries (little-endian u16 pairs,
    /// 2-byte aligned: checked when mapped), shared by clones.
    Mapped(Arc<Mmap>),
}

impl PartialEq for BrickRanges {
    fn eq(&self, other: &Self) -> bool {
        self.grid == other.grid && self.as_slice() == other.as_slice()
    }
}

impl Eq for BrickRanges {}

/// The `[min, max]` of brick `b` of `grid` in `volume`, as a table holds it.
pub(crate) fn brick_range<T: Sample>(
    volume: &TypedVolume<'_, T>,
    grid: &BlockGrid,
    b: [u32; 3],
) -> [u16; 2] {
    let (lo, hi) = volume.brick(grid, b).value_range();
    [lo.to_u16(), hi.to_u16()]
}

impl BrickRanges {
    /// Scans every brick of `grid` in `volume` (in parallel).
    pub fn compute<T: Sample>(volume: &TypedVolume<'_, T>, grid: &BlockGrid) -> Self {
        let ranges = (0..grid.block_count())
            .into_par_iter()
            .map(|i| brick_range(volume, grid, grid.coords(i)))
            .collect();
        BrickRanges {
            grid: *grid,
            ranges: Entries::Owned(ranges),
        }
    }

    /// Builds from ranges already known, in file order of `grid`.
    ///
    /// # Panics
    /// If the count does not match the grid.
    pub fn from_parts(grid: BlockGrid, ranges: Vec<[u16; 2]>) -> Self {
        assert_eq!(ranges.len() as u64, grid.block_count());
        BrickRanges {
            grid,
            ranges: Entries::Owned(ranges),
        }
    }

    /// The ranges of the coarser grid whose bricks span `factor` of these bricks
    /// per axis (step `factor × step`), merged from these without reading a sample:
    /// brick `j` of the coarse grid covers exactly bricks `j·factor ..
    /// j·factor + factor − 1` of this one (clamped at the volume's end).
    pub fn coarsened(&self, factor: u32) -> BrickRanges {
        let factor = factor.max(1);
        let grid = BlockGrid::new(self.grid.dims(), factor * self.grid.step() + 1);
        let fine = self.grid.counts();
        let ranges = grid
            .iter()
            .map(|j| {
                let lo = j.map(|c| c * factor);
                let hi = [0, 1, 2].map(|a| (lo[a] + factor).min(fine[a]));
                let mut merged = [u16::MAX, 0];
                for x in lo[0]..hi[0] {
                    for y in lo[1]..hi[1] {
                        for z in lo[2]..hi[2] {
                            let [l, h] = self.range([x, y, z]);
                            merged = [merged[0].min(l), merged[1].max(h)];
                        }
                    }
                }
                merged
            })
            .collect();
        BrickRanges {
            grid,
            ranges: Entries::Owned(ranges),
        }
    }

    /// Ranges for another grid over the same volume, merged from these without
    /// reading a sample: each brick of `grid` gets the union of the ranges of the
    /// bricks here that hold any of its voxels. Exact when `grid`'s bricks are
    /// unions of these (the same grid, or [`Self::coarsened`]'s); otherwise a
    /// superset of the true range, which empty-space skipping may use safely.
    pub fn covering(&self, grid: &BlockGrid) -> BrickRanges {
        let ranges = grid.iter().map(|b| self.covering_range(grid, b)).collect();
        BrickRanges {
            grid: *grid,
            ranges: Entries::Owned(ranges),
        }
    }

    /// The range of brick `b` of another grid over the same volume, merged from
    /// these ([`Self::covering`]'s entry for `b`, without building the table).
    pub fn covering_range(&self, grid: &BlockGrid, b: [u32; 3]) -> [u16; 2] {
        if grid == &self.grid {
            return self.range(b);
        }
        let step = self.grid.step();
        let counts = self.grid.counts();
        let origin = grid.origin(b);
        let extent = grid.extent(b);
        // Bricks j whose voxels [j·step, j·step + step] meet [a, z]; one
        // sharing only voxel z is left out when its neighbour holds z too.
        let span = |a: usize| {
            let (lo, hi) = (origin[a], origin[a] + extent[a] - 1);
            let first = (lo / step).min(counts[a] - 1);
            let last = ((hi.max(lo + 1) - 1) / step).min(counts[a] - 1);
            first..=last
        };
        let mut merged = [u16::MAX, 0];
        for x in span(0) {
            for y in span(1) {
                for z in span(2) {
                    let [l, h] = self.range([x, y, z]);
                    merged = [merged[0].min(l), merged[1].max(h)];
                }
            }
        }
        merged
    }

    /// The grid the ranges belong to.
    pub fn grid(&self) -> &BlockGrid {
        &self.grid
    }

    /// `[min, max]` of brick `b`.
    pub fn range(&self, b: [u32; 3]) -> [u16; 2] {
        self.as_slice()[self.grid.index(b) as usize]
    }

    /// All ranges in file order of the grid.
    pub fn as_slice(&self) -> &[[u16; 2]] {
        match &self.ranges {
            Entries::Owned(v) => v,
            // Alignment and length were checked when the table was mapped.
            Entries::Mapped(map) => bytemuck::cast_slice(&map[..]),
        }
    }

    /// Whether the entries are read through a mapping of the file (no copy in
    /// memory) rather than held in memory.
    pub fn is_mapped(&self) -> bool {
        matches!(self.ranges, Entries::Mapped(_))
    }

    /// Smallest and largest sample of the whole volume.
    pub fn overall(&self) -> [u16; 2] {
        self.as_slice()
            .iter()
            .fold([u16::MAX, 0], |[lo, hi], r| [lo.min(r[0]), hi.max(r[1])])
    }

    /// Bytes of the encoded table ([`Self::encode`]) of the bricks of `grid`.
    pub fn table_len(grid: &BlockGrid) -> u64 {
        TABLE_HEADER_LEN as u64 + 4 * grid.block_count()
    }

    /// Encodes the table (the form embedded after the samples of extended files).
    pub fn encode(&self) -> Vec<u8> {
        let entries = self.as_slice();
        let mut out = Vec::with_capacity(TABLE_HEADER_LEN + entries.len() * 4);
        out.extend_from_slice(&TABLE_MAGIC);
        out.extend_from_slice(&self.grid.side().to_le_bytes());
        for c in self.grid.dims() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&(entries.len() as u64).to_le_bytes());
        for [lo, hi] in entries {
            out.extend_from_slice(&lo.to_le_bytes());
            out.extend_from_slice(&hi.to_le_bytes());
        }
        out
    }

    /// Decodes a table written by [`Self::encode`] for a volume of `dims`; `None` when
    /// the bytes are not a consistent table for those dims.
    pub fn decode(bytes: &[u8], dims: [u32; 3]) -> Option<Self> {
        let grid = table_grid(bytes.get(..TABLE_HEADER_LEN)?, dims)?;
        let count = grid.block_count();
        let body = bytes.get(TABLE_HEADER_LEN..)?;
        if (body.len() as u64) < count.checked_mul(4)? {
            return None;
        }
        let ranges: Vec<[u16; 2]> = body
            .chunks_exact(4)
            .take(count as usize)
            .map(|c| {
                [
                    u16::from_le_bytes([c[0], c[1]]),
                    u16::from_le_bytes([c[2], c[3]]),
                ]
            })
            .collect();
        let table = BrickRanges {
            grid,
            ranges: Entries::Owned(ranges),
        };
        table.consistent().then_some(table)
    }

    /// The table written by [`Self::encode`] at byte `offset` of `file`, at most
    /// `len` bytes long, for a volume of `dims`: its entries mapped read-only where
    /// `access` maps and the file allows it (they stay in the page cache, not in this process's
    /// memory), else read and decoded. `Ok(None)` when the bytes are not a
    /// consistent table for those dims.
    pub fn read_from(
        file: &File,
        offset: u64,
        len: u64,
        dims: [u32; 3],
        access: Access,
    ) -> std::io::Result<Option<Self>> {
        let mut head = [0u8; TABLE_HEADER_LEN];
        if len < TABLE_HEADER_LEN as u64 {
            return Ok(None);
        }
        file.read_exact_at(&mut head, offset)?;
        let Some(grid) = table_grid(&head, dims) else {
            return Ok(None);
        };
        let Some(body) = grid.block_count().checked_mul(4) else {
            return Ok(None);
        };
        if body > len - TABLE_HEADER_LEN as u64 {
            return Ok(None);
        }
        let start = offset + TABLE_HEADER_LEN as u64;
        if body > 0
            && access == Access::Mapped
            && let Ok(map) = super::pyramid::map_region(file, start, body)
            && bytemuck::try_cast_slice::<u8, [u16; 2]>(&map).is_ok()
        {
            // Checked in one pass: the table is asked for whole first (exactly its
            // pages; sequential advice would let read-ahead run on past its end).
            let _ = map.advise(memmap2::Advice::WillNeed);
            let table = BrickRanges {
                grid,
                ranges: Entries::Mapped(Arc::new(map)),
            };
            return Ok(table.consistent().then_some(table));
        }
        let mut bytes = vec![0u8; TABLE_HEADER_LEN + body as usize];
        file.read_exact_at(&mut bytes, offset)?;
        Ok(Self::decode(&bytes, dims))
    }

    /// Whether every entry is a range (`min ≤ max`).
    fn consistent(&self) -> bool {
        self.as_slice().iter().all(|[lo, hi]| lo <= hi)
    }

    /// Encodes a sidecar file for a volume file of `file_len` bytes modified at `mtime`.
    pub fn encode_sidecar(&self, file_len: u64, mtime: SystemTime) -> Vec<u8> {
        let (secs, nanos) = split_time(mtime);
        let mut out = Vec::new();
        out.extend_from_slice(&SIDECAR_MAGIC);
        out.extend_from_slice(&SIDECAR_VERSION.to_le_bytes());
        out.extend_from_slice(&file_len.to_le_bytes());
        out.extend_from_slice(&secs.to_le_bytes());
        out.extend_from_slice(&nanos.to_le_bytes());
        out.extend(self.encode());
        out
    }

    /// Decodes a sidecar; `None` when it is malformed or describes another version
    /// of the file (different length or modification time).
    pub fn decode_sidecar(
        bytes: &[u8],
        dims: [u32; 3],
        file_len: u64,
        mtime: SystemTime,
    ) -> Option<Self> {
        if !sidecar_is_fresh(bytes, file_len, mtime) {
            return None;
        }
        Self::decode(&bytes[SIDECAR_HEADER_LEN..], dims)
    }

    /// The table of the sidecar `sidecar` (of `sidecar_len` bytes), as
    /// [`Self::decode_sidecar`] would decode it, its entries mapped
    /// ([`Self::read_from`]); `Ok(None)` when it is malformed or stale.
    pub fn read_sidecar(
        sidecar: &File,
        sidecar_len: u64,
        dims: [u32; 3],
        file_len: u64,
        mtime: SystemTime,
    ) -> std::io::Result<Option<Self>> {
        let mut head = [0u8; SIDECAR_HEADER_LEN];
        if sidecar_len < SIDECAR_HEADER_LEN as u64 {
            return Ok(None);
        }
        sidecar.read_exact_at(&mut head, 0)?;
        if !sidecar_is_fresh(&head, file_len, mtime) {
            return Ok(None);
        }
        let header = SIDECAR_HEADER_LEN as u64;
        // Read into memory (4 bytes a brick): a sidecar cut while mapped would
        // fault, and no check of the volume's own file sees it.
        Self::read_from(sidecar, header, sidecar_len - header, dims, Access::Ram)
    }
}

/// The grid a table's header (its first [`TABLE_HEADER_LEN`] bytes) declares, if
/// it is a table for a volume of `dims`.
fn table_grid(head: &[u8], dims: [u32; 3]) -> Option<BlockGrid> {
    if head.len() < TABLE_HEADER_LEN || head[..4] != TABLE_MAGIC {
        return None;
    }
    let u32_at = |o: usize| u32::from_le_bytes(head[o..o + 4].try_into().unwrap());
    let side = u32_at(4);
    if side < 2 || [u32_at(8), u32_at(12), u32_at(16)] != dims {
        return None;
    }
    let count = u64::from_le_bytes(head[20..28].try_into().unwrap());
    let grid = BlockGrid::new(dims, side);
    (count == grid.block_count()).then_some(grid)
}

/// Whether a sidecar starting with `head` describes the file of `file_len` bytes
/// modified at `mtime`.
fn sidecar_is_fresh(head: &[u8], file_len: u64, mtime: SystemTime) -> bool {
    let Some(head) = head.get(..SIDECAR_HEADER_LEN) else {
        return false;
    };
    let (secs, nanos) = split_time(mtime);
    head[..4] == SIDECAR_MAGIC
        && head[4..8] == SIDECAR_VERSION.to_le_bytes()
        && head[8..16] == file_len.to_le_bytes()
        && head[16..24] == secs.to_le_bytes()
        && head[24..28] == nanos.to_le_bytes()
}

/// Seconds (negative before the epoch) and nanoseconds of `t`, as sidecars record it.
pub(crate) fn split_time(t: SystemTime) -> (i64, u32) {
    match t.duration_since(SystemTime::UNIX_EPOCH) {
        Ok(d) => (d.as_secs() as i64, d.subsec_nanos()),
        Err(e) => (
            -(e.duration().as_secs() as i64),
            e.duration().subsec_nanos(),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Layout;

    fn ramp_volume(dims: [u32; 3]) -> Vec<u8> {
        let n = dims.iter().product::<u32>();
        (0..n).map(|i| (i % 251) as u8).collect()
    }

    #[test]
    fn coarsened_ranges_equal_a_scan_of_the_coarse_grid() {
        let dims = [37, 50, 23];
        let mut seed = 12345u32;
        let samples: Vec<u16> = (0..dims.iter().product::<u32>())
            .map(|_| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (seed >> 20) as u16
            })
            .collect();
        let volume = TypedVolume::new(&samples, dims, Layout::Linear);
        let fine = BrickRanges::compute(&volume, &BlockGrid::new(dims, 6));
        for factor in [1, 2, 3, 7, 20] {
            let coarse = fine.coarsened(factor);
            let grid = BlockGrid::new(dims, factor * 5 + 1);
            assert_eq!(coarse.grid(), &grid);
            assert_eq!(
                coarse,
                BrickRanges::compute(&volume, &grid),
                "factor {factor}"
            );
        }
    }

    #[test]
    fn covering_ranges_hold_every_voxel_and_are_exact_for_coarser_grids() {
        let dims = [37, 50, 23];
        let samples: Vec<u8> = (0..dims.iter().product::<u32>())
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
            .collect();
        let volume = TypedVolume::new(&samples, dims, Layout::Linear);
        let fine = BrickRanges::compute(&volume, &BlockGrid::new(dims, 6));
        for side in [6, 11, 16, 4, 9, 31] {
            let grid = BlockGrid::new(dims, side);
            let covering = fine.covering(&grid);
            let exact = BrickRanges::compute(&volume, &grid);
            if (side - 1) % 5 == 0 {
                assert_eq!(covering, exact, "side {side}");
            }
            for (c, e) in covering.as_slice().iter().zip(exact.as_slice()) {
                assert!(c[0] <= e[0] && c[1] >= e[1], "side {side}: {c:?} ⊉ {e:?}");
            }
        }
    }

    #[test]
    fn table_round_trips_and_rejects_other_dims() {
        let dims = [10, 7, 5];
        let data = ramp_volume(dims);
        let vol = TypedVolume::new(&data, dims, Layout::Linear);
        let r = BrickRanges::compute(&vol, &BlockGrid::new(dims, 4));
        let bytes = r.encode();
        assert_eq!(BrickRanges::decode(&bytes, dims), Some(r.clone()));
        assert_eq!(BrickRanges::decode(&bytes, [10, 7, 6]), None);
        assert_eq!(BrickRanges::decode(&bytes[..bytes.len() - 1], dims), None);
    }

    #[test]
    fn tables_read_from_a_file_are_mapped_where_aligned_and_equal_the_decoded_ones() {
        let dims = [37, 50, 23];
        let data: Vec<u8> = (0..dims.iter().product::<u32>())
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
            .collect();
        let vol = TypedVolume::new(&data, dims, Layout::Linear);
        let table = BrickRanges::compute(&vol, &BlockGrid::new(dims, 6));
        let bytes = table.encode();
        for (offset, mapped) in [(0u64, true), (4098, true), (4099, false)] {
            let mut file = tempfile::tempfile().unwrap();
            let mut image = vec![0xAAu8; offset as usize];
            image.extend_from_slice(&bytes);
            image.extend_from_slice(&[0x55; 10]);
            std::io::Write::write_all(&mut file, &image).unwrap();
            let len = image.len() as u64 - offset;
            let read = BrickRanges::read_from(&file, offset, len, dims, Access::Mapped)
                .unwrap()
                .unwrap();
            assert_eq!(read, table, "offset {offset}");
            assert_eq!(read.is_mapped(), mapped, "offset {offset}");
            assert_eq!(read.clone().as_slice(), table.as_slice());
            // Cut short, another volume's dims, or an entry with min > max: refused.
            let short =
                BrickRanges::read_from(&file, offset, bytes.len() as u64 - 1, dims, Access::Mapped);
            assert!(short.unwrap().is_none());
            let other = BrickRanges::read_from(&file, offset, len, [37, 50, 24], Access::Mapped);
            assert!(other.unwrap().is_none());
            let mut bad = image.clone();
            let at = offset as usize + TABLE_HEADER_LEN + 4 * 7;
            bad[at..at + 4].copy_from_slice(&[9, 0, 8, 0]);
            std::os::unix::fs::FileExt::write_all_at(&file, &bad, 0).unwrap();
            assert!(
                BrickRanges::read_from(&file, offset, len, dims, Access::Mapped)
                    .unwrap()
                    .is_none()
            );
        }
    }

    #[test]
    fn a_fresh_sidecar_is_read_into_memory_and_a_stale_one_refused() {
        let dims = [10, 7, 5];
        let data = ramp_volume(dims);
        let vol = TypedVolume::new(&data, dims, Layout::Linear);
        let table = BrickRanges::compute(&vol, &BlockGrid::new(dims, 4));
        let t = SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(77);
        let bytes = table.encode_sidecar(350, t);
        let mut file = tempfile::tempfile().unwrap();
        std::io::Write::write_all(&mut file, &bytes).unwrap();
        let len = bytes.len() as u64;
        let read = BrickRanges::read_sidecar(&file, len, dims, 350, t)
            .unwrap()
            .unwrap();
        // (Not mapped: a sidecar cut while mapped would fault, unchecked.)
        assert!(!read.is_mapped());
        assert_eq!(read, table);
        assert!(
            BrickRanges::read_sidecar(&file, len, dims, 351, t)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn ranges_cover_the_overlap_voxels() {
        let dims = [9, 1, 1];
        let mut data = vec![0u8; 9];
        data[4] = 200; // the voxel shared by bricks 0 and 1 (side 5, step 4)
        let vol = TypedVolume::new(&data, dims, Layout::Linear);
        let r = BrickRanges::compute(&vol, &BlockGrid::new(dims, 5));
        assert_eq!(r.as_slice(), &[[0, 200], [0, 200]]);
    }

    #[test]
    fn stale_sidecar_is_rejected() {
        let dims = [4, 4, 4];
        let data = ramp_volume(dims);
        let vol = TypedVolume::new(&data, dims, Layout::Linear);
        let r = BrickRanges::compute(&vol, &BlockGrid::new(dims, 3));
        let t = SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1000);
        let bytes = r.encode_sidecar(90, t);
        assert_eq!(BrickRanges::decode_sidecar(&bytes, dims, 90, t), Some(r));
        assert_eq!(BrickRanges::decode_sidecar(&bytes, dims, 91, t), None);
        let later = t + std::time::Duration::from_nanos(1);
        assert_eq!(BrickRanges::decode_sidecar(&bytes, dims, 90, later), None);
    }
}
