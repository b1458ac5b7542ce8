//! Slab-wise reading of raw and `.vol` inputs with positioned reads.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use super::decode::{Endian, RawType, decode_into};
use crate::job::Job;
use crate::text::counted;
use crate::volume::{
    AtPath, BlockGrid, Content, Header, Layout, MAX_AXIS, Orientation, SampleType, ValueUnits,
    VolumeError, VolumeErrorKind, read_header,
};

/// Bytes read per positioned read when streaming.
const CHUNK_BYTES: usize = 4 << 20;

/// Which coordinate changes fastest in a raw file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RawOrder {
    /// x fastest, then y, then z (C order `[z][y][x]`: most raw dumps).
    #[default]
    XFastest,
    /// z fastest, then y, then x (the `.vol` linear order).
    ZFastest,
}

/// How to read a headerless raw file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawSpec {
    /// Voxel counts on x, y, z.
    pub dims: [u32; 3],
    /// Sample type.
    pub sample: RawType,
    /// Byte order of multi-byte samples.
    pub endian: Endian,
    /// Bytes to skip before the first sample (a foreign header).
    pub skip: u64,
    /// Which coordinate is fastest.
    pub order: RawOrder,
}

impl RawSpec {
    /// Why a raw file of `len` bytes does not hold these samples: its length
    /// is not the skip plus the samples. Said with the difference, and for a
    /// longer file the skip that would pass over a header before the samples,
    /// written as `skip_flag N` (`--skip` for volgen's flag). `None` when the
    /// length fits.
    pub fn length_problem(&self, len: u64, skip_flag: &str) -> Option<String> {
        let [x, y, z] = self.dims;
        // (Sizes past 64 bits are refused before a file is measured.)
        let needed = self.sample_bytes()?;
        let shape = format!("{x}x{y}x{z} {}", self.sample);
        let skipped = match self.skip {
            0 => String::new(),
            n => format!("the {n}-byte skip and "),
        };
        let samples = counted(needed, "byte");
        let have = len.saturating_sub(self.skip);
        if have > needed {
            let extra = have - needed;
            Some(format!(
                "the file holds {} more than {skipped}its {samples} of samples ({shape}; a header before them? {skip_flag} {} skips it)",
                counted(extra, "byte"),
                self.skip + extra
            ))
        } else if have < needed {
            Some(format!(
                "the file holds {}, fewer than {skipped}its {samples} of samples ({shape})",
                counted(len, "byte")
            ))
        } else {
            None
        }
    }

    /// Bytes of the samples (without the skip); `None` past 64 bits.
    fn sample_bytes(&self) -> Option<u64> {
        self.dims
            .iter()
            .try_fold(self.sample.size() as u64, |n, &d| {
                n.checked_mul(u64::from(d))
            })
    }
}

/// The value type an input delivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputType {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit float.
    F32,
}

impl InputType {
    /// Whether every value of this type is stored exactly by `out`.
    pub fn fits_in(self, out: SampleType) -> bool {
        matches!(
            (self, out),
            (InputType::U8, _) | (InputType::U16, SampleType::U16)
        )
    }
}

#[derive(Debug)]
enum Source {
    Raw(RawSpec),
    Vol(Header),
}

/// Where an input's bytes are: an open file (read with positioned reads) or a buffer
/// (a decompressed stream).
#[derive(Debug)]
pub enum RawData {
    /// A file, read with positioned reads.
    File(File),
    /// Bytes in memory.
    Memory(Vec<u8>),
}

impl RawData {
    fn len(&self) -> std::io::Result<u64> {
        match self {
            RawData::File(f) => Ok(f.metadata()?.len()),
            RawData::Memory(b) => Ok(b.len() as u64),
        }
    }

    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
        match self {
            RawData::File(f) => f.read_exact_at(buf, offset),
            RawData::Memory(bytes) => {
                let src = usize::try_from(offset)
                    .ok()
                    .and_then(|o| bytes.get(o..)?.get(..buf.len()))
                    .ok_or(std::io::ErrorKind::UnexpectedEof)?;
                buf.copy_from_slice(src);
                Ok(())
            }
        }
    }
}

/// A volume being read slab by slab (runs of whole x-planes).
#[derive(Debug)]
pub struct Input {
    path: PathBuf,
    file: RawData,
    source: Source,
    spacing: Option<[f32; 3]>,
    /// What raw input values mean (raw files: set by the importer that knows).
    units: ValueUnits,
    /// Where the volume lies in the patient, when the source says.
    orientation: Option<Orientation>,
    /// Other files the input reads (a foreign header's detached data file,
    /// a DICOM series' slices): no output may be one of them.
    also_reads: Vec<PathBuf>,
}

impl Input {
    /// Opens a headerless raw file described by `spec`; its size must match exactly.
    pub fn open_raw(path: &Path, spec: RawSpec) -> Result<Input, VolumeError> {
        let file = crate::files::open_regular(path).at(path)?;
        Self::from_raw_data(path, RawData::File(file), spec, None)
    }

    /// Reads raw samples described by `spec` from `data` (a file or a buffer), whose
    /// length must be exactly `spec.skip` plus the samples; `path` names the input in
    /// errors and `spacing` is the voxel spacing the input declares, if any.
    pub fn from_raw_data(
        path: &Path,
        data: RawData,
        spec: RawSpec,
        spacing: Option<[f32; 3]>,
    ) -> Result<Input, VolumeError> {
        let bad = |msg: String| VolumeError::new(path, VolumeErrorKind::RawSpec(msg));
        for (axis, &d) in ['x', 'y', 'z'].iter().zip(&spec.dims) {
            if d == 0 || d > MAX_AXIS {
                return Err(bad(format!(
                    "raw size on {axis} is {d}; it must be between 1 and {MAX_AXIS}"
                )));
            }
        }
        let file = data;
        let len = file.len().at(path)?;
        // (Checked first: the length problem assumes sizes within 64 bits.)
        spec.sample_bytes()
            .and_then(|n| n.checked_add(spec.skip))
            .ok_or_else(|| bad("raw sizes overflow 64 bits".into()))?;
        if let Some(problem) = spec.length_problem(len, "a skip of") {
            return Err(bad(problem));
        }
        Ok(Input {
            path: path.to_path_buf(),
            file,
            source: Source::Raw(spec),
            spacing,
            units: ValueUnits::IDENTITY,
            orientation: None,
            also_reads: Vec::new(),
        })
    }

    /// Opens a `.vol` file (either header format, any layout).
    pub fn open_vol(path: &Path) -> Result<Input, VolumeError> {
        // A range table or pyramid cut off: the samples before it are whole and
        // read (the blocks' damage is reported by `embedded_ranges_intact` and
        // `embedded_pyramid_intact`).
        let (header, file, _) = match read_header(path) {
            Err(e) if matches!(&e.kind, VolumeErrorKind::Header(h) if h.is_block_past_end()) => {
                crate::volume::read_header_of_cut_file(path)?
            }
            result => result?,
        };
        Ok(Input {
            path: path.to_path_buf(),
            file: RawData::File(file),
            units: header.value_units(),
            orientation: header.orientation.clone(),
            source: Source::Vol(header),
            spacing: None,
            also_reads: Vec::new(),
        })
    }

    /// For a `.vol` input with an embedded value-range table: what is wrong with
    /// it (`Some(Err(why))`: cut off or corrupt, so a conversion recomputes the
    /// ranges from the samples, which it always does). `None` for other inputs.
    pub fn embedded_ranges_intact(&self) -> Option<Result<(), String>> {
        let (Source::Vol(header), RawData::File(file)) = (&self.source, &self.file) else {
            return None;
        };
        let offset = header.ranges_offset?;
        let grid = header.block_grid(crate::volume::LINEAR_RANGE_SIDE);
        let len = file.metadata().map(|m| m.len()).unwrap_or(0);
        let end = match crate::volume::embedded_ranges_end(header, offset, len) {
            Ok(end) => end,
            Err(cut) => return Some(Err(cut.without_advice())),
        };
        let mut table = vec![0u8; (end - offset) as usize];
        let intact = file.read_exact_at(&mut table, offset).is_ok()
            && crate::volume::BrickRanges::decode(&table, header.dims)
                .is_some_and(|r| r.grid() == &grid);
        Some(if intact {
            Ok(())
        } else {
            Err("the value-range table after the samples is corrupt".to_string())
        })
    }

    /// For a `.vol` input with an embedded resolution pyramid: what is wrong
    /// with it (`Some(Err(why))`: a conversion builds the output's pyramid from
    /// the samples, which it always does). `None` for other inputs.
    pub fn embedded_pyramid_intact(&self) -> Option<Result<(), String>> {
        let (Source::Vol(header), RawData::File(file)) = (&self.source, &self.file) else {
            return None;
        };
        let offset = header.pyramid_offset?;
        let len = file.metadata().map(|m| m.len()).unwrap_or(0);
        let cells = Some(header.pyramid_cells);
        Some(
            crate::volume::pyramid::PyramidLayout::read(file, offset, len, header, cells)
                .map(|_| ())
                // (Not the advice to convert: this is the conversion.)
                .map_err(|e| e.without_advice()),
        )
    }

    /// For a `.vol` input: the bytes after its last block (samples, range
    /// table, pyramid), as [`crate::volume::Volume::unused_tail`] (where they
    /// start, how many); `None` when there are none or for other inputs.
    pub fn unused_tail(&self) -> Option<(u64, u64)> {
        let (Source::Vol(header), RawData::File(file)) = (&self.source, &self.file) else {
            return None;
        };
        let len = file.metadata().ok()?.len();
        let end = crate::volume::content_end(header).ok()?;
        (len > end).then(|| (end, len - end))
    }

    /// This input with `units` saying what its values mean (a foreign file's
    /// rescale slope and intercept, and its unit when known).
    pub fn with_units(mut self, units: ValueUnits) -> Input {
        self.units = units;
        self
    }

    /// This input placed in the patient by `orientation` (a foreign file's
    /// direction cosines and origin).
    pub fn with_orientation(mut self, orientation: Option<Orientation>) -> Input {
        self.orientation = orientation;
        self
    }

    /// Where the volume lies in the patient, when its file says.
    pub fn orientation(&self) -> Option<&Orientation> {
        self.orientation.as_ref()
    }

    /// What the values this input delivers mean (a `.vol` input: its header's
    /// units; raw files: identity unless an importer said otherwise).
    pub fn units(&self) -> &ValueUnits {
        &self.units
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// This input noting that it reads `files` too (a foreign header's data
    /// file, a series' slices).
    pub fn also_reading(mut self, files: Vec<PathBuf>) -> Input {
        self.also_reads = files;
        self
    }

    /// Every file the input reads: [`Self::path`] and those it also reads.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        std::iter::once(self.path.as_path()).chain(self.also_reads.iter().map(PathBuf::as_path))
    }

    /// The raw file's description when its x is fastest (most foreign
    /// formats): slabs of whole x-planes are strided in it.
    pub(super) fn x_fastest_raw(&self) -> Option<&RawSpec> {
        match &self.source {
            Source::Raw(spec) if spec.order == RawOrder::XFastest => Some(spec),
            _ => None,
        }
    }

    /// Voxel counts on x, y, z.
    pub fn dims(&self) -> [u32; 3] {
        match &self.source {
            Source::Raw(spec) => spec.dims,
            Source::Vol(h) => h.dims,
        }
    }

    /// Voxel spacing: a `.vol` input's, or what a foreign file declared; `None` for
    /// headerless raw files.
    pub fn spacing(&self) -> Option<[f32; 3]> {
        self.header().map(|h| h.spacing).or(self.spacing)
    }

    /// The header of a `.vol` input.
    pub fn header(&self) -> Option<&Header> {
        match &self.source {
            Source::Raw(_) => None,
            Source::Vol(h) => Some(h),
        }
    }

    /// Scalar values or labels (raw inputs are scalar).
    pub fn content(&self) -> Content {
        self.header().map_or(Content::Scalar, |h| h.content)
    }

    /// The type of the values this input delivers.
    pub fn value_type(&self) -> InputType {
        match &self.source {
            Source::Raw(spec) => match spec.sample {
                RawType::U8 => InputType::U8,
                RawType::U16 => InputType::U16,
                RawType::I16 => InputType::I16,
                RawType::F32 => InputType::F32,
            },
            Source::Vol(h) => match h.sample_type {
                SampleType::U8 => InputType::U8,
                SampleType::U16 => InputType::U16,
            },
        }
    }

    pub(super) fn raw_type(&self) -> (RawType, Endian) {
        match &self.source {
            Source::Raw(spec) => (spec.sample, spec.endian),
            Source::Vol(h) => match h.sample_type {
                SampleType::U8 => (RawType::U8, Endian::Little),
                SampleType::U16 => (RawType::U16, Endian::Little),
            },
        }
    }

    pub(super) fn read_at(&self, buf: &mut [u8], offset: u64) -> Result<(), VolumeError> {
        self.file
            .read_exact_at(buf, offset)
            .map_err(|e| match e.kind() {
                // Its length was checked when it was opened: another program
                // cut the file while it was read.
                std::io::ErrorKind::UnexpectedEof => {
                    let now = self.file.len().unwrap_or(0);
                    let needed = offset.saturating_add(buf.len() as u64);
                    std::io::Error::new(
                        e.kind(),
                        format!(
                            "shrank to {now} bytes while it was read (it needs {needed}): another program truncated it"
                        ),
                    )
                }
                _ => e,
            })
            .at(&self.path)
    }

    /// Fills `out` with `map(value)` for every voxel of planes `x0..x1`, x slowest
    /// and z fastest (`out.len() == (x1 - x0) · dims_y · dims_z`).
    pub fn read_slab<O: Copy>(
        &self,
        x0: u32,
        x1: u32,
        map: &impl Fn(f32) -> O,
        out: &mut [O],
    ) -> Result<(), VolumeError> {
        let [dx, dy, dz] = self.dims().map(u64::from);
        assert!(x0 < x1 && u64::from(x1) <= dx, "slab outside the volume");
        let plane = (dy * dz) as usize;
        assert_eq!(out.len(), (x1 - x0) as usize * plane, "slab buffer size");
        let (ty, endian) = self.raw_type();
        let size = ty.size();
        match &self.source {
            Source::Raw(RawSpec {
                order: RawOrder::ZFastest,
                skip,
                ..
            }) => {
                self.read_contiguous(*skip + u64::from(x0) * plane as u64 * size as u64, map, out)
            }
            Source::Vol(h) if h.layout == Layout::Linear => {
                let offset = h.data_offset + u64::from(x0) * plane as u64 * size as u64;
                self.read_contiguous(offset, map, out)
            }
            Source::Raw(spec) => {
                // x fastest: read whole rows in large chunks, keep x0..x1 of each.
                let row_len = dx as usize * size;
                let rows_per_chunk = (CHUNK_BYTES / row_len).max(1);
                let total_rows = (dy * dz) as usize;
                let width = (x1 - x0) as usize;
                let mut buf = vec![0u8; rows_per_chunk * row_len];
                let mut vals = vec![map(0.0); width];
                let mut row = 0;
                while row < total_rows {
                    let n = rows_per_chunk.min(total_rows - row);
                    let chunk = &mut buf[..n * row_len];
                    self.read_at(chunk, spec.skip + (row * row_len) as u64)?;
                    for (r, bytes) in chunk.chunks_exact(row_len).enumerate() {
                        let (z, y) = ((row + r) / dy as usize, (row + r) % dy as usize);
                        let picked = &bytes[x0 as usize * size..x1 as usize * size];
                        decode_into(picked, ty, endian, map, &mut vals);
                        for (i, &v) in vals.iter().enumerate() {
                            out[i * plane + y * dz as usize + z] = v;
                        }
                    }
                    row += n;
                }
                Ok(())
            }
            Source::Vol(h) => self.read_bricked_slab(h, x0, x1, map, out),
        }
    }

    fn read_contiguous<O: Copy>(
        &self,
        offset: u64,
        map: &impl Fn(f32) -> O,
        out: &mut [O],
    ) -> Result<(), VolumeError> {
        let (ty, endian) = self.raw_type();
        let per_chunk = CHUNK_BYTES / ty.size();
        let mut buf = vec![0u8; per_chunk.min(out.len()) * ty.size()];
        let mut pos = offset;
        for part in out.chunks_mut(per_chunk) {
            let bytes = &mut buf[..part.len() * ty.size()];
            self.read_at(bytes, pos)?;
            decode_into(bytes, ty, endian, map, part);
            pos += bytes.len() as u64;
        }
        Ok(())
    }

    fn read_bricked_slab<O: Copy>(
        &self,
        header: &Header,
        x0: u32,
        x1: u32,
        map: &impl Fn(f32) -> O,
        out: &mut [O],
    ) -> Result<(), VolumeError> {
        let Layout::Bricked { side } = header.layout else {
            unreachable!("linear handled by the caller")
        };
        let (ty, endian) = self.raw_type();
        let grid = BlockGrid::new(header.dims, u32::from(side));
        let [_, ny, nz] = grid.counts();
        let [_, dy, dz] = header.dims.map(|d| d as usize);
        let b = side as usize;
        let brick_bytes = b * b * b * ty.size();
        // Bricks of one (bx, by) are contiguous in the file: read them together.
        let mut buf = vec![0u8; nz as usize * brick_bytes];
        let mut vals = vec![map(0.0); nz as usize * b * b * b];
        let bx_first = grid.brick_of_voxel([x0, 0, 0])[0];
        let bx_last = grid.brick_of_voxel([x1 - 1, 0, 0])[0];
        for bx in bx_first..=bx_last {
            for by in 0..ny {
                let first = grid.index([bx, by, 0]);
                self.read_at(&mut buf, header.data_offset + first * brick_bytes as u64)?;
                decode_into(&buf, ty, endian, map, &mut vals);
                for bz in 0..nz {
                    let brick = &vals[bz as usize * b * b * b..][..b * b * b];
                    let o = grid.origin([bx, by, bz]);
                    let e = grid.extent([bx, by, bz]);
                    for lx in 0..e[0] {
                        let x = o[0] + lx;
                        if x < x0 || x >= x1 {
                            continue;
                        }
                        for ly in 0..e[1] as usize {
                            let src = &brick[(lx as usize * b + ly) * b..][..e[2] as usize];
                            let row = ((x - x0) as usize * dy + o[1] as usize + ly) * dz;
                            out[row + o[2] as usize..][..src.len()].copy_from_slice(src);
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Reports `n` more values read of this input to `job`; its
    /// [`VolumeErrorKind::Cancelled`] error when `job` is cancelled.
    pub(super) fn advance(&self, job: &Job, n: u64) -> Result<(), VolumeError> {
        job.advance(n);
        if job.is_cancelled() {
            return Err(VolumeError::new(&self.path, VolumeErrorKind::Cancelled));
        }
        Ok(())
    }

    /// Calls `visit` with `map`ped values of consecutive slabs of whole x-planes, each
    /// of at most `max_values` values (at least one plane), reporting progress to `job`
    /// and stopping with [`VolumeErrorKind::Cancelled`] when it is cancelled.
    pub fn for_each_slab<O: Copy>(
        &self,
        max_values: usize,
        map: &impl Fn(f32) -> O,
        job: &Job,
        mut visit: impl FnMut(&[O]),
    ) -> Result<(), VolumeError> {
        let [dx, dy, dz] = self.dims();
        let plane = dy as usize * dz as usize;
        let planes = (max_values / plane).clamp(1, dx as usize) as u32;
        let mut slab = Vec::new();
        let mut x0 = 0;
        while x0 < dx {
            let x1 = (x0 + planes).min(dx);
            slab.resize((x1 - x0) as usize * plane, map(0.0));
            self.read_slab(x0, x1, map, &mut slab)?;
            visit(&slab);
            self.advance(job, slab.len() as u64)?;
            x0 = x1;
        }
        Ok(())
    }

    /// Calls `visit` with `map`ped values of every voxel once, in chunks of at
    /// most `max_values` values (whole x-planes for bricked `.vol` inputs), in
    /// whatever order the file holds them: for passes the order does not
    /// matter to (ranges, histograms). Raw and linear inputs stream in file
    /// order, one pass over the file (slabs of whole x-planes read an x-fastest
    /// file whole for every slab). Progress and cancelling as
    /// [`Self::for_each_slab`].
    pub fn for_each_value<O: Copy>(
        &self,
        max_values: usize,
        map: &impl Fn(f32) -> O,
        job: &Job,
        mut visit: impl FnMut(&[O]),
    ) -> Result<(), VolumeError> {
        if let Some(Header {
            layout: Layout::Bricked { .. },
            ..
        }) = self.header()
        {
            // Bricks carry padding past the volume's edge: go through slabs.
            return self.for_each_slab(max_values, map, job, visit);
        }
        // Every stored sample is a voxel: stream them in file order.
        let start = match &self.source {
            Source::Raw(spec) => spec.skip,
            Source::Vol(h) => h.data_offset,
        };
        let total: u64 = self.dims().iter().map(|&d| u64::from(d)).product();
        let size = self.raw_type().0.size() as u64;
        let mut buf = Vec::new();
        let mut done = 0u64;
        while done < total {
            let n = (total - done).min(max_values.max(1) as u64) as usize;
            buf.resize(n, map(0.0));
            self.read_contiguous(start + done * size, map, &mut buf)?;
            visit(&buf);
            self.advance(job, n as u64)?;
            done += n as u64;
        }
        Ok(())
    }

    /// Smallest and largest finite value of the volume (NaN and ±∞ ignored: a
    /// window mapped onto the samples clamps ±∞ to its ends), in one streaming
    /// pass, with the count of values that are not finite.
    pub fn value_range(&self, job: &Job) -> Result<ValueRange, VolumeError> {
        let mut lo_hi = (f32::INFINITY, f32::NEG_INFINITY);
        let mut non_finite = 0u64;
        self.for_each_value(CHUNK_BYTES / 4, &|v| v, job, |values| {
            for &v in values {
                if !v.is_finite() {
                    non_finite += 1;
                    continue;
                }
                if v < lo_hi.0 {
                    lo_hi.0 = v;
                }
                if v > lo_hi.1 {
                    lo_hi.1 = v;
                }
            }
        })?;
        let (lo, hi) = lo_hi;
        Ok(ValueRange {
            finite: (lo <= hi).then_some((lo, hi)),
            non_finite,
        })
    }
}

/// What [`Input::value_range`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValueRange {
    /// Smallest and largest finite value; `None` when no value is finite.
    pub finite: Option<(f32, f32)>,
    /// Values that are NaN or infinite.
    pub non_finite: u64,
}
