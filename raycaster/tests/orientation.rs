//! True orientation: the importers place voxels in the patient where the libraries
//! that wrote the fixtures say (nibabel, pynrrd, SimpleITK:
//! `volumes/fixtures/make_oriented_fixtures.py` and its `oriented.toml`), the
//! placement survives conversion to `.vol` (format version 4), and files without an
//! orientation stay without one.

use std::path::{Path, PathBuf};

use raycaster::convert::{ConvertOptions, convert};
use raycaster::import;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::volume::{Format, Layout, ORIENTED_HEADER_LEN, PatientSpace, Volume};

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
        assert_eq!(volume.voxel([5, 4, 3]), (5 + 40 + 150) % 256);
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
