//! An opened `.vol` file: header, samples (mapped or in RAM) and per-brick ranges.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use super::cells::CellTable;
use super::error::{AtPath, VolumeError, VolumeErrorKind};
use super::header::{Content, Format, Header, HeaderError, Layout, MAX_HEADER_LEN, SampleType};
use super::orientation::Orientation;
use super::pyramid::{
    PyramidLayout, SIDECAR_HEAD_LEN, level_dims, pyramid_sidecar_path, sidecar_head,
    sidecar_is_fresh, write_block,
};
use super::ranges::{BrickRanges, LINEAR_RANGE_SIDE, brick_range};
use super::sample::Sample;
use super::storage::{Access, Storage};
use super::units::ValueUnits;
use super::view::TypedVolume;

/// How to open a volume.
#[derive(Clone, Copy, Debug)]
pub struct OpenOptions {
    /// Map the file or read it into RAM.
    pub access: Access,
    /// For thesis-format files, write the computed brick ranges to a sidecar
    /// `<file>.ranges` so the next open does not rescan (best effort).
    pub write_ranges_sidecar: bool,
}

impl Default for OpenOptions {
    fn default() -> Self {
        OpenOptions {
            access: Access::Mapped,
            write_ranges_sidecar: true,
        }
    }
}

/// The samples of a volume, typed.
#[derive(Clone, Copy, Debug)]
pub enum VolumeData<'a> {
    /// 8-bit samples.
    U8(TypedVolume<'a, u8>),
    /// 16-bit samples.
    U16(TypedVolume<'a, u16>),
}

/// An opened volume file. Whether it is mapped or in RAM is invisible to users of
/// [`Volume::data`].
#[derive(Debug)]
pub struct Volume {
    path: PathBuf,
    header: Header,
    storage: Storage,
    ranges: BrickRanges,
    /// The stored cell ranges of the default brick grid, if the file has them.
    cells: Option<CellTable>,
    /// Levels 1, 2, … of the resolution pyramid, if the file has one.
    levels: Vec<Volume>,
    /// Which pyramid level this is (0: the full-resolution volume).
    level: u32,
    /// The full-resolution volume's voxels per axis (this volume's own for
    /// level 0): the box every level samples ([`Volume::sampled_box`]).
    full_dims: [u32; 3],
    /// Bytes after the file's last block (samples, range table, pyramid) that
    /// no part of the format accounts for: where they start and how many.
    unused_tail: Option<(u64, u64)>,
    /// Why the `FILE.pyramid` sidecar, fresh for this file, was ignored (it is
    /// damaged): the volume opens without a pyramid.
    ignored_pyramid: Option<String>,
}

/// Where full-resolution voxel coordinate `p` lies among the voxels of a
/// pyramid level whose voxels span `scale` (`2^k`) full-resolution ones: level
/// voxel 0 is centred on the first `scale` of them, at `(scale − 1)/2`.
pub fn level_coordinate(p: f32, scale: f32) -> f32 {
    (p - (scale - 1.0) / 2.0) / scale
}

/// The inverse of [`level_coordinate`]: level voxel coordinate `q` in
/// full-resolution voxels.
pub fn full_resolution_coordinate(q: f32, scale: f32) -> f32 {
    q * scale + (scale - 1.0) / 2.0
}

/// Reads and validates the header of the volume file `path` (without mapping it).
pub fn read_header(path: &Path) -> Result<(Header, File, u64), VolumeError> {
    read_header_as(path, None)
}

/// [`read_header`] of a file whose samples are whole though it ends before a
/// block its header places after them (a range table or pyramid cut off): the
/// header as if the file were long enough. For reading the samples alone (a
/// conversion rescuing them); the blocks are checked apart.
pub fn read_header_of_cut_file(path: &Path) -> Result<(Header, File, u64), VolumeError> {
    read_header_as(path, Some(u64::MAX))
}

fn read_header_as(
    path: &Path,
    claimed_len: Option<u64>,
) -> Result<(Header, File, u64), VolumeError> {
    // Regular files only: a named pipe would block the read below forever.
    let file = crate::files::open_regular(path).at(path)?;
    let len = file.metadata().at(path)?.len();
    let mut head = Vec::with_capacity(MAX_HEADER_LEN as usize);
    (&file)
        .take(MAX_HEADER_LEN)
        .read_to_end(&mut head)
        .at(path)?;
    // A sidecar given for its volume: named as what it is.
    if let Some(what) = sidecar_kind(&head) {
        let volume = path.with_extension("");
        let kind = VolumeErrorKind::Sidecar {
            what,
            volume: volume.display().to_string(),
        };
        return Err(VolumeError::new(path, kind));
    }
    // (A cut file's header that is wrong anyway: said with the file's length.)
    let parsed = match claimed_len {
        Some(claimed) => Header::parse(&head, claimed)
            .map_err(|wrong| Header::parse(&head, len).err().unwrap_or(wrong)),
        None => Header::parse(&head, len),
    };
    let header = parsed.map_err(|e| match e {
        // The first byte that tells formats apart names no .vol layout: a file
        // not named `.vol` is most likely no volume at all (a README, a PNG).
        // Gzip data (a `.nii.gz` renamed, a `.vol` compressed): said as such.
        _ if head.starts_with(&[0x1f, 0x8b]) => {
            VolumeError::new(path, VolumeErrorKind::GzipUnnamed)
        }
        // (A few bytes not named .vol: no volume either.)
        HeaderError::UnknownOrder(_) | HeaderError::TooShort { .. } if !has_vol_extension(path) => {
            VolumeError::new(path, VolumeErrorKind::NotAVolume(e))
        }
        e => VolumeError::new(path, VolumeErrorKind::Header(e)),
    })?;
    Ok((header, file, len))
}

/// Where the embedded value-range table at `offset` of a file with `header`
/// ends, or that a file of `file_len` bytes cuts it off.
pub(crate) fn embedded_ranges_end(
    header: &Header,
    offset: u64,
    file_len: u64,
) -> Result<u64, VolumeErrorKind> {
    let end = offset.saturating_add(BrickRanges::table_len(
        &header.block_grid(LINEAR_RANGE_SIDE),
    ));
    if end > file_len {
        return Err(VolumeErrorKind::RangesCutOff { end, file_len });
    }
    Ok(end)
}

/// What kind of sidecar a file starting with `head` is, if it is one.
fn sidecar_kind(head: &[u8]) -> Option<&'static str> {
    match head.get(..4)? {
        b"RCPS" => Some("the resolution pyramid"),
        b"RCRS" => Some("the value-range table"),
        _ => None,
    }
}

/// Where a file with `header` ends by its format: after its samples, its
/// value-range table or its embedded resolution pyramid, whichever ends last
/// (the lengths of both blocks follow from the header). Bytes past it are
/// [`Volume::unused_tail`].
pub(crate) fn content_end(header: &Header) -> Result<u64, HeaderError> {
    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    let ranges = header
        .ranges_offset
        .map(|offset| offset.saturating_add(BrickRanges::table_len(&grid)));
    let pyramid = match header.pyramid_offset {
        Some(offset) => {
            let block = PyramidLayout::plan(header, header.pyramid_cells)?.block_len();
            Some(offset.saturating_add(block))
        }
        None => None,
    };
    let data_end = header.data_end()?;
    Ok([data_end]
        .into_iter()
        .chain(ranges)
        .chain(pyramid)
        .max()
        .unwrap_or(data_end))
}

/// The warning for the `count` bytes from byte `start` of file `path` past its
/// last block ([`Volume::unused_tail`]), ending with what becomes of them.
pub fn unused_tail_warning(path: &Path, (start, count): (u64, u64), fate: &str) -> String {
    let bytes = if count == 1 { "byte" } else { "bytes" };
    format!(
        "warning: {}: the file has {count} {bytes} after its last block (from byte {start}) that are not part of the volume; {fate}",
        path.display()
    )
}

/// Whether `path`'s name ends in `.vol` (any case).
pub fn has_vol_extension(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vol"))
}

/// The sidecar file that caches brick ranges of a thesis-format file.
pub fn ranges_sidecar_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".ranges");
    PathBuf::from(name)
}

impl Volume {
    /// Opens `path` memory-mapped, caching brick ranges as [`OpenOptions::default`].
    pub fn open(path: impl AsRef<Path>) -> Result<Volume, VolumeError> {
        Self::open_with(path, OpenOptions::default())
    }

    /// Opens `path` as `options` say.
    pub fn open_with(path: impl AsRef<Path>, options: OpenOptions) -> Result<Volume, VolumeError> {
        let path = path.as_ref();
        let (header, file, len) = read_header(path)?;
        let storage = Storage::open(&file, len, options.access).at(path)?;
        if matches!(header.layout, Layout::Bricked { .. }) {
            storage.advise_random();
        }
        let data = typed_data(&header, storage.bytes()).at(path)?;
        let ranges = load_ranges(path, &header, &storage, data, &file, len, options)?;
        let pyramid = load_pyramid(path, &header, &file, len, options.access)?;
        let content_end = content_end(&header).at(path)?;
        Ok(Volume {
            path: path.to_path_buf(),
            full_dims: header.dims,
            header,
            storage,
            ranges,
            cells: pyramid.level0_cells,
            levels: pyramid.levels,
            level: 0,
            unused_tail: (len > content_end).then(|| (content_end, len - content_end)),
            ignored_pyramid: pyramid.ignored,
        })
    }

    /// Builds a volume in RAM from a header and its samples in file order, as if it
    /// had been read from `name` (used for built-in scenes and tests).
    ///
    /// The header's sample type must be `T`'s; its range table offset is ignored (the
    /// ranges are computed).
    pub fn from_samples<T: Sample>(
        name: impl Into<PathBuf>,
        header: &Header,
        samples: &[T],
    ) -> Result<Volume, VolumeError> {
        let path = name.into();
        let mut header = header.clone();
        header.ranges_offset = None;
        header.pyramid_offset = None;
        header.data_offset = header.standard_data_offset();
        if header.sample_type != T::TYPE {
            let kind = VolumeErrorKind::Header(HeaderError::SampleTypeMismatch {
                header: header.sample_type,
                samples: T::TYPE,
            });
            return Err(VolumeError::new(&path, kind));
        }
        let mut image = header.encode().at(&path)?;
        let needed = header.data_len().at(&path)?;
        let bytes: &[u8] = bytemuck::cast_slice(samples);
        if bytes.len() as u64 != needed {
            let kind = VolumeErrorKind::Header(HeaderError::DataLengthMismatch {
                declared: bytes.len() as u64,
                expected: needed,
            });
            return Err(VolumeError::new(&path, kind));
        }
        image.extend_from_slice(bytes);
        Volume::in_ram(path, Storage::from_bytes(&image))
    }

    /// A volume over a file image in RAM: its header parsed, its ranges scanned.
    fn in_ram(path: PathBuf, storage: Storage) -> Result<Volume, VolumeError> {
        let bytes = storage.bytes();
        let header = Header::parse(bytes, bytes.len() as u64).at(&path)?;
        let ranges = compute_ranges(&header, typed_data(&header, bytes).at(&path)?);
        Ok(Volume {
            path,
            full_dims: header.dims,
            header,
            storage,
            ranges,
            cells: None,
            levels: Vec::new(),
            level: 0,
            unused_tail: None,
            ignored_pyramid: None,
        })
    }

    /// Builds a volume in RAM from a header whose samples `fill` writes in file order
    /// into the buffer it is given (no intermediate copy), as if read from `name`.
    ///
    /// The header's sample type must be `T`'s; its range table offset is ignored.
    pub fn from_fill<T: Sample>(
        name: impl Into<PathBuf>,
        header: &Header,
        fill: impl FnOnce(&mut [T]) -> Result<(), VolumeError>,
    ) -> Result<Volume, VolumeError> {
        let path = name.into();
        let mut header = header.clone();
        header.ranges_offset = None;
        header.pyramid_offset = None;
        if header.sample_type != T::TYPE {
            let kind = VolumeErrorKind::Header(HeaderError::SampleTypeMismatch {
                header: header.sample_type,
                samples: T::TYPE,
            });
            return Err(VolumeError::new(&path, kind));
        }
        let head = header.encode().at(&path)?;
        let start = head.len();
        let len = header.data_end().at(&path)? as usize;
        let mut words = vec![0u64; len.div_ceil(8)];
        {
            let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
            bytes[..start].copy_from_slice(&head);
            // u16 samples need the extended header (64 bytes): they stay aligned.
            let samples = bytemuck::try_cast_slice_mut::<u8, T>(&mut bytes[start..len])
                .map_err(|_| VolumeError::new(&path, VolumeErrorKind::Misaligned))?;
            fill(samples)?;
        }
        Volume::in_ram(path, Storage::Ram { words, len })
    }

    /// Scans the samples for the per-brick ranges (what open does without a cache).
    pub fn compute_ranges(&self) -> BrickRanges {
        compute_ranges(&self.header, self.data())
    }

    /// Bytes at the end of the file that no part of it accounts for (after its
    /// samples, value-range table and resolution pyramid, whichever ends
    /// last): where they start and how many; `None` when the file ends with
    /// its last block, and for volumes not read from a file. Opening ignores
    /// them; they may be the sign of a damaged copy or of two files joined.
    pub fn unused_tail(&self) -> Option<(u64, u64)> {
        self.unused_tail
    }

    /// Why a damaged pyramid sidecar was ignored when the file opened (a
    /// stale one, built before the file last changed, is ignored silently).
    pub fn ignored_pyramid(&self) -> Option<&str> {
        self.ignored_pyramid.as_deref()
    }

    /// What opening the file found that the user should know of, one warning
    /// each: bytes past its last block ([`Self::unused_tail_warning`]), a
    /// damaged pyramid sidecar that was ignored.
    pub fn open_warnings(&self) -> Vec<String> {
        let sidecar = self.ignored_pyramid.as_ref().map(|why| {
            format!(
                "warning: {}: ignored ({why}); the volume has no pyramid until `volgen pyramid {}` writes it again",
                pyramid_sidecar_path(&self.path).display(),
                self.path.display()
            )
        });
        self.unused_tail_warning()
            .into_iter()
            .chain(sidecar)
            .collect()
    }

    /// A warning naming [`Self::unused_tail`], if there is one.
    pub fn unused_tail_warning(&self) -> Option<String> {
        let tail = self.unused_tail?;
        Some(unused_tail_warning(
            &self.path,
            tail,
            "they are ignored (a damaged copy, or two files joined?)",
        ))
    }

    /// Number of resolution levels: 1 (the volume itself) plus the pyramid's.
    pub fn level_count(&self) -> usize {
        1 + self.levels.len()
    }

    /// Resolution level `k` (0: this volume; `k` is clamped to the coarsest).
    pub fn level(&self, k: usize) -> &Volume {
        match k.min(self.levels.len()) {
            0 => self,
            k => &self.levels[k - 1],
        }
    }

    /// Which pyramid level this volume is (0 for an opened file).
    pub fn level_index(&self) -> u32 {
        self.level
    }

    /// Marks this volume as level `k` of a pyramid whose level 0 had `2^-k` times
    /// its spacing and `full_dims` voxels: it is then placed, sampled and
    /// composited as [`Self::level`] `k` of such a file would be (used to compare
    /// a pyramid with a separately reduced volume).
    pub fn placed_as_level(mut self, k: u32, full_dims: [u32; 3]) -> Volume {
        self.level = k;
        self.full_dims = full_dims;
        self
    }

    /// Voxel counts of the full-resolution volume (level 0) this volume is a
    /// level of; its own for level 0.
    pub fn full_dims(&self) -> [u32; 3] {
        self.full_dims
    }

    /// The box rays sample, in this volume's voxel coordinates (lower and
    /// upper corner): the full-resolution volume's, from the centre of its
    /// first voxel to that of its last, whatever the level. Level 0 samples
    /// `[0, dims − 1]`; a coarser level's voxel centres lie up to half a coarse
    /// voxel inside that box, and its samples there read the edge voxels (reads
    /// clamp to `[0, dims − 1]`), so every level shows the volume, and a cut,
    /// at the same place and size.
    pub fn sampled_box(&self) -> [[f32; 3]; 2] {
        let scale = self.level_scale();
        [
            [level_coordinate(0.0, scale); 3],
            self.full_dims
                .map(|d| level_coordinate(d.saturating_sub(1) as f32, scale)),
        ]
    }

    /// World position of voxel `(0, 0, 0)`: the origin for level 0; the centre of
    /// the `2^k` level-0 voxels a level-`k` voxel stands for otherwise.
    pub fn origin(&self) -> [f32; 3] {
        let scale = (1u64 << self.level) as f32;
        self.header
            .spacing
            .map(|s| (scale - 1.0) / 2.0 * (s / scale))
    }

    /// How many level-0 voxels one voxel of this level spans per axis: `2^level`.
    pub fn level_scale(&self) -> f32 {
        (1u64 << self.level) as f32
    }

    /// Bytes of samples of this level.
    pub fn data_bytes(&self) -> u64 {
        self.header.data_len().unwrap_or(0)
    }

    /// Asks the OS to read `len` bytes of samples at byte `offset` of this level's
    /// data ahead of use (mapped volumes; a no-op in RAM). Best effort.
    pub fn prefetch(&self, offset: u64, len: u64) {
        self.storage
            .will_need(self.header.data_offset + offset, len);
    }

    /// The file this volume was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The parsed header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Voxel counts on x, y, z.
    pub fn dims(&self) -> [u32; 3] {
        self.header.dims
    }

    /// What stored samples mean (identity for files without a value block).
    pub fn value_units(&self) -> ValueUnits {
        self.header.value_units()
    }

    /// Where the volume lies in the patient, when the file says (format version 4).
    pub fn orientation(&self) -> Option<&Orientation> {
        self.header.orientation.as_ref()
    }

    /// Voxel spacing on x, y, z.
    pub fn spacing(&self) -> [f32; 3] {
        self.header.spacing
    }

    /// The volume's diagonal in level-0 voxels of its smallest spacing: the
    /// length, in the reference steps opacity is defined per, of the longest
    /// ray through it (the same for every level of a pyramid).
    pub fn diagonal_voxels(&self) -> f32 {
        let extent: f32 = (0..3)
            .map(|a| (self.header.dims[a] as f32 * self.header.spacing[a]).powi(2))
            .sum::<f32>()
            .sqrt();
        let smallest = self
            .header
            .spacing
            .into_iter()
            .fold(f32::INFINITY, f32::min);
        extent / (smallest / self.level_scale())
    }

    /// Sample order in the file.
    pub fn layout(&self) -> Layout {
        self.header.layout
    }

    /// Stored sample type.
    pub fn sample_type(&self) -> SampleType {
        self.header.sample_type
    }

    /// Scalar values or labels.
    pub fn content(&self) -> Content {
        self.header.content
    }

    /// Mapped or in RAM.
    pub fn access(&self) -> Access {
        self.storage.access()
    }

    /// Per-brick value ranges (bricks of the file, or logical bricks of
    /// [`LINEAR_RANGE_SIDE`] voxels for linear files).
    pub fn ranges(&self) -> &BrickRanges {
        &self.ranges
    }

    /// The cell ranges the file stores for its default brick grid
    /// ([`CellShape::default_for`](super::CellShape::default_for)), if it stores
    /// them (files with a pyramid written by this build).
    pub fn stored_cells(&self) -> Option<&CellTable> {
        self.cells.as_ref()
    }

    /// Checks that the files this volume maps (its own, and its pyramid's) still
    /// hold every byte it may read. A file another program truncated while it is
    /// mapped would stop the process at the first read of a missing byte
    /// ([`crate::files::guard_mapped_reads`]); a long-lived reader (the viewer)
    /// asks this before each frame and refuses to read a shrunk file instead.
    pub fn check_whole(&self) -> Result<(), VolumeError> {
        if let Some((now, needed)) = self.storage.shrunk() {
            let message = format!(
                "shrank to {now} bytes while open (it held {needed}): another program truncated it; open it again once it is whole"
            );
            return Err(VolumeError::new(
                &self.path,
                std::io::Error::new(std::io::ErrorKind::UnexpectedEof, message),
            ));
        }
        self.levels.iter().try_for_each(Volume::check_whole)
    }

    /// The typed samples.
    pub fn data(&self) -> VolumeData<'_> {
        typed_data(&self.header, self.storage.bytes()).expect("alignment checked at open")
    }

    /// The sample at voxel `v` widened to u16 (slow path, for tools and tests).
    ///
    /// # Panics
    /// If `v` is outside the volume.
    pub fn voxel(&self, v: [u32; 3]) -> u16 {
        match self.data() {
            VolumeData::U8(t) => u16::from(t.voxel(v)),
            VolumeData::U16(t) => t.voxel(v),
        }
    }
}

/// The typed samples of a file whose bytes are `file_bytes`.
fn typed_data<'a>(
    header: &Header,
    file_bytes: &'a [u8],
) -> Result<VolumeData<'a>, VolumeErrorKind> {
    let start = header.data_offset as usize;
    // The header was validated against the file length when it was parsed.
    let end = header.data_end()? as usize;
    let bytes = &file_bytes[start..end];
    let (dims, layout) = (header.dims, header.layout);
    Ok(match header.sample_type {
        SampleType::U8 => VolumeData::U8(TypedVolume::new(bytes, dims, layout)),
        SampleType::U16 => {
            let samples =
                bytemuck::try_cast_slice(bytes).map_err(|_| VolumeErrorKind::Misaligned)?;
            VolumeData::U16(TypedVolume::new(samples, dims, layout))
        }
    })
}

fn compute_ranges(header: &Header, data: VolumeData<'_>) -> BrickRanges {
    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    match data {
        VolumeData::U8(v) => BrickRanges::compute(&v, &grid),
        VolumeData::U16(v) => BrickRanges::compute(&v, &grid),
    }
}

/// Whether every range of `ranges` lies within what a sample of `sample_type`
/// holds (a u8 file's table claiming 60000 is corrupt). u16 tables always do;
/// a u8 table is read once more for it (a few milliseconds for 2000³).
fn ranges_fit_type(ranges: &BrickRanges, sample_type: SampleType) -> bool {
    sample_type == SampleType::U16 || ranges.overall()[1] <= sample_type.max_value()
}

/// Bricks of a stored range table checked against their samples when a file
/// opens: a few, spread over the volume (every brick would read the whole
/// file, which opening never does).
const RANGE_SPOT_CHECKS: u64 = 9;

/// The first of a few bricks spread over the volume whose stored range does
/// not hold its samples' values (a damaged table: zeroed, shifted, another
/// file's), with the stored range and the values' range; `None` when they
/// agree.
fn ranges_disagree(
    table: &BrickRanges,
    data: VolumeData<'_>,
) -> Option<([u32; 3], [u16; 2], [u16; 2])> {
    let grid = *table.grid();
    let count = grid.block_count();
    let picks = RANGE_SPOT_CHECKS.min(count);
    (0..picks)
        .map(|k| {
            if picks > 1 {
                k * (count - 1) / (picks - 1)
            } else {
                0
            }
        })
        .map(|i| grid.coords(i))
        .find_map(|b| {
            let [lo, hi] = match data {
                VolumeData::U8(v) => brick_range(&v, &grid, b),
                VolumeData::U16(v) => brick_range(&v, &grid, b),
            };
            let stored = table.range(b);
            (stored[0] > lo || stored[1] < hi).then_some((b, stored, [lo, hi]))
        })
}

/// The brick ranges of an opened file: from its embedded table, from a fresh
/// sidecar, or computed (and then cached in a sidecar for thesis files).
fn load_ranges(
    path: &Path,
    header: &Header,
    storage: &Storage,
    data: VolumeData<'_>,
    file: &File,
    len: u64,
    options: OpenOptions,
) -> Result<BrickRanges, VolumeError> {
    let dims = header.dims;
    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    if let Some(offset) = header.ranges_offset {
        // Mapped files keep the table in the file (its own read-only mapping,
        // read ahead sequentially: the samples' mapping of bricked files is advised
        // for random access); files in RAM decode it from their bytes.
        let available = len.saturating_sub(offset);
        embedded_ranges_end(header, offset, len).at(path)?;
        let table = match storage {
            Storage::Mapped { .. } => {
                BrickRanges::read_from(file, offset, available, dims, Access::Mapped).at(path)?
            }
            Storage::Ram { .. } => {
                let table_len = BrickRanges::table_len(&grid).min(available);
                BrickRanges::decode(
                    &storage.bytes()[offset as usize..(offset + table_len) as usize],
                    dims,
                )
            }
        };
        let table = table
            .filter(|r| r.grid() == &grid && ranges_fit_type(r, header.sample_type))
            .ok_or_else(|| VolumeError::new(path, VolumeErrorKind::CorruptRanges))?;
        if let Some((brick, stored, values)) = ranges_disagree(&table, data) {
            return Err(VolumeError::new(
                path,
                VolumeErrorKind::RangesDisagree {
                    brick,
                    stored,
                    values,
                },
            ));
        }
        return Ok(table);
    }
    let sidecar = ranges_sidecar_path(path);
    let mtime = file.metadata().and_then(|m| m.modified()).ok();
    // A sidecar that is not a regular file (a named pipe) is ignored, never read;
    // its table is mapped like an embedded one.
    if let Some(mtime) = mtime
        && let Ok(side) = crate::files::open_regular(&sidecar)
        && let Ok(side_len) = side.metadata().map(|m| m.len())
        && let Ok(Some(r)) = BrickRanges::read_sidecar(&side, side_len, dims, len, mtime)
        && r.grid() == &grid
        && ranges_fit_type(&r, header.sample_type)
    {
        return Ok(r);
    }
    let ranges = compute_ranges(header, data);
    if options.write_ranges_sidecar
        && header.format == Format::Thesis
        && let Some(mtime) = mtime
    {
        // Best effort: a read-only directory only costs a rescan next time.
        let _ = write_file_atomically(&sidecar, &ranges.encode_sidecar(len, mtime));
    }
    Ok(ranges)
}

/// A resolution pyramid as read: its levels and the stored level-0 cell
/// ranges.
#[derive(Default)]
struct PyramidBlock {
    levels: Vec<Volume>,
    level0_cells: Option<CellTable>,
    /// Why a damaged sidecar was ignored.
    ignored: Option<String>,
}

/// The pyramid of an opened file: embedded (extended header version 2 or
/// later), else from a fresh `FILE.pyramid`
/// sidecar, else none. A corrupt embedded pyramid is an error; a stale or
/// unreadable sidecar is ignored, and a fresh one that is damaged too, with
/// the reason ([`PyramidBlock::ignored`]).
fn load_pyramid(
    path: &Path,
    header: &Header,
    file: &File,
    len: u64,
    access: Access,
) -> Result<PyramidBlock, VolumeError> {
    if let Some(start) = header.pyramid_offset {
        let cells = Some(header.pyramid_cells);
        return read_levels(path, header, file, start, len, access, cells);
    }
    let none = || Ok(PyramidBlock::default());
    let sidecar = pyramid_sidecar_path(path);
    // Never block on a FIFO or read a directory posing as the sidecar.
    let Ok(side) = crate::files::open_regular(&sidecar) else {
        return none();
    };
    let mtime = file.metadata().and_then(|m| m.modified());
    let side_len = side.metadata().map(|m| m.len()).unwrap_or(0);
    let mut head = vec![0u8; SIDECAR_HEAD_LEN as usize];
    let fresh = match mtime {
        Ok(mtime) => {
            std::os::unix::fs::FileExt::read_exact_at(&side, &mut head, 0).is_ok()
                && sidecar_is_fresh(&head, len, mtime)
        }
        Err(_) => false,
    };
    if !fresh || !side.metadata().is_ok_and(|m| m.is_file()) {
        return none();
    }
    // A fresh sidecar that does not read is damaged: opened without it, said.
    Ok(read_levels(
        path,
        header,
        &side,
        SIDECAR_HEAD_LEN,
        side_len,
        access,
        None,
    )
    .unwrap_or_else(|e| PyramidBlock {
        // (`volgen pyramid` writes it again: the warning says so.)
        ignored: Some(e.kind.without_advice()),
        ..PyramidBlock::default()
    }))
}

/// The pyramid block at `start` of `file`; `cells`: whether the block must
/// store cell tables (`None`: either).
fn read_levels(
    path: &Path,
    base: &Header,
    file: &File,
    start: u64,
    file_len: u64,
    access: Access,
    cells: Option<bool>,
) -> Result<PyramidBlock, VolumeError> {
    let layout = PyramidLayout::read(file, start, file_len, base, cells).at(path)?;
    let level0_cells = layout.read_cells(file, start, base, 0, access).at(path)?;
    let levels = (1..=layout.levels.len())
        .map(|k| {
            let e = &layout.levels[k - 1];
            let header = layout.level_header(base, k);
            let storage =
                Storage::open_region(file, start + e.data_offset, e.data_len, access).at(path)?;
            if matches!(header.layout, Layout::Bricked { .. }) {
                storage.advise_random();
            }
            typed_data(&header, storage.bytes()).at(path)?;
            let ranges = layout.read_ranges(file, start, base, k, access).at(path)?;
            let cells = layout.read_cells(file, start, base, k, access).at(path)?;
            Ok(Volume {
                path: path.to_path_buf(),
                header,
                storage,
                ranges,
                cells,
                levels: Vec::new(),
                level: k as u32,
                full_dims: base.dims,
                unused_tail: None,
                ignored_pyramid: None,
            })
        })
        .collect::<Result<_, VolumeError>>()?;
    Ok(PyramidBlock {
        levels,
        level0_cells,
        ignored: None,
    })
}

/// Computes the resolution pyramid of the volume file `path` (any format) into its
/// sidecar `FILE.pyramid`, atomically; returns the number of levels (0 when the
/// volume is small enough to need none, and then no sidecar is written).
pub fn write_pyramid_sidecar(
    path: &Path,
    options: &crate::io::WriteOptions,
    job: &crate::job::Job,
) -> Result<usize, VolumeError> {
    let volume = Volume::open(path)?;
    if level_dims(volume.dims()).is_empty() {
        return Ok(0);
    }
    let meta = std::fs::metadata(path).at(path)?;
    let sidecar = pyramid_sidecar_path(path);
    let tmp = temp_file_beside(&sidecar).at(&sidecar)?;
    let out = tmp.as_file();
    std::os::unix::fs::FileExt::write_all_at(
        out,
        &sidecar_head(meta.len(), meta.modified().at(path)?),
        0,
    )
    .at(&sidecar)?;
    let layout = match volume.data() {
        VolumeData::U8(v) => write_block(
            out,
            SIDECAR_HEAD_LEN,
            volume.header(),
            v,
            options,
            job,
            &sidecar,
        )?,
        VolumeData::U16(v) => write_block(
            out,
            SIDECAR_HEAD_LEN,
            volume.header(),
            v,
            options,
            job,
            &sidecar,
        )?,
    };
    out.sync_all().at(&sidecar)?;
    tmp.persist(&sidecar)
        .map_err(|e| VolumeError::new(&sidecar, e.error))?;
    Ok(layout.levels.len())
}

/// Creates the temporary file that will become `path`
/// ([`crate::files::temp_file_beside`]).
pub(crate) fn temp_file_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    crate::files::temp_file_beside(path)
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a
/// rename, so readers never see a partial file.
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let tmp = temp_file_beside(path)?;
    // (Through the file itself: the temporary file's own writer names its
    // path in errors, which the user never chose.)
    tmp.as_file().write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}
