//! The `.vol` header: the thesis's 26-byte header and our versioned extension.
//!
//! The byte tables are in `docs/format.md`. Parsing is a pure function of the header
//! bytes and the file length, so it can be property-tested on random bytes.

use super::grid::BlockGrid;
use super::orientation::{ORIENTATION_BLOCK_LEN, Orientation};
use super::units::{UNITS_BLOCK_LEN, ValueUnits};

/// Length of the thesis header (format version 0).
pub const THESIS_HEADER_LEN: u64 = 26;
/// Length of the extended header (thesis header + extension block).
pub const EXTENDED_HEADER_LEN: u64 = 64;
/// Magic bytes that open the extension block at byte 26.
pub const EXTENSION_MAGIC: [u8; 4] = *b"RCVX";
/// The newest extension version this build writes and reads: version 2 adds a
/// resolution pyramid, version 3 a value block (what samples mean: units), version
/// 4 an orientation block (where the volume lies in the patient), version 5 the
/// cell-range tables in the pyramid block (whose presence of value and orientation
/// blocks the data offset says). Files are written with the oldest version that
/// holds what they carry.
pub const EXTENSION_VERSION: u16 = 5;
/// The extension version of files with an orientation block and no cell tables.
const EXTENSION_VERSION_ORIENTED: u16 = 4;
/// The extension version of files with a value block and no orientation.
const EXTENSION_VERSION_UNITS: u16 = 3;
/// The extension version of files with a pyramid and no value block.
const EXTENSION_VERSION_PYRAMID: u16 = 2;
/// The header length of version 3: the extended header and the value block.
pub const UNITS_HEADER_LEN: u64 = EXTENDED_HEADER_LEN + UNITS_BLOCK_LEN;
/// The header length of version 4: version 3's and the orientation block.
pub const ORIENTED_HEADER_LEN: u64 = UNITS_HEADER_LEN + ORIENTATION_BLOCK_LEN;
/// The longest header of any version (what a reader reads before parsing).
pub const MAX_HEADER_LEN: u64 = ORIENTED_HEADER_LEN;

/// The extension version of files without a pyramid (older readers open them).
pub const EXTENSION_VERSION_PLAIN: u16 = 1;
/// The largest size accepted on any axis (2^20 voxels).
pub const MAX_AXIS: u32 = 1 << 20;

/// The smallest spacing a header may give (a denormal such as 1e-45 is a broken
/// header, not a scale; squares of distances stay normal floats above it).
pub const MIN_SPACING: f32 = 1e-15;

/// The largest spacing, and the largest extent (spacing × size) along an axis,
/// a header may give: beyond it the squares of world distances (the camera's)
/// overflow.
pub const MAX_SPACING: f32 = 1e15;
/// Order byte of a thesis linear file.
const ORDER_LINEAR: u8 = 1;
/// Order byte of a thesis bricked file.
const ORDER_BRICKED: u8 = 2;
/// Set in the order byte when the extension block follows the thesis header.
const ORDER_EXTENDED_BIT: u8 = 0x80;

/// How samples are ordered in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layout {
    /// One linear array, z fastest, then y, then x.
    Linear,
    /// Cubic bricks of `side` voxels overlapping their neighbours by one voxel.
    Bricked {
        /// Brick side length in voxels (2..=255).
        side: u8,
    },
}

/// The numeric type of one stored sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleType {
    /// Unsigned 8-bit samples.
    U8,
    /// Unsigned 16-bit little-endian samples.
    U16,
}

impl std::fmt::Display for SampleType {
    /// `u8`, `u16`: as the tools' flags and messages write types.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SampleType::U8 => "u8",
            SampleType::U16 => "u16",
        })
    }
}

impl SampleType {
    /// Bytes per stored sample.
    pub fn size(self) -> u64 {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 => 2,
        }
    }

    /// The largest value a sample of this type holds.
    pub fn max_value(self) -> u16 {
        match self {
            SampleType::U8 => u8::MAX as u16,
            SampleType::U16 => u16::MAX,
        }
    }

    fn code(self) -> u8 {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 => 2,
        }
    }
}

/// What the samples mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Content {
    /// Scalar values (densities, intensities), interpolated when sampled.
    Scalar,
    /// Object ids of a segmentation; looked up nearest-neighbour, never interpolated.
    Labels,
}

/// Which header a file carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// The thesis's 26-byte header; u8 scalar samples only.
    Thesis,
    /// The 64-byte extended header (version [`EXTENSION_VERSION`]).
    Extended,
}

/// A parsed and validated `.vol` header.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Voxel counts on x, y, z.
    pub dims: [u32; 3],
    /// Distance between neighbouring voxels on x, y, z (positive and finite).
    pub spacing: [f32; 3],
    /// Sample order.
    pub layout: Layout,
    /// Stored sample type.
    pub sample_type: SampleType,
    /// Scalar data or labels.
    pub content: Content,
    /// Which header the file has.
    pub format: Format,
    /// Byte offset of the first sample.
    pub data_offset: u64,
    /// Byte offset of the embedded per-brick value-range table, if the file has one.
    pub ranges_offset: Option<u64>,
    /// Byte offset of the embedded resolution pyramid (extension version 2), if any.
    pub pyramid_offset: Option<u64>,
    /// Whether the embedded pyramid block also stores the cell-range tables of
    /// every level (block version 2, extension version 5).
    pub pyramid_cells: bool,
    /// What samples mean (extension version 3); `None`: values are the samples.
    /// Set it with [`Header::with_units`], which moves the data offset.
    pub units: Option<ValueUnits>,
    /// Where the volume lies in the patient (extension version 4); `None`: the
    /// file does not say. Set it with [`Header::with_orientation`].
    pub orientation: Option<Orientation>,
}

/// What is wrong with a header.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HeaderError {
    /// The file is shorter than the header it starts.
    #[error("file is {len} bytes, shorter than the {needed}-byte header")]
    TooShort {
        /// The file's length.
        len: u64,
        /// The header length needed.
        needed: u64,
    },
    /// A dimension is zero.
    #[error("size on {axis} is 0")]
    ZeroDimension {
        /// Axis name.
        axis: char,
    },
    /// A dimension is larger than [`MAX_AXIS`].
    #[error("size on {axis} is {value}, more than the {MAX_AXIS} supported")]
    AbsurdDimension {
        /// Axis name.
        axis: char,
        /// The size found.
        value: u32,
    },
    /// Spacing is NaN, infinite, zero or negative.
    #[error("spacing on {axis} is {value}; it must be a positive finite number")]
    BadSpacing {
        /// Axis name.
        axis: char,
        /// The spacing found.
        value: f32,
    },
    /// Spacing is finite and positive but absurd: outside
    /// [`MIN_SPACING`]..=[`MAX_SPACING`].
    #[error(
        "spacing on {axis} is {value:e}; a spacing is read from {MIN_SPACING:e} to {MAX_SPACING:e}, with the volume's extent (spacing × size) at most {MAX_SPACING:e}"
    )]
    AbsurdSpacing {
        /// Axis name.
        axis: char,
        /// The spacing found.
        value: f32,
    },
    /// The volume's extent along an axis (spacing × size) is above
    /// [`MAX_SPACING`], where world positions and the camera overflow.
    #[error(
        "spacing on {axis} is {spacing:e} over {size} voxels: an extent of {:e}, past the most a volume may span ({MAX_SPACING:e}; world positions and the camera would overflow)",
        *spacing * *size as f32
    )]
    HugeExtent {
        /// Axis name.
        axis: char,
        /// The spacing found.
        spacing: f32,
        /// Voxels along the axis.
        size: u32,
    },
    /// The order byte (24) is not one this reader knows.
    #[error(
        "unknown sample order byte {0:#04x} (expected 1 = linear, 2 = bricked, or 0x81/0x82 for the extended header)"
    )]
    UnknownOrder(u8),
    /// The brick side (byte 25) is below 2.
    #[error("brick side {0} is too small (bricked files need a side of at least 2)")]
    BadBrickSide(u8),
    /// The extension block does not start with [`EXTENSION_MAGIC`].
    #[error("order byte says extended header but bytes 26..30 are not \"RCVX\"")]
    BadExtensionMagic,
    /// The extension version is newer than this reader.
    #[error(
        "extended header version {0} is not supported (this build reads version {EXTENSION_VERSION})"
    )]
    UnsupportedVersion(u16),
    /// The sample type code is unknown.
    #[error("unknown sample type code {0} (1 = u8, 2 = u16)")]
    UnknownSampleType(u8),
    /// The content code is unknown.
    #[error("unknown content code {0} (0 = scalar, 1 = labels)")]
    UnknownContent(u8),
    /// The data offset is not where this version puts data.
    #[error(
        "data offset {0} is not valid for this extended header (64, or 128 with a value block)"
    )]
    BadDataOffset(u64),
    /// The value block is malformed, or units are given where they cannot be.
    #[error("value units: {0}")]
    BadUnits(String),
    /// The orientation block is malformed, or an orientation is given where it
    /// cannot be.
    #[error("orientation: {0}")]
    BadOrientation(String),
    /// The declared data length does not match the dimensions.
    #[error("header declares {declared} bytes of samples but the sizes need {expected}")]
    DataLengthMismatch {
        /// Length in the header.
        declared: u64,
        /// Length the dimensions and layout need.
        expected: u64,
    },
    /// Samples handed over in memory are not of the header's type.
    #[error("the header declares {header} samples but {samples} samples were given")]
    SampleTypeMismatch {
        /// The header's sample type.
        header: SampleType,
        /// The type of the samples given.
        samples: SampleType,
    },
    /// A label volume whose samples are not u8.
    #[error("label volumes hold u8 object ids; this one declares {0} samples")]
    LabelsNotU8(SampleType),
    /// The sizes multiply past what 64 bits hold.
    #[error("sizes overflow: the sample data would exceed 2^64 bytes")]
    SizeOverflow,
    /// The file ends before the samples do.
    #[error(
        "the file is cut short: its samples end at byte {expected}, the file has {actual} bytes (an incomplete copy?)"
    )]
    Truncated {
        /// Where the samples end.
        expected: u64,
        /// The file's length.
        actual: u64,
    },
    /// The range table offset points inside the samples or past the file.
    #[error("{}", misplaced_block("value-range table", ("an", 1), *offset, *data_end, *file_len))]
    BadRangesOffset {
        /// The offset in the header.
        offset: u64,
        /// Where the samples end.
        data_end: u64,
        /// The file's length.
        file_len: u64,
    },
    /// The pyramid offset is outside the bytes after the samples or not 64-aligned.
    #[error("{}", misplaced_block("resolution pyramid", ("a 64-aligned", 64), *offset, *data_end, *file_len))]
    BadPyramidOffset {
        /// The offset in the header.
        offset: u64,
        /// Where the samples end.
        data_end: u64,
        /// The file's length.
        file_len: u64,
    },
}

impl HeaderError {
    /// Whether the file ends before the samples, or before a block the header
    /// places after them: a file cut short rather than a bad header.
    pub fn is_cut_short(&self) -> bool {
        matches!(self, HeaderError::Truncated { .. }) || self.is_block_past_end()
    }

    /// Whether the file's samples are whole but it ends before a block (range
    /// table, pyramid) its header places after them.
    pub fn is_block_past_end(&self) -> bool {
        match *self {
            HeaderError::BadRangesOffset {
                offset,
                data_end,
                file_len,
            } => offset >= file_len && offset >= data_end && could_start_a_block(offset, 1),
            HeaderError::BadPyramidOffset {
                offset,
                data_end,
                file_len,
            } => offset >= file_len && offset >= data_end && could_start_a_block(offset, 64),
            _ => false,
        }
    }
}

/// Whether a block (range table, pyramid) could start at `offset` of some
/// file: a multiple of `align` (the pyramid's 64), with room for its bytes
/// before 2⁶⁴. Cutting a file short keeps such an offset; one that is not is a
/// damaged header (a conversion could not rescue the samples either).
fn could_start_a_block(offset: u64, align: u64) -> bool {
    offset.is_multiple_of(align) && offset.checked_add(64).is_some()
}

/// The message of a block (range table, pyramid) whose offset is wrong: one
/// past the file's end, where a block could start, most likely means a
/// truncated file.
fn misplaced_block(
    block: &str,
    (offset_kind, align): (&str, u64),
    offset: u64,
    data_end: u64,
    file_len: u64,
) -> String {
    if offset >= file_len && offset >= data_end && could_start_a_block(offset, align) {
        format!(
            "the {block} starts at byte {offset}, past the file's end ({file_len} bytes): the file is cut short (an incomplete copy?) or its header is damaged; the samples before it are whole: `volgen convert` copies them into a new file"
        )
    } else if offset >= file_len && offset >= data_end {
        format!(
            "the {block} starts at byte {offset}, past the file's end ({file_len} bytes), where no {block} can start: the header is damaged"
        )
    } else {
        format!(
            "{block} offset {offset} is not {offset_kind} offset in the file's trailing bytes ({data_end}..{file_len})"
        )
    }
}

const AXES: [char; 3] = ['x', 'y', 'z'];

impl Header {
    /// A header for a new file (extended format unless `format` says thesis).
    pub fn new(
        dims: [u32; 3],
        spacing: [f32; 3],
        layout: Layout,
        sample_type: SampleType,
        content: Content,
        format: Format,
    ) -> Self {
        let data_offset = match format {
            Format::Thesis => THESIS_HEADER_LEN,
            Format::Extended => EXTENDED_HEADER_LEN,
        };
        Header {
            dims,
            spacing,
            layout,
            sample_type,
            content,
            format,
            data_offset,
            ranges_offset: None,
            pyramid_offset: None,
            pyramid_cells: false,
            units: None,
            orientation: None,
        }
    }

    /// This header with `units` (identity units are dropped), its data offset
    /// moved to where the header's version puts samples.
    pub fn with_units(mut self, units: Option<ValueUnits>) -> Header {
        self.units = units.filter(|u| !u.is_identity());
        self.data_offset = self.standard_data_offset();
        self
    }

    /// This header with `orientation`, its data offset moved to where the
    /// header's version puts samples.
    pub fn with_orientation(mut self, orientation: Option<Orientation>) -> Header {
        self.orientation = orientation;
        self.data_offset = self.standard_data_offset();
        self
    }

    /// Where samples start for this header's format and contents: 26 (thesis), 64
    /// (extended), 128 (extended with a value block), 256 (extended with an
    /// orientation block).
    pub fn standard_data_offset(&self) -> u64 {
        match (self.format, &self.units, &self.orientation) {
            (Format::Thesis, _, _) => THESIS_HEADER_LEN,
            (Format::Extended, _, Some(_)) => ORIENTED_HEADER_LEN,
            (Format::Extended, Some(_), None) => UNITS_HEADER_LEN,
            (Format::Extended, None, None) => EXTENDED_HEADER_LEN,
        }
    }

    /// The extension version this header is written with: the oldest that holds
    /// what it carries.
    pub fn extension_version(&self) -> u16 {
        match (&self.orientation, &self.units, self.pyramid_offset) {
            (_, _, Some(_)) if self.pyramid_cells => EXTENSION_VERSION,
            (Some(_), _, _) => EXTENSION_VERSION_ORIENTED,
            (None, Some(_), _) => EXTENSION_VERSION_UNITS,
            (None, None, Some(_)) => EXTENSION_VERSION_PYRAMID,
            (None, None, None) => EXTENSION_VERSION_PLAIN,
        }
    }

    /// What stored samples mean (identity when the file says nothing).
    pub fn value_units(&self) -> ValueUnits {
        self.units.clone().unwrap_or_default()
    }

    /// Checks the fields that do not depend on a file: sizes, spacing, brick side,
    /// and that the thesis format is only used for u8 scalars.
    pub fn validate(&self) -> Result<(), HeaderError> {
        for (axis, &d) in AXES.iter().zip(&self.dims) {
            if d == 0 {
                return Err(HeaderError::ZeroDimension { axis: *axis });
            }
            if d > MAX_AXIS {
                return Err(HeaderError::AbsurdDimension {
                    axis: *axis,
                    value: d,
                });
            }
        }
        for ((axis, &s), &d) in AXES.iter().zip(&self.spacing).zip(&self.dims) {
            if !(s.is_finite() && s > 0.0) {
                return Err(HeaderError::BadSpacing {
                    axis: *axis,
                    value: s,
                });
            }
            if !(MIN_SPACING..=MAX_SPACING).contains(&s) {
                return Err(HeaderError::AbsurdSpacing {
                    axis: *axis,
                    value: s,
                });
            }
            if f64::from(s) * f64::from(d) > f64::from(MAX_SPACING) {
                return Err(HeaderError::HugeExtent {
                    axis: *axis,
                    spacing: s,
                    size: d,
                });
            }
        }
        if let Layout::Bricked { side } = self.layout
            && side < 2
        {
            return Err(HeaderError::BadBrickSide(side));
        }
        if self.content == Content::Labels && self.sample_type != SampleType::U8 {
            return Err(HeaderError::LabelsNotU8(self.sample_type));
        }
        if let Some(units) = &self.units {
            if self.format == Format::Thesis {
                return Err(HeaderError::BadUnits(
                    "the thesis header has no room for value units".into(),
                ));
            }
            if self.content == Content::Labels {
                return Err(HeaderError::BadUnits("label ids have no units".into()));
            }
            units.validate()?;
        }
        if let Some(orientation) = &self.orientation {
            if self.format == Format::Thesis {
                return Err(HeaderError::BadOrientation(
                    "the thesis header has no room for an orientation".into(),
                ));
            }
            orientation.validate()?;
        }
        self.data_len().map(|_| ())
    }

    /// Number of samples stored in the file (bricked files store whole bricks,
    /// padding included).
    pub fn stored_samples(&self) -> Result<u64, HeaderError> {
        match self.layout {
            Layout::Linear => self
                .dims
                .iter()
                .try_fold(1u64, |acc, &d| acc.checked_mul(u64::from(d))),
            Layout::Bricked { side } => {
                let grid = BlockGrid::new(self.dims, u32::from(side));
                let per_brick = u64::from(side).pow(3);
                grid.block_count().checked_mul(per_brick)
            }
        }
        .ok_or(HeaderError::SizeOverflow)
    }

    /// Bytes of sample data in the file.
    pub fn data_len(&self) -> Result<u64, HeaderError> {
        self.stored_samples()?
            .checked_mul(self.sample_type.size())
            .ok_or(HeaderError::SizeOverflow)
    }

    /// Byte offset just past the last sample.
    pub fn data_end(&self) -> Result<u64, HeaderError> {
        self.data_offset
            .checked_add(self.data_len()?)
            .ok_or(HeaderError::SizeOverflow)
    }

    /// The grid of bricks (bricked files) or of logical bricks of side
    /// `linear_side` (linear files).
    pub fn block_grid(&self, linear_side: u32) -> BlockGrid {
        match self.layout {
            Layout::Linear => BlockGrid::new(self.dims, linear_side),
            Layout::Bricked { side } => BlockGrid::new(self.dims, u32::from(side)),
        }
    }

    /// Parses and validates a header from the first bytes of a file of length
    /// `file_len`. `bytes` may be longer than the header; only the header is read.
    pub fn parse(bytes: &[u8], file_len: u64) -> Result<Header, HeaderError> {
        let too_short = |needed| HeaderError::TooShort {
            len: file_len,
            needed,
        };
        if bytes.len() < THESIS_HEADER_LEN as usize || file_len < THESIS_HEADER_LEN {
            return Err(too_short(THESIS_HEADER_LEN));
        }
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        let dims = [u32_at(0), u32_at(4), u32_at(8)];
        let spacing = [f32_at(12), f32_at(16), f32_at(20)];
        let order = bytes[24];
        let side = bytes[25];
        let layout = match order & !ORDER_EXTENDED_BIT {
            ORDER_LINEAR => Layout::Linear,
            ORDER_BRICKED => Layout::Bricked { side },
            _ => return Err(HeaderError::UnknownOrder(order)),
        };
        let mut header = Header::new(
            dims,
            spacing,
            layout,
            SampleType::U8,
            Content::Scalar,
            Format::Thesis,
        );
        if order & ORDER_EXTENDED_BIT != 0 {
            if bytes.len() < EXTENDED_HEADER_LEN as usize || file_len < EXTENDED_HEADER_LEN {
                return Err(too_short(EXTENDED_HEADER_LEN));
            }
            if bytes[26..30] != EXTENSION_MAGIC {
                return Err(HeaderError::BadExtensionMagic);
            }
            let version = u16::from_le_bytes([bytes[30], bytes[31]]);
            if !(EXTENSION_VERSION_PLAIN..=EXTENSION_VERSION).contains(&version) {
                return Err(HeaderError::UnsupportedVersion(version));
            }
            let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap());
            header.format = Format::Extended;
            header.sample_type = match bytes[32] {
                1 => SampleType::U8,
                2 => SampleType::U16,
                code => return Err(HeaderError::UnknownSampleType(code)),
            };
            header.content = match bytes[33] {
                0 => Content::Scalar,
                1 => Content::Labels,
                code => return Err(HeaderError::UnknownContent(code)),
            };
            header.data_offset = u64_at(40);
            // Version 5 has the blocks its data offset makes room for: one of
            // three offsets (any other is said as such, before a block is
            // looked for where there is none).
            if version == EXTENSION_VERSION
                && ![EXTENDED_HEADER_LEN, UNITS_HEADER_LEN, ORIENTED_HEADER_LEN]
                    .contains(&header.data_offset)
            {
                return Err(HeaderError::BadDataOffset(header.data_offset));
            }
            let (has_units, has_orientation) = match version {
                EXTENSION_VERSION => (
                    header.data_offset >= UNITS_HEADER_LEN,
                    header.data_offset >= ORIENTED_HEADER_LEN,
                ),
                v => (
                    v >= EXTENSION_VERSION_UNITS,
                    v >= EXTENSION_VERSION_ORIENTED,
                ),
            };
            if has_units {
                if bytes.len() < UNITS_HEADER_LEN as usize || file_len < UNITS_HEADER_LEN {
                    return Err(too_short(UNITS_HEADER_LEN));
                }
                let block = &bytes[EXTENDED_HEADER_LEN as usize..UNITS_HEADER_LEN as usize];
                // Version 4 always has a value block; identity there means none.
                header.units = Some(ValueUnits::decode(block)?).filter(|u| !u.is_identity());
            }
            if has_orientation {
                if bytes.len() < ORIENTED_HEADER_LEN as usize || file_len < ORIENTED_HEADER_LEN {
                    return Err(too_short(ORIENTED_HEADER_LEN));
                }
                let block = &bytes[UNITS_HEADER_LEN as usize..ORIENTED_HEADER_LEN as usize];
                header.orientation = Some(Orientation::decode(block)?);
            }
            if header.data_offset != header.standard_data_offset() {
                return Err(HeaderError::BadDataOffset(header.data_offset));
            }
            let declared = u64_at(48);
            let ranges = u64_at(56);
            header.validate()?;
            let expected = header.data_len()?;
            if declared != expected {
                return Err(HeaderError::DataLengthMismatch { declared, expected });
            }
            header.ranges_offset = (ranges != 0).then_some(ranges);
            if version >= 2 {
                let mut six = [0u8; 8];
                six[..6].copy_from_slice(&bytes[34..40]);
                let pyramid = u64::from_le_bytes(six);
                header.pyramid_offset = (pyramid != 0).then_some(pyramid);
                header.pyramid_cells = version >= EXTENSION_VERSION && pyramid != 0;
            }
        } else {
            header.validate()?;
        }
        let data_end = header.data_end()?;
        if file_len < data_end {
            return Err(HeaderError::Truncated {
                expected: data_end,
                actual: file_len,
            });
        }
        if let Some(offset) = header.ranges_offset
            && (offset < data_end || offset >= file_len)
        {
            return Err(HeaderError::BadRangesOffset {
                offset,
                data_end,
                file_len,
            });
        }
        if let Some(offset) = header.pyramid_offset
            && (offset < data_end || offset >= file_len || offset % 64 != 0)
        {
            return Err(HeaderError::BadPyramidOffset {
                offset,
                data_end,
                file_len,
            });
        }
        Ok(header)
    }

    /// Encodes the header; the result is `data_offset` bytes long.
    pub fn encode(&self) -> Result<Vec<u8>, HeaderError> {
        self.validate()?;
        if self.data_offset != self.standard_data_offset() {
            return Err(HeaderError::BadDataOffset(self.data_offset));
        }
        let mut out = Vec::with_capacity(MAX_HEADER_LEN as usize);
        for d in self.dims {
            out.extend_from_slice(&d.to_le_bytes());
        }
        for s in self.spacing {
            out.extend_from_slice(&s.to_le_bytes());
        }
        let (order, side) = match self.layout {
            Layout::Linear => (ORDER_LINEAR, 0),
            Layout::Bricked { side } => (ORDER_BRICKED, side),
        };
        match self.format {
            Format::Thesis => {
                out.push(order);
                out.push(side);
            }
            Format::Extended => {
                out.push(order | ORDER_EXTENDED_BIT);
                out.push(side);
                out.extend_from_slice(&EXTENSION_MAGIC);
                out.extend_from_slice(&self.extension_version().to_le_bytes());
                out.push(self.sample_type.code());
                out.push(match self.content {
                    Content::Scalar => 0,
                    Content::Labels => 1,
                });
                let pyramid = self.pyramid_offset.unwrap_or(0);
                if pyramid >= 1 << 48 {
                    return Err(HeaderError::SizeOverflow);
                }
                out.extend_from_slice(&pyramid.to_le_bytes()[..6]);
                out.extend_from_slice(&self.data_offset.to_le_bytes());
                out.extend_from_slice(&self.data_len()?.to_le_bytes());
                out.extend_from_slice(&self.ranges_offset.unwrap_or(0).to_le_bytes());
                if self.units.is_some() || self.orientation.is_some() {
                    let units = self.units.clone().unwrap_or_default();
                    out.extend_from_slice(&units.encode());
                }
                if let Some(orientation) = &self.orientation {
                    out.extend_from_slice(&orientation.encode());
                }
            }
        }
        debug_assert_eq!(out.len() as u64, self.data_offset);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_header(format: Format, sample_type: SampleType, layout: Layout) -> Header {
        Header::new(
            [5, 7, 9],
            [1.0, 0.5, 2.0],
            layout,
            sample_type,
            Content::Scalar,
            format,
        )
    }

    #[test]
    fn thesis_header_is_26_bytes_in_the_thesis_order() {
        let h = sample_header(Format::Thesis, SampleType::U8, Layout::Bricked { side: 4 });
        let bytes = h.encode().unwrap();
        assert_eq!(bytes.len(), 26);
        assert_eq!(&bytes[0..4], &5u32.to_le_bytes());
        assert_eq!(&bytes[16..20], &0.5f32.to_le_bytes());
        assert_eq!(bytes[24], 2);
        assert_eq!(bytes[25], 4);
    }

    #[test]
    fn extended_header_round_trips() {
        for st in [SampleType::U8, SampleType::U16] {
            for layout in [Layout::Linear, Layout::Bricked { side: 16 }] {
                let mut h = sample_header(Format::Extended, st, layout);
                if st == SampleType::U8 {
                    h.content = Content::Labels;
                }
                let bytes = h.encode().unwrap();
                assert_eq!(bytes.len(), 64);
                let file_len = h.data_end().unwrap();
                assert_eq!(Header::parse(&bytes, file_len).unwrap(), h);
            }
        }
    }

    #[test]
    fn value_block_is_version_3_with_samples_at_128_and_refused_where_it_cannot_be() {
        let units = ValueUnits::new(1.0, -32768.0, "HU").unwrap();
        let plain = sample_header(Format::Extended, SampleType::U16, Layout::Linear);
        let h = plain.clone().with_units(Some(units.clone()));
        assert_eq!(h.data_offset, UNITS_HEADER_LEN);
        let bytes = h.encode().unwrap();
        assert_eq!(bytes.len(), 128);
        assert_eq!(u16::from_le_bytes([bytes[30], bytes[31]]), 3);
        let file_len = h.data_end().unwrap();
        let parsed = Header::parse(&bytes, file_len).unwrap();
        assert_eq!(parsed.value_units(), units);
        assert_eq!(parsed, h);
        // Identity units are no units: such files stay version 1.
        let identity = plain.clone().with_units(Some(ValueUnits::IDENTITY));
        assert_eq!(identity, plain);
        assert_eq!(identity.encode().unwrap().len(), 64);
        // A version-3 header cut short, or claiming samples at 64.
        assert!(matches!(
            Header::parse(&bytes[..100], file_len),
            Err(HeaderError::TooShort { needed: 128, .. })
        ));
        let mut at_64 = bytes.clone();
        at_64[40..48].copy_from_slice(&64u64.to_le_bytes());
        assert_eq!(
            Header::parse(&at_64, file_len),
            Err(HeaderError::BadDataOffset(64))
        );
        // A version-5 header's offset says which blocks it has: one that is
        // none of the three is said as the offset (before: "the value block
        // does not start with RCVU").
        let mut v5 = bytes.clone();
        v5[30..32].copy_from_slice(&EXTENSION_VERSION.to_le_bytes());
        v5[40..48].copy_from_slice(&0xffff_ffff_ffff_ffc0u64.to_le_bytes());
        assert_eq!(
            Header::parse(&v5, file_len),
            Err(HeaderError::BadDataOffset(0xffff_ffff_ffff_ffc0))
        );
        let mut bad_block = bytes.clone();
        bad_block[72..80].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(matches!(
            Header::parse(&bad_block, file_len),
            Err(HeaderError::BadUnits(_))
        ));
        // Units on a thesis header or on labels are refused.
        let thesis = sample_header(Format::Thesis, SampleType::U8, Layout::Linear)
            .with_units(Some(units.clone()));
        assert!(matches!(thesis.encode(), Err(HeaderError::BadUnits(_))));
        let mut labels = sample_header(Format::Extended, SampleType::U8, Layout::Linear);
        labels.content = Content::Labels;
        let labels = labels.with_units(Some(units));
        assert!(matches!(labels.encode(), Err(HeaderError::BadUnits(_))));
    }

    #[test]
    fn orientation_block_is_version_4_with_samples_at_256() {
        let placed = Orientation {
            axes: [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            origin: [1.5, -2.0, 300.25],
        };
        let plain = sample_header(Format::Extended, SampleType::U16, Layout::Linear);
        for units in [None, Some(ValueUnits::new(1.0, -32768.0, "HU").unwrap())] {
            let h = plain
                .clone()
                .with_units(units.clone())
                .with_orientation(Some(placed.clone()));
            assert_eq!(h.data_offset, ORIENTED_HEADER_LEN);
            let bytes = h.encode().unwrap();
            assert_eq!(bytes.len(), 256);
            assert_eq!(u16::from_le_bytes([bytes[30], bytes[31]]), 4);
            let file_len = h.data_end().unwrap();
            let parsed = Header::parse(&bytes, file_len).unwrap();
            assert_eq!(parsed, h);
            assert_eq!(parsed.orientation, Some(placed.clone()));
            assert_eq!(parsed.units, units);
            assert!(matches!(
                Header::parse(&bytes[..200], file_len),
                Err(HeaderError::TooShort { needed: 256, .. })
            ));
            let mut bad = bytes.clone();
            bad[136..144].copy_from_slice(&2.0f64.to_le_bytes());
            assert!(matches!(
                Header::parse(&bad, file_len),
                Err(HeaderError::BadOrientation(_))
            ));
        }
        let thesis = sample_header(Format::Thesis, SampleType::U8, Layout::Linear)
            .with_orientation(Some(placed));
        assert!(matches!(
            thesis.encode(),
            Err(HeaderError::BadOrientation(_))
        ));
    }

    /// Version 5 (cell tables in the pyramid block) carries whatever versions 1–4
    /// carry; its data offset says which blocks are there.
    #[test]
    fn cell_tables_are_version_5_with_the_blocks_the_data_offset_makes_room_for() {
        let placed = Orientation {
            axes: [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            origin: [1.5, -2.0, 300.25],
        };
        let hu = Some(ValueUnits::new(1.0, -32768.0, "HU").unwrap());
        let plain = sample_header(Format::Extended, SampleType::U16, Layout::Linear);
        let cases = [
            (None, None, EXTENDED_HEADER_LEN),
            (hu.clone(), None, UNITS_HEADER_LEN),
            (None, Some(placed.clone()), ORIENTED_HEADER_LEN),
            (hu, Some(placed), ORIENTED_HEADER_LEN),
        ];
        for (units, orientation, data_offset) in cases {
            let mut h = plain
                .clone()
                .with_units(units.clone())
                .with_orientation(orientation.clone());
            let file_len = h.data_end().unwrap() + 4096;
            h.pyramid_offset = Some(h.data_end().unwrap().next_multiple_of(64));
            // Without cell tables: the version the blocks need (2 to 4).
            let older = h.encode().unwrap();
            assert!((2..=4).contains(&u16::from_le_bytes([older[30], older[31]])));
            assert!(!Header::parse(&older, file_len).unwrap().pyramid_cells);
            h.pyramid_cells = true;
            let bytes = h.encode().unwrap();
            assert_eq!(bytes.len() as u64, data_offset);
            assert_eq!(u16::from_le_bytes([bytes[30], bytes[31]]), 5);
            let parsed = Header::parse(&bytes, file_len).unwrap();
            assert_eq!(parsed, h);
            assert_eq!((parsed.units, parsed.orientation), (units, orientation));
            // A data offset that is not one of the three is refused.
            let mut bad = bytes.clone();
            bad[40..48].copy_from_slice(&(data_offset + 64).to_le_bytes());
            assert!(Header::parse(&bad, file_len).is_err());
        }
        // Cell tables live in the pyramid block: no block, no version 5.
        let mut no_pyramid = plain.clone();
        no_pyramid.pyramid_cells = true;
        let bytes = no_pyramid.encode().unwrap();
        assert_eq!(u16::from_le_bytes([bytes[30], bytes[31]]), 1);
    }

    #[test]
    fn linear_thesis_file_ignores_nothing_and_needs_all_samples() {
        let h = sample_header(Format::Thesis, SampleType::U8, Layout::Linear);
        let bytes = h.encode().unwrap();
        let err = Header::parse(&bytes, 26 + 5 * 7 * 9 - 1).unwrap_err();
        assert_eq!(
            err,
            HeaderError::Truncated {
                expected: 26 + 315,
                actual: 26 + 314
            }
        );
    }
}
