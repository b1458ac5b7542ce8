//! Frame quality: the step presets and the coarser frames that keep interaction
//! fluid while the camera moves.

use std::time::Duration;

/// Frame time a moving frame aims for (the pacing budget).
pub const MOVING_BUDGET: Duration = Duration::from_millis(50);
/// Range of the pacing factor P: moving frames are rendered at resolution 0.5/P
/// and twice the still step × P, so P = 0.5 is the still quality.
const PACING_RANGE: (f32, f32) = (0.5, 4.0);

/// The step presets of the settings panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepPreset {
    /// Half-voxel steps.
    Fine,
    /// 1.5-voxel steps.
    Coarse,
    /// Unit steps.
    Adaptive,
}

impl StepPreset {
    /// The preset at `index` of the panel's list (fine, coarse, adaptive).
    pub fn from_index(index: i32) -> StepPreset {
        match index {
            1 => StepPreset::Coarse,
            2 => StepPreset::Adaptive,
            _ => StepPreset::Fine,
        }
    }
}

/// How one frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameQuality {
    /// Image resolution as a fraction of the canvas (1 = full).
    pub resolution: f32,
    /// Sampling step in voxels.
    pub step: f32,
}

/// Chooses the quality of still and moving frames, and paces moving frames:
/// their resolution and step follow a factor learnt from the moving frames
/// before, so that they take about [`MOVING_BUDGET`] — coarser on a slow machine
/// or a large volume, up to the still quality on a fast one.
#[derive(Clone, Debug)]
pub struct QualityPolicy {
    /// The step preset.
    pub preset: StepPreset,
    /// Render moving frames at full quality too (no pacing).
    pub full_quality_only: bool,
    /// The pacing factor P (see [`PACING_RANGE`]); 1 at the start: half
    /// resolution and twice the still step.
    pacing: f32,
}

impl Default for QualityPolicy {
    fn default() -> Self {
        QualityPolicy {
            preset: StepPreset::Fine,
            full_quality_only: false,
            pacing: 1.0,
        }
    }
}

impl QualityPolicy {
    /// The full-quality frame shown when the camera rests.
    pub fn still(&self) -> FrameQuality {
        let step = match self.preset {
            StepPreset::Fine => 0.5,
            StepPreset::Coarse => 1.5,
            StepPreset::Adaptive => 1.0,
        };
        FrameQuality {
            resolution: 1.0,
            step,
        }
    }

    /// A frame rendered while the camera moves.
    pub fn moving(&self) -> FrameQuality {
        if self.full_quality_only {
            return self.still();
        }
        FrameQuality {
            resolution: 0.5 / self.pacing,
            step: 2.0 * self.still().step * self.pacing,
        }
    }

    /// Learns from a finished moving frame: its cost scales with pixels × samples
    /// per ray, i.e. with `factor⁻³`, so the factor moves by the cube root of the
    /// time ratio to the budget.
    pub fn moving_frame_took(&mut self, time: Duration) {
        if self.full_quality_only || time.is_zero() {
            return;
        }
        let ratio = time.as_secs_f32() / MOVING_BUDGET.as_secs_f32();
        let (lo, hi) = PACING_RANGE;
        self.pacing = (self.pacing * ratio.cbrt()).clamp(lo, hi);
    }

    /// The size of a frame for a canvas of `width × height` physical pixels.
    pub fn frame_size(quality: FrameQuality, width: u32, height: u32) -> (u32, u32) {
        let scale = |n: u32| ((n as f32 * quality.resolution).round() as u32).max(1);
        (scale(width), scale(height))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_frames_are_coarser_unless_full_quality_only() {
        let mut q = QualityPolicy::default();
        for preset in [StepPreset::Fine, StepPreset::Coarse, StepPreset::Adaptive] {
            q.preset = preset;
            q.full_quality_only = false;
            let (still, moving) = (q.still(), q.moving());
            assert_eq!(still.resolution, 1.0);
            assert!(
                moving.resolution < 1.0 && moving.step > still.step,
                "{preset:?}"
            );
            q.full_quality_only = true;
            assert_eq!(q.moving(), q.still());
        }
    }

    #[test]
    fn every_preset_paces_moving_frames_coarser_when_slow_and_back_when_fast() {
        for preset in [StepPreset::Fine, StepPreset::Coarse, StepPreset::Adaptive] {
            let mut q = QualityPolicy {
                preset,
                ..QualityPolicy::default()
            };
            let base = q.moving();
            q.moving_frame_took(Duration::from_millis(400));
            // 8× the budget: twice as coarse on both counts (cost ÷ 8).
            let paced = q.moving();
            assert!((paced.step / base.step - 2.0).abs() < 1e-4, "{preset:?}");
            assert!((base.resolution / paced.resolution - 2.0).abs() < 1e-4);
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(400));
            }
            assert_eq!(q.moving().step, base.step * PACING_RANGE.1);
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(5));
            }
            assert_eq!(q.moving(), q.still(), "never finer than a still frame");
            // Frames on budget leave the pacing where it is.
            q.moving_frame_took(Duration::from_millis(400));
            let settled = q.moving();
            q.moving_frame_took(MOVING_BUDGET);
            assert_eq!(q.moving(), settled);
            // Full quality only: no pacing.
            q.full_quality_only = true;
            q.moving_frame_took(Duration::from_millis(400));
            assert_eq!(q.moving(), q.still());
        }
    }

    #[test]
    fn frame_sizes_scale_and_never_vanish() {
        let half = FrameQuality {
            resolution: 0.5,
            step: 1.0,
        };
        assert_eq!(QualityPolicy::frame_size(half, 801, 600), (401, 300));
        assert_eq!(QualityPolicy::frame_size(half, 1, 1), (1, 1));
    }
}
