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
        // A fixed X-ray gain: the analytic expectations are written for 1, and
        // a crop must render as the sub-volume it keeps, whose diagonal (the
        // automatic gain's) is shorter.
        mode_parameters: raycaster::render::ModeParameters {
            xray_gain: Some(1.0),
            ..Default::default()
        },
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
    actual
        .save_png(&dir.join(format!("{name}.actual.png")))
        .unwrap();
    expected
        .save_png(&dir.join(format!("{name}.expected.png")))
        .unwrap();
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

/// A built-in scene of `n³` voxels, linear, in RAM.
pub fn scene_volume(kind: raycaster::synth::SceneKind, n: u32) -> Volume {
    let scene = kind.build([n; 3], 7);
    raycaster::synth::synthesize(
        scene.as_ref(),
        kind.name(),
        [n; 3],
        [1.0; 3],
        SampleType::U8,
    )
    .unwrap()
}

/// The same scene written as a file with `layout` and opened with `access`.
pub fn scene_file(
    dir: &Path,
    kind: raycaster::synth::SceneKind,
    n: u32,
    layout: Layout,
    sample_type: SampleType,
    access: raycaster::volume::Access,
) -> Volume {
    let scene = kind.build([n; 3], 7);
    let header = Header::new(
        [n; 3],
        [1.0; 3],
        layout,
        sample_type,
        Content::Scalar,
        Format::Extended,
    );
    let path = dir.join(format!(
        "{}-{n}-{layout:?}-{sample_type:?}.vol",
        kind.name()
    ));
    if !path.exists() {
        raycaster::generate::generate(
            scene.as_ref(),
            &header,
            &path,
            &raycaster::io::WriteOptions::default(),
            &raycaster::job::Job::silent(),
        )
        .unwrap();
    }
    let options = raycaster::volume::OpenOptions {
        access,
        write_ranges_sidecar: false,
    };
    Volume::open_with(&path, options).unwrap()
}

/// The preset that suits a built-in scene.
pub fn scene_preset(kind: raycaster::synth::SceneKind) -> TransferFunction {
    use raycaster::synth::SceneKind;
    let name = match kind {
        SceneKind::Shapes => "shapes",
        SceneKind::Shells => "shells",
        SceneKind::Noise => "cloud",
        SceneKind::Gradient => "rainbow",
    };
    TransferFunction::preset(name).unwrap()
}

/// The default orbit view of a volume.
pub fn default_camera(volume: &Volume, size: u32) -> raycaster::render::Camera {
    let (lo, hi) = (Vec3::ZERO, centre(volume) * 2.0);
    raycaster::render::Orbit::default_view(lo, hi)
        .camera(size, size)
        .unwrap()
}

/// Renders with an explicit logical brick side for linear volumes.
pub fn render_bricked(
    volume: &Volume,
    brick: Option<u32>,
    camera: &raycaster::render::Camera,
    settings: &RenderSettings,
) -> Frame {
    let prepared = RenderVolume::new(volume, brick).unwrap();
    render_sequential(&prepared, camera, settings).unwrap()
}

/// The `shapes` scene as a 256³ u8 file, bricked (side 16) and mapped, with
/// pyramid levels 0–2: what frames of several levels are tested on.
pub fn pyramid_shapes(dir: &Path) -> Volume {
    scene_file(
        dir,
        raycaster::synth::SceneKind::Shapes,
        256,
        Layout::Bricked { side: 16 },
        SampleType::U8,
        raycaster::volume::Access::Mapped,
    )
}

/// A wide view of `volume` from `distance` to its centre (azimuth in radians,
/// elevation 0.3): perspective with a 90° field, or orthographic 300 units high.
pub fn wide_view(
    volume: &Volume,
    distance: f32,
    azimuth: f32,
    orthographic: bool,
    width: u32,
    height: u32,
) -> raycaster::render::Camera {
    let c = centre(volume);
    raycaster::render::Orbit {
        target: c,
        distance,
        azimuth,
        elevation: 0.3,
        vfov_deg: (!orthographic).then_some(90.0),
        ortho_height: 300.0,
        ..raycaster::render::Orbit::default_view(Vec3::ZERO, c * 2.0)
    }
    .camera(width, height)
    .unwrap()
}

/// The levels of `volume` that `bands` sample, prepared (default bricks).
pub fn prepare_levels<'v>(
    volume: &'v Volume,
    bands: &[raycaster::render::LevelBand],
) -> Vec<RenderVolume<'v>> {
    bands
        .iter()
        .map(|b| RenderVolume::new(volume.level(b.level), None).unwrap())
        .collect()
}

/// The passes of a frame of several levels: each prepared level with its band.
pub fn level_passes<'p, 'v>(
    levels: &'p [RenderVolume<'v>],
    bands: &[raycaster::render::LevelBand],
) -> Vec<(&'p RenderVolume<'v>, Option<raycaster::render::DepthBand>)> {
    levels
        .iter()
        .zip(bands)
        .map(|(l, b)| (l, b.depth))
        .collect()
}
