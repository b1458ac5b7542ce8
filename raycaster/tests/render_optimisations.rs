//! Early ray termination and empty-space skipping: what they change in the image
//! (ERT a little, ESS nothing) and how many samples they save.

mod render_support;

use raycaster::render::{Camera, Frame, Mode, RenderSettings, RenderVolume, TransferFunction};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Layout, SampleType, Volume};
use render_support::*;

const SCENES: [SceneKind; 3] = [SceneKind::Shapes, SceneKind::Shells, SceneKind::Noise];

fn settings(kind: SceneKind, ert: Option<f32>, ess: bool) -> RenderSettings {
    RenderSettings {
        early_termination: ert,
        empty_space_skipping: ess,
        transfer: scene_preset(kind),
        ..RenderSettings::default()
    }
}

/// Renders `with` (empty-space skipping on) and the same settings without
/// skipping, asserts that their images match within `tolerance`, and returns
/// both frames (with skipping first).
fn with_and_without_skipping(
    name: &str,
    volume: &Volume,
    brick: Option<u32>,
    camera: &Camera,
    with: &RenderSettings,
    tolerance: u8,
) -> (Frame, Frame) {
    let without = RenderSettings {
        empty_space_skipping: false,
        ..with.clone()
    };
    let a = render_bricked(volume, brick, camera, with);
    let b = render_bricked(volume, brick, camera, &without);
    assert_images_match(name, &a.to_image(), &b.to_image(), tolerance);
    (a, b)
}

#[test]
fn early_termination_changes_pixels_by_at_most_its_residual() {
    for kind in SCENES {
        let volume = scene_volume(kind, 48);
        let camera = default_camera(&volume, 64);
        let exact = render(&volume, &camera, &settings(kind, None, true)).to_image();
        for (threshold, tolerance) in [(0.99, 3), (0.999, 1)] {
            let frame = render(&volume, &camera, &settings(kind, Some(threshold), true));
            let name = format!("ert-{}-{threshold}", kind.name());
            assert_images_match(&name, &frame.to_image(), &exact, tolerance);
        }
    }
}

#[test]
fn empty_space_skipping_stays_exact_with_preintegration() {
    for kind in SCENES {
        let volume = scene_volume(kind, 40);
        let camera = default_camera(&volume, 48);
        // Steps below and above the cells (4 voxels, the last of a brick of
        // step 15 3, of step 8 4): the run walker checks the cells between
        // samples; below the brick step in every case.
        for (step, brick, jitter) in [
            (0.5, Some(5), false),
            (1.0, None, true),
            (1.5, Some(5), true),
            (1.0, Some(8), false),
            (3.5, None, true),
            (6.0, None, false),
            (9.5, None, false),
            (5.0, Some(9), true),
        ] {
            // Without ERT the same bits. With it, a marched sample that also
            // composites the skipped sample's segment stops after both, where
            // the unskipped ray may stop between them: within ERT's residual.
            for (ert, tolerance) in [(None, 0), (Some(0.99), 3)] {
                let with = RenderSettings {
                    step,
                    preintegrated: true,
                    jitter,
                    ..settings(kind, ert, true)
                };
                let name = format!(
                    "ess-pre-{}-{step}-{brick:?}-jitter{jitter}-ert{ert:?}",
                    kind.name()
                );
                let (a, b) =
                    with_and_without_skipping(&name, &volume, brick, &camera, &with, tolerance);
                let (sa, sb) = (a.stats.counters.samples, b.stats.counters.samples);
                assert!(sa < sb, "{name}: skipping must skip ({sa} vs {sb})");
                // Not vacuous: pre-integration changes the picture.
                let plain = render_bricked(
                    &volume,
                    brick,
                    &camera,
                    &RenderSettings {
                        preintegrated: false,
                        ..with.clone()
                    },
                );
                assert_ne!(plain.to_image(), a.to_image(), "{name}");
            }
        }
        // The limit the library reports (what the viewer's moving frames stay
        // below): the brick step, 4 voxels for brick 5; at that step skipping
        // is off, just below it on.
        let prepared = RenderVolume::new(&volume, Some(5)).unwrap();
        let limit = prepared.preintegrated_skipping_below();
        assert_eq!(limit, 4.0);
        for (step, skips) in [(limit - 0.01, true), (limit, false)] {
            let with = RenderSettings {
                step,
                preintegrated: true,
                ..settings(kind, Some(0.99), true)
            };
            let skipped = render_bricked(&volume, Some(5), &camera, &with)
                .stats
                .counters
                .samples_skipped_empty;
            assert_eq!(skipped > 0, skips, "{} at step {step}", kind.name());
        }
        // Modes that ignore pre-integration keep skipping at that step: their
        // frames are those without it, samples included.
        for mode in [Mode::Mip, Mode::FirstHit] {
            let plain = RenderSettings {
                step: limit,
                mode,
                ..settings(kind, Some(0.99), true)
            };
            let asked = RenderSettings {
                preintegrated: true,
                ..plain.clone()
            };
            let (a, b) = (
                render_bricked(&volume, Some(5), &camera, &asked),
                render_bricked(&volume, Some(5), &camera, &plain),
            );
            let name = format!("{} {mode:?}", kind.name());
            assert!(a.stats.counters.samples_skipped_empty > 0, "{name}");
            assert_eq!(a.stats.counters.samples, b.stats.counters.samples, "{name}");
            assert_eq!(a.to_image(), b.to_image(), "{name}");
        }
    }
}

#[test]
fn preintegrated_skipping_sees_surfaces_between_coarse_samples() {
    // Solid balls (255) in an empty (0) background, with a transfer function
    // that shows only the values in between: a surface less than a voxel thick
    // that a coarse step jumps, with samples on both sides in empty cells.
    // Only the pre-integrated segment between them shows it, so skipping must
    // march one of them (the cells crossed between samples).
    let centres = [
        (14.0, 16.0, 20.0, 9.0),
        (32.0, 30.0, 26.0, 11.0),
        (30.0, 12.0, 34.0, 7.0),
    ];
    let volume = volume_u8([48, 44, 46], [1.0; 3], |x, y, z| {
        let inside = centres.iter().any(|&(cx, cy, cz, r)| {
            let d = |a: u32, c: f32| a as f32 - c;
            d(x, cx).powi(2) + d(y, cy).powi(2) + d(z, cz).powi(2) < r * r
        });
        if inside { 255 } else { 0 }
    });
    let tf = white_tf(&[
        (0.0, 0.0),
        (0.35, 0.0),
        (0.45, 0.9),
        (0.55, 0.9),
        (0.65, 0.0),
        (1.0, 0.0),
    ]);
    let camera = default_camera(&volume, 64);
    for (step, brick) in [(5.0, None), (6.5, Some(9)), (9.0, None), (3.0, Some(5))] {
        let with = RenderSettings {
            step,
            preintegrated: true,
            early_termination: None,
            empty_space_skipping: true,
            transfer: tf.clone(),
            ..RenderSettings::default()
        };
        let name = format!("ess-pre-surfaces-{step}-{brick:?}");
        let (a, b) = with_and_without_skipping(&name, &volume, brick, &camera, &with, 0);
        let (sa, sb) = (a.stats.counters.samples, b.stats.counters.samples);
        assert!(sa < sb / 2, "{name}: skipping must skip ({sa} vs {sb})");
        let lit = b.to_image().data().chunks(3).filter(|p| p[0] > 20).count();
        assert!(lit > 200, "{name}: the surfaces show ({lit} pixels)");
    }
}

#[test]
fn preintegrated_two_level_scenes_stay_exact_at_coarse_steps() {
    // Ten value layers, each its own DVR object: a segment may change object
    // between two coarse samples. A skipped step could take the next object's
    // table, so such scenes march every sample
    // (`tests/two_level.rs`: `scenes_render_alike_with_skipping_at_every_brick_size`).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../volumes/scenes/shapes-layers10.toml");
    let scene = raycaster::render::SegmentScene::load(&path).unwrap();
    let volume = scene_volume(SceneKind::Shapes, 48);
    let camera = default_camera(&volume, 56);
    for step in [2.0, 5.0, 8.0] {
        let with = RenderSettings {
            step,
            preintegrated: true,
            early_termination: None,
            empty_space_skipping: true,
            transfer: scene_preset(SceneKind::Shapes),
            segments: Some(scene.clone()),
            ..RenderSettings::default()
        };
        let name = format!("ess-pre-layers-{step}");
        let (a, b) = with_and_without_skipping(&name, &volume, None, &camera, &with, 0);
        let (sa, sb) = (a.stats.counters.samples, b.stats.counters.samples);
        assert_eq!(sa, sb, "{name}: every sample is marched");
    }
}

#[test]
fn empty_space_skipping_leaves_every_mode_identical() {
    for kind in SCENES {
        let volume = scene_volume(kind, 40);
        let camera = default_camera(&volume, 48);
        for mode in Mode::ALL {
            for brick in [Some(5), None] {
                let with = RenderSettings {
                    mode,
                    ..settings(kind, Some(0.99), true)
                };
                let name = format!("ess-{}-{}-{brick:?}", kind.name(), mode.name());
                let (a, b) = with_and_without_skipping(&name, &volume, brick, &camera, &with, 0);
                assert_eq!(a.depth, b.depth, "{name}");
                assert!(
                    a.stats.counters.samples <= b.stats.counters.samples,
                    "{name}"
                );
            }
        }
    }
}

#[test]
fn sample_counts_follow_the_thesis_pattern_on_an_opaque_scene() {
    // The thesis's 68×256×256 opaque volume, here the shapes scene with every
    // object opaque: none / ERT / ESS / both.
    let volume = scene_volume(SceneKind::Shapes, 128);
    let camera = default_camera(&volume, 96);
    let count = |ert: Option<f32>, ess: bool| {
        let s = RenderSettings {
            transfer: TransferFunction::preset("opaque").unwrap(),
            ..settings(SceneKind::Shapes, ert, ess)
        };
        render(&volume, &camera, &s).stats.counters.samples
    };
    let none = count(None, false);
    let ert = count(Some(0.99), false);
    let ess = count(None, true);
    let both = count(Some(0.99), true);
    eprintln!("samples: none {none}, ERT {ert}, ESS {ess}, both {both}");
    assert!(
        ert < none && ess < none,
        "each optimisation must save samples"
    );
    assert!(both < ert && both < ess, "together they must save more");
    assert!(
        (both as f64) < 0.1 * none as f64,
        "both together must save well over 90 % ({both} of {none})"
    );
}

#[test]
fn the_image_does_not_depend_on_how_the_volume_is_cut_or_stored() {
    // Samples are placed globally and owned by exactly one brick: any brick size,
    // linear or bricked storage, mapped or in RAM, u8 — the same pixels.
    let dir = tempfile::tempdir().unwrap();
    let kind = SceneKind::Shapes;
    let reference_volume = scene_volume(kind, 40);
    let camera = default_camera(&reference_volume, 48);
    for mode in [Mode::Dvr, Mode::FirstHit] {
        let s = RenderSettings {
            mode,
            ..settings(kind, Some(0.99), true)
        };
        let reference = render_bricked(&reference_volume, Some(16), &camera, &s);
        for brick in [Some(2), Some(4), Some(8), Some(33), Some(64)] {
            let frame = render_bricked(&reference_volume, brick, &camera, &s);
            let name = format!("cut-{}-{brick:?}", mode.name());
            assert_images_match(&name, &frame.to_image(), &reference.to_image(), 0);
            // The same samples are considered (taken or skipped as empty).
            let considered = |f: &raycaster::render::Frame| {
                f.stats.counters.samples + f.stats.counters.samples_skipped_empty
            };
            assert_eq!(considered(&frame), considered(&reference), "{name}");
        }
        for layout in [
            Layout::Bricked { side: 8 },
            Layout::Bricked { side: 32 },
            Layout::Linear,
        ] {
            for access in [Access::Mapped, Access::Ram] {
                let file = scene_file(dir.path(), kind, 40, layout, SampleType::U8, access);
                let frame = render(&file, &camera, &s);
                let name = format!("stored-{}-{layout:?}-{access:?}", mode.name());
                assert_images_match(&name, &frame.to_image(), &reference.to_image(), 0);
            }
        }
    }
}

#[test]
fn u16_volumes_render_like_u8_ones() {
    // The same scene quantised to 16 bits, with the transfer function over the
    // same normalised range, differs only by quantisation.
    let dir = tempfile::tempdir().unwrap();
    let kind = SceneKind::Shapes;
    let u8_volume = scene_volume(kind, 32);
    let u16_volume = scene_file(
        dir.path(),
        kind,
        32,
        Layout::Bricked { side: 16 },
        SampleType::U16,
        Access::Mapped,
    );
    let camera = default_camera(&u8_volume, 48);
    let s = settings(kind, Some(0.99), true);
    let a = render(&u8_volume, &camera, &s).to_image();
    let b = render(&u16_volume, &camera, &s).to_image();
    let differing = a.count_differences(&b, 24);
    assert!(
        differing < a.data().len() / 100,
        "{differing} channels differ by more than 24"
    );
}
