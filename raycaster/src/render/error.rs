//! Errors of rendering: bad settings found before a frame, and worker threads the
//! system refuses; a frame that starts cannot fail.

use super::camera::CameraError;

/// Why a frame cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The step is not a positive finite number.
    #[error("step {0} must be a positive number of voxels")]
    Step(f32),
    /// The early-termination threshold is outside (0, 1].
    #[error("early termination threshold {0} must lie in (0, 1]")]
    ErtThreshold(f32),
    /// A setting out of its range (a field set in code: files are checked as
    /// they are read).
    #[error("{field}: {what}")]
    Setting {
        /// The field, as the library names it (`transfer.domain`).
        field: String,
        /// What is wrong.
        what: String,
    },
    /// The iso-value is outside [0, 1].
    #[error("iso-value {0} must lie in [0, 1] (normalised over the transfer function's domain)")]
    IsoValue(f32),
    /// A logical brick side below 2.
    #[error("brick side {0} is too small (at least 2)")]
    BrickSide(u32),
    /// A two-level scene object's crop box or planes are wrong.
    #[error("scene object {object:?}: {source}")]
    ObjectClip {
        /// The object's name.
        object: String,
        /// What is wrong.
        source: Box<RenderError>,
    },
    /// A logical brick that does not tile the file's bricks.
    #[error(
        "brick side {side} does not tile the file's bricks of side {file_side}: bricks share a voxel with their neighbours, so a sub-brick of side s advances s−1 voxels, and s−1 must divide {}; sides that tile them are {}",
        file_side.saturating_sub(1),
        sub_brick_sides(*file_side)
    )]
    SubBrick {
        /// The side asked for.
        side: u32,
        /// The file's brick side.
        file_side: u32,
    },
    /// A label scene without a label volume, or a label volume that does not fit.
    #[error("labels: {0}")]
    Labels(String),
    /// A frame of several pyramid levels that cannot be rendered so.
    #[error("levels: {0}")]
    Levels(&'static str),
    /// A frame would take more samples than any render should: an absurd spacing
    /// ratio or a tiny step. Refused up front instead of rendering "forever".
    #[error(
        "a ray would take up to {per_ray:.3e} samples and the frame up to {per_frame:.3e} (limits {max_ray:.0e} and {max_frame:.0e}): {}",
        budget_cause(*spacing, *ratio, *step)
    )]
    SampleBudget {
        /// Samples one ray may take.
        per_ray: f64,
        /// Samples the whole frame may take.
        per_frame: f64,
        /// Limit per ray.
        max_ray: f64,
        /// Limit per frame.
        max_frame: f64,
        /// The volume's spacing.
        spacing: [f32; 3],
        /// Largest over smallest spacing.
        ratio: f64,
        /// The step, in units of the smallest spacing.
        step: f32,
    },
    /// A kernel level this machine cannot run.
    #[error(
        "the {0} kernel needs an instruction set this CPU lacks (available here: {available})",
        available = super::simd::available().iter().map(|l| l.name()).collect::<Vec<_>>().join(", ")
    )]
    Simd(super::simd::SimdLevel),
    /// A distributed frame failed between ranks (a message not delivered or
    /// malformed).
    #[error("distributed rendering: {0}")]
    Distributed(String),
    /// Direct-send compositing asked for a frame it cannot composite.
    #[error(
        "direct-send compositing composites partial images with \"over\": plain DVR without pre-integration only (the relay serves every mode)"
    )]
    DirectSendMode,
    /// A crop box or clipping plane that cuts nothing sensible (inverted box,
    /// zero normal, not finite, too many planes).
    #[error("clip region: {0}")]
    Clip(String),
    /// The camera is invalid.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The system refused the memory of a frame's pixels.
    #[error(
        "a {width}×{height} frame takes {} and the system refused that much memory; render a smaller image",
        crate::files::human_bytes(*bytes)
    )]
    FrameMemory {
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Bytes of the frame's pixels.
        bytes: u64,
    },
    /// The system refused the renderer's worker threads (an address-space or
    /// process limit).
    #[error(
        "the system refused the renderer's threads ({count} asked for): {reason}; raise the limit (ulimit -v, ulimit -u) or ask for fewer threads"
    )]
    Threads {
        /// Threads asked for.
        count: usize,
        /// The system's refusal.
        reason: String,
    },
}

/// What makes a frame's rays too long ([`RenderError::SampleBudget`]): a
/// lopsided spacing (a broken header), else the step.
fn budget_cause([x, y, z]: [f32; 3], ratio: f64, step: f32) -> String {
    if ratio >= 10.0 {
        format!(
            "the spacing {x} x {y} x {z} puts {ratio:.3e} of the smallest spacing in the largest, and the step is {step} of the smallest; check the file's spacing or raise the step"
        )
    } else {
        format!(
            "the step is {} voxel; raise the step (`--step`, or `step` in a session's [render]; 0.5 is the default)",
            crate::volume::number_text(step)
        )
    }
}

/// The logical brick sides that tile a file's bricks of side `file_side`
/// (`side − 1` divides `file_side − 1`), smallest first, as a list.
fn sub_brick_sides(file_side: u32) -> String {
    let step = file_side.saturating_sub(1).max(1);
    let sides: Vec<String> = (1..=step)
        .filter(|d| step.is_multiple_of(*d))
        .map(|d| (d + 1).to_string())
        .collect();
    sides.join(", ")
}
