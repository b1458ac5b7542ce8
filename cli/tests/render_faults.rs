//! `raycaster render` on user mistakes and faults: the output checked before
//! rendering, no overwrite without --force, PNG only, a label volume given as data,
//! near-miss presets, negative values, a closed stdout, absurd spacings.

mod support;

use support::{raycaster, stderr};

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use raycaster::volume::{Content, Format, Header, Layout, Orientation, PatientSpace, SampleType};

const SMALL: [&str; 4] = ["--scene-size", "16", "--size", "24"];

fn render(dir: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["render"];
    args.extend(SMALL);
    args.extend(extra);
    raycaster(&args, dir)
}

/// An output that is a link to a missing file is refused without `--force`
/// before any work (the render used to replace the link silently), and
/// replaced with it.
#[test]
fn a_dangling_link_as_the_output_needs_force() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::os::unix::fs::symlink(d.join("nowhere.png"), d.join("out.png")).unwrap();
    let o = render(d, &["-o", "out.png"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("out.png: is a symbolic link to a missing file (pass --force"),
        "{}",
        stderr(&o)
    );
    assert!(d.join("out.png").symlink_metadata().unwrap().is_symlink());
    let o = render(d, &["-o", "out.png", "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(raycaster::render::RgbImage::load_png(&d.join("out.png")).is_ok());
}

/// Writes a `.vol` of `dims` u8 samples (`value(i)`) with `spacing` and `content`.
fn write_vol(path: &Path, dims: [u32; 3], spacing: [f32; 3], content: Content) {
    let h = Header::new(
        dims,
        spacing,
        Layout::Linear,
        SampleType::U8,
        content,
        Format::Extended,
    );
    let mut bytes = h.encode().unwrap();
    let n = dims.iter().product::<u32>() as usize;
    bytes.extend((0..n).map(|i| (i % 5) as u8 * 50));
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn the_output_is_checked_before_rendering_and_kept_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A missing folder: refused at once, said once.
    let o = render(d, &["-o", "nodir/a.png"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("nodir/a.png") && e.contains("does not exist"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "{e}");
    assert_eq!(e.matches("does not exist").count(), 1, "{e}");
    // A file where the folder should be is no folder (it was "does not exist").
    std::fs::write(d.join("plain"), b"x").unwrap();
    let o = render(d, &["-o", "plain/a.png"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o)
            .trim_end()
            .ends_with("plain/a.png: cannot write there: plain is not a directory"),
        "{}",
        stderr(&o)
    );
    // Another format's name.
    let o = render(d, &["-o", "a.jpg"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("a.jpg: only PNG"), "{}", stderr(&o));
    assert!(!d.join("a.jpg").exists());
    // An existing image is replaced only with --force.
    std::fs::write(d.join("a.png"), b"keep me").unwrap();
    let o = render(d, &["-o", "a.png"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("a.png: already exists (pass --force"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(d.join("a.png")).unwrap(), b"keep me");
    let o = render(d, &["-o", "a.png", "--force", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(std::fs::read(d.join("a.png")).unwrap(), b"keep me");
}

#[test]
fn a_label_volume_given_as_data_points_at_labels_and_segments() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_vol(&d.join("x.labels.vol"), [8; 3], [1.0; 3], Content::Labels);
    write_vol(&d.join("x.vol"), [8; 3], [1.0; 3], Content::Scalar);
    let o = raycaster(&["render", "x.labels.vol", "-o", "a.png"], d);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("x.labels.vol: is a label volume")
            && e.contains("--labels")
            && e.contains("--segments"),
        "{e}"
    );
    assert!(!d.join("a.png").exists());
    // And values given as labels.
    let scene = d.join("s.toml");
    std::fs::write(&scene, "labels = \"x.vol\"\n[[object]]\nmode = \"dvr\"\n").unwrap();
    let o = raycaster(
        &[
            "render",
            "x.vol",
            "--segments",
            "s.toml",
            "--labels",
            "x.vol",
            "-o",
            "b.png",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not labels"), "{}", stderr(&o));
    // Labels for a scene of value layers: they would be ignored; said.
    let layers = d.join("layers.toml");
    std::fs::write(
        &layers,
        "layers = [[0.1, 1.0]]\n[[object]]\nid = 1\nmode = \"dvr\"\n",
    )
    .unwrap();
    let o = raycaster(
        &[
            "render",
            "x.vol",
            "--segments",
            "layers.toml",
            "--labels",
            "x.labels.vol",
            "-o",
            "c.png",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("x.labels.vol: the scene takes its objects from value layers"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "said once: {e}");
    assert!(!d.join("c.png").exists());
    // Labels of another size: said in the files' own sizes (before: those of
    // the pyramid level the frame sampled, which neither file is).
    write_vol(&d.join("y.vol"), [12; 3], [1.0; 3], Content::Scalar);
    let o = raycaster(
        &[
            "render",
            "y.vol",
            "--segments",
            "s.toml",
            "--labels",
            "x.labels.vol",
            "-o",
            "d.png",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("x.labels.vol: the labels are 8x8x8 voxels and the volume 12x12x12"),
        "{e}"
    );
    assert!(!d.join("d.png").exists());
}

#[test]
fn near_miss_presets_get_a_suggestion_and_a_missing_file_is_not_a_preset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = render(d, &["--tf", "ct-bon"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("did you mean ct-bone?"),
        "{}",
        stderr(&o)
    );
    let o = render(d, &["--tf", "ramp.tf"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("ramp.tf: no such transfer-function file"), "{e}");
    assert!(!e.contains("unknown"), "{e}");
    let o = render(d, &["--tf", "tfs/ct-bonee"]);
    assert!(
        stderr(&o).contains("did you mean the preset ct-bone?"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("render.png").exists());
}

/// Under an address-space limit (`ulimit -v`) a frame too large for it is
/// refused with the numbers and the limit named, where the allocation failed
/// and the process aborted.
#[test]
fn a_frame_beyond_the_address_space_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = under_limit(dir.path(), "-v 3000000", "render --size 8192 -o big.png");
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let said = stderr(&out);
    assert!(
        said.contains("a 8192×8192 frame needs about 4.8 GB of memory")
            && said.contains("under the process's address-space limit (ulimit -v)"),
        "{said}"
    );
    assert!(!dir.path().join("big.png").exists());
}

/// `raycaster ARGS` (a subcommand and its flags) in `dir` under the shell limit
/// `limit` (`-v KIB`: address space, `-f BLOCKS`: file size).
fn under_limit(dir: &Path, limit: &str, args: &str) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit {limit} && exec {} {args}",
            env!("CARGO_BIN_EXE_raycaster")
        ))
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Writes a linear 600³ u8 `.vol` at `path` whose 216 MB of samples are a
/// hole: nothing on disk.
fn sparse_volume(path: &Path) {
    let h = Header::new(
        [600; 3],
        [1.0; 3],
        Layout::Linear,
        SampleType::U8,
        Content::Scalar,
        Format::Extended,
    );
    let header = h.encode().unwrap();
    std::fs::write(path, &header).unwrap();
    std::fs::File::options()
        .append(true)
        .open(path)
        .unwrap()
        .set_len(header.len() as u64 + 600 * 600 * 600)
        .unwrap();
}

/// A volume larger than the address-space limit is refused with the numbers,
/// read into memory (`--ram`: the allocation aborted the process, status 134)
/// or mapped (it said "Cannot allocate memory (os error 12)").
#[test]
fn a_volume_beyond_the_address_space_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    sparse_volume(&dir.path().join("large.vol"));
    for (flags, said) in [
        (
            "--ram",
            "large.vol: reading it into memory (--ram) needs about 237.6 MB and ",
        ),
        (
            "",
            "large.vol: mapping it needs 216.0 MB of address space, more than this process may take",
        ),
    ] {
        let out = under_limit(
            dir.path(),
            "-v 200000",
            &format!("render large.vol --size 32x32 {flags} -o out.png"),
        );
        assert_eq!(out.status.code(), Some(1), "{flags}: {}", stderr(&out));
        assert!(stderr(&out).contains(said), "{flags}: {}", stderr(&out));
        assert!(!dir.path().join("out.png").exists());
    }
}

/// A `--brick` side whose bricks' tables cannot fit the memory the process
/// may take is refused with the numbers (the allocation aborted the process,
/// or the machine ran out of memory).
#[test]
fn bricks_beyond_the_address_space_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    sparse_volume(&dir.path().join("large.vol"));
    let out = under_limit(
        dir.path(),
        "-v 1000000",
        "render large.vol --size 32x32 --brick 2 -o out.png",
    );
    let said = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("--brick 2 cuts the volume into 214.9 M bricks, whose tables need about 1.7 GB of memory")
            && said.contains("under the process's address-space limit (ulimit -v)"),
        "{said}"
    );
    assert!(!dir.path().join("out.png").exists());
}

/// `bench` refuses what render refuses under a memory limit: `--ram` of a
/// volume (a named file or the generated one) larger than the process may
/// take, and `--bricks` sides whose tables cannot fit (both aborted the
/// process, status 134). Nothing is generated into the cache folder.
#[test]
fn bench_beyond_the_address_space_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    sparse_volume(&dir.path().join("large.vol"));
    let bench = "bench --image 16x16 --threads 1 --tiles 16 --frames 1 --cache-dir cache";
    for (limit, flags, said) in [
        (
            "-v 200000",
            "large.vol --ram --bricks 16",
            "large.vol: reading it into memory (--ram) needs about 237.6 MB and ",
        ),
        (
            "-v 200000",
            "--volume-size 600 --ram --bricks 16",
            "the generated volume: reading it into memory (--ram) needs about 237.6 MB and ",
        ),
        (
            "-v 1000000",
            "large.vol --bricks 16,2",
            "--bricks 2 cuts the volume into 214.9 M bricks, whose tables need about 1.7 GB of memory",
        ),
    ] {
        let out = under_limit(dir.path(), limit, &format!("{bench} {flags}"));
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{flags}: {err}");
        assert!(err.contains(said), "{flags}: {err}");
        assert!(
            err.contains("under the process's address-space limit (ulimit -v)"),
            "{flags}: {err}"
        );
        assert_eq!(
            err.lines().filter(|l| l.starts_with("error")).count(),
            1,
            "{err}"
        );
        let cached = std::fs::read_dir(dir.path().join("cache")).map_or(0, |d| d.count());
        assert_eq!(cached, 0, "{flags}");
    }
}

/// `compare` of images larger than the process may hold is refused with the
/// numbers, once: decoding them (or the `--diff` image) aborted the process
/// (status 134).
#[test]
fn compare_beyond_the_address_space_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let black = raycaster::render::RgbImage::new(8000, 8000, vec![0; 8000 * 8000 * 3]);
    black.save_png(&dir.path().join("a.png")).unwrap();
    std::fs::copy(dir.path().join("a.png"), dir.path().join("b.png")).unwrap();
    for flags in ["", "--diff d.png"] {
        let out = under_limit(
            dir.path(),
            "-v 200000",
            &format!("compare a.png b.png {flags}"),
        );
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{flags}: {err}");
        assert!(
            err.contains("a.png: decoding it needs ")
                && err.contains(" MB of memory, more than this process can allocate"),
            "{flags}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!dir.path().join("d.png").exists());
    }
}

/// Threads the system refuses (an address-space limit leaving no room for
/// their stacks) are said once, before any frame: the frame's threads, or
/// rayon's pool at its first use, panicked (status 101).
#[test]
fn threads_the_system_refuses_are_said_not_panicked() {
    let dir = tempfile::tempdir().unwrap();
    for command in [
        "render --scene-size 16 --size 16 --threads 200 -o out.png",
        "bench --quick --image 16x16 --threads 1,200 --tiles 16 --bricks 16 --cache-dir cache",
    ] {
        let out = under_limit(dir.path(), "-v 30000", command);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{command}: {err}");
        assert!(err.starts_with("error: cannot start "), "{command}: {err}");
        assert!(err.contains("ulimit -v"), "{command}: {err}");
        assert_eq!(err.lines().count(), 1, "{command}: {err}");
        assert!(!dir.path().join("out.png").exists());
    }
}

/// An elevation past a pole is refused (it was clamped to the pole without a
/// word), and an --up within a degree of the view direction is warned of
/// (the picture's roll then follows the small difference).
#[test]
fn camera_flags_past_their_sense_are_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for elevation in ["91", "-90.5", "1000"] {
        let o = render(d, &["--elevation", elevation]);
        assert_eq!(o.status.code(), Some(2), "{elevation}");
        assert!(
            stderr(&o).contains("must lie between -90"),
            "{}",
            stderr(&o)
        );
    }
    let o = render(d, &["--elevation", "-90", "-o", "pole.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render(
        d,
        &[
            "--position",
            "1000,0,1",
            "--target",
            "0,0,0",
            "--up",
            "1,0,0",
            "-o",
            "up.png",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    assert!(
        said.contains("warning: --up 1,0,0 lies 0.06° from the view direction"),
        "{said}"
    );
    let o = render(
        d,
        &[
            "--position",
            "1000,0,1",
            "--target",
            "0,0,0",
            "--up",
            "0,0,1",
            "-o",
            "up2.png",
        ],
    );
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

#[test]
fn negative_numbers_are_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = render(d, &["--step", "-1"]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("must be a positive number"), "{e}");
    assert!(!e.contains("-- -1"), "{e}");
    let o = render(
        d,
        &[
            "--azimuth",
            "-30",
            "--elevation",
            "-10",
            "--domain",
            "-10,200",
            "--light",
            "-1,0,-1",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render(
        d,
        &[
            "--position",
            "-40,-30,20",
            "--up",
            "0,0,-1",
            "-o",
            "p.png",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A camera the flags make impossible is refused naming the flags and a way
/// out (before: one line about "view direction and up vector" for all).
#[test]
fn impossible_cameras_name_their_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (flags, said) in [
        (
            &["--position", "0,0,500", "--target", "0,0,0"][..],
            "error: the camera looks along its up direction --up 0,0,1 (from 0,0,500 to 0,0,0): give another --up, e.g. --up 0,1,0",
        ),
        (
            &["--position", "8,8,8", "--target", "8,8,8"][..],
            "error: --position 8,8,8 and --target 8,8,8 are the same point: the camera looks nowhere",
        ),
        (
            &["--distance", "1e30"][..],
            "error: --distance 1e30: the camera is too far away for its view to be computed",
        ),
    ] {
        let mut args = flags.to_vec();
        args.extend(["-o", "c.png"]);
        let o = render(d, &args);
        assert_eq!(o.status.code(), Some(1), "{flags:?}");
        let e = stderr(&o);
        assert!(e.starts_with(said), "{flags:?}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(!d.join("c.png").exists());
    }
    // A zero --up is a command-line error, as a zero --light is (it was a
    // failure, exit 1).
    for flag in ["--up", "--light"] {
        let o = render(d, &[flag, "0,0,0", "-o", "c.png"]);
        assert_eq!(o.status.code(), Some(2), "{flag}");
        assert!(
            stderr(&o).contains("\"0,0,0\" is no direction: x, y and z are all zero"),
            "{}",
            stderr(&o)
        );
    }
}

#[test]
fn a_closed_stdout_is_a_quiet_exit_not_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let mut args = vec!["render", "--stats-json", "-q"];
    args.extend(SMALL);
    let o = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args(&args)
        .current_dir(dir.path())
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(!e.contains("panicked"), "{e}");
    assert_ne!(o.status.code(), Some(101), "{e}");
    assert_eq!(
        o.status.signal(),
        Some(libc::SIGPIPE),
        "{:?}: {e}",
        o.status
    );
}

/// Standard output or error on a full disk (`> /dev/full`): the image is
/// written, one error line says what was lost, exit 1 (it panicked, 101).
#[test]
fn a_full_standard_output_or_error_is_an_error_line_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let full = || std::fs::File::create("/dev/full").unwrap();
    let mut args = vec!["render", "--stats-json", "--force", "-o", "out.png"];
    args.extend(SMALL);
    let o = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args(&args)
        .current_dir(dir.path())
        .stdout(full())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    // (With --stats-json the summary line goes to standard error.)
    assert!(
        e.ends_with("\nerror: standard output: No space left on device (os error 28); the output printed is incomplete\n"),
        "{e}"
    );
    assert_eq!(e.matches("error:").count(), 1, "{e}");
    assert!(dir.path().join("out.png").exists());
    // Standard error full: nothing can be said, the image is written all the same.
    let o = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args(&args)
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(full())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&o.stdout).contains("\"samples\""));
}

#[test]
fn absurd_spacings_are_refused_at_once_not_rendered_forever() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A .vol whose spacing is fine for its header but whose rays would take
    // billions of samples at this step.
    write_vol(
        &d.join("thin.vol"),
        [32; 3],
        [1e-4, 1.0, 1.0],
        Content::Scalar,
    );
    let start = Instant::now();
    let o = raycaster(
        &[
            "render", "thin.vol", "--step", "0.001", "--size", "64", "-o", "t.png",
        ],
        d,
    );
    assert!(start.elapsed() < Duration::from_secs(20));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("a ray would take up to") && e.contains("spacing"),
        "{e}"
    );
    assert!(!d.join("t.png").exists());
    // An even spacing: the step is the cause, and the message says only that.
    write_vol(&d.join("even.vol"), [32; 3], [1.0; 3], Content::Scalar);
    let o = raycaster(
        &[
            "render", "even.vol", "--step", "1e-5", "--size", "64", "-o", "t.png",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("a ray would take up to")
            && e.contains("raise the step (`--step`")
            && !e.contains("spacing"),
        "{e}"
    );
    // The same volume at the default step renders.
    let o = raycaster(
        &["render", "thin.vol", "--size", "32", "-o", "u.png", "-q"],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));

    // A NIfTI header with pixdim (1e-45, 1, 1).
    let mut nii = vec![0u8; 352];
    nii[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, v) in [3i16, 8, 8, 8, 1, 1, 1, 1].iter().enumerate() {
        nii[40 + 2 * i..42 + 2 * i].copy_from_slice(&v.to_le_bytes());
    }
    nii[70..72].copy_from_slice(&2i16.to_le_bytes());
    nii[72..74].copy_from_slice(&8i16.to_le_bytes());
    for (i, p) in [1.0f32, 1e-45, 1.0, 1.0].iter().enumerate() {
        nii[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
    }
    nii[108..112].copy_from_slice(&352f32.to_le_bytes());
    nii[344..348].copy_from_slice(b"n+1\0");
    nii.extend(vec![7u8; 512]);
    std::fs::write(d.join("thin.nii"), nii).unwrap();
    let start = Instant::now();
    let o = raycaster(&["render", "thin.nii", "-o", "n.png"], d);
    assert!(start.elapsed() < Duration::from_secs(20));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("thin.nii") && e.contains("times the smallest"),
        "{e}"
    );
}

#[test]
fn a_mapped_file_truncated_while_rendering_fails_with_a_message_not_sigbus() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_vol(&d.join("big.vol"), [128; 3], [1.0; 3], Content::Scalar);
    // A frame of many seconds: no early termination, no skipping, a fine step.
    let child = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args([
            "render", "big.vol", "--size", "1024", "--step", "0.1", "--no-ert", "--no-ess", "--tf",
            "cloud", "-o", "big.png", "-q",
        ])
        .current_dir(d)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    // Another program truncates the file under the mapping.
    std::fs::OpenOptions::new()
        .write(true)
        .open(d.join("big.vol"))
        .unwrap()
        .set_len(64)
        .unwrap();
    let o = child.wait_with_output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{:?}: {e}", o.status);
    assert!(
        e.contains("big.vol: shrank or vanished while it was read"),
        "{e}"
    );
    assert!(!d.join("big.png").exists());
}

#[test]
fn long_frames_show_progress() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A frame of a second or so.
    let slow = [
        "render",
        "--scene",
        "noise",
        "--scene-size",
        "96",
        "--size",
        "512",
        "--step",
        "0.2",
        "--no-ert",
        "--no-ess",
        "-q",
    ];
    let o = raycaster(&[&slow[..], &["--progress", "-o", "a.png"]].concat(), d);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("rendering") && e.contains(" %"), "{e}");
    // A log (not a terminal) ends on the finished state, on a line of its own;
    // the same for the sequential renderer.
    for e in [e, {
        let o = raycaster(
            &[&slow[..], &["--progress", "--sequential", "-o", "s.png"]].concat(),
            d,
        );
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    }] {
        let last = e.lines().last().unwrap_or("").rsplit('\r').next().unwrap();
        assert!(last.starts_with("rendering 100 % ("), "{e:?}");
    }
    // Quiet without --progress when stderr is not a terminal.
    let o = raycaster(&[&slow[..], &["-o", "b.png"]].concat(), d);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
}

/// Bench's sweep lists are read as render reads its flags: a value out of
/// range is a wrong command line (exit 2), said before anything runs. (Before:
/// `--bricks 100000` aborted on a 62 TB allocation; the others exited 1.)
#[test]
fn bench_refuses_out_of_range_lists_as_a_wrong_command_line() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, value) in [
        ("--bricks", "100000"),
        ("--bricks", "8,1"),
        ("--threads", "0"),
        ("--threads", "5000"),
        ("--tiles", "0"),
        ("--frames", "0"),
        ("--step", "0"),
    ] {
        let o = raycaster(&["bench", "--quick", flag, value], dir.path());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {e}");
        assert!(e.starts_with("error: invalid value"), "{flag} {value}: {e}");
        assert!(e.contains(flag), "{e}");
    }
}

/// Bench reads `.vol` files only, and says so of a foreign volume; a folder
/// named like a volume file is said to be a folder.
#[test]
fn bench_names_what_it_reads_and_folders_named_vol_are_folders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut nrrd = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
    nrrd.extend([7u8; 64]);
    std::fs::write(d.join("s.nrrd"), nrrd).unwrap();
    let o = raycaster(&["bench", "s.nrrd", "--quick"], d);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("s.nrrd: is a NRRD volume, and this command reads .vol files"),
        "{}",
        stderr(&o)
    );
    // A file as the cache folder (before: "File exists (os error 17)").
    std::fs::write(d.join("afile"), b"x").unwrap();
    let o = raycaster(&["bench", "--quick", "--cache-dir", "afile"], d);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("--cache-dir afile: is not a folder"),
        "{}",
        stderr(&o)
    );
    std::fs::create_dir(d.join("d.vol")).unwrap();
    for args in [
        &["render", "d.vol", "-o", "x.png"][..],
        &[
            "slice", "d.vol", "--axis", "z", "--index", "0", "-o", "x.png",
        ],
        &["bench", "d.vol", "--quick"],
    ] {
        let o = raycaster(args, d);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(
            stderr(&o).contains("d.vol: is a directory"),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(!d.join("x.png").exists());
    }
}

/// A foreign file whose samples are cut short is said to be, whatever size
/// its header declares (before: a 35 TB declaration was refused as too large
/// to open in memory, with the advice to convert it, which then failed).
#[test]
fn a_truncated_foreign_file_is_said_to_be_before_its_size_is_weighed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut nrrd =
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 32767 32767 32767\nencoding: raw\n\n"
            .to_vec();
    nrrd.extend([0u8; 1000]);
    std::fs::write(d.join("t.nrrd"), nrrd).unwrap();
    for args in [
        &["render", "t.nrrd", "-o", "x.png"][..],
        &[
            "slice", "t.nrrd", "--axis", "z", "--index", "0", "-o", "x.png",
        ],
    ] {
        let o = raycaster(args, d);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(
            e.contains("holds 1000 bytes of samples but the header needs"),
            "{e}"
        );
        assert!(!e.contains("limit"), "{e}");
    }
}

/// A logical brick past the volume's size renders as the one brick it is:
/// as fast as that brick, and the same picture (before: `--brick 1000
/// --sequential` on 64³ ran for over a minute over empty cells).
#[test]
fn a_brick_larger_than_the_volume_is_the_one_brick_of_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (brick, out) in [("1000", "big.png"), ("64", "one.png")] {
        let o = raycaster(
            &[
                "render",
                "--scene-size",
                "64",
                "--brick",
                brick,
                "--sequential",
                "--size",
                "48",
                "-o",
                out,
            ],
            d,
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let big = std::fs::read(d.join("big.png")).unwrap();
    assert!(big == std::fs::read(d.join("one.png")).unwrap());
}

#[test]
fn bench_reports_median_and_spread_writes_its_csv_and_warns_on_one_frame() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = [
        "bench",
        "--volume-size",
        "16",
        "--image",
        "32x32",
        "--threads",
        "1,2",
        "--tiles",
        "16",
        "--bricks",
        "8",
        "--cache-dir",
        "cache",
        "--csv",
        "b.csv",
    ];
    let o = raycaster(&[&common[..], &["--frames", "3"]].concat(), d);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(d.join("b.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    assert!(
        header.contains(&"median_ms") && header.contains(&"spread_ms"),
        "{csv}"
    );
    assert_eq!(csv.lines().count(), 3, "{csv}");
    let table = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(table.contains("median_ms"), "{table}");
    assert!(!stderr(&o).contains("one frame"), "{}", stderr(&o));
    // An existing CSV is refused before the sweep, and kept, without --force.
    let o = raycaster(&[&common[..], &["--frames", "1"]].concat(), d);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("b.csv: already exists (pass --force"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_to_string(d.join("b.csv")).unwrap(), csv);
    let o = raycaster(&[&common[..], &["--frames", "1", "--force"]].concat(), d);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("timed on one frame"), "{}", stderr(&o));
}

#[test]
fn an_interrupted_bench_leaves_no_partial_volume_in_its_cache() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let partials = || -> Vec<String> {
        std::fs::read_dir(&cache)
            .map(|entries| {
                entries
                    .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default()
    };
    for signal in ["TERM", "INT"] {
        // 600³ voxels: seconds of generation, interrupted while the volume is
        // being written (its temporary file exists).
        let child = Command::new(env!("CARGO_BIN_EXE_raycaster"))
            .args([
                "bench",
                "--volume-size",
                "600",
                "--threads",
                "1",
                "--frames",
                "1",
                "--cache-dir",
                "cache",
            ])
            .current_dir(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let started = Instant::now();
        while !partials().iter().any(|n| n.ends_with(".partial")) {
            assert!(
                started.elapsed() < Duration::from_secs(60),
                "no partial file"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let killed = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(130), "{signal}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("interrupted; no partial output was left"),
            "{}",
            stderr(&out)
        );
        assert_eq!(partials(), Vec::<String>::new(), "{signal}");
    }
}

/// An interrupted sweep leaves no CSV of part of its grid (it wrote one row by
/// row while saying that no partial output was left), and `--csv` may name
/// neither the volume it reads (`--force` replaced it with the CSV) nor `-`.
#[test]
fn an_interrupted_bench_leaves_no_csv_and_the_csv_is_never_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut child = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args([
            "bench",
            "--volume-size",
            "48",
            "--image",
            "96x96",
            "--threads",
            "1,2",
            "--tiles",
            "8,16,32",
            "--bricks",
            "8,16",
            "--frames",
            "20",
            "--cache-dir",
            "cache",
            "--csv",
            "part.csv",
        ])
        .current_dir(d)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The heading, then the first measured row: the sweep is under way.
    let mut lines = std::io::BufRead::lines(std::io::BufReader::new(child.stdout.take().unwrap()));
    for _ in 0..2 {
        lines.next().unwrap().unwrap();
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    drop(lines);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", stderr(&out));
    assert!(!d.join("part.csv").exists(), "{}", stderr(&out));
    // The volume it reads, and standard output, are refused before any work.
    let volume = cached_bench_volume(d);
    let before = std::fs::read(&volume).unwrap();
    let name = volume.to_str().unwrap();
    for (csv, said) in [
        (
            name,
            "is an input of this command; name another file for the CSV",
        ),
        ("-", "--csv -: the table goes to standard output already"),
    ] {
        let o = raycaster(&["bench", name, "--quick", "--csv", csv, "--force"], d);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(said), "{}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    }
    assert!(std::fs::read(&volume).unwrap() == before);
}

/// A value given twice in a list is measured once (`--threads 1,1,2` ran
/// rows under identical labels), and `render -o -` says images go to files.
#[test]
fn bench_measures_a_repeated_value_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = raycaster(
        &[
            "bench",
            "--quick",
            "--threads",
            "1,1",
            "--tiles",
            "16,16",
            "--bricks",
            "16,16",
            "--optimisations",
            "both,both",
            "--cache-dir",
            "cache",
            "--csv",
            "r.csv",
        ],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(d.join("r.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2, "{csv}");
    let o = raycaster(&["render", "-o", "-"], d);
    assert!(
        stderr(&o).contains("-: images are written to files, not to standard output"),
        "{}",
        stderr(&o)
    );
}

/// The volume file `raycaster bench` generated into `DIR/cache`.
fn cached_bench_volume(dir: &Path) -> PathBuf {
    std::fs::read_dir(dir.join("cache"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "vol"))
        .expect("the bench's volume")
}

/// Column `name` of the first row of the bench CSV at `path`.
fn first_csv_row_column(path: &Path, name: &str) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().map(|l| l.split(',').collect::<Vec<_>>());
    let header = lines.next().unwrap();
    let row = lines.next().unwrap();
    row[header.iter().position(|h| *h == name).unwrap()].to_string()
}

/// The `samples` of `--stats-json` output.
fn stats_json_samples(out: &std::process::Output) -> u64 {
    let json = String::from_utf8_lossy(&out.stdout).into_owned();
    let at = json.find("\"samples\":").expect("samples") + "\"samples\":".len();
    json[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect::<String>()
        .parse()
        .unwrap()
}

/// `raycaster bench --preintegrate` times the frame `raycaster render
/// --preintegrate` renders: the same samples for the same volume, image, step,
/// bricks and tiles, pre-integrated or not, and the CSV says which.
#[test]
fn bench_preintegrates_the_frame_render_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let samples_of = |pre: bool| {
        let csv = if pre { "p.csv" } else { "n.csv" };
        let mut args = vec![
            "bench",
            "--volume-size",
            "32",
            "--image",
            "48x48",
            "--threads",
            "2",
            "--tiles",
            "16",
            "--bricks",
            "8",
            "--step",
            "1",
            "--frames",
            "1",
            "--cache-dir",
            "cache",
            "--csv",
            csv,
        ];
        if pre {
            args.push("--preintegrate");
        }
        let o = raycaster(&args, d);
        assert!(o.status.success(), "{}", stderr(&o));
        let column = |name| first_csv_row_column(&d.join(csv), name);
        assert_eq!(column("preintegrated"), pre.to_string());
        column("samples").parse::<u64>().unwrap()
    };
    let (bench_pre, bench_plain) = (samples_of(true), samples_of(false));
    let volume = cached_bench_volume(d);
    let rendered = |pre: bool| {
        let mut args = vec![
            "render",
            volume.to_str().unwrap(),
            "--size",
            "48x48",
            "--step",
            "1",
            "--brick",
            "8",
            "--threads",
            "2",
            "--tile",
            "16",
            "--stats-json",
            "-o",
            "r.png",
            "--force",
        ];
        if pre {
            args.push("--preintegrate");
        }
        let o = raycaster(&args, d);
        assert!(o.status.success(), "{}", stderr(&o));
        stats_json_samples(&o)
    };
    assert_eq!(bench_pre, rendered(true));
    assert_eq!(bench_plain, rendered(false));
    assert_ne!(
        bench_pre, bench_plain,
        "pre-integration changes what is skipped"
    );
}

/// bench takes render's names of the same things (`--size`, `--tile`,
/// `--brick`, `--scene-size`) as aliases.
#[test]
fn bench_takes_render_flag_names_as_aliases() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |names: [&str; 4], csv: &str| {
        let [size, tile, brick, scene] = names;
        let args = [
            "bench",
            scene,
            "32",
            size,
            "40x40",
            tile,
            "16",
            brick,
            "8",
            "--threads",
            "1",
            "--frames",
            "1",
            "--warm-up",
            "0",
            "--cache-dir",
            "cache",
            "--csv",
            csv,
        ];
        let o = raycaster(&args, d);
        assert!(o.status.success(), "{}", stderr(&o));
        ["image", "tile", "brick", "volume", "samples"]
            .map(|c| first_csv_row_column(&d.join(csv), c))
    };
    let canonical = run(["--image", "--tiles", "--bricks", "--volume-size"], "a.csv");
    let aliases = run(["--size", "--tile", "--brick", "--scene-size"], "b.csv");
    assert_eq!(canonical, aliases);
    assert_eq!(canonical[..3], ["40x40", "16", "8"]);
}

/// `--quick` gives the volume, image and frame count when they are not
/// given: a size or frame count asked for stays (it used to set 128×128
/// whatever `--size` said, then to cap it; and one frame whatever `--frames`
/// said).
#[test]
fn bench_quick_gives_way_to_sizes_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = [
        "bench",
        "--quick",
        "--threads",
        "1",
        "--tiles",
        "16",
        "--bricks",
        "16",
        "--cache-dir",
        "cache",
        "--csv",
        "q.csv",
        "--force",
    ];
    for (size, expected) in [("64x48", "64x48"), ("200x100", "200x100")] {
        let o = raycaster(&[&common[..], &["--size", size]].concat(), d);
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(first_csv_row_column(&d.join("q.csv"), "image"), expected);
    }
    // Without --size, --quick's 128×128; --frames 2 stays two frames (the
    // one-frame warning does not come).
    let o = raycaster(&[&common[..], &["--frames", "2"]].concat(), d);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(first_csv_row_column(&d.join("q.csv"), "image"), "128x128");
    assert!(
        stderr(&o).contains("2 frame(s) per configuration"),
        "{}",
        stderr(&o)
    );
}

/// `raycaster bench FILE` times the frame `raycaster render FILE --level 0`
/// renders: the transfer function render fits to a u16 file (not the `shapes`
/// preset over the whole u16 range), a named preset over the data's fitted
/// domain, and the view turned to the patient's directions of an oriented file.
#[test]
fn bench_of_a_file_times_the_frame_render_renders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = [
        "--image",
        "40x40",
        "--threads",
        "1",
        "--tiles",
        "16",
        "--bricks",
        "8",
        "--step",
        "1",
        "--frames",
        "1",
        "--warm-up",
        "0",
    ];
    // A u16 volume: the bench's own, cached.
    let mut args = vec![
        "bench",
        "--volume-size",
        "32",
        "--sample-type",
        "u16",
        "--cache-dir",
        "cache",
    ];
    args.extend(common);
    let o = raycaster(&args, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let u16_file = cached_bench_volume(d);
    // An oriented volume (RAS, NIfTI's usual space: the view turns).
    let oriented = d.join("ras.vol");
    let (orientation, _) = Orientation::from_steps(
        PatientSpace::Ras,
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [0.0; 3],
    )
    .unwrap();
    let header = Header::new(
        [32; 3],
        [1.0; 3],
        Layout::Bricked { side: 15 },
        SampleType::U8,
        Content::Scalar,
        Format::Extended,
    )
    .with_orientation(Some(orientation));
    let scene = raycaster::synth::SceneKind::Shapes.build([32; 3], 1);
    raycaster::generate::generate(
        scene.as_ref(),
        &header,
        &oriented,
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap();
    let bench_samples = |file: &Path, tf: Option<&str>| {
        let mut args = vec!["bench", file.to_str().unwrap(), "--csv", "b.csv", "--force"];
        args.extend(common);
        args.extend(tf.map(|t| ["--tf", t]).into_iter().flatten());
        let o = raycaster(&args, d);
        assert!(o.status.success(), "{}", stderr(&o));
        first_csv_row_column(&d.join("b.csv"), "samples")
            .parse::<u64>()
            .unwrap()
    };
    let rendered = |file: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            file.to_str().unwrap(),
            "--size",
            "40x40",
            "--threads",
            "1",
            "--tile",
            "16",
            "--brick",
            "8",
            "--step",
            "1",
            "--level",
            "0",
            "--stats-json",
            "-o",
            "r.png",
            "--force",
        ];
        args.extend(extra);
        let o = raycaster(&args, d);
        assert!(o.status.success(), "{}", stderr(&o));
        stats_json_samples(&o)
    };
    let fitted = bench_samples(&u16_file, None);
    assert_eq!(fitted, rendered(&u16_file, &[]));
    let shapes = bench_samples(&u16_file, Some("shapes"));
    assert_eq!(shapes, rendered(&u16_file, &["--tf", "shapes"]));
    assert_ne!(shapes, fitted);
    let turned = bench_samples(&oriented, None);
    assert_eq!(turned, rendered(&oriented, &[]));
    // (Rendered about the voxel axes, the same file takes other samples.)
    assert_ne!(turned, rendered(&oriented, &["--volume-axes"]));
}

#[test]
fn a_domain_outside_the_data_warns() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The shapes scene holds u8 values 0..=254.
    let o = render(d, &["--domain", "300,400", "-o", "a.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: --domain 300 to 400 lies outside the data's values 0 to 254"),
        "{}",
        stderr(&o)
    );
    let o = render(d, &["--domain", "10,200", "-o", "b.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

/// A float scan with NaN or infinite values among finite ones renders (the
/// non-finite values stored as the window's ends), and `render` and `slice`
/// say how many there were, once, as `volgen convert` does; `-q` silences it.
#[test]
fn non_finite_values_of_a_scan_are_counted_and_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut nrrd =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\n\n"
            .to_vec();
    nrrd.extend((0..64).flat_map(|i| {
        let v = if i % 16 == 3 { f32::NAN } else { i as f32 };
        v.to_le_bytes()
    }));
    std::fs::write(d.join("f.nrrd"), nrrd).unwrap();
    let said = "warning: f.nrrd: 4 of its 64 values are NaN or infinite: NaN is stored as the window's low end, ±infinity as its ends";
    let o = raycaster(&["render", "f.nrrd", "--size", "24", "-o", "a.png"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches(said).count(), 1, "{}", stderr(&o));
    let o = raycaster(
        &[
            "slice", "f.nrrd", "--axis", "z", "--index", "1", "-o", "s.png",
        ],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches(said).count(), 1, "{}", stderr(&o));
    let o = raycaster(
        &["render", "f.nrrd", "--size", "24", "-q", "-o", "b.png"],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("NaN"), "{}", stderr(&o));
}

#[test]
fn reading_a_compressed_scan_shows_progress() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut nrrd =
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 64 64 64\nencoding: gzip\n\n".to_vec();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(
        &(0..64 * 64 * 64)
            .map(|i| (i % 251) as u8)
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    nrrd.extend(gz.finish().unwrap());
    std::fs::write(d.join("s.nrrd"), nrrd).unwrap();
    let o = raycaster(
        &[
            "render",
            "s.nrrd",
            "--size",
            "24",
            "--progress",
            "-q",
            "-o",
            "a.png",
        ],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("reading s.nrrd"), "{e}");
    assert!(e.contains("rendering"), "{e}");
}

/// `raycaster compare --diff` never replaces one of the images compared nor,
/// without `--force`, an existing file; a named pipe given as an image is
/// refused at once (it once blocked the reader); outputs never replace a
/// device (`--force -o /dev/null` once turned it into a regular file).
#[test]
fn compare_keeps_its_inputs_and_outputs_refuse_pipes_and_devices() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let render = |more: &[&str]| {
        let tiny = [
            "render",
            "--scene",
            "shapes",
            "--scene-size",
            "16",
            "--size",
            "16",
        ];
        raycaster(&[&tiny[..], more].concat(), d)
    };
    for name in ["a.png", "b.png"] {
        let o = render(&["-o", name]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // Identical images: a PSNR of null in JSON (it was the string "inf").
    let o = raycaster(&["compare", "a.png", "b.png", "--json"], d);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json["psnr_db"].is_null(), "{json}");
    assert_eq!(json["max_difference"], 0, "{json}");
    let b = std::fs::read(d.join("b.png")).unwrap();
    let o = raycaster(
        &["compare", "a.png", "b.png", "--diff", "b.png", "--force"],
        d,
    );
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("is one of the images compared"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(d.join("b.png")).unwrap(), b);
    let o = raycaster(&["compare", "a.png", "b.png", "--diff", "d.png"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    // The difference image is said (it was written without a word).
    assert!(
        stderr(&o).contains("wrote d.png (the differences ×8, 16×16)"),
        "{}",
        stderr(&o)
    );
    // An unreadable second argument is named the reference (it was "the image").
    std::fs::write(d.join("text.png"), "not a picture").unwrap();
    let o = raycaster(&["compare", "a.png", "text.png"], d);
    assert!(
        stderr(&o).contains("cannot read the reference: text.png"),
        "{}",
        stderr(&o)
    );
    let o = raycaster(&["compare", "a.png", "b.png", "--diff", "d.png"], d);
    assert!(
        stderr(&o).contains("d.png: already exists (pass --force"),
        "{}",
        stderr(&o)
    );
    let fifo = d.join("pipe.png");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let started = Instant::now();
    let o = raycaster(&["compare", "a.png", "pipe.png"], d);
    assert!(started.elapsed() < Duration::from_secs(20));
    assert!(stderr(&o).contains("named pipe"), "{}", stderr(&o));
    let o = render(&["-o", "pipe.png", "--force"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("named pipe"), "{}", stderr(&o));
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    // A PNG whose header claims 100000² pixels: an error, not an abort for
    // lack of memory (the decoder would allocate 30 GB).
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        let mut crc = crc32(kind);
        crc = crc32_more(crc, data);
        c.extend_from_slice(&crc.to_be_bytes());
        c
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    // 1000 zero bytes as a zlib stream of one stored block (adler32 1, 1000).
    let mut idat = vec![0x78, 0x01, 0x01, 0xE8, 0x03, 0x17, 0xFC];
    idat.extend_from_slice(&[0; 1000]);
    idat.extend_from_slice(&0x03E8_0001u32.to_be_bytes());
    png.extend(chunk(b"IDAT", &idat));
    png.extend(chunk(b"IEND", &[]));
    std::fs::write(d.join("huge.png"), png).unwrap();
    let o = raycaster(&["compare", "huge.png", "a.png"], d);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(
            "huge.png: the image is 100000×100000 pixels, more than the 16384×16384 read"
        ),
        "{}",
        stderr(&o)
    );
}

/// CRC-32 (PNG's) of `bytes`.
fn crc32(bytes: &[u8]) -> u32 {
    crc32_more(0, bytes)
}

/// CRC-32 of what `crc` covered followed by `bytes`.
fn crc32_more(crc: u32, bytes: &[u8]) -> u32 {
    let mut c = !crc;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn render_and_slice_never_write_the_image_over_their_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A volume named like an image (volgen warns of the name, and writes it).
    write_vol(&d.join("v.png"), [8; 3], [1.0; 3], Content::Scalar);
    let volume = std::fs::read(d.join("v.png")).unwrap();
    for args in [
        &["render", "v.png", "-o", "v.png", "--force", "--size", "16"][..],
        &[
            "slice", "v.png", "--axis", "z", "--index", "0", "-o", "v.png", "--force",
        ],
        &["render", "v.png", "-o", "./v.png", "--size", "16"],
    ] {
        let o = raycaster(args, d);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        // (The input named where the image's name differs from it.)
        let said = if args.contains(&"./v.png") {
            "./v.png: is an input of this command (v.png); name another file"
        } else {
            "v.png: is an input of this command; name another file"
        };
        assert!(stderr(&o).contains(said), "{args:?}: {}", stderr(&o));
        assert!(
            std::fs::read(d.join("v.png")).unwrap() == volume,
            "{args:?}"
        );
    }
    // A header's detached data file, and a transfer-function file, are
    // inputs too (before: replaced by the image with --force).
    let samples: Vec<u8> = (0..64).collect();
    std::fs::write(d.join("data.png"), &samples).unwrap();
    std::fs::write(
        d.join("p.nhdr"),
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: data.png\n",
    )
    .unwrap();
    std::fs::write(d.join("tf.png"), "point 0 0 0 0 0\npoint 1 1 1 1 1\n").unwrap();
    for (args, input) in [
        (
            &[
                "render", "p.nhdr", "-o", "data.png", "--force", "--size", "16",
            ][..],
            "data.png",
        ),
        (
            &[
                "slice", "p.nhdr", "--axis", "z", "--index", "0", "-o", "data.png", "--force",
            ],
            "data.png",
        ),
        (
            &[
                "render", "--tf", "tf.png", "-o", "tf.png", "--force", "--size", "16",
            ],
            "tf.png",
        ),
    ] {
        let before = std::fs::read(d.join(input)).unwrap();
        let o = raycaster(args, d);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("{input}: is an input of this command")),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(std::fs::read(d.join(input)).unwrap() == before, "{args:?}");
    }
    let o = raycaster(&["render", "v.png", "-o", ".png", "--size", "16"], d);
    assert!(
        stderr(&o).contains(".png: the image needs a name before .png"),
        "{}",
        stderr(&o)
    );
    // A folder as the output is said as one, whatever its name.
    std::fs::create_dir(d.join("out")).unwrap();
    let o = raycaster(&["render", "v.png", "-o", "out", "--size", "16"], d);
    assert!(
        stderr(&o).starts_with("error: out: is a directory; name a file"),
        "{}",
        stderr(&o)
    );
}

/// Bench's outputs: the CSV and the plot under one name, or an output that is
/// the generated volume it reads, are refused before the sweep (the plot
/// replaced the CSV; the CSV replaced the cached volume); a table piped to a
/// reader that closes early still gets its CSV written (the process ended at
/// the first row past the pipe).
#[test]
fn bench_outputs_never_replace_each_other_or_its_volume() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let quick = [
        "bench",
        "--quick",
        "--volume-size",
        "16",
        "--cache-dir",
        "c",
    ];
    let o = raycaster(
        &[&quick[..], &["--csv", "o.png", "--plot", "./o.png"]].concat(),
        d,
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--csv and --plot both name ./o.png: the plot would replace the CSV"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("o.png").exists());
    // The cache's volume as the CSV (its name is what bench generates).
    let o = raycaster(&quick, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let cached: Vec<_> = std::fs::read_dir(d.join("c"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(cached.len(), 1, "{cached:?}");
    let before = std::fs::read(&cached[0]).unwrap();
    let name = cached[0].to_str().unwrap();
    let o = raycaster(&[&quick[..], &["--csv", name, "--force"]].concat(), d);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is the volume this benchmark reads; name another file"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&cached[0]).unwrap(), before);
    // A reader that closes at once: the sweep goes on and writes its CSV.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args([&quick[..], &["--csv", "t.csv"]].concat())
        .current_dir(d)
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{:?}: {}", o.status, stderr(&o));
    assert!(stderr(&o).contains("wrote t.csv"), "{}", stderr(&o));
    assert!(
        std::fs::read_to_string(d.join("t.csv"))
            .unwrap()
            .lines()
            .count()
            > 1
    );
}

/// A PNG past the file-size limit (`ulimit -f`) fails with its error and
/// leaves no partial file (SIGXFSZ killed the process and left it behind).
#[test]
fn the_file_size_limit_fails_the_write_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = under_limit(
        dir.path(),
        "-f 20",
        "render --scene noise --scene-size 32 --size 1024 -o big.png",
    );
    let said = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(said.contains("File too large"), "{said}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
