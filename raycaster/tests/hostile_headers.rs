//! Hostile `.vol` headers.
//!
//! Every validation rule of the format (`docs/format.md`, "Validation") is exercised
//! with a header built by hand, byte by byte (never through `Header::encode`), and the
//! file is opened both memory-mapped and into RAM: each open must return the exact
//! typed error, with the file's path in its message, never panic. Property tests then
//! feed random and mutated header bytes to `Header::parse` and random whole files to
//! `Volume::open`: nothing panics (so nothing reads out of bounds), and whatever is
//! accepted is consistent with the file it came from.

use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use proptest::prelude::*;
use proptest::sample::Index;
use raycaster::volume::{
    Access, BlockGrid, BrickRanges, Content, Format, Header, HeaderError, LINEAR_RANGE_SIDE,
    Layout, MAX_AXIS, MAX_HEADER_LEN, OpenOptions, SampleType, THESIS_HEADER_LEN, TypedVolume,
    Volume, VolumeError, VolumeErrorKind, ranges_sidecar_path,
};
use tempfile::TempDir;

const AXES: [char; 3] = ['x', 'y', 'z'];

// ---------------------------------------------------------------------------------
// Headers as bytes, and the sizes the format gives them (computed independently of
// the library, in 128 bits so nothing here can wrap).
// ---------------------------------------------------------------------------------

/// The extension block (bytes 26..64), field by field.
#[derive(Clone, Debug)]
struct RawExt {
    magic: [u8; 4],
    version: u16,
    sample_type: u8,
    content: u8,
    reserved: [u8; 6],
    data_offset: u64,
    data_len: u64,
    ranges_offset: u64,
}

/// A `.vol` header field by field: the thesis's 26 bytes, plus the extension block
/// when `ext` is set.
#[derive(Clone, Debug)]
struct RawHeader {
    dims: [u32; 3],
    spacing: [f32; 3],
    order: u8,
    side: u8,
    ext: Option<RawExt>,
}

/// Bricks on one axis: `max(1, ceil((size - 1) / (side - 1)))` (`side` >= 2).
fn bricks_on_axis(size: u32, side: u8) -> u128 {
    let step = u128::from(side) - 1;
    (u128::from(size).saturating_sub(1)).div_ceil(step).max(1)
}

/// Samples stored for `dims`: all voxels (linear, `side` None) or whole bricks.
fn stored_samples(dims: [u32; 3], side: Option<u8>) -> u128 {
    match side {
        None => dims.iter().map(|&d| u128::from(d)).product(),
        Some(side) => {
            dims.iter()
                .map(|&d| bricks_on_axis(d, side))
                .product::<u128>()
                * u128::from(side).pow(3)
        }
    }
}

impl RawHeader {
    fn thesis_linear(dims: [u32; 3]) -> Self {
        RawHeader {
            dims,
            spacing: [1.0, 0.5, 2.0],
            order: 1,
            side: 0,
            ext: None,
        }
    }

    fn thesis_bricked(dims: [u32; 3], side: u8) -> Self {
        RawHeader {
            order: 2,
            side,
            ..Self::thesis_linear(dims)
        }
    }

    /// A consistent extended header: linear when `side` is None; `sample_type` 1 (u8)
    /// or 2 (u16); the declared data length is the one the sizes need.
    fn extended(dims: [u32; 3], side: Option<u8>, sample_type: u8) -> Self {
        let mut h = RawHeader {
            dims,
            spacing: [1.0, 0.5, 2.0],
            order: if side.is_some() { 0x82 } else { 0x81 },
            side: side.unwrap_or(0),
            ext: Some(RawExt {
                magic: *b"RCVX",
                version: 1,
                sample_type,
                content: 0,
                reserved: [0; 6],
                data_offset: 64,
                data_len: 0,
                ranges_offset: 0,
            }),
        };
        h.ext_mut().data_len = u64::try_from(h.expected_data_len()).unwrap();
        h
    }

    fn ext_mut(&mut self) -> &mut RawExt {
        self.ext.as_mut().expect("an extended header")
    }

    fn header_len(&self) -> u64 {
        if self.ext.is_some() { 64 } else { 26 }
    }

    /// Brick side if the order byte says bricked.
    fn brick_side(&self) -> Option<u8> {
        (self.order & 0x7f == 2).then_some(self.side)
    }

    fn sample_size(&self) -> u128 {
        self.ext.as_ref().map_or(1, |e| u128::from(e.sample_type))
    }

    /// Bytes of samples the sizes, layout and sample type need (docs/format.md).
    fn expected_data_len(&self) -> u128 {
        stored_samples(self.dims, self.brick_side()) * self.sample_size()
    }

    /// Byte offset just past the last sample.
    fn data_end(&self) -> u64 {
        u64::try_from(u128::from(self.header_len()) + self.expected_data_len()).unwrap()
    }

    fn bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(64);
        for d in self.dims {
            b.extend_from_slice(&d.to_le_bytes());
        }
        for s in self.spacing {
            b.extend_from_slice(&s.to_le_bytes());
        }
        b.push(self.order);
        b.push(self.side);
        if let Some(e) = &self.ext {
            b.extend_from_slice(&e.magic);
            b.extend_from_slice(&e.version.to_le_bytes());
            b.push(e.sample_type);
            b.push(e.content);
            b.extend_from_slice(&e.reserved);
            b.extend_from_slice(&e.data_offset.to_le_bytes());
            b.extend_from_slice(&e.data_len.to_le_bytes());
            b.extend_from_slice(&e.ranges_offset.to_le_bytes());
        }
        assert_eq!(b.len() as u64, self.header_len());
        b
    }

    /// The header followed by `samples` bytes of a non-constant pattern.
    fn file_with(&self, samples: u64) -> Vec<u8> {
        let mut b = self.bytes();
        b.extend((0..samples).map(|i| (i.wrapping_mul(37).wrapping_add(11) % 251) as u8));
        b
    }

    /// The header followed by exactly the samples it needs.
    fn file(&self) -> Vec<u8> {
        self.file_with(u64::try_from(self.expected_data_len()).unwrap())
    }

    /// The header the library should parse from these bytes (valid headers only).
    fn parsed(&self) -> Header {
        let layout = match self.brick_side() {
            None => Layout::Linear,
            Some(side) => Layout::Bricked { side },
        };
        let (sample_type, content, format) = match &self.ext {
            None => (SampleType::U8, Content::Scalar, Format::Thesis),
            Some(e) => (
                if e.sample_type == 2 {
                    SampleType::U16
                } else {
                    SampleType::U8
                },
                if e.content == 1 {
                    Content::Labels
                } else {
                    Content::Scalar
                },
                Format::Extended,
            ),
        };
        let mut h = Header::new(
            self.dims,
            self.spacing,
            layout,
            sample_type,
            content,
            format,
        );
        h.ranges_offset = self
            .ext
            .as_ref()
            .and_then(|e| (e.ranges_offset != 0).then_some(e.ranges_offset));
        h
    }
}

/// The encoded value-range table of a file with header `raw` and samples `data`,
/// over the grid the library expects (the bricks, or logical bricks of
/// [`LINEAR_RANGE_SIDE`] for linear files).
fn range_table(raw: &RawHeader, data: &[u8]) -> Vec<u8> {
    let dims = raw.dims;
    let (layout, grid) = match raw.brick_side() {
        None => (Layout::Linear, BlockGrid::new(dims, LINEAR_RANGE_SIDE)),
        Some(side) => (
            Layout::Bricked { side },
            BlockGrid::new(dims, u32::from(side)),
        ),
    };
    let ranges = if raw.sample_size() == 2 {
        let words: Vec<u16> = data
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        BrickRanges::compute(&TypedVolume::new(&words, dims, layout), &grid)
    } else {
        BrickRanges::compute(&TypedVolume::new(data, dims, layout), &grid)
    };
    ranges.encode()
}

// ---------------------------------------------------------------------------------
// Opening files
// ---------------------------------------------------------------------------------

fn write(dir: &TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn ram() -> OpenOptions {
    OpenOptions {
        access: Access::Ram,
        ..OpenOptions::default()
    }
}

/// Opens `path` memory-mapped and into RAM. Both must fail, name the file in their
/// message and path field, and agree; returns the error of the mapped open.
fn open_fails(path: &Path) -> VolumeError {
    let shown = path.display().to_string();
    let mapped = Volume::open(path).expect_err(&format!("mapped open of {shown} must fail"));
    let in_ram =
        Volume::open_with(path, ram()).expect_err(&format!("RAM open of {shown} must fail"));
    for err in [&mapped, &in_ram] {
        assert_eq!(err.path, path, "the error's path field");
        let msg = err.to_string();
        assert!(msg.contains(&shown), "{msg:?} does not name {shown}");
    }
    assert_eq!(
        mapped.to_string(),
        in_ram.to_string(),
        "mapped and RAM opens disagree"
    );
    mapped
}

/// The header error that opening `path` (mapped and in RAM) gives.
fn header_error(path: &Path) -> HeaderError {
    let err = open_fails(path);
    let msg = err.to_string();
    match err.kind {
        VolumeErrorKind::Header(h) => {
            assert!(
                msg.contains(&h.to_string()),
                "{msg:?} does not explain {h:?}"
            );
            h
        }
        other => panic!("{}: expected a header error, got {other:?}", path.display()),
    }
}

fn assert_header_error(path: &Path, expected: HeaderError) {
    assert_eq!(header_error(path), expected, "{}", path.display());
}

/// The OS error kind that opening `path` (mapped and in RAM) gives.
fn io_error(path: &Path) -> ErrorKind {
    match open_fails(path).kind {
        VolumeErrorKind::Io(e) => e.kind(),
        other => panic!("{}: expected an I/O error, got {other:?}", path.display()),
    }
}

/// Opens `path` both ways; both must succeed and read the same voxels.
fn open_ok(path: &Path) -> Volume {
    let mapped = Volume::open(path).unwrap_or_else(|e| panic!("{e}"));
    let in_ram = Volume::open_with(path, ram()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(mapped.header(), in_ram.header());
    let [dx, dy, dz] = mapped.dims();
    for v in [
        [0, 0, 0],
        [dx - 1, dy - 1, dz - 1],
        [dx / 2, dy / 2, dz / 2],
    ] {
        assert_eq!(mapped.voxel(v), in_ram.voxel(v));
    }
    mapped
}

// ---------------------------------------------------------------------------------
// Files that are not volumes at all
// ---------------------------------------------------------------------------------

#[test]
fn empty_file_is_too_short() {
    let dir = TempDir::new().unwrap();
    let p = write(&dir, "empty.vol", &[]);
    assert_header_error(&p, HeaderError::TooShort { len: 0, needed: 26 });
}

#[test]
fn files_shorter_than_26_bytes_are_too_short() {
    let dir = TempDir::new().unwrap();
    // Prefixes of a valid thesis file, and bytes that would be absurd anyway.
    let valid = RawHeader::thesis_linear([2; 3]).file();
    for len in 1..26 {
        let p = write(&dir, &format!("prefix{len}.vol"), &valid[..len]);
        assert_header_error(
            &p,
            HeaderError::TooShort {
                len: len as u64,
                needed: 26,
            },
        );
        let p = write(&dir, &format!("ff{len}.vol"), &vec![0xff; len]);
        assert_header_error(
            &p,
            HeaderError::TooShort {
                len: len as u64,
                needed: 26,
            },
        );
    }
}

#[test]
fn extended_order_byte_needs_the_whole_64_byte_header() {
    let dir = TempDir::new().unwrap();
    let bytes = RawHeader::extended([2; 3], None, 1).bytes();
    for len in 26..64 {
        let p = write(&dir, &format!("ext{len}.vol"), &bytes[..len]);
        assert_header_error(
            &p,
            HeaderError::TooShort {
                len: len as u64,
                needed: 64,
            },
        );
    }
}

#[test]
fn a_directory_is_an_io_error() {
    let dir = TempDir::new().unwrap();
    assert_eq!(io_error(dir.path()), ErrorKind::IsADirectory);
    let sub = dir.path().join("looks-like.vol");
    std::fs::create_dir(&sub).unwrap();
    assert_eq!(io_error(&sub), ErrorKind::IsADirectory);
}

#[test]
fn a_missing_path_is_an_io_error() {
    let dir = TempDir::new().unwrap();
    assert_eq!(io_error(&dir.path().join("nope.vol")), ErrorKind::NotFound);
    assert_eq!(
        io_error(&dir.path().join("no-such-dir").join("nope.vol")),
        ErrorKind::NotFound
    );
}

// ---------------------------------------------------------------------------------
// Sizes
// ---------------------------------------------------------------------------------

#[test]
fn thesis_samples_truncated_by_one_byte() {
    let dir = TempDir::new().unwrap();
    // Linear 3 × 4 × 5: 60 samples after the 26-byte header.
    let linear = RawHeader::thesis_linear([3, 4, 5]);
    assert_eq!(linear.data_end(), 86);
    let p = write(&dir, "linear.vol", &linear.file_with(59));
    assert_header_error(
        &p,
        HeaderError::Truncated {
            expected: 86,
            actual: 85,
        },
    );
    // Bricked 10 × 4 × 1, side 4 (step 3): 3 × 1 × 1 whole bricks of 64 samples.
    let bricked = RawHeader::thesis_bricked([10, 4, 1], 4);
    assert_eq!(bricked.data_end(), 26 + 192);
    let p = write(&dir, "bricked.vol", &bricked.file_with(191));
    assert_header_error(
        &p,
        HeaderError::Truncated {
            expected: 218,
            actual: 217,
        },
    );
    // Only the header: every sample missing.
    let p = write(&dir, "header-only.vol", &linear.bytes());
    assert_header_error(
        &p,
        HeaderError::Truncated {
            expected: 86,
            actual: 26,
        },
    );
    // Controls: the exact length opens, and so do trailing bytes after the samples.
    for (name, raw) in [("linear-ok.vol", &linear), ("bricked-ok.vol", &bricked)] {
        let mut bytes = raw.file();
        let p = write(&dir, name, &bytes);
        assert_eq!(open_ok(&p).dims(), raw.dims);
        bytes.extend_from_slice(b"trailing");
        let p = write(&dir, &format!("trailing-{name}"), &bytes);
        assert_eq!(open_ok(&p).dims(), raw.dims);
    }
}

#[test]
fn extended_samples_truncated_by_one_byte() {
    let dir = TempDir::new().unwrap();
    // u16 bricked 5 × 6 × 7, side 4: 2 × 2 × 2 bricks of 64 samples of 2 bytes.
    let raw = RawHeader::extended([5, 6, 7], Some(4), 2);
    assert_eq!(raw.data_end(), 64 + 8 * 64 * 2);
    let p = write(&dir, "u16.vol", &raw.file_with(1023));
    assert_header_error(
        &p,
        HeaderError::Truncated {
            expected: 1088,
            actual: 1087,
        },
    );
    let p = write(&dir, "u16-ok.vol", &raw.file());
    assert_eq!(open_ok(&p).sample_type(), SampleType::U16);
}

#[test]
fn zero_dimension_on_each_axis() {
    let dir = TempDir::new().unwrap();
    for (a, axis) in AXES.into_iter().enumerate() {
        let mut dims = [3; 3];
        dims[a] = 0;
        let cases = [
            ("thesis", RawHeader::thesis_linear(dims)),
            ("bricked", RawHeader::thesis_bricked(dims, 4)),
            ("ext", RawHeader::extended(dims, Some(4), 2)),
        ];
        for (name, raw) in cases {
            let p = write(&dir, &format!("{name}-{axis}.vol"), &raw.file_with(4096));
            assert_header_error(&p, HeaderError::ZeroDimension { axis });
        }
    }
    // The first bad axis is reported.
    let p = write(&dir, "all.vol", &RawHeader::thesis_linear([0; 3]).bytes());
    assert_header_error(&p, HeaderError::ZeroDimension { axis: 'x' });
    let p = write(
        &dir,
        "zero-then-huge.vol",
        &RawHeader::thesis_linear([1, 0, u32::MAX]).bytes(),
    );
    assert_header_error(&p, HeaderError::ZeroDimension { axis: 'y' });
}

#[test]
fn absurd_dimension_on_each_axis() {
    let dir = TempDir::new().unwrap();
    for (a, axis) in AXES.into_iter().enumerate() {
        for value in [MAX_AXIS + 1, 1 << 31, u32::MAX] {
            let mut dims = [3; 3];
            dims[a] = value;
            let cases = [
                ("thesis", RawHeader::thesis_linear(dims)),
                ("bricked", RawHeader::thesis_bricked(dims, 255)),
            ];
            for (name, raw) in cases {
                let p = write(&dir, &format!("{name}-{axis}-{value}.vol"), &raw.bytes());
                assert_header_error(&p, HeaderError::AbsurdDimension { axis, value });
            }
            // The extended header cannot even state the length: any value is rejected
            // for the size before the length is compared.
            let mut raw = RawHeader::thesis_linear(dims);
            raw.order = 0x82;
            raw.side = 2;
            raw.ext = RawHeader::extended([1; 3], None, 2).ext;
            raw.ext_mut().data_len = 123;
            let p = write(&dir, &format!("ext-{axis}-{value}.vol"), &raw.bytes());
            assert_header_error(&p, HeaderError::AbsurdDimension { axis, value });
        }
    }
}

#[test]
fn largest_legal_sizes_never_overflow() {
    // MAX_AXIS = 2^20 per axis keeps every size below 2^64: the worst case, bricks of
    // side 2 (8 samples per cell) of u16, is (2^20 - 1)^3 · 16 bytes, just under 2^64.
    // So `SizeOverflow` cannot come out of a file; what does is the exact length
    // (computed here in 128 bits) as a mismatch or a truncation.
    let dims = [MAX_AXIS; 3];
    let mut worst = 0u128;
    for sample_type in [1u8, 2] {
        for side in std::iter::once(None).chain((2..=255).map(Some)) {
            let mut raw = RawHeader {
                dims,
                ..RawHeader::extended([1; 3], side, sample_type)
            };
            let expected = raw.expected_data_len();
            worst = worst.max(expected);
            raw.ext_mut().data_len = 0;
            let got = Header::parse(&raw.bytes(), 64);
            assert_eq!(
                got,
                Err(HeaderError::DataLengthMismatch {
                    declared: 0,
                    expected: u64::try_from(expected).expect("fits 64 bits"),
                }),
                "side {side:?}, sample type {sample_type}"
            );
        }
    }
    assert_eq!(worst, u128::from(MAX_AXIS - 1).pow(3) * 8 * 2);
    assert!(worst + 64 < 1 << 64);

    let dir = TempDir::new().unwrap();
    // Worst case with the right declared length: a (hugely) truncated file.
    let mut raw = RawHeader {
        dims,
        ..RawHeader::extended([1; 3], Some(2), 2)
    };
    let expected = u64::try_from(worst).unwrap();
    raw.ext_mut().data_len = expected;
    let p = write(&dir, "worst.vol", &raw.bytes());
    assert_header_error(
        &p,
        HeaderError::Truncated {
            expected: 64 + expected,
            actual: 64,
        },
    );
    // The same through the thesis header (u8, bricked side 2, and linear).
    for (name, raw) in [
        ("thesis-bricked.vol", RawHeader::thesis_bricked(dims, 2)),
        ("thesis-linear.vol", RawHeader::thesis_linear(dims)),
    ] {
        let p = write(&dir, name, &raw.file_with(10));
        assert_header_error(
            &p,
            HeaderError::Truncated {
                expected: raw.data_end(),
                actual: 36,
            },
        );
    }

    // Sizes past the cap do overflow, and the size arithmetic says so instead of
    // wrapping (a header that was never validated).
    let unchecked = Header::new(
        [u32::MAX; 3],
        [1.0; 3],
        Layout::Linear,
        SampleType::U16,
        Content::Scalar,
        Format::Extended,
    );
    assert_eq!(unchecked.stored_samples(), Err(HeaderError::SizeOverflow));
    assert_eq!(unchecked.data_len(), Err(HeaderError::SizeOverflow));
    assert_eq!(unchecked.data_end(), Err(HeaderError::SizeOverflow));
    assert_eq!(
        unchecked.encode(),
        Err(HeaderError::AbsurdDimension {
            axis: 'x',
            value: u32::MAX
        })
    );
    // Right at the 64-bit edge: (2^32 - 1)^2 u8 samples (+ 64) still fit exactly, twice
    // as many do not.
    let edge = |dims| {
        Header::new(
            dims,
            [1.0; 3],
            Layout::Linear,
            SampleType::U8,
            Content::Scalar,
            Format::Extended,
        )
    };
    let fits = u64::try_from(u128::from(u32::MAX).pow(2)).unwrap();
    assert_eq!(edge([u32::MAX, u32::MAX, 1]).data_end(), Ok(fits + 64));
    assert_eq!(
        edge([u32::MAX, u32::MAX, 2]).data_len(),
        Err(HeaderError::SizeOverflow)
    );
}

// ---------------------------------------------------------------------------------
// Spacing, order byte, brick side
// ---------------------------------------------------------------------------------

#[test]
fn nan_negative_zero_and_infinite_spacing() {
    let dir = TempDir::new().unwrap();
    let bad = [
        f32::NAN,
        -f32::NAN,
        f32::from_bits(0x7f80_0001), // signalling NaN
        -1.0,
        -f32::MIN_POSITIVE,
        f32::MIN,
        -0.0,
        0.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    for (a, axis) in AXES.into_iter().enumerate() {
        for (i, value) in bad.into_iter().enumerate() {
            for extended in [false, true] {
                let mut raw = if extended {
                    RawHeader::extended([2; 3], None, 1)
                } else {
                    RawHeader::thesis_linear([2; 3])
                };
                raw.spacing[a] = value;
                let p = write(&dir, &format!("{axis}{i}{extended}.vol"), &raw.file());
                match header_error(&p) {
                    HeaderError::BadSpacing {
                        axis: got,
                        value: v,
                    } => {
                        assert_eq!(got, axis);
                        assert_eq!(v.to_bits(), value.to_bits(), "spacing {value}");
                    }
                    other => panic!("spacing {value} on {axis}: got {other:?}"),
                }
            }
        }
    }
    // Control: positive finite spacing, however uneven, is accepted.
    let mut raw = RawHeader::thesis_linear([2; 3]);
    raw.spacing = [0.001, 1.0, 250.0];
    let p = write(&dir, "ok.vol", &raw.file());
    assert_eq!(open_ok(&p).spacing(), [0.001, 1.0, 250.0]);
}

/// Finite positive spacings that no scan has: a denormal, one near the largest
/// float, or one whose extent over the volume overflows world positions (they
/// once passed `info` and `convert` and failed in `render` with "camera
/// position must be finite").
#[test]
fn absurd_spacing_and_extent() {
    let dir = TempDir::new().unwrap();
    for (i, (dims, value)) in [
        ([2; 3], 1e-45f32),
        ([2; 3], 1e-16),
        ([2; 3], 3e38),
        ([2; 3], 2e15),
    ]
    .into_iter()
    .enumerate()
    {
        let mut raw = RawHeader::extended(dims, None, 1);
        raw.spacing[0] = value;
        let p = write(&dir, &format!("absurd{i}.vol"), &raw.file());
        match header_error(&p) {
            HeaderError::AbsurdSpacing {
                axis: 'x',
                value: v,
            } => {
                assert_eq!(v.to_bits(), value.to_bits(), "spacing {value}")
            }
            other => panic!("spacing {value}: got {other:?}"),
        }
    }
    // A spacing in bounds whose extent is not: said with the extent.
    let mut raw = RawHeader::extended([20, 2, 2], None, 1);
    raw.spacing[0] = 1e14;
    let p = write(&dir, "extent.vol", &raw.file());
    let e = header_error(&p);
    assert_eq!(
        e,
        HeaderError::HugeExtent {
            axis: 'x',
            spacing: 1e14,
            size: 20
        }
    );
    assert!(
        e.to_string()
            .starts_with("spacing on x is 1e14 over 20 voxels: an extent of 2e15, past the most"),
        "{e}"
    );
    // Control: the bounds themselves are read.
    for (i, value) in [1e-15f32, 5e14].into_iter().enumerate() {
        let mut raw = RawHeader::extended([2; 3], None, 1);
        raw.spacing[0] = value;
        let p = write(&dir, &format!("edge{i}.vol"), &raw.file());
        assert_eq!(open_ok(&p).spacing()[0], value);
    }
}

#[test]
fn unknown_order_byte() {
    let dir = TempDir::new().unwrap();
    for order in [0u8, 3, 4, 0x7f, 0x80, 0x83, 0xc1, 0xfe, 0xff] {
        // As a thesis header, and in front of a complete extension block.
        let mut thesis = RawHeader::thesis_linear([2; 3]);
        thesis.order = order;
        let mut ext = RawHeader::extended([2; 3], None, 1);
        ext.order = order;
        for (name, bytes) in [("thesis", thesis.file()), ("ext", ext.file())] {
            let p = write(&dir, &format!("{name}-{order:#04x}.vol"), &bytes);
            assert_header_error(&p, HeaderError::UnknownOrder(order));
        }
    }
}

#[test]
fn a_file_of_another_kind_is_called_no_volume_not_a_broken_header() {
    let dir = TempDir::new().unwrap();
    let text = b"# raycaster\n\nCPU volume rendering of huge volumes\n".repeat(4);
    for name in ["README.md", "notes", "picture.png"] {
        let p = write(&dir, name, &text);
        let e = open_fails(&p);
        assert!(
            matches!(
                e.kind,
                VolumeErrorKind::NotAVolume(HeaderError::UnknownOrder(b'r' | b' '))
            ),
            "{name}: {e:?}"
        );
        assert!(e.to_string().contains("not a volume file"), "{e}");
        // (A raw dump is the likeliest such file that is a volume.)
        assert!(
            e.to_string().contains("volgen convert FILE --raw XxYxZ"),
            "{e}"
        );
    }
    // Gzip data under a name that says no compression: said as such.
    let p = write(
        &dir,
        "scan.gz",
        &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3],
    );
    let e = open_fails(&p);
    assert!(matches!(e.kind, VolumeErrorKind::GzipUnnamed), "{e:?}");
    assert!(e.to_string().contains("holds gzip-compressed data"), "{e}");
    // A compressed .vol too (it was "unknown sample order byte 0x72").
    let p = write(
        &dir,
        "packed.vol",
        &[
            0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15,
            16, 17, 18,
        ],
    );
    let e = open_fails(&p);
    assert!(e.to_string().contains("gunzip it first"), "{e}");
    // A few bytes not named .vol: no volume (it was "shorter than the header").
    let p = write(&dir, "tiny.bin", b"0123456789");
    assert!(matches!(
        open_fails(&p).kind,
        VolumeErrorKind::NotAVolume(_)
    ));
    // Named .vol, the same bytes are a broken .vol header.
    let p = write(&dir, "broken.VOL", &text);
    assert!(matches!(
        open_fails(&p).kind,
        VolumeErrorKind::Header(HeaderError::UnknownOrder(_))
    ));
}

#[test]
fn brick_side_0_and_1_in_a_bricked_header() {
    let dir = TempDir::new().unwrap();
    for side in [0u8, 1] {
        let thesis = RawHeader::thesis_bricked([4; 3], side);
        let mut ext = RawHeader::extended([4; 3], Some(2), 1);
        ext.side = side;
        for (name, raw) in [("thesis", thesis), ("ext", ext)] {
            let p = write(&dir, &format!("{name}-{side}.vol"), &raw.file_with(4096));
            assert_header_error(&p, HeaderError::BadBrickSide(side));
        }
    }
    // Controls: side 2 is the smallest legal side; linear files ignore byte 25.
    let p = write(
        &dir,
        "side2.vol",
        &RawHeader::thesis_bricked([4; 3], 2).file(),
    );
    assert_eq!(open_ok(&p).layout(), Layout::Bricked { side: 2 });
    let mut linear = RawHeader::thesis_linear([4; 3]);
    linear.side = 1;
    let p = write(&dir, "linear-side1.vol", &linear.file());
    assert_eq!(open_ok(&p).layout(), Layout::Linear);
}

// ---------------------------------------------------------------------------------
// The extension block
// ---------------------------------------------------------------------------------

/// Writes a u8 linear 2³ extended file edited by `edit` and checks the error.
fn extended_case(dir: &TempDir, name: &str, edit: impl Fn(&mut RawExt), expected: HeaderError) {
    let mut raw = RawHeader::extended([2; 3], None, 1);
    edit(raw.ext_mut());
    // Enough bytes after the header that no field is rejected for the file length.
    let p = write(dir, name, &raw.file_with(64));
    assert_header_error(&p, expected);
}

#[test]
fn extended_bad_magic() {
    let dir = TempDir::new().unwrap();
    for (i, magic) in [*b"RCVY", *b"rcvx", *b"XVCR", *b"RCRG", [0; 4], [0xff; 4]]
        .into_iter()
        .enumerate()
    {
        extended_case(
            &dir,
            &format!("magic{i}.vol"),
            |e| e.magic = magic,
            HeaderError::BadExtensionMagic,
        );
    }
}

#[test]
fn extended_unsupported_version() {
    let dir = TempDir::new().unwrap();
    for version in [0u16, 6, 0x100, u16::MAX] {
        extended_case(
            &dir,
            &format!("v{version}.vol"),
            |e| e.version = version,
            HeaderError::UnsupportedVersion(version),
        );
    }
}

#[test]
fn extended_unknown_sample_type_code() {
    let dir = TempDir::new().unwrap();
    for code in [0u8, 3, 4, 0x81, 0xff] {
        extended_case(
            &dir,
            &format!("type{code}.vol"),
            |e| e.sample_type = code,
            HeaderError::UnknownSampleType(code),
        );
    }
}

#[test]
fn extended_unknown_content_code() {
    let dir = TempDir::new().unwrap();
    for code in [2u8, 3, 0x80, 0xff] {
        extended_case(
            &dir,
            &format!("content{code}.vol"),
            |e| e.content = code,
            HeaderError::UnknownContent(code),
        );
    }
}

#[test]
fn extended_wrong_data_offset() {
    let dir = TempDir::new().unwrap();
    for offset in [0u64, 26, 63, 65, 128, 1 << 32, u64::MAX] {
        extended_case(
            &dir,
            &format!("offset{offset}.vol"),
            |e| e.data_offset = offset,
            HeaderError::BadDataOffset(offset),
        );
    }
}

#[test]
fn extended_declared_data_length_mismatch() {
    let dir = TempDir::new().unwrap();
    // u8 linear 2³: 8 bytes.
    for declared in [0u64, 7, 9, 16, 1 << 40, u64::MAX] {
        extended_case(
            &dir,
            &format!("len{declared}.vol"),
            |e| e.data_len = declared,
            HeaderError::DataLengthMismatch {
                declared,
                expected: 8,
            },
        );
    }
    // u16 declared as if u8; bricked declared without the padding of edge bricks.
    let mut raw = RawHeader::extended([5, 6, 7], None, 2);
    raw.ext_mut().data_len = 5 * 6 * 7;
    let p = write(&dir, "u16-as-u8.vol", &raw.file_with(4096));
    assert_header_error(
        &p,
        HeaderError::DataLengthMismatch {
            declared: 210,
            expected: 420,
        },
    );
    let mut raw = RawHeader::extended([5, 6, 7], Some(4), 1);
    raw.ext_mut().data_len = 5 * 6 * 7;
    let p = write(&dir, "bricked-no-padding.vol", &raw.file_with(4096));
    assert_header_error(
        &p,
        HeaderError::DataLengthMismatch {
            declared: 210,
            expected: 8 * 64,
        },
    );
}

/// A u16 bricked extended file with a correct value-range table right after its
/// samples: (header, samples, table).
fn file_with_table() -> (RawHeader, Vec<u8>, Vec<u8>) {
    let mut raw = RawHeader::extended([5, 6, 7], Some(4), 2);
    let file = raw.file();
    let data = file[64..].to_vec();
    let table = range_table(&raw, &data);
    raw.ext_mut().ranges_offset = raw.data_end();
    (raw, data, table)
}

fn assemble(raw: &RawHeader, data: &[u8], tail: &[u8]) -> Vec<u8> {
    [raw.bytes().as_slice(), data, tail].concat()
}

#[test]
fn ranges_offset_inside_the_samples() {
    let dir = TempDir::new().unwrap();
    let (mut raw, data, table) = file_with_table();
    let data_end = raw.data_end();
    let file_len = data_end + table.len() as u64;
    for offset in [1u64, 26, 56, 63, 64, 65, data_end / 2, data_end - 1] {
        raw.ext_mut().ranges_offset = offset;
        let p = write(
            &dir,
            &format!("inside{offset}.vol"),
            &assemble(&raw, &data, &table),
        );
        assert_header_error(
            &p,
            HeaderError::BadRangesOffset {
                offset,
                data_end,
                file_len,
            },
        );
    }
}

#[test]
fn ranges_offset_past_the_end() {
    let dir = TempDir::new().unwrap();
    let (mut raw, data, table) = file_with_table();
    let data_end = raw.data_end();
    let file_len = data_end + table.len() as u64;
    // (2⁶⁴ − 1, where no table fits, is a damaged header: below.)
    for offset in [file_len, file_len + 1, 1 << 40] {
        raw.ext_mut().ranges_offset = offset;
        let p = write(
            &dir,
            &format!("past{offset}.vol"),
            &assemble(&raw, &data, &table),
        );
        assert_header_error(
            &p,
            HeaderError::BadRangesOffset {
                offset,
                data_end,
                file_len,
            },
        );
        // Past the end: most likely a file cut short, and the message says so
        // (not as an invalid header).
        let message = header_error(&p).to_string();
        assert!(
            message.starts_with(&format!(
                "the value-range table starts at byte {offset}, past the file's end"
            )) && message.contains("cut short"),
            "{message}"
        );
        let said = open_fails(&p).to_string();
        assert!(!said.contains("invalid header"), "{said}");
    }
    raw.ext_mut().ranges_offset = u64::MAX;
    let p = write(&dir, "nowhere.vol", &assemble(&raw, &data, &table));
    let message = header_error(&p).to_string();
    assert!(
        message.ends_with("where no value-range table can start: the header is damaged"),
        "{message}"
    );
    // No bytes after the samples at all: the table offset cannot be anywhere.
    raw.ext_mut().ranges_offset = data_end;
    let p = write(&dir, "no-tail.vol", &assemble(&raw, &data, &[]));
    assert_header_error(
        &p,
        HeaderError::BadRangesOffset {
            offset: data_end,
            data_end,
            file_len: data_end,
        },
    );
}

/// A well-formed table whose ranges are not the samples' (zeroed, or another
/// file's) is refused: the bricks it calls empty would not be drawn, and the
/// picture would lose them without a word. A few bricks spread over the
/// volume are checked when the file opens.
#[test]
fn a_range_table_that_disagrees_with_the_samples_is_refused() {
    let dir = TempDir::new().unwrap();
    let (raw, data, table) = file_with_table();
    assert!(data.iter().any(|&v| v > 0), "samples to disagree with");
    let mut zeroed = table.clone();
    zeroed[28..].fill(0);
    let p = write(&dir, "zeroed.vol", &assemble(&raw, &data, &zeroed));
    let err = open_fails(&p);
    assert!(
        matches!(
            err.kind,
            VolumeErrorKind::RangesDisagree { stored: [0, 0], .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("`volgen convert`"), "{err}");
    // Another volume's table of the same shape: the samples doubled.
    let doubled: Vec<u8> = data.iter().map(|v| v.saturating_mul(2)).collect();
    let p = write(&dir, "other.vol", &assemble(&raw, &doubled, &table));
    assert!(matches!(
        open_fails(&p).kind,
        VolumeErrorKind::RangesDisagree { .. }
    ));
    // The intact table opens.
    open_ok(&write(&dir, "intact.vol", &assemble(&raw, &data, &table)));
}

#[test]
fn corrupt_ranges_table() {
    let dir = TempDir::new().unwrap();
    let (raw, data, table) = file_with_table();
    // Control: the intact table opens and is the one in use.
    let p = write(&dir, "intact.vol", &assemble(&raw, &data, &table));
    let v = open_ok(&p);
    assert_eq!(v.ranges().encode(), table);
    assert_eq!(v.ranges(), &v.compute_ranges());

    let corrupt_at = |at: usize, value: u8| {
        let mut t = table.clone();
        t[at] = value;
        t
    };
    let u32_field = |at: usize, value: u32| {
        let mut t = table.clone();
        t[at..at + 4].copy_from_slice(&value.to_le_bytes());
        t
    };
    let mut lo_above_hi = table.clone();
    lo_above_hi[28..32].copy_from_slice(&[0xff, 0xff, 0, 0]);
    let mut count_plus_one = table.clone();
    count_plus_one[20..28].copy_from_slice(&9u64.to_le_bytes());
    let mut count_huge = table.clone();
    count_huge[20..28].copy_from_slice(&u64::MAX.to_le_bytes());
    let cases: Vec<(&str, Vec<u8>)> = vec![
        (
            "garbage",
            b"this is not a value-range table at all".to_vec(),
        ),
        ("one-byte", vec![0x52]),
        ("zeros", vec![0; table.len()]),
        ("magic", corrupt_at(0, b'X')),
        ("side-1", u32_field(4, 1)),
        ("side-other", u32_field(4, 5)),
        ("dims", u32_field(16, 8)),
        ("count+1", count_plus_one),
        ("count-huge", count_huge),
        ("lo>hi", lo_above_hi),
        ("truncated-body", table[..table.len() - 1].to_vec()),
        ("truncated-head", table[..27].to_vec()),
    ];
    for (name, bad) in cases {
        let p = write(&dir, &format!("{name}.vol"), &assemble(&raw, &data, &bad));
        let err = open_fails(&p);
        // A file that ends before the table can is cut off, with the numbers.
        if bad.len() < table.len() {
            let file_len = std::fs::metadata(&p).unwrap().len();
            let end = file_len - bad.len() as u64 + table.len() as u64;
            assert!(
                matches!(err.kind, VolumeErrorKind::RangesCutOff { end: e, file_len: f } if (e, f) == (end, file_len)),
                "{name}: {err}"
            );
        } else {
            assert!(
                matches!(err.kind, VolumeErrorKind::CorruptRanges),
                "{name}: {err}"
            );
        }
    }
    // The offset one byte into an intact table at the file's end: the table
    // it points to would end one byte past it.
    let mut shifted = raw.clone();
    shifted.ext_mut().ranges_offset += 1;
    let p = write(&dir, "shifted.vol", &assemble(&shifted, &data, &table));
    assert!(matches!(
        open_fails(&p).kind,
        VolumeErrorKind::RangesCutOff { .. }
    ));
}

#[test]
fn a_garbage_ranges_sidecar_of_a_thesis_file_is_ignored() {
    let dir = TempDir::new().unwrap();
    let raw = RawHeader::thesis_bricked([9, 5, 3], 3);
    let p = write(&dir, "thesis.vol", &raw.file());
    let sidecar = ranges_sidecar_path(&p);
    for junk in [&b""[..], b"RCRS", b"RCRS\x01\0\0\0garbage", &[0xff; 300]] {
        std::fs::write(&sidecar, junk).unwrap();
        let v = open_ok(&p);
        assert_eq!(v.ranges(), &v.compute_ranges());
    }
}

/// docs/format.md: "content: 1 = labels (object ids, u8 only)"; `convert` and
/// `generate` refuse u16 labels, but the reader accepts them.
#[test]
fn u16_label_volumes_are_rejected() {
    let dir = TempDir::new().unwrap();
    let mut raw = RawHeader::extended([2; 3], None, 2);
    raw.ext_mut().content = 1;
    let p = write(&dir, "u16-labels.vol", &raw.file());
    assert_eq!(header_error(&p), HeaderError::LabelsNotU8(SampleType::U16));
    // Generating one is a typed error too, not a panic, and writes nothing.
    let h = Header::new(
        [4; 3],
        [1.0; 3],
        Layout::Linear,
        SampleType::U16,
        Content::Labels,
        Format::Extended,
    );
    let out = dir.path().join("gen-u16-labels.vol");
    let scene = raycaster::synth::SceneKind::Shells.build([4; 3], 0);
    let err = raycaster::generate::generate(
        scene.as_ref(),
        &h,
        &out,
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap_err();
    assert!(matches!(
        err.kind,
        VolumeErrorKind::Header(HeaderError::LabelsNotU8(SampleType::U16))
    ));
    assert!(!out.exists());
}

// ---------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        // One new test file only: no regression files next to it.
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Parses `bytes` as the start of a file of `file_len` bytes. Whatever is accepted
/// must satisfy every rule of the format.
fn parse_and_check(bytes: &[u8], file_len: u64) -> Result<Option<Header>, TestCaseError> {
    let parsed = Header::parse(bytes, file_len);
    if bytes.len() < 26 || file_len < 26 {
        prop_assert_eq!(
            parsed.clone(),
            Err(HeaderError::TooShort {
                len: file_len,
                needed: 26
            })
        );
    }
    let Ok(h) = parsed else { return Ok(None) };
    prop_assert!(
        h.dims.iter().all(|d| (1..=MAX_AXIS).contains(d)),
        "dims {:?}",
        h.dims
    );
    prop_assert!(
        h.spacing.iter().all(|s| s.is_finite() && *s > 0.0),
        "spacing {:?}",
        h.spacing
    );
    let data_end = h.data_end();
    prop_assert!(
        matches!(data_end, Ok(end) if end <= file_len),
        "data end {:?} past file length {}",
        data_end,
        file_len
    );
    let data_end = data_end.unwrap();
    match h.format {
        Format::Thesis => {
            prop_assert_eq!(h.data_offset, THESIS_HEADER_LEN);
            prop_assert_eq!(h.sample_type, SampleType::U8);
            prop_assert_eq!(h.content, Content::Scalar);
            prop_assert_eq!(h.ranges_offset, None);
        }
        Format::Extended => prop_assert_eq!(h.data_offset, h.standard_data_offset()),
    }
    prop_assert!(bytes.len() as u64 >= h.data_offset);
    let side = match h.layout {
        Layout::Linear => None,
        Layout::Bricked { side } => {
            prop_assert!(side >= 2);
            Some(side)
        }
    };
    prop_assert_eq!(
        u128::from(h.data_len().unwrap()),
        stored_samples(h.dims, side) * u128::from(h.sample_type.size())
    );
    if let Some(offset) = h.ranges_offset {
        prop_assert!(data_end <= offset && offset < file_len);
    }
    prop_assert_eq!(h.validate(), Ok(()));
    // Only the header bytes matter, and the header survives a round trip.
    let longer = [bytes, &[0xa5; 80][..]].concat();
    prop_assert_eq!(Header::parse(&longer, file_len), Ok(h.clone()));
    let encoded = h.encode().unwrap();
    prop_assert_eq!(encoded.len() as u64, h.data_offset);
    prop_assert_eq!(Header::parse(&encoded, file_len), Ok(h.clone()));
    Ok(Some(h))
}

/// Spacings from 0.01 to 100 in steps of 0.01. Drawn from integers because
/// proptest 1.12's own `f32` range sampler trips a debug assertion of its own
/// (`self.low - result < initial.step`) on rare draws.
fn spacing_value() -> impl Strategy<Value = f32> {
    (1u32..=10_000).prop_map(|hundredths| hundredths as f32 / 100.0)
}

/// Valid small headers of every kind (thesis/extended, linear/bricked, u8/u16).
fn valid_raw_header() -> impl Strategy<Value = RawHeader> {
    (
        prop::array::uniform3(1u32..=12),
        prop::array::uniform3(prop_oneof![Just(1.0f32), spacing_value()]),
        prop::option::of(2u8..=6),
        any::<bool>(),
        1u8..=2,
        any::<bool>(),
    )
        .prop_map(|(dims, spacing, side, extended, sample_type, labels)| {
            let mut raw = match (extended, side) {
                (true, _) => RawHeader::extended(dims, side, sample_type),
                (false, None) => RawHeader::thesis_linear(dims),
                (false, Some(side)) => RawHeader::thesis_bricked(dims, side),
            };
            raw.spacing = spacing;
            if let Some(ext) = &mut raw.ext {
                // Labels are u8 only (docs/format.md).
                ext.content = u8::from(labels && sample_type == 1);
            }
            raw
        })
}

/// What parsing `raw`'s own bytes gives in a file of `file_len` bytes: the
/// header; `Truncated` when the file ends before its samples do; `TooShort`
/// when it ends inside the header itself.
fn unflipped_outcome(raw: &RawHeader, file_len: u64) -> Result<Header, HeaderError> {
    if file_len < raw.header_len() {
        Err(HeaderError::TooShort {
            len: file_len,
            needed: raw.header_len(),
        })
    } else if file_len < raw.data_end() {
        Err(HeaderError::Truncated {
            expected: raw.data_end(),
            actual: file_len,
        })
    } else {
        Ok(raw.parsed())
    }
}

/// A one-voxel volume's header in files that end before, inside and after its
/// sample (the property test above found the file ending inside the header
/// expected as `Truncated`; the parser says `TooShort`, the more precise error).
#[test]
fn a_valid_header_in_a_short_file_is_too_short_or_truncated() {
    for raw in [
        RawHeader::thesis_linear([1, 1, 1]),
        RawHeader::extended([1, 1, 1], None, 1),
    ] {
        let bytes = raw.bytes();
        let header_len = raw.header_len();
        for file_len in header_len - 3..=raw.data_end() + 1 {
            let expected = unflipped_outcome(&raw, file_len);
            assert_eq!(Header::parse(&bytes, file_len), expected, "{file_len}");
        }
        assert!(matches!(
            Header::parse(&bytes, header_len - 1),
            Err(HeaderError::TooShort { .. })
        ));
        assert!(matches!(
            Header::parse(&bytes, header_len),
            Err(HeaderError::Truncated { .. })
        ));
        assert!(Header::parse(&bytes, raw.data_end()).is_ok());
    }
}

/// XORs `value` (non-zero) into the byte at `at` of `bytes`.
fn flip(bytes: &mut [u8], at: Index, value: u8) {
    let i = at.index(bytes.len());
    bytes[i] ^= value;
}

/// Deterministic filler bytes (xorshift) for samples and gaps.
fn filler(seed: u64, len: usize) -> Vec<u8> {
    let mut s = seed | 1;
    (0..len)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 24) as u8
        })
        .collect()
}

/// The sample of voxel `v` straight from the file bytes, by the layout rules of
/// docs/format.md (independent of the library's views).
fn expected_voxel(file: &[u8], h: &Header, v: [u32; 3]) -> u16 {
    let [dx, dy, dz] = h.dims.map(|d| d as usize);
    let [x, y, z] = v.map(|c| c as usize);
    let index = match h.layout {
        Layout::Linear => (x * dy + y) * dz + z,
        Layout::Bricked { side } => {
            let s = usize::from(side);
            let step = s - 1;
            let counts = [dx, dy, dz].map(|d| (d.saturating_sub(1)).div_ceil(step).max(1));
            let b = [0, 1, 2].map(|a| ([x, y, z][a] / step).min(counts[a] - 1));
            let l = [0, 1, 2].map(|a| [x, y, z][a] - b[a] * step);
            let brick = (b[0] * counts[1] + b[1]) * counts[2] + b[2];
            brick * s * s * s + (l[0] * s + l[1]) * s + l[2]
        }
    };
    let size = h.sample_type.size() as usize;
    let at = h.data_offset as usize + index * size;
    match h.sample_type {
        SampleType::U8 => u16::from(file[at]),
        SampleType::U16 => u16::from_le_bytes([file[at], file[at + 1]]),
    }
}

/// Every voxel of an opened volume is the one in the file.
fn check_volume(v: &Volume, file: &[u8]) -> Result<(), TestCaseError> {
    let h = v.header();
    let [dx, dy, dz] = h.dims;
    // Every voxel is stored at least once, so this loop is bounded by the file.
    prop_assert!(u64::from(dx) * u64::from(dy) * u64::from(dz) <= file.len() as u64);
    for x in 0..dx {
        for y in 0..dy {
            for z in 0..dz {
                let got = v.voxel([x, y, z]);
                prop_assert!(got <= v.sample_type().max_value());
                prop_assert_eq!(
                    got,
                    expected_voxel(file, h, [x, y, z]),
                    "at {:?}",
                    [x, y, z]
                );
            }
        }
    }
    prop_assert_eq!(v.ranges().grid(), &h.block_grid(LINEAR_RANGE_SIDE));
    if h.ranges_offset.is_none() {
        prop_assert_eq!(v.ranges(), &v.compute_ranges());
    }
    Ok(())
}

/// Writes `file` to a fresh directory and opens it mapped and into RAM: the two
/// agree, errors name the file and are the ones `Header::parse` gives, and whatever
/// opens reads back the file's samples.
fn open_and_check(file: &[u8]) -> Result<(), TestCaseError> {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "random.vol", file);
    // What `Volume::open` reads before parsing: the longest header of any version.
    let head = file.len().min(MAX_HEADER_LEN as usize);
    let parsed = Header::parse(&file[..head], file.len() as u64);
    let mapped = Volume::open(&path);
    let in_ram = Volume::open_with(&path, ram());
    match (mapped, in_ram) {
        (Err(a), Err(b)) => {
            prop_assert_eq!(a.to_string(), b.to_string());
            prop_assert_eq!(&a.path, &path);
            let shown = path.display().to_string();
            prop_assert!(a.to_string().contains(&shown));
            match (&parsed, &a.kind) {
                // Debug, not ==: a NaN spacing in the error is not equal to itself.
                (Err(p), VolumeErrorKind::Header(h)) => {
                    prop_assert_eq!(format!("{p:?}"), format!("{h:?}"));
                }
                // (A header whose x size reads "RCPS" or "RCRS": a sidecar's.)
                (Err(_), VolumeErrorKind::Sidecar { .. }) => {}
                // (A mutated table, or samples, that the spot check finds
                // disagreeing is refused as damaged.)
                (
                    Ok(h),
                    VolumeErrorKind::CorruptRanges
                    | VolumeErrorKind::RangesCutOff { .. }
                    | VolumeErrorKind::RangesDisagree { .. },
                ) => {
                    prop_assert!(h.ranges_offset.is_some())
                }
                (p, k) => prop_assert!(false, "parse gave {:?} but open {:?}", p, k),
            }
        }
        (Ok(a), Ok(b)) => {
            prop_assert_eq!(Ok(a.header().clone()), parsed);
            prop_assert_eq!(a.header(), b.header());
            prop_assert_eq!(a.ranges(), b.ranges());
            check_volume(&a, file)?;
            check_volume(&b, file)?;
        }
        (a, b) => prop_assert!(
            false,
            "mapped open ok: {}, RAM open ok: {}",
            a.is_ok(),
            b.is_ok()
        ),
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(3000))]

    /// Random bytes of any length, against any file length.
    #[test]
    fn parse_random_bytes_never_panics(
        bytes in prop::collection::vec(any::<u8>(), 0..200),
        file_len in prop_oneof![any::<u64>(), 0u64..4096, Just(u64::MAX)],
    ) {
        parse_and_check(&bytes, file_len)?;
        parse_and_check(&bytes, bytes.len() as u64)?;
    }

    /// Random bytes behind a plausible order byte and extension block, so that the
    /// later checks are reached too.
    #[test]
    fn parse_random_fields_never_panics(
        mut bytes in prop::collection::vec(any::<u8>(), 64),
        order in prop_oneof![1u8..=2, 0x81u8..=0x82],
        file_len in prop_oneof![any::<u64>(), 0u64..1 << 20],
    ) {
        bytes[24] = order;
        bytes[26..30].copy_from_slice(b"RCVX");
        bytes[30..32].copy_from_slice(&1u16.to_le_bytes());
        parse_and_check(&bytes, file_len)?;
    }

    /// Valid headers with random bytes flipped, against file lengths near and far
    /// from where their samples end.
    #[test]
    fn parse_flipped_valid_headers_never_panics(
        raw in valid_raw_header(),
        flips in prop::collection::vec((any::<Index>(), 1u8..=255), 0..6),
        delta in -4i64..=64,
        any_len in any::<u64>(),
        use_any_len in prop::bool::weighted(0.2),
    ) {
        let mut bytes = raw.bytes();
        let unflipped = flips.is_empty();
        for (at, value) in flips {
            flip(&mut bytes, at, value);
        }
        let file_len = if use_any_len {
            any_len
        } else {
            raw.data_end().saturating_add_signed(delta)
        };
        let parsed = parse_and_check(&bytes, file_len)?;
        if unflipped {
            prop_assert_eq!(Header::parse(&bytes, file_len), unflipped_outcome(&raw, file_len));
            if file_len >= raw.data_end() {
                prop_assert_eq!(parsed, Some(raw.parsed()));
            }
        }
    }
}

proptest! {
    #![proptest_config(config(200))]

    /// Random bytes written to a file.
    #[test]
    fn open_random_files_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        open_and_check(&bytes)?;
    }
}

proptest! {
    #![proptest_config(config(300))]

    /// Valid files (samples, optionally a range table and trailing bytes) with bytes
    /// flipped, mostly in the header, and lengths a little off.
    #[test]
    fn open_mutated_valid_files_never_panics(
        raw in valid_raw_header(),
        seed in any::<u64>(),
        with_table in any::<bool>(),
        gap in 0usize..8,
        flips in prop::collection::vec((any::<Index>(), prop::bool::weighted(0.7), 1u8..=255), 0..4),
        len_delta in prop_oneof![3 => Just(0i64), 1 => -3i64..=3],
    ) {
        let mut raw = raw;
        let data = filler(seed, usize::try_from(raw.expected_data_len()).unwrap());
        let mut tail = filler(!seed, gap);
        if with_table && raw.ext.is_some() {
            raw.ext_mut().ranges_offset = raw.data_end() + gap as u64;
            tail.extend(range_table(&raw, &data));
        }
        let mut file = assemble(&raw, &data, &tail);
        let header_len = raw.header_len() as usize;
        for (at, in_header, value) in flips {
            let span = if in_header { header_len } else { file.len() };
            flip(&mut file[..span], at, value);
        }
        let len = (file.len() as i64 + len_delta) as usize;
        file.resize(len, 0);
        open_and_check(&file)?;
    }
}
