//! The resolution pyramid: levels 1, 2, … of a volume, each half the previous on
//! every axis (a 2×2×2 box filter, or the most frequent id for label volumes), stored in the
//! same layout as level 0 with their own brick value ranges.
//!
//! One block format serves both places a pyramid can live (docs/format.md): embedded
//! after the range table of an extended file (header version 2), or in a sidecar
//! `FILE.vol.pyramid` beside any file. The block starts with a directory of the
//! levels; every offset in it is relative to the block's start, and a directory is
//! only accepted when it is exactly the one this build would write for the file's
//! header (so a lying directory is refused, never followed). Block version 2 also
//! holds the cell-range tables of level 0 and of every level (`CellTable`).

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::SystemTime;

use rayon::prelude::*;

use super::cells::{CellShape, CellTable};
use super::error::{AtPath, VolumeError, VolumeErrorKind};
use super::header::{Content, Format, Header, HeaderError};
use super::ranges::{BrickRanges, LINEAR_RANGE_SIDE};
use super::sample::Sample;
use super::storage::Access;
use super::view::TypedVolume;

/// Levels are added until the largest axis is at most this many voxels.
pub const COARSEST_EDGE: u32 = 64;

const BLOCK_MAGIC: [u8; 4] = *b"RCPY";
/// Block version 1: the levels; version 2: the levels and the cell-range tables of
/// level 0 and of every level.
const BLOCK_VERSION_LEVELS: u32 = 1;
const BLOCK_VERSION_CELLS: u32 = 2;
const DIRECTORY_HEAD_LEN: u64 = 16;
/// The directory head of block version 2: version 1's and where level 0's cell
/// table lies.
const DIRECTORY_HEAD_LEN_CELLS: u64 = 64;
const ENTRY_LEN: u64 = 64;
const SIDECAR_MAGIC: [u8; 4] = *b"RCPS";
const SIDECAR_VERSION: u32 = 1;
/// Bytes before the block in a sidecar.
pub const SIDECAR_HEAD_LEN: u64 = 64;

/// The sidecar that holds the pyramid of `path` (any format): `FILE.pyramid`.
pub fn pyramid_sidecar_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".pyramid");
    PathBuf::from(name)
}

/// The dimensions of levels 1, 2, … of a volume of `dims`: each half the previous
/// (rounded up) until the largest axis is at most [`COARSEST_EDGE`].
pub fn level_dims(dims: [u32; 3]) -> Vec<[u32; 3]> {
    let mut out = Vec::new();
    let mut d = dims;
    while d.iter().any(|&v| v > COARSEST_EDGE) {
        d = d.map(|v| v.div_ceil(2));
        out.push(d);
    }
    out
}

/// Voxels of all pyramid levels of a volume of `dims` together (about a seventh of
/// level 0's): the extra work of writing a pyramid, for progress bars.
pub fn pyramid_voxels(dims: [u32; 3]) -> u64 {
    level_dims(dims)
        .iter()
        .map(|d| d.iter().map(|&v| u64::from(v)).product::<u64>())
        .sum()
}

fn align64(v: u64) -> u64 {
    v.div_ceil(64) * 64
}

/// Where one level lives inside a pyramid block.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelEntry {
    /// Voxel counts.
    pub dims: [u32; 3],
    /// Voxel spacing (`2^k` times level 0's).
    pub spacing: [f32; 3],
    /// Offset of the samples from the block's start (64-aligned).
    pub data_offset: u64,
    /// Bytes of samples.
    pub data_len: u64,
    /// Offset of the level's brick value-range table from the block's start.
    pub ranges_offset: u64,
    /// Bytes of that table.
    pub ranges_len: u64,
    /// Where the level's cell-range table lies (offset from the block's start,
    /// 64-aligned, and length), in a block that stores them.
    pub cells: Option<(u64, u64)>,
}

/// The directory of a pyramid block: levels 1, 2, … in order.
#[derive(Clone, Debug, PartialEq)]
pub struct PyramidLayout {
    /// One entry per level beyond 0.
    pub levels: Vec<LevelEntry>,
    /// Where level 0's cell-range table lies (offset from the block's start and
    /// length), in a block that stores cell tables.
    pub level0_cells: Option<(u64, u64)>,
}

impl PyramidLayout {
    /// The layout this build writes for a volume with header `base`: with the
    /// cell-range tables of every level (block version 2) when `cells`.
    pub fn plan(base: &Header, cells: bool) -> Result<Self, HeaderError> {
        let dims = level_dims(base.dims);
        let head = if cells {
            DIRECTORY_HEAD_LEN_CELLS
        } else {
            DIRECTORY_HEAD_LEN
        };
        let mut offset = align64(head + ENTRY_LEN * dims.len() as u64);
        let cell_table = |header: &Header, offset: &mut u64| -> Result<_, HeaderError> {
            if !cells {
                return Ok(None);
            }
            let len = CellShape::default_for(header)
                .table_len(header.sample_type)
                .ok_or(HeaderError::SizeOverflow)?;
            let at = *offset;
            *offset = align64(at.checked_add(len).ok_or(HeaderError::SizeOverflow)?);
            Ok(Some((at, len)))
        };
        let level0_cells = cell_table(base, &mut offset)?;
        let mut levels = Vec::with_capacity(dims.len());
        for (k, d) in dims.into_iter().enumerate() {
            let scale = (1u64 << (k + 1)) as f32;
            let spacing = base.spacing.map(|s| s * scale);
            let header = level_header(base, d, spacing);
            let data_len = header.data_len()?;
            let ranges_len = BrickRanges::table_len(&header.block_grid(LINEAR_RANGE_SIDE));
            let ranges_offset = offset
                .checked_add(data_len)
                .ok_or(HeaderError::SizeOverflow)?;
            let data_offset = offset;
            offset = align64(ranges_offset + ranges_len);
            levels.push(LevelEntry {
                dims: d,
                spacing,
                data_offset,
                data_len,
                ranges_offset,
                ranges_len,
                cells: cell_table(&header, &mut offset)?,
            });
        }
        let block_len = offset;
        let layout = PyramidLayout {
            levels,
            level0_cells,
        };
        debug_assert_eq!(layout.block_len(), block_len);
        Ok(layout)
    }

    /// Whether the block stores cell-range tables (block version 2).
    pub fn has_cells(&self) -> bool {
        self.level0_cells.is_some()
    }

    /// The shape of the cells of level `k` (0: the volume itself) stored in this
    /// block.
    pub fn cell_shape(&self, base: &Header, k: usize) -> CellShape {
        match k {
            0 => CellShape::default_for(base),
            k => CellShape::default_for(&self.level_header(base, k)),
        }
    }

    /// Bytes of the whole block.
    pub fn block_len(&self) -> u64 {
        let directory = if self.has_cells() {
            DIRECTORY_HEAD_LEN_CELLS
        } else {
            DIRECTORY_HEAD_LEN
        };
        let ends = self.levels.iter().map(|l| {
            let end = l
                .cells
                .map_or(l.ranges_offset + l.ranges_len, |(o, n)| o + n);
            align64(end)
        });
        let level0 = self.level0_cells.map_or(0, |(o, n)| align64(o + n));
        ends.chain([level0, align64(directory)]).max().unwrap_or(0)
    }

    /// The header describing level `k` (1-based) on its own: extended format, samples
    /// at offset 0 of the level's bytes.
    pub fn level_header(&self, base: &Header, k: usize) -> Header {
        let e = &self.levels[k - 1];
        level_header(base, e.dims, e.spacing)
    }

    /// The directory's bytes (the start of the block).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(&BLOCK_MAGIC);
        let version = if self.has_cells() {
            BLOCK_VERSION_CELLS
        } else {
            BLOCK_VERSION_LEVELS
        };
        out.extend_from_slice(&version.to_le_bytes());
        out.extend_from_slice(&(self.levels.len() as u32).to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        if let Some((offset, len)) = self.level0_cells {
            out.extend_from_slice(&offset.to_le_bytes());
            out.extend_from_slice(&len.to_le_bytes());
            out.resize(DIRECTORY_HEAD_LEN_CELLS as usize, 0);
        }
        for e in &self.levels {
            for d in e.dims {
                out.extend_from_slice(&d.to_le_bytes());
            }
            for s in e.spacing {
                out.extend_from_slice(&s.to_le_bytes());
            }
            for v in [e.data_offset, e.data_len, e.ranges_offset, e.ranges_len] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            // Version 2: where the level's cell table starts (its length is
            // the shape's).
            out.extend_from_slice(&e.cells.map_or(0, |(o, _)| o).to_le_bytes());
        }
        out.resize(align64(out.len() as u64) as usize, 0);
        out
    }

    /// Reads the directory at `block_start` of `file` for a volume with header
    /// `base`, checking it is exactly the one [`Self::plan`] gives for its block
    /// version (`cells`: whether it must store cell tables; `None`: either) and
    /// that the block fits in `file_len` bytes.
    pub fn read(
        file: &File,
        block_start: u64,
        file_len: u64,
        base: &Header,
        cells: Option<bool>,
    ) -> Result<Self, VolumeErrorKind> {
        let corrupt = |why: &str| VolumeErrorKind::CorruptPyramid(why.to_string());
        let cut_off = |part, end| VolumeErrorKind::PyramidCutOff {
            part,
            end,
            file_len,
        };
        let mut head = [0u8; 8];
        if block_start.saturating_add(8) > file_len {
            return Err(cut_off("its directory", block_start.saturating_add(8)));
        }
        file.read_exact_at(&mut head, block_start)?;
        if head[..4] != BLOCK_MAGIC {
            return Err(corrupt("bad magic"));
        }
        let has_cells = match u32::from_le_bytes(head[4..8].try_into().unwrap()) {
            BLOCK_VERSION_LEVELS => false,
            BLOCK_VERSION_CELLS => true,
            _ => return Err(corrupt("unsupported pyramid version")),
        };
        if cells.is_some_and(|c| c != has_cells) {
            return Err(corrupt(if has_cells {
                "it stores cell tables, which the header's version does not have"
            } else {
                "it lacks the cell tables the header's version says it has"
            }));
        }
        let plan = PyramidLayout::plan(base, has_cells)?;
        let expected = plan.encode();
        let mut bytes = vec![0u8; expected.len()];
        let directory_end = block_start.saturating_add(expected.len() as u64);
        if directory_end > file_len {
            return Err(cut_off("its directory", directory_end));
        }
        file.read_exact_at(&mut bytes, block_start)?;
        if bytes != expected {
            return Err(corrupt(
                "its directory does not match the volume's dimensions",
            ));
        }
        let block_end = block_start.saturating_add(plan.block_len());
        if block_end > file_len {
            return Err(cut_off("its levels", block_end));
        }
        Ok(plan)
    }

    /// Reads and checks the value-range table of level `k` (1-based); its entries
    /// stay in the file, mapped where `access` maps ([`BrickRanges::read_from`]).
    pub fn read_ranges(
        &self,
        file: &File,
        block_start: u64,
        base: &Header,
        k: usize,
        access: Access,
    ) -> Result<BrickRanges, VolumeErrorKind> {
        let e = &self.levels[k - 1];
        let header = self.level_header(base, k);
        BrickRanges::read_from(
            file,
            block_start + e.ranges_offset,
            e.ranges_len,
            e.dims,
            access,
        )?
        .filter(|r| r.grid() == &header.block_grid(LINEAR_RANGE_SIDE))
        .ok_or_else(|| VolumeErrorKind::CorruptPyramid(format!("level {k}'s range table")))
    }

    /// Reads and checks the cell-range table of level `k` (0: the volume itself),
    /// if the block stores cell tables; its entries stay in the file, mapped
    /// where `access` maps.
    pub fn read_cells(
        &self,
        file: &File,
        block_start: u64,
        base: &Header,
        k: usize,
        access: Access,
    ) -> Result<Option<CellTable>, VolumeErrorKind> {
        let place = match k {
            0 => self.level0_cells,
            k => self.levels[k - 1].cells,
        };
        let Some((offset, len)) = place else {
            return Ok(None);
        };
        let shape = self.cell_shape(base, k);
        CellTable::read_from(
            file,
            block_start + offset,
            len,
            &shape,
            base.sample_type,
            access,
        )?
        .map(Some)
        .ok_or_else(|| {
            VolumeErrorKind::CorruptPyramid(format!(
                "level {k}'s cell table does not match its bricks"
            ))
        })
    }
}

fn level_header(base: &Header, dims: [u32; 3], spacing: [f32; 3]) -> Header {
    let mut h = Header::new(
        dims,
        spacing,
        base.layout,
        base.sample_type,
        base.content,
        Format::Extended,
    );
    // A level's samples are means of level 0's: they mean the same.
    h.units = base.units.clone();
    h.data_offset = 0;
    h
}

/// The sample of level `k + 1` at `(x, y, z)` from level `k` rows: the rounded mean
/// of the 2×2×2 block at `2·(x, y, z)` (indices clamped to the level), or for
/// labels its most frequent id, the largest of ids as frequent (the maximum
/// pushed a boundary's larger id into its neighbour, where the averaged
/// values are the neighbour's: coarse two-level frames speckled). `rows` are the four z-runs at `(2x, 2y)`, `(2x+1, 2y)`,
/// `(2x, 2y+1)`, `(2x+1, 2y+1)` (clamped).
#[inline]
fn reduce<T: Sample>(rows: [&[T]; 4], z: usize, labels: bool) -> T {
    let last = rows[0].len() - 1;
    let (z0, z1) = (2 * z, (2 * z + 1).min(last));
    if labels {
        let ids: [T; 8] = std::array::from_fn(|i| rows[i / 2][if i % 2 == 0 { z0 } else { z1 }]);
        // Inside an object (most blocks): one id.
        if ids.iter().all(|&v| v == ids[0]) {
            return ids[0];
        }
        let count = |id: T| ids.iter().filter(|&&v| v == id).count();
        let mut best = ids[0];
        for &id in &ids[1..] {
            let (c, b) = (count(id), count(best));
            if c > b || (c == b && id > best) {
                best = id;
            }
        }
        return best;
    }
    let sum: u32 = rows
        .iter()
        .map(|r| u32::from(r[z0].to_u16()) + u32::from(r[z1].to_u16()))
        .sum();
    T::from_u16_saturating(((sum + 4) / 8) as u16)
}

/// Plane `x` of the level below from planes `2x` and `2x + 1` (or `2x` twice at an
/// odd end) of a level whose planes are `src_yz` (y, z) voxels: into `out`, a plane
/// of `ceil(src_yz / 2)` voxels.
fn reduce_plane_pair<T: Sample>(p0: &[T], p1: &[T], src_yz: [u32; 2], labels: bool, out: &mut [T]) {
    let (sy, sz) = (src_yz[0] as usize, src_yz[1] as usize);
    let dz = sz.div_ceil(2);
    out.par_chunks_mut(dz).enumerate().for_each(|(y, dst)| {
        let (y0, y1) = (2 * y, (2 * y + 1).min(sy - 1));
        let rows = [
            &p0[y0 * sz..][..sz],
            &p1[y0 * sz..][..sz],
            &p0[y1 * sz..][..sz],
            &p1[y1 * sz..][..sz],
        ];
        for (z, d) in dst.iter_mut().enumerate() {
            *d = reduce(rows, z, labels);
        }
    });
}

/// Fills planes `x0..x1` of the level below `src` (x slowest, z fastest).
pub(crate) fn downsample_planes<T: Sample>(
    src: &TypedVolume<'_, T>,
    dims: [u32; 3],
    labels: bool,
    x0: u32,
    x1: u32,
    slab: &mut [T],
) {
    let s = src.dims();
    let plane = dims[1] as usize * dims[2] as usize;
    let src_plane = s[1] as usize * s[2] as usize;
    slab[..(x1 - x0) as usize * plane]
        .par_chunks_mut(plane)
        .enumerate()
        .for_each(|(i, out)| {
            let x = x0 + i as u32;
            let mut planes = vec![T::from_u16_saturating(0); 2 * src_plane];
            let (p0, p1) = planes.split_at_mut(src_plane);
            for (p, sx) in [(p0, 2 * x), (p1, (2 * x + 1).min(s[0] - 1))] {
                for (y, row) in p.chunks_mut(s[2] as usize).enumerate() {
                    src.row_into(sx, y as u32, row);
                }
            }
            let (p0, p1) = planes.split_at(src_plane);
            reduce_plane_pair(p0, p1, [s[1], s[2]], labels, out);
        });
}

/// Turns the planes of level 0, as a writer produces them, into the planes of
/// level 1, sent in order to the level-1 writer ([`PlaneFeed`]): the pyramid's
/// first level is built in the same pass as level 0, without reading it back.
pub(crate) struct PlaneTap<T: Sample> {
    to_level1: Option<mpsc::SyncSender<Vec<T>>>,
    dims: [u32; 3],
    labels: bool,
    /// The next level-0 plane not seen yet (slabs share their first plane).
    next: u32,
    /// An even plane waiting for its odd partner.
    pending: Option<Vec<T>>,
}

impl<T: Sample> PlaneTap<T> {
    /// A tap for a level 0 of `dims` sending to `to_level1`.
    pub(crate) fn new(to_level1: mpsc::SyncSender<Vec<T>>, dims: [u32; 3], labels: bool) -> Self {
        PlaneTap {
            to_level1: Some(to_level1),
            dims,
            labels,
            next: 0,
            pending: None,
        }
    }

    /// Takes level-0 planes `x0..x1` (`slab`, x slowest).
    pub(crate) fn push(&mut self, x0: u32, x1: u32, slab: &[T]) {
        let plane = (self.dims[1] * self.dims[2]) as usize;
        for x in self.next.max(x0)..x1 {
            let p = &slab[(x - x0) as usize * plane..][..plane];
            match self.pending.take() {
                None => self.pending = Some(p.to_vec()),
                Some(even) => self.emit(&even, p),
            }
            self.next = x + 1;
        }
        if self.next == self.dims[0]
            && let Some(even) = self.pending.take()
        {
            self.emit(&even, &even);
        }
    }

    fn emit(&mut self, p0: &[T], p1: &[T]) {
        let out_len = (self.dims[1].div_ceil(2) * self.dims[2].div_ceil(2)) as usize;
        let mut out = vec![T::from_u16_saturating(0); out_len];
        reduce_plane_pair(p0, p1, [self.dims[1], self.dims[2]], self.labels, &mut out);
        // A level-1 writer that stopped (its error is reported when it is joined)
        // takes no more planes; level 0 goes on.
        if let Some(tx) = &self.to_level1
            && tx.send(out).is_err()
        {
            self.to_level1 = None;
        }
    }
}

/// The level-1 side of a [`PlaneTap`]: fills the level-1 writer's slabs from the
/// planes it receives (re-serving the plane consecutive slabs share).
pub(crate) struct PlaneFeed<T: Sample> {
    from_level0: mpsc::Receiver<Vec<T>>,
    last: Option<(u32, Vec<T>)>,
}

impl<T: Sample> PlaneFeed<T> {
    /// A feed of the planes `from_level0` receives.
    pub(crate) fn new(from_level0: mpsc::Receiver<Vec<T>>) -> Self {
        PlaneFeed {
            from_level0,
            last: None,
        }
    }

    /// Fills `slab` with planes `x0..x1`; an error when level 0 stopped first.
    pub(crate) fn fill(
        &mut self,
        x0: u32,
        x1: u32,
        slab: &mut [T],
        path: &Path,
    ) -> Result<(), VolumeError> {
        let plane = slab.len() / (x1 - x0) as usize;
        for x in x0..x1 {
            let fresh = !matches!(&self.last, Some((lx, _)) if *lx == x);
            if fresh {
                let p = self
                    .from_level0
                    .recv()
                    .map_err(|_| VolumeError::new(path, VolumeErrorKind::Cancelled))?;
                self.last = Some((x, p));
            }
            let (_, p) = self.last.as_ref().expect("just set");
            slab[(x - x0) as usize * plane..][..plane].copy_from_slice(p);
        }
        Ok(())
    }
}

/// Maps `len` bytes of `file` at `offset` read-only.
#[allow(unsafe_code)] // memmap2: mapping a file is unsafe by contract
pub(crate) fn map_region(file: &File, offset: u64, len: u64) -> std::io::Result<memmap2::Mmap> {
    let len = usize::try_from(len).map_err(|_| std::io::Error::other("region too large"))?;
    // SAFETY: read-only map of a region of a file this process wrote or opened
    // read-only; the same contract as `Storage::open` (a file truncated under us is
    // outside what we can defend against and would raise SIGBUS, not unsoundness in
    // any Rust invariant beyond the bytes' values).
    unsafe {
        memmap2::MmapOptions::new()
            .offset(offset)
            .len(len)
            .map(file)
    }
}

/// Writes the pyramid of the volume whose header is `base` and whose level-0 samples
/// are `level0`, as a block at `block_start` of `file` (opened for writing). Each
/// level is computed from the previous one, read back through a mapping of what was
/// just written, slab by slab (bounded memory).
pub(crate) fn write_block<T: Sample>(
    file: &File,
    block_start: u64,
    base: &Header,
    level0: TypedVolume<'_, T>,
    options: &crate::io::WriteOptions,
    job: &crate::job::Job,
    path: &Path,
) -> Result<PyramidLayout, VolumeError> {
    let layout = PyramidLayout::plan(base, true).at(path)?;
    file.write_all_at(&layout.encode(), block_start).at(path)?;
    // Level 0's cells are computed in the pass that reads it for level 1.
    let level0_cells = layout.level0_cells.map(|(offset, _)| ColumnCells {
        shape: layout.cell_shape(base, 0),
        offset: block_start + offset,
        next: 0,
    });
    write_levels(
        file,
        block_start,
        base,
        &layout,
        1,
        level0,
        level0_cells,
        options,
        job,
        path,
    )?;
    Ok(layout)
}

/// The cell table of a level being read plane by plane (for the next level):
/// each column of bricks (one x index) is scanned and written once the planes it
/// spans have been read, while they are in the page cache.
pub(crate) struct ColumnCells {
    shape: CellShape,
    /// Byte offset of the table in the output.
    offset: u64,
    /// The first column not written yet.
    next: u32,
}

impl ColumnCells {
    /// Writes the head and the columns lying wholly in planes `..read_to` of
    /// `src` (every remaining column when `last`).
    fn catch_up<T: Sample>(
        &mut self,
        file: &File,
        src: &TypedVolume<'_, T>,
        read_to: u32,
        last: bool,
    ) -> std::io::Result<()> {
        let grid = *self.shape.grid();
        let nx = grid.counts()[0];
        if self.next == 0 {
            file.write_all_at(&self.shape.encode_head(T::TYPE), self.offset)?;
        }
        let mut end = self.next;
        while end < nx
            && (last || grid.origin([end, 0, 0])[0] + grid.extent([end, 0, 0])[0] <= read_to)
        {
            end += 1;
        }
        if end > self.next {
            self.shape
                .write_columns(file, self.offset, self.next..end, |b| src.brick(&grid, b))?;
            self.next = end;
        }
        Ok(())
    }
}

/// Writes levels `from..` of `layout` into the block at `block_start`, level
/// `from − 1` being `src` (whose cell table `src_cells`, when given, is written
/// in the same pass); then pads the block to its end.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_levels<T: Sample>(
    file: &File,
    block_start: u64,
    base: &Header,
    layout: &PyramidLayout,
    from: usize,
    src: TypedVolume<'_, T>,
    mut src_cells: Option<ColumnCells>,
    options: &crate::io::WriteOptions,
    job: &crate::job::Job,
    path: &Path,
) -> Result<(), VolumeError> {
    let labels = base.content == Content::Labels;
    let mut previous: Option<memmap2::Mmap> = None;
    for k in from..=layout.levels.len() {
        let e = &layout.levels[k - 1];
        let header = layout.level_header(base, k);
        let ranges = {
            let src = match &previous {
                None => src,
                Some(map) => {
                    let prev = layout.level_header(base, k - 1);
                    let samples: &[T] = bytemuck::try_cast_slice(&map[..])
                        .map_err(|_| VolumeError::new(path, VolumeErrorKind::Misaligned))?;
                    TypedVolume::new(samples, prev.dims, prev.layout)
                }
            };
            crate::io::stream_samples(
                file,
                block_start + e.data_offset,
                &header,
                options,
                job,
                path,
                e.cells
                    .map(|(offset, _)| crate::io::CellSink {
                        shape: CellShape::default_for(&header),
                        file,
                        offset: block_start + offset,
                    })
                    .as_ref(),
                &mut |x0, x1, slab: &mut [T]| {
                    downsample_planes(&src, e.dims, labels, x0, x1, slab);
                    if let Some(cells) = src_cells.as_mut().filter(|_| k == from) {
                        // Planes up to 2·x1 − 1 of the level below were read.
                        let read_to = (2 * x1).min(src.dims()[0]);
                        cells
                            .catch_up(file, &src, read_to, x1 == e.dims[0])
                            .at(path)?;
                    }
                    Ok(())
                },
            )?
        };
        file.write_all_at(&ranges.encode(), block_start + e.ranges_offset)
            .at(path)?;
        file.sync_data().at(path)?;
        previous = Some(map_region(file, block_start + e.data_offset, e.data_len).at(path)?);
    }
    // The block ends 64-aligned: pad the file to its length.
    let end = block_start + layout.block_len();
    if file.metadata().at(path)?.len() < end {
        file.set_len(end).at(path)?;
    }
    Ok(())
}

/// The head of a pyramid sidecar for a volume file of `file_len` bytes modified at
/// `mtime`.
pub(crate) fn sidecar_head(file_len: u64, mtime: SystemTime) -> Vec<u8> {
    let (secs, nanos) = super::ranges::split_time(mtime);
    let mut out = Vec::with_capacity(SIDECAR_HEAD_LEN as usize);
    out.extend_from_slice(&SIDECAR_MAGIC);
    out.extend_from_slice(&SIDECAR_VERSION.to_le_bytes());
    out.extend_from_slice(&file_len.to_le_bytes());
    out.extend_from_slice(&secs.to_le_bytes());
    out.extend_from_slice(&nanos.to_le_bytes());
    out.resize(SIDECAR_HEAD_LEN as usize, 0);
    out
}

/// Whether a sidecar head describes this version of the volume file.
pub(crate) fn sidecar_is_fresh(head: &[u8], file_len: u64, mtime: SystemTime) -> bool {
    head.len() >= SIDECAR_HEAD_LEN as usize
        && head[..SIDECAR_HEAD_LEN as usize] == sidecar_head(file_len, mtime)[..]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Layout, SampleType};

    #[test]
    fn levels_halve_until_the_coarsest_edge() {
        assert_eq!(level_dims([64, 10, 3]), Vec::<[u32; 3]>::new());
        assert_eq!(
            level_dims([300, 65, 7]),
            vec![[150, 33, 4], [75, 17, 2], [38, 9, 1]]
        );
        assert_eq!(level_dims([3072; 3]).len(), 6);
    }

    #[test]
    fn a_directory_round_trips_and_offsets_are_aligned() {
        let base = Header::new(
            [300, 200, 129],
            [1.0, 1.0, 2.0],
            Layout::Bricked { side: 32 },
            SampleType::U16,
            Content::Scalar,
            Format::Extended,
        );
        let plan = PyramidLayout::plan(&base, false).unwrap();
        assert_eq!(plan.levels.len(), 3);
        for e in &plan.levels {
            assert_eq!(e.data_offset % 64, 0);
            assert!(e.ranges_offset >= e.data_offset + e.data_len);
        }
        assert_eq!(plan.levels[0].spacing, [2.0, 2.0, 4.0]);
        assert_eq!(plan.encode().len() % 64, 0);
    }

    /// Files written before cell tables existed (a version-2 header over a
    /// version-1 block) open with their levels and compute their cells lazily.
    #[test]
    fn a_pyramid_without_cell_tables_still_opens() {
        use crate::io::{WriteOptions, write_volume};
        use crate::volume::Volume;
        let dims = [130, 40, 20];
        let base = Header::new(
            dims,
            [1.0; 3],
            Layout::Bricked { side: 16 },
            SampleType::U8,
            Content::Scalar,
            Format::Extended,
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.vol");
        let options = WriteOptions {
            pyramid: false,
            ..WriteOptions::default()
        };
        let job = crate::job::Job::silent();
        write_volume::<u8>(&path, &base, &options, &job, |x0, _, slab| {
            for (i, v) in slab.iter_mut().enumerate() {
                *v = ((x0 as usize * 800 + i) % 251) as u8;
            }
            Ok(())
        })
        .unwrap();
        let volume = Volume::open(&path).unwrap();
        let crate::volume::VolumeData::U8(level0) = volume.data() else {
            unreachable!()
        };
        let file = std::fs::OpenOptions::new()
            .write(true)
            .read(true)
            .open(&path)
            .unwrap();
        let block_start = align64(file.metadata().unwrap().len());
        let layout = PyramidLayout::plan(volume.header(), false).unwrap();
        assert!(!layout.has_cells());
        file.write_all_at(&layout.encode(), block_start).unwrap();
        write_levels(
            &file,
            block_start,
            volume.header(),
            &layout,
            1,
            level0,
            None,
            &options,
            &job,
            &path,
        )
        .unwrap();
        let mut header = volume.header().clone();
        header.pyramid_offset = Some(block_start);
        let head = header.encode().unwrap();
        assert_eq!(&head[30..32], &2u16.to_le_bytes(), "written as version 2");
        file.write_all_at(&head, 0).unwrap();
        drop(file);
        drop(volume);
        let volume = Volume::open(&path).unwrap();
        assert_eq!(volume.level_count(), 3);
        assert!(!volume.header().pyramid_cells);
        for k in 0..3 {
            assert!(volume.level(k).stored_cells().is_none(), "level {k}");
        }
    }
}
