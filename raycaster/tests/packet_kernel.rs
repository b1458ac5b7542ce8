//! The SIMD kernel (the samples of a ray in SIMD lanes) against the scalar
//! kernel, on every instruction set this machine runs: the same frames to the bit and the
//! same counts, over scenes, sample types, layouts, shading, lights, early
//! termination and empty-space skipping; and against the sequential renderer.

mod render_support;

use raycaster::render::{
    Counters, ImportanceSource, Light, Mode, ModeParameters, ParallelOptions, RenderSettings,
    RenderVolume, SegmentScene, Shading, SimdLevel, TransferFunction, Vec3, render_parallel,
    render_sequential, simd_levels,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Layout, SampleType};
use render_support::*;

const N: u32 = 36;

fn packet_levels() -> Vec<SimdLevel> {
    simd_levels()
        .iter()
        .copied()
        .filter(|&l| l != SimdLevel::Scalar)
        .collect()
}

/// The layouts the kernels are compared on. (Logical sub-bricks of a bricked
/// file last: their neighbours across a face lie in the same stored brick or
/// the next. Bricks of side 5: wraps across a z face whose bytes have no sign
/// bit, which a byte mask once missed.)
const LAYOUTS: [(Layout, SampleType, Option<u32>); 5] = [
    (Layout::Linear, SampleType::U8, None),
    (Layout::Bricked { side: 16 }, SampleType::U16, None),
    (Layout::Bricked { side: 8 }, SampleType::U8, None),
    (Layout::Bricked { side: 5 }, SampleType::U8, None),
    (Layout::Bricked { side: 16 }, SampleType::U8, Some(6)),
];

/// Scene `kind` in each of [`LAYOUTS`], prepared and framed at `size` pixels:
/// `visit(layout, prepared, camera)`, `layout` naming the scene and layout
/// for messages.
fn for_each_layout(
    dir: &std::path::Path,
    kind: SceneKind,
    size: u32,
    mut visit: impl FnMut(&str, &RenderVolume<'_>, &raycaster::render::Camera),
) {
    for (layout, sample_type, brick_side) in LAYOUTS {
        let file = scene_file(dir, kind, N, layout, sample_type, Access::Mapped);
        let prepared = RenderVolume::new(&file, brick_side).unwrap();
        let camera = default_camera(&file, size);
        let name = format!("{kind:?} {layout:?} {sample_type:?} bricks {brick_side:?}");
        visit(&name, &prepared, &camera);
    }
}

/// Renders `settings` (on the scalar kernel; two render threads, one
/// compositor, tiles of `tile_size`) on each of `levels` too and asserts the
/// same frame to the bit and the same counts, and that a packet kernel
/// marched samples at `level` exactly where `in_lanes(level)` says; the
/// frames compared.
fn assert_levels_equal_scalar(
    prepared: &RenderVolume<'_>,
    camera: &raycaster::render::Camera,
    settings: &RenderSettings,
    tile_size: u32,
    levels: &[SimdLevel],
    name: &str,
    in_lanes: impl Fn(SimdLevel) -> bool,
) -> usize {
    let options = &ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size,
    };
    let scalar = render_parallel(prepared, camera, settings, options).unwrap();
    let counts = scalar.stats.counters;
    assert!(counts.samples > 0, "{name}");
    assert_eq!(counts.samples_in_lanes, 0, "{name}: the scalar kernel");
    for &level in levels {
        let packets = render_parallel(
            prepared,
            camera,
            &RenderSettings {
                simd: Some(level),
                ..settings.clone()
            },
            options,
        )
        .unwrap();
        assert!(packets.rgba == scalar.rgba, "{name} {level}: images differ");
        let in_packets = packets.stats.counters;
        let lanes = in_packets.samples_in_lanes;
        assert_eq!(
            Counters {
                samples_in_lanes: 0,
                ..in_packets
            },
            counts,
            "{name} {level}: counts differ"
        );
        assert!(lanes <= counts.samples, "{name} {level}");
        assert_eq!(
            lanes > 0,
            in_lanes(level),
            "{name} {level}: samples in lanes"
        );
    }
    levels.len()
}

#[test]
fn packets_equal_the_scalar_kernel_bit_for_bit_on_every_level() {
    let levels = packet_levels();
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    assert!(!levels.is_empty(), "no packet level detected");
    let dir = tempfile::tempdir().unwrap();
    let mut frames = 0;
    for kind in [SceneKind::Shapes, SceneKind::Noise, SceneKind::Shells] {
        for_each_layout(dir.path(), kind, 48, |layout, prepared, camera| {
            let lights = [
                None,
                Some(Shading::default()),
                Some(Shading {
                    light: Light::Fixed(Vec3::new(0.3, -1.0, -0.4)),
                    shininess: 7.5,
                    ..Shading::default()
                }),
            ];
            for (round, shading) in lights.into_iter().enumerate() {
                for (ert, ess) in [(true, true), (false, true), (true, false)] {
                    let settings = RenderSettings {
                        transfer: scene_preset(kind),
                        shading,
                        early_termination: ert.then_some(0.95),
                        empty_space_skipping: ess,
                        step: [0.5, 0.3, 0.9][round],
                        simd: Some(SimdLevel::Scalar),
                        ..RenderSettings::default()
                    };
                    let tile_size = [16, 7, 32][round];
                    let name = format!("{layout} light {round} ert {ert} ess {ess}");
                    frames += assert_levels_equal_scalar(
                        prepared,
                        camera,
                        &settings,
                        tile_size,
                        &levels,
                        &name,
                        |_| true,
                    );
                }
            }
        });
    }
    assert_eq!(frames, 135 * levels.len());
}

/// The modes that read only their samples' values (maximum, average, X-ray,
/// first hit, Sabella's) take the value kernel on the levels with gathers:
/// the same frames to the bit and the same counts as the scalar kernel, over
/// scenes, sample types, layouts, ray-start jitter, early termination and
/// empty-space skipping.
#[test]
fn value_modes_in_packets_equal_the_scalar_kernel_bit_for_bit_on_every_level() {
    let levels = packet_levels();
    let dir = tempfile::tempdir().unwrap();
    let modes = [
        Mode::Mip,
        Mode::Average,
        Mode::XRay,
        Mode::FirstHit,
        Mode::Sabella,
    ];
    let mut frames = 0;
    for kind in [SceneKind::Shapes, SceneKind::Noise] {
        for_each_layout(dir.path(), kind, 40, |layout, prepared, camera| {
            for (round, mode) in modes.into_iter().enumerate() {
                for (ert, ess) in [(true, true), (false, true), (true, false)] {
                    let settings = RenderSettings {
                        mode,
                        transfer: scene_preset(kind),
                        early_termination: ert.then_some(0.9),
                        empty_space_skipping: ess,
                        step: [0.5, 0.3, 0.9, 0.7, 1.3][round],
                        jitter: round % 2 == 1,
                        simd: Some(SimdLevel::Scalar),
                        ..RenderSettings::default()
                    };
                    let tile_size = [16, 7, 32, 11, 9][round];
                    let name = format!("{layout} {} ert {ert} ess {ess}", mode.name());
                    frames += assert_levels_equal_scalar(
                        prepared,
                        camera,
                        &settings,
                        tile_size,
                        &levels,
                        &name,
                        SimdLevel::has_gathers,
                    );
                }
            }
        });
    }
    assert_eq!(frames, 150 * levels.len());
}

/// The modes that read a visible sample's gradient (importance-aware,
/// context-preserving, tone and silhouette, and DVR with a 2D transfer
/// function) take the gradient kernel on the levels with gathers: the same
/// frames to the bit and the same counts as the scalar kernel, over scenes,
/// sample types, layouts, shading, ray-start jitter, 1D and 2D functions,
/// early termination and empty-space skipping.
#[test]
fn gradient_modes_in_packets_equal_the_scalar_kernel_bit_for_bit_on_every_level() {
    let levels = packet_levels();
    let dir = tempfile::tempdir().unwrap();
    let modes = [
        Mode::Importance,
        Mode::ContextPreserving,
        Mode::Silhouette,
        Mode::Dvr,
    ];
    let mut frames = 0;
    for kind in [SceneKind::Shapes, SceneKind::Noise] {
        for_each_layout(dir.path(), kind, 40, |layout, prepared, camera| {
            for (round, mode) in modes.into_iter().enumerate() {
                let combinations = [(true, true), (false, true), (true, false)];
                for (i, (ert, ess)) in combinations.into_iter().enumerate() {
                    // Importance from the value, the gradient or the view.
                    let importance = [
                        ImportanceSource::Intensity(0.8),
                        ImportanceSource::Gradient(1.5),
                        ImportanceSource::Silhouette([1.0, 0.2, 0.9]),
                    ][i];
                    // A 2D function for DVR always (its 1D one takes the
                    // DVR kernel), for the others once.
                    let settings = RenderSettings {
                        mode,
                        mode_parameters: ModeParameters {
                            importance,
                            context: [1.5 + i as f32, 0.4],
                            ..ModeParameters::default()
                        },
                        transfer: {
                            let mut tf = scene_preset(kind);
                            tf.gradient_ramp = (mode == Mode::Dvr || i == 2)
                                .then_some([0.02, 0.3 + 0.2 * i as f32]);
                            tf
                        },
                        shading: (round != 1 || ess).then(Shading::default),
                        early_termination: ert.then_some(0.9),
                        empty_space_skipping: ess,
                        step: [0.5, 0.3, 0.9, 0.6][round],
                        jitter: round % 2 == 1,
                        simd: Some(SimdLevel::Scalar),
                        ..RenderSettings::default()
                    };
                    let tile_size = [16, 7, 11, 13][round];
                    let name = format!("{layout} {} ert {ert} ess {ess}", mode.name());
                    frames += assert_levels_equal_scalar(
                        prepared,
                        camera,
                        &settings,
                        tile_size,
                        &levels,
                        &name,
                        SimdLevel::has_gathers,
                    );
                }
            }
        });
    }
    assert_eq!(frames, 120 * levels.len());
}

/// Two-level scenes take the value kernel on the levels with gathers (their
/// values gathered, every sample folded by the scene's compositor, a gradient
/// read through the cell cache where an object asks for one), or the gradient
/// kernel folding every sample when every object is shaded DVR: the same
/// frames to the bit and the same counts as
/// the scalar kernel, over value-layer scenes of every local mode,
/// pre-integrated DVR objects, layouts, sample types, ray-start jitter, early
/// termination and empty-space skipping.
#[test]
fn two_level_scenes_in_packets_equal_the_scalar_kernel_bit_for_bit_on_every_level() {
    let levels = packet_levels();
    let dir = tempfile::tempdir().unwrap();
    // Three layers of DVR objects of two functions, with `global` and the
    // second object's `clip` lines.
    let three_dvr_layers = |global: &str, clip: &str| {
        format!(
            "layers = [[0.0, 0.3], [0.3, 0.55], [0.55, 1.0]]\n{global}\
             [[object]]\ntf = \"cloud\"\n[[object]]\ntf = \"shapes\"\n{clip}\
             [[object]]\ntf = \"shapes\"\n"
        )
    };
    // Two functions over parts of the stored values (`domain` in stored
    // values: a file per sample type, the scenes' values spanning their type),
    // in three layers.
    for (type_max, suffix) in [(255.0f32, "u8"), (65535.0, "u16")] {
        for (name, preset, [d0, d1]) in [
            ("low", "cloud", [0.0f32, 0.4]),
            ("high", "shapes", [0.25, 0.9]),
        ] {
            let mut tf = TransferFunction::preset(preset).unwrap();
            tf.domain = Some([d0 * type_max, d1 * type_max]);
            std::fs::write(dir.path().join(format!("{name}-{suffix}.tf")), tf.to_text()).unwrap();
        }
    }
    let own_domains = |global: &str| {
        format!(
            "layers = [[0.0, 0.3], [0.3, 0.55], [0.55, 1.0]]\n{global}\
             [[object]]\ntf = \"low-TYPE.tf\"\n[[object]]\ntf = \"high-TYPE.tf\"\n\
             [[object]]\ntf = \"low-TYPE.tf\"\n"
        )
    };
    let scenes = [
        // Every local mode, one per layer.
        r#"layers = [[0.0, 0.12], [0.12, 0.3], [0.3, 0.45], [0.45, 0.6], [0.6, 0.75], [0.75, 0.9], [0.9, 1.0]]
[[object]]
tf = "shapes"
mode = "xray"
[[object]]
tf = "shapes"
mode = "importance"
importance = "gradient"
weight = 4.0
[[object]]
tf = "shapes"
mode = "mip"
[[object]]
tf = "shapes"
mode = "silhouette"
[[object]]
tf = "shapes"
mode = "context"
[[object]]
tf = "shapes"
mode = "dvr"
[[object]]
tf = "shapes"
mode = "first-hit"
"#
        .to_string(),
        // DVR objects only, of two functions (transparent layers skipped):
        // composited directly, the DVR kernel with the layers' entries when
        // shaded, the value kernel when not.
        three_dvr_layers("global = \"dvr\"\n", ""),
        // The same, composited by maximum: segments, not one direct
        // accumulation (the gradient kernel folding every sample).
        three_dvr_layers("global = \"mip\"\n", ""),
        // Composited directly, an object clipped to half the volume: the
        // gradient kernel folding the visible samples through the scene.
        three_dvr_layers("", "clip = [[20, 20, 20, 1, 0, 0]]\n"),
        // Objects whose functions have domains of their own (their tables
        // map values to entries differently): the gradient kernel with a
        // filter visible wherever any of them may be (the scalar loop
        // before), composited directly and by maximum.
        own_domains("global = \"dvr\"\n"),
        own_domains("global = \"mip\"\n"),
    ];
    let mut frames = 0;
    let kind = SceneKind::Shapes;
    for_each_layout(dir.path(), kind, 40, |layout, prepared, camera| {
        for (round, text) in scenes.iter().enumerate() {
            let suffix = if layout.contains("U16") { "u16" } else { "u8" };
            let text = text.replace("TYPE", suffix);
            let scene = SegmentScene::parse(&text, dir.path()).unwrap();
            let combinations = [
                (true, true, false),
                (false, true, true),
                (true, false, true),
            ];
            for (i, (ert, ess, preintegrated)) in combinations.into_iter().enumerate() {
                let settings = RenderSettings {
                    segments: Some(scene.clone()),
                    transfer: scene_preset(kind),
                    shading: (i != 1).then(Shading::default),
                    early_termination: ert.then_some(0.9),
                    empty_space_skipping: ess,
                    preintegrated,
                    step: if preintegrated { 1.0 } else { 0.5 },
                    jitter: (round + i) % 2 == 1,
                    simd: Some(SimdLevel::Scalar),
                    ..RenderSettings::default()
                };
                let tile_size = [16, 7, 11][i];
                let name =
                    format!("{layout} scene {round} ert {ert} ess {ess} pre {preintegrated}");
                frames += assert_levels_equal_scalar(
                    prepared,
                    camera,
                    &settings,
                    tile_size,
                    &levels,
                    &name,
                    |level| {
                        // Shaded DVR objects with pre-integrated tables: the
                        // scalar loop.
                        level.has_gathers() && !(round >= 1 && i == 2)
                    },
                );
            }
        }
    });
    assert_eq!(frames, 90 * levels.len());
}

/// The sequential renderer (the scalar loop: the oracle) against the parallel
/// one on each packet level, and against itself on each packet level (packets
/// of one ray), for the kernels' modes: DVR, a value mode, a gradient mode and
/// pre-integrated DVR.
#[test]
fn packets_equal_the_sequential_renderer() {
    let kind = SceneKind::Shapes;
    let volume = scene_volume(kind, N);
    let prepared = RenderVolume::new(&volume, Some(12)).unwrap();
    let camera = default_camera(&volume, 40);
    let cases = [
        (Mode::Dvr, false),
        (Mode::Mip, false),
        (Mode::Silhouette, false),
        (Mode::Dvr, true),
    ];
    for (mode, preintegrated) in cases {
        let settings = RenderSettings {
            mode,
            transfer: scene_preset(kind),
            preintegrated,
            step: if preintegrated { 1.0 } else { 0.5 },
            ..RenderSettings::default()
        };
        let at = |simd| RenderSettings {
            simd: Some(simd),
            ..settings.clone()
        };
        let reference = render_sequential(&prepared, &camera, &at(SimdLevel::Scalar)).unwrap();
        let name = format!("{}{}", mode.name(), if preintegrated { " pre" } else { "" });
        for level in packet_levels() {
            // The sequential renderer's packets of one ray: the scalar bits.
            let one_ray = render_sequential(&prepared, &camera, &at(level)).unwrap();
            assert!(one_ray.rgba == reference.rgba, "{name} sequential {level}");
            let (counts, lanes) = (
                one_ray.stats.counters,
                one_ray.stats.counters.samples_in_lanes,
            );
            let reference_counts = reference.stats.counters;
            let without_lanes = Counters {
                samples_in_lanes: 0,
                ..counts
            };
            assert_eq!(without_lanes, reference_counts, "{name} sequential {level}");
            // (Pre-integrated DVR: the scalar loop on every level.)
            let kernel = !preintegrated && (mode == Mode::Dvr || level.has_gathers());
            assert_eq!(
                lanes > 0,
                kernel,
                "{name} sequential {level}: samples in lanes"
            );
            let options = ParallelOptions {
                render_threads: 3,
                compositing_threads: 2,
                tile_size: 9,
            };
            let frame = render_parallel(&prepared, &camera, &at(level), &options).unwrap();
            assert_images_match(
                &format!("packets-{name}-{level}"),
                &frame.to_image(),
                &reference.to_image(),
                1,
            );
            let samples = (
                frame.stats.counters.samples,
                reference.stats.counters.samples,
            );
            assert_eq!(samples.0, samples.1, "{name} {level}");
        }
    }
}

#[test]
fn a_level_this_cpu_lacks_is_refused_by_name() {
    let volume = scene_volume(SceneKind::Shapes, 16);
    let prepared = RenderVolume::new(&volume, None).unwrap();
    let camera = default_camera(&volume, 8);
    for level in SimdLevel::ALL {
        let settings = RenderSettings {
            simd: Some(level),
            ..RenderSettings::default()
        };
        let result = render_parallel(&prepared, &camera, &settings, &ParallelOptions::default());
        if level.is_available() {
            assert!(result.is_ok(), "{level}");
        } else {
            let e = result.unwrap_err().to_string();
            assert!(e.contains(level.name()) && e.contains("scalar"), "{e}");
        }
    }
}
