//! `raycaster render --crop/--clip/--mode sabella` and `raycaster slice`, driven
//! as a user would: real binary, real files.

mod support;

use support::{raycaster, stderr, write_scene};

use std::path::Path;

use raycaster::render::RgbImage;
use raycaster::volume::{Content, Format, Header, Layout, SampleType, Volume};

/// Voxel (x, y, z) = `100·x + 10·y + z` (u16) or that modulo 256 (u8).
struct Formula(SampleType);

impl raycaster::synth::Scene for Formula {
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]) {
        for (z, o) in out.iter_mut().enumerate() {
            let v = 100 * x + 10 * y + z as u32;
            *o = match self.0 {
                SampleType::U8 => (v % 256) as f32 / 255.0,
                SampleType::U16 => v as f32 / 65535.0,
            };
        }
    }
}

/// Writes `name`: 20 × 12 × 9 voxels of [`Formula`] in `layout`.
fn write_volume(dir: &Path, name: &str, sample: SampleType, layout: Layout) {
    write_spaced_volume(dir, name, sample, layout, [1.0; 3]);
}

/// [`write_volume`] with voxel spacing `spacing`.
fn write_spaced_volume(
    dir: &Path,
    name: &str,
    sample: SampleType,
    layout: Layout,
    spacing: [f32; 3],
) {
    let header = Header::new(
        [20, 12, 9],
        spacing,
        layout,
        sample,
        Content::Scalar,
        Format::Extended,
    );
    raycaster::generate::generate(
        &Formula(sample),
        &header,
        &dir.join(name),
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap();
    let volume = Volume::open(dir.join(name)).unwrap();
    assert_eq!(
        volume.voxel([7, 5, 4]),
        if sample == SampleType::U16 {
            754
        } else {
            754 % 256
        }
    );
}

#[test]
fn slices_have_square_pixels_unless_voxels_are_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    // Slices 3 mm apart, 0.5 × 1 mm pixels (CT-like).
    write_spaced_volume(
        dir.path(),
        "ct.vol",
        SampleType::U16,
        Layout::Linear,
        [0.5, 1.0, 3.0],
    );
    let slice = |extra: &[&str]| {
        let mut args = vec!["slice", "ct.vol", "-o", "s.png", "--force"];
        args.extend_from_slice(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let image = RgbImage::load_png(&dir.path().join("s.png")).unwrap();
        ((image.width(), image.height()), stderr(&out), image)
    };
    // y slice: columns x (0.5 mm), rows z (3 mm): 9 rows become 54.
    let (size, said, image) = slice(&["--axis", "y", "--index", "5"]);
    assert_eq!(size, (20, 54));
    assert!(
        said.contains("20×54 from 20×9 voxels, stretched to square pixels"),
        "{said}"
    );
    // Top row z = 8 (white at x 19), bottom row z = 0, grey between.
    let (top, bottom) = (image.pixel(19, 0)[0], image.pixel(19, 53)[0]);
    assert!(top > bottom, "{top} {bottom}");
    // z slice: rows y (1 mm) are stretched to the columns' 0.5 mm: 12 → 24.
    assert_eq!(slice(&["--axis", "z", "--index", "4"]).0, (20, 24));
    // A named CT window on values without HU units: warned of, rendered.
    let (_, said, _) = slice(&["--axis", "z", "--index", "4", "--window", "lung"]);
    assert!(
        said.contains("warning: --window lung: a CT window in Hounsfield units, and ct.vol holds stored samples without value units"),
        "{said}"
    );
    let (_, said, _) = slice(&["--axis", "z", "--index", "4", "--window", "0,500"]);
    assert!(!said.contains("warning"), "{said}");
    // --voxels: one pixel per voxel, and no word of stretching.
    let (size, said, _) = slice(&["--axis", "y", "--index", "5", "--voxels"]);
    assert_eq!(size, (20, 9));
    assert!(!said.contains("stretched"), "{said}");
    assert!(
        said.contains("20×9, pixels 6.000× as high as wide"),
        "{said}"
    );
    // Rounding to whole pixels (9 rows of 2.75 become 25, not 24.75) is no
    // limit of the stretch.
    write_spaced_volume(
        dir.path(),
        "round.vol",
        SampleType::U8,
        Layout::Linear,
        [1.0, 1.0, 2.75],
    );
    let out = raycaster(
        &[
            "slice",
            "round.vol",
            "--axis",
            "y",
            "--index",
            "5",
            "-o",
            "r.png",
            "--force",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let said = stderr(&out);
    assert!(
        said.contains("20×25 from 20×9 voxels, stretched to square pixels,"),
        "{said}"
    );
    assert!(!said.contains("8192"), "{said}");
}

#[test]
fn slices_of_linear_and_bricked_u8_and_u16_files_show_the_plane() {
    let dir = tempfile::tempdir().unwrap();
    for (sample, layout) in [
        (SampleType::U16, Layout::Linear),
        (SampleType::U16, Layout::Bricked { side: 8 }),
        (SampleType::U8, Layout::Bricked { side: 16 }),
        (SampleType::U8, Layout::Linear),
    ] {
        let name = format!("v-{sample:?}-{layout:?}.vol");
        write_volume(dir.path(), &name, sample, layout);
        // z = 4: columns x (20), rows y (12) from y = 11 at the top.
        let out = raycaster(
            &[
                "slice", &name, "--axis", "z", "--index", "4", "-o", "z.png", "--force",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let image = RgbImage::load_png(&dir.path().join("z.png")).unwrap();
        assert_eq!((image.width(), image.height()), (20, 12), "{name}");
        if sample == SampleType::U16 {
            // The default window is the slice's range, 4..=2014: the top right
            // (x 19, y 11) is white, the bottom left (0, 0) black, grey between
            // by value.
            assert_eq!(image.pixel(19, 0), [255; 3], "{name}");
            assert_eq!(image.pixel(0, 11), [0; 3], "{name}");
            let grey = |v: f32| ((v - 4.0) / 2010.0 * 255.0 + 0.5) as u8;
            assert_eq!(image.pixel(7, 6), [grey(700.0 + 50.0 + 4.0); 3], "{name}");
        }
        // A window: x slice 3 holds 300..=413 (u16); 350..400 clamps the rest.
        let out = raycaster(
            &[
                "slice", &name, "--axis", "x", "--index", "3", "--window", "350,400", "-o",
                "x.png", "--force", "-q",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        assert!(stderr(&out).is_empty());
        let image = RgbImage::load_png(&dir.path().join("x.png")).unwrap();
        assert_eq!((image.width(), image.height()), (12, 9), "{name}");
        if sample == SampleType::U16 {
            // Top row: z = 8; column y. y = 4 → 348 (black), y = 5 → 358.
            assert_eq!(image.pixel(4, 0), [0; 3]);
            assert_eq!(
                image.pixel(5, 0),
                [((8.0f32 / 50.0) * 255.0 + 0.5) as u8; 3]
            );
            assert_eq!(image.pixel(10, 0), [255; 3]);
        }
    }
}

#[test]
fn slice_refuses_bad_indices_windows_and_outputs_clearly() {
    let dir = tempfile::tempdir().unwrap();
    write_volume(dir.path(), "v.vol", SampleType::U16, Layout::Linear);
    let fail = |args: &[&str], needle: &str| {
        let out = raycaster(args, dir.path());
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        let e = stderr(&out);
        assert!(e.contains(needle), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    };
    fail(
        &[
            "slice", "v.vol", "--axis", "y", "--index", "12", "-o", "s.png",
        ],
        "outside the volume along y (0..=11)",
    );
    assert!(!dir.path().join("s.png").exists());
    fail(
        &[
            "slice",
            "missing.vol",
            "--axis",
            "z",
            "--index",
            "0",
            "-o",
            "s.png",
        ],
        "missing.vol",
    );
    fail(
        &[
            "slice", "v.vol", "--axis", "z", "--index", "0", "-o", "s.jpg",
        ],
        "only PNG",
    );
    std::fs::write(dir.path().join("s.png"), b"keep").unwrap();
    fail(
        &[
            "slice", "v.vol", "--axis", "z", "--index", "0", "-o", "s.png",
        ],
        "already exists (pass --force",
    );
    assert_eq!(std::fs::read(dir.path().join("s.png")).unwrap(), b"keep");
    let out = raycaster(
        &[
            "slice", "v.vol", "--axis", "z", "--index", "0", "--window", "5,5", "-o", "t.png",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("lo < hi"), "{}", stderr(&out));
}

#[test]
fn crop_and_clip_cut_the_picture_and_bad_values_name_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let render = |extra: &[&str], out_name: &str| {
        let mut args = vec![
            "render",
            "--scene-size",
            "48",
            "--size",
            "64",
            "--azimuth",
            "-90",
            "--elevation",
            "0",
            "--orthographic",
            "--force",
            "-o",
            out_name,
        ];
        args.extend_from_slice(extra);
        raycaster(&args, dir.path())
    };
    let lit = |name: &str, columns: std::ops::Range<u32>| {
        let image = RgbImage::load_png(&dir.path().join(name)).unwrap();
        columns
            .flat_map(|x| (0..64).map(move |y| (x, y)))
            .filter(|&(x, y)| image.pixel(x, y) != [0, 0, 0])
            .count()
    };
    let out = render(&[], "whole.png");
    assert!(out.status.success(), "{}", stderr(&out));
    // Looking along +y: x runs left to right. Keeping x ≥ 50 % (a plane) or
    // x ≤ 40 % (a box) empties the other side of the picture.
    for (extra, dark) in [
        (vec!["--clip", "50%,0,0,1,0,0"], 0..24),
        (vec!["--crop", "0,0,0,40%,100%,100%"], 36..64),
        (
            vec![
                "--crop",
                "0%,0%,0%,100%,100%,100%",
                "--clip",
                "0,0,0,-1,0,0",
            ],
            0..64,
        ),
    ] {
        let out = render(&extra, "cut.png");
        assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
        assert!(lit("whole.png", dark.clone()) > 50, "{extra:?}");
        assert_eq!(lit("cut.png", dark), 0, "{extra:?}");
    }
    for (extra, needle) in [
        (
            vec!["--crop", "10,0,0,5,47,47"],
            "--crop: the box is empty or inverted along x",
        ),
        (
            vec!["--crop", "0,0,9,47,47,9"],
            "--crop: the box is empty or inverted along z",
        ),
        (
            vec!["--crop", "0,0,60,47,47,70"],
            "--crop: the box 60..70 along z lies outside",
        ),
        (
            vec!["--clip", "1,1,1,0,0,0"],
            "--clip: the plane's normal is zero",
        ),
        (
            vec!["--clip", "1,1,1,0,nan,0"],
            "--clip <PX,PY,PZ,NX,NY,NZ>",
        ),
        (vec!["--crop", "1,2,3,4"], "--crop <X0,Y0,Z0,X1,Y1,Z1>"),
    ] {
        let out = render(&extra, "bad.png");
        assert!(!out.status.success(), "{extra:?}");
        let e = stderr(&out);
        assert!(e.contains(needle), "{extra:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!dir.path().join("bad.png").exists());
    }
    let seven: Vec<&str> = (0..7).flat_map(|_| ["--clip", "1,1,1,0,0,1"]).collect();
    let out = render(&seven, "bad.png");
    assert!(
        stderr(&out).contains("--clip given 7 times"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn sabella_mode_colours_by_depth_or_centroid() {
    let dir = tempfile::tempdir().unwrap();
    let run = |depth: &str, name: &str| {
        let out = raycaster(
            &[
                "render",
                "--scene-size",
                "48",
                "--size",
                "48",
                "--mode",
                "sabella",
                "--sabella-depth",
                depth,
                "-o",
                name,
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        RgbImage::load_png(&dir.path().join(name)).unwrap()
    };
    let peak = run("peak", "peak.png");
    let centroid = run("centroid", "centroid.png");
    let lit = peak.data().chunks(3).filter(|p| p != &[0, 0, 0]).count();
    assert!(lit > 200, "{lit} lit pixels");
    assert!(peak.max_difference(&centroid).is_some_and(|d| d > 0));
    let out = raycaster(
        &["render", "--mode", "sabella", "--sabella-depth", "middle"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--sabella-depth"));
}

/// Writes `name`: a NRRD of 20 × 12 × 9 u16 voxels, `100·i + 10·j + k` at
/// index (i, j, k), placed in RAS space with unit axes (x grows to the
/// patient's right, y anterior, z superior).
fn write_ras_nrrd(dir: &Path, name: &str) {
    write_nrrd_with_axes(dir, name, "(1,0,0) (0,1,0) (0,0,1)");
}

/// [`write_ras_nrrd`] with the voxel axes' RAS directions `directions`.
fn write_nrrd_with_axes(dir: &Path, name: &str, directions: &str) {
    let mut bytes = format!(
        "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 20 12 9\n\
space: right-anterior-superior\nspace directions: {directions}\n\
space origin: (0,0,0)\nendian: little\nencoding: raw\n\n"
    )
    .into_bytes();
    for k in 0..9u16 {
        for j in 0..12u16 {
            for i in 0..20u16 {
                bytes.extend_from_slice(&(100 * i + 10 * j + k).to_le_bytes());
            }
        }
    }
    std::fs::write(dir.join(name), bytes).unwrap();
}

/// A volume turned 45° about the patient's z has no axial reading: the slice
/// keeps voxel order and says so (it did so without a word).
#[test]
fn a_slice_with_no_anatomical_reading_says_it_keeps_voxel_order() {
    let dir = tempfile::tempdir().unwrap();
    write_nrrd_with_axes(
        dir.path(),
        "turned.nrrd",
        "(0.7071068,0.7071068,0) (-0.7071068,0.7071068,0) (0,0,1)",
    );
    let slice = |extra: &[&str]| {
        let mut args = vec![
            "slice",
            "turned.nrrd",
            "--axis",
            "z",
            "--index",
            "4",
            "-o",
            "s.png",
            "--force",
        ];
        args.extend_from_slice(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let image = RgbImage::load_png(&dir.path().join("s.png")).unwrap();
        (image, stderr(&out))
    };
    let (read, said) = slice(&[]);
    assert!(
        said.contains("voxel axes lie about 45° from the patient's")
            && said.contains("keeps voxel order"),
        "{said}"
    );
    assert!(!said.contains("axial"), "{said}");
    let (plain, plain_said) = slice(&["--volume-axes"]);
    assert_eq!(read, plain);
    assert!(!plain_said.contains("45°"), "{plain_said}");
    let (_, quiet_said) = slice(&["--quiet"]);
    assert!(quiet_said.is_empty(), "{quiet_said}");
}

#[test]
fn slices_of_a_volume_in_the_patient_read_as_radiologists_read_them() {
    let dir = tempfile::tempdir().unwrap();
    write_ras_nrrd(dir.path(), "ras.nrrd");
    let slice = |axis: &str, index: &str, extra: &[&str]| {
        let mut args = vec![
            "slice", "ras.nrrd", "--axis", axis, "--index", index, "-o", "s.png", "--force",
        ];
        args.extend_from_slice(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let image = RgbImage::load_png(&dir.path().join("s.png")).unwrap();
        (image, stderr(&out))
    };
    // RAS axes: voxel order shows the patient's right on the right in axial
    // and coronal slices and anterior on the right in sagittal ones; as read,
    // each of them is mirrored left to right (rows: anterior and superior
    // already grow upwards).
    for (axis, index, said) in [
        (
            "z",
            "4",
            "axial slice z = 4 of ras.nrrd, R on the left, A at the top",
        ),
        (
            "y",
            "5",
            "coronal slice y = 5 of ras.nrrd, R on the left, S at the top",
        ),
        (
            "x",
            "7",
            "sagittal slice x = 7 of ras.nrrd, A on the left, S at the top",
        ),
    ] {
        let (plain, plain_said) = slice(axis, index, &["--volume-axes"]);
        let (read, read_said) = slice(axis, index, &[]);
        assert!(read_said.contains(said), "{read_said}");
        assert!(!plain_said.contains(" on the left"), "{plain_said}");
        let (w, h) = (plain.width(), plain.height());
        assert_eq!((read.width(), read.height()), (w, h), "{axis}");
        // The slice is not symmetric, so the mirror is seen.
        assert_ne!(read, plain, "{axis}");
        for row in 0..h {
            for col in 0..w {
                assert_eq!(
                    read.pixel(col, row),
                    plain.pixel(w - 1 - col, row),
                    "{axis}"
                );
            }
        }
    }
}

/// A crop box is given in full-resolution voxels whatever level renders it:
/// one in the far half of the volume (beyond a coarse level's voxel count)
/// renders at every pyramid level. (It was refused as lying outside the
/// volume at levels whose voxel count it exceeded, which is also how the
/// viewer's first, coarse frame of a cut session failed.)
#[test]
fn a_crop_box_renders_at_every_pyramid_level() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(
        &dir.path().join("shapes.vol"),
        raycaster::synth::SceneKind::Shapes,
        128,
        7,
        raycaster::volume::Format::Extended,
    );
    // (128³: one pyramid level, 64³; the box starts at y = 70.)
    for level in ["0", "1", "auto"] {
        let out = raycaster(
            &[
                "render",
                "shapes.vol",
                "--crop",
                "0,70,0,127,127,127",
                "--level",
                level,
                "--size",
                "64x64",
                "--stats-json",
                "-o",
                "c.png",
                "--force",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "--level {level}: {}", stderr(&out));
        let stats = String::from_utf8_lossy(&out.stdout).to_string();
        if level != "auto" {
            assert!(stats.contains(&format!("\"level\":{level},")), "{stats}");
        }
        let image = RgbImage::load_png(&dir.path().join("c.png")).unwrap();
        let lit = image.data().chunks(3).filter(|p| p != &[0, 0, 0]).count();
        assert!(lit > 100, "--level {level}: {lit} lit pixels");
    }
}

/// A clipping plane with the whole volume on its cut side renders background,
/// and says so once; a plane through the volume says nothing.
#[test]
fn a_plane_that_keeps_nothing_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    // Renders with one `--clip` per plane given, and flags `extra`.
    let run_with = |planes: &[&str], extra: &[&str]| {
        let mut args = vec![
            "render",
            "--scene-size",
            "32",
            "--size",
            "24x24",
            "-o",
            "p.png",
            "--force",
        ];
        for plane in planes {
            args.extend(["--clip", plane]);
        }
        args.extend(extra);
        let out = raycaster(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    let run_planes = |planes: &[&str]| run_with(planes, &[]);
    let run = |clip: &str| run_planes(&[clip]);
    let said = run("40,0,0,1,0,0");
    assert_eq!(
        said.matches("warning: the clipping plane through [40, 0, 0] with normal [1, 0, 0] keeps nothing of built-in shapes scene 32³: the picture is background").count(),
        1,
        "{said}"
    );
    let image = RgbImage::load_png(&dir.path().join("p.png")).unwrap();
    assert!(image.data().iter().all(|&c| c == 0));
    assert!(!run("16,0,0,1,0,0").contains("warning"));
    // Two planes facing apart, each keeping half: together nothing, said once
    // (it rendered background without a word); overlapping halves are not.
    let said = run_planes(&["16,0,0,1,0,0", "12,0,0,-1,0,0"]);
    assert_eq!(
        said.matches("warning: the crop box and clipping planes together keep nothing of built-in shapes scene 32³: the picture is background").count(),
        1,
        "{said}"
    );
    assert!(!run_planes(&["12,0,0,1,0,0", "16,0,0,-1,0,0"]).contains("warning"));
    // A frame the transfer function leaves empty (a domain above the data:
    // no brick marched, no ray made) is not blamed on the planes.
    let said = run_with(&["16,0,0,1,0,0"], &["--domain", "300,400"]);
    assert!(!said.contains("clipping planes"), "{said}");
}

#[test]
fn a_slice_of_one_value_is_shown_as_in_the_volume_not_mid_grey() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The shapes scene has planes of empty space (0); its values 0 to 254.
    write_scene(
        &d.join("shapes.vol"),
        raycaster::synth::SceneKind::Shapes,
        48,
        7,
        Format::Extended,
    );
    let volume = Volume::open(d.join("shapes.vol")).unwrap();
    let [lo, hi] = volume.ranges().overall();
    assert!(lo == 0 && hi > 200, "{lo} {hi}");
    let empty = (0..48)
        .find(|&x| (0..48).all(|y| (0..48).all(|z| volume.voxel([x, y, z]) == 0)))
        .expect("an empty plane")
        .to_string();
    let args = [
        "slice",
        "shapes.vol",
        "--axis",
        "x",
        "--index",
        &empty,
        "-o",
        "flat.png",
    ];
    let out = raycaster(&args, d);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!(
            "every value 0, shown as in the volume's values 0 (black) to {hi} (white))"
        )),
        "{}",
        stderr(&out)
    );
    // Black, as empty space is in every other slice (it was a flat 128 grey).
    let image = RgbImage::load_png(&d.join("flat.png")).unwrap();
    assert!(image.data().iter().all(|&v| v == 0));
}

/// A scene object whose crop box lies beside the volume is refused naming it,
/// at whatever level the frame renders (a coarse level's margin let it pass);
/// one inside renders.
#[test]
fn a_scene_object_cropped_beside_the_volume_is_refused_at_every_level() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(
        &d.join("s.vol"),
        raycaster::synth::SceneKind::Shapes,
        96,
        1,
        raycaster::volume::Format::Extended,
    );
    let scene = |crop: &str| {
        format!(
            "layers = [[0.0, 0.5], [0.5, 1.0]]\n[[object]]\nname = \"low\"\n\
             [[object]]\nname = \"high\"\ncrop = {crop}\n"
        )
    };
    std::fs::write(d.join("beside.toml"), scene("[96, 0, 0, 200, 95, 95]")).unwrap();
    std::fs::write(d.join("inside.toml"), scene("[10, 0, 0, 60, 95, 95]")).unwrap();
    for level in ["0", "1"] {
        let args = |scene| {
            [
                "render",
                "s.vol",
                "--segments",
                scene,
                "--level",
                level,
                "--size",
                "32",
                "-o",
                "o.png",
                "--force",
            ]
        };
        let out = raycaster(&args("beside.toml"), d);
        assert!(!out.status.success(), "level {level}");
        let said = stderr(&out);
        assert!(
            said.contains("beside.toml: scene object \"high\"") && said.contains("outside"),
            "level {level}: {said}"
        );
        let out = raycaster(&args("inside.toml"), d);
        assert!(out.status.success(), "level {level}: {}", stderr(&out));
    }
}
