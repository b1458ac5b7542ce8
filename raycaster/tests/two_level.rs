//! Two-level compositing of segmented volumes: reductions to plain rendering,
//! analytic local modes, and parallel == sequential with segments crossing bricks.

mod render_support;

use std::path::Path;

use raycaster::render::{
    Camera, GlobalMode, ImportanceSource, LocalMode, Membership, Mode, ObjectStyle,
    ParallelOptions, Projection, RenderSettings, RenderVolume, SegmentScene, Shading,
    TransferFunction, Vec3, render_parallel, render_sequential,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Content, Format, Header, Layout, SampleType, Volume};
use render_support::*;

fn layers_scene(
    layers: Vec<[f32; 2]>,
    style: impl Fn(usize) -> (TransferFunction, LocalMode),
) -> SegmentScene {
    let objects = (0..layers.len())
        .map(|i| {
            let (transfer, mode) = style(i);
            ObjectStyle {
                name: format!("layer {i}"),
                id: (i + 1) as u8,
                visible: true,
                transfer,
                mode,
                clip: Default::default(),
            }
        })
        .collect();
    SegmentScene {
        membership: Membership::Layers(layers),
        objects,
        global: GlobalMode::Dvr,
    }
}

fn with_segments(base: &RenderSettings, scene: SegmentScene) -> RenderSettings {
    RenderSettings {
        segments: Some(scene),
        ..base.clone()
    }
}

/// DVR segments composited by DVR are the samples composited directly ("over"
/// is associative), which the scene does: the same bits as plain DVR, shaded
/// or not, with the same sample counts (the packet kernels equal this loop to
/// the bit: `tests/packet_kernel.rs`).
#[test]
fn all_objects_in_dvr_with_one_transfer_function_is_plain_dvr() {
    let volume = scene_volume(SceneKind::Shapes, 48);
    let camera = default_camera(&volume, 64);
    let tf = scene_preset(SceneKind::Shapes);
    let shadings = [Some(Shading::default()), None];
    for ((ert, ess), shading) in [(None, false), (Some(0.99), true)]
        .into_iter()
        .flat_map(|c| shadings.map(|s| (c, s)))
    {
        let plain = RenderSettings {
            early_termination: ert,
            empty_space_skipping: ess,
            transfer: tf.clone(),
            shading,
            ..RenderSettings::default()
        };
        let layers = vec![[0.0, 0.2], [0.2, 0.5], [0.5, 0.8], [0.8, 1.0]];
        let two = with_segments(
            &plain,
            layers_scene(layers, |_| (tf.clone(), LocalMode::Dvr)),
        );
        let a = render(&volume, &camera, &plain);
        let b = render(&volume, &camera, &two);
        let name = format!("two-level-dvr-{ess}-{}", shading.is_some());
        assert_images_match(&name, &b.to_image(), &a.to_image(), 0);
        assert!(b.rgba == a.rgba, "{name}: the premultiplied colours differ");
        assert_eq!(b.stats.counters.samples, a.stats.counters.samples, "{name}");
    }
}

/// A scene's picture does not depend on empty-space skipping or the brick
/// size: a scene composited by maximum of DVR objects (a skipped run of
/// samples of no object joined two segments: 162/255 at step 2) and
/// pre-integrated DVR objects (a skipped step took the next object's table:
/// 29/255) see every sample; a scene composited directly skips.
#[test]
fn scenes_render_alike_with_skipping_at_every_brick_size() {
    let volume = scene_volume(SceneKind::Shapes, 96);
    let camera = default_camera(&volume, 64);
    let tf = scene_preset(SceneKind::Shapes);
    let one = |global| SegmentScene {
        global,
        ..layers_scene(vec![[0.08, 1.0]], |_| (tf.clone(), LocalMode::Dvr))
    };
    let two = |global| SegmentScene {
        global,
        ..layers_scene(vec![[0.08, 0.5], [0.5, 1.0]], |i| {
            let name = ["cloud", "shapes"][i];
            (TransferFunction::preset(name).unwrap(), LocalMode::Dvr)
        })
    };
    let cases = [
        ("mip", one(GlobalMode::Mip), false, 2.0, false),
        ("mip-two", two(GlobalMode::Mip), false, 1.5, false),
        ("pre-integrated", one(GlobalMode::Dvr), true, 1.0, false),
        ("pre-integrated-two", two(GlobalMode::Dvr), true, 1.0, false),
        ("direct", two(GlobalMode::Dvr), false, 1.0, true),
    ];
    for (name, scene, preintegrated, step, skips) in cases {
        let settings = |ess| RenderSettings {
            step,
            preintegrated,
            empty_space_skipping: ess,
            transfer: tf.clone(),
            segments: Some(scene.clone()),
            ..RenderSettings::default()
        };
        let reference = render_bricked(&volume, None, &camera, &settings(false));
        for brick in [Some(4), Some(16), None] {
            let frame = render_bricked(&volume, brick, &camera, &settings(true));
            let case = format!("{name}-{brick:?}");
            assert_images_match(&case, &frame.to_image(), &reference.to_image(), 0);
            let skipped = frame.stats.counters.samples_skipped_empty;
            assert_eq!(skipped > 0, skips, "{case}: {skipped} samples skipped");
        }
    }
}

#[test]
fn one_layer_in_a_local_mode_equals_the_plain_mode() {
    let volume = scene_volume(SceneKind::Shells, 40);
    let camera = default_camera(&volume, 48);
    let tf = scene_preset(SceneKind::Shells);
    let plain = RenderSettings {
        shading: None,
        early_termination: None,
        transfer: tf.clone(),
        ..RenderSettings::default()
    };
    let cases = [
        (Mode::Mip, LocalMode::Mip),
        (Mode::Average, LocalMode::Average),
        (Mode::FirstHit, LocalMode::FirstHit { iso: 0.5 }),
    ];
    for (mode, local) in cases {
        let plain = RenderSettings {
            mode,
            ..plain.clone()
        };
        let two = with_segments(
            &plain,
            layers_scene(vec![[0.0, 1.0]], |_| (tf.clone(), local)),
        );
        let a = render(&volume, &camera, &plain);
        let b = render(&volume, &camera, &two);
        assert_images_match(
            &format!("two-level-{}", mode.name()),
            &b.to_image(),
            &a.to_image(),
            1,
        );
        if mode == Mode::FirstHit {
            // The object's hit is refined between samples as the plain mode's
            // (one compositor): the same depths, not a step behind.
            for (da, db) in a.depth.iter().zip(&b.depth) {
                assert_eq!(da.to_bits(), db.to_bits(), "{da} vs {db}");
            }
        }
    }
}

#[test]
fn context_preserving_with_zero_kt_is_dvr() {
    let volume = scene_volume(SceneKind::Shapes, 40);
    let camera = default_camera(&volume, 48);
    let tf = scene_preset(SceneKind::Shapes);
    // Without early termination: DVR segments may stop inside a segment, others
    // only between segments.
    let base = RenderSettings {
        transfer: tf.clone(),
        early_termination: None,
        ..RenderSettings::default()
    };
    let dvr = with_segments(
        &base,
        layers_scene(vec![[0.0, 1.0]], |_| (tf.clone(), LocalMode::Dvr)),
    );
    let cpr = with_segments(
        &base,
        layers_scene(vec![[0.0, 1.0]], |_| {
            (
                tf.clone(),
                LocalMode::ContextPreserving { kt: 0.0, ks: 0.5 },
            )
        }),
    );
    let a = render(&volume, &camera, &dvr);
    let b = render(&volume, &camera, &cpr);
    assert_images_match("cpr-kt0", &b.to_image(), &a.to_image(), 0);
    // And κt > 0 does change it (the mode is not a no-op).
    let cpr2 = with_segments(
        &base,
        layers_scene(vec![[0.0, 1.0]], |_| {
            (
                tf.clone(),
                LocalMode::ContextPreserving { kt: 3.0, ks: 0.5 },
            )
        }),
    );
    let c = render(&volume, &camera, &cpr2);
    assert!(c.to_image().max_difference(&a.to_image()).unwrap() > 10);
}

#[test]
fn xray_of_a_homogeneous_slab_sums_the_value_along_the_ray() {
    // 17 voxels along x at spacing 1: L = 16 world units = 32 samples of 0.5.
    let volume = volume_u8([17, 9, 9], [1.0; 3], |_, _, _| 200);
    let c = centre(&volume);
    let camera = Camera::new(
        Vec3::new(-10.0, c.y, c.z),
        Vec3::X,
        Vec3::Z,
        Projection::Orthographic { height: 4.0 },
        6,
        6,
    )
    .unwrap();
    let tf = white_tf(&[(0.0, 1.0), (1.0, 1.0)]);
    let gain = 0.05;
    let settings = with_segments(
        &plain_settings(tf.clone()),
        layers_scene(vec![[0.0, 1.0]], |_| {
            (tf.clone(), LocalMode::XRay { gain: Some(gain) })
        }),
    );
    let frame = render(&volume, &camera, &settings);
    let expected = 1.0 - (-gain * (200.0f32 / 255.0) * 16.0).exp();
    for px in &frame.rgba {
        assert!((px[3] - expected).abs() < 1e-4, "{} vs {expected}", px[3]);
    }
}

/// An X-ray object without a gain takes the plain X-ray mode's automatic one
/// (it took 1, which saturated every volume larger than a few dozen voxels):
/// a scene of that one object renders the plain mode's picture.
#[test]
fn an_xray_object_without_a_gain_renders_as_the_plain_xray_mode() {
    let volume = scene_volume(SceneKind::Shells, 48);
    let camera = default_camera(&volume, 40);
    let tf = scene_preset(SceneKind::Shells);
    let plain = RenderSettings {
        mode: Mode::XRay,
        // The automatic gain (`plain_settings` fixes one).
        mode_parameters: raycaster::render::ModeParameters::default(),
        ..plain_settings(tf.clone())
    };
    let scene = with_segments(
        &plain,
        layers_scene(vec![[0.0, 1.0]], |_| {
            (tf.clone(), LocalMode::XRay { gain: None })
        }),
    );
    let (a, b) = (
        render(&volume, &camera, &plain),
        render(&volume, &camera, &scene),
    );
    let alpha: f32 = a.rgba.iter().map(|p| p[3]).sum::<f32>() / a.rgba.len() as f32;
    assert!(
        alpha > 0.05 && a.rgba.iter().all(|p| p[3] < 0.99),
        "the automatic gain neither vanishes nor saturates: mean opacity {alpha}"
    );
    for (p, q) in a.rgba.iter().zip(&b.rgba) {
        for c in 0..4 {
            assert!((p[c] - q[c]).abs() <= 1.0 / 255.0, "{p:?} vs {q:?}");
        }
    }
}

#[test]
fn hidden_objects_are_clipped_and_global_mip_picks_the_densest_segment() {
    let volume = scene_volume(SceneKind::Shells, 40);
    let camera = default_camera(&volume, 48);
    let tf = scene_preset(SceneKind::Shells);
    // Without early termination: rays stopping at the threshold under either
    // global mode may overshoot it by different amounts.
    let base = RenderSettings {
        transfer: tf.clone(),
        early_termination: None,
        ..RenderSettings::default()
    };
    let mut scene = layers_scene(vec![[0.0, 0.3], [0.3, 1.0]], |_| {
        (tf.clone(), LocalMode::Dvr)
    });
    let all = render(&volume, &camera, &with_segments(&base, scene.clone()));
    scene.objects[1].visible = false;
    let inner_only = render(&volume, &camera, &with_segments(&base, scene.clone()));
    scene.objects[0].visible = false;
    let none = render(&volume, &camera, &with_segments(&base, scene.clone()));
    assert!(
        none.rgba.iter().all(|p| p[3] == 0.0),
        "everything hidden: nothing drawn"
    );
    let coverage = |f: &raycaster::render::Frame| f.rgba.iter().filter(|p| p[3] > 0.01).count();
    assert!(coverage(&inner_only) < coverage(&all));
    scene.objects[0].visible = true;
    scene.objects[1].visible = true;
    scene.global = GlobalMode::Mip;
    let mip = render(&volume, &camera, &with_segments(&base, scene));
    for (m, a) in mip.rgba.iter().zip(&all.rgba) {
        assert!(
            m[3] <= a[3] + 1e-5,
            "one segment is never more opaque than all of them: {m:?} vs {a:?}"
        );
    }
}

fn labelled_shells(dir: &Path, layout: Layout) -> (Volume, Volume) {
    let n = 40;
    let scene = SceneKind::Shells.build([n; 3], 1);
    let mut paths = Vec::new();
    for content in [Content::Scalar, Content::Labels] {
        let header = Header::new(
            [n; 3],
            [1.0; 3],
            layout,
            SampleType::U8,
            content,
            Format::Extended,
        );
        let path = dir.join(format!("shells-{content:?}-{layout:?}.vol"));
        raycaster::generate::generate(
            scene.as_ref(),
            &header,
            &path,
            &Default::default(),
            &raycaster::job::Job::silent(),
        )
        .unwrap();
        paths.push(path);
    }
    let open = |p: &Path| {
        Volume::open_with(
            p,
            raycaster::volume::OpenOptions {
                access: Access::Mapped,
                write_ranges_sidecar: false,
            },
        )
        .unwrap()
    };
    (open(&paths[0]), open(&paths[1]))
}

fn mixed_label_scene() -> SegmentScene {
    let tf = scene_preset(SceneKind::Shells);
    let style = |id: u8, mode| ObjectStyle {
        name: format!("shell {id}"),
        id,
        visible: true,
        transfer: tf.clone(),
        mode,
        clip: Default::default(),
    };
    SegmentScene {
        membership: Membership::Labels("labels.vol".into()),
        objects: vec![
            style(1, LocalMode::FirstHit { iso: 0.1 }),
            style(2, LocalMode::Mip),
            style(
                3,
                LocalMode::Importance {
                    source: ImportanceSource::Silhouette([1.0, 0.3, 0.9]),
                },
            ),
            style(4, LocalMode::ContextPreserving { kt: 1.5, ks: 0.4 }),
        ],
        global: GlobalMode::Dvr,
    }
}

#[test]
fn label_scenes_render_the_same_in_parallel_across_bricks_tiles_and_threads() {
    let dir = tempfile::tempdir().unwrap();
    for layout in [Layout::Linear, Layout::Bricked { side: 16 }] {
        let (data, labels) = labelled_shells(dir.path(), layout);
        let camera = default_camera(&data, 40);
        let settings = RenderSettings {
            segments: Some(mixed_label_scene()),
            transfer: scene_preset(SceneKind::Shells),
            ..RenderSettings::default()
        };
        let bricks: &[Option<u32>] = match layout {
            Layout::Linear => &[Some(5), Some(8), Some(16), Some(33)],
            Layout::Bricked { .. } => &[None, Some(4), Some(6)],
        };
        for (i, &brick) in bricks.iter().enumerate() {
            let prepared = RenderVolume::new(&data, brick)
                .unwrap()
                .with_labels(&labels)
                .unwrap();
            let reference = render_sequential(&prepared, &camera, &settings).unwrap();
            assert!(
                reference.rgba.iter().filter(|p| p[3] > 0.05).count() > 100,
                "the scene must be visible"
            );
            for (tile, threads) in [(1, 3), (7, 2), (16, 1), (10, 8)] {
                let options = ParallelOptions {
                    render_threads: threads,
                    compositing_threads: 1 + i % 2,
                    tile_size: tile,
                };
                let frame = render_parallel(&prepared, &camera, &settings, &options).unwrap();
                let name = format!("two-level-par-{layout:?}-{brick:?}-t{tile}-r{threads}");
                assert_images_match(&name, &frame.to_image(), &reference.to_image(), 1);
                assert_eq!(
                    frame.stats.counters.samples, reference.stats.counters.samples,
                    "{name}"
                );
            }
        }
        // Segments do not depend on the cut either.
        let a = render_sequential(
            &RenderVolume::new(&data, Some(4))
                .ok()
                .or(RenderVolume::new(&data, None).ok())
                .unwrap()
                .with_labels(&labels)
                .unwrap(),
            &camera,
            &settings,
        )
        .unwrap();
        let b = render_sequential(
            &RenderVolume::new(&data, None)
                .unwrap()
                .with_labels(&labels)
                .unwrap(),
            &camera,
            &settings,
        )
        .unwrap();
        assert_images_match(
            &format!("two-level-cut-{layout:?}"),
            &a.to_image(),
            &b.to_image(),
            1,
        );
    }
}

#[test]
fn a_label_scene_without_labels_or_with_wrong_labels_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (data, labels) = labelled_shells(dir.path(), Layout::Linear);
    let camera = default_camera(&data, 16);
    let settings = RenderSettings {
        segments: Some(mixed_label_scene()),
        ..RenderSettings::default()
    };
    let plain = RenderVolume::new(&data, None).unwrap();
    let e = render_sequential(&plain, &camera, &settings)
        .unwrap_err()
        .to_string();
    assert!(e.contains("label"), "{e}");
    let other = scene_volume(SceneKind::Shapes, 20);
    let e = RenderVolume::new(&data, None)
        .unwrap()
        .with_labels(&other)
        .unwrap_err()
        .to_string();
    assert!(e.contains("dimensions"), "{e}");
    // A volume of values of the right size is no label volume (every value
    // was taken for an id: a blank scene).
    let e = RenderVolume::new(&data, None)
        .unwrap()
        .with_labels(&data)
        .unwrap_err()
        .to_string();
    assert!(e.contains("holds values, not labels"), "{e}");
    assert!(
        RenderVolume::new(&data, None)
            .unwrap()
            .with_labels(&labels)
            .is_ok()
    );
}

/// A scene object's crop box outside the volume is refused naming the object,
/// as the frame's own is (it hid the object without a word).
#[test]
fn an_object_cropped_outside_the_volume_is_refused_by_name() {
    let volume = scene_volume(SceneKind::Shapes, 24);
    let prepared = RenderVolume::new(&volume, None).unwrap();
    let camera = default_camera(&volume, 16);
    let mut scene = layers_scene(vec![[0.0, 0.5], [0.5, 1.0]], |_| {
        (TransferFunction::preset("shapes").unwrap(), LocalMode::Dvr)
    });
    scene.objects[1].clip.crop = Some(raycaster::render::CropBox {
        lo: Vec3::splat(40.0),
        hi: Vec3::splat(50.0),
    });
    let settings = with_segments(&RenderSettings::default(), scene.clone());
    let e = render_sequential(&prepared, &camera, &settings)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scene object \"layer 1\"") && e.contains("outside"),
        "{e}"
    );
    // Inside, it renders.
    scene.objects[1].clip.crop = Some(raycaster::render::CropBox {
        lo: Vec3::splat(4.0),
        hi: Vec3::splat(20.0),
    });
    let settings = with_segments(&RenderSettings::default(), scene);
    assert!(render_sequential(&prepared, &camera, &settings).is_ok());
}

/// A label scene of shaded DVR objects composited directly runs the gradient
/// kernel, folding the samples its filter shows through the scene: the same
/// frames to the bit and the same counts as the scalar loop on every level,
/// objects with domains of their own (the filter a superset) and a hidden one
/// included; marched in lanes where the level has gathers. (A layer kernel
/// taking each lane's label was tried: fewer instructions, but 0.27 → 0.32 s
/// at 256³; docs/benchmarks.md, twenty-third step.)
#[test]
fn shaded_dvr_label_scenes_in_packets_equal_the_scalar_loop_bit_for_bit() {
    use raycaster::render::{SimdLevel, simd_levels};
    let dir = tempfile::tempdir().unwrap();
    let tf = scene_preset(SceneKind::Shells);
    let own = |lo: f32, hi: f32| {
        let mut t = TransferFunction::preset("cloud").unwrap();
        t.domain = Some([lo, hi]);
        t
    };
    let style = |id: u8, transfer: TransferFunction, visible: bool| ObjectStyle {
        name: format!("shell {id}"),
        id,
        visible,
        transfer,
        mode: LocalMode::Dvr,
        clip: Default::default(),
    };
    let scene = SegmentScene {
        membership: Membership::Labels("labels.vol".into()),
        objects: vec![
            style(1, tf.clone(), true),
            style(2, own(20.0, 180.0), true),
            style(3, tf.clone(), false),
            style(4, own(0.0, 255.0), true),
        ],
        global: GlobalMode::Dvr,
    };
    let mut checked = 0;
    for layout in [Layout::Linear, Layout::Bricked { side: 16 }] {
        let (data, labels) = labelled_shells(dir.path(), layout);
        let prepared = RenderVolume::new(&data, None)
            .unwrap()
            .with_labels(&labels)
            .unwrap();
        let camera = default_camera(&data, 40);
        for (ert, ess, jitter) in [
            (true, true, false),
            (false, true, true),
            (true, false, true),
        ] {
            let settings = RenderSettings {
                segments: Some(scene.clone()),
                transfer: tf.clone(),
                early_termination: ert.then_some(0.9),
                empty_space_skipping: ess,
                jitter,
                step: 0.6,
                ..RenderSettings::default()
            };
            let options = ParallelOptions {
                render_threads: 2,
                compositing_threads: 1,
                tile_size: 11,
            };
            let at = |simd| RenderSettings {
                simd: Some(simd),
                ..settings.clone()
            };
            let scalar =
                render_parallel(&prepared, &camera, &at(SimdLevel::Scalar), &options).unwrap();
            assert!(
                scalar.rgba.iter().filter(|p| p[3] > 0.05).count() > 100,
                "visible"
            );
            for &level in simd_levels().iter().filter(|&&l| l != SimdLevel::Scalar) {
                let frame = render_parallel(&prepared, &camera, &at(level), &options).unwrap();
                let name = format!("{layout:?} ert {ert} ess {ess} jitter {jitter} {level}");
                assert!(frame.rgba == scalar.rgba, "{name}: images differ");
                let (a, b) = (frame.stats.counters, scalar.stats.counters);
                assert_eq!(a.samples, b.samples, "{name}");
                assert_eq!(a.samples_in_lanes > 0, level.has_gathers(), "{name}: lanes");
                checked += 1;
            }
        }
    }
    assert!(checked >= 6, "{checked}");
}
