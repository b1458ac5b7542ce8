//! Small golden images of the synthetic scenes, compared with a tolerance. A
//! failing comparison writes the actual, expected and diff images to
//! `target/test-images/`. Regenerate with `UPDATE_GOLDEN=1 cargo test --test render_golden`
//! after a deliberate change, and look at the new images before committing them.

mod render_support;

use std::path::PathBuf;

use raycaster::render::{Mode, RenderSettings, RgbImage};
use raycaster::synth::SceneKind;
use render_support::*;

/// Per-channel tolerance: room for floating-point differences between builds.
const TOLERANCE: u8 = 2;

fn golden_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(format!("{name}.png"))
}

fn check(name: &str, actual: &RgbImage) {
    let path = golden_path(name);
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        actual.save_png(&path).unwrap();
        return;
    }
    let expected = RgbImage::load_png(&path).unwrap_or_else(|e| {
        panic!("{name}: no golden image ({e}); run with UPDATE_GOLDEN=1 to create it")
    });
    assert_images_match(name, actual, &expected, TOLERANCE);
}

#[test]
fn synthetic_scenes_match_their_golden_images() {
    for kind in SceneKind::ALL {
        let volume = scene_volume(kind, 48);
        let camera = default_camera(&volume, 96);
        let settings = RenderSettings {
            transfer: scene_preset(kind),
            ..RenderSettings::default()
        };
        let frame = render(&volume, &camera, &settings);
        check(&format!("{}-dvr", kind.name()), &frame.to_image());
    }
}

#[test]
fn other_modes_match_their_golden_images() {
    let volume = scene_volume(SceneKind::Shapes, 48);
    let camera = default_camera(&volume, 96);
    for mode in [Mode::Mip, Mode::Average, Mode::FirstHit] {
        let settings = RenderSettings {
            mode,
            transfer: scene_preset(SceneKind::Shapes),
            background: [0.1, 0.1, 0.15],
            ..RenderSettings::default()
        };
        let frame = render(&volume, &camera, &settings);
        check(&format!("shapes-{}", mode.name()), &frame.to_image());
    }
}

#[test]
fn a_changed_renderer_is_caught_and_the_diff_is_written() {
    // The comparison itself must fail on a real difference and leave a diff image.
    let volume = scene_volume(SceneKind::Shapes, 32);
    let camera = default_camera(&volume, 32);
    let settings = RenderSettings {
        transfer: scene_preset(SceneKind::Shapes),
        ..RenderSettings::default()
    };
    let a = render(&volume, &camera, &settings).to_image();
    let shifted = RenderSettings {
        background: [0.5, 0.0, 0.0],
        ..settings
    };
    let b = render(&volume, &camera, &shifted).to_image();
    let result = std::panic::catch_unwind(|| assert_images_match("self-check", &a, &b, TOLERANCE));
    assert!(
        result.is_err(),
        "a different background must fail the comparison"
    );
    assert!(artifact_dir().join("self-check.diff.png").exists());
}
