//! Errors of opening, reading and writing volume files: each names the file.

use std::path::{Path, PathBuf};

use super::header::HeaderError;

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
    /// The header is invalid or does not match the file.
    #[error("invalid header: {0}")]
    Header(#[from] HeaderError),
    /// A file not named `.vol` whose first bytes are no `.vol` header either.
    #[error(
        "not a volume file: its name ends in none of .vol, .nrrd, .nhdr, .nii, .nii.gz, .hdr, .mha, .mhd, .dcm, and its first bytes are no .vol header: {0}"
    )]
    NotAVolume(HeaderError),
    /// The embedded value-range table is unreadable.
    #[error("the value-range table after the samples is corrupt")]
    CorruptRanges,
    /// The resolution pyramid (embedded or sidecar) is inconsistent.
    #[error("the resolution pyramid is corrupt: {0}")]
    CorruptPyramid(String),
    /// The samples are not aligned for their type in memory.
    #[error("u16 samples are not 2-byte aligned in memory")]
    Misaligned,
    /// A raw input's description does not fit the file.
    #[error("{0}")]
    RawSpec(String),
    /// The output exists and overwriting was not allowed.
    #[error("already exists (overwrite it explicitly)")]
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
