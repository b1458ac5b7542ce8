//! `volgen` under faults: signals, impossible sizes, stale partial files of a killed
//! run, a closed stdout, named pipes and corrupt range tables.

#![allow(unsafe_code)] // libc without a safe wrapper: FIFOs, signals, resource limits

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn volgen(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("volgen runs")
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

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
}

/// The output of `child`, failing (and killing it) when it runs longer than `limit`.
fn wait_at_most(mut child: std::process::Child, limit: Duration) -> Output {
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("the process hung (over {limit:?})");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// Starts a long `generate` and waits until its partial file exists.
fn start_generate(dir: &Path) -> std::process::Child {
    let child = Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(dir)
        .args([
            "generate", "--scene", "noise", "--size", "600", "-o", "big.vol",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !files_in(dir).iter().any(|n| n.ends_with(".partial")) {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no partial file appeared"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child
}

/// Starts a long `generate`, waits until its partial file exists, sends `signal` and
/// returns the finished process's output.
fn interrupt_generate(dir: &Path, signal: i32) -> Output {
    let child = start_generate(dir);
    assert_eq!(unsafe { libc::kill(child.id() as i32, signal) }, 0);
    wait_at_most(child, Duration::from_secs(60))
}

#[test]
fn sigterm_and_sighup_cancel_like_ctrl_c_and_leave_no_partial_file() {
    for signal in [libc::SIGTERM, libc::SIGHUP, libc::SIGINT] {
        let dir = tempfile::tempdir().unwrap();
        let o = interrupt_generate(dir.path(), signal);
        // 130: interrupted, as a shell reports it (not 1, a failure).
        assert_eq!(
            o.status.code(),
            Some(130),
            "signal {signal}: {}",
            stderr(&o)
        );
        assert!(
            stderr(&o).contains("interrupted; no partial output was left"),
            "{}",
            stderr(&o)
        );
        assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
        assert!(
            files_in(dir.path()).is_empty(),
            "signal {signal} left {:?}",
            files_in(dir.path())
        );
    }
}

/// A fault on a mapped file (SIGBUS: another program truncated it) ends the
/// process at once, with no unwinding: the handler itself removes the output
/// being written (`volgen pyramid` left a 218 MB partial file behind, saying
/// nothing was written).
#[test]
fn a_fault_on_a_mapped_file_leaves_no_partial_file() {
    let dir = tempfile::tempdir().unwrap();
    let o = interrupt_generate(dir.path(), libc::SIGBUS);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("shrank or vanished while it was read"),
        "{}",
        stderr(&o)
    );
    assert!(
        files_in(dir.path()).is_empty(),
        "left {:?}",
        files_in(dir.path())
    );
}

/// Standard output on a full disk (`> /dev/full`): the volume is written, one
/// error line says what was lost, exit 1 (it panicked, 101); `info` too.
#[test]
fn a_full_standard_output_is_an_error_line_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &["generate", "--size", "16", "-o", "g.vol"][..],
        &["info", "g.vol"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_volgen"))
            .current_dir(dir.path())
            .args(args)
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert_eq!(
            stderr(&o),
            "error: standard output: No space left on device (os error 28); the output printed is incomplete\n",
            "{args:?}"
        );
    }
    assert!(dir.path().join("g.vol").exists());
}

/// Two signals (GNU `timeout` sends the child two): the second exits at once,
/// and leaves no partial file either.
#[test]
fn a_second_signal_exits_at_once_and_leaves_no_partial_file() {
    let dir = tempfile::tempdir().unwrap();
    let child = start_generate(dir.path());
    let pid = child.id() as i32;
    assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
    // (Not at once: two pending signals of one kind are delivered as one.)
    std::thread::sleep(Duration::from_millis(2));
    assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
    let o = wait_at_most(child, Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(
        files_in(dir.path()).is_empty(),
        "left {:?}: {}",
        files_in(dir.path()),
        stderr(&o)
    );
}

/// A scene with labels writes both files or neither: interrupted while the
/// labels are written, the volume and labels that were there stay as they
/// were (before: the new volume replaced the old, then was deleted).
#[test]
fn an_interrupted_run_with_labels_keeps_the_files_it_would_replace() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate", "--scene", "shells", "--size", "24", "-o", "s.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let old = ["s.vol", "s.labels.vol"].map(|n| std::fs::read(d.join(n)).unwrap());
    let child = Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(d)
        .args([
            "generate", "--scene", "shells", "--size", "500", "-o", "s.vol", "--force",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !files_in(d).iter().any(|n| n.starts_with(".s.labels.vol.")) {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{:?}",
            files_in(d)
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGTERM) }, 0);
    let o = wait_at_most(child, Duration::from_secs(60));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{e}");
    assert!(
        e.contains("interrupted; no partial output was left") && !e.contains(".partial"),
        "{e}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).is_empty(), "no 'wrote'");
    assert_eq!(files_in(d), ["s.labels.vol", "s.vol"]);
    let now = ["s.vol", "s.labels.vol"].map(|n| std::fs::read(d.join(n)).unwrap());
    assert!(now == old, "the old files changed");
}

/// A header's detached data file is an input: converting onto it is refused
/// as converting onto the header is (before: `--force` replaced the samples).
#[test]
fn convert_never_writes_over_a_header_s_data_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let samples: Vec<u8> = (0..64).collect();
    std::fs::write(d.join("scan.raw"), &samples).unwrap();
    std::fs::write(
        d.join("scan.mhd"),
        "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nElementDataFile = scan.raw\n",
    )
    .unwrap();
    std::fs::write(
        d.join("scan.nhdr"),
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: scan.raw\n",
    )
    .unwrap();
    for header in ["scan.mhd", "scan.nhdr"] {
        let o = volgen(d, &["convert", header, "-o", "scan.raw", "--force"]);
        assert_eq!(o.status.code(), Some(1), "{header}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("scan.raw: is both the input and the output"),
            "{header}: {}",
            stderr(&o)
        );
        assert_eq!(std::fs::read(d.join("scan.raw")).unwrap(), samples);
    }
    assert_eq!(files_in(d), ["scan.mhd", "scan.nhdr", "scan.raw"]);
}

/// Commands that read `.vol` files only say so of a foreign volume, and a
/// folder named like a volume file is said to be a folder (before: "its name
/// ends in none of .vol, .nrrd, …" of a .nrrd; a DICOM search of the folder).
#[test]
fn vol_only_commands_and_folders_named_vol_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut nrrd = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
    nrrd.extend([7u8; 64]);
    std::fs::write(d.join("s.nrrd"), nrrd).unwrap();
    let o = volgen(d, &["pyramid", "s.nrrd"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("s.nrrd: is a NRRD volume, and this command reads .vol files: `volgen convert s.nrrd -o NAME.vol`"),
        "{}",
        stderr(&o)
    );
    std::fs::create_dir(d.join("d.vol")).unwrap();
    for args in [&["info", "d.vol"][..], &["pyramid", "d.vol"]] {
        let o = volgen(d, args);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(
            stderr(&o).contains("d.vol: is a directory"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
}

/// The thesis header cannot mark labels: a thesis scene's labels take the
/// extended header (before: a thesis label file that read as values), and a
/// conversion of labels to the thesis format is refused.
#[test]
fn labels_never_take_the_thesis_header() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(
        d,
        &[
            "generate", "--scene", "shells", "--size", "20", "--format", "thesis", "-o", "t.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        out.contains("t.vol: 20x20x20 u8 bricked (side 16), thesis header"),
        "{out}"
    );
    assert!(
        out.contains("t.labels.vol: 20x20x20 u8 labels bricked (side 16), extended header"),
        "{out}"
    );
    let o = volgen(
        d,
        &[
            "convert",
            "t.labels.vol",
            "--format",
            "thesis",
            "-o",
            "x.vol",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("the thesis header cannot mark a label volume"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("x.vol").exists());
}

/// `-o -` is no file: refused, where it made a file named `-`; a folder as the
/// output is said alone, without the warning about its name.
#[test]
fn standard_output_and_folders_are_refused_as_outputs_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(d, &["generate", "--size", "8", "-o", "-"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("not to standard output"),
        "{}",
        stderr(&o)
    );
    std::fs::create_dir(d.join("out")).unwrap();
    let o = volgen(d, &["generate", "--size", "8", "-o", "out"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    assert_eq!(files_in(d), ["out"]);
}

/// `--brick` with `--layout linear` is refused by generate as by convert
/// (generate ignored it).
#[test]
fn a_brick_side_for_a_linear_layout_is_refused_by_both_writers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(d, &["generate", "--size", "8", "-o", "a.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for args in [
        &[
            "generate", "--size", "8", "--layout", "linear", "--brick", "8", "-o", "x.vol",
        ][..],
        &[
            "convert", "a.vol", "--layout", "linear", "--brick", "8", "-o", "x.vol",
        ],
    ] {
        let o = volgen(d, args);
        // Flags that do not go together: a wrong command line.
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(
            stderr(&o).contains("--brick applies to --layout bricked only"),
            "{}",
            stderr(&o)
        );
    }
    for args in [
        &[
            "generate", "--size", "8", "--type", "u16", "--format", "thesis", "-o", "x.vol",
        ][..],
        &[
            "convert", "a.vol", "--type", "u16", "--format", "thesis", "-o", "x.vol",
        ],
    ] {
        let o = volgen(d, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("--format thesis holds u8 samples only"));
    }
    assert_eq!(files_in(d), ["a.vol"]);
}

/// Extreme spacings are shown in exponent form (before: `0.000000000001 x 2
/// x 1000000000000`). (Two files: one spacing of 1e-12 beside one of 1e12
/// is past the ratio `volgen generate` writes.)
#[test]
fn info_shows_extreme_spacings_in_exponent_form() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (spacing, shown) in [
        ("1e-12,2e-12,1e-12", "spacing     1e-12 x 2e-12 x 1e-12\n"),
        ("1e12,2e12,1e12", "spacing     1e12 x 2e12 x 1e12\n"),
    ] {
        let args = [
            "generate",
            "--size",
            "8",
            "--spacing",
            spacing,
            "-o",
            "a.vol",
            "--force",
        ];
        let o = volgen(d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = volgen(d, &["info", "a.vol", "--no-histogram"]);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(out.contains(shown), "{out}");
    }
}

#[test]
fn an_impossible_size_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let o = volgen(dir.path(), &["generate", "--size", "100000", "-o", "x.vol"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("x.vol: needs ") && e.contains("free"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(start.elapsed() < Duration::from_secs(10));
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?}",
        files_in(dir.path())
    );
}

#[test]
fn stale_partial_files_of_a_killed_run_are_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // What SIGKILL leaves: the partial file of a process that is gone.
    let child = Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(d)
        .args([
            "generate", "--scene", "noise", "--size", "600", "-o", "a.vol",
        ])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !files_in(d).iter().any(|n| n.ends_with(".partial")) {
        assert!(start.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut child = child;
    child.kill().unwrap();
    child.wait().unwrap();
    let left = files_in(d);
    assert!(
        left.iter()
            .any(|n| n.starts_with(".a.vol.") && n.ends_with(".partial")),
        "{left:?}"
    );
    // Someone else's file of a similar name stays.
    std::fs::write(d.join(".a.vol.notes.partial"), b"not ours").unwrap();
    let o = volgen(d, &["generate", "--size", "8", "-o", "a.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(files_in(d), [".a.vol.notes.partial", "a.vol"]);
}

#[test]
fn a_closed_stdout_is_a_quiet_exit_not_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let o = volgen(
        dir.path(),
        &["generate", "--size", "20", "-o", "a.vol", "-q"],
    );
    assert!(o.status.success());
    // `volgen info a.vol | head -0`: the reader is gone before anything is written.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(dir.path())
        .args(["info", "a.vol"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(!e.contains("panicked"), "{e}");
    assert_ne!(o.status.code(), Some(101), "{e}");
    assert!(
        o.status.signal() == Some(libc::SIGPIPE) || o.status.success(),
        "{:?}: {e}",
        o.status
    );
}

#[test]
fn named_pipes_and_devices_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mkfifo(&d.join("p.vol"));
    mkfifo(&d.join("p.nrrd"));
    mkfifo(&d.join("plain"));
    for args in [
        &["info", "p.vol"][..],
        &["convert", "p.vol", "-o", "o.vol"],
        &["convert", "p.nrrd", "-o", "o.vol"],
        &["convert", "plain", "-o", "o.vol"],
        &["convert", "plain", "--raw", "4", "-o", "o.vol"],
        &["info", "/dev/zero"],
    ] {
        let start = Instant::now();
        let o = volgen(d, args);
        assert!(start.elapsed() < Duration::from_secs(10), "{args:?} hung");
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("named pipe") || e.contains("is a device"),
            "{args:?}: {e}"
        );
    }
    assert!(!d.join("o.vol").exists());
}

#[test]
fn a_corrupt_range_table_is_reported_by_convert() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = volgen(d, &["generate", "--size", "20", "-o", "a.vol", "-q"]);
    assert!(o.status.success());
    // The table ends the file: scribble over its magic.
    let mut bytes = std::fs::read(d.join("a.vol")).unwrap();
    let table = bytes
        .windows(4)
        .rposition(|w| w == b"RCRG")
        .expect("the range table's magic");
    bytes[table..table + 4].copy_from_slice(b"JUNK");
    std::fs::write(d.join("a.vol"), &bytes).unwrap();
    let o = volgen(d, &["convert", "a.vol", "-o", "b.vol"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("a.vol: the value-range table after the samples is corrupt"),
        "{}",
        stderr(&o)
    );
    // The copy has a good table again.
    let o = volgen(d, &["info", "b.vol", "--no-histogram"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = volgen(d, &["info", "a.vol", "--no-histogram"]);
    assert!(stderr(&o).contains("corrupt"), "{}", stderr(&o));
    // A u8 file's table claiming a value no u8 sample holds is corrupt too
    // (before: read, and `info` said "max 60000").
    let mut bytes = std::fs::read(d.join("b.vol")).unwrap();
    let table = bytes.windows(4).rposition(|w| w == b"RCRG").unwrap();
    let first = table + TABLE_HEADER_LEN;
    bytes[first + 2..first + 4].copy_from_slice(&60000u16.to_le_bytes());
    std::fs::write(d.join("c.vol"), &bytes).unwrap();
    let o = volgen(d, &["info", "c.vol", "--no-histogram"]);
    assert!(
        stderr(&o).contains("c.vol: the value-range table after the samples is corrupt"),
        "{}",
        stderr(&o)
    );
}

/// Bytes of a range table before its entries (docs/format.md: magic, brick
/// side, volume size, brick count).
const TABLE_HEADER_LEN: usize = 4 + 4 + 12 + 8;

#[test]
fn negative_numbers_reach_the_value_checks() {
    let dir = tempfile::tempdir().unwrap();
    let o = volgen(dir.path(), &["generate", "--spacing", "-1", "-o", "a.vol"]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(!e.contains("-- -1"), "{e}");
    assert!(e.contains("-1"), "{e}");
}

#[test]
fn force_onto_a_symbolic_link_replaces_the_link_and_keeps_its_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("target.vol"), b"the link's target").unwrap();
    std::os::unix::fs::symlink("target.vol", d.join("link.vol")).unwrap();
    let o = volgen(d, &["generate", "--size", "8", "-o", "link.vol"]);
    assert_eq!(o.status.code(), Some(1), "an existing link needs --force");
    let o = volgen(d, &["generate", "--size", "8", "-o", "link.vol", "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let meta = std::fs::symlink_metadata(d.join("link.vol")).unwrap();
    assert!(meta.file_type().is_file(), "the link became the new file");
    assert_eq!(
        std::fs::read(d.join("target.vol")).unwrap(),
        b"the link's target"
    );
}

#[test]
fn sigterm_while_converting_a_compressed_scan_cancels_cleanly() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 400usize;
    let mut nrrd =
        format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: {n} {n} {n}\nencoding: gzip\n\n")
            .into_bytes();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    let plane: Vec<u8> = (0..n * n).map(|i| (i % 251) as u8).collect();
    for _ in 0..n {
        gz.write_all(&plane).unwrap();
    }
    nrrd.extend(gz.finish().unwrap());
    std::fs::write(d.join("s.nrrd"), nrrd).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_volgen"))
        .current_dir(d)
        .args(["convert", "s.nrrd", "-o", "s.vol"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Early: while the stream is decompressed (the handler is installed at start).
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGTERM) }, 0);
    let o = wait_at_most(child, Duration::from_secs(30));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{e}");
    assert!(e.contains("interrupted; no partial output was left"), "{e}");
    assert!(!e.contains("corrupt"), "{e}");
    assert_eq!(files_in(d), ["s.nrrd"]);
}

#[test]
fn info_charts_a_constant_or_narrow_float_file_with_labels_that_differ() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let header =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\n\n";
    let write = |name: &str, value: &dyn Fn(usize) -> f32| {
        let mut nrrd = header.to_vec();
        (0..64).for_each(|i| nrrd.extend(value(i).to_le_bytes()));
        std::fs::write(d.join(name), nrrd).unwrap();
    };
    let chart = |name: &str| {
        let o = volgen(d, &["info", name]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let labels: Vec<String> = out
            .lines()
            .skip_while(|l| !l.starts_with("histogram"))
            .skip(1)
            .map(|l| l.split_whitespace().next().unwrap().to_string())
            .collect();
        (out, labels)
    };
    // One value: one bin (before: sixteen, each labelled 3).
    write("constant.nrrd", &|_| 3.0);
    let (out, labels) = chart("constant.nrrd");
    assert!(out.contains("histogram   1 bin over min..max"), "{out}");
    assert_eq!(labels, ["3"], "{out}");
    // Values 1e-5 apart: sixteen bins, no two labelled alike.
    write("narrow.nrrd", &|i| 1000.0 + i as f32 * 1e-5);
    let (out, labels) = chart("narrow.nrrd");
    assert_eq!(labels.len(), 16, "{out}");
    let mut distinct = labels.clone();
    distinct.dedup();
    assert_eq!(distinct, labels, "{out}");
    // The whole f32 range: bins of finite width (before: NaN and inf, the
    // range's width overflowing f32).
    write("huge.nrrd", &|i| if i % 2 == 0 { 3.4e38 } else { -3.4e38 });
    let (out, labels) = chart("huge.nrrd");
    assert_eq!(labels.len(), 16, "{out}");
    assert!(!out.contains("NaN") && !out.contains("inf"), "{out}");
}

#[test]
fn info_reads_foreign_files_in_their_own_units() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // An i16 NRRD of CT-like values: -1000 (air) and 40..=1039.
    let mut nrrd = b"NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\nspacings: 0.5 0.5 2\n\n".to_vec();
    for i in 0..64i16 {
        let v: i16 = if i < 32 { -1000 } else { 40 + (i - 32) * 32 };
        nrrd.extend(v.to_le_bytes());
    }
    std::fs::write(d.join("ct.nrrd"), nrrd).unwrap();
    let o = volgen(d, &["info", "ct.nrrd"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    for needle in [
        "format      NRRD",
        "4x4x4 (64 voxels)",
        "spacing     0.5 x 0.5 x 2",
        "i16, little endian, raw data",
        "min -1000, max 1032 (the file's units)",
        "16 bins over min..max, bars on a log scale",
        // Whole-number bins for whole-number values (2033 values: 128 a bin,
        // the last one cut at the largest value).
        "-1000..-873",
        "920..1032",
    ] {
        assert!(out.contains(needle), "info lacks `{needle}`:\n{out}");
    }
    assert!(!out.contains("Some(") && !out.contains("Raw"), "{out}");
}

/// A write past the file-size limit (`ulimit -f`) fails with its error, said
/// once, and leaves no partial file (SIGXFSZ killed the process, status 153,
/// and left its temporary files behind).
#[test]
fn the_file_size_limit_fails_the_write_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let o = volgen(
        dir.path(),
        &[
            "generate",
            "--size",
            "200",
            "--no-pyramid",
            "-o",
            "flat.vol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for command in ["generate --size 300 -o generated.vol", "pyramid flat.vol"] {
        let out = Command::new("bash")
            .arg("-c")
            .arg(format!(
                "ulimit -f 40 && exec {} {command}",
                env!("CARGO_BIN_EXE_volgen")
            ))
            .current_dir(dir.path())
            .output()
            .unwrap();
        let said = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{command}: {said}");
        assert!(said.contains("File too large"), "{command}: {said}");
        assert_eq!(
            said.matches("error:").count(),
            1,
            "{command}: said once: {said}"
        );
        assert_eq!(files_in(dir.path()), ["flat.vol"], "{command}");
    }
}
