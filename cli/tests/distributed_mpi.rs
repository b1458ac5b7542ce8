//! `mpirun -np N raycaster render --distributed` against the single-process
//! binary: the same image (max channel difference ≤ 2/255; the relay is exact,
//! so 0 is expected) for N = 1, 2, 3, 4, 8, perspective, orthographic and
//! inside cameras, every plain mode and a two-level scene; and a bad input
//! stops every rank with one message. Built only with `--features mpi` (the
//! CI installs Open MPI and runs it).
#![cfg(feature = "mpi")]

mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use raycaster::render::RgbImage;

fn binary() -> &'static str {
    env!("CARGO_BIN_EXE_raycaster")
}

/// Runs `mpirun -np ranks raycaster ARGS`, killed after two minutes (a hang
/// fails the test instead of blocking CI).
fn mpirun(ranks: usize, args: &[&str]) -> Output {
    let ranks = ranks.to_string();
    mpirun_line(&[&["-np", &ranks, binary()][..], args].concat())
}

/// One rank per argument list (`mpirun -np 1 raycaster A : -np 1 raycaster B`).
fn mpirun_ranks(ranks: &[&[&str]]) -> Output {
    let mut line: Vec<&str> = Vec::new();
    for (i, args) in ranks.iter().enumerate() {
        if i > 0 {
            line.push(":");
        }
        line.extend(["-np", "1", binary()]);
        line.extend(args.iter());
    }
    mpirun_line(&line)
}

fn mpirun_line(line: &[&str]) -> Output {
    let mut child = Command::new("mpirun")
        .arg("--oversubscribe")
        .args(line)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("mpirun (Open MPI) is installed");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            panic!("mpirun {line:?} hung");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn single(args: &[&str]) -> Output {
    Command::new(binary()).args(args).output().unwrap()
}

fn max_difference(a: &Path, b: &Path) -> u8 {
    let (a, b) = (
        RgbImage::load_png(a).unwrap(),
        RgbImage::load_png(b).unwrap(),
    );
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    a.data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes")
}

#[test]
fn distributed_images_equal_the_single_process_image() {
    let dir = tempfile::tempdir().unwrap();
    let common = [
        "--scene-size",
        "64",
        "--size",
        "72x64",
        "--step",
        "0.7",
        "--quiet",
        "--force",
    ];
    let layers = scenes_dir().join("shapes-layers10.toml");
    let layers = layers.to_str().unwrap();
    let cameras: [(&str, Vec<&str>); 3] = [
        ("perspective", vec![]),
        (
            "orthographic",
            vec!["--orthographic", "--azimuth", "130", "--elevation", "-35"],
        ),
        (
            "inside",
            vec![
                "--position",
                "30,33,28",
                "--target",
                "60,50,20",
                "--fov",
                "100",
            ],
        ),
    ];
    let mut cases: Vec<(String, Vec<&str>, Vec<usize>)> = Vec::new();
    for (view, flags) in &cameras {
        cases.push((format!("{view} dvr"), flags.clone(), vec![1, 2, 3, 4, 8]));
    }
    for mode in [
        "mip",
        "average",
        "first-hit",
        "xray",
        "importance",
        "context",
        "silhouette",
        "sabella",
    ] {
        cases.push((format!("perspective {mode}"), vec!["--mode", mode], vec![3]));
    }
    cases.push((
        "two-level".into(),
        vec!["--segments", layers],
        vec![1, 2, 3, 4, 8],
    ));
    for (i, (name, flags, rank_counts)) in cases.iter().enumerate() {
        let reference = dir.path().join(format!("single-{i}.png"));
        let out = single(
            &[
                &["render", "-o", reference.to_str().unwrap()],
                &common[..],
                flags,
            ]
            .concat(),
        );
        assert!(out.status.success(), "{name}: {out:?}");
        for &ranks in rank_counts {
            let image = dir.path().join(format!("dist-{i}-{ranks}.png"));
            let out = mpirun(
                ranks,
                &[
                    &["render", "--distributed", "-o", image.to_str().unwrap()],
                    &common[..],
                    flags,
                ]
                .concat(),
            );
            assert!(
                out.status.success(),
                "{name}, {ranks} ranks: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let d = max_difference(&image, &reference);
            assert!(d <= 2, "{name}, {ranks} ranks: differs by {d}/255");
        }
    }
}

/// A dark average frame is warned of once, as one process warns of it (the
/// distributed frame said nothing).
#[test]
fn a_dark_average_frame_is_warned_of_once() {
    let dir = tempfile::tempdir().unwrap();
    let args = |image: &str| -> Vec<String> {
        [
            "render",
            "--mode",
            "average",
            "--scene-size",
            "48",
            "--size",
            "40",
            "-o",
            image,
        ]
        .map(String::from)
        .to_vec()
    };
    let single_png = dir.path().join("single.png");
    let out = single(
        &args(single_png.to_str().unwrap())
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    let said = String::from_utf8_lossy(&out.stderr);
    let warning = said
        .lines()
        .find(|l| l.starts_with("warning: --mode average: the picture is dark"))
        .unwrap_or_else(|| panic!("{said}"))
        .to_string();
    let image = dir.path().join("dist.png");
    let mut line = args(image.to_str().unwrap());
    line.insert(1, "--distributed".into());
    let out = mpirun(3, &line.iter().map(String::as_str).collect::<Vec<_>>());
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert_eq!(text.matches(&warning).count(), 1, "{text}");
}

#[test]
fn stats_list_every_rank_and_a_bad_input_stops_every_rank_with_one_message() {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("stats.png");
    let out = mpirun(
        4,
        &[
            "render",
            "--distributed",
            "--stats",
            "--scene-size",
            "48",
            "--size",
            "40",
            "-o",
            image.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stderr);
    for rank in 0..4 {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(&format!("{rank}  ["))),
            "no row for rank {rank}:\n{text}"
        );
    }
    assert!(text.contains("gather"), "{text}");
    assert!(image.exists());

    // Direct send of partial images (DVR only): early termination per part
    // may add up to 2.55/255 behind opaque parts.
    let reference = dir.path().join("single.png");
    let direct = dir.path().join("direct.png");
    let flags = ["--scene-size", "48", "--size", "40", "--quiet"];
    let out = single(&[&["render", "-o", reference.to_str().unwrap()], &flags[..]].concat());
    assert!(out.status.success(), "{out:?}");
    let out = mpirun(
        3,
        &[
            &[
                "render",
                "--distributed",
                "--compositing",
                "direct-send",
                "-o",
                direct.to_str().unwrap(),
            ],
            &flags[..],
        ]
        .concat(),
    );
    assert!(out.status.success(), "{out:?}");
    assert!(max_difference(&direct, &reference) <= 3);

    let missing = dir.path().join("missing.vol");
    let out = mpirun(
        3,
        &[
            "render",
            missing.to_str().unwrap(),
            "--distributed",
            "-o",
            dir.path().join("never.png").to_str().unwrap(),
        ],
    );
    assert!(!out.status.success());
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        text.matches("No such file").count(),
        1,
        "the error is said once:\n{text}"
    );
    assert!(!dir.path().join("never.png").exists());
}

#[test]
fn a_deep_view_of_a_pyramid_file_samples_the_same_levels_distributed() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("shapes.vol");
    support::write_scene(
        &file,
        raycaster::synth::SceneKind::Shapes,
        256,
        7,
        raycaster::volume::Format::Extended,
    );
    let view = [
        file.to_str().unwrap(),
        "--size",
        "64",
        "--fov",
        "90",
        "--zoom",
        "2",
        "--quiet",
        "--force",
        "--stats-json",
    ];
    let reference = dir.path().join("single.png");
    let out = single(&[&["render", "-o", reference.to_str().unwrap()], &view[..]].concat());
    assert!(out.status.success(), "{out:?}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["coarsest_level"].as_u64(), Some(2), "{json}");
    for ranks in [2, 3] {
        let image = dir.path().join(format!("dist-{ranks}.png"));
        let out = mpirun(
            ranks,
            &[
                &["render", "--distributed", "-o", image.to_str().unwrap()],
                &view[..],
            ]
            .concat(),
        );
        assert!(
            out.status.success(),
            "{ranks} ranks: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let d = max_difference(&image, &reference);
        assert!(d <= 2, "{ranks} ranks: differs by {d}/255");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let dist: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
        assert_eq!(dist["samples"], json["samples"], "{ranks} ranks");
    }
    // Direct send renders one level for the whole frame: said once (its
    // picture differed from the single process's by 43–104/255 unsaid), and
    // it equals the single process's at that level.
    let image = dir.path().join("direct.png");
    let out = mpirun(
        2,
        &[
            &[
                "render",
                "--distributed",
                "--compositing",
                "direct-send",
                "--no-ert",
                "-o",
                image.to_str().unwrap(),
            ],
            &view[..view.len() - 3],
        ]
        .concat(),
    );
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert_eq!(
        text.matches("warning: direct-send renders one level for the whole frame, level 0; one process (and the relay) samples the farther depths at levels up to 2").count(),
        1,
        "{text}"
    );
    let level0 = dir.path().join("level0.png");
    let out = single(
        &[
            &[
                "render",
                "--no-ert",
                "--level",
                "0",
                "-o",
                level0.to_str().unwrap(),
            ],
            &view[..],
        ]
        .concat(),
    );
    assert!(out.status.success(), "{out:?}");
    assert!(max_difference(&image, &level0) <= 1);
    // It has no bands: `--bands` is refused, once.
    let out = mpirun(
        2,
        &[
            &[
                "render",
                "--distributed",
                "--compositing",
                "direct-send",
                "--bands",
                "4",
                "-o",
                dir.path().join("never.png").to_str().unwrap(),
            ],
            &view[..],
        ]
        .concat(),
    );
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(
        text.matches("--bands pipelines the relay").count(),
        1,
        "{text}"
    );
    assert!(!dir.path().join("never.png").exists());
    // Pre-integration is refused (the seams lost the segments reaching into
    // the part behind, 8–19/255), once, without the level warning first.
    let out = mpirun(
        2,
        &[
            &[
                "render",
                "--distributed",
                "--compositing",
                "direct-send",
                "--preintegrate",
                "-o",
                dir.path().join("never.png").to_str().unwrap(),
            ],
            &view[..view.len() - 3],
        ]
        .concat(),
    );
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(
        text.matches("plain DVR without pre-integration only")
            .count(),
        1,
        "{text}"
    );
    assert!(!text.contains("renders one level"), "{text}");
    assert!(!dir.path().join("never.png").exists());
}

/// Ranks that open another volume, or were given another view or settings,
/// end the job with one error naming the first such rank and what differs
/// (they hung waiting for bands of another frame, or wrote a mixed image).
#[test]
fn ranks_of_another_frame_end_the_job_with_one_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mixed.png");
    let out = out.to_str().unwrap();
    let base = [
        "render",
        "--distributed",
        "--scene-size",
        "24",
        "--size",
        "32",
        "-o",
        out,
    ];
    for (other, needle) in [
        (
            &["--scene", "noise"][..],
            "rank 1 of 2: its volume's samples (built-in",
        ),
        (
            &["--azimuth", "10"][..],
            "rank 1 of 2: its camera is not rank 0's: every rank must be given the same flags",
        ),
        (
            &["--step", "0.3"][..],
            "rank 1 of 2: its step (0.3) is not rank 0's",
        ),
        (
            &["--tf", "cloud"][..],
            "rank 1 of 2: its transfer function is not rank 0's",
        ),
    ] {
        let second = [&base[..], other].concat();
        let o = mpirun_ranks(&[&base, &second]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{other:?}: {e}");
        assert_eq!(e.matches("error:").count(), 1, "{other:?}: {e}");
        assert!(e.contains(needle), "{other:?}: {e}");
        // (The ranks mpirun then ends say nothing more.)
        assert!(!e.contains("interrupted"), "{other:?}: {e}");
        assert!(!Path::new(out).exists(), "{other:?} wrote an image");
    }
    // Label volumes of other ids on one rank (it wrote a mixed image).
    let labels = |name: &str, period: u32| {
        let path = dir.path().join(name);
        let header = raycaster::volume::Header::new(
            [24; 3],
            [1.0; 3],
            raycaster::volume::Layout::Bricked { side: 16 },
            raycaster::volume::SampleType::U8,
            raycaster::volume::Content::Labels,
            raycaster::volume::Format::Extended,
        );
        // Ids by the x plane (x fastest-changing slabs: planes x0..x1).
        raycaster::io::write_volume::<u8>(
            &path,
            &header,
            &Default::default(),
            &raycaster::job::Job::silent(),
            |x0, _, slab| {
                for (i, id) in slab.iter_mut().enumerate() {
                    *id = ((x0 + (i / (24 * 24)) as u32) / period % 2 + 1) as u8;
                }
                Ok(())
            },
        )
        .unwrap();
        path.to_str().unwrap().to_string()
    };
    let a = labels("a.labels.vol", 4);
    let b = labels("b.labels.vol", 6);
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, "labels = \"a.labels.vol\"\n[[object]]\nid = 1\n").unwrap();
    let scene = scene.to_str().unwrap();
    let with = |l: &'static str| [&base[..], &["--segments", scene, "--labels", l]].concat();
    let (a, b): (&'static str, &'static str) = (a.leak(), b.leak());
    let o = mpirun_ranks(&[&with(a), &with(b)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("rank 1 of 2: its label volume (")
            && e.contains("b.labels.vol) is not rank 0's"),
        "{e}"
    );
}

/// Every rank runs one command line: what is wrong with it is said once (it
/// was said by every rank), and a render without `--distributed` under
/// mpirun is warned of once (each rank renders the whole frame); a script
/// each rank runs, or ranks given other command lines, speak for themselves.
#[test]
fn a_command_line_is_judged_once_under_mpirun() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.png");
    let out = out.to_str().unwrap();
    let args = ["render", "--distributed", "--bogus", "-o", out];
    let o = mpirun(2, &args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert_eq!(e.matches("error:").count(), 1, "{e}");
    assert!(e.contains("unexpected argument '--bogus'"), "{e}");
    assert!(!Path::new(out).exists(), "an image was written");
    // Ranks rendering the whole frame each: warned of once.
    let plain = dir.path().join("plain.png");
    let o = mpirun(
        2,
        &[
            "render",
            "--scene-size",
            "16",
            "--size",
            "16",
            "-o",
            plain.to_str().unwrap(),
            "--force",
        ],
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert_eq!(
        e.matches("warning: raycaster render runs as 2 processes under mpirun, each rendering the whole frame: --distributed renders one frame together").count(),
        1,
        "{e}"
    );
    // A script run by every rank, rendering a frame of its own: not refused.
    let script = format!(
        "{} render --scene-size 16 --size 16 -q -o {}/frame-$OMPI_COMM_WORLD_RANK.png",
        binary(),
        dir.path().display()
    );
    let o = mpirun_line(&["-np", "2", "sh", "-c", &script]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for rank in 0..2 {
        assert!(dir.path().join(format!("frame-{rank}.png")).exists());
    }
    // Ranks given other command lines (`A : B`): the one that is wrong says so.
    let good = ["render", "--distributed", "--scene-size", "24", "-o", out];
    let bad = [&good[..], &["--bogus"]].concat();
    let o = mpirun_ranks(&[&good, &bad]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert_eq!(e.matches("unexpected argument '--bogus'").count(), 1, "{e}");
}
