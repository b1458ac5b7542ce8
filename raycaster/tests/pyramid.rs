//! The resolution pyramid and out-of-core opening: levels against an independent
//! box filter, renders of a level against a separately reduced volume, interrupted
//! writes, old files, corrupt or stale pyramids, and that opening reads nothing.

mod render_support;

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use raycaster::io::{WriteOptions, write_volume};
use raycaster::job::Job;
use raycaster::render::{
    LevelChoice, ParallelOptions, RenderVolume, Vec3, render_parallel, render_sequential,
};
use raycaster::volume::{
    CellShape, Content, Format, Header, Layout, SampleType, Volume, VolumeErrorKind,
    pyramid_sidecar_path, write_pyramid_sidecar,
};
use render_support::{assert_images_match, default_camera, scene_preset};
use tempfile::TempDir;

const DIMS: [u32; 3] = [150, 97, 70];

/// Deterministic structured values: a few spheres over a ramp, plus noise.
fn pattern(dims: [u32; 3], max: u16, labels: bool) -> Vec<u16> {
    let mut out = Vec::with_capacity(dims.iter().product::<u32>() as usize);
    for x in 0..dims[0] {
        for y in 0..dims[1] {
            for z in 0..dims[2] {
                let d = |c: [f32; 3]| {
                    ((x as f32 - c[0]).powi(2)
                        + (y as f32 - c[1]).powi(2)
                        + (z as f32 - c[2]).powi(2))
                    .sqrt()
                };
                let noise = (x.wrapping_mul(73_856_093)
                    ^ y.wrapping_mul(19_349_663)
                    ^ z.wrapping_mul(83_492_791))
                    % 7;
                let v = if labels {
                    if d([40.0, 40.0, 30.0]) < 25.0 {
                        1
                    } else if d([110.0, 60.0, 40.0]) < 20.0 {
                        3
                    } else {
                        0
                    }
                } else if d([40.0, 40.0, 30.0]) < 25.0 {
                    max / 2 + noise as u16 * 3
                } else if d([110.0, 60.0, 40.0]) < 20.0 {
                    max - noise as u16
                } else {
                    (x * u32::from(max) / (dims[0] * 4)) as u16 + noise as u16
                };
                out.push(v.min(max));
            }
        }
    }
    out
}

/// The level below `src` computed voxel by voxel: the rounded mean of the 2×2×2
/// block at twice the coordinates, indices clamped; for labels the most frequent
/// id of the block (the largest of ids as frequent).
fn reduce_reference(src: &[u16], dims: [u32; 3], labels: bool) -> (Vec<u16>, [u32; 3]) {
    let out_dims = dims.map(|d| d.div_ceil(2));
    let at = |x: u32, y: u32, z: u32| {
        src[((x.min(dims[0] - 1) * dims[1] + y.min(dims[1] - 1)) * dims[2] + z.min(dims[2] - 1))
            as usize]
    };
    let mut out = Vec::new();
    for x in 0..out_dims[0] {
        for y in 0..out_dims[1] {
            for z in 0..out_dims[2] {
                let block: Vec<u16> = (0..8)
                    .map(|i| at(2 * x + (i & 1), 2 * y + ((i >> 1) & 1), 2 * z + (i >> 2)))
                    .collect();
                out.push(if labels {
                    // The most frequent id; of ids as frequent, the largest.
                    let count = |id: u16| block.iter().filter(|&&v| v == id).count();
                    *block.iter().max_by_key(|&&id| (count(id), id)).unwrap()
                } else {
                    ((block.iter().map(|&v| u32::from(v)).sum::<u32>() + 4) / 8) as u16
                });
            }
        }
    }
    (out, out_dims)
}

fn write(
    path: &Path,
    header: &Header,
    values: &[u16],
    options: &WriteOptions,
    job: &Job,
) -> Result<(), raycaster::volume::VolumeError> {
    let plane = (header.dims[1] * header.dims[2]) as usize;
    match header.sample_type {
        SampleType::U8 => write_volume::<u8>(path, header, options, job, |x0, x1, slab| {
            let src = &values[x0 as usize * plane..x1 as usize * plane];
            for (o, &v) in slab.iter_mut().zip(src) {
                *o = v as u8;
            }
            Ok(())
        }),
        SampleType::U16 => write_volume::<u16>(path, header, options, job, |x0, x1, slab| {
            slab.copy_from_slice(&values[x0 as usize * plane..x1 as usize * plane]);
            Ok(())
        }),
    }
    .map(|_| ())
}

/// A u8 scalar volume of [`DIMS`] and unit spacing.
fn u8_header(layout: Layout, format: Format) -> Header {
    Header::new(
        DIMS,
        [1.0; 3],
        layout,
        SampleType::U8,
        Content::Scalar,
        format,
    )
}

fn small_slabs() -> WriteOptions {
    WriteOptions {
        overwrite: true,
        slab_bytes: 64 << 10,
        pyramid: true,
    }
}

/// A first render's fitted domain (the 0.5th..99.5th percentile of u16
/// values) is the same for a file with a pyramid and for its samples in
/// memory without one (a scan opened directly, then converted): a small
/// volume is counted at full resolution, not on the coarsest level, whose
/// averaged values have narrower tails (the two pictures were up to 87/255
/// apart on an MR scan).
#[test]
fn a_volume_fits_one_domain_with_and_without_its_pyramid() {
    let dir = TempDir::new().unwrap();
    let header = Header::new(
        DIMS,
        [1.0; 3],
        Layout::Bricked { side: 16 },
        SampleType::U16,
        Content::Scalar,
        Format::Extended,
    );
    let values = pattern(DIMS, 4000, false);
    let path = dir.path().join("p.vol");
    write(
        &path,
        &header,
        &values,
        &WriteOptions::default(),
        &Job::silent(),
    )
    .unwrap();
    let file = Volume::open(&path).unwrap();
    assert!(file.level_count() > 1, "the file has a pyramid");
    let linear = Header {
        layout: Layout::Linear,
        ..header.clone()
    };
    let memory = Volume::from_samples("p.raw", &linear, &values).unwrap();
    assert_eq!(memory.level_count(), 1);
    let (a, b) = (
        raycaster::windows::fit(&file).domain,
        raycaster::windows::fit(&memory).domain,
    );
    assert!(a.is_some() && a == b, "{a:?} {b:?}");
}

#[test]
fn every_level_equals_an_independent_box_filter_or_maximum() {
    let dir = TempDir::new().unwrap();
    let cases = [
        (
            Format::Extended,
            Layout::Bricked { side: 16 },
            SampleType::U8,
            Content::Scalar,
        ),
        (
            Format::Extended,
            Layout::Linear,
            SampleType::U16,
            Content::Scalar,
        ),
        (
            Format::Thesis,
            Layout::Bricked { side: 9 },
            SampleType::U8,
            Content::Scalar,
        ),
        (
            Format::Thesis,
            Layout::Linear,
            SampleType::U8,
            Content::Scalar,
        ),
        (
            Format::Extended,
            Layout::Bricked { side: 16 },
            SampleType::U8,
            Content::Labels,
        ),
    ];
    for (i, (format, layout, ty, content)) in cases.into_iter().enumerate() {
        let labels = content == Content::Labels;
        let header = Header::new(DIMS, [1.0, 0.5, 2.0], layout, ty, content, format);
        let values = pattern(DIMS, ty.max_value(), labels);
        let path = dir.path().join(format!("case{i}.vol"));
        write(&path, &header, &values, &small_slabs(), &Job::silent()).unwrap();
        let volume = Volume::open(&path).unwrap();
        assert_eq!(volume.level_count(), 3, "case {i}");
        assert_eq!(
            pyramid_sidecar_path(&path).exists(),
            format == Format::Thesis,
            "case {i}: thesis files keep the pyramid in a sidecar"
        );
        let (mut reference, mut dims) = (values, DIMS);
        for k in 1..volume.level_count() {
            (reference, dims) = reduce_reference(&reference, dims, labels);
            let level = volume.level(k);
            assert_eq!(level.dims(), dims, "case {i} level {k}");
            assert_eq!(level.level_index(), k as u32);
            let scale = (1 << k) as f32;
            assert_eq!(level.spacing(), [scale, 0.5 * scale, 2.0 * scale]);
            let mut n = 0;
            for x in 0..dims[0] {
                for y in 0..dims[1] {
                    for z in 0..dims[2] {
                        assert_eq!(
                            level.voxel([x, y, z]),
                            reference[n],
                            "case {i} level {k} voxel {x},{y},{z}"
                        );
                        n += 1;
                    }
                }
            }
            assert_eq!(
                level.ranges(),
                &level.compute_ranges(),
                "case {i} level {k} ranges"
            );
        }
    }
}

#[test]
fn a_render_at_level_k_equals_the_render_of_a_separately_reduced_volume() {
    let dir = TempDir::new().unwrap();
    let header = u8_header(Layout::Bricked { side: 16 }, Format::Extended);
    let values = pattern(DIMS, 255, false);
    let path = dir.path().join("a.vol");
    write(&path, &header, &values, &small_slabs(), &Job::silent()).unwrap();
    let volume = Volume::open(&path).unwrap();
    let camera = default_camera(&volume, 96);
    let mut settings = raycaster::render::RenderSettings {
        transfer: scene_preset(raycaster::synth::SceneKind::Shapes),
        ..Default::default()
    };
    settings.transfer.domain = Some([0.0, 255.0]);
    let (mut reference, mut dims) = (values, DIMS);
    for k in 1..volume.level_count() {
        (reference, dims) = reduce_reference(&reference, dims, false);
        let scale = (1 << k) as f32;
        let h = Header::new(
            dims,
            [scale; 3],
            Layout::Linear,
            SampleType::U8,
            Content::Scalar,
            Format::Extended,
        );
        let bytes: Vec<u8> = reference.iter().map(|&v| v as u8).collect();
        let separate = Volume::from_samples("separate", &h, &bytes)
            .unwrap()
            .placed_as_level(k as u32, volume.dims());
        assert_eq!(separate.origin(), volume.level(k).origin());
        let expected = RenderVolume::new(&separate, Some(16)).unwrap();
        let actual = RenderVolume::new(volume.level(k), Some(16)).unwrap();
        let want = render_sequential(&expected, &camera, &settings).unwrap();
        let got = render_sequential(&actual, &camera, &settings).unwrap();
        assert!(got.stats.counters.samples > 0);
        assert_eq!(got.stats.counters.samples, want.stats.counters.samples);
        assert_images_match(
            &format!("pyramid-level{k}"),
            &got.to_image(),
            &want.to_image(),
            0,
        );
        let parallel =
            render_parallel(&actual, &camera, &settings, &ParallelOptions::default()).unwrap();
        assert_images_match(
            &format!("pyramid-level{k}-parallel"),
            &parallel.to_image(),
            &want.to_image(),
            1,
        );
        assert_eq!(parallel.stats.counters.samples, want.stats.counters.samples);
    }
    // Coarser levels take fewer samples for the same picture size.
    let full = render_sequential(
        &RenderVolume::new(&volume, None).unwrap(),
        &camera,
        &settings,
    )
    .unwrap();
    let coarse = render_sequential(
        &RenderVolume::new(volume.level(1), None).unwrap(),
        &camera,
        &settings,
    )
    .unwrap();
    assert!(coarse.stats.counters.samples * 3 < full.stats.counters.samples * 2);
}

#[test]
fn an_interrupted_pyramid_write_leaves_no_file() {
    let dir = TempDir::new().unwrap();
    let level0: u64 = DIMS.iter().map(|&d| u64::from(d)).product();
    for format in [Format::Extended, Format::Thesis] {
        let header = u8_header(Layout::Bricked { side: 16 }, format);
        let values = pattern(DIMS, 255, false);
        let path = dir.path().join("cut.vol");
        // Cancel once level 0 is written: while the pyramid is being built.
        let cancel = AtomicBool::new(false);
        let done = AtomicU64::new(0);
        let on_progress = |n| {
            if done.fetch_add(n, Ordering::Relaxed) + n > level0 {
                cancel.store(true, Ordering::Relaxed);
            }
        };
        let job = Job::silent()
            .with_progress(&on_progress)
            .with_cancel(&cancel);
        let result = write(&path, &header, &values, &small_slabs(), &job);
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        match format {
            Format::Extended => {
                let err = result.expect_err("cancelled during the pyramid");
                assert!(matches!(err.kind, VolumeErrorKind::Cancelled), "{err}");
                assert!(leftovers.is_empty(), "left behind: {leftovers:?}");
            }
            Format::Thesis => {
                // The volume itself is complete and renamed before its sidecar is
                // built; an interrupted sidecar leaves no sidecar or partial file.
                assert!(result.is_err());
                assert!(!pyramid_sidecar_path(&path).exists());
                assert!(
                    leftovers
                        .iter()
                        .all(|n| !n.to_string_lossy().contains("partial")),
                    "left behind: {leftovers:?}"
                );
                let volume = Volume::open(&path).unwrap();
                assert_eq!(volume.level_count(), 1);
                // `volgen pyramid` interrupted the same way leaves nothing either.
                let cancel = AtomicBool::new(true);
                let job = Job::silent().with_cancel(&cancel);
                assert!(write_pyramid_sidecar(&path, &small_slabs(), &job).is_err());
                assert!(!pyramid_sidecar_path(&path).exists());
                let n = std::fs::read_dir(dir.path()).unwrap().count();
                assert_eq!(n, leftovers.len(), "a partial sidecar was left");
                // And completes when not interrupted.
                assert_eq!(
                    write_pyramid_sidecar(&path, &small_slabs(), &Job::silent()).unwrap(),
                    2
                );
                assert_eq!(Volume::open(&path).unwrap().level_count(), 3);
                for e in std::fs::read_dir(dir.path()).unwrap() {
                    std::fs::remove_file(e.unwrap().path()).unwrap();
                }
            }
        }
    }
}

#[test]
fn files_without_a_pyramid_still_open_and_render() {
    let dir = TempDir::new().unwrap();
    let header = u8_header(Layout::Linear, Format::Extended);
    let values = pattern(DIMS, 255, false);
    let path = dir.path().join("old.vol");
    let options = WriteOptions {
        pyramid: false,
        ..small_slabs()
    };
    write(&path, &header, &values, &options, &Job::silent()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[30..32], &1u16.to_le_bytes(), "written as version 1");
    let volume = Volume::open(&path).unwrap();
    assert_eq!(volume.level_count(), 1);
    let camera = default_camera(&volume, 32);
    let far = LevelChoice::Auto { bias: 5.0 };
    assert_eq!(far.resolve(&volume, &camera), 0, "no pyramid: level 0");
    let frame = render_sequential(
        &RenderVolume::new(volume.level(far.resolve(&volume, &camera)), None).unwrap(),
        &camera,
        &Default::default(),
    )
    .unwrap();
    assert!(frame.stats.counters.samples > 0);
    // `volgen pyramid` adds levels in a sidecar beside a version-1 file.
    assert_eq!(
        write_pyramid_sidecar(&path, &small_slabs(), &Job::silent()).unwrap(),
        2
    );
    let volume = Volume::open(&path).unwrap();
    assert_eq!(volume.level_count(), 3);
    assert_eq!(volume.header().pyramid_offset, None);
    // The sidecar also stores the cells of every level, level 0's included.
    for k in 0..3 {
        assert!(volume.level(k).stored_cells().is_some(), "level {k}");
    }
}

/// Every level samples the full-resolution volume's box, up to its faces: a
/// coarse level's voxel centres lie up to half a coarse voxel inside it (1.5
/// voxels at level 2), and its samples there read the edge voxels. So a cut
/// that keeps the first two voxel layers at a face shows at every level, where
/// it used to show nothing at level 2, and the whole volume covers the
/// same pixels at every level, sequential and parallel alike.
#[test]
fn every_level_samples_the_volume_box_up_to_its_faces() {
    let dir = TempDir::new().unwrap();
    let header = u8_header(Layout::Bricked { side: 16 }, Format::Extended);
    let values = vec![255u16; DIMS.iter().product::<u32>() as usize];
    let path = dir.path().join("solid.vol");
    write(&path, &header, &values, &small_slabs(), &Job::silent()).unwrap();
    let volume = Volume::open(&path).unwrap();
    assert!(volume.level_count() >= 3, "{} levels", volume.level_count());
    let camera = default_camera(&volume, 96);
    let mut settings = raycaster::render::RenderSettings {
        transfer: scene_preset(raycaster::synth::SceneKind::Shapes),
        ..Default::default()
    };
    settings.transfer.domain = Some([0.0, 255.0]);
    let lit_box = |image: &raycaster::render::RgbImage| {
        let (mut lo, mut hi, mut lit) = ([u32::MAX; 2], [0u32; 2], 0);
        for y in 0..image.height() {
            for x in 0..image.width() {
                if image.pixel(x, y) != [0, 0, 0] {
                    lit += 1;
                    lo = [lo[0].min(x), lo[1].min(y)];
                    hi = [hi[0].max(x), hi[1].max(y)];
                }
            }
        }
        (lit, lo, hi)
    };
    let last = DIMS.map(|d| (d - 1) as f32);
    let slab = raycaster::render::ClipRegion {
        crop: Some(raycaster::render::CropBox {
            lo: glam::Vec3::ZERO,
            hi: glam::Vec3::new(last[0], last[1], 1.0),
        }),
        planes: Vec::new(),
    };
    let mut whole_at_0 = None;
    for k in 0..volume.level_count() {
        let level = RenderVolume::new(volume.level(k), None).unwrap();
        let whole = render_sequential(&level, &camera, &settings).unwrap();
        let (lit, lo, hi) = lit_box(&whole.to_image());
        let (_, lo0, hi0) = *whole_at_0.get_or_insert((lit, lo, hi));
        for a in 0..2 {
            assert!(
                lo[a].abs_diff(lo0[a]) <= 1 && hi[a].abs_diff(hi0[a]) <= 1,
                "level {k}: lit box {lo:?}–{hi:?}, level 0 {lo0:?}–{hi0:?}"
            );
        }
        let cut_settings = raycaster::render::RenderSettings {
            clip: slab.clone(),
            ..settings.clone()
        };
        let cut = render_sequential(&level, &camera, &cut_settings).unwrap();
        let (lit, _, _) = lit_box(&cut.to_image());
        assert!(
            lit > 50,
            "level {k}: the slab at the face shows {lit} pixels"
        );
        let parallel =
            render_parallel(&level, &camera, &cut_settings, &ParallelOptions::default()).unwrap();
        assert_images_match(
            &format!("face-slab-level{k}"),
            &parallel.to_image(),
            &cut.to_image(),
            1,
        );
        assert_eq!(parallel.stats.counters.samples, cut.stats.counters.samples);
    }
}

#[test]
fn every_level_has_the_diagonal_of_level_0_in_level_0_voxels() {
    // (The automatic X-ray gain's length: a level must not change it.)
    let dir = TempDir::new().unwrap();
    let volume = Volume::open(bricked_pattern_file(&dir, "d.vol")).unwrap();
    assert!(volume.level_count() >= 2);
    let d0 = volume.diagonal_voxels();
    let expected = DIMS.map(|d| (d as f32).powi(2)).iter().sum::<f32>().sqrt();
    assert!((d0 - expected).abs() < 1e-3, "{d0} against {expected}");
    for k in 1..volume.level_count() {
        let dk = volume.level(k).diagonal_voxels();
        // A level's odd sizes round up: within a voxel per halving.
        assert!(
            (dk - d0).abs() <= 2.0 * (1 << k) as f32,
            "level {k}: {dk} against {d0}"
        );
    }
    assert_eq!(
        raycaster::render::auto_xray_gain(d0),
        raycaster::render::AUTO_XRAY_DEPTH / d0
    );
}

/// The [`pattern`] as an extended u8 file `name` in `dir`, bricked (side 16),
/// with its pyramid.
fn bricked_pattern_file(dir: &TempDir, name: &str) -> std::path::PathBuf {
    pattern_file_spaced(dir, name, [1.0; 3])
}

/// [`bricked_pattern_file`] with voxels `spacing` apart.
fn pattern_file_spaced(dir: &TempDir, name: &str, spacing: [f32; 3]) -> std::path::PathBuf {
    let mut header = u8_header(Layout::Bricked { side: 16 }, Format::Extended);
    header.spacing = spacing;
    let path = dir.path().join(name);
    write(
        &path,
        &header,
        &pattern(DIMS, 255, false),
        &small_slabs(),
        &Job::silent(),
    )
    .unwrap();
    path
}

/// A bricked u8 file `c.vol` of `values` with an embedded pyramid, and the
/// pyramid block's offset.
fn embedded_pyramid_file(dir: &TempDir, values: &[u16]) -> (std::path::PathBuf, usize) {
    let header = u8_header(Layout::Bricked { side: 16 }, Format::Extended);
    let path = dir.path().join("c.vol");
    write(&path, &header, values, &small_slabs(), &Job::silent()).unwrap();
    let offset = Volume::open(&path)
        .unwrap()
        .header()
        .pyramid_offset
        .unwrap();
    (path, offset as usize)
}

#[test]
fn a_corrupt_embedded_pyramid_is_refused_and_a_stale_sidecar_ignored() {
    let dir = TempDir::new().unwrap();
    let values = pattern(DIMS, 255, false);
    let (path, offset) = embedded_pyramid_file(&dir, &values);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[offset + 64] ^= 0x40; // level 1's x size in the directory
    std::fs::write(&path, &bytes).unwrap();
    let err = Volume::open(&path).expect_err("a lying directory");
    let msg = err.to_string();
    assert!(msg.contains("pyramid") && msg.contains("c.vol"), "{msg}");
    // A pyramid offset past the file's end: a file cut short (or a damaged
    // header).
    bytes[offset + 64] ^= 0x40;
    let past_end = (bytes.len() as u64 + 64).to_le_bytes();
    bytes[34..40].copy_from_slice(&past_end[..6]);
    std::fs::write(&path, &bytes).unwrap();
    let msg = Volume::open(&path)
        .expect_err("offset past the end")
        .to_string();
    assert!(
        msg.contains("resolution pyramid starts at byte") && msg.contains("cut short"),
        "{msg}"
    );

    let thesis = u8_header(Layout::Bricked { side: 16 }, Format::Thesis);
    let path = dir.path().join("t.vol");
    write(&path, &thesis, &values, &small_slabs(), &Job::silent()).unwrap();
    assert_eq!(Volume::open(&path).unwrap().level_count(), 3);
    assert!(Volume::open(&path).unwrap().open_warnings().is_empty());
    // A fresh sidecar cut short opens without a pyramid, said (it was ignored
    // without a word); written again, it is read.
    let sidecar = pyramid_sidecar_path(&path);
    let whole = std::fs::read(&sidecar).unwrap();
    std::fs::write(&sidecar, &whole[..100]).unwrap();
    let cut = Volume::open(&path).unwrap();
    assert_eq!(cut.level_count(), 1);
    let warnings = cut.open_warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("t.vol.pyramid: ignored (the resolution pyramid is cut off in its directory (it ends at byte 256, the file has 100 bytes))")
            && warnings[0].contains("`volgen pyramid ")
            && !warnings[0].contains("volgen convert"),
        "{warnings:?}"
    );
    write_pyramid_sidecar(&path, &small_slabs(), &Job::silent()).unwrap();
    assert_eq!(Volume::open(&path).unwrap().level_count(), 3);
    // The file changes: its sidecar no longer describes it and is ignored.
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap();
    std::io::Write::write_all(&mut f, &[0u8; 3]).unwrap();
    drop(f);
    assert_eq!(Volume::open(&path).unwrap().level_count(), 1);
}

#[test]
fn opening_reads_nothing_and_frames_read_stored_cells_or_compute_them_for_bricks_they_visit() {
    let dir = TempDir::new().unwrap();
    let header = u8_header(Layout::Bricked { side: 16 }, Format::Extended);
    let values = pattern(DIMS, 255, false);
    let path = dir.path().join("lazy.vol");
    write(&path, &header, &values, &small_slabs(), &Job::silent()).unwrap();
    let volume = Volume::open(&path).unwrap();
    // The range and cell tables stay in the file (mapped), for every level.
    for k in 0..volume.level_count() {
        let level = volume.level(k);
        assert!(level.ranges().is_mapped(), "level {k}");
        assert!(
            level.stored_cells().is_some_and(|c| c.is_mapped()),
            "level {k}"
        );
    }
    // Opened into RAM, nothing stays mapped (a file cut while open would fault).
    let options = raycaster::volume::OpenOptions {
        access: raycaster::volume::Access::Ram,
        write_ranges_sidecar: false,
    };
    let in_ram = Volume::open_with(&path, options).unwrap();
    for k in 0..in_ram.level_count() {
        let level = in_ram.level(k);
        assert!(!level.ranges().is_mapped(), "level {k}");
        assert!(
            level.stored_cells().is_some_and(|c| !c.is_mapped()),
            "level {k}"
        );
    }
    // Only the spheres' values are visible: the ramp's bricks are transparent.
    let settings = raycaster::render::RenderSettings {
        transfer: raycaster::render::TransferFunction::parse(
            "point 0.0 1 1 1 0\npoint 0.45 1 1 1 0\npoint 0.5 1 0.5 0.2 0.8\npoint 1.0 1 0.5 0.2 0.8\n",
        )
        .unwrap(),
        ..Default::default()
    };
    let camera = default_camera(&volume, 64);
    // The file's own bricks: their cells are read from the file, none scanned.
    let stored = RenderVolume::new(&volume, None).unwrap();
    assert!(stored.cells().is_stored());
    let frame = render_parallel(&stored, &camera, &settings, &ParallelOptions::default()).unwrap();
    assert_eq!(stored.cells().bricks_scanned(), 0);
    assert_eq!(stored.cells().bricks_known(), 0);
    // Sub-bricks of side 6 have no stored table: their cells are computed the
    // first time a frame visits them, and only then.
    let prepared = RenderVolume::new(&volume, Some(6)).unwrap();
    assert!(!prepared.cells().is_stored());
    assert_eq!(
        prepared.cells().bricks_known(),
        0,
        "nothing computed at open"
    );
    let lazy = render_parallel(&prepared, &camera, &settings, &ParallelOptions::default()).unwrap();
    let visible = prepared.geometry().grid().block_count() - lazy.stats.bricks_transparent;
    let known = prepared.cells().bricks_known();
    assert!(
        known > 0 && known <= visible,
        "{known} bricks computed, {visible} not transparent"
    );
    // A second frame reuses them.
    let again =
        render_parallel(&prepared, &camera, &settings, &ParallelOptions::default()).unwrap();
    assert_eq!(prepared.cells().bricks_known(), known);
    assert_eq!(again.to_image(), lazy.to_image());
    // Both agree with the sequential oracle.
    let sequential = render_sequential(&stored, &camera, &settings).unwrap();
    assert_images_match("stored-cells", &frame.to_image(), &sequential.to_image(), 1);
    assert_images_match("lazy-cells", &lazy.to_image(), &sequential.to_image(), 1);
}

#[test]
fn the_automatic_level_follows_the_projected_voxel_size() {
    let dir = TempDir::new().unwrap();
    let volume = Volume::open(bricked_pattern_file(&dir, "lod.vol")).unwrap();
    let auto = LevelChoice::default();
    // The level is chosen at the volume's corner nearest to the camera, so the
    // picture must be well below a pixel per voxel before it coarsens.
    let levels = [300, 100, 50, 20].map(|px| auto.resolve(&volume, &default_camera(&volume, px)));
    assert_eq!(levels, [0, 0, 1, 2]);
    let coarser = LevelChoice::Auto { bias: 1.0 };
    let finer = LevelChoice::Auto { bias: -1.0 };
    assert_eq!(coarser.resolve(&volume, &default_camera(&volume, 50)), 2);
    assert_eq!(finer.resolve(&volume, &default_camera(&volume, 50)), 0);
    assert_eq!(
        LevelChoice::Fixed(9).resolve(&volume, &default_camera(&volume, 300)),
        2
    );
    assert_eq!("auto".parse::<LevelChoice>(), Ok(LevelChoice::default()));
    assert_eq!("1".parse::<LevelChoice>(), Ok(LevelChoice::Fixed(1)));
    assert!("coarse".parse::<LevelChoice>().is_err());
}

/// On a volume whose voxels are 8 times longer along z (a CT's slices), the
/// automatic level keeps its voxels at most a pixel along z too: the level
/// measured by the finest spacing was three levels coarser, 64-voxel-long
/// voxels in a small frame (a chest CT lost its ribs).
#[test]
fn the_automatic_level_keeps_the_coarsest_axis_within_a_pixel() {
    let dir = TempDir::new().unwrap();
    let volume = Volume::open(pattern_file_spaced(&dir, "slices.vol", [1.0, 1.0, 8.0])).unwrap();
    let coarsest = volume.level_count() - 1;
    assert!(coarsest >= 2);
    let hi = Vec3::from(volume.dims().map(|d| (d - 1) as f32)) * Vec3::from(volume.spacing());
    let mut finer_than_before = 0;
    for px in [400, 200, 100, 50, 20, 8] {
        let camera = default_camera(&volume, px);
        let footprint = camera.pixel_footprint(camera.position().clamp(Vec3::ZERO, hi));
        let level = LevelChoice::default().resolve(&volume, &camera);
        // Its z voxels project to at most a pixel; the next level's would not.
        let z_voxel = 8.0 * (1u32 << level) as f32;
        assert!(z_voxel <= footprint || level == 0, "{px} px: level {level}");
        assert!(
            level == coarsest || 2.0 * z_voxel > footprint,
            "{px} px: level {level}"
        );
        // Measured by x and y, the level was floor(log2 footprint).
        let by_finest = (footprint.log2().floor().max(0.0) as usize).min(coarsest);
        finer_than_before += usize::from(level < by_finest);
    }
    assert!(finer_than_before >= 2, "{finer_than_before}");
}

/// The cell ranges of every brick of `shape`'s grid over `values` (a volume of the
/// grid's dims, x slowest), voxel by voxel: each cell's voxels and the voxel after,
/// within the volume; `[u16::MAX, 0]` for a cell past the volume's edge; a brick of
/// one value gives it to every cell.
fn cells_reference(values: &[u16], shape: &CellShape) -> Vec<[u16; 2]> {
    let grid = shape.grid();
    let dims = grid.dims();
    let at = |v: [u32; 3]| values[((v[0] * dims[1] + v[1]) * dims[2] + v[2]) as usize];
    let range = |lo: [u32; 3], hi: [u32; 3]| {
        let mut r = [u16::MAX, 0];
        for x in lo[0]..hi[0] {
            for y in lo[1]..hi[1] {
                for z in lo[2]..hi[2] {
                    let v = at([x, y, z]);
                    r = [r[0].min(v), r[1].max(v)];
                }
            }
        }
        r
    };
    let (m, cs) = (shape.per_axis(), shape.cell_step());
    let mut out = Vec::new();
    for i in 0..grid.block_count() {
        let b = grid.coords(i);
        let (o, e) = (grid.origin(b), grid.extent(b));
        let end = [0, 1, 2].map(|a| o[a] + e[a]);
        let whole = range(o, end);
        for c in 0..m * m * m {
            let c = [c / (m * m), c / m % m, c % m];
            let start = [0, 1, 2].map(|a| o[a] + c[a] * cs);
            out.push(if whole[0] == whole[1] {
                whole
            } else if (0..3).any(|a| start[a] >= end[a]) {
                [u16::MAX, 0]
            } else {
                range(start, [0, 1, 2].map(|a| (start[a] + cs + 1).min(end[a])))
            });
        }
    }
    out
}

#[test]
fn every_level_stores_the_cell_ranges_of_its_bricks_as_computed_independently() {
    let dir = TempDir::new().unwrap();
    let cases = [
        (
            "bricked-u8",
            u8_header(Layout::Bricked { side: 16 }, Format::Extended),
            255,
        ),
        (
            "thesis",
            u8_header(Layout::Bricked { side: 9 }, Format::Thesis),
            255,
        ),
        (
            "thesis-linear",
            u8_header(Layout::Linear, Format::Thesis),
            255,
        ),
        (
            "linear-u16",
            Header::new(
                DIMS,
                [1.0; 3],
                Layout::Linear,
                SampleType::U16,
                Content::Scalar,
                Format::Extended,
            ),
            4000,
        ),
    ];
    for (name, header, max) in cases {
        let path = dir.path().join(format!("{name}.vol"));
        let values = pattern(DIMS, max, false);
        write(&path, &header, &values, &small_slabs(), &Job::silent()).unwrap();
        let volume = Volume::open(&path).unwrap();
        assert_eq!(volume.level_count(), 3, "{name}");
        if header.format == Format::Extended {
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[30..32], &5u16.to_le_bytes(), "{name}: version 5");
        }
        let (mut level_values, mut dims) = (values, DIMS);
        for k in 0..volume.level_count() {
            let level = volume.level(k);
            assert_eq!(level.dims(), dims);
            let table = level
                .stored_cells()
                .unwrap_or_else(|| panic!("{name} level {k}"));
            assert_eq!(table.shape(), &CellShape::default_for(level.header()));
            assert_eq!(
                table.to_vec(),
                cells_reference(&level_values, table.shape()),
                "{name} level {k}"
            );
            (level_values, dims) = reduce_reference(&level_values, dims, false);
        }
    }
}

#[test]
fn frames_reading_stored_cells_equal_frames_that_compute_them() {
    use raycaster::render::{Mode, RenderSettings};
    let dir = TempDir::new().unwrap();
    let values = pattern(DIMS, 255, false);
    for layout in [Layout::Bricked { side: 16 }, Layout::Linear] {
        let header = u8_header(layout, Format::Extended);
        let stored_path = dir.path().join("stored.vol");
        let lazy_path = dir.path().join("lazy.vol");
        write(
            &stored_path,
            &header,
            &values,
            &small_slabs(),
            &Job::silent(),
        )
        .unwrap();
        let no_pyramid = WriteOptions {
            pyramid: false,
            ..small_slabs()
        };
        write(&lazy_path, &header, &values, &no_pyramid, &Job::silent()).unwrap();
        let (stored_volume, lazy_volume) = (
            Volume::open(&stored_path).unwrap(),
            Volume::open(&lazy_path).unwrap(),
        );
        let stored = RenderVolume::new(&stored_volume, None).unwrap();
        let lazy = RenderVolume::new(&lazy_volume, None).unwrap();
        assert!(stored.cells().is_stored() && !lazy.cells().is_stored());
        let camera = default_camera(&stored_volume, 48);
        for (mode, jitter) in [(Mode::Dvr, false), (Mode::Dvr, true), (Mode::Mip, false)] {
            let settings = RenderSettings {
                mode,
                jitter,
                transfer: raycaster::render::TransferFunction::parse(
                    "point 0.0 1 1 1 0\npoint 0.3 1 1 1 0\npoint 0.5 1 0.5 0.2 0.6\npoint 1.0 1 0.5 0.2 0.9\n",
                )
                .unwrap(),
                ..Default::default()
            };
            let what = format!("{layout} {mode:?} jitter {jitter}");
            let options = ParallelOptions::default();
            let a = render_parallel(&stored, &camera, &settings, &options).unwrap();
            let b = render_parallel(&lazy, &camera, &settings, &options).unwrap();
            assert_eq!(a.to_image(), b.to_image(), "{what}");
            assert_eq!(a.stats.counters, b.stats.counters, "{what}");
            assert!(
                a.stats.counters.samples_skipped_empty > 0,
                "{what}: skipping"
            );
            let oracle = render_sequential(&stored, &camera, &settings).unwrap();
            assert_eq!(
                oracle.stats.counters.samples, a.stats.counters.samples,
                "{what}"
            );
        }
        assert_eq!(stored.cells().bricks_scanned(), 0, "{layout}");
        assert!(lazy.cells().bricks_scanned() > 0, "{layout}");
    }
}

#[test]
fn cell_tables_that_do_not_check_out_are_refused_or_ignored() {
    let dir = TempDir::new().unwrap();
    let values = pattern(DIMS, 255, false);
    let (path, offset) = embedded_pyramid_file(&dir, &values);
    let good = std::fs::read(&path).unwrap();
    let at = |o: usize| u64::from_le_bytes(good[o..o + 8].try_into().unwrap()) as usize;
    // Level 0's cell table: its head names another shape.
    let mut bytes = good.clone();
    let table = offset + at(offset + 16);
    bytes[table + 28] ^= 1; // cells per axis
    std::fs::write(&path, &bytes).unwrap();
    let msg = Volume::open(&path)
        .expect_err("a lying cell table")
        .to_string();
    assert!(
        msg.contains("level 0's cell table") && msg.contains("c.vol"),
        "{msg}"
    );
    // A header of version 4 over a block with cell tables, and the reverse.
    let mut bytes = good.clone();
    bytes[30..32].copy_from_slice(&2u16.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let msg = Volume::open(&path)
        .expect_err("version 2 with cells")
        .to_string();
    assert!(msg.contains("cell tables"), "{msg}");
    let mut bytes = good.clone();
    bytes[offset + 4..offset + 8].copy_from_slice(&1u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let msg = Volume::open(&path)
        .expect_err("version 5 without cells")
        .to_string();
    assert!(msg.contains("cell tables"), "{msg}");

    // A thesis file's sidecar whose cell table is damaged is ignored as a whole.
    let thesis = u8_header(Layout::Bricked { side: 16 }, Format::Thesis);
    let path = dir.path().join("t.vol");
    write(&path, &thesis, &values, &small_slabs(), &Job::silent()).unwrap();
    assert!(Volume::open(&path).unwrap().stored_cells().is_some());
    let sidecar = pyramid_sidecar_path(&path);
    let mut side = std::fs::read(&sidecar).unwrap();
    let table = 64 + u64::from_le_bytes(side[64 + 16..64 + 24].try_into().unwrap()) as usize;
    side[table] = b'X';
    // Keep the file's time: the sidecar must stay fresh for the test to mean anything.
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&sidecar)
        .unwrap();
    std::os::unix::fs::FileExt::write_all_at(&file, &side[table..table + 1], table as u64).unwrap();
    let volume = Volume::open(&path).unwrap();
    assert_eq!(volume.level_count(), 1);
    assert!(volume.stored_cells().is_none());
}
