//! Per-brick value ranges (min/max of the samples), the basis of empty-space skipping.
//!
//! Computed in one parallel streaming pass over the bricks and stored, so re-opening a
//! multi-GB file does not rescan it: files with the extended header carry the table
//! after their samples; thesis files get a sidecar `<file>.ranges` that records the
//! length and modification time of the file it describes.

use std::time::SystemTime;

use rayon::prelude::*;

use super::grid::BlockGrid;
use super::sample::Sample;
use super::view::TypedVolume;

/// Side of the logical bricks whose ranges are kept for linear volumes.
pub const LINEAR_RANGE_SIDE: u32 = 16;
const TABLE_MAGIC: [u8; 4] = *b"RCRG";
const SIDECAR_MAGIC: [u8; 4] = *b"RCRS";
const SIDECAR_VERSION: u32 = 1;
const TABLE_HEADER_LEN: usize = 4 + 4 + 12 + 8;
const SIDECAR_HEADER_LEN: usize = 4 + 4 + 8 + 8 + 4;

/// The smallest and largest sample of every brick of a grid.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BrickRanges {
    grid: BlockGrid,
    ranges: Vec<[u16; 2]>,
}

impl BrickRanges {
    /// Scans every brick of `grid` in `volume` (in parallel).
    pub fn compute<T: Sample>(volume: &TypedVolume<'_, T>, grid: &BlockGrid) -> Self {
        let ranges = (0..grid.block_count())
            .into_par_iter()
            .map(|i| {
                let (lo, hi) = volume.brick(grid, grid.coords(i)).value_range();
                [lo.to_u16(), hi.to_u16()]
            })
            .collect();
        BrickRanges {
            grid: *grid,
            ranges,
        }
    }

    /// Builds from ranges already known, in file order of `grid`.
    ///
    /// # Panics
    /// If the count does not match the grid.
    pub fn from_parts(grid: BlockGrid, ranges: Vec<[u16; 2]>) -> Self {
        assert_eq!(ranges.len() as u64, grid.block_count());
        BrickRanges { grid, ranges }
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
        BrickRanges { grid, ranges }
    }

    /// Ranges for another grid over the same volume, merged from these without
    /// reading a sample: each brick of `grid` gets the union of the ranges of the
    /// bricks here that hold any of its voxels. Exact when `grid`'s bricks are
    /// unions of these (the same grid, or [`Self::coarsened`]'s); otherwise a
    /// superset of the true range, which empty-space skipping may use safely.
    pub fn covering(&self, grid: &BlockGrid) -> BrickRanges {
        let step = self.grid.step();
        let counts = self.grid.counts();
        let ranges = grid
            .iter()
            .map(|b| {
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
            })
            .collect();
        BrickRanges {
            grid: *grid,
            ranges,
        }
    }

    /// The grid the ranges belong to.
    pub fn grid(&self) -> &BlockGrid {
        &self.grid
    }

    /// `[min, max]` of brick `b`.
    pub fn range(&self, b: [u32; 3]) -> [u16; 2] {
        self.ranges[self.grid.index(b) as usize]
    }

    /// All ranges in file order of the grid.
    pub fn as_slice(&self) -> &[[u16; 2]] {
        &self.ranges
    }

    /// Smallest and largest sample of the whole volume.
    pub fn overall(&self) -> [u16; 2] {
        self.ranges
            .iter()
            .fold([u16::MAX, 0], |[lo, hi], r| [lo.min(r[0]), hi.max(r[1])])
    }

    /// Encodes the table (the form embedded after the samples of extended files).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(TABLE_HEADER_LEN + self.ranges.len() * 4);
        out.extend_from_slice(&TABLE_MAGIC);
        out.extend_from_slice(&self.grid.side().to_le_bytes());
        for c in self.grid.dims() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&(self.ranges.len() as u64).to_le_bytes());
        for [lo, hi] in &self.ranges {
            out.extend_from_slice(&lo.to_le_bytes());
            out.extend_from_slice(&hi.to_le_bytes());
        }
        out
    }

    /// Decodes a table written by [`Self::encode`] for a volume of `dims`; `None` when
    /// the bytes are not a consistent table for those dims.
    pub fn decode(bytes: &[u8], dims: [u32; 3]) -> Option<Self> {
        let head = bytes.get(..TABLE_HEADER_LEN)?;
        if head[..4] != TABLE_MAGIC {
            return None;
        }
        let u32_at = |o: usize| u32::from_le_bytes(head[o..o + 4].try_into().unwrap());
        let side = u32_at(4);
        if side < 2 || [u32_at(8), u32_at(12), u32_at(16)] != dims {
            return None;
        }
        let count = u64::from_le_bytes(head[20..28].try_into().unwrap());
        let grid = BlockGrid::new(dims, side);
        if count != grid.block_count() {
            return None;
        }
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
        if ranges.iter().any(|[lo, hi]| lo > hi) {
            return None;
        }
        Some(BrickRanges { grid, ranges })
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
        let head = bytes.get(..SIDECAR_HEADER_LEN)?;
        let (secs, nanos) = split_time(mtime);
        let fresh = head[..4] == SIDECAR_MAGIC
            && head[4..8] == SIDECAR_VERSION.to_le_bytes()
            && head[8..16] == file_len.to_le_bytes()
            && head[16..24] == secs.to_le_bytes()
            && head[24..28] == nanos.to_le_bytes();
        if !fresh {
            return None;
        }
        Self::decode(&bytes[SIDECAR_HEADER_LEN..], dims)
    }
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
