//! True orientation: the importers place voxels in the patient where the libraries
//! that wrote the fixtures say (nibabel, pynrrd, SimpleITK:
//! `volumes/fixtures/make_oriented_fixtures.py` and its `oriented.toml`), the
//! placement survives conversion to `.vol` (format version 4), and files without an
//! orientation stay without one; a volume placed in the patient is shown upright,
//! in patient directions and not mirrored.

mod render_support;

use std::path::{Path, PathBuf};

use raycaster::convert::{ConvertOptions, convert};
use raycaster::import;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::render::{Mat3, Orbit, Vec3, patient_axes};
use raycaster::volume::{Format, Layout, ORIENTED_HEADER_LEN, Orientation, PatientSpace, Volume};
use render_support::{plain_settings, render, white_tf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/fixtures")
}

/// One fixture's expectations from `oriented.toml`.
struct Expected {
    name: String,
    space: PatientSpace,
    corners: Vec<[f64; 3]>,
    points: Vec<[f64; 3]>,
}

fn expectations() -> Vec<Expected> {
    let text = std::fs::read_to_string(fixtures().join("oriented.toml")).unwrap();
    let table: toml::Table = text.parse().unwrap();
    let triples = |v: &toml::Value| -> Vec<[f64; 3]> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|p| {
                let p = p.as_array().unwrap();
                std::array::from_fn(|i| {
                    p[i].as_float()
                        .or(p[i].as_integer().map(|n| n as f64))
                        .unwrap()
                })
            })
            .collect()
    };
    table
        .iter()
        .map(|(name, e)| Expected {
            name: name.clone(),
            space: PatientSpace::from_nrrd(e["space"].as_str().unwrap()).unwrap(),
            corners: triples(&e["corners"]),
            points: triples(&e["points"]),
        })
        .collect()
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-4)
}

fn convert_extended(input: &raycaster::io::Input, out: &Path, format: Format) {
    let options = ConvertOptions {
        layout: Layout::Bricked { side: 3 },
        sample_type: None,
        format,
        spacing: None,
        window: None,
        labels: false,
    };
    convert(
        input,
        out,
        &options,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
}

#[test]
fn corner_voxels_lie_where_nibabel_pynrrd_and_simpleitk_put_them() {
    let expected = expectations();
    assert_eq!(expected.len(), 5, "every oriented fixture is checked");
    let dir = tempfile::tempdir().unwrap();
    for e in &expected {
        let imported = import::open(&fixtures().join(&e.name)).unwrap();
        let placed = imported
            .orientation
            .clone()
            .unwrap_or_else(|| panic!("{}: no orientation read", e.name));
        for (corner, point) in e.corners.iter().zip(&e.points) {
            let want = e.space.to_lps_vector(*point);
            let got = placed.patient_position(imported.spacing, *corner);
            assert!(
                close(got, want),
                "{}: voxel {corner:?} at {got:?}, the writer says {want:?} (LPS)",
                e.name
            );
        }
        // The placement survives conversion, in a version 4 header; samples stay
        // where they were.
        let out = dir.path().join(format!("{}.vol", e.name));
        let input = imported.input(None, 1 << 20).unwrap();
        convert_extended(&input, &out, Format::Extended);
        let volume = Volume::open(&out).unwrap();
        assert_eq!(volume.orientation(), Some(&placed), "{}", e.name);
        assert_eq!(volume.spacing(), imported.spacing, "{}", e.name);
        assert_eq!(volume.header().data_offset, ORIENTED_HEADER_LEN);
        let memory = import::open_volume_any(&fixtures().join(&e.name), 1 << 20).unwrap();
        assert_eq!(memory.orientation(), Some(&placed), "{}", e.name);
        assert_eq!(volume.voxel([5, 4, 3]), 5 + 10 * 4 + 50 * 3); // below 256: no wrap
        // The thesis header has no room: the conversion drops the placement.
        let thesis = dir.path().join(format!("{}.thesis.vol", e.name));
        convert_extended(&input, &thesis, Format::Thesis);
        assert_eq!(Volume::open(&thesis).unwrap().orientation(), None);
    }
}

#[test]
fn files_without_an_orientation_stay_without_one() {
    let dir = tempfile::tempdir().unwrap();
    let imported = import::open(&fixtures().join("u8_raw.nrrd")).unwrap();
    assert_eq!(imported.orientation, None);
    let out = dir.path().join("plain.vol");
    convert_extended(
        &imported.input(None, 1 << 20).unwrap(),
        &out,
        Format::Extended,
    );
    let volume = Volume::open(&out).unwrap();
    assert_eq!(volume.orientation(), None);
    assert_eq!(volume.header().data_offset, 64);
}

/// Where the bright pixels of a frame are: their mean (x, y) in pixels.
fn bright_centroid(frame: &raycaster::render::Frame) -> [f32; 2] {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let (mut sum, mut n) = ([0.0f32; 2], 0.0f32);
    for y in 0..h {
        for x in 0..w {
            if frame.rgba[y * w + x][0] > 0.5 {
                sum[0] += x as f32;
                sum[1] += y as f32;
                n += 1.0;
            }
        }
    }
    assert!(n > 0.0, "nothing bright in the frame");
    [sum[0] / n, sum[1] / n]
}

#[test]
fn anatomy_stands_upright_in_patient_directions_and_is_not_mirrored() {
    // Voxel x grows towards the patient's right, y towards inferior, z towards
    // posterior: a rotated mirror image of LPS, as files often are.
    let orientation = Orientation {
        axes: [[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        origin: [0.0; 3],
    };
    assert!(orientation.is_mirrored());
    assert_eq!(orientation.axis_code(), "RIP");
    // A marker in the patient's upper left (superior: low y; left: low x).
    let marked =
        render_support::volume_u8(
            [16, 16, 16],
            [1.0; 3],
            |x, y, _| {
                if x < 4 && y < 4 { 255 } else { 0 }
            },
        );
    let header = marked
        .header()
        .clone()
        .with_orientation(Some(orientation.clone()));
    let mut samples = Vec::new();
    for x in 0..16 {
        for y in 0..16 {
            for z in 0..16 {
                samples.push(marked.voxel([x, y, z]) as u8);
            }
        }
    }
    let volume = Volume::from_samples("oriented", &header, &samples).unwrap();
    assert_eq!(volume.orientation(), Some(&orientation));
    let settings = plain_settings(white_tf(&[(0.0, 0.0), (0.8, 0.0), (1.0, 1.0)]));
    let (lo, hi) = (Vec3::ZERO, Vec3::splat(15.0));
    // From the front (azimuth −90° in patient axes), level.
    let front = |axes: Mat3| {
        let orbit = Orbit::framing(lo, hi, (-90f32).to_radians(), 0.0, None).with_axes(axes);
        bright_centroid(&render(&volume, &orbit.camera(64, 64).unwrap(), &settings))
    };
    let [x, y] = front(patient_axes(volume.orientation()));
    // Facing the patient: their left on the image's right, superior at the top.
    assert!(x > 40.0 && y < 24.0, "marker at ({x}, {y}), not top right");
    // The volume's own axes put it elsewhere: the test can fail.
    let [x, y] = front(Mat3::IDENTITY);
    assert!(!(x > 40.0 && y < 24.0), "voxel axes give ({x}, {y})");
    // A session stores the axes; a mirrored camera stays mirrored when resized.
    let orbit =
        Orbit::framing(lo, hi, -1.0, 0.2, Some(30.0)).with_axes(patient_axes(volume.orientation()));
    let camera = orbit.camera(32, 32).unwrap();
    let resized = camera.with_size(64, 48).unwrap();
    assert!(camera.right().dot(resized.right()) > 0.999);
}
