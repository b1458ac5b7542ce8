//! Round trips through the `.vol` format: every layout and sample type, the thesis's
//! exact byte layout, edge bricks, mapped vs RAM, and lossless conversions.

use std::path::{Path, PathBuf};

use raycaster::convert::{ConvertOptions, ValueMap, convert};
use raycaster::generate::generate;
use raycaster::io::{Endian, Input, RawOrder, RawSpec, RawType, WriteOptions, write_volume};
use raycaster::job::Job;
use raycaster::synth::SceneKind;
use raycaster::volume::{
    Access, BlockGrid, Content, Format, Header, Layout, OpenOptions, SampleType, Volume,
    VolumeData, VolumeErrorKind, ranges_sidecar_path,
};

/// A value that differs for every voxel of small volumes and is easy to recompute.
fn pattern(v: [u32; 3], max: u32) -> u16 {
    ((v[0] * 7919 + v[1] * 104_729 + v[2] * 31 + 11) % (max + 1)) as u16
}

/// A scalar header with unit spacing.
fn unit_header(dims: [u32; 3], layout: Layout, sample_type: SampleType, format: Format) -> Header {
    Header::new(dims, [1.0; 3], layout, sample_type, Content::Scalar, format)
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Writes the pattern with our writer.
fn write_pattern(path: &Path, header: &Header) {
    let [_, dy, dz] = header.dims;
    let max = u32::from(header.sample_type.max_value());
    let fill_value = |x0: u32, i: usize| {
        let plane = (dy * dz) as usize;
        let x = x0 + (i / plane) as u32;
        let y = ((i % plane) / dz as usize) as u32;
        let z = (i % dz as usize) as u32;
        pattern([x, y, z], max)
    };
    let options = WriteOptions {
        overwrite: false,
        // Small slabs: several slabs per file, so slab seams are exercised.
        slab_bytes: 4096,
        pyramid: true,
    };
    match header.sample_type {
        SampleType::U8 => write_volume::<u8>(path, header, &options, &Job::silent(), |x0, _, s| {
            for (i, o) in s.iter_mut().enumerate() {
                *o = fill_value(x0, i) as u8;
            }
            Ok(())
        }),
        SampleType::U16 => {
            write_volume::<u16>(path, header, &options, &Job::silent(), |x0, _, s| {
                for (i, o) in s.iter_mut().enumerate() {
                    *o = fill_value(x0, i);
                }
                Ok(())
            })
        }
    }
    .unwrap();
}

fn assert_pattern(volume: &Volume) {
    let [dx, dy, dz] = volume.dims();
    let max = u32::from(volume.sample_type().max_value());
    for x in 0..dx {
        for y in 0..dy {
            for z in 0..dz {
                assert_eq!(
                    volume.voxel([x, y, z]),
                    pattern([x, y, z], max),
                    "at {x},{y},{z}"
                );
            }
        }
    }
}

#[test]
fn every_layout_and_sample_type_round_trips_mapped_and_in_ram() {
    let dir = tmp();
    let dims = [19, 8, 13]; // no axis a multiple of any brick step below
    for format in [Format::Thesis, Format::Extended] {
        for st in [SampleType::U8, SampleType::U16] {
            if format == Format::Thesis && st == SampleType::U16 {
                continue;
            }
            for layout in [
                Layout::Linear,
                Layout::Bricked { side: 2 },
                Layout::Bricked { side: 4 },
                Layout::Bricked { side: 7 },
                Layout::Bricked { side: 32 },
            ] {
                let name =
                    format!("{format:?}-{st:?}-{layout:?}.vol").replace([' ', '{', '}', ':'], "");
                let path = dir.path().join(name);
                let header =
                    Header::new(dims, [0.5, 1.0, 2.5], layout, st, Content::Scalar, format);
                write_pattern(&path, &header);
                for access in [Access::Mapped, Access::Ram] {
                    let options = OpenOptions {
                        access,
                        ..OpenOptions::default()
                    };
                    let v = Volume::open_with(&path, options).unwrap();
                    assert_eq!(v.access(), access);
                    assert_eq!(v.header().dims, dims);
                    assert_eq!(v.header().spacing, [0.5, 1.0, 2.5]);
                    assert_eq!(v.layout(), layout);
                    assert_eq!(v.sample_type(), st);
                    assert_eq!(v.header().format, format);
                    assert_pattern(&v);
                    assert_eq!(v.ranges(), &v.compute_ranges(), "stored ranges are exact");
                    assert_eq!(v.unused_tail(), None, "the file ends with its last block");
                }
            }
        }
    }
}

#[test]
fn bytes_appended_after_the_last_block_are_reported_and_ignored() {
    let dir = tmp();
    // Large enough for a resolution pyramid (the file's last block); the
    // thesis file ends with its samples, the small extended one with its
    // range table.
    let cases = [
        (
            [80, 72, 66],
            Format::Extended,
            Layout::Bricked { side: 16 },
            2,
        ),
        ([80, 72, 66], Format::Extended, Layout::Linear, 2),
        (
            [19, 8, 13],
            Format::Extended,
            Layout::Bricked { side: 4 },
            1,
        ),
        ([19, 8, 13], Format::Thesis, Layout::Bricked { side: 4 }, 1),
    ];
    for (dims, format, layout, levels) in cases {
        let path = dir
            .path()
            .join(format!("tail-{format:?}-{}-{}.vol", dims[0], layout).replace(' ', ""));
        let header = unit_header(dims, layout, SampleType::U8, format);
        write_pattern(&path, &header);
        let len = std::fs::metadata(&path).unwrap().len();
        let v = Volume::open(&path).unwrap();
        assert_eq!(v.level_count(), levels, "{path:?}");
        assert_eq!(v.unused_tail(), None, "{path:?}");
        assert_eq!(v.unused_tail_warning(), None);
        drop(v);
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .unwrap();
        std::io::Write::write_all(&mut f, &[0xA5; 1000]).unwrap();
        drop(f);
        let v = Volume::open(&path).unwrap();
        assert_eq!(v.unused_tail(), Some((len, 1000)), "{path:?}");
        let warning = v.unused_tail_warning().unwrap();
        assert!(
            warning.contains("1000 bytes after its last block (from byte"),
            "{warning}"
        );
        assert_eq!(v.level_count(), levels, "the file still opens whole");
        assert_pattern(&v);
    }
}

/// The thesis's bricked layout written by the most literal reading of its description
/// (seed digest): bricks bz fastest, then by, then bx; inside a brick z fastest; every
/// brick stored whole; padding left as the generator's values (here: the pattern
/// continued past the edge).
fn thesis_bricked_bytes(dims: [u32; 3], side: u32, spacing: [f32; 3]) -> Vec<u8> {
    let mut out = Vec::new();
    for d in dims {
        out.extend_from_slice(&d.to_le_bytes());
    }
    for s in spacing {
        out.extend_from_slice(&s.to_le_bytes());
    }
    out.push(2);
    out.push(side as u8);
    let n = dims.map(|d| (d - 1).div_ceil(side - 1));
    for bx in 0..n[0] {
        for by in 0..n[1] {
            for bz in 0..n[2] {
                for lx in 0..side {
                    for ly in 0..side {
                        for lz in 0..side {
                            let v = [
                                bx * (side - 1) + lx,
                                by * (side - 1) + ly,
                                bz * (side - 1) + lz,
                            ];
                            out.push(pattern(v, 255) as u8);
                        }
                    }
                }
            }
        }
    }
    out
}

#[test]
fn a_file_in_the_thesis_layout_reads_back_sample_exact() {
    let dir = tmp();
    let dims = [33, 17, 20];
    let bytes = thesis_bricked_bytes(dims, 16, [1.0, 1.0, 1.0]);
    // 3 × 2 × 2 bricks of 16³ after the 26-byte header.
    assert_eq!(bytes.len(), 26 + 12 * 4096);
    let path = dir.path().join("thesis.vol");
    std::fs::write(&path, &bytes).unwrap();
    let v = Volume::open(&path).unwrap();
    assert_eq!(v.header().format, Format::Thesis);
    assert_eq!(v.layout(), Layout::Bricked { side: 16 });
    assert_pattern(&v);
    // The ranges were cached beside the file and a second open uses them.
    assert!(ranges_sidecar_path(&path).exists());
    let again = Volume::open(&path).unwrap();
    assert_eq!(again.ranges(), v.ranges());
}

#[test]
fn thesis_format_is_written_bit_compatibly() {
    let dir = tmp();
    let dims = [33, 17, 20];
    let path = dir.path().join("ours.vol");
    let header = unit_header(
        dims,
        Layout::Bricked { side: 16 },
        SampleType::U8,
        Format::Thesis,
    );
    write_pattern(&path, &header);
    let ours = std::fs::read(&path).unwrap();
    let thesis = thesis_bricked_bytes(dims, 16, [1.0; 3]);
    assert_eq!(ours.len(), thesis.len());
    assert_eq!(ours[..26], thesis[..26], "header bytes");
    // Inside the volume every byte matches; padding past the edge repeats the edge
    // voxel in our files and is unspecified in the thesis's.
    let v = Volume::open(&path).unwrap();
    let VolumeData::U8(data) = v.data() else {
        panic!("u8 expected")
    };
    let grid = BlockGrid::new(dims, 16);
    for b in grid.iter() {
        let brick = data.brick(&grid, b);
        let e = brick.extent();
        for lx in 0..16u32 {
            for ly in 0..16u32 {
                for lz in 0..16u32 {
                    let at =
                        26 + grid.index(b) as usize * 4096 + ((lx * 16 + ly) * 16 + lz) as usize;
                    if lx < e[0] && ly < e[1] && lz < e[2] {
                        assert_eq!(ours[at], thesis[at], "brick {b:?} local {lx},{ly},{lz}");
                    } else {
                        let clamp = [lx.min(e[0] - 1), ly.min(e[1] - 1), lz.min(e[2] - 1)];
                        assert_eq!(ours[at], brick.get(clamp), "padding repeats the edge");
                    }
                }
            }
        }
    }
}

#[test]
fn edge_bricks_and_brick_views_address_locally() {
    let dir = tmp();
    let dims = [20, 9, 31];
    let path = dir.path().join("edge.vol");
    let header = unit_header(
        dims,
        Layout::Bricked { side: 8 },
        SampleType::U16,
        Format::Extended,
    );
    write_pattern(&path, &header);
    let v = Volume::open(&path).unwrap();
    let VolumeData::U16(data) = v.data() else {
        panic!("u16 expected")
    };
    let grid = data.natural_grid(16);
    assert_eq!(grid.counts(), [3, 2, 5]);
    let mut covered = vec![false; 20 * 9 * 31];
    for b in grid.iter() {
        let brick = data.brick(&grid, b);
        let (o, e) = (brick.origin(), brick.extent());
        for lx in 0..e[0] {
            for ly in 0..e[1] {
                for lz in 0..e[2] {
                    let g = [o[0] + lx, o[1] + ly, o[2] + lz];
                    assert_eq!(brick.get([lx, ly, lz]), pattern(g, 65535));
                    covered[((g[0] * 9 + g[1]) * 31 + g[2]) as usize] = true;
                }
            }
        }
    }
    assert!(covered.iter().all(|&c| c), "bricks cover every voxel");
    // The last brick on x holds voxels 14..=19: six, not eight.
    assert_eq!(data.brick(&grid, [2, 0, 0]).extent(), [6, 8, 8]);
}

#[test]
fn linear_volumes_give_logical_bricks_of_any_side() {
    let dir = tmp();
    let dims = [11, 12, 13];
    let path = dir.path().join("lin.vol");
    let header = unit_header(dims, Layout::Linear, SampleType::U8, Format::Extended);
    write_pattern(&path, &header);
    let v = Volume::open(&path).unwrap();
    let VolumeData::U8(data) = v.data() else {
        panic!()
    };
    for side in [2, 5, 16] {
        let grid = BlockGrid::new(dims, side);
        for b in grid.iter() {
            let brick = data.brick(&grid, b);
            let o = brick.origin();
            let e = brick.extent();
            let last = [e[0] - 1, e[1] - 1, e[2] - 1];
            let g = [o[0] + last[0], o[1] + last[1], o[2] + last[2]];
            assert_eq!(u16::from(brick.get(last)), pattern(g, 255));
        }
    }
}

fn raw_file(
    dir: &Path,
    dims: [u32; 3],
    ty: RawType,
    endian: Endian,
    order: RawOrder,
    skip: usize,
) -> PathBuf {
    let max = match ty {
        RawType::U8 => 255,
        _ => 65535,
    };
    let mut bytes = vec![0xEEu8; skip];
    let mut push = |v: [u32; 3]| {
        let value = pattern(v, max);
        match (ty, endian) {
            (RawType::U8, _) => bytes.push(value as u8),
            (RawType::U16, Endian::Little) => bytes.extend_from_slice(&value.to_le_bytes()),
            (RawType::U16, Endian::Big) => bytes.extend_from_slice(&value.to_be_bytes()),
            _ => unreachable!(),
        }
    };
    let [dx, dy, dz] = dims;
    match order {
        RawOrder::XFastest => {
            (0..dz).for_each(|z| (0..dy).for_each(|y| (0..dx).for_each(|x| push([x, y, z]))))
        }
        RawOrder::ZFastest => {
            (0..dx).for_each(|x| (0..dy).for_each(|y| (0..dz).for_each(|z| push([x, y, z]))))
        }
    }
    let path = dir.join(format!("in-{ty:?}-{endian:?}-{order:?}.raw"));
    std::fs::write(&path, bytes).unwrap();
    path
}

fn convert_to(
    input: &Input,
    out: &Path,
    layout: Layout,
    sample_type: Option<SampleType>,
) -> Volume {
    let options = ConvertOptions {
        layout,
        sample_type,
        format: Format::Extended,
        spacing: None,
        window: None,
        labels: false,
    };
    let write = WriteOptions {
        overwrite: false,
        slab_bytes: 2048,
        pyramid: true,
    };
    convert(input, out, &options, &write, &Job::silent()).unwrap();
    Volume::open(out).unwrap()
}

#[test]
fn raw_to_bricked_to_linear_is_lossless_for_u8_and_u16() {
    let dir = tmp();
    let dims = [23, 10, 17];
    for (ty, endian) in [
        (RawType::U8, Endian::Little),
        (RawType::U16, Endian::Little),
        (RawType::U16, Endian::Big),
    ] {
        for order in [RawOrder::XFastest, RawOrder::ZFastest] {
            let raw = raw_file(dir.path(), dims, ty, endian, order, 5);
            let spec = RawSpec {
                dims,
                sample: ty,
                endian,
                skip: 5,
                order,
            };
            let input = Input::open_raw(&raw, spec).unwrap();
            let tag = format!("{ty:?}{endian:?}{order:?}");
            let bricked = dir.path().join(format!("{tag}-b.vol"));
            let v = convert_to(&input, &bricked, Layout::Bricked { side: 6 }, None);
            assert_pattern(&v);
            let linear = dir.path().join(format!("{tag}-l.vol"));
            let v2 = convert_to(
                &Input::open_vol(&bricked).unwrap(),
                &linear,
                Layout::Linear,
                None,
            );
            assert_eq!(v2.layout(), Layout::Linear);
            assert_pattern(&v2);
            // And back to bricks of another side, through the bricked reader again.
            let rebricked = dir.path().join(format!("{tag}-b2.vol"));
            let v3 = convert_to(
                &Input::open_vol(&bricked).unwrap(),
                &rebricked,
                Layout::Bricked { side: 9 },
                None,
            );
            assert_pattern(&v3);
        }
    }
}

#[test]
fn windowing_maps_the_window_onto_the_full_u8_range() {
    let dir = tmp();
    let dims = [4, 3, 2];
    let values: Vec<i16> = (0..24).map(|i| i * 100 - 1000).collect();
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let raw = dir.path().join("ct.raw");
    std::fs::write(&raw, bytes).unwrap();
    let spec = RawSpec {
        dims,
        sample: RawType::I16,
        endian: Endian::Little,
        skip: 0,
        order: RawOrder::XFastest,
    };
    let input = Input::open_raw(&raw, spec).unwrap();
    let out = dir.path().join("ct.vol");
    let options = ConvertOptions {
        layout: Layout::Linear,
        sample_type: Some(SampleType::U8),
        format: Format::Extended,
        spacing: Some([0.5, 0.5, 3.0]),
        window: Some((-1000.0, 1300.0)),
        labels: false,
    };
    let done = convert(
        &input,
        &out,
        &options,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    assert_eq!(done.values, ValueMap::Window(-1000.0, 1300.0));
    let v = Volume::open(&out).unwrap();
    assert_eq!(v.spacing(), [0.5, 0.5, 3.0]);
    // x fastest in the raw file: value index i = (z*3 + y)*4 + x.
    for (x, y, z) in [(0, 0, 0), (3, 2, 1), (2, 1, 1)] {
        let i = (z * 3 + y) * 4 + x;
        let t = ((f32::from(values[i as usize]) + 1000.0) / 2300.0).clamp(0.0, 1.0);
        assert_eq!(
            v.voxel([x, y, z]),
            (t * 255.0 + 0.5) as u16,
            "at {x},{y},{z}"
        );
    }
    // Without a window the input's own range is used: its extremes map to 0 and 255.
    let out2 = dir.path().join("ct2.vol");
    let auto = ConvertOptions {
        window: None,
        labels: false,
        ..options
    };
    let done = convert(
        &input,
        &out2,
        &auto,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    assert_eq!(done.values, ValueMap::Window(-1000.0, 1300.0));
    let v = Volume::open(&out2).unwrap();
    assert_eq!(v.voxel([0, 0, 0]), 0);
    assert_eq!(v.voxel([3, 2, 1]), 255);
}

#[test]
fn same_seed_gives_identical_files_and_another_seed_does_not() {
    let dir = tmp();
    let header = Header::new(
        [40, 33, 27],
        [1.0; 3],
        Layout::Bricked { side: 8 },
        SampleType::U16,
        Content::Scalar,
        Format::Extended,
    );
    for kind in SceneKind::ALL {
        let mut files = Vec::new();
        for (i, seed) in [5u64, 5, 6].iter().enumerate() {
            let path = dir.path().join(format!("{}-{i}.vol", kind.name()));
            let scene = kind.build(header.dims, *seed);
            generate(
                scene.as_ref(),
                &header,
                &path,
                &WriteOptions::default(),
                &Job::silent(),
            )
            .unwrap();
            files.push(std::fs::read(&path).unwrap());
        }
        assert_eq!(files[0], files[1], "{} is deterministic", kind.name());
        if matches!(kind, SceneKind::Shapes | SceneKind::Noise) {
            assert_ne!(files[0], files[2], "{} depends on the seed", kind.name());
        }
    }
}

#[test]
fn gradient_scene_is_an_exact_ramp_and_shells_labels_match_values() {
    let dir = tmp();
    let dims = [52, 6, 40];
    let mut header = unit_header(
        dims,
        Layout::Bricked { side: 16 },
        SampleType::U8,
        Format::Extended,
    );
    let ramp = dir.path().join("ramp.vol");
    generate(
        SceneKind::Gradient.build(dims, 0).as_ref(),
        &header,
        &ramp,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    let v = Volume::open(&ramp).unwrap();
    for x in 0..dims[0] {
        let expected = (x as f32 / 51.0 * 255.0 + 0.5) as u16;
        assert_eq!(v.voxel([x, 3, 17]), expected);
    }

    let shells = SceneKind::Shells.build([48; 3], 0);
    header.dims = [48; 3];
    let values = dir.path().join("shells.vol");
    generate(
        shells.as_ref(),
        &header,
        &values,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    header.content = Content::Labels;
    let labels = dir.path().join("shells.labels.vol");
    generate(
        shells.as_ref(),
        &header,
        &labels,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    let (v, l) = (
        Volume::open(&values).unwrap(),
        Volume::open(&labels).unwrap(),
    );
    assert_eq!(l.content(), Content::Labels);
    let mut seen = [false; 5];
    for x in 0..48 {
        for y in 0..48 {
            for z in 0..48 {
                let (value, label) = (v.voxel([x, y, z]), l.voxel([x, y, z]));
                seen[label as usize] = true;
                // Each shell's values lie in its own band; background is 0.
                let band = [(0, 0), (25, 52), (89, 115), (153, 179), (216, 243)][label as usize];
                assert!(
                    value >= band.0 && value <= band.1,
                    "label {label} value {value}"
                );
            }
        }
    }
    assert!(seen.iter().all(|&s| s), "every shell is present");
}

#[test]
fn existing_output_is_kept_without_overwrite_and_nothing_partial_is_left() {
    let dir = tmp();
    let path = dir.path().join("keep.vol");
    std::fs::write(&path, b"precious").unwrap();
    let header = unit_header([8; 3], Layout::Linear, SampleType::U8, Format::Extended);
    let scene = SceneKind::Gradient.build([8; 3], 0);
    let err = generate(
        scene.as_ref(),
        &header,
        &path,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap_err();
    assert!(matches!(err.kind, VolumeErrorKind::Exists));
    assert_eq!(std::fs::read(&path).unwrap(), b"precious");

    // A cancelled job leaves neither the output nor a temporary file.
    let flag = std::sync::atomic::AtomicBool::new(true);
    let out = dir.path().join("cancelled.vol");
    let job = Job::silent().with_cancel(&flag);
    let err = generate(
        scene.as_ref(),
        &header,
        &out,
        &WriteOptions::default(),
        &job,
    )
    .unwrap_err();
    assert!(matches!(err.kind, VolumeErrorKind::Cancelled));
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("keep.vol")]);

    // Overwrite replaces it whole.
    let options = WriteOptions {
        overwrite: true,
        ..WriteOptions::default()
    };
    generate(scene.as_ref(), &header, &path, &options, &Job::silent()).unwrap();
    assert_eq!(Volume::open(&path).unwrap().dims(), [8; 3]);
}

#[test]
fn converting_a_file_onto_itself_is_refused() {
    let dir = tmp();
    let path = dir.path().join("self.vol");
    let header = unit_header([8; 3], Layout::Linear, SampleType::U8, Format::Extended);
    generate(
        SceneKind::Gradient.build([8; 3], 0).as_ref(),
        &header,
        &path,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    let before = std::fs::read(&path).unwrap();
    let input = Input::open_vol(&path).unwrap();
    let options = ConvertOptions {
        layout: Layout::Linear,
        sample_type: None,
        format: Format::Extended,
        spacing: None,
        window: None,
        labels: false,
    };
    let write = WriteOptions {
        overwrite: true,
        ..WriteOptions::default()
    };
    let err = convert(&input, &path, &options, &write, &Job::silent()).unwrap_err();
    assert!(matches!(err.kind, VolumeErrorKind::SameFile));
    assert_eq!(std::fs::read(&path).unwrap(), before);
}

#[test]
fn raw_size_mismatch_names_the_file_and_the_sizes() {
    let dir = tmp();
    let raw = dir.path().join("short.raw");
    std::fs::write(&raw, vec![0u8; 999]).unwrap();
    let spec = RawSpec {
        dims: [10; 3],
        sample: RawType::U8,
        endian: Endian::Little,
        skip: 0,
        order: RawOrder::XFastest,
    };
    let err = Input::open_raw(&raw, spec).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("short.raw")
            && msg.contains(
                "the file holds 999 bytes, fewer than its 1000 bytes of samples (10x10x10 u8)"
            ),
        "{msg}"
    );
    // Longer: said as longer, with the skip that reads the samples at the end
    // (it read like a shortfall, "file has 1062 bytes but ... need 1000").
    let long = dir.path().join("long.raw");
    std::fs::write(&long, vec![0u8; 1062]).unwrap();
    let msg = Input::open_raw(&long, spec).unwrap_err().to_string();
    assert!(
        msg.contains(
            "the file holds 62 bytes more than its 1000 bytes of samples (10x10x10 u8; a header before them? a skip of 62 skips it)"
        ),
        "{msg}"
    );
    let skipped = RawSpec { skip: 62, ..spec };
    assert!(Input::open_raw(&long, skipped).is_ok());
}

/// A `.vol` input cut by another program while it is converted: said as such,
/// with the sizes (it said "failed to fill whole buffer").
#[test]
fn an_input_cut_while_it_is_read_says_it_shrank() {
    let dir = tmp();
    let path = dir.path().join("cut.vol");
    let header = unit_header([16; 3], Layout::Linear, SampleType::U8, Format::Extended);
    write_pattern(&path, &header);
    let input = Input::open_vol(&path).unwrap();
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(header.data_offset + 100).unwrap();
    let mut slab = vec![0u8; 16 * 16 * 16];
    let e = input
        .read_slab(0, 16, &|v: f32| v as u8, &mut slab)
        .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("cut.vol")
            && text.contains(&format!(
                "shrank to {} bytes while it was read",
                header.data_offset + 100
            ))
            && text.contains("another program truncated it"),
        "{text}"
    );
}
