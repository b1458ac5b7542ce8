//! What a frame is rendered with, besides the camera.

use super::segments::SegmentScene;
use super::shading::Shading;
use super::transfer::TransferFunction;

/// How the samples of a whole ray become one pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Emission–absorption, front to back: `c += (1−α)·αs·cs; α += (1−α)·αs`.
    Dvr,
    /// Maximum intensity projection: the largest value along the ray.
    Mip,
    /// Average intensity projection: the mean value along the ray.
    Average,
    /// The first sample at or above the iso-value, shaded as a surface.
    FirstHit,
}

impl Mode {
    /// Every mode, in the order `--help` lists them.
    pub const ALL: [Mode; 4] = [Mode::Dvr, Mode::Mip, Mode::Average, Mode::FirstHit];

    /// The mode's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Dvr => "dvr",
            Mode::Mip => "mip",
            Mode::Average => "average",
            Mode::FirstHit => "first-hit",
        }
    }
}

/// Render settings of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Compositing mode.
    pub mode: Mode,
    /// Distance between samples along a ray, in voxels (of the smallest spacing).
    /// The transfer function's opacities are per one such voxel (the reference step).
    pub step: f32,
    /// Early ray termination: stop a ray once its opacity reaches this; `None` off.
    pub early_termination: Option<f32>,
    /// Empty-space skipping with the per-brick value ranges.
    pub empty_space_skipping: bool,
    /// Blinn-Phong shading (DVR and first hit); `None` renders unshaded colours.
    pub shading: Option<Shading>,
    /// Iso-value of first-hit mode, normalised over the transfer function's domain.
    pub iso_value: f32,
    /// Colour behind the volume (linear RGB in `[0, 1]`).
    pub background: [f32; 3],
    /// The transfer function (and, with segments, the data domain for layers).
    pub transfer: TransferFunction,
    /// Two-level compositing of a segmented volume: when set, each object's own
    /// transfer function and local mode replace `mode` and `transfer`'s colours.
    pub segments: Option<SegmentScene>,
}

/// The default early-ray-termination threshold.
pub const DEFAULT_ERT_THRESHOLD: f32 = 0.99;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            mode: Mode::Dvr,
            step: 0.5,
            early_termination: Some(DEFAULT_ERT_THRESHOLD),
            empty_space_skipping: true,
            shading: Some(Shading::default()),
            iso_value: 0.5,
            background: [0.0; 3],
            transfer: TransferFunction::preset("shapes").expect("built-in preset"),
            segments: None,
        }
    }
}
