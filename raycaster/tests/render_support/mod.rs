//! Helpers shared by the rendering tests: volumes from formulas, cameras, images.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use raycaster::render::{
    ControlPoint, Frame, RenderSettings, RenderVolume, RgbImage, TransferFunction, Vec3,
    render_sequential,
};
use raycaster::volume::{Content, Format, Header, Layout, SampleType, Volume};

/// A linear u8 volume in RAM whose voxel (x, y, z) is `f(x, y, z)`.
pub fn volume_u8(dims: [u32; 3], spacing: [f32; 3], f: impl Fn(u32, u32, u32) -> u8) -> Volume {
    let mut samples = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
    for x in 0..dims[0] {
        for y in 0..dims[1] {
            for z in 0..dims[2] {
                samples.push(f(x, y, z));
            }
        }
    }
    let header = Header::new(
        dims,
        spacing,
        Layout::Linear,
        SampleType::U8,
        Content::Scalar,
        Format::Extended,
    );
    Volume::from_samples("test volume", &header, &samples).unwrap()
}

/// A transfer function from `(value, alpha)` pairs with white colour.
pub fn white_tf(points: &[(f32, f32)]) -> TransferFunction {
    TransferFunction::new(
        points
            .iter()
            .map(|&(value, alpha)| ControlPoint {
                value,
                color: [1.0; 3],
                alpha,
            })
            .collect(),
    )
    .unwrap()
}

/// Unshaded settings with `tf`, no ERT, no ESS.
pub fn plain_settings(tf: TransferFunction) -> RenderSettings {
    RenderSettings {
        early_termination: None,
        empty_space_skipping: false,
        shading: None,
        transfer: tf,
        ..RenderSettings::default()
    }
}

/// Renders `volume` sequentially with `camera` and `settings`.
pub fn render(
    volume: &Volume,
    camera: &raycaster::render::Camera,
    settings: &RenderSettings,
) -> Frame {
    let prepared = RenderVolume::new(volume, None).unwrap();
    render_sequential(&prepared, camera, settings).unwrap()
}

/// Where tests leave images for people to look at.
pub fn artifact_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/test-images");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Asserts `actual` matches `expected` within `tolerance` per channel; on failure
/// writes both and an amplified diff image to `target/test-images/`.
pub fn assert_images_match(name: &str, actual: &RgbImage, expected: &RgbImage, tolerance: u8) {
    let diff = actual.max_difference(expected);
    if diff.is_some_and(|d| d <= tolerance) {
        return;
    }
    let dir = artifact_dir();
    actual.save_png(&dir.join(format!("{name}.actual.png"))).unwrap();
    expected.save_png(&dir.join(format!("{name}.expected.png"))).unwrap();
    if diff.is_some() {
        actual
            .diff(expected)
            .save_png(&dir.join(format!("{name}.diff.png")))
            .unwrap();
    }
    panic!(
        "{name}: images differ by {diff:?} (tolerance {tolerance}); see {}",
        dir.display()
    );
}

/// The world centre of a volume's box.
pub fn centre(volume: &Volume) -> Vec3 {
    let d = Vec3::from(volume.dims().map(|d| (d - 1) as f32));
    d * Vec3::from(volume.spacing()) / 2.0
}
