//! Hostile `.vol` files: every validation error is typed and names the file; random
//! header bytes never panic and never read out of bounds.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use raycaster::volume::{
    Access, Header, HeaderError, MAX_AXIS, OpenOptions, Volume, VolumeError, VolumeErrorKind,
};

/// A header as bytes: the thesis's 26 bytes, or 64 with the extension block.
#[derive(Clone)]
struct RawHeader {
    dims: [u32; 3],
    spacing: [f32; 3],
    order: u8,
    side: u8,
    ext: Option<Ext>,
}

#[derive(Clone)]
struct Ext {
    magic: [u8; 4],
    version: u16,
    sample: u8,
    content: u8,
    data_offset: u64,
    data_len: u64,
    ranges: u64,
}

impl RawHeader {
    fn thesis(dims: [u32; 3], order: u8, side: u8) -> Self {
        RawHeader {
            dims,
            spacing: [1.0; 3],
            order,
            side,
            ext: None,
        }
    }

    fn extended(dims: [u32; 3], sample: u8) -> Self {
        let n: u64 = dims.iter().map(|&d| u64::from(d)).product();
        RawHeader {
            dims,
            spacing: [1.0; 3],
            order: 0x81,
            side: 0,
            ext: Some(Ext {
                magic: *b"RCVX",
                version: 1,
                sample,
                content: 0,
                data_offset: 64,
                data_len: n * u64::from(sample),
                ranges: 0,
            }),
        }
    }

    fn bytes(&self) -> Vec<u8> {
        let mut b = Vec::new();
        self.dims
            .iter()
            .for_each(|d| b.extend_from_slice(&d.to_le_bytes()));
        self.spacing
            .iter()
            .for_each(|s| b.extend_from_slice(&s.to_le_bytes()));
        b.push(self.order);
        b.push(self.side);
        if let Some(e) = &self.ext {
            b.extend_from_slice(&e.magic);
            b.extend_from_slice(&e.version.to_le_bytes());
            b.push(e.sample);
            b.push(e.content);
            b.extend_from_slice(&[0; 6]);
            b.extend_from_slice(&e.data_offset.to_le_bytes());
            b.extend_from_slice(&e.data_len.to_le_bytes());
            b.extend_from_slice(&e.ranges.to_le_bytes());
        }
        b
    }

    /// The header followed by `samples` zero bytes.
    fn file(&self, samples: usize) -> Vec<u8> {
        let mut b = self.bytes();
        b.resize(b.len() + samples, 0);
        b
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Opens `path` mapped and in RAM; both must fail the same way. Returns the error.
fn open_err(path: &Path) -> VolumeError {
    let mapped = Volume::open(path).expect_err("mapped open must fail");
    let ram = Volume::open_with(
        path,
        OpenOptions {
            access: Access::Ram,
            ..OpenOptions::default()
        },
    )
    .expect_err("RAM open must fail");
    assert_eq!(mapped.to_string(), ram.to_string());
    assert!(
        mapped.to_string().contains(&path.display().to_string()),
        "error names the file: {mapped}"
    );
    mapped
}

fn header_err(path: &Path) -> HeaderError {
    match open_err(path).kind {
        VolumeErrorKind::Header(h) => h,
        other => panic!("expected a header error, got {other:?}"),
    }
}

#[test]
fn missing_files_directories_and_short_files() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.vol");
    assert!(matches!(open_err(&missing).kind, VolumeErrorKind::Io(_)));
    assert!(matches!(open_err(dir.path()).kind, VolumeErrorKind::Io(_)));
    let empty = write(dir.path(), "empty.vol", &[]);
    assert_eq!(
        header_err(&empty),
        HeaderError::TooShort { len: 0, needed: 26 }
    );
    let short = write(dir.path(), "short.vol", &[1; 25]);
    assert_eq!(
        header_err(&short),
        HeaderError::TooShort {
            len: 25,
            needed: 26
        }
    );
    let ext = RawHeader::extended([2; 3], 1).bytes();
    let short_ext = write(dir.path(), "short-ext.vol", &ext[..40]);
    assert_eq!(
        header_err(&short_ext),
        HeaderError::TooShort {
            len: 40,
            needed: 64
        }
    );
}

#[test]
fn truncated_samples() {
    let dir = tempfile::tempdir().unwrap();
    let h = RawHeader::thesis([3, 4, 5], 1, 0);
    let p = write(dir.path(), "t.vol", &h.file(59));
    assert_eq!(
        header_err(&p),
        HeaderError::Truncated {
            expected: 86,
            actual: 85
        }
    );
    // Bricked: 3 bricks of 4³ on x (size 10, step 3), 1 on y and z.
    let h = RawHeader::thesis([10, 4, 4], 2, 4);
    let p = write(dir.path(), "tb.vol", &h.file(3 * 64 - 1));
    assert_eq!(
        header_err(&p),
        HeaderError::Truncated {
            expected: 26 + 192,
            actual: 26 + 191
        }
    );
    let p = write(dir.path(), "ok.vol", &h.file(3 * 64));
    assert_eq!(Volume::open(&p).unwrap().dims(), [10, 4, 4]);
}

#[test]
fn zero_and_absurd_dimensions() {
    let dir = tempfile::tempdir().unwrap();
    for (axis, name) in ['x', 'y', 'z'].iter().zip(0..) {
        let mut dims = [4; 3];
        dims[name] = 0;
        let p = write(
            dir.path(),
            &format!("zero{name}.vol"),
            &RawHeader::thesis(dims, 1, 0).file(0),
        );
        assert_eq!(header_err(&p), HeaderError::ZeroDimension { axis: *axis });
        dims[name] = MAX_AXIS + 1;
        let p = write(
            dir.path(),
            &format!("huge{name}.vol"),
            &RawHeader::thesis(dims, 1, 0).file(0),
        );
        assert_eq!(
            header_err(&p),
            HeaderError::AbsurdDimension {
                axis: *axis,
                value: MAX_AXIS + 1
            }
        );
    }
    // Huge but legal sizes are a truncation (the file cannot hold 2^60 samples).
    let p = write(
        dir.path(),
        "big.vol",
        &RawHeader::thesis([MAX_AXIS; 3], 1, 0).file(10),
    );
    assert!(matches!(header_err(&p), HeaderError::Truncated { .. }));
}

#[test]
fn largest_sizes_are_computed_exactly_without_wrapping() {
    // The worst case the axis cap allows: 2^20 per axis in bricks of side 2 (one cell
    // each), u16: (2^20 - 1)^3 bricks × 8 samples × 2 bytes, just below 2^64.
    let mut h = RawHeader::extended([MAX_AXIS; 3], 2);
    h.order = 0x82;
    h.side = 2;
    h.ext.as_mut().unwrap().data_len = 0;
    let expected = u64::from(MAX_AXIS - 1).pow(3) * 16;
    assert_eq!(
        Header::parse(&h.bytes(), 64),
        Err(HeaderError::DataLengthMismatch {
            declared: 0,
            expected
        })
    );
    h.ext.as_mut().unwrap().data_len = expected;
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "huge.vol", &h.bytes());
    assert_eq!(
        header_err(&p),
        HeaderError::Truncated {
            expected: 64 + expected,
            actual: 64
        }
    );
}

#[test]
fn bad_spacing() {
    let dir = tempfile::tempdir().unwrap();
    for (i, bad) in [f32::NAN, -1.0, 0.0, f32::INFINITY].into_iter().enumerate() {
        let mut h = RawHeader::thesis([2; 3], 1, 0);
        h.spacing[i % 3] = bad;
        let p = write(dir.path(), &format!("sp{i}.vol"), &h.file(8));
        match header_err(&p) {
            HeaderError::BadSpacing { axis, value } => {
                assert_eq!(axis, ['x', 'y', 'z'][i % 3]);
                assert!(value.is_nan() == bad.is_nan() && (bad.is_nan() || value == bad));
            }
            other => panic!("expected BadSpacing, got {other:?}"),
        }
    }
}

#[test]
fn unknown_order_and_bad_brick_sides() {
    let dir = tempfile::tempdir().unwrap();
    for order in [0u8, 3, 0x83, 0xff] {
        let p = write(
            dir.path(),
            &format!("o{order}.vol"),
            &RawHeader::thesis([2; 3], order, 0).file(8),
        );
        assert_eq!(header_err(&p), HeaderError::UnknownOrder(order));
    }
    for side in [0u8, 1] {
        let p = write(
            dir.path(),
            &format!("s{side}.vol"),
            &RawHeader::thesis([2; 3], 2, side).file(64),
        );
        assert_eq!(header_err(&p), HeaderError::BadBrickSide(side));
    }
}

#[test]
fn extended_header_fields_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let base = RawHeader::extended([2; 3], 1);
    let case = |name: &str, edit: &dyn Fn(&mut Ext), expected: HeaderError| {
        let mut h = base.clone();
        edit(h.ext.as_mut().unwrap());
        let p = write(dir.path(), name, &h.file(8));
        assert_eq!(header_err(&p), expected, "{name}");
    };
    case(
        "magic.vol",
        &|e| e.magic = *b"RCVY",
        HeaderError::BadExtensionMagic,
    );
    case(
        "version.vol",
        &|e| e.version = 2,
        HeaderError::UnsupportedVersion(2),
    );
    case(
        "type.vol",
        &|e| e.sample = 3,
        HeaderError::UnknownSampleType(3),
    );
    case(
        "content.vol",
        &|e| e.content = 2,
        HeaderError::UnknownContent(2),
    );
    case(
        "offset.vol",
        &|e| e.data_offset = 26,
        HeaderError::BadDataOffset(26),
    );
    case(
        "len.vol",
        &|e| e.data_len = 9,
        HeaderError::DataLengthMismatch {
            declared: 9,
            expected: 8,
        },
    );
    case(
        "ranges-inside.vol",
        &|e| e.ranges = 70,
        HeaderError::BadRangesOffset {
            offset: 70,
            data_end: 72,
            file_len: 72,
        },
    );
    case(
        "ranges-past.vol",
        &|e| e.ranges = 72,
        HeaderError::BadRangesOffset {
            offset: 72,
            data_end: 72,
            file_len: 72,
        },
    );
}

#[test]
fn corrupt_range_table() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = RawHeader::extended([2; 3], 1);
    h.ext.as_mut().unwrap().ranges = 72;
    let mut bytes = h.file(8);
    bytes.extend_from_slice(b"garbage, not a table");
    let p = write(dir.path(), "table.vol", &bytes);
    assert!(matches!(open_err(&p).kind, VolumeErrorKind::CorruptRanges));
}

fn valid_header_bytes() -> Vec<u8> {
    let mut h = RawHeader::extended([5, 6, 7], 2);
    h.order = 0x82;
    h.side = 4;
    // 2 × 2 × 2 bricks of 4³ u16.
    h.ext.as_mut().unwrap().data_len = 8 * 64 * 2;
    h.bytes()
}

fn check_parsed(bytes: &[u8], file_len: u64) {
    if let Ok(h) = Header::parse(bytes, file_len) {
        assert!(h.data_end().unwrap() <= file_len);
        assert!(h.dims.iter().all(|&d| (1..=MAX_AXIS).contains(&d)));
        assert!(h.spacing.iter().all(|s| s.is_finite() && *s > 0.0));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200), file_len in any::<u64>()) {
        check_parsed(&bytes, file_len);
        check_parsed(&bytes, bytes.len() as u64);
    }

    #[test]
    fn flipped_valid_headers_never_panic(flips in proptest::collection::vec((0usize..64, any::<u8>()), 1..6), extra in 0u64..4096) {
        let mut bytes = valid_header_bytes();
        for (at, v) in flips {
            bytes[at] = v;
        }
        check_parsed(&bytes, 64 + extra);
        check_parsed(&bytes, 64 + 1024 + extra);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Whole files: random headers over random sample bytes open or fail cleanly, and
    /// whatever opens can be read everywhere inside its dims.
    #[test]
    fn random_files_open_or_fail_cleanly(
        flips in proptest::collection::vec((0usize..64, any::<u8>()), 0..4),
        tail in proptest::collection::vec(any::<u8>(), 0..2000),
    ) {
        let mut bytes = valid_header_bytes();
        for (at, v) in flips {
            bytes[at] = v;
        }
        bytes.extend_from_slice(&tail);
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), "random.vol", &bytes);
        if let Ok(v) = Volume::open(&p) {
            let [dx, dy, dz] = v.dims();
            for c in [[0, 0, 0], [dx - 1, dy - 1, dz - 1], [dx / 2, dy / 2, dz / 2]] {
                let value = v.voxel(c);
                prop_assert!(value <= v.sample_type().max_value());
            }
            prop_assert_eq!(v.ranges().as_slice().len() as u64, v.ranges().grid().block_count());
        }
    }
}
