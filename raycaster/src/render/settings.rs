//! What a frame is rendered with, besides the camera.

use super::clip::ClipRegion;
use super::sabella::SabellaOutput;
use super::segments::{ImportanceSource, LocalMode, SegmentScene};
use super::shading::Shading;
use super::simd::SimdLevel;
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
    /// The first sample at or above the iso-value (refined between samples),
    /// shaded as a surface.
    FirstHit,
    /// X-ray: the sum of values along the ray times the step, as opacity
    /// `1 − exp(−gain·Σ)` ([`ModeParameters::xray_gain`]).
    XRay,
    /// Importance-aware compositing ([`ModeParameters::importance`]).
    Importance,
    /// Context-preserving rendering ([`ModeParameters::context`]).
    ContextPreserving,
    /// Tone shading and silhouette darkening.
    Silhouette,
    /// Sabella's colouring: the peak value, its depth (or the centroid) and the
    /// accumulated intensity as hue, saturation and value
    /// ([`ModeParameters::sabella`]).
    Sabella,
}

impl Mode {
    /// Every mode, in the order `--help` lists them.
    pub const ALL: [Mode; 9] = [
        Mode::Dvr,
        Mode::Mip,
        Mode::Average,
        Mode::FirstHit,
        Mode::XRay,
        Mode::Importance,
        Mode::ContextPreserving,
        Mode::Silhouette,
        Mode::Sabella,
    ];

    /// The mode's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Dvr => "dvr",
            Mode::Mip => "mip",
            Mode::Average => "average",
            Mode::FirstHit => "first-hit",
            Mode::XRay => "xray",
            Mode::Importance => "importance",
            Mode::ContextPreserving => "context",
            Mode::Silhouette => "silhouette",
            Mode::Sabella => "sabella",
        }
    }

    /// The local mode of two-level compositing that composites like this mode,
    /// with `parameters` and first-hit iso-value `iso` (normalised).
    pub fn local(self, parameters: &ModeParameters, iso: f32) -> LocalMode {
        match self {
            Mode::Dvr => LocalMode::Dvr,
            Mode::Mip => LocalMode::Mip,
            Mode::Average => LocalMode::Average,
            Mode::FirstHit => LocalMode::FirstHit { iso },
            Mode::XRay => LocalMode::XRay {
                gain: parameters.xray_gain,
            },
            Mode::Importance => LocalMode::Importance {
                source: parameters.importance,
            },
            Mode::ContextPreserving => LocalMode::ContextPreserving {
                kt: parameters.context[0],
                ks: parameters.context[1],
            },
            Mode::Silhouette => LocalMode::Silhouette,
            Mode::Sabella => LocalMode::Sabella {
                output: parameters.sabella,
            },
        }
    }
}

/// The X-ray gain a frame takes unless one is given: [`AUTO_XRAY_DEPTH`] ÷ the
/// volume's diagonal in level-0 voxels (of its smallest spacing), so that a ray
/// through the whole volume in material of half the domain's value reaches
/// opacity `1 − e^−2` (86 %): an X-ray at every size. A fixed gain of 1 turned
/// every volume larger than a few dozen voxels into a flat saturated shape.
pub fn auto_xray_gain(diagonal: f32) -> f32 {
    AUTO_XRAY_DEPTH / diagonal.max(1.0)
}

/// What to say of a `step` (in the smallest spacing) longer than a volume's
/// diagonal (`Volume::diagonal_voxels`): every ray then takes one sample at
/// most, a legal but empty frame. `None` for sensible steps.
pub fn step_past_volume(step: f32, diagonal: f32) -> Option<String> {
    (step > diagonal).then(|| {
        format!(
            "a step of {} is longer than the volume's diagonal ({diagonal:.0} of its smallest spacing): each ray takes one sample at most (0.5 is the default)",
            crate::volume::number_text(step)
        )
    })
}

/// What to say of a frame of `settings` over a volume of `dims` voxels that
/// is one voxel thick along an axis (a 2D image, a single slice, a line): its
/// sampled box has no depth there, so the modes that accumulate along the ray
/// (DVR and its importance-aware, context-preserving and silhouette forms,
/// Sabella, X-ray, two-level scenes) accumulate nothing and the picture is
/// background; MIP, average and first hit show it. `None` otherwise.
pub fn flat_volume(dims: [u32; 3], settings: &RenderSettings) -> Option<String> {
    let absorbs = settings.segments.is_some()
        || !matches!(settings.mode, Mode::Mip | Mode::Average | Mode::FirstHit);
    let flat: Vec<&str> = ["x", "y", "z"]
        .into_iter()
        .zip(dims)
        .filter(|&(_, d)| d < 2)
        .map(|(axis, _)| axis)
        .collect();
    (absorbs && !flat.is_empty()).then(|| {
        let [x, y, z] = dims;
        format!(
            "{x}x{y}x{z} voxels, one voxel thick along {}: rays cross it in no depth, and this mode accumulates nothing there (the picture is background); --mode mip, or `raycaster slice`, shows it",
            flat.join(" and ")
        )
    })
}

/// The automatic X-ray gain's numerator ([`auto_xray_gain`]): about 0.036 for
/// a 128³ volume, 0.0096 for a 512 × 512 × 48 CT of 0.57 × 0.57 × 5 mm voxels.
pub const AUTO_XRAY_DEPTH: f32 = 8.0;

/// Parameters of the modes that have some (the defaults of scene descriptions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeParameters {
    /// X-ray gain, or `None` for [`auto_xray_gain`] of the volume rendered.
    pub xray_gain: Option<f32>,
    /// Context-preserving κt and κs.
    pub context: [f32; 2],
    /// Where importance-aware compositing takes a sample's importance.
    pub importance: ImportanceSource,
    /// Sabella's colouring: the mapping to colours (or raw channels).
    pub sabella: SabellaOutput,
}

impl Default for ModeParameters {
    fn default() -> Self {
        ModeParameters {
            xray_gain: None,
            context: [1.5, 0.4],
            importance: ImportanceSource::Constant(1.0),
            sabella: SabellaOutput::default(),
        }
    }
}

/// Render settings of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Compositing mode.
    pub mode: Mode,
    /// Parameters of the X-ray, importance and context-preserving modes.
    pub mode_parameters: ModeParameters,
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
    /// The marching kernel: `None` for [`SimdLevel::automatic`] (the sequential
    /// renderer: the scalar loop, faster there), [`SimdLevel::Scalar`] for one
    /// sample at a time (the reference), or a packet level (an error if this
    /// CPU lacks it), which both renderers then use.
    pub simd: Option<SimdLevel>,
    /// Pre-integrated transfer tables (Engel et al. 2001) for DVR, plain and the
    /// DVR segments of two-level scenes: each sample stands for the segment to
    /// the next one with the value going linearly between them, so thin features
    /// and steep ramps between samples are not missed. 1D transfer functions only
    /// (2D ones render as without). Off by default (see `docs/rendering.md`).
    pub preintegrated: bool,
    /// Per-pixel ray-start jitter: each ray's first sample moves by a
    /// deterministic per-pixel fraction of a step (interleaved gradient noise),
    /// trading the stripe and ring moiré of fixed sample positions for fine noise.
    pub jitter: bool,
    /// The part of the volume shown: a crop box and clipping planes (in voxel
    /// coordinates); everything by default. Rays keep their samples inside it at
    /// their global places; bricks entirely outside are left out.
    pub clip: ClipRegion,
}

/// The default early-ray-termination threshold.
pub const DEFAULT_ERT_THRESHOLD: f32 = 0.99;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            mode: Mode::Dvr,
            mode_parameters: ModeParameters::default(),
            step: 0.5,
            early_termination: Some(DEFAULT_ERT_THRESHOLD),
            empty_space_skipping: true,
            shading: Some(Shading::default()),
            iso_value: 0.5,
            background: [0.0; 3],
            transfer: TransferFunction::preset("shapes").expect("built-in preset"),
            segments: None,
            simd: None,
            preintegrated: false,
            jitter: false,
            clip: ClipRegion::default(),
        }
    }
}

impl RenderSettings {
    /// Whether frames of these settings use pre-integrated tables:
    /// [`Self::preintegrated`] in DVR, or for a two-level scene's DVR objects
    /// (other modes ignore it).
    pub fn preintegrates(&self) -> bool {
        self.preintegrated && (self.mode == Mode::Dvr || self.segments.is_some())
    }

    /// Whether direct-send compositing (partial images composited with
    /// "over") composites frames of these settings: plain DVR without
    /// pre-integration (a pre-integrated sample's segment reaches the next
    /// sample, which may lie in another rank's part: the seams would lose it).
    pub fn direct_send_composites(&self) -> bool {
        self.mode == Mode::Dvr && self.segments.is_none() && !self.preintegrates()
    }
}
