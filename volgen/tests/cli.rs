//! The `volgen` binary as a user runs it: generate, info, convert, and clear errors.

use std::path::Path;
use std::process::{Command, Output};

fn volgen(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("volgen runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn generate_info_convert_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate", "--scene", "shapes", "--size", "40x30x20", "--brick", "8", "-o", "a.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("wrote a.vol: 40x30x20 u8 bricked (side 8)"),
        "{}",
        stdout(&o)
    );

    let o = volgen(d, &["info", "a.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let info = stdout(&o);
    for needle in [
        "40x30x20 (24000 voxels)",
        "bricked (side 8)",
        "bricks      6x5x3 = 90",
        "histogram",
        "median",
    ] {
        assert!(info.contains(needle), "info lacks `{needle}`:\n{info}");
    }

    let o = volgen(
        d,
        &[
            "convert", "a.vol", "--layout", "linear", "--type", "u16", "-o", "b.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("values copied"), "{}", stdout(&o));
    let o = volgen(
        d,
        &[
            "convert", "b.vol", "--brick", "8", "--type", "u8", "--format", "thesis", "-o", "c.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // u16 → u8 is windowed from the data's own range; shapes spans 0..=254 here so
    // the round trip a → b → c changes values only by that linear stretch.
    let info = stdout(&volgen(d, &["info", "c.vol", "--no-histogram"]));
    assert!(
        info.contains("26 bytes (reference thesis format)"),
        "{info}"
    );
    assert!(info.contains("min 0, max 255"), "{info}");
    assert_eq!(files_in(d), ["a.vol", "b.vol", "c.vol", "c.vol.ranges"]);
}

#[test]
fn shells_writes_a_matching_label_volume() {
    let dir = tempfile::tempdir().unwrap();
    let o = volgen(
        dir.path(),
        &[
            "generate", "--scene", "shells", "--size", "24", "-o", "s.vol", "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "--quiet prints nothing");
    assert_eq!(files_in(dir.path()), ["s.labels.vol", "s.vol"]);
    let info = stdout(&volgen(dir.path(), &["info", "s.labels.vol"]));
    assert!(
        info.contains("u8 labels") && info.contains("max 4"),
        "{info}"
    );
}

/// A run writes its volume and its labels or neither: a labels path that
/// cannot be written, or that names the volume in other words, is refused
/// before anything is written.
#[test]
fn labels_that_cannot_be_written_leave_no_volume_either() {
    let dir = tempfile::tempdir().unwrap();
    for (labels, says) in [
        ("missing/s.vol", "cannot write there"),
        ("./s.vol", "must differ"),
    ] {
        let o = volgen(
            dir.path(),
            &[
                "generate", "--scene", "shells", "--size", "16", "-o", "s.vol", "--labels", labels,
                "--force",
            ],
        );
        assert!(!o.status.success());
        assert!(stderr(&o).contains(says), "{labels}: {}", stderr(&o));
        assert!(
            files_in(dir.path()).is_empty(),
            "{:?}",
            files_in(dir.path())
        );
    }
}

#[test]
fn an_output_not_named_vol_is_written_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(d, &["generate", "--size", "8", "-o", "x.raw"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).trim_end(),
        "warning: x.raw will be a .vol file whatever its name says (name it NAME.vol)"
    );
    // It is one, and opens as one.
    assert!(stdout(&volgen(d, &["info", "x.raw"])).contains("8x8x8"));
    let o = volgen(d, &["generate", "--size", "8", "-o", "x.vol"]);
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
}

#[test]
fn a_damaged_pyramid_or_bytes_after_the_file_are_named_and_the_samples_converted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 80³: a file with a range table and a one-level pyramid, ending with it.
    let o = volgen(d, &["generate", "--size", "80", "-o", "whole.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let whole = std::fs::read(d.join("whole.vol")).unwrap();
    let o = volgen(d, &["info", "whole.vol"]);
    assert!(!stdout(&o).contains("unused"), "{}", stdout(&o));
    let o = volgen(d, &["convert", "whole.vol", "-o", "copy.vol"]);
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    let copy = std::fs::read(d.join("copy.vol")).unwrap();

    // Bytes after the pyramid: info shows them, convert says they are dropped
    // and writes the same file as from the whole one.
    let mut joined = whole.clone();
    joined.extend_from_slice(&[7u8; 300]);
    std::fs::write(d.join("joined.vol"), &joined).unwrap();
    let o = volgen(d, &["info", "joined.vol"]);
    assert!(
        stdout(&o).contains(&format!(
            "unused      300 bytes after the file's last block, from byte {}",
            whole.len()
        )),
        "{}",
        stdout(&o)
    );
    let o = volgen(d, &["convert", "joined.vol", "-o", "from-joined.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).trim_end(),
        format!(
            "warning: joined.vol: the file has 300 bytes after its last block (from byte {}) that are not part of the volume; they are not copied",
            whole.len()
        )
    );
    assert!(std::fs::read(d.join("from-joined.vol")).unwrap() == copy);
    // One byte is one byte (was "unused      1 bytes").
    std::fs::write(d.join("one.vol"), [&whole[..], &[7]].concat()).unwrap();
    let o = volgen(d, &["info", "one.vol"]);
    assert!(
        stdout(&o).contains("unused      1 byte after the file's last block"),
        "{}",
        stdout(&o)
    );

    // A pyramid cut short: the file does not open (the error says where it
    // ends and what rescues the samples), and convert rebuilds it.
    std::fs::write(d.join("cut.vol"), &whole[..whole.len() - 100]).unwrap();
    let o = volgen(d, &["info", "cut.vol"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o).trim_end(),
        format!(
            "error: cut.vol: the resolution pyramid is cut off in its levels: it ends at byte {}, the file has {} bytes (an incomplete copy?); the samples before it are whole: `volgen convert` copies them into a new file with a new pyramid",
            whole.len(),
            whole.len() - 100
        )
    );
    let o = volgen(d, &["convert", "cut.vol", "-o", "from-cut.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).trim_end(),
        format!(
            "warning: cut.vol: the resolution pyramid is cut off in its levels (it ends at byte {}, the file has {} bytes); the output's is built from the samples",
            whole.len(),
            whole.len() - 100
        )
    );
    assert!(std::fs::read(d.join("from-cut.vol")).unwrap() == copy);

    // Cut inside the range table (the pyramid, after it, is gone too): the
    // header places blocks past the end, said as a file cut short (not an
    // invalid header); convert still rescues the samples, whole.
    let header = raycaster::volume::Header::parse(&whole[..64], whole.len() as u64).unwrap();
    let (table, pyramid) = (
        header.ranges_offset.unwrap(),
        header.pyramid_offset.unwrap(),
    );
    let cut_at = table + 100;
    std::fs::write(d.join("cut-table.vol"), &whole[..cut_at as usize]).unwrap();
    let o = volgen(d, &["info", "cut-table.vol"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o).trim_end(),
        format!(
            "error: cut-table.vol: the resolution pyramid starts at byte {pyramid}, past the file's end ({cut_at} bytes): the file is cut short (an incomplete copy?) or its header is damaged; the samples before it are whole: `volgen convert` copies them into a new file"
        )
    );
    let o = volgen(d, &["convert", "cut-table.vol", "-o", "from-cut-table.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    assert!(
        said.starts_with(&format!(
            "warning: cut-table.vol: the value-range table after the samples is cut off (it ends at byte {}, the file has {cut_at} bytes); the output's table is computed from the samples\n",
            table + raycaster::volume::BrickRanges::table_len(&header.block_grid(raycaster::volume::LINEAR_RANGE_SIDE))
        )) && said.contains("warning: cut-table.vol: the resolution pyramid is cut off in its directory"),
        "{said}"
    );
    assert!(std::fs::read(d.join("from-cut-table.vol")).unwrap() == copy);
    // A table offset no cut file has (all bits set): a damaged header, said
    // with the file's length by info and convert alike, with no advice to run
    // the convert that refuses it (it said the file had 2^64 − 1 bytes).
    let mut damaged = whole.clone();
    damaged[56..64].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(d.join("damaged.vol"), &damaged).unwrap();
    for command in ["info", "convert"] {
        let o = volgen(
            d,
            &[command, "damaged.vol", "-o", "none.vol"][..if command == "info" { 2 } else { 4 }],
        );
        assert_eq!(o.status.code(), Some(1), "{command}");
        assert_eq!(
            stderr(&o).trim_end(),
            format!(
                "error: damaged.vol: invalid header: the value-range table starts at byte {}, past the file's end ({} bytes), where no value-range table can start: the header is damaged",
                u64::MAX,
                whole.len()
            ),
            "{command}"
        );
    }
    assert!(!d.join("none.vol").exists());
    // Cut inside the samples: nothing to rescue.
    std::fs::write(d.join("cut-samples.vol"), &whole[..1000]).unwrap();
    let o = volgen(d, &["convert", "cut-samples.vol", "-o", "none.vol"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("the file is cut short: its samples end at byte"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("none.vol").exists());
}

#[test]
fn existing_output_needs_force() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("x.vol"), b"keep me").unwrap();
    let o = volgen(dir.path(), &["generate", "--size", "8", "-o", "x.vol"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("x.vol: already exists (pass --force"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(dir.path().join("x.vol")).unwrap(), b"keep me");
    let o = volgen(
        dir.path(),
        &["generate", "--size", "8", "-o", "x.vol", "--force"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(files_in(dir.path()), ["x.vol"]);
}

#[test]
fn bad_inputs_get_clear_errors_and_leave_no_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("short.raw"), vec![0u8; 100]).unwrap();
    std::fs::write(d.join("trunc.vol"), [1u8, 0, 0]).unwrap();
    let mut nrrd = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1e30 1e30 1e30\nencoding: raw\n\n".to_vec();
    nrrd.extend_from_slice(&[0; 8]);
    std::fs::write(d.join("far.nrrd"), nrrd).unwrap();
    let cases: &[(&[&str], &str)] = &[
        // The input's spacing cannot be stored: the input is named.
        (
            &["convert", "far.nrrd", "-o", "o.vol"],
            "error: far.nrrd: invalid header: spacing on x is 1e30",
        ),
        (&["info", "missing.vol"], "missing.vol: No such file"),
        (
            &["info", "trunc.vol"],
            "trunc.vol: invalid header: file is 3 bytes, shorter than the 26-byte header",
        ),
        (
            &["convert", "short.raw", "--raw", "5", "-o", "o.vol"],
            "short.raw: the file holds 100 bytes, fewer than its 125 bytes of samples (5x5x5 u8)",
        ),
        (
            &["convert", "missing.vol", "-o", "o.vol"],
            "missing.vol: No such file",
        ),
        (
            &["generate", "--size", "0", "-o", "o.vol"],
            "size 0 is out of range",
        ),
        (
            &["generate", "--brick", "1", "-o", "o.vol"],
            "brick side 1 is out of range 2..=255",
        ),
        (
            &["generate", "--spacing", "nan", "-o", "o.vol"],
            "spacing `nan` is out of range",
        ),
        (
            &[
                "generate", "--type", "u16", "--format", "thesis", "-o", "o.vol",
            ],
            "thesis holds u8 samples only",
        ),
        (
            &["generate", "--scene", "cubes", "-o", "o.vol"],
            "invalid value 'cubes'",
        ),
        (
            &[
                "convert",
                "short.raw",
                "--raw",
                "10x10x1",
                "--window",
                "5:1",
                "-o",
                "o.vol",
            ],
            "window low 5 must be below high 1",
        ),
        (
            &[
                "convert",
                "short.raw",
                "--raw",
                "10x10x1",
                "--layout",
                "linear",
                "--brick",
                "8",
                "-o",
                "o.vol",
            ],
            "--brick applies to --layout bricked only",
        ),
        (
            &["generate", "-o", "no/such/dir/o.vol", "--size", "8"],
            "no/such/dir/o.vol",
        ),
    ];
    for (args, needle) in cases {
        let o = volgen(d, args);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(
            stderr(&o).contains(needle),
            "{args:?}: expected `{needle}` in:\n{}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"), "{args:?} panicked");
    }
    assert_eq!(
        files_in(d),
        ["far.nrrd", "short.raw", "trunc.vol"],
        "no output left behind"
    );
}

#[test]
fn raw_conversion_with_window_and_skip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 4x2x2 i16 big-endian after a 3-byte foreign header, x fastest.
    let mut bytes = vec![9u8, 9, 9];
    for i in 0..16i16 {
        bytes.extend_from_slice(&(i * 100 - 500).to_be_bytes());
    }
    std::fs::write(d.join("ct.raw"), bytes).unwrap();
    let o = volgen(
        d,
        &[
            "convert",
            "ct.raw",
            "--raw",
            "4x2x2",
            "--raw-type",
            "i16",
            "--endian",
            "big",
            "--skip",
            "3",
            "--window",
            "-500:1000",
            "--type",
            "u8",
            "--spacing",
            "0.5,0.5,2",
            "-o",
            "ct.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("values -500..=1000 mapped"),
        "{}",
        stdout(&o)
    );
    let info = stdout(&volgen(d, &["info", "ct.vol"]));
    assert!(info.contains("spacing     0.5 x 0.5 x 2"), "{info}");
    // Values in the input's units: the window's ends.
    assert!(info.contains("min -500, max 1000"), "{info}");
    assert!(info.contains("extension version 3"), "{info}");
}

#[test]
fn float_input_wider_than_f32_differences_keeps_its_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // max − min overflows f32: every sample was stored as 0 before.
    let values = [-2e38f32, 2e38, -1e38, 1e38, 0.0, 5.0, -5.0, 1.0];
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(d.join("wide.raw"), bytes).unwrap();
    let o = volgen(
        d,
        &[
            "convert",
            "wide.raw",
            "--raw",
            "2x2x2",
            "--raw-type",
            "f32",
            "-o",
            "wide.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let info = stdout(&volgen(d, &["info", "wide.vol"]));
    assert!(info.contains("values      min -2e38, max 2e38"), "{info}");
    let file = std::fs::read(d.join("wide.vol")).unwrap();
    let v = raycaster::volume::Volume::open(d.join("wide.vol")).unwrap();
    let stored: Vec<u16> = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
        .iter()
        .map(|&p| v.voxel(p))
        .collect();
    // x fastest in the raw file: -2e38, 2e38, -1e38, 1e38 → 0, 65535, ¼, ¾.
    assert_eq!(stored, [0, 65535, 16384, 49151], "{} bytes", file.len());
}

#[test]
fn float_input_with_infinities_and_nan_is_windowed_by_its_finite_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 4x2x2 f32, values 10..=25 but for one +inf, one -inf and one NaN.
    let mut values: Vec<f32> = (0..16).map(|i| 10.0 + i as f32).collect();
    values[3] = f32::INFINITY;
    values[7] = f32::NEG_INFINITY;
    values[11] = f32::NAN;
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(d.join("f.raw"), bytes).unwrap();
    let args = ["convert", "f.raw", "--raw", "4x2x2", "--raw-type", "f32"];
    let o = volgen(d, &[&args[..], &["--type", "u8", "-o", "f.vol"]].concat());
    // Before: the window became -inf..inf and the header's value units were
    // refused as broken.
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("values 10..=25 mapped"),
        "{}",
        stdout(&o)
    );
    // The values that are not finite are counted, once.
    assert_eq!(
        stderr(&o)
            .matches("f.raw: 3 of its 16 values are NaN or infinite: NaN is stored as the window's low end")
            .count(),
        1,
        "{}",
        stderr(&o)
    );
    let info = stdout(&volgen(d, &["info", "f.vol"]));
    assert!(info.contains("min 10, max 25"), "{info}");
    // `info` on a float scan counts them too (the same values as an NRRD).
    let mut nrrd =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 2 2\nendian: little\nencoding: raw\n\n"
            .to_vec();
    nrrd.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    std::fs::write(d.join("f.nrrd"), nrrd).unwrap();
    let o = volgen(d, &["info", "f.nrrd"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let info = stdout(&o);
    assert!(
        info.contains("min 10, max 25")
            && info.contains("3 of its 16 values are NaN or infinite (left out of the histogram"),
        "{info}"
    );
    // The samples: a linear u8 file in the thesis format ends with them.
    let o = volgen(
        d,
        &[
            &args[..],
            &[
                "--type", "u8", "--layout", "linear", "--format", "thesis", "-o", "t.vol",
            ],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let file = std::fs::read(d.join("t.vol")).unwrap();
    let samples = &file[file.len() - 16..];
    // ±inf clamp to the window's ends (25 and +inf: 255; 10 and -inf: 0);
    // NaN is stored as its low end.
    assert_eq!(
        samples.iter().filter(|&&v| v == 255).count(),
        2,
        "{samples:?}"
    );
    assert_eq!(
        samples.iter().filter(|&&v| v == 0).count(),
        3,
        "{samples:?}"
    );
    // No finite value at all: refused by name, nothing written (before: a
    // volume of zeros and no word).
    let nan: Vec<u8> = [f32::NAN, f32::INFINITY]
        .repeat(8)
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(d.join("nan.raw"), nan).unwrap();
    let o = volgen(
        d,
        &[
            "convert",
            "nan.raw",
            "--raw",
            "4x2x2",
            "--raw-type",
            "f32",
            "-o",
            "n.vol",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("holds no finite value (every sample is NaN or infinite)"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("n.vol").exists());
}

#[test]
fn help_explains_every_command() {
    let dir = tempfile::tempdir().unwrap();
    for (cmd, needles) in [
        (
            "generate",
            &[
                "--scene", "--size", "--layout", "--brick", "--type", "--seed", "--force", "shapes",
            ][..],
        ),
        (
            "convert",
            &[
                "--raw",
                "--raw-type",
                "--endian",
                "--skip",
                "--window",
                "bounded memory",
            ][..],
        ),
        ("info", &["histogram", "--no-histogram"][..]),
    ] {
        let o = volgen(dir.path(), &[cmd, "--help"]);
        assert!(o.status.success());
        let help = stdout(&o);
        for n in needles {
            assert!(help.contains(n), "`{cmd} --help` lacks `{n}`:\n{help}");
        }
    }
}

#[test]
fn outputs_get_the_usual_file_mode_not_the_temp_file_mode() {
    use std::os::unix::fs::PermissionsExt;
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let umask = status
        .lines()
        .find_map(|l| l.strip_prefix("Umask:"))
        .map(|v| u32::from_str_radix(v.trim(), 8).unwrap())
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let o = volgen(
        dir.path(),
        &[
            "generate", "--size", "8", "--format", "thesis", "-o", "m.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["m.vol", "m.vol.ranges"] {
        let mode = std::fs::metadata(dir.path().join(name))
            .unwrap()
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o666 & !umask, "{name}");
    }
}

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../volumes/fixtures")
        .join(name)
}

#[test]
fn converts_nrrd_nifti_and_metaimage_keeping_spacing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (name, kept) in [
        ("i16_gzip.nrrd", "i16 samples stored as sample + 32768"),
        ("u16_detached.nhdr", "values copied"),
        ("u8.nii", "values copied"),
        ("f32.nii.gz", "values -0.875..=7.125 mapped"),
        ("u16_zlib.mha", "values copied"),
        ("i16.mhd", "i16 samples stored"),
    ] {
        let input = fixture(name);
        let o = volgen(
            d,
            &[
                "convert",
                input.to_str().unwrap(),
                "-o",
                "out.vol",
                "--force",
            ],
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(
            stdout(&o).contains("wrote out.vol: 6x5x4"),
            "{}",
            stdout(&o)
        );
        assert!(stdout(&o).contains(kept), "{name}: {}", stdout(&o));
        assert!(
            stderr(&o).contains("spacing 0.5 x 0.75 x 2"),
            "{}",
            stderr(&o)
        );
        let info = stdout(&volgen(d, &["info", "out.vol"]));
        assert!(
            info.contains("spacing     0.5 x 0.75 x 2"),
            "{name}: {info}"
        );
    }
}

#[test]
fn a_truncated_compressed_input_fails_cleanly_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bytes = std::fs::read(fixture("i16.nii.gz")).unwrap();
    std::fs::write(d.join("cut.nii.gz"), &bytes[..bytes.len() - 30]).unwrap();
    let o = volgen(d, &["convert", "cut.nii.gz", "-o", "cut.vol"]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("cut.nii.gz") && err.contains("truncated or corrupt"),
        "{err}"
    );
    assert_eq!(files_in(d), ["cut.nii.gz"]);
}

/// A raw file longer than its samples is said as longer, by how much, with
/// the `--skip` that passes over a header before them (before: "file has
/// 1376318 bytes but 128x128x84 samples of 1 bytes after a 0-byte skip need
/// 1376256", which reads like a shortfall).
#[test]
fn a_raw_file_longer_than_its_samples_is_said_with_the_skip_that_fits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut bytes = vec![7u8; 62];
    bytes.extend((0..125u8).collect::<Vec<_>>());
    std::fs::write(d.join("head.raw"), &bytes).unwrap();
    let o = volgen(d, &["convert", "head.raw", "--raw", "5", "-o", "o.vol"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).trim_end(),
        "error: head.raw: the file holds 62 bytes more than its 125 bytes of samples (5x5x5 u8; a header before them? --skip 62 skips it)"
    );
    let args = [
        "convert", "head.raw", "--raw", "5", "--skip", "61", "-o", "o.vol",
    ];
    let o = volgen(d, &args);
    assert!(
        stderr(&o).contains(
            "the file holds 1 byte more than the 61-byte skip and its 125 bytes of samples (5x5x5 u8; a header before them? --skip 62 skips it)"
        ),
        "{}",
        stderr(&o)
    );
    assert_eq!(files_in(d), ["head.raw"]);
    // The skip it names reads the samples.
    let o = volgen(
        d,
        &[
            "convert", "head.raw", "--raw", "5", "--skip", "62", "-o", "o.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let info = stdout(&volgen(d, &["info", "o.vol"]));
    assert!(info.contains("min 0, max 124"), "{info}");
}

/// A CT MetaImage of `values` (HU) along x, placed in the patient.
fn write_ct_mha(path: &Path, values: &[i16]) {
    let mut bytes = format!(
        "ObjectType = Image\nNDims = 3\nDimSize = {} 1 1\nElementSpacing = 1 1 1\n\
         TransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = -10 20 30\n\
         Modality = MET_MOD_CT\nElementType = MET_SHORT\nElementDataFile = LOCAL\n",
        values.len()
    )
    .into_bytes();
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// A `.vol` file of HU (stored + 32768) converted with a window says the
/// window in HU, as the NRRD's conversion does (before: "values
/// 31768..=34768 mapped to the full range").
#[test]
fn a_window_is_said_in_the_files_units() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_ct_mha(&d.join("ct.mha"), &[-1024, -1000, 0, 400, 3071]);
    let o = volgen(d, &["convert", "ct.mha", "-o", "ct.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (window, said) in [
        (
            &["--window", "-1000:2000"][..],
            "values -1000..=2000 mapped to the full range (values in HU)",
        ),
        (
            &[][..],
            "values -1024..=3071 mapped to the full range (values in HU)",
        ),
    ] {
        let args = [
            &[
                "convert", "ct.vol", "--type", "u8", "--force", "-o", "u8.vol",
            ][..],
            window,
        ]
        .concat();
        let o = volgen(d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).contains(said), "{window:?}: {}", stdout(&o));
        assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    }
}

/// A window wholly outside the data's values is warned of, once, in the
/// file's units (before: a flat volume without a word); one that meets the
/// data is not, and `-q` silences the warning.
#[test]
fn a_window_outside_the_data_is_warned_of_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_ct_mha(&d.join("ct.mha"), &[-1024, -1000, 0, 400, 3071]);
    assert!(
        volgen(d, &["convert", "ct.mha", "-o", "ct.vol"])
            .status
            .success()
    );
    for input in ["ct.mha", "ct.vol"] {
        for window in ["10000:20000", "-5000:-2000"] {
            let args = [
                "convert", input, "--type", "u8", "--window", window, "--force", "-o", "w.vol",
            ];
            let o = volgen(d, &args);
            assert!(o.status.success(), "{}", stderr(&o));
            let e = stderr(&o);
            let [lo, hi] = match window {
                "10000:20000" => ["10000", "20000"],
                _ => ["-5000", "-2000"],
            };
            let said = format!(
                "warning: --window {lo} HU to {hi} HU lies outside the data's values -1024 HU to 3071 HU; every voxel of the output holds one value"
            );
            assert_eq!(
                e.matches("lies outside").count(),
                1,
                "{input} {window}: {e}"
            );
            assert!(e.contains(&said), "{input} {window}: {e}");
            let o = volgen(d, &[&args[..], &["-q"]].concat());
            assert!(
                o.status.success() && stderr(&o).is_empty(),
                "{}",
                stderr(&o)
            );
        }
        // Touching the data is not outside it.
        let args = [
            "convert",
            input,
            "--type",
            "u8",
            "--window",
            "3071:5000",
            "--force",
            "-o",
            "w.vol",
        ];
        let o = volgen(d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!stderr(&o).contains("lies outside"), "{}", stderr(&o));
    }
}

/// The thesis format cannot hold units or an orientation: converting a file
/// with them to it says so (before: dropped without a word).
#[test]
fn a_thesis_output_says_what_it_cannot_keep() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_ct_mha(&d.join("ct.mha"), &[-1024, -1000, 0, 400, 3071]);
    assert!(
        volgen(d, &["convert", "ct.mha", "-o", "ct.vol"])
            .status
            .success()
    );
    let args = [
        "convert", "ct.vol", "--type", "u8", "--format", "thesis", "-o", "t.vol",
    ];
    let o = volgen(d, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert_eq!(
        e.trim_end(),
        "warning: ct.vol: the thesis format keeps neither what its values mean (value = stored − 32768 (HU)) nor where it lies in the patient; the output stores plain samples (--format extended keeps both)"
    );
    let o = volgen(d, &[&args[..], &["--force", "-q"]].concat());
    assert!(
        o.status.success() && stderr(&o).is_empty(),
        "{}",
        stderr(&o)
    );
    // A file with neither converts to the thesis format without a word.
    assert!(
        volgen(d, &["generate", "--size", "8", "-o", "plain.vol"])
            .status
            .success()
    );
    let o = volgen(
        d,
        &["convert", "plain.vol", "--format", "thesis", "-o", "pt.vol"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
}

/// A spacing whose largest is more than 1e4 times its smallest (the ratio
/// foreign files are read under) is refused before anything is written
/// (before: written, and `raycaster render` refused the file).
#[test]
fn a_spacing_the_renderer_would_refuse_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate",
            "--size",
            "64",
            "--spacing",
            "1,1,100000",
            "-o",
            "g.vol",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o)
            .contains("the largest spacing is 1.000e5 times the smallest; at most 1e4 renders"),
        "{}",
        stderr(&o)
    );
    assert!(files_in(d).is_empty(), "{:?}", files_in(d));
    let o = volgen(
        d,
        &[
            "generate",
            "--size",
            "8",
            "--spacing",
            "1,1,10000",
            "-o",
            "g.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_sidecar_given_for_its_volume_is_named_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate", "--size", "80", "--format", "thesis", "-o", "t.vol", "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = volgen(d, &["pyramid", "t.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (sidecar, what) in [
        ("t.vol.pyramid", "the resolution pyramid"),
        ("t.vol.ranges", "the value-range table"),
    ] {
        assert!(d.join(sidecar).exists(), "{sidecar}");
        let o = volgen(d, &["info", sidecar]);
        assert_eq!(o.status.code(), Some(1));
        // (It said "unknown sample order byte 0x51".)
        assert_eq!(
            stderr(&o).trim_end(),
            format!(
                "error: {sidecar}: is a sidecar holding {what} of t.vol, not a volume: give t.vol"
            )
        );
    }
}

/// A pyramid sidecar made stale by a change of its file is said so by
/// `info` (it said "none", as if there were no sidecar), and `volgen
/// pyramid` builds it again without --force.
#[test]
fn a_stale_pyramid_sidecar_is_named_by_info() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate",
            "--size",
            "140",
            "--no-pyramid",
            "-o",
            "s.vol",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = volgen(d, &["pyramid", "s.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let pyramid_line = |o: &Output| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .find(|l| l.starts_with("pyramid"))
            .map(str::to_string)
    };
    let o = volgen(d, &["info", "s.vol", "--no-histogram"]);
    assert!(pyramid_line(&o).unwrap().contains("in s.vol.pyramid"));
    // The file changes (its time: what the sidecar was built for is gone).
    let file = std::fs::File::options()
        .append(true)
        .open(d.join("s.vol"))
        .unwrap();
    file.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(60))
        .unwrap();
    let o = volgen(d, &["info", "s.vol", "--no-histogram"]);
    assert_eq!(
        pyramid_line(&o).unwrap(),
        "pyramid     none: s.vol.pyramid is stale, built before the file last changed (`volgen pyramid s.vol` builds it again)"
    );
    let o = volgen(d, &["pyramid", "s.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = volgen(d, &["info", "s.vol", "--no-histogram"]);
    assert!(pyramid_line(&o).unwrap().contains("in s.vol.pyramid"));
}

#[test]
fn pyramid_checks_its_sidecar_can_be_written_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate",
            "--size",
            "80",
            "--format",
            "thesis",
            "--no-pyramid",
            "-o",
            "t.vol",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // A folder where the sidecar goes: said at once, nothing written.
    std::fs::create_dir(d.join("t.vol.pyramid")).unwrap();
    let o = volgen(d, &["pyramid", "t.vol"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o).trim_end(),
        "error: t.vol.pyramid: is a directory, where the pyramid of t.vol goes: move it away"
    );
}

/// A segmentation from elsewhere (ids in a u16 or f32 NRRD) becomes a label
/// volume with `convert --labels`: the ids of the generated shells' labels,
/// voxel for voxel, opened as labels by what `raycaster render --labels` and
/// the viewer call; the NRRD itself, or a conversion without `--labels`, is
/// refused there with the command that makes one; ids beyond 0..=255 are
/// refused with nothing written.
#[test]
fn a_segmentation_converted_with_labels_is_a_label_volume_of_its_ids() {
    use raycaster::source::open_labels;
    use raycaster::volume::{Content, Volume};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate", "--scene", "shells", "--size", "24", "-o", "s.vol", "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let generated = Volume::open(d.join("s.labels.vol")).unwrap();
    let [nx, ny, nz] = generated.dims();
    let ids: Vec<u16> = (0..nz)
        .flat_map(|z| (0..ny).flat_map(move |y| (0..nx).map(move |x| [x, y, z])))
        .map(|v| generated.voxel(v))
        .collect();
    assert!(ids.contains(&4), "the shells have ids 0 to 4");
    let nrrd = |name: &str, kind: &str, bytes: Vec<u8>| {
        let header = format!(
            "NRRD0004\ntype: {kind}\ndimension: 3\nsizes: {nx} {ny} {nz}\nencoding: raw\nendian: little\n\n"
        );
        std::fs::write(d.join(name), [header.into_bytes(), bytes].concat()).unwrap();
    };
    nrrd(
        "seg.nrrd",
        "uint16",
        ids.iter().flat_map(|i| i.to_le_bytes()).collect(),
    );
    nrrd(
        "seg-f.nrrd",
        "float",
        ids.iter()
            .flat_map(|&i| f32::from(i).to_le_bytes())
            .collect(),
    );
    for input in ["seg.nrrd", "seg-f.nrrd"] {
        let out = input.replace(".nrrd", ".labels.vol");
        let o = volgen(d, &["convert", input, "--labels", "-o", &out]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            stdout(&o).contains("object ids copied (a label volume)"),
            "{}",
            stdout(&o)
        );
        let converted = open_labels(&d.join(&out)).unwrap();
        assert_eq!(converted.content(), Content::Labels);
        assert_eq!(converted.dims(), [nx, ny, nz]);
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let v = [x, y, z];
                    assert_eq!(converted.voxel(v), generated.voxel(v), "{input} at {v:?}");
                }
            }
        }
    }
    // The NRRD itself and its conversion as values: the command that helps.
    let e = open_labels(&d.join("seg.nrrd")).unwrap_err().to_string();
    assert!(
        e.contains("label volumes are .vol files of object ids")
            && e.contains("seg.nrrd --labels -o NAME.labels.vol"),
        "{e}"
    );
    let o = volgen(d, &["convert", "seg.nrrd", "-o", "values.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = open_labels(&d.join("values.vol")).unwrap_err().to_string();
    assert!(
        e.contains("holds values, not labels") && e.contains("--labels"),
        "{e}"
    );
    // An id of 256 fits no label volume: refused, nothing written.
    let mut wide = ids.clone();
    wide[3] = 256;
    nrrd(
        "wide.nrrd",
        "uint16",
        wide.iter().flat_map(|i| i.to_le_bytes()).collect(),
    );
    let o = volgen(d, &["convert", "wide.nrrd", "--labels", "-o", "wide.vol"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(
            "wide.nrrd: its values span 0 to 256: a label volume holds object ids 0 to 255"
        ),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("wide.vol").exists());
}

/// A named CT window (Hounsfield units) on 8-bit data without value units is
/// warned of, as render's `--domain` and slice's `--window` warn (it squeezed
/// the values into a few stored levels without a word); a numeric window not.
#[test]
fn a_named_ct_window_on_8_bit_data_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(d, &["generate", "--size", "16", "-o", "u8.vol", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = volgen(
        d,
        &["convert", "u8.vol", "--window", "lung", "-o", "w.vol", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "--quiet: {}", stderr(&o));
    let o = volgen(
        d,
        &[
            "convert", "u8.vol", "--window", "lung", "-o", "w.vol", "--force",
        ],
    );
    assert_eq!(
        stderr(&o).matches("warning: --window lung: a CT window in Hounsfield units, and u8.vol holds 8-bit samples without value units").count(),
        1,
        "{}",
        stderr(&o)
    );
    let o = volgen(
        d,
        &[
            "convert", "u8.vol", "--window", "0:100", "-o", "w.vol", "--force",
        ],
    );
    assert!(!stderr(&o).contains("Hounsfield"), "{}", stderr(&o));
}

/// `volgen info` on a file whose spacing convert and render refuse says so,
/// with the flag that overrides it (it printed the spacing as if usable).
#[test]
fn info_says_a_spacing_that_convert_refuses_and_convert_overrides_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1e30 1e30 1e30\nencoding: raw\n\n";
    std::fs::write(d.join("far.nrrd"), [header.as_bytes(), &[9u8; 8]].concat()).unwrap();
    let o = volgen(d, &["info", "far.nrrd", "--no-histogram"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("spacing     1e30 x 1e30 x 1e30"),
        "{}",
        stdout(&o)
    );
    assert_eq!(
        stderr(&o)
            .matches("warning: `volgen convert` refuses this file's spacing (spacing on x is 1e30;")
            .count(),
        1,
        "{}",
        stderr(&o)
    );
    let o = volgen(d, &["convert", "far.nrrd", "-o", "far.vol"]);
    assert!(!o.status.success());
    assert!(!d.join("far.vol").exists());
    let o = volgen(
        d,
        &["convert", "far.nrrd", "-o", "far.vol", "--spacing", "1"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // A usable spacing gets no warning.
    let o = volgen(d, &["info", "far.vol", "--no-histogram"]);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

/// A float NIfTI file whose value scaling takes its values beyond f32 is
/// refused when its values are read (it was converted as "values 0..=inf
/// mapped to the full range"); an ordinary scaling of the same file converts.
#[test]
fn float_values_scaled_beyond_f32_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nifti = |slope: f32| {
        let mut h = vec![0u8; 352];
        h[0..4].copy_from_slice(&348i32.to_le_bytes());
        for (i, v) in [3i16, 2, 2, 2, 1, 1, 1, 1].iter().enumerate() {
            h[40 + 2 * i..42 + 2 * i].copy_from_slice(&v.to_le_bytes());
        }
        h[70..72].copy_from_slice(&16i16.to_le_bytes());
        h[72..74].copy_from_slice(&32i16.to_le_bytes());
        for (i, p) in [1f32, 1.0, 1.0, 1.0].iter().enumerate() {
            h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
        }
        h[108..112].copy_from_slice(&352f32.to_le_bytes());
        h[112..116].copy_from_slice(&slope.to_le_bytes());
        h[344..348].copy_from_slice(b"n+1\0");
        for v in [0f32, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        std::fs::write(d.join("f.nii"), &h).unwrap();
    };
    nifti(3e38);
    let o = volgen(d, &["convert", "f.nii", "-o", "f.vol"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("its values reach 2.1") && stderr(&o).contains("beyond the ±3.4e38"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("f.vol").exists());
    nifti(2.0);
    let o = volgen(d, &["convert", "f.nii", "-o", "f.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
