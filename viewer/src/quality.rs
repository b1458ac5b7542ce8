//! Frame quality: the step presets and the coarser frames that keep interaction
//! fluid while the camera moves.

use std::time::Duration;

/// Frame time an adaptive interactive frame aims for.
const INTERACTIVE_TARGET: Duration = Duration::from_millis(50);
/// Coarsening range of adaptive interactive frames.
const ADAPTIVE_LEVELS: (f32, f32) = (1.0, 4.0);

/// The step presets of the settings panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepPreset {
    /// Half-voxel steps when still; moving frames at half resolution, step 1.
    Fine,
    /// 1.5-voxel steps; moving frames at half resolution, step 3.
    Coarse,
    /// Unit steps when still; moving frames coarsened (resolution and step
    /// together) so they take about 50 ms, learnt from the previous moving frame.
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

/// Chooses the quality of still and moving frames.
#[derive(Clone, Debug)]
pub struct QualityPolicy {
    /// The step preset.
    pub preset: StepPreset,
    /// Render moving frames at full quality too.
    pub full_quality_only: bool,
    /// Coarsening of adaptive moving frames (resolution 1/level, step level).
    adaptive_level: f32,
}

impl Default for QualityPolicy {
    fn default() -> Self {
        QualityPolicy {
            preset: StepPreset::Fine,
            full_quality_only: false,
            adaptive_level: 2.0,
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
        match self.preset {
            StepPreset::Fine => FrameQuality {
                resolution: 0.5,
                step: 1.0,
            },
            StepPreset::Coarse => FrameQuality {
                resolution: 0.5,
                step: 3.0,
            },
            StepPreset::Adaptive => FrameQuality {
                resolution: 1.0 / self.adaptive_level,
                step: self.adaptive_level,
            },
        }
    }

    /// Learns from a finished moving frame: its cost scales with pixels × samples
    /// per ray, i.e. with `level⁻³`, so the level moves by the cube root of the
    /// time ratio.
    pub fn moving_frame_took(&mut self, time: Duration) {
        if self.preset != StepPreset::Adaptive || time.is_zero() {
            return;
        }
        let ratio = time.as_secs_f32() / INTERACTIVE_TARGET.as_secs_f32();
        let (lo, hi) = ADAPTIVE_LEVELS;
        self.adaptive_level = (self.adaptive_level * ratio.cbrt()).clamp(lo, hi);
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
    fn adaptive_frames_coarsen_when_slow_and_refine_when_fast() {
        let mut q = QualityPolicy {
            preset: StepPreset::Adaptive,
            ..QualityPolicy::default()
        };
        let start = q.moving().step;
        q.moving_frame_took(Duration::from_millis(400));
        assert!(q.moving().step > start);
        for _ in 0..20 {
            q.moving_frame_took(Duration::from_millis(400));
        }
        assert_eq!(q.moving().step, ADAPTIVE_LEVELS.1);
        for _ in 0..20 {
            q.moving_frame_took(Duration::from_millis(5));
        }
        assert_eq!(q.moving().step, ADAPTIVE_LEVELS.0);
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
