//! Volume files and their in-memory representation.
//!
//! The `.vol` format (the reference thesis's 26-byte header, plus our versioned
//! extension for u16 samples and label volumes; specified in `docs/format.md`),
//! opened memory-mapped or into RAM behind one interface, with per-brick value ranges
//! for empty-space skipping. Streaming readers and writers convert and generate
//! files in bounded memory.

mod cells;
mod error;
mod file;
mod grid;
mod header;
mod orientation;
pub mod pyramid;
mod ranges;
mod sample;
mod storage;
mod units;
mod view;

pub use cells::{
    CELL_TABLE_HEAD_LEN, CellShape, CellTable, LARGE_LINEAR_BRICKS, MAX_CELLS, TARGET_CELL_STEP,
    default_linear_brick_side, target_cell_step,
};
pub use error::{VolumeError, VolumeErrorKind};
pub use file::{
    OpenOptions, Volume, VolumeData, full_resolution_coordinate, has_vol_extension,
    level_coordinate, ranges_sidecar_path, read_header, read_header_of_cut_file,
    unused_tail_warning, write_pyramid_sidecar,
};
pub(crate) use file::{content_end, embedded_ranges_end};
pub use grid::BlockGrid;
pub use header::{
    Content, EXTENDED_HEADER_LEN, EXTENSION_MAGIC, EXTENSION_VERSION, Format, Header, HeaderError,
    Layout, MAX_AXIS, MAX_HEADER_LEN, MAX_SPACING, MIN_SPACING, ORIENTED_HEADER_LEN, SampleType,
    THESIS_HEADER_LEN, UNITS_HEADER_LEN,
};
pub use orientation::{ORIENTATION_BLOCK_LEN, Orientation, PatientSpace};
pub use pyramid::{COARSEST_EDGE, level_dims, pyramid_sidecar_path, pyramid_voxels};
pub use ranges::{BrickRanges, LINEAR_RANGE_SIDE};
pub use sample::Sample;
pub use storage::Access;
pub use units::{HOUNSFIELD, MAX_UNIT_LEN, ValueUnits, number_text};
pub use view::{BrickView, TypedVolume};

pub(crate) use error::AtPath;
pub(crate) use file::temp_file_beside;
pub use file::write_file_atomically;

/// `linear` or `bricked (side 16)`: the layout as people read it (no Rust debug text
/// in messages).
impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Layout::Linear => write!(f, "linear"),
            Layout::Bricked { side } => write!(f, "bricked (side {side})"),
        }
    }
}
