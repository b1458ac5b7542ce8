//! Errors of opening, reading and writing volume files: each names the file.

use std::path::{Path, PathBuf};

use super::header::HeaderError;

impl VolumeErrorKind {
    /// The message without its advice to convert the file, for where that is
    /// not the way out (a conversion saying what it rescues, a sidecar that
    /// `volgen pyramid` writes again).
    pub fn without_advice(&self) -> String {
        match *self {
            VolumeErrorKind::PyramidCutOff {
                part,
                end,
                file_len,
            } => format!(
                "the resolution pyramid is cut off in {part} ({})",
                cut_off_at(end, file_len)
            ),
            VolumeErrorKind::RangesCutOff { end, file_len } => format!(
                "the value-range table after the samples is cut off ({})",
                cut_off_at(end, file_len)
            ),
            ref other => other.to_string(),
        }
    }
}

/// Where a block cut off ends and what the file holds.
fn cut_off_at(end: u64, file_len: u64) -> String {
    format!("it ends at byte {end}, the file has {file_len} bytes")
}

/// A header error as said to users: "invalid header: …", except for a file
/// that ends before its samples or blocks do (the header is fine there).
fn header_text(e: &HeaderError) -> String {
    if e.is_cut_short() {
        e.to_string()
    } else {
        format!("invalid header: {e}")
    }
}

/// An error about one volume file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct VolumeError {
    /// The file concerned.
    pub path: PathBuf,
    /// What went wrong.
    pub kind: VolumeErrorKind,
}

/// What went wrong with a volume file.
#[derive(Debug, thiserror::Error)]
pub enum VolumeErrorKind {
    /// The operating system refused or failed an operation.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The header is invalid or does not match the file (a file cut short is
    /// said as such, not as an invalid header).
    #[error("{}", header_text(.0))]
    Header(#[from] HeaderError),
    /// A file not named `.vol` whose first bytes are no `.vol` header either.
    #[error(
        "not a volume file: its name ends in none of .vol, .nrrd, .nhdr, .nii, .nii.gz, .hdr, .mha, .mhd, .dcm, and its first bytes are no .vol header: {0} (headerless raw samples convert with `volgen convert FILE --raw XxYxZ -o NAME.vol`)"
    )]
    NotAVolume(HeaderError),
    /// A label volume was asked for and the file is a foreign one (a
    /// segmentation in NRRD, NIfTI, ...), which is imported as values.
    #[error(
        "label volumes are .vol files of object ids; `volgen convert {file} --labels -o NAME.labels.vol` makes one of this segmentation"
    )]
    ForeignLabels {
        /// The file, as the command names it.
        file: String,
    },
    /// A label volume was asked for and the file holds values.
    #[error(
        "holds values, not labels: a label volume holds object ids (`volgen convert FILE --labels -o NAME.labels.vol` makes one of a segmentation; `volgen generate --scene shells` writes one beside its volume)"
    )]
    ValuesNotLabels,
    /// A file not named for a compressed format that holds gzip data.
    #[error(
        "not a volume file: it holds gzip-compressed data; gunzip it first (.vol, NRRD and MetaImage files are never compressed as a whole; a compressed NIfTI-1 file is named .nii.gz)"
    )]
    GzipUnnamed,
    /// The embedded value-range table is unreadable.
    #[error("the value-range table after the samples is corrupt")]
    CorruptRanges,
    /// The embedded value-range table does not hold a brick's values.
    #[error(
        "the value-range table after the samples disagrees with them (brick {brick:?}: the table says {}..{}, its values span {}..{}): the table is damaged, and bricks it calls empty would not be drawn; `volgen convert` writes the samples into a new file with a new table",
        stored[0], stored[1], values[0], values[1]
    )]
    RangesDisagree {
        /// The brick, in the table's grid.
        brick: [u32; 3],
        /// The table's range.
        stored: [u16; 2],
        /// The samples' range.
        values: [u16; 2],
    },
    /// The file ends inside its embedded value-range table.
    #[error(
        "the value-range table after the samples is cut off: {} (an incomplete copy?); the samples before it are whole: `volgen convert` copies them into a new file",
        cut_off_at(*end, *file_len)
    )]
    RangesCutOff {
        /// Where the table ends.
        end: u64,
        /// The file's length.
        file_len: u64,
    },
    /// The resolution pyramid (embedded or sidecar) is inconsistent.
    #[error("the resolution pyramid is corrupt: {0}")]
    CorruptPyramid(String),
    /// The file ends inside its embedded resolution pyramid (`part`: its
    /// directory or its levels).
    #[error(
        "the resolution pyramid is cut off in {part}: {} (an incomplete copy?); the samples before it are whole: `volgen convert` copies them into a new file with a new pyramid",
        cut_off_at(*end, *file_len)
    )]
    PyramidCutOff {
        /// What the file lacks: "its directory" or "its levels".
        part: &'static str,
        /// Where the pyramid ends.
        end: u64,
        /// The file's length.
        file_len: u64,
    },
    /// A sidecar file (a pyramid's, a range table's) given where its volume
    /// belongs.
    #[error("is a sidecar holding {what} of {volume}, not a volume: give {volume}")]
    Sidecar {
        /// What the sidecar holds.
        what: &'static str,
        /// The volume it belongs to (the sidecar's name without its suffix).
        volume: String,
    },
    /// A volume built in memory needs more than the system gives.
    #[error(
        "building it in memory takes {} and the system refused that much; make a smaller one, or write it to a file (volgen generate), which is built slab by slab",
        crate::files::human_bytes(*bytes)
    )]
    InMemory {
        /// Bytes the volume takes while it is built.
        bytes: u64,
    },
    /// The samples are not aligned for their type in memory.
    #[error("u16 samples are not 2-byte aligned in memory")]
    Misaligned,
    /// A raw input's description does not fit the file.
    #[error("{0}")]
    RawSpec(String),
    /// The output exists and overwriting was not allowed.
    #[error("already exists (pass --force to replace it)")]
    Exists,
    /// Output and input are the same file.
    #[error("is both the input and the output")]
    SameFile,
    /// Floating-point input without one finite value: no range to map, nothing
    /// to show.
    #[error(
        "holds no finite value (every sample is NaN or infinite): there is no value range to map and nothing to show"
    )]
    NoFiniteValues,
    /// The file's value scaling takes its values beyond f32, the values the
    /// tools take and say.
    #[error(
        "its values reach {value:e} under the file's value scaling, beyond the ±3.4e38 values are read in"
    )]
    ValuesBeyondF32 {
        /// The value farthest out.
        value: f64,
    },
    /// The job was cancelled; nothing was written.
    #[error("cancelled; no output was written")]
    Cancelled,
}

impl VolumeError {
    /// An error about `path`.
    pub fn new(path: &Path, kind: impl Into<VolumeErrorKind>) -> Self {
        VolumeError {
            path: path.to_path_buf(),
            kind: kind.into(),
        }
    }
}

/// Attaches a path to errors of the kinds a volume error can hold.
pub(crate) trait AtPath<T> {
    fn at(self, path: &Path) -> Result<T, VolumeError>;
}

impl<T, E: Into<VolumeErrorKind>> AtPath<T> for Result<T, E> {
    fn at(self, path: &Path) -> Result<T, VolumeError> {
        self.map_err(|e| VolumeError::new(path, e))
    }
}
