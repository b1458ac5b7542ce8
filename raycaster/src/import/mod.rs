//! Importing the volume formats users arrive with: NRRD, NIfTI-1, MetaImage and
//! DICOM series.
//!
//! Each format module parses its header into an [`Imported`] description: sizes,
//! spacing, sample type and byte order, and where the samples are (a region of a file,
//! or a gzip/zlib stream). All three formats store the first axis fastest, so the
//! samples are read as raw x-fastest data through [`crate::io::Input`], and the
//! existing conversion machinery streams them into a `.vol` file
//! ([`Imported::input`] + [`crate::convert::convert`]) or into a volume in RAM
//! ([`open_volume_any`]). `docs/import.md` describes what is kept (axis order,
//! spacing) and what is ignored (direction cosines, origin, value scaling).
//!
//! Headers are parsed by pure functions of their bytes (`parse_header` in each
//! module), which the fuzz targets and the no-panic tests drive directly.

pub mod dicom;
mod gzip;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
mod zlib;

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::convert::{ValueMap, plan_values};
use crate::io::{Endian, Input, RawData, RawOrder, RawSpec, RawType};
use crate::job::Job;
use crate::volume::{
    Content, Format as VolFormat, Header, Layout, MAX_AXIS, Orientation, Sample, SampleType,
    ValueUnits, Volume, VolumeError,
};

/// Default limit of [`open_volume_any`] on the samples built in memory: 1 GiB.
pub const DEFAULT_IN_MEMORY_LIMIT: u64 = 1 << 30;

/// Compressed streams up to this many decompressed bytes are decompressed into
/// memory; larger ones into an anonymous temporary file (bounded memory).
pub const DECOMPRESS_IN_MEMORY_MAX: u64 = 256 << 20;

/// Bytes of a compressed stream past its samples that are decompressed to say
/// how many there are (beyond, the count is said as "at least").
const EXTRA_COUNT_MAX: u64 = 64 << 20;

/// A foreign file format this module reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportFormat {
    /// NRRD (`.nrrd` with attached data, `.nhdr` with a detached data file).
    Nrrd,
    /// NIfTI-1 (`.nii`, `.nii.gz`, or an `.hdr`/`.img` pair).
    Nifti,
    /// MetaImage (`.mha` with attached data, `.mhd` with a detached data file).
    MetaImage,
    /// A DICOM series: a folder of single-frame slices (or one `.dcm` file of it).
    Dicom,
}

impl ImportFormat {
    /// The format's usual name.
    pub fn name(self) -> &'static str {
        match self {
            ImportFormat::Nrrd => "NRRD",
            ImportFormat::Nifti => "NIfTI-1",
            ImportFormat::MetaImage => "MetaImage",
            ImportFormat::Dicom => "DICOM",
        }
    }
}

/// How the samples are encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Plain samples.
    Raw,
    /// A gzip stream (NRRD `gzip`, `.nii.gz`); concatenated members are read through.
    Gzip,
    /// A zlib stream (MetaImage `CompressedData = True`).
    Zlib,
    /// One uncompressed slice per file ([`Imported::slices`], DICOM).
    Slices,
}

/// A foreign volume file, parsed: what it holds and where its samples are.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The file the user named (the header).
    pub path: PathBuf,
    /// Its format.
    pub format: ImportFormat,
    /// Voxel counts along the file's axes, fastest first.
    pub dims: [u32; 3],
    /// Distance between voxel centres on each axis (positive; 1 where the file says
    /// nothing).
    pub spacing: [f32; 3],
    /// Sample type.
    pub sample: RawType,
    /// Byte order of multi-byte samples.
    pub endian: Endian,
    /// The file holding the samples (the header itself for attached data).
    pub data_path: PathBuf,
    /// Byte offset of the samples in `data_path` (of the compressed stream when
    /// compressed).
    pub data_offset: u64,
    /// Bytes to skip after decompression (NRRD `byte skip` of compressed data).
    pub skip_after_decode: u64,
    /// Raw or compressed.
    pub encoding: Encoding,
    /// The compressed stream's length in bytes where the header gives it
    /// (MetaImage `CompressedDataSize`): checked when the stream is read.
    pub compressed_size: Option<u64>,
    /// The linear value scaling the file declares (`value = slope · stored +
    /// intercept`): samples are converted unscaled and the scaling is kept as the
    /// volume's [`ValueUnits`], so values are given and shown in the file's units.
    pub scaling: Option<(f32, f32)>,
    /// The values' unit where the file says: "HU" for a CT scan (DICOM or
    /// MetaImage modality CT); empty when unknown.
    pub unit: String,
    /// Where the volume lies in the patient (direction cosines and origin, LPS),
    /// when the file says; its spacing is then the length of each axis step.
    pub orientation: Option<Orientation>,
    /// For [`Encoding::Slices`]: each z-slice's file and the offset of its samples,
    /// in z order.
    pub slices: Vec<(PathBuf, u64)>,
}

/// An error about one foreign file.
#[derive(Debug)]
pub struct ImportError {
    /// The file concerned.
    pub path: PathBuf,
    /// What went wrong.
    pub kind: ImportErrorKind,
}

/// What went wrong with a foreign file.
#[derive(Debug, thiserror::Error)]
pub enum ImportErrorKind {
    /// The operating system refused or failed an operation.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The header is malformed.
    #[error("invalid {format} header: {message}")]
    Header {
        /// The format being parsed.
        format: &'static str,
        /// What is wrong, naming the field.
        message: String,
    },
    /// A valid file using a feature this reader does not support.
    #[error("unsupported {format} file: {message}")]
    Unsupported {
        /// The format being parsed.
        format: &'static str,
        /// What is not supported.
        message: String,
    },
    /// The data is shorter than the header says.
    #[error(
        "{what} holds {} of samples but the header needs {expected}",
        crate::text::counted(*actual, "byte")
    )]
    WrongDataSize {
        /// Which data (the file or the decompressed stream).
        what: String,
        /// Bytes the header needs.
        expected: u64,
        /// Bytes found.
        actual: u64,
    },
    /// The data is longer than the header says: said with how much longer, and
    /// how the header would skip the surplus when it is a header before the
    /// samples.
    #[error(
        "{what} holds {}{} more than its {} of samples{hint}",
        if *at_least { "at least " } else { "" },
        crate::text::counted(*extra, "byte"),
        crate::text::counted(*expected, "byte")
    )]
    ExtraData {
        /// Which data (the file or the decompressed stream).
        what: String,
        /// Bytes the header needs.
        expected: u64,
        /// Bytes found beyond them.
        extra: u64,
        /// Whether `extra` is a lower bound (a long stream is not read to its end).
        at_least: bool,
        /// What to change in the header, in parentheses after a space (or empty).
        hint: String,
    },
    /// The detached data file the header names cannot be opened.
    #[error("cannot open the data file {}: {source}", file.display())]
    DataFile {
        /// The data file.
        file: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A gzip or zlib stream is corrupt or ends early.
    #[error("the compressed data is truncated or corrupt ({0})")]
    Compressed(std::io::Error),
    /// Bytes follow the zlib stream that holds the samples.
    #[error(
        "{}{} {} the zlib stream of the samples, which ends after {}{}",
        if *at_least { "at least " } else { "" },
        crate::text::counted(*extra, "byte"),
        if *extra == 1 { "follows" } else { "follow" },
        crate::text::counted(*stream, "byte"),
        match declared {
            Some(d) if d != stream => format!(" (CompressedDataSize says {d})"),
            _ => String::new(),
        }
    )]
    AfterStream {
        /// The stream's length in bytes.
        stream: u64,
        /// Bytes after it.
        extra: u64,
        /// Whether `extra` is a lower bound (the rest was not counted).
        at_least: bool,
        /// The length the header gives, if any.
        declared: Option<u64>,
    },
    /// The zlib stream's length is not the header's `CompressedDataSize`.
    #[error(
        "CompressedDataSize is {declared}, but the zlib stream of the samples is {} long",
        crate::text::counted(*actual, "byte")
    )]
    CompressedSize {
        /// The length the header gives.
        declared: u64,
        /// The stream's length.
        actual: u64,
    },
    /// The file's extension and first bytes match no known format.
    #[error(
        "not a known volume format (expected .vol, .nrrd, .nhdr, .nii, .nii.gz, .hdr, .mha, .mhd, or a DICOM folder or .dcm file)"
    )]
    UnknownFormat,
    /// A NRRD or MetaImage file compressed as a whole (a `.nrrd.gz`
    /// renamed): those formats compress their samples only.
    #[error(
        "the whole file is gzip-compressed: a {format} file compresses only its samples \
         ({how}); gunzip it first"
    )]
    CompressedWhole {
        /// The format its name gives.
        format: &'static str,
        /// How the format compresses its samples.
        how: &'static str,
    },
    /// Samples the header calls raw that are gzip-compressed.
    #[error(
        "the samples are gzip-compressed but the header says they are raw: write {how} in \
         the header, or gunzip the data"
    )]
    CompressedRaw {
        /// The header field that says the samples are compressed.
        how: &'static str,
    },
    /// A file opened as a DICOM slice (a `.dcm` file) is not DICOM.
    #[error("not a DICOM file (it has no DICM marker at byte 128)")]
    NotDicom,
    /// A folder (opened as a DICOM series) holds no DICOM file.
    #[error("{}", no_dicom_files_message(*files, *folders))]
    NoDicomFiles {
        /// The plain files it holds (none with the DICM marker).
        files: usize,
        /// The folders it holds.
        folders: usize,
    },
    /// The volume is too large to be built in memory.
    #[error(
        "{samples} bytes of samples exceed the {limit}-byte limit for opening foreign files in memory; \
         convert it first: volgen convert {file} -o {stem}.vol"
    )]
    TooLargeForMemory {
        /// Bytes of samples the volume needs.
        samples: u64,
        /// The limit.
        limit: u64,
        /// The file, for the hint.
        file: String,
        /// Suggested output name, for the hint.
        stem: String,
    },
    /// Reading samples or building the volume failed.
    #[error("{0}")]
    Volume(#[from] VolumeError),
}

/// [`ImportErrorKind::NoDicomFiles`]'s text.
fn no_dicom_files_message(files: usize, folders: usize) -> String {
    let held = match files {
        // Series in subfolders (a study's folder): not searched.
        0 if folders > 0 => format!(
            "it holds no files, only {} (subfolders are not searched: name the series' own folder)",
            crate::text::counted(folders as u64, "folder")
        ),
        0 => "it holds no files".to_string(),
        1 => "its one file is not DICOM (it has no DICM marker)".to_string(),
        n => format!("none of its {n} files is DICOM (none has the DICM marker)"),
    };
    format!("a folder opens as a DICOM series, and {held}")
}

impl std::fmt::Display for ImportError {
    /// `path: what`, said once: a volume error already names its own file.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.kind {
            ImportErrorKind::Volume(v) => write!(f, "{v}"),
            kind => write!(f, "{}: {kind}", self.path.display()),
        }
    }
}

impl std::error::Error for ImportError {}

impl ImportError {
    /// An error about `path`.
    pub fn new(path: &Path, kind: impl Into<ImportErrorKind>) -> Self {
        ImportError {
            path: path.to_path_buf(),
            kind: kind.into(),
        }
    }
}

/// A header problem of `format`, for the parsers.
pub(crate) fn header_error(format: ImportFormat, message: impl Into<String>) -> ImportErrorKind {
    ImportErrorKind::Header {
        format: format.name(),
        message: message.into(),
    }
}

/// An unsupported feature of `format`, for the parsers.
pub(crate) fn unsupported(format: ImportFormat, message: impl Into<String>) -> ImportErrorKind {
    ImportErrorKind::Unsupported {
        format: format.name(),
        message: message.into(),
    }
}

/// Checks sizes parsed from a header: 1..=[`MAX_AXIS`] each.
pub(crate) fn check_dims(format: ImportFormat, dims: &[u64]) -> Result<[u32; 3], ImportErrorKind> {
    let mut out = [1u32; 3];
    for (i, &d) in dims.iter().enumerate() {
        if d == 0 || d > u64::from(MAX_AXIS) {
            return Err(header_error(
                format,
                format!("size {d} on axis {i} is outside 1..={MAX_AXIS}"),
            ));
        }
        out[i] = d as u32;
    }
    Ok(out)
}

/// Checks one spacing value: finite and non-zero; its magnitude is kept (a negative
/// spacing only says the axis points the other way, which we do not apply).
pub(crate) fn check_spacing(
    format: ImportFormat,
    axis: usize,
    s: f64,
) -> Result<f32, ImportErrorKind> {
    let a = s.abs() as f32;
    if a.is_finite() && a > 0.0 {
        Ok(a)
    } else {
        Err(header_error(
            format,
            format!(
                "spacing {} on axis {axis} must be a finite non-zero number of the ±3.4e38 a spacing holds",
                crate::volume::number_text(s)
            ),
        ))
    }
}

/// The first `max` bytes of the text header at `path` (at most: the header's end is
/// found by its parser).
pub(crate) fn read_text_header(path: &Path, max: usize) -> Result<Vec<u8>, ImportError> {
    let mut bytes = Vec::new();
    crate::files::open_regular(path)
        .and_then(|f| f.take(max as u64).read_to_end(&mut bytes))
        .map_err(|e| ImportError::new(path, e))?;
    Ok(bytes)
}

/// Where raw samples start when a header says they end the data file (NRRD
/// `byte skip: -1`, MetaImage `HeaderSize = -1`): `sample_bytes` before its end, not
/// before `not_before` (the end of what precedes the data in that file).
/// `header` is the file that names `data_path`, for the error when that is
/// missing or no regular file.
pub(crate) fn data_at_end(
    header: &Path,
    data_path: &Path,
    sample_bytes: u64,
    not_before: u64,
) -> Result<u64, ImportError> {
    // (A device's length is 0: said as what it is, not as a short file.)
    let len = crate::files::check_regular(data_path)
        .and_then(|()| std::fs::metadata(data_path))
        .map_err(|source| data_file_error(header, data_path, source))?
        .len();
    len.checked_sub(sample_bytes)
        .filter(|&start| start >= not_before)
        .ok_or_else(|| {
            ImportError::new(
                data_path,
                ImportErrorKind::WrongDataSize {
                    what: "the data file".into(),
                    expected: sample_bytes,
                    actual: len.saturating_sub(not_before),
                },
            )
        })
}

/// [`ImportErrorKind::DataFile`] about `header`'s data file `file`.
pub(crate) fn data_file_error(header: &Path, file: &Path, source: std::io::Error) -> ImportError {
    let file = file.to_path_buf();
    ImportError::new(header, ImportErrorKind::DataFile { file, source })
}

/// The file name endings of the foreign formats (lower case), and their formats.
pub const FOREIGN_EXTENSIONS: [(&str, ImportFormat); 8] = [
    (".nrrd", ImportFormat::Nrrd),
    (".nhdr", ImportFormat::Nrrd),
    (".nii", ImportFormat::Nifti),
    (".nii.gz", ImportFormat::Nifti),
    (".hdr", ImportFormat::Nifti),
    (".mha", ImportFormat::MetaImage),
    (".mhd", ImportFormat::MetaImage),
    (".dcm", ImportFormat::Dicom),
];

/// Which format `path` is, by extension, then by its first bytes; `None` for `.vol`
/// files and anything unknown. A folder is taken for a DICOM series.
pub fn detect(path: &Path) -> Option<ImportFormat> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if path.is_dir() {
        // (A folder named like a volume file is said to be a folder where it
        // is opened as one, not searched for DICOM files.)
        return (!name.ends_with(".vol")).then_some(ImportFormat::Dicom);
    }
    if let Some((_, f)) = FOREIGN_EXTENSIONS
        .iter()
        .find(|(ext, _)| name.ends_with(ext))
    {
        return Some(*f);
    }
    if name.ends_with(".vol") {
        return None;
    }
    let mut head = [0u8; 348];
    // Never File::open here: a named pipe would block; open_regular refuses it.
    let n = crate::files::open_regular(path)
        .and_then(|f| f.take(348).read(&mut head))
        .unwrap_or(0);
    let head = &head[..n];
    if head.starts_with(b"NRRD000") {
        Some(ImportFormat::Nrrd)
    } else if head.len() == 348 && nifti::parse_header(head).is_ok() {
        Some(ImportFormat::Nifti)
    } else if metaimage::parse_header(head).is_ok() {
        Some(ImportFormat::MetaImage)
    } else if head.len() >= 132 && &head[128..132] == b"DICM" {
        Some(ImportFormat::Dicom)
    } else {
        None
    }
}

/// The largest ratio between a file's largest and smallest voxel spacing that is
/// read: beyond it the header is broken (pixdim 1e-45), and rendering at the
/// smallest spacing's step would take practically forever.
pub const MAX_SPACING_RATIO: f32 = 1e4;

/// Refuses spacings whose largest is more than [`MAX_SPACING_RATIO`] times the
/// smallest.
pub(crate) fn check_spacing_ratio(
    format: ImportFormat,
    spacing: [f32; 3],
) -> Result<(), ImportErrorKind> {
    let Some(ratio) = lopsided_spacing(spacing) else {
        return Ok(());
    };
    let [x, y, z] = spacing.map(crate::volume::number_text);
    Err(header_error(
        format,
        format!(
            "spacing {x} x {y} x {z}: the largest is {ratio:.3e} times the smallest (at most {MAX_SPACING_RATIO:.0e} is read); the header's spacing is broken. Convert with `volgen convert --spacing` to override it"
        ),
    ))
}

/// How many times the smallest of `spacing` its largest is, when that is more
/// than [`MAX_SPACING_RATIO`] (or not a number); `None` for a spacing within
/// it. Foreign files are refused beyond it, and `volgen` writes no file
/// beyond it (the renderer would refuse the file's rays as too long).
pub fn lopsided_spacing(spacing: [f32; 3]) -> Option<f64> {
    let lo = spacing.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = spacing.iter().copied().fold(0.0, f32::max);
    // Written so that NaN fails too.
    if hi / lo <= MAX_SPACING_RATIO {
        None
    } else {
        Some(f64::from(hi) / f64::from(lo))
    }
}

/// The files a volume at `path` is read from, for commands that refuse to
/// write over their inputs: `path` itself and, for a NRRD, MetaImage or NIfTI
/// header, its detached data file. (A DICOM series' slices, or the data of a
/// header that does not parse, are not looked for: its error is said where it
/// is opened.)
pub fn volume_files(path: &Path) -> Vec<PathBuf> {
    match detect(path) {
        Some(ImportFormat::Nrrd | ImportFormat::Nifti | ImportFormat::MetaImage) => {
            if let Ok(imported) = open_unchecked(path) {
                return imported.files().map(Path::to_path_buf).collect();
            }
            vec![path.to_path_buf()]
        }
        _ => vec![path.to_path_buf()],
    }
}

/// Why a command that reads `.vol` files only cannot take `path`: a foreign
/// volume (NRRD, NIfTI-1, MetaImage, a DICOM series), with the conversion
/// that makes one. `None` for anything else (a `.vol` file, or a file whose
/// own open says what is wrong with it).
pub fn vol_only_problem(path: &Path) -> Option<String> {
    let format = detect(path)?;
    // (Any folder is taken for a DICOM series: an empty one was called a
    // DICOM volume.)
    if path.is_dir() {
        return Some(format!(
            "is a folder, and this command reads .vol files (a DICOM series folder converts: `volgen convert {} -o NAME.vol`)",
            path.display()
        ));
    }
    Some(format!(
        "is a {} volume, and this command reads .vol files: `volgen convert {} -o NAME.vol` makes one",
        format.name(),
        path.display()
    ))
}

/// Parses the foreign file at `path` (any supported format).
pub fn open(path: &Path) -> Result<Imported, ImportError> {
    open_unchecked(path).and_then(|imported| {
        check_spacing_ratio(imported.format, imported.spacing)
            .map_err(|e| ImportError::new(path, e))?;
        Ok(imported)
    })
}

/// Checks that the values an integer sample type's scaling gives (`slope ·
/// stored + intercept`) stay within f32, the values the tools take and say
/// (`--domain`, `--window`, the slices' windows): a slope of 3e38 made
/// every value but 0 infinite there.
fn check_value_range(imported: &Imported) -> Result<(), ImportErrorKind> {
    let Some((slope, intercept)) = imported.scaling else {
        return Ok(());
    };
    let stored: [f64; 2] = match imported.sample {
        RawType::U8 => [0.0, 255.0],
        RawType::U16 => [0.0, 65535.0],
        RawType::I16 => [-32768.0, 32767.0],
        // (Float samples are windowed onto u16 by their own values.)
        RawType::F32 => return Ok(()),
    };
    let units = imported.units();
    for s in stored {
        let value = units.value(s);
        if value.is_nan() || value.abs() > f64::from(f32::MAX) {
            return Err(header_error(
                imported.format,
                format!(
                    "the value scaling (slope {slope:e}, intercept {intercept:e}) takes stored {} value {s} to {value:e}, beyond the ±3.4e38 values are read in",
                    imported.sample
                ),
            ));
        }
    }
    Ok(())
}

/// Parses `path` without checking the spacing ratio (`volgen convert --spacing`
/// replaces a broken spacing).
pub fn open_unchecked(path: &Path) -> Result<Imported, ImportError> {
    let format = detect(path);
    let how = match format {
        Some(ImportFormat::Nrrd) => Some("`encoding: gzip` in its header"),
        Some(ImportFormat::MetaImage) => Some("`CompressedData = True` in its header"),
        _ => None,
    };
    if let (Some(format), Some(how)) = (format, how)
        // (Unreadable files are not: their error comes from the reader.)
        && gzip::gzip_magic_at(path, 0).unwrap_or(false)
    {
        let kind = ImportErrorKind::CompressedWhole {
            format: format.name(),
            how,
        };
        return Err(ImportError::new(path, kind));
    }
    let imported = match format {
        Some(ImportFormat::Nrrd) => nrrd::open(path),
        Some(ImportFormat::Nifti) => nifti::open(path),
        Some(ImportFormat::MetaImage) => metaimage::open(path),
        Some(ImportFormat::Dicom) => dicom::open(path),
        None => Err(ImportError::new(path, ImportErrorKind::UnknownFormat)),
    }?;
    check_value_range(&imported).map_err(|e| ImportError::new(path, e))?;
    Ok(imported)
}

impl Imported {
    /// Number of voxels.
    pub fn voxels(&self) -> u64 {
        self.dims.iter().map(|&d| u64::from(d)).product()
    }

    /// Bytes of samples the file holds (decompressed).
    pub fn sample_bytes(&self) -> u64 {
        self.voxels() * self.sample.size() as u64
    }

    /// The sample type a `.vol` stores this file's values in by default (u8 stays u8;
    /// u16, i16 and f32 become u16).
    pub fn default_sample_type(&self) -> SampleType {
        match self.sample {
            RawType::U8 => SampleType::U8,
            _ => SampleType::U16,
        }
    }

    /// The samples as a slab-wise [`Input`]. Uncompressed data is read in place with
    /// positioned reads; compressed data is decompressed first, into memory when it
    /// is at most `memory_max` bytes, otherwise into an anonymous temporary file in
    /// `scratch_dir` (default: the system's temporary directory).
    pub fn input(&self, scratch_dir: Option<&Path>, memory_max: u64) -> Result<Input, ImportError> {
        self.input_with(scratch_dir, memory_max, &Job::silent())
    }

    /// [`Self::input`], reporting decompressed (or gathered) bytes to `job` and
    /// stopping with an error when it is cancelled.
    pub fn input_with(
        &self,
        scratch_dir: Option<&Path>,
        memory_max: u64,
        job: &Job,
    ) -> Result<Input, ImportError> {
        let input = self.unscaled_input(scratch_dir, memory_max, job)?;
        Ok(input
            .with_units(self.units())
            .with_orientation(self.orientation.clone())
            .also_reading(self.files().map(Path::to_path_buf).collect()))
    }

    /// Every file the volume is read from: the header, its detached data file,
    /// a series' slices.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        [self.path.as_path(), self.data_path.as_path()]
            .into_iter()
            .chain(self.slices.iter().map(|(p, _)| p.as_path()))
    }

    /// What the file's stored values mean: its rescale slope and intercept (or
    /// none) and its unit.
    pub fn units(&self) -> ValueUnits {
        let (slope, intercept) = self.scaling.unwrap_or((1.0, 0.0));
        ValueUnits {
            scale: f64::from(slope),
            offset: f64::from(intercept),
            unit: self.unit.clone(),
        }
    }

    fn unscaled_input(
        &self,
        scratch_dir: Option<&Path>,
        memory_max: u64,
        job: &Job,
    ) -> Result<Input, ImportError> {
        let spec = RawSpec {
            dims: self.dims,
            sample: self.sample,
            endian: self.endian,
            skip: 0,
            order: RawOrder::XFastest,
        };
        let at_data = |e: std::io::Error| ImportError::new(&self.data_path, e);
        if self.encoding == Encoding::Slices {
            let data = self.gather_slices(scratch_dir, memory_max, job)?;
            return Input::from_raw_data(&self.path, data, spec, Some(self.spacing))
                .map_err(|e| ImportError::new(&self.path, e));
        }
        let file = crate::files::open_regular(&self.data_path)
            .map_err(|source| data_file_error(&self.path, &self.data_path, source))?;
        let data = match self.encoding {
            Encoding::Raw => {
                self.check_raw_size(file.metadata().map_err(at_data)?.len())?;
                let spec = RawSpec {
                    skip: self.data_offset,
                    ..spec
                };
                return Input::from_raw_data(
                    &self.path,
                    RawData::File(file),
                    spec,
                    Some(self.spacing),
                )
                .map_err(|e| ImportError::new(&self.path, e));
            }
            _ => self.decompress(file, scratch_dir, memory_max, job)?,
        };
        Input::from_raw_data(&self.path, data, spec, Some(self.spacing))
            .map_err(|e| ImportError::new(&self.path, e))
    }

    /// Refuses uncompressed samples in a data file of `len` bytes that does
    /// not hold exactly what the header says (truncated, or longer).
    fn check_raw_size(&self, len: u64) -> Result<(), ImportError> {
        let actual = len.saturating_sub(self.data_offset);
        let expected = self.sample_bytes();
        if actual == expected {
            return Ok(());
        }
        // Compressed samples the header calls raw: their size says nothing.
        let how = match self.format {
            ImportFormat::Nrrd => Some("`encoding: gzip`"),
            ImportFormat::MetaImage => Some("`CompressedData = True`"),
            _ => None,
        };
        if let Some(how) = how
            && gzip::gzip_magic_at(&self.data_path, self.data_offset).unwrap_or(false)
        {
            let kind = ImportErrorKind::CompressedRaw { how };
            return Err(ImportError::new(&self.data_path, kind));
        }
        let what = match self.data_offset {
            0 => "the data file".into(),
            start => format!(
                "the data file ({}, the samples from byte {start})",
                crate::text::counted(len, "byte")
            ),
        };
        let kind = if actual > expected {
            let extra = actual - expected;
            ImportErrorKind::ExtraData {
                what,
                expected,
                extra,
                at_least: false,
                hint: self.extra_data_hint(extra, false),
            }
        } else {
            ImportErrorKind::WrongDataSize {
                what,
                expected,
                actual,
            }
        };
        Err(ImportError::new(&self.data_path, kind))
    }

    /// What [`ImportErrorKind::ExtraData`] suggests for samples followed by
    /// `extra` bytes more than the header needs (`at_least`: at least that
    /// many): the header field that skips them when they are a header before
    /// the samples (MetaImage's `HeaderSize = -1` and NRRD's `byte skip: -1`
    /// read the samples that end the file), else a question about the sizes.
    fn extra_data_hint(&self, extra: u64, at_least: bool) -> String {
        let detached = self.data_path != self.path;
        let (offset, after_decode) = (self.data_offset, self.skip_after_decode);
        let sizes = " (are the header's sizes and sample type right?)".to_string();
        match (self.format, self.encoding) {
            (ImportFormat::Nrrd, Encoding::Raw) if offset == 0 => format!(
                " (a header before them? `byte skip: {extra}` skips it; `byte skip: -1` reads the samples that end the file)"
            ),
            (ImportFormat::Nrrd, Encoding::Raw) => {
                " (a header before them? `byte skip: -1` reads the samples that end the file)"
                    .into()
            }
            (ImportFormat::Nrrd, Encoding::Gzip) if !at_least => format!(
                " (a header before them? `byte skip: {}` skips it)",
                after_decode + extra
            ),
            (ImportFormat::MetaImage, Encoding::Raw) if detached => format!(
                " (a header before them? `HeaderSize = {}` skips it; `HeaderSize = -1` reads the samples that end the file)",
                offset + extra
            ),
            (ImportFormat::Nifti, Encoding::Raw) => format!(
                " (is vox_offset {offset} right? the samples that end the file start at byte {})",
                offset + extra
            ),
            (ImportFormat::Nifti, Encoding::Gzip) if !at_least => format!(
                " (is vox_offset {after_decode} right? the samples that end the stream start at byte {})",
                after_decode + extra
            ),
            _ => sizes,
        }
    }

    /// Decompresses the stream after `data_offset`, drops `skip_after_decode` bytes
    /// and checks that exactly the samples remain.
    fn decompress(
        &self,
        mut file: File,
        scratch_dir: Option<&Path>,
        memory_max: u64,
        job: &Job,
    ) -> Result<RawData, ImportError> {
        use std::io::{Seek, SeekFrom};
        let at_data = |e: std::io::Error| ImportError::new(&self.data_path, e);
        file.seek(SeekFrom::Start(self.data_offset))
            .map_err(at_data)?;
        let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
        // MetaImage's zlib data may come with a gzip header, as ITK reads it.
        let gzip = self.encoding == Encoding::Gzip
            || std::io::BufRead::fill_buf(&mut reader)
                .map_err(at_data)?
                .starts_with(&[0x1f, 0x8b]);
        let mut stream: Box<dyn Read> = if gzip {
            Box::new(gzip::GzipMembers::new(reader))
        } else {
            Box::new(zlib::ZlibData::new(reader, self.compressed_size))
        };
        let compressed = |e: std::io::Error| {
            // The stream's own findings are said as they are, not as corrupt data.
            let kind = if e.get_ref().is_some_and(|i| i.is::<ImportErrorKind>()) {
                match e.into_inner().map(|i| i.downcast::<ImportErrorKind>()) {
                    Some(Ok(kind)) => *kind,
                    _ => unreachable!("checked to be an ImportErrorKind"),
                }
            } else {
                ImportErrorKind::Compressed(e)
            };
            ImportError::new(&self.data_path, kind)
        };
        let skipped = std::io::copy(
            &mut (&mut stream).take(self.skip_after_decode),
            &mut std::io::sink(),
        )
        .map_err(compressed)?;
        let expected = self.sample_bytes();
        let (data, got) = self.collect(&mut stream, scratch_dir, memory_max, job, &compressed)?;
        if skipped == self.skip_after_decode && got > expected {
            // How much longer, up to a bound: the rest is decompressed for
            // the count only.
            let more = std::io::copy(
                &mut (&mut stream).take(EXTRA_COUNT_MAX),
                &mut std::io::sink(),
            )
            .map_err(compressed)?;
            let extra = got - expected + more;
            let at_least = more == EXTRA_COUNT_MAX;
            return Err(ImportError::new(
                &self.data_path,
                ImportErrorKind::ExtraData {
                    what: "the decompressed stream".into(),
                    expected,
                    extra,
                    at_least,
                    hint: self.extra_data_hint(extra, at_least),
                },
            ));
        }
        if skipped < self.skip_after_decode || got != expected {
            return Err(ImportError::new(
                &self.data_path,
                ImportErrorKind::WrongDataSize {
                    what: "the decompressed stream".into(),
                    expected,
                    actual: if skipped < self.skip_after_decode {
                        0
                    } else {
                        got
                    },
                },
            ));
        }
        Ok(data)
    }

    /// Reads up to one byte more than the samples from `stream` into memory (at most
    /// `memory_max` bytes) or an anonymous temporary file; returns the bytes read.
    fn collect(
        &self,
        stream: &mut dyn Read,
        scratch_dir: Option<&Path>,
        memory_max: u64,
        job: &Job,
        read_error: &dyn Fn(std::io::Error) -> ImportError,
    ) -> Result<(RawData, u64), ImportError> {
        let expected = self.sample_bytes();
        let mut stream = Reported { inner: stream, job };
        // A cancelled job is said as such, not as corrupt data.
        let failed = |e: std::io::Error| {
            if job.is_cancelled() {
                let cancelled =
                    VolumeError::new(&self.path, crate::volume::VolumeErrorKind::Cancelled);
                ImportError::new(&self.path, cancelled)
            } else {
                read_error(e)
            }
        };
        // One byte more than needed: a longer stream is an error too.
        let mut limited = (&mut stream).take(expected + 1);
        if expected <= memory_max {
            let mut buf = Vec::with_capacity(expected as usize);
            limited.read_to_end(&mut buf).map_err(failed)?;
            let got = buf.len() as u64;
            Ok((RawData::Memory(buf), got))
        } else {
            let dir = scratch_dir.map_or_else(std::env::temp_dir, Path::to_path_buf);
            // A write that fails is the scratch folder's, not the input's
            // data: said as such (a full disk read as "truncated or
            // corrupt"), naming both.
            let scratch = |e: std::io::Error| {
                let said = format!(
                    "its decompressed samples go to a temporary file in {} first: {e}",
                    dir.display()
                );
                ImportError::new(&self.data_path, std::io::Error::new(e.kind(), said))
            };
            // (A folder whose free space cannot be read is tried all the same.)
            if let Err(e) = crate::files::check_free_space_in(&dir, expected)
                && e.kind() == std::io::ErrorKind::StorageFull
            {
                return Err(scratch(e));
            }
            let mut tmp = tempfile::tempfile_in(&dir).map_err(|e| ImportError::new(&dir, e))?;
            let mut got = 0u64;
            let mut buf = vec![0u8; 1 << 20];
            loop {
                let n = match limited.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(failed(e)),
                };
                tmp.write_all(&buf[..n]).map_err(scratch)?;
                got += n as u64;
            }
            tmp.flush().map_err(scratch)?;
            Ok((RawData::File(tmp), got))
        }
    }

    /// Concatenates the slices' samples (each checked to be whole first). Slices
    /// are opened one at a time as the stream reaches them, and only their pixel
    /// data's byte range is read: a series of thousands of slices stays under the
    /// open-file limit.
    fn gather_slices(
        &self,
        scratch_dir: Option<&Path>,
        memory_max: u64,
        job: &Job,
    ) -> Result<RawData, ImportError> {
        let per_slice = self.sample_bytes() / self.slices.len().max(1) as u64;
        for (path, offset) in &self.slices {
            let at = |e: std::io::Error| ImportError::new(path, e);
            crate::files::check_regular(path).map_err(at)?;
            let len = std::fs::metadata(path).map_err(at)?.len();
            if len.saturating_sub(*offset) < per_slice {
                return Err(ImportError::new(
                    path,
                    ImportErrorKind::WrongDataSize {
                        what: "the slice".into(),
                        expected: per_slice,
                        actual: len.saturating_sub(*offset),
                    },
                ));
            }
        }
        let mut stream = SliceStream {
            slices: &self.slices,
            per_slice,
            next: 0,
            current: None,
        };
        let read_error = |e: std::io::Error| ImportError::new(&self.path, e);
        let (data, got) = self.collect(&mut stream, scratch_dir, memory_max, job, &read_error)?;
        if got != self.sample_bytes() {
            return Err(ImportError::new(
                &self.path,
                ImportErrorKind::WrongDataSize {
                    what: "the series".into(),
                    expected: self.sample_bytes(),
                    actual: got,
                },
            ));
        }
        Ok(data)
    }
}

/// A stream that reports the bytes read to a job and fails once it is cancelled.
struct Reported<'a, 'j> {
    inner: &'a mut dyn Read,
    job: &'a Job<'j>,
}

impl Read for Reported<'_, '_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.job.is_cancelled() {
            // Not ErrorKind::Interrupted: read_to_end and io::copy retry on that.
            return Err(std::io::Error::other("cancelled; nothing was written"));
        }
        let n = self.inner.read(buf)?;
        self.job.advance(n as u64);
        Ok(n)
    }
}

/// The pixel data of a series' slices as one stream, holding one slice file open at
/// a time.
struct SliceStream<'a> {
    slices: &'a [(PathBuf, u64)],
    per_slice: u64,
    next: usize,
    current: Option<std::io::Take<File>>,
}

impl Read for SliceStream<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        use std::io::{Seek, SeekFrom};
        loop {
            if let Some(r) = &mut self.current {
                let n = r.read(buf)?;
                if n > 0 || buf.is_empty() {
                    return Ok(n);
                }
                self.current = None;
            }
            let Some((path, offset)) = self.slices.get(self.next) else {
                return Ok(0);
            };
            self.next += 1;
            let name = |e: std::io::Error| {
                std::io::Error::new(e.kind(), format!("{}: {e}", path.display()))
            };
            let mut f = crate::files::open_regular(path).map_err(name)?;
            f.seek(SeekFrom::Start(*offset)).map_err(name)?;
            self.current = Some(f.take(self.per_slice));
        }
    }
}

/// Opens any volume file: a `.vol` file is mapped as usual; a foreign file (NRRD,
/// NIfTI-1, MetaImage) is converted into a linear volume in RAM when its stored
/// samples take at most `limit` bytes, and otherwise refused with an error that
/// says how to convert it with `volgen convert`.
///
/// Values are stored as [`crate::convert::plan_values`] chooses for a conversion
/// without options (u8 and u16 copied, i16 offset by 32768, f32 mapped from its
/// min..max onto u16).
pub fn open_volume_any(path: &Path, limit: u64) -> Result<Volume, ImportError> {
    let Some(_) = detect(path) else {
        return Volume::open(path).map_err(|e| ImportError::new(path, e));
    };
    let imported = open(path)?;
    imported.to_volume(limit)
}

impl Imported {
    /// Builds the volume in RAM (linear layout), refusing volumes whose stored
    /// samples exceed `limit` bytes.
    pub fn to_volume(&self, limit: u64) -> Result<Volume, ImportError> {
        self.to_volume_with(limit, &Job::silent())
    }

    /// [`Self::to_volume`], reporting the bytes decompressed (or gathered from
    /// slices) to `job`: up to [`Self::sample_bytes`] in all; raw files report
    /// nothing (they are read in one pass at disk speed).
    pub fn to_volume_with(&self, limit: u64, job: &Job) -> Result<Volume, ImportError> {
        Ok(self.to_volume_noting(limit, job)?.0)
    }

    /// [`Self::to_volume_with`], and the warning its values call for: how many
    /// were NaN or infinite (stored as the window's ends, as `volgen convert`
    /// stores them; [`crate::convert::non_finite_warning`]), `None` when all
    /// were finite.
    pub fn to_volume_noting(
        &self,
        limit: u64,
        job: &Job,
    ) -> Result<(Volume, Option<String>), ImportError> {
        // A data file that is missing or no regular file (a device's length
        // is 0), or a truncated one, is said as such before its declared size
        // is weighed against the limit (what is wrong is the file).
        if self.encoding != Encoding::Slices {
            crate::files::check_regular(&self.data_path)
                .map_err(|source| data_file_error(&self.path, &self.data_path, source))?;
        }
        if self.encoding == Encoding::Raw
            && let Ok(meta) = std::fs::metadata(&self.data_path)
        {
            self.check_raw_size(meta.len())?;
        }
        let sample_type = self.default_sample_type();
        let samples = self.voxels() * sample_type.size();
        if samples > limit {
            let file = self.path.display().to_string();
            let stem = self
                .path
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default();
            let stem = stem.split('.').next().unwrap_or("volume").to_string();
            return Err(ImportError::new(
                &self.path,
                ImportErrorKind::TooLargeForMemory {
                    samples,
                    limit,
                    file,
                    stem,
                },
            ));
        }
        let input = self.input_with(None, u64::MAX, job)?;
        let units = input.units().clone();
        let (sample_type, values, non_finite) =
            plan_values(&input, Some(sample_type), None, &Job::silent())
                .map_err(|e| ImportError::new(&self.path, e))?;
        let header = Header::new(
            self.dims,
            self.spacing,
            Layout::Linear,
            sample_type,
            Content::Scalar,
            VolFormat::Extended,
        )
        .with_units(Some(values.output_units(&units, sample_type)))
        .with_orientation(self.orientation.clone());
        let volume = match sample_type {
            SampleType::U8 => build::<u8>(&input, &header, values),
            SampleType::U16 => build::<u16>(&input, &header, values),
        };
        let volume = volume.map_err(|e| ImportError::new(&self.path, e))?;
        let warning = non_finite
            .filter(|&n| n > 0)
            .map(|n| crate::convert::non_finite_warning(&self.path, n, self.voxels()));
        Ok((volume, warning))
    }
}

fn build<T: Sample>(
    input: &Input,
    header: &Header,
    values: ValueMap,
) -> Result<Volume, VolumeError> {
    let map = values.to_sample::<T>();
    let dx = header.dims[0];
    Volume::from_fill::<T>(input.path(), header, |samples| {
        input.read_slab(0, dx, &map, samples)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spacing_beyond_f32_is_named_in_scientific_notation() {
        let e = check_spacing(ImportFormat::Nrrd, 0, 1e300)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("spacing 1e300 on axis 0 must be a finite non-zero number"),
            "{e}"
        );
        assert!(check_spacing(ImportFormat::Nrrd, 1, -0.5).unwrap() == 0.5);
        let e = check_spacing(ImportFormat::Nrrd, 2, 0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("spacing 0 on axis 2"), "{e}");
    }
}
