//! The hostile-input corpus: writes malformed and hostile volume, scan,
//! transfer-function and scene files into a folder.
//!
//! Included by the corpus tests of `volgen` (`volgen/tests/hostile_corpus.rs`) and
//! `raycaster` (`cli/tests/hostile_corpus.rs`), which run every tool on every file
//! with a timeout and assert a clean error or a valid result: no panic, no hang, no
//! partial output. Add a case here when a new kind of bad input is found.

#![allow(unsafe_code)] // libc without a safe wrapper: FIFOs, signals, resource limits
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// What a corpus file is, so each tool gets the files it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A volume or scan (`volgen info`, `volgen convert`, `raycaster render FILE`).
    Volume,
    /// A transfer-function file (`raycaster render --tf FILE`).
    Transfer,
    /// A two-level scene (`raycaster render --segments FILE`).
    Scene,
}

/// One corpus file.
#[derive(Clone, Debug)]
pub struct Case {
    /// The file (or folder, or named pipe).
    pub path: PathBuf,
    /// What it poses as.
    pub kind: Kind,
    /// Whether a tool may accept it (a valid file); otherwise it must be refused.
    pub valid: bool,
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0, "mkfifo");
}

/// A NIfTI-1 single file of `dims` u8 samples (value x + y + z) with `pixdim`.
pub fn nifti(dims: [i16; 3], pixdim: [f32; 3], vox_offset: f32) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim = [3, dims[0], dims[1], dims[2], 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&2i16.to_le_bytes());
    h[72..74].copy_from_slice(&8i16.to_le_bytes());
    for (i, p) in [1.0, pixdim[0], pixdim[1], pixdim[2]].iter().enumerate() {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
    }
    h[108..112].copy_from_slice(&vox_offset.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    let n = dims.iter().map(|&d| d.max(0) as usize).product::<usize>();
    h.extend((0..n).map(|i| (i % 7) as u8));
    h
}

/// A NRRD file with attached raw u8 data of 4³ samples and `extra` header lines.
pub fn nrrd(extra: &str) -> Vec<u8> {
    nrrd_sized("4 4 4", extra)
}

/// A NRRD file declaring `sizes`, with attached raw u8 data of 4³ samples.
pub fn nrrd_sized(sizes: &str, extra: &str) -> Vec<u8> {
    let mut b =
        format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: {sizes}\nencoding: raw\n{extra}\n")
            .into_bytes();
    b.extend((0..64).map(|i| i as u8));
    b
}

/// A MetaImage `.mha` with attached u8 data of 4³ samples and `extra` lines.
pub fn mha(extra: &str, dims: &str) -> Vec<u8> {
    let mut b = format!(
        "ObjectType = Image\nNDims = 3\nDimSize = {dims}\nElementType = MET_UCHAR\n{extra}ElementDataFile = LOCAL\n"
    )
    .into_bytes();
    b.extend((0..64).map(|i| i as u8));
    b
}

/// A valid `.vol` file (16³ u8, bricked, extended header with its range table).
pub fn valid_vol(path: &Path) {
    use raycaster::volume::{Content, Format, Header, Layout, SampleType};
    let header = Header::new(
        [16; 3],
        [1.0; 3],
        Layout::Bricked { side: 8 },
        SampleType::U8,
        Content::Scalar,
        Format::Extended,
    );
    let scene = raycaster::synth::SceneKind::Shapes.build([16; 3], 1);
    raycaster::generate::generate(
        scene.as_ref(),
        &header,
        path,
        &raycaster::io::WriteOptions::default(),
        &raycaster::job::Job::silent(),
    )
    .expect("a valid corpus volume");
}

/// Writes the corpus into `dir` and lists its cases.
pub fn write(dir: &Path) -> Vec<Case> {
    let cases = std::cell::RefCell::new(Vec::new());
    let file = |name: &str, bytes: &[u8], kind: Kind, valid: bool| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        cases.borrow_mut().push(Case { path, kind, valid });
    };
    use Kind::{Scene, Transfer, Volume};

    // --- .vol files
    let good = dir.join("good.vol");
    valid_vol(&good);
    let bytes = std::fs::read(&good).unwrap();
    file("good-copy.vol", &bytes, Volume, true);
    file("empty.vol", b"", Volume, false);
    file("tiny.vol", &[1, 0, 0], Volume, false);
    file("header-only.vol", &bytes[..64], Volume, false);
    file("truncated.vol", &bytes[..bytes.len() / 2], Volume, false);
    let mut corrupt_table = bytes.clone();
    let at = corrupt_table
        .windows(4)
        .rposition(|w| w == b"RCRG")
        .unwrap();
    corrupt_table[at..at + 4].copy_from_slice(b"JUNK");
    // Renders and `info` refuse it; `convert` reads the samples and says so.
    file("corrupt-table.vol", &corrupt_table, Volume, false);
    let mut huge_dims = bytes.clone();
    huge_dims[0..4].copy_from_slice(&u32::MAX.to_le_bytes());
    file("huge-dims.vol", &huge_dims, Volume, false);
    let mut zero_dims = bytes.clone();
    zero_dims[4..8].copy_from_slice(&0u32.to_le_bytes());
    file("zero-dims.vol", &zero_dims, Volume, false);
    file("random.vol", &pseudo_random(5000, 7), Volume, false);
    let mut labels = Vec::new();
    {
        use raycaster::volume::{Content, Format, Header, Layout, SampleType};
        let h = Header::new(
            [8; 3],
            [1.0; 3],
            Layout::Linear,
            SampleType::U8,
            Content::Labels,
            Format::Extended,
        );
        labels.extend(h.encode().unwrap());
        labels.extend((0..512).map(|i| (i % 3) as u8));
    }
    // A label volume: `info`/`convert` read it, `render` refuses it as data.
    file("x.labels.vol", &labels, Volume, false);

    // A thesis-format file whose `.ranges` sidecar is a named pipe: never read.
    {
        use raycaster::volume::{Content, Format, Header, Layout, SampleType};
        let h = Header::new(
            [8; 3],
            [1.0; 3],
            Layout::Linear,
            SampleType::U8,
            Content::Scalar,
            Format::Thesis,
        );
        let mut thesis = h.encode().unwrap();
        thesis.extend((0..512).map(|i| (i % 200) as u8));
        file("thesis.vol", &thesis, Volume, true);
        mkfifo(&dir.join("thesis.vol.ranges"));
    }

    // --- NRRD
    file("good.nrrd", &nrrd(""), Volume, true);
    file(
        "nan-spacing.nrrd",
        &nrrd("spacings: 1 nan 1\n"),
        Volume,
        false,
    );
    file(
        "inf-spacing.nrrd",
        &nrrd("spacings: 1 inf 1\n"),
        Volume,
        false,
    );
    file(
        "tiny-spacing.nrrd",
        &nrrd("spacings: 1e-45 1 1\n"),
        Volume,
        false,
    );
    file(
        "wrapping-skip.nrrd",
        &nrrd(&format!("byte skip: {}\n", u64::MAX - 60)),
        Volume,
        false,
    );
    file(
        "huge-skip.nrrd",
        &nrrd("byte skip: 1000000\n"),
        Volume,
        false,
    );
    file(
        "huge-sizes.nrrd",
        &nrrd_sized("4000000 4000000 4000000", ""),
        Volume,
        false,
    );
    file(
        "gzip-garbage.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n\x1f\x8b\x08\x00garbage",
        Volume,
        false,
    );
    file(
        "detached-missing.nhdr",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: nowhere.raw\n\n",
        Volume,
        false,
    );
    file(
        "detached-self.nhdr",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: .\n\n",
        Volume,
        false,
    );

    // --- NIfTI
    file(
        "good.nii",
        &nifti([4, 4, 4], [1.0, 1.0, 2.0], 352.0),
        Volume,
        true,
    );
    file(
        "denormal-pixdim.nii",
        &nifti([4, 4, 4], [1e-45, 1.0, 1.0], 352.0),
        Volume,
        false,
    );
    file(
        "nan-pixdim.nii",
        &nifti([4, 4, 4], [f32::NAN, 1.0, 1.0], 352.0),
        Volume,
        false,
    );
    file(
        "negative-dims.nii",
        &nifti([4, -4, 4], [1.0; 3], 352.0),
        Volume,
        false,
    );
    file(
        "huge-offset.nii",
        &nifti([4, 4, 4], [1.0; 3], 1e30),
        Volume,
        false,
    );
    file(
        "nan-offset.nii",
        &nifti([4, 4, 4], [1.0; 3], f32::NAN),
        Volume,
        false,
    );
    let mut short_nii = nifti([4, 4, 4], [1.0; 3], 352.0);
    short_nii.truncate(300);
    file("short.nii", &short_nii, Volume, false);
    file(
        "gzip-garbage.nii.gz",
        b"\x1f\x8b\x08\x00notgzip",
        Volume,
        false,
    );

    // --- MetaImage
    file("good.mha", &mha("", "4 4 4"), Volume, true);
    file(
        "nan-spacing.mha",
        &mha("ElementSpacing = 1 nan 1\n", "4 4 4"),
        Volume,
        false,
    );
    file("zero-size.mha", &mha("", "4 0 4"), Volume, false);
    file(
        "huge-size.mha",
        &mha("", "100000 100000 100000"),
        Volume,
        false,
    );
    file(
        "huge-header-size.mha",
        b"ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nHeaderSize = 18446744073709551000\nElementDataFile = data.raw\n",
        Volume,
        false,
    );

    // --- DICOM: a folder whose only file has the marker but nothing readable.
    let dicom = dir.join("dicom-junk");
    std::fs::create_dir(&dicom).unwrap();
    let mut dcm = vec![0u8; 128];
    dcm.extend(b"DICM");
    dcm.extend(pseudo_random(300, 3));
    std::fs::write(dicom.join("a.dcm"), &dcm).unwrap();
    cases.borrow_mut().push(Case {
        path: dicom,
        kind: Volume,
        valid: false,
    });
    let empty_dir = dir.join("empty-folder");
    std::fs::create_dir(&empty_dir).unwrap();
    cases.borrow_mut().push(Case {
        path: empty_dir,
        kind: Volume,
        valid: false,
    });
    let dir_vol = dir.join("folder.vol");
    std::fs::create_dir(&dir_vol).unwrap();
    cases.borrow_mut().push(Case {
        path: dir_vol,
        kind: Volume,
        valid: false,
    });

    // --- Named pipes posing as each kind of file: must never block.
    for (name, kind) in [
        ("pipe.vol", Volume),
        ("pipe.nrrd", Volume),
        ("pipe.nii", Volume),
        ("pipe.mha", Volume),
        ("pipe-noext", Volume),
        ("pipe.tf", Transfer),
        ("pipe.toml", Scene),
    ] {
        let path = dir.join(name);
        mkfifo(&path);
        cases.borrow_mut().push(Case {
            path,
            kind,
            valid: false,
        });
    }

    // --- Transfer functions
    file(
        "good.tf",
        b"domain 0 255\npoint 0 0 0 0 0\npoint 1 1 1 1 1\n",
        Transfer,
        true,
    );
    file(
        "zero-domain.tf",
        b"domain 5 5\npoint 0 1 1 1 1\n",
        Transfer,
        false,
    );
    file(
        "reversed-domain.tf",
        b"domain 9 1\npoint 0 1 1 1 1\n",
        Transfer,
        false,
    );
    file(
        "nan-domain.tf",
        b"domain nan 1\npoint 0 1 1 1 1\n",
        Transfer,
        false,
    );
    file("inf-point.tf", b"point inf 1 1 1 1\n", Transfer, false);
    file(
        "bad-ramp.tf",
        b"gradient 0.5 0.1\npoint 0 1 1 1 1\n",
        Transfer,
        false,
    );
    file("binary.tf", &pseudo_random(2000, 11), Transfer, false);
    file("empty.tf", b"", Transfer, false);

    // --- Two-level scenes
    let scene = |body: &str| format!("layers = [[0.1, 0.5], [0.5, 1.0]]\n{body}");
    file(
        "good.toml",
        scene("[[object]]\nmode = \"dvr\"\n").as_bytes(),
        Scene,
        true,
    );
    for (name, body) in [
        (
            "nan-p.toml",
            scene(
                "[[object]]\nmode = \"importance\"\nimportance = \"silhouette\"\np = [1.0, nan, 0.5]\n",
            ),
        ),
        (
            "inf-p.toml",
            scene(
                "[[object]]\nmode = \"importance\"\nimportance = \"lighting\"\np = [inf, 1.0, 0.5]\n",
            ),
        ),
        (
            "negative-gain.toml",
            scene("[[object]]\nmode = \"xray\"\ngain = -1\n"),
        ),
        (
            "nan-kt.toml",
            scene("[[object]]\nmode = \"context\"\nkt = nan\n"),
        ),
        (
            "zero-domain.toml",
            scene("[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], domain = [5, 5] }\n"),
        ),
        (
            "nan-domain.toml",
            scene("[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], domain = [nan, 5] }\n"),
        ),
        (
            "bad-ramp.toml",
            scene("[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], gradient = [-1, inf] }\n"),
        ),
        (
            "three-layer.toml",
            "layers = [[0.1, 0.5, 0.9]]\n".to_string(),
        ),
        ("fifo-tf.toml", scene("[[object]]\ntf = \"pipe.tf\"\n")),
        ("empty-layers.toml", "layers = []\n".to_string()),
        ("scalar-labels.toml", "labels = 3\n".to_string()),
        ("empty-labels.toml", "labels = \"\"\n".to_string()),
        (
            "missing-labels.toml",
            "labels = \"nowhere.labels.vol\"\n".to_string(),
        ),
        (
            "values-as-labels.toml",
            "labels = \"good.vol\"\n".to_string(),
        ),
        (
            "binary.toml",
            String::from_utf8_lossy(&pseudo_random(500, 5)).into_owned(),
        ),
    ] {
        file(name, body.as_bytes(), Scene, false);
    }
    cases.into_inner()
}

/// Deterministic noise bytes.
pub fn pseudo_random(n: usize, seed: u64) -> Vec<u8> {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect()
}
