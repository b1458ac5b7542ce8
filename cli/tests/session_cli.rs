//! `raycaster render --session`: a session written by the library renders the
//! same pixels as the equivalent flags; flags that describe the picture are
//! refused with a session; bad sessions are refused by field.

mod support;

use support::{raycaster, stderr};

use std::path::Path;

use raycaster::render::{
    ClipPlane, ClipRegion, CropBox, LevelChoice, Mode, ModeParameters, Orbit, RenderSettings,
    RgbImage, SabellaDepth, SabellaMapping, SabellaOutput, Shading, TransferFunction, Vec3,
};
use raycaster::session::{Session, SessionCamera};
use raycaster::source::VolumeSource;
use raycaster::synth::SceneKind;

/// The built-in shapes scene of 40³ voxels: voxel centres 0..39.
const N: u32 = 40;

/// The session the flags of `flags()` describe, built with the library.
fn session(mode: Mode) -> Session {
    let hi = Vec3::splat((N - 1) as f32);
    let mut orbit = Orbit::framing(
        Vec3::ZERO,
        hi,
        30f32.to_radians(),
        20f32.to_radians(),
        Some(35.0),
    );
    orbit.zoom(1.0 / 1.25);
    Session {
        source: VolumeSource::BuiltIn {
            kind: SceneKind::Shapes,
            size: N,
            seed: 3,
        },
        labels: None,
        size: [72, 56],
        camera: SessionCamera::Orbit(orbit),
        settings: RenderSettings {
            mode,
            mode_parameters: ModeParameters {
                xray_gain: Some(2.0),
                sabella: SabellaOutput::Colours(SabellaMapping {
                    depth: SabellaDepth::Centroid,
                    ..SabellaMapping::default()
                }),
                ..ModeParameters::default()
            },
            step: 0.75,
            shading: Some(Shading::default()),
            iso_value: 0.4,
            transfer: TransferFunction::preset("shapes").unwrap(),
            jitter: true,
            clip: ClipRegion {
                crop: Some(CropBox {
                    lo: Vec3::new(0.0, 0.0, 0.0),
                    hi: Vec3::new(39.0, 30.0, 39.0),
                }),
                planes: vec![ClipPlane {
                    point: Vec3::new(19.5, 19.5, 19.5),
                    normal: Vec3::new(1.0, 0.0, 1.0),
                }],
            },
            ..RenderSettings::default()
        },
        level: LevelChoice::Auto { bias: 0.0 },
        slices: None,
    }
}

/// The same frame as flags (a mode's parameters with that mode only: render
/// refuses them with another).
fn flags(mode: &str) -> Vec<String> {
    let parameter: &[&str] = match mode {
        "xray" => &["--xray-gain", "2"],
        "sabella" => &["--sabella-depth", "centroid"],
        "first-hit" => &["--iso", "40%"],
        _ => &[],
    };
    let all = [
        "--scene",
        "shapes",
        "--scene-size",
        "40",
        "--seed",
        "3",
        "--size",
        "72x56",
        "--azimuth",
        "30",
        "--elevation",
        "20",
        "--fov",
        "35",
        "--zoom",
        "1.25",
        "--mode",
        mode,
        "--step",
        "0.75",
        "--jitter",
        "--tf",
        "shapes",
        "--crop",
        "0,0,0,39,30,39",
        "--clip",
        "19.5,19.5,19.5,1,0,1",
    ];
    all.iter().chain(parameter).map(|a| a.to_string()).collect()
}

fn render(dir: &Path, args: &[String], out: &str) -> RgbImage {
    let mut all: Vec<&str> = vec!["render", "-q", "--force", "-o", out];
    all.extend(args.iter().map(String::as_str));
    let run = raycaster(&all, dir);
    assert!(run.status.success(), "{all:?}: {}", stderr(&run));
    RgbImage::load_png(&dir.join(out)).unwrap()
}

#[test]
fn a_session_renders_the_pixels_of_the_equivalent_flags() {
    let dir = tempfile::tempdir().unwrap();
    for (mode, name) in [
        (Mode::Dvr, "dvr"),
        (Mode::Sabella, "sabella"),
        (Mode::FirstHit, "first-hit"),
        (Mode::XRay, "xray"),
    ] {
        let path = dir.path().join(format!("{name}.toml"));
        session(mode).save(&path).unwrap();
        let from_flags = render(dir.path(), &flags(name), "flags.png");
        let session_args = vec!["--session".to_string(), path.display().to_string()];
        let from_session = render(dir.path(), &session_args, "session.png");
        assert_eq!((from_session.width(), from_session.height()), (72, 56));
        let lit = from_session
            .data()
            .chunks(3)
            .filter(|p| p != &[0, 0, 0])
            .count();
        assert!(lit > 100, "{name}: the scene shows ({lit} lit pixels)");
        assert!(
            from_session.data() == from_flags.data(),
            "{name}: the session's image differs from the flags' image"
        );
        // The sequential reference renderer agrees.
        let mut sequential = session_args.clone();
        sequential.push("--sequential".into());
        let reference = render(dir.path(), &sequential, "sequential.png");
        assert!(
            reference.data() == from_session.data(),
            "{name}: sequential"
        );
    }
    // A changed session field changes the picture (the comparison can fail).
    let mut other = session(Mode::Dvr);
    other.settings.step = 0.5;
    let path = dir.path().join("other.toml");
    other.save(&path).unwrap();
    let changed = render(
        dir.path(),
        &["--session".into(), path.display().to_string()],
        "other.png",
    );
    let dvr = render(dir.path(), &flags("dvr"), "flags.png");
    assert!(changed.data() != dvr.data(), "the step shows in the image");
}

#[test]
fn size_overrides_a_session_and_picture_flags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    session(Mode::Dvr).save(&path).unwrap();
    let s = path.display().to_string();
    let big = render(
        dir.path(),
        &[
            "--session".into(),
            s.clone(),
            "--size".into(),
            "100x80".into(),
        ],
        "big.png",
    );
    assert_eq!((big.width(), big.height()), (100, 80));
    for extra in [
        &["--mode", "mip"][..],
        &["--azimuth", "10"],
        &["--tf", "cloud"],
        &["--crop", "0,0,0,5,5,5"],
        &["--scene", "shells"],
    ] {
        let mut args = vec!["render", "--session", &s, "-o", "x.png"];
        args.extend(extra);
        let run = raycaster(&args, dir.path());
        assert!(!run.status.success(), "{extra:?} is refused");
        let e = stderr(&run);
        assert!(e.contains("--session") && e.contains(extra[0]), "{e}");
    }
    let run = raycaster(&["render", "in.vol", "--session", &s], dir.path());
    assert!(!run.status.success(), "a FILE with a session is refused");
}

#[test]
fn a_session_level_past_the_coarsest_or_a_step_past_the_volume_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let mut deep = session(Mode::Dvr);
    deep.level = LevelChoice::Fixed(99);
    deep.settings.step = 5000.0;
    deep.save(&dir.path().join("deep.toml")).unwrap();
    let run = raycaster(
        &["render", "--session", "deep.toml", "-o", "d.png"],
        dir.path(),
    );
    assert!(run.status.success(), "{}", stderr(&run));
    assert_eq!(
        stderr(&run)
            .matches("warning: deep.toml: `level = 99`: the volume's coarsest level is 0; rendering level 0")
            .count(),
        1,
        "{}",
        stderr(&run)
    );
    assert_eq!(
        stderr(&run)
            .matches(
                "warning: deep.toml: `step`: a step of 5000 is longer than the volume's diagonal"
            )
            .count(),
        1,
        "{}",
        stderr(&run)
    );
}

/// A session's domain beside the data's values is warned of, as `--domain`
/// is; with a clipping plane, the empty picture is not blamed on the plane.
#[test]
fn a_session_domain_outside_the_data_is_warned_of_and_not_blamed_on_its_planes() {
    let dir = tempfile::tempdir().unwrap();
    let mut high = session(Mode::Dvr);
    high.settings.transfer.domain = Some([300.0, 400.0]);
    high.settings.clip.planes = vec![raycaster::render::ClipPlane {
        point: Vec3::splat(20.0),
        normal: Vec3::X,
    }];
    high.save(&dir.path().join("high.toml")).unwrap();
    let run = raycaster(
        &["render", "--session", "high.toml", "-o", "h.png"],
        dir.path(),
    );
    assert!(run.status.success(), "{}", stderr(&run));
    let said = stderr(&run);
    assert_eq!(
        said.matches("warning: high.toml: `[transfer] domain = [300, 400]` is in stored sample values and lies outside the data's, 0 to 254").count(),
        1,
        "{said}"
    );
    assert!(!said.contains("clipping planes"), "{said}");
}

#[test]
fn bad_sessions_are_refused_by_field() {
    let dir = tempfile::tempdir().unwrap();
    let good = session(Mode::Dvr).to_toml().unwrap();
    support::write_labels(&dir.path().join("l.vol"), 40);
    for (from, to, word) in [
        ("step = 0.75", "step = -1.0", "render.step"),
        ("mode = \"dvr\"", "mode = \"glow\"", "render.mode"),
        ("width = 72", "width = 0", "image.width"),
        (
            "scene = \"shapes\"\nsize = 40\nseed = 3",
            "file = \"missing.vol\"",
            "missing.vol",
        ),
        ("version = 1", "version = 9", "version"),
        // A file that is there but is no volume: said as the session's.
        (
            "scene = \"shapes\"\nsize = 40\nseed = 3",
            "file = \".\"",
            "the session's `volume`: .: ",
        ),
        // A crop box beside the volume: refused as `--crop` refuses it
        // (before: an empty picture, exit 0).
        (
            "crop = [0.0, 0.0, 0.0, 39.0, 30.0, 39.0]",
            "crop = [100.0, 0.0, 0.0, 200.0, 30.0, 39.0]",
            "lies outside the volume along x",
        ),
    ] {
        assert!(good.contains(from), "{from}");
        std::fs::write(dir.path().join("bad.toml"), good.replace(from, to)).unwrap();
        let run = raycaster(
            &["render", "--session", "bad.toml", "-o", "x.png"],
            dir.path(),
        );
        assert!(!run.status.success(), "{to}");
        let e = stderr(&run);
        assert!(e.contains(word), "{to}: {e}");
        // The error names the file it is about, once.
        assert!(e.starts_with("error: bad.toml: "), "{to}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!dir.path().join("x.png").exists());
    }
    // A label volume as the data: advised in the session's words (it named
    // --labels and --segments, which --session does not take).
    let labels_as_data = good.replace(
        "scene = \"shapes\"\nsize = 40\nseed = 3",
        "file = \"l.vol\"",
    );
    std::fs::write(dir.path().join("bad.toml"), labels_as_data).unwrap();
    let run = raycaster(
        &["render", "--session", "bad.toml", "-o", "x.png"],
        dir.path(),
    );
    assert_eq!(
        stderr(&run),
        "error: l.vol: is a label volume (object ids, not values); name the data volume in the session's `volume.file` and this one in `volume.labels` (with a `[scene]`)\n"
    );
}

#[test]
fn a_session_image_too_large_is_refused_unless_size_replaces_it() {
    let dir = tempfile::tempdir().unwrap();
    let good = session(Mode::Dvr).to_toml().unwrap();
    assert!(good.contains("width = 72"));
    std::fs::write(
        dir.path().join("huge.toml"),
        good.replace("width = 72", "width = 100000"),
    )
    .unwrap();
    let run = raycaster(
        &["render", "--session", "huge.toml", "-o", "x.png"],
        dir.path(),
    );
    assert_eq!(run.status.code(), Some(1));
    let e = stderr(&run);
    assert!(
        e.starts_with(
            "error: huge.toml: image.width = 100000 pixels: must lie in 1..=16384 (--size WxH"
        ),
        "{e}"
    );
    assert!(!dir.path().join("x.png").exists());
    let run = raycaster(
        &[
            "render",
            "--session",
            "huge.toml",
            "--size",
            "40x30",
            "-o",
            "x.png",
        ],
        dir.path(),
    );
    assert!(run.status.success(), "{}", stderr(&run));
    let image = raycaster::render::RgbImage::load_png(&dir.path().join("x.png")).unwrap();
    assert_eq!((image.width(), image.height()), (40, 30));
}

#[test]
fn errors_in_transfer_function_and_scene_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
    write("bad.tf", "point 0.5 garbage 0 0 0\n");
    write(
        "scene.toml",
        "layers = [[0.1, 0.5], [0.5, 1.0]]\n[[object]]\nname = \"a\"\ntf = \"bad.tf\"\n[[object]]\nname = \"b\"\n",
    );
    write("broken.toml", "[camera]\n");
    let base = [
        "render",
        "--scene",
        "shapes",
        "--scene-size",
        "16",
        "--size",
        "16",
        "-o",
        "x.png",
    ];
    for (extra, needle) in [
        (["--tf", "bad.tf"], "error: bad.tf: line 1: "),
        (
            ["--segments", "scene.toml"],
            "error: scene.toml: scene description: object \"a\": ",
        ),
        (
            ["--segments", "broken.toml"],
            "error: broken.toml: scene description: line 1, column 2 (`[camera]`): unknown field `camera`",
        ),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(extra).collect();
        let run = raycaster(&args, dir.path());
        assert!(!run.status.success(), "{extra:?}");
        let e = stderr(&run);
        assert!(e.starts_with(needle), "{extra:?}: {e}");
        assert_eq!(e.matches(extra[1]).count(), 1, "{extra:?}: {e}");
        // One line, as `--help` promises (TOML's errors quoted the line
        // under a caret, over five).
        assert_eq!(e.lines().count(), 1, "{extra:?}: {e}");
        assert!(!dir.path().join("x.png").exists());
    }
    // An object's function file is named after its scene.
    let run = raycaster(
        &[&base[..], &["--segments", "scene.toml"]].concat(),
        dir.path(),
    );
    assert!(
        stderr(&run).contains("bad.tf: line 1: "),
        "{}",
        stderr(&run)
    );
    // Values of the wrong kind say what the key takes (not a Rust type's
    // name), and a missing file is one, not an unknown preset.
    write("tf5.toml", "layers = [[0, 1]]\n[[object]]\ntf = 5\n");
    write(
        "missing.toml",
        "layers = [[0, 1]]\n[[object]]\ntf = \"nope.tf\"\n",
    );
    write(
        "four.toml",
        "layers = [[0, 1]]\n[[object]]\ntf = { points = [[0.0, 0.0, 0.0, 0.0]] }\n",
    );
    let whole = session(Mode::Dvr).to_toml().unwrap();
    let level = whole
        .lines()
        .find(|l| l.starts_with("level = "))
        .expect("a level line");
    write("level.toml", &whole.replace(level, "level = -1"));
    for (extra, needle) in [
        (
            ["--segments", "tf5.toml"],
            "`tf` is a preset name or file path (a string) or an inline table",
        ),
        // An inline table's own error is said (a point of four numbers was
        // said as the generic forms of `tf`).
        (
            ["--segments", "four.toml"],
            "`tf` inline table: invalid length 4, expected an array of length 5",
        ),
        (
            ["--segments", "missing.toml"],
            "cannot read transfer function file nope.tf: No such file",
        ),
        (
            ["--session", "level.toml"],
            "`level` is `\"auto\"` or a level number",
        ),
    ] {
        let args: Vec<&str> = ["render", "-o", "x.png"].into_iter().chain(extra).collect();
        let e = stderr(&raycaster(&args, dir.path()));
        assert!(
            e.contains(needle) && !e.contains("untagged"),
            "{extra:?}: {e}"
        );
    }
}
