//! Sabella's colouring: the channels (peak, its depth, centroid, intensity) against
//! values computed by hand, and re-mapping the channels against rendering again.

mod render_support;

use raycaster::render::{
    Camera, ClipRegion, CropBox, Mode, ModeParameters, ParallelOptions, Projection, RenderSettings,
    RenderVolume, SabellaChannels, SabellaDepth, SabellaMapping, SabellaOutput, Vec3,
    render_parallel, render_sequential,
};
use raycaster::synth::SceneKind;
use render_support::*;

fn along_x(position: Vec3) -> Camera {
    Camera::new(
        position,
        Vec3::X,
        Vec3::Z,
        Projection::Orthographic { height: 8.0 },
        8,
        8,
    )
    .unwrap()
}

#[test]
fn channels_are_the_peak_its_depth_the_centroid_and_the_intensity() {
    // Along x: 50 everywhere but a peak of 250 at x = 12 (of 0..=16).
    let value = |x: u32| if x == 12 { 250u8 } else { 50 };
    let volume = volume_u8([17, 5, 5], [1.0; 3], |x, _, _| value(x));
    let camera = along_x(Vec3::new(-10.0, 2.0, 2.0));
    let alpha0 = 0.05;
    let settings = RenderSettings {
        mode: Mode::Sabella,
        ..plain_settings(white_tf(&[(0.0, alpha0), (1.0, alpha0)]))
    };
    let prepared = RenderVolume::new(&volume, None).unwrap();
    let channels = SabellaChannels::render(&prepared, &camera, &settings, None).unwrap();
    // The samples by hand: x = 0.5·k, k < 32, values linear between voxels.
    let (mut weight, mut weighted) = (0.0f64, 0.0f64);
    for k in 0..32 {
        let x = 0.5 * k as f64;
        let (i, f) = (x.floor() as u32, x.fract());
        let v = f64::from(value(i)) * (1.0 - f) + f64::from(value((i + 1).min(16))) * f;
        weight += v / 255.0;
        weighted += v / 255.0 * (x / 16.0);
    }
    let centroid = (weighted / weight) as f32;
    let intensity = 1.0 - (1.0f32 - alpha0).powf(16.0);
    for y in 2..6 {
        for x in 2..6 {
            let [m, d, c, i] = channels.channels[(y * 8 + x) as usize];
            assert!((m - 250.0 / 255.0).abs() < 1e-6, "M {m}");
            assert!((d - 0.75).abs() < 1e-6, "D {d}");
            assert!((c - centroid).abs() < 1e-5, "C {c}, expected {centroid}");
            assert!((i - intensity).abs() < 1e-5, "I {i}, expected {intensity}");
        }
    }
    // The peak is later than the centroid here (the mass is spread evenly).
    assert!(centroid < 0.75);
    // A ray that misses: all zero.
    assert_eq!(channels.channels[0], [0.0; 4]);
}

#[test]
fn re_mapping_the_channels_equals_rendering_with_the_new_mapping() {
    let volume = scene_volume(SceneKind::Shells, 48);
    let camera = default_camera(&volume, 48);
    let prepared = RenderVolume::new(&volume, Some(12)).unwrap();
    let options = ParallelOptions {
        render_threads: 3,
        compositing_threads: 2,
        tile_size: 7,
    };
    let base = RenderSettings {
        mode: Mode::Sabella,
        transfer: scene_preset(SceneKind::Shells),
        background: [0.1, 0.2, 0.3],
        ..RenderSettings::default()
    };
    for clip in [
        ClipRegion::default(),
        ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::splat(10.0),
                hi: Vec3::new(47.0, 30.0, 40.0),
            }),
            planes: Vec::new(),
        },
    ] {
        let settings = RenderSettings {
            clip: clip.clone(),
            ..base.clone()
        };
        let channels =
            SabellaChannels::render(&prepared, &camera, &settings, Some(&options)).unwrap();
        let sequential_channels =
            SabellaChannels::render(&prepared, &camera, &settings, None).unwrap();
        assert_eq!(channels.channels, sequential_channels.channels);
        let mappings = [
            SabellaMapping::default(),
            SabellaMapping {
                depth: SabellaDepth::Centroid,
                hue: [300.0, 60.0],
                saturation: [0.9, 0.0],
            },
        ];
        for mapping in mappings {
            let direct = RenderSettings {
                mode_parameters: ModeParameters {
                    sabella: SabellaOutput::Colours(mapping),
                    ..ModeParameters::default()
                },
                ..settings.clone()
            };
            let remapped = channels.map(&mapping, direct.background);
            for frame in [
                render_sequential(&prepared, &camera, &direct).unwrap(),
                render_parallel(&prepared, &camera, &direct, &options).unwrap(),
            ] {
                assert_eq!(frame.rgba, remapped.rgba, "{mapping:?} {clip:?}");
                assert_eq!(frame.to_image(), remapped.to_image());
            }
        }
        // The two mappings differ somewhere (the test can fail).
        let a = channels.map(&mappings[0], [0.0; 3]).to_image();
        let b = channels.map(&mappings[1], [0.0; 3]).to_image();
        assert!(a.max_difference(&b).is_some_and(|d| d > 20));
    }
}
