//! The `raycaster render` command driven as a user would: real binary, real files.

mod support;

use support::{raycaster, stderr, write_scene};

use std::path::Path;
use std::process::Command;

use raycaster::render::RgbImage;

#[test]
fn renders_the_built_in_scene_without_arguments_but_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = raycaster(
        &["render", "--size", "64x48", "--scene-size", "48"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = RgbImage::load_png(&dir.path().join("render.png")).unwrap();
    assert_eq!((image.width(), image.height()), (64, 48));
    let lit = image.data().chunks(3).filter(|p| p != &[0, 0, 0]).count();
    assert!(lit > 200, "the scene must be visible ({lit} lit pixels)");
    assert!(stderr(&out).contains("wrote render.png"));
}

/// The exit statuses `--help` documents: 2 for a command line that is wrong,
/// 1 for a failure past it.
#[test]
fn exit_statuses_are_the_documented_ones() {
    let dir = tempfile::tempdir().unwrap();
    let help = raycaster(&["--help"], dir.path());
    assert!(help.status.success());
    assert!(
        String::from_utf8_lossy(&help.stdout)
            .contains("Exit status: 0 done, 1 failed (the error says why, in one line), 2 the command line is wrong"),
        "{}",
        String::from_utf8_lossy(&help.stdout)
    );
    for (args, code) in [
        (&["render", "--no-such-flag"][..], 2),
        (&["render", "--size", "0"][..], 2),
        (&["render", "missing.vol", "-o", "a.png"][..], 1),
    ] {
        let o = raycaster(args, dir.path());
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn flags_without_effect_get_a_warning_and_the_frame_renders() {
    let dir = tempfile::tempdir().unwrap();
    let base = [
        "render",
        "--size",
        "32",
        "--scene-size",
        "40",
        "-o",
        "w.png",
        "--force",
    ];
    for (extra, warning) in [
        (
            &["--level", "7"][..],
            "warning: --level 7: the volume's coarsest level is 0; rendering level 0",
        ),
        (
            &["--mode", "mip", "--preintegrate"][..],
            "warning: --preintegrate applies to --mode dvr only; mip frames ignore it",
        ),
        (
            &["--step", "1e30"][..],
            "warning: --step: a step of 1e30 is longer than the volume's diagonal (69 of its smallest spacing): each ray takes one sample at most",
        ),
    ] {
        let out = raycaster(&[&base[..], extra].concat(), dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let e = stderr(&out);
        assert_eq!(e.matches(warning).count(), 1, "{extra:?}: {e}");
        // -q silences warnings with the rest.
        let quiet = raycaster(&[&base[..], extra, &["-q"]].concat(), dir.path());
        assert!(
            quiet.status.success() && stderr(&quiet).is_empty(),
            "{}",
            stderr(&quiet)
        );
    }
    // A DVR frame with pre-integration warns of nothing.
    let out = raycaster(&[&base[..], &["--preintegrate"]].concat(), dir.path());
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
}

#[test]
fn an_xray_frame_is_not_saturated_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let base = [
        "render",
        "--mode",
        "xray",
        "--size",
        "64",
        "--scene-size",
        "96",
        "-q",
    ];
    let render = |extra: &[&str], name: &str| {
        let out = raycaster(&[&base[..], extra, &["-o", name]].concat(), dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        RgbImage::load_png(&dir.path().join(name)).unwrap()
    };
    // The brightest channel of each lit pixel.
    let levels = |image: &RgbImage| -> Vec<u8> {
        let mut v: Vec<u8> = image
            .data()
            .chunks(3)
            .map(|p| *p.iter().max().unwrap())
            .filter(|&m| m > 0)
            .collect();
        v.sort_unstable();
        v
    };
    let auto = levels(&render(&[], "auto.png"));
    let one = levels(&render(&["--xray-gain", "1"], "one.png"));
    // With a gain of 1 most lit pixels show the one saturated colour; by
    // default the densest reach it and the rest shade below.
    let median = |v: &[u8]| v[v.len() / 2];
    assert!(auto.len() > 500 && one.len() > 500);
    assert_eq!(median(&one), *one.last().unwrap(), "gain 1 saturates");
    assert!(
        u32::from(median(&auto)) * 3 < u32::from(*auto.last().unwrap()) * 2,
        "default: median {} against brightest {}",
        median(&auto),
        auto.last().unwrap()
    );
}

#[test]
fn bytes_after_a_files_last_block_get_one_warning_and_the_frame_renders() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tail.vol");
    write_scene(
        &path,
        raycaster::synth::SceneKind::Shapes,
        40,
        1,
        raycaster::volume::Format::Extended,
    );
    let len = std::fs::metadata(&path).unwrap().len();
    let args = [
        "render", "tail.vol", "-o", "t.png", "--size", "32", "--force",
    ];
    let out = raycaster(&args, dir.path());
    assert!(
        out.status.success() && !stderr(&out).contains("warning"),
        "{}",
        stderr(&out)
    );
    let whole = std::fs::read(dir.path().join("t.png")).unwrap();
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap();
    std::io::Write::write_all(&mut f, b"garbage").unwrap();
    drop(f);
    let out = raycaster(&args, dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    let warning = format!(
        "warning: tail.vol: the file has 7 bytes after its last block (from byte {len}) that are not part of the volume; they are ignored"
    );
    assert_eq!(
        stderr(&out).matches(&warning).count(),
        1,
        "{}",
        stderr(&out)
    );
    assert!(std::fs::read(dir.path().join("t.png")).unwrap() == whole);
    let quiet = raycaster(&[&args[..], &["-q"]].concat(), dir.path());
    assert!(stderr(&quiet).is_empty(), "{}", stderr(&quiet));
}

#[test]
fn renders_a_file_and_reports_stats_as_json() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(
        &dir.path().join("shells.vol"),
        raycaster::synth::SceneKind::Shells,
        40,
        1,
        raycaster::volume::Format::Thesis,
    );
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "shells.vol",
            "-o",
            "s.png",
            "--size",
            "48",
            "--tf",
            "shells",
            "--stats-json",
            "-q",
            "--force",
        ];
        args.extend_from_slice(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        let json = serde_json::from_str::<serde_json::Value>(&text).expect("one JSON object");
        (json, text)
    };
    let (both, text) = run(&[]);
    // As written (it read 0.9900000095367432, the f32's exact value).
    assert!(text.contains("\"ert_threshold\":0.99,"), "{text}");
    let (none, _) = run(&["--no-ert", "--no-ess"]);
    assert_eq!(both["rays"], none["rays"]);
    let samples = |v: &serde_json::Value| v["samples"].as_u64().unwrap();
    assert!(samples(&both) < samples(&none), "{both} vs {none}");
    assert!(none["samples_skipped_empty"].as_u64() == Some(0));
    assert_eq!(both["ert"], serde_json::json!(true));
    assert_eq!(both["ert_threshold"], serde_json::json!(0.99));
    assert_eq!(none["ert"], serde_json::json!(false));
    assert_eq!(none["ert_threshold"], serde_json::Value::Null);
    assert_eq!(none["ess"], serde_json::json!(false));
    // How many samples a SIMD kernel marched: none on the scalar kernel and
    // in the sequential renderer under `auto`; every one of this DVR frame
    // where the automatic level has a kernel (AVX2).
    let lanes = |v: &serde_json::Value| v["samples_in_lanes"].as_u64().unwrap();
    assert_eq!(lanes(&run(&["--simd", "scalar"]).0), 0);
    assert_eq!(lanes(&run(&["--sequential"]).0), 0);
    let automatic = raycaster::render::SimdLevel::automatic();
    let expected = if automatic == raycaster::render::SimdLevel::Scalar {
        0
    } else {
        samples(&both)
    };
    assert_eq!(lanes(&both), expected, "{both}");
    // Human-readable counters on stderr.
    let out = raycaster(
        &[
            "render",
            "shells.vol",
            "-o",
            "t.png",
            "--size",
            "32",
            "--stats",
            "--mode",
            "mip",
            "--orthographic",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    for needle in [
        "rays cast",
        "samples taken",
        "% in SIMD lanes",
        "terminated early",
        "skipped (empty)",
    ] {
        assert!(
            stderr(&out).contains(needle),
            "{needle} missing in {}",
            stderr(&out)
        );
    }
}

#[test]
fn a_transfer_function_file_is_read() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("red.tf"),
        "# everything above 0.1 red and opaque\npoint 0 1 0 0 0\npoint 0.1 1 0 0 1\npoint 1 1 0 0 1\n",
    )
    .unwrap();
    let out = raycaster(
        &[
            "render",
            "--tf",
            "red.tf",
            "--size",
            "32",
            "--scene-size",
            "32",
            "--no-shading",
            "-o",
            "red.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = RgbImage::load_png(&dir.path().join("red.png")).unwrap();
    let red = image
        .data()
        .chunks(3)
        .filter(|p| p[0] > 200 && p[1] == 0 && p[2] == 0)
        .count();
    assert!(red > 50, "{red} red pixels");
}

#[test]
fn bad_inputs_fail_with_a_clear_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.tf"),
        "point 0 0 0 0 0\npoint 2 1 1 1 1\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("short.vol"), [1u8, 2, 3]).unwrap();
    let cases: [(&[&str], &str); 10] = [
        (&["render", "missing.vol"], "missing.vol"),
        (&["render", "short.vol"], "short.vol"),
        (&["render", "--size", "0x10"], "image size"),
        (
            &["render", "--tf", "nope"],
            "unknown transfer function preset \"nope\"",
        ),
        (&["render", "--tf", "bad.tf"], "line 2"),
        (&["render", "--step", "0"], "positive"),
        (&["render", "--ert-threshold", "1.5"], "(0, 1]"),
        (&["render", "--iso", "101%"], "--iso"),
        (
            &["render", "--mode", "first-hit", "--iso", "300"],
            "outside the transfer function's domain",
        ),
        (&["render", "--fov", "190"], "--fov"),
    ];
    // An impossible field of view is a wrong command line (exit 2), as any
    // value a flag does not take.
    for fov in ["0", "nan", "180"] {
        let out = raycaster(&["render", "--fov", fov], dir.path());
        assert_eq!(out.status.code(), Some(2), "--fov {fov}: {}", stderr(&out));
    }
    // --lod-bias with a fixed level: refused as a session refuses it (it was
    // ignored), said once; with the automatic level it is taken.
    let out = raycaster(
        &["render", "--level", "2", "--lod-bias", "1", "-o", "lod.png"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert_eq!(
        stderr(&out)
            .matches(
                "--lod-bias shifts the automatic level only; it takes --level auto, not --level 2"
            )
            .count(),
        1,
        "{}",
        stderr(&out)
    );
    assert!(!dir.path().join("lod.png").exists());
    let out = raycaster(
        &[
            "render",
            "--lod-bias",
            "1",
            "--size",
            "32x32",
            "-o",
            "lod.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    for (args, needle) in cases {
        let out = raycaster(args, dir.path());
        assert!(!out.status.success(), "{args:?} must fail");
        assert!(
            stderr(&out).contains(needle),
            "{args:?}: {needle:?} not in {}",
            stderr(&out)
        );
        assert!(
            !dir.path().join("render.png").exists(),
            "{args:?} left an image"
        );
    }
    let out = raycaster(
        &["render", "--size", "8", "-o", "no/such/dir/x.png"],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(stderr(&out).contains("no/such/dir"), "{}", stderr(&out));
}

#[test]
fn bench_quick_writes_a_table_csv_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let out = raycaster(
        &[
            "bench",
            "--quick",
            "--volume-size",
            "32",
            "--threads",
            "1,2",
            "--tiles",
            "8",
            "--bricks",
            "8,16",
            "--optimisations",
            "none,both",
            "--sequential",
            "--cache-dir",
            "vols",
            "--csv",
            "b.csv",
            "--plot",
            "b.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let csv = std::fs::read_to_string(dir.path().join("b.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert!(rows[0].starts_with("renderer,threads,tile,brick"));
    // 2 bricks × 2 optimisation sets × (1 sequential + 2 thread counts × 1 tile).
    assert_eq!(rows.len(), 1 + 2 * 2 * 3, "{csv}");
    // The same configuration takes the same samples whatever the threads.
    let samples = |r: &str| r.split(',').nth(6).unwrap().parse::<u64>().unwrap();
    assert_eq!(samples(rows[1]), samples(rows[2]));
    assert_eq!(samples(rows[2]), samples(rows[3]));
    // The plot is a valid PNG with something drawn on it.
    let plot = RgbImage::load_png(&dir.path().join("b.png")).unwrap();
    assert!(plot.width() >= 800 && plot.height() >= 500);
    let drawn = plot
        .data()
        .chunks(3)
        .filter(|p| p != &[255, 255, 255])
        .count();
    assert!(drawn > 10_000, "{drawn} drawn pixels");
    // The CSV names the volume, image and step of every row.
    assert!(
        rows[1].contains(",shapes-32-u8-linear-mapped,128x128,0.5,default,"),
        "{}",
        rows[1]
    );
    assert!(
        dir.path().join("vols/shapes-32-u8-linear.vol").exists(),
        "the volume is cached"
    );
    assert!(stderr(&out).contains("speedup 2 threads over 1"));
    let bad = raycaster(&["bench", "--quick", "--optimisations", "fast"], dir.path());
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("unknown optimisation set"));
}

/// What bench cannot measure is refused, said once: the generated volume's
/// flags beside a FILE (they were ignored), a label volume (measured with no
/// sample taken) and a folder (called a DICOM volume when empty).
#[test]
fn bench_refuses_what_it_cannot_measure() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    support::write_labels(&d.join("l.vol"), 8);
    std::fs::create_dir(d.join("empty")).unwrap();
    for (args, code, said) in [
        (
            &["l.vol", "--volume-size", "64"][..],
            2,
            "cannot be used with",
        ),
        (
            &["l.vol", "--layout", "bricked"][..],
            2,
            "cannot be used with",
        ),
        (&["l.vol"][..], 1, "l.vol: is a label volume"),
        (
            &["empty"][..],
            1,
            "empty: is a folder, and this command reads .vol files",
        ),
        // Frame counts whose times would not fit in memory (an abort before).
        (
            &["--frames", "4000000000"][..],
            2,
            "4000000000 is not in 1..=10000",
        ),
        (&["--warm-up", "10001"][..], 2, "10001 is not in 0..=10000"),
    ] {
        let mut all = vec!["bench", "--quick", "--cache-dir", "c"];
        all.extend(args);
        let out = raycaster(&all, d);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(said), "{args:?}: {err}");
        assert_eq!(err.matches("error").count(), 1, "{args:?}: {err}");
    }
}

/// Without a home, volumes are cached in a folder of the user's own in the
/// temporary folder; one another user made there is refused (its files were
/// measured under the scene's name).
#[test]
fn bench_refuses_a_shared_cache_folder_of_another_user() {
    use std::os::unix::fs::MetadataExt;
    let dir = tempfile::tempdir().unwrap();
    let uid = std::fs::metadata("/proc/self").unwrap().uid();
    let planted = dir.path().join(format!("raycaster-{uid}"));
    std::fs::create_dir_all(planted.join("bench-volumes")).unwrap();
    let other = if uid == 65534 { 65533 } else { 65534 };
    // (Only root can give a folder away: elsewhere there is nothing to test.)
    if std::os::unix::fs::chown(&planted, Some(other), None).is_err() {
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args(["bench", "--quick", "--threads", "1", "--tiles", "16"])
        .env_remove("HOME")
        .env_remove("XDG_CACHE_HOME")
        .env("TMPDIR", dir.path())
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!(
            "raycaster-{uid}: belongs to another user (uid {other})"
        )),
        "{err}"
    );
}

/// The memory kinds of the generated volume (u16, bricked, in RAM) are separate
/// cached files; an SVG plot is written when the name ends in `.svg`.
#[test]
fn bench_generates_the_volume_kind_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = raycaster(
        &[
            "bench",
            "--quick",
            "--volume-size",
            "24",
            "--sample-type",
            "u16",
            "--layout",
            "bricked:9",
            "--ram",
            "--threads",
            "2",
            "--tiles",
            "16",
            "--bricks",
            "5,9",
            "--cache-dir",
            "vols",
            "--csv",
            "b.csv",
            "--plot",
            "b.svg",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(dir.path().join("vols/shapes-24-u16-b9.vol").exists());
    let csv = std::fs::read_to_string(dir.path().join("b.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    assert!(csv.contains("shapes-24-u16-b9-ram"), "{csv}");
    let svg = std::fs::read_to_string(dir.path().join("b.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("brick side"));
    // A brick that does not divide the stored bricks is an error naming it.
    let bad = raycaster(
        &[
            "bench",
            "--quick",
            "--volume-size",
            "24",
            "--layout",
            "bricked:9",
            "--bricks",
            "4",
            "--cache-dir",
            "vols",
        ],
        dir.path(),
    );
    assert!(!bad.status.success());
    // Without --bricks a bricked volume is swept by sides that tile its
    // bricks: none of 8, 16, 32 tiles side 9, so its own.
    let default = raycaster(
        &[
            "bench",
            "--quick",
            "--volume-size",
            "24",
            "--layout",
            "bricked:9",
            "--threads",
            "1",
            "--tiles",
            "16",
            "--cache-dir",
            "vols",
        ],
        dir.path(),
    );
    assert!(default.status.success(), "{}", stderr(&default));
    assert!(
        stderr(&default).contains("fastest: 1 thread, tile 16, brick 9"),
        "{}",
        stderr(&default)
    );
    // Bricks of side 9 (step 8) are cut by sides whose step divides 8.
    assert!(
        stderr(&bad).contains(
            "brick side 4 does not tile the file's bricks of side 9: bricks share a voxel with their neighbours, so a sub-brick of side s advances s−1 voxels, and s−1 must divide 8; sides that tile them are 2, 3, 5, 9"
        ),
        "{}",
        stderr(&bad)
    );
}

/// Every ready-made scene in `volumes/scenes/` renders on the built-in volume its
/// name starts with, and shows something other than that volume's plain image.
#[test]
fn every_ready_made_segment_scene_renders_on_its_built_in_volume() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes");
    let mut rendered = 0;
    for entry in std::fs::read_dir(&scenes).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let volume = stem.split('-').next().unwrap().to_owned();
        let common = ["--scene", &volume, "--scene-size", "40", "--size", "40"];
        let plain = raycaster(
            &[&["render", "-o", "plain.png", "-q", "--force"][..], &common].concat(),
            dir.path(),
        );
        assert!(plain.status.success(), "{}", stderr(&plain));
        let out = raycaster(
            &[
                &["render", "-o", "two.png", "-q", "--force", "--segments"][..],
                &[path.to_str().unwrap()],
                &common,
            ]
            .concat(),
            dir.path(),
        );
        assert!(out.status.success(), "{stem}: {}", stderr(&out));
        let two = RgbImage::load_png(&dir.path().join("two.png")).unwrap();
        let lit = two.data().chunks(3).filter(|p| p != &[0, 0, 0]).count();
        assert!(lit > 50, "{stem}: only {lit} lit pixels");
        if stem != "shapes-layers10" {
            let plain = RgbImage::load_png(&dir.path().join("plain.png")).unwrap();
            assert_ne!(plain.data(), two.data(), "{stem} looks like plain DVR");
        }
        rendered += 1;
    }
    assert!(rendered >= 12, "only {rendered} scenes found");
}

#[test]
fn bad_segment_scenes_fail_with_a_clear_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
    write(
        "typo.toml",
        "layers = [[0.0, 1.0]]\n[[object]]\nmdoe = \"mip\"\n",
    );
    write(
        "mode.toml",
        "layers = [[0.0, 1.0]]\n[[object]]\nmode = \"glow\"\n",
    );
    write("both.toml", "layers = [[0.0, 1.0]]\nlabels = \"x.vol\"\n");
    // Ids a layer scene can never show: 0 (the values in no layer) and one
    // past its layers (a second object without an id takes 2).
    write("zero.toml", "layers = [[0.1, 0.5]]\n[[object]]\nid = 0\n");
    write(
        "second.toml",
        "layers = [[0.1, 0.5]]\n[[object]]\n[[object]]\nname = \"rim\"\n",
    );
    write(
        "labels.toml",
        "labels = \"missing.labels.vol\"\n[[object]]\n",
    );
    write_scene(
        &dir.path().join("data.vol"),
        raycaster::synth::SceneKind::Shapes,
        24,
        1,
        raycaster::volume::Format::Extended,
    );
    let cases: [(&[&str], &str); 11] = [
        (
            &["--segments", "zero.toml"],
            "object \"object 0\": id 0 names no layer: the scene has 1 layer (id 1; layer i is object i + 1)",
        ),
        (
            &["--segments", "second.toml"],
            "object \"rim\": id 2 names no layer",
        ),
        // A scene given as the volume: the flag that takes it is named.
        (
            &["labels.toml"],
            "labels.toml: is a TOML file, not a volume: --session FILE renders a saved session, --segments FILE a two-level scene",
        ),
        // (One that does not exist is said not to.)
        (&["missing.toml"], "missing.toml: No such file"),
        (&["--segments", "typo.toml"], "mdoe"),
        (&["--segments", "mode.toml"], "glow"),
        (&["--segments", "both.toml"], "either"),
        (&["--segments", "nowhere.toml"], "nowhere.toml"),
        (
            &["--segments", "labels.toml", "--scene", "noise"],
            "no label volume",
        ),
        (&["--labels", "x.vol"], "--segments"),
        // A file's scene names its label volume: said to be the scene's.
        (
            &["data.vol", "--segments", "labels.toml"],
            "the scene's label volume (its `labels =`, read beside the scene file; --labels FILE names another)",
        ),
    ];
    for (extra, needle) in cases {
        // (The built-in scene's size only where no file is named.)
        let scene: &[&str] = if extra[0].starts_with("--") {
            &["--scene-size", "32"]
        } else {
            &[]
        };
        let args = [
            &["render", "-o", "out.png", "--size", "32"][..],
            scene,
            extra,
        ]
        .concat();
        let out = raycaster(&args, dir.path());
        assert!(!out.status.success(), "{extra:?} must fail");
        let err = stderr(&out);
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            !dir.path().join("out.png").exists(),
            "{extra:?} left an image"
        );
    }
}

/// A scene that shows nothing, or an object whose id the labels never hold,
/// is rendered with a warning naming it (it rendered black without a word).
#[test]
fn scenes_showing_nothing_are_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
    write("empty.toml", "labels = \"unused.labels.vol\"\n");
    write(
        "hidden.toml",
        "layers = [[0.0, 1.0]]\n[[object]]\nvisible = false\n",
    );
    write(
        "nine.toml",
        "labels = \"unused.labels.vol\"\n[[object]]\nid = 9\nname = \"ghost\"\n[[object]]\nid = 2\n",
    );
    // The built-in shells bring their labels (ids 0 to 4).
    let cases = [
        (
            "empty.toml",
            "warning: the scene has no [[object]]: nothing shows",
        ),
        (
            "hidden.toml",
            "warning: the scene has no visible [[object]]: nothing shows",
        ),
        (
            "nine.toml",
            "warning: object \"ghost\" (id 9) shows nothing: the ids of ",
        ),
    ];
    let render = |scene: &str| {
        let args = [
            "render",
            "--scene",
            "shells",
            "--scene-size",
            "32",
            "--size",
            "32",
        ];
        let more = ["--segments", scene, "-o", "out.png", "--force"];
        raycaster(&[&args[..], &more].concat(), dir.path())
    };
    for (scene, needle) in cases {
        let out = render(scene);
        assert!(out.status.success(), "{scene}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.matches(needle).count(), 1, "{scene}: {err}");
        assert_eq!(err.matches("warning").count(), 1, "{scene}: {err}");
    }
    // A scene whose objects all show: no warning.
    write(
        "fine.toml",
        "labels = \"unused.labels.vol\"\n[[object]]\nid = 4\n",
    );
    let out = render("fine.toml");
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
}

/// A flag the frame would not use is refused (exit 2, said once), where it
/// was ignored without a word: a mode's parameter with another mode, what a
/// two-level scene's file sets, the built-in scene's flags with a file.
#[test]
fn flags_the_frame_would_not_use_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes/gradient-bands.toml");
    let scene = scene.to_str().unwrap();
    write_scene(
        &dir.path().join("data.vol"),
        raycaster::synth::SceneKind::Shapes,
        24,
        1,
        raycaster::volume::Format::Extended,
    );
    let refused: [(&[&str], &str); 7] = [
        (
            &["--iso", "10%"],
            "--iso is a parameter of --mode first-hit; a dvr frame does not use it",
        ),
        (
            &["--mode", "mip", "--xray-gain", "3"],
            "--xray-gain is a parameter of --mode xray; a mip frame does not use it",
        ),
        (
            &["--sabella-depth", "centroid", "--mode", "average"],
            "--sabella-depth is a parameter of --mode sabella",
        ),
        (
            &["--segments", scene, "--mode", "mip"],
            "--mode is not used with --segments: the scene file sets its global and local modes",
        ),
        (
            &["--segments", scene, "--tf", "rainbow"],
            "--tf is not used with --segments",
        ),
        (
            &["--segments", scene, "--mode", "first-hit", "--iso", "10%"],
            "--mode is not used with --segments",
        ),
        (&["data.vol", "--seed", "3"], "cannot be used with"),
    ];
    for (extra, said) in refused {
        let args = [&["render", "-o", "out.png", "--size", "16"][..], extra].concat();
        let out = raycaster(&args, dir.path());
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        let err = stderr(&out);
        assert!(err.contains(said), "{extra:?}: {err}");
        assert_eq!(err.matches("error:").count(), 1, "{err}");
        assert!(!dir.path().join("out.png").exists());
    }
    // Each with its own mode, and the defaults, are taken.
    for extra in [
        &["--mode", "first-hit", "--iso", "10%"][..],
        &["--mode", "xray", "--xray-gain", "3"],
        &["--mode", "sabella", "--sabella-depth", "centroid"],
        &["--segments", scene],
        &["data.vol", "--mode", "mip"],
    ] {
        let args = [
            &[
                "render", "-o", "out.png", "--size", "16", "--force", "--quiet",
            ][..],
            extra,
        ]
        .concat();
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
    }
}

/// An average frame of a mostly empty volume is dark (its rays' means lie
/// low in the domain): render says so once and names a domain spanning the
/// means, which brightens it; with a domain given, nothing is said.
#[test]
fn a_dark_average_frame_names_the_domain_that_shows_it() {
    let dir = tempfile::tempdir().unwrap();
    let render = |extra: &[&str]| {
        let args = [
            &[
                "render", "--mode", "average", "--size", "64", "-o", "a.png", "--force",
            ][..],
            extra,
        ]
        .concat();
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let image = RgbImage::load_png(&dir.path().join("a.png")).unwrap();
        let brightest = image.data().iter().copied().max().unwrap();
        (stderr(&out), brightest)
    };
    let (said, dark) = render(&[]);
    assert_eq!(said.matches("warning:").count(), 1, "{said}");
    let suggested = said
        .split("--domain ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .unwrap_or_else(|| panic!("{said}"))
        .to_string();
    assert!(
        said.contains("--mode average: the picture is dark"),
        "{said}"
    );
    let (said, bright) = render(&["--domain", &suggested]);
    assert!(!said.contains("warning"), "{suggested}: {said}");
    assert!(bright > dark.saturating_mul(2), "{dark} → {bright}");
    let (said, _) = render(&["--quiet"]);
    assert!(said.is_empty(), "{said}");
}

#[test]
fn renders_a_nifti_file_directly() {
    let dir = tempfile::tempdir().unwrap();
    let nii = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/fixtures/i16.nii.gz");
    let out = raycaster(
        &[
            "render",
            nii.to_str().unwrap(),
            "--size",
            "48",
            "--tf",
            "opaque",
            "-o",
            "nii.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = RgbImage::load_png(&dir.path().join("nii.png")).unwrap();
    let lit = image.data().chunks(3).filter(|p| p != &[0, 0, 0]).count();
    assert!(lit > 50, "the volume must be visible ({lit} lit pixels)");
    // Not a volume: a clear error naming the file.
    std::fs::write(dir.path().join("junk.nrrd"), b"NRRD0004\ntype: double\n\n").unwrap();
    let out = raycaster(&["render", "junk.nrrd"], dir.path());
    assert!(!out.status.success());
    assert!(stderr(&out).contains("junk.nrrd"), "{}", stderr(&out));
}

#[test]
fn a_deep_perspective_view_samples_each_depth_at_its_own_level() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(
        &dir.path().join("shapes.vol"),
        raycaster::synth::SceneKind::Shapes,
        256,
        7,
        raycaster::volume::Format::Extended,
    );
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "render",
            "shapes.vol",
            "-o",
            out,
            "--size",
            "64",
            "--fov",
            "90",
            "--zoom",
            "2",
            "--stats-json",
            "-q",
        ];
        args.extend_from_slice(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("one JSON object")
    };
    let auto = run("auto.png", &[]);
    assert_eq!(
        (auto["level"].as_u64(), auto["coarsest_level"].as_u64()),
        (Some(0), Some(2))
    );
    let sequential = run("sequential.png", &["--sequential"]);
    assert_eq!(sequential["samples"], auto["samples"]);
    let image = |name: &str| RgbImage::load_png(&dir.path().join(name)).unwrap();
    assert_eq!(image("auto.png"), image("sequential.png"));
    // Full resolution everywhere takes more samples than the bands.
    let full = run("full.png", &["--level", "0"]);
    assert_eq!(full["coarsest_level"].as_u64(), Some(0));
    let samples = |v: &serde_json::Value| v["samples"].as_u64().unwrap();
    assert!(samples(&auto) < samples(&full), "{auto} vs {full}");
    // The human-readable table names the levels and how they are split.
    let out = raycaster(
        &[
            "render",
            "shapes.vol",
            "-o",
            "t.png",
            "--size",
            "64",
            "--fov",
            "90",
            "--zoom",
            "2",
            "--stats",
        ],
        dir.path(),
    );
    assert!(
        stderr(&out).contains("0–2 of 0..=2 (by depth"),
        "{}",
        stderr(&out)
    );
}

/// A volume one voxel thick (a 2D image, a single slice, a line) renders as
/// background: said, with the command that shows it (it wrote a black
/// picture without a word).
#[test]
fn a_flat_volume_is_said_to_render_as_background() {
    let dir = tempfile::tempdir().unwrap();
    let nrrd = |name: &str, sizes: [u32; 3]| {
        let n: u32 = sizes.iter().product();
        let [x, y, z] = sizes;
        let header =
            format!("NRRD0004\ntype: uint8\ndimension: 3\nsizes: {x} {y} {z}\nencoding: raw\n\n");
        let data: Vec<u8> = (0..n).map(|i| (i * 7 % 256) as u8).collect();
        std::fs::write(dir.path().join(name), [header.into_bytes(), data].concat()).unwrap();
    };
    nrrd("slice.nrrd", [24, 16, 1]);
    nrrd("line.nrrd", [1, 1, 40]);
    nrrd("thin.nrrd", [24, 16, 2]);
    let render = |file: &str, mode: &str| {
        let args = ["render", file, "--mode", mode, "-o", "out.png", "--force"];
        let out = raycaster(&[&args[..], &["--size", "32"]].concat(), dir.path());
        assert!(out.status.success(), "{file} {mode}: {}", stderr(&out));
        stderr(&out)
    };
    for (name, needle) in [
        (
            "slice.nrrd",
            "slice.nrrd: 24x16x1 voxels, one voxel thick along z: rays cross it in no depth, and this mode accumulates nothing there (the picture is background); --mode mip, or `raycaster slice`, shows it",
        ),
        (
            "line.nrrd",
            "line.nrrd: 1x1x40 voxels, one voxel thick along x and y",
        ),
    ] {
        for mode in ["dvr", "xray", "importance", "context", "silhouette"] {
            let err = render(name, mode);
            assert_eq!(err.matches(needle).count(), 1, "{name} {mode}: {err}");
        }
    }
    // The maximum and the mean show the plane: no warning, and a picture (the
    // mean of a ray of no depth is its one sample's value: it was 0/0, black);
    // two voxels give depth: none.
    for (name, mode) in [
        ("slice.nrrd", "mip"),
        ("slice.nrrd", "average"),
        ("thin.nrrd", "dvr"),
    ] {
        let err = render(name, mode);
        assert!(!err.contains("thick"), "{name} {mode}: {err}");
        let image = RgbImage::load_png(&dir.path().join("out.png")).unwrap();
        let brightest = image.data().iter().copied().max().unwrap();
        assert!(brightest > 100, "{name} {mode}: brightest {brightest}");
    }
}
