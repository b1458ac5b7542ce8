//! Frame quality: the step presets and the coarser frames that keep interaction
//! fluid while the camera moves.

use std::time::Duration;

/// Frame time a moving frame aims for (the pacing budget).
pub const MOVING_BUDGET: Duration = Duration::from_millis(50);
/// Range of the pacing factor P: moving frames are rendered at resolution 0.5/P
/// (and, with [`QualityPolicy::coarse_steps`], twice the still step × P), so
/// P = 0.5 is the still quality.
const PACING_RANGE: (f32, f32) = (0.5, 4.0);
/// Pyramid levels moving frames start coarser than the automatic choice.
const START_LEVEL_BIAS: u32 = 1;
/// A moving frame this many times over the budget with the pacing at its
/// coarsest takes the next coarser pyramid level; one this many times under it
/// with the pacing at still quality, the next finer (a level halves the samples,
/// so the hysteresis keeps the choice from swinging back).
const LEVEL_STEP_RATIO: f32 = 1.5;
/// Moving frames coarsen their step in rungs of this many per doubling: the
/// pre-integration table depends on the step, and a step that followed the
/// pacing continuously would rebuild it for nearly every moving frame (the
/// library caches a few tables: with rungs the pacing settles on one or two).
const STEP_RUNGS_PER_DOUBLING: f32 = 4.0;
/// Moving frames coarser than the still step pre-integrate from this step (in
/// voxels) on: below it, rings and stripes are too fine to see.
const PREINTEGRATE_FROM_STEP: f32 = 1.0;

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
    /// Pre-integrate the transfer function whatever the settings panel says:
    /// moving frames at coarse steps, so that they show no rings or stripes
    /// (the panel's "Pre-integration" decides for still frames).
    pub preintegrated: bool,
}

/// Chooses the quality of still and moving frames, and paces moving frames:
/// their resolution (and step, [`Self::coarse_steps`]) follow a factor learnt
/// from the moving frames before, so that they take about [`MOVING_BUDGET`] —
/// coarser on a slow machine or a large volume, up to the still quality on a
/// fast one.
#[derive(Clone, Debug)]
pub struct QualityPolicy {
    /// The step preset.
    pub preset: StepPreset,
    /// Render moving frames at full quality too (no pacing).
    pub full_quality_only: bool,
    /// Moving frames coarsen their step with their resolution (pre-integrated
    /// from a voxel on): where a sample costs much, on the scalar kernel.
    /// Where the frames' SIMD level has hardware gathers a sample costs
    /// little beside its ray, and a plain step of the still frame's costs
    /// less than a coarser pre-integrated one (a third to a half at the moving
    /// frames' size, docs/viewer.md "Pacing"): moving frames then keep the
    /// still step and coarsen their resolution only.
    pub coarse_steps: bool,
    /// The pacing factor P (see [`PACING_RANGE`]); 1 at the start: half
    /// resolution and twice the still step.
    pacing: f32,
    /// Pyramid levels moving frames sample coarser than the automatic choice
    /// (which already follows their lower resolution), learnt from their times.
    level_bias: u32,
}

impl Default for QualityPolicy {
    fn default() -> Self {
        QualityPolicy {
            preset: StepPreset::Fine,
            full_quality_only: false,
            coarse_steps: !raycaster::render::SimdLevel::automatic().has_gathers(),
            pacing: 1.0,
            level_bias: START_LEVEL_BIAS,
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
            preintegrated: false,
        }
    }

    /// A frame rendered while the camera moves.
    pub fn moving(&self) -> FrameQuality {
        if self.full_quality_only {
            return self.still();
        }
        let (still, resolution) = (self.still(), 0.5 / self.pacing);
        if !self.coarse_steps {
            return FrameQuality {
                resolution,
                ..still
            };
        }
        // 2·P times the still step, rounded to a rung (P = 0.5: the still step).
        let rungs = ((2.0 * self.pacing).log2() * STEP_RUNGS_PER_DOUBLING).round();
        let step = still.step * (rungs / STEP_RUNGS_PER_DOUBLING).exp2();
        FrameQuality {
            resolution,
            step,
            preintegrated: step > still.step && step >= PREINTEGRATE_FROM_STEP,
        }
    }

    /// The pyramid level bias of moving frames: levels coarser than the
    /// automatic choice for their resolution.
    pub fn moving_level_bias(&self) -> f32 {
        self.level_bias as f32
    }

    /// Learns from a finished moving frame: its cost scales with pixels × samples
    /// per ray, i.e. with `factor⁻³` (`factor⁻²` without
    /// [`Self::coarse_steps`]), so the factor moves by the cube (square) root
    /// of the time ratio to the budget. Beyond what resolution and step can do, the
    /// pyramid level follows the budget: a frame well over it with the pacing at
    /// its coarsest makes the next moving frames one level coarser (unless it
    /// sampled the coarsest level, `at_coarsest`), one well under it with the
    /// pacing at still quality one level finer.
    pub fn moving_frame_took(&mut self, time: Duration, at_coarsest: bool) {
        if self.full_quality_only || time.is_zero() {
            return;
        }
        let ratio = time.as_secs_f32() / MOVING_BUDGET.as_secs_f32();
        let (lo, hi) = PACING_RANGE;
        let by = if self.coarse_steps {
            ratio.cbrt()
        } else {
            ratio.sqrt()
        };
        self.pacing = (self.pacing * by).clamp(lo, hi);
        if ratio > LEVEL_STEP_RATIO && self.pacing >= hi && !at_coarsest {
            self.level_bias += 1;
        } else if ratio < 1.0 / LEVEL_STEP_RATIO && self.pacing <= lo {
            self.level_bias = self.level_bias.saturating_sub(1);
        }
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

    /// The policy of coarse moving steps (the scalar kernel's).
    fn coarse_steps() -> QualityPolicy {
        QualityPolicy {
            coarse_steps: true,
            ..QualityPolicy::default()
        }
    }

    #[test]
    fn moving_frames_are_coarser_unless_full_quality_only() {
        let mut q = coarse_steps();
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
                ..coarse_steps()
            };
            let base = q.moving();
            q.moving_frame_took(Duration::from_millis(400), false);
            // 8× the budget: twice as coarse on both counts (cost ÷ 8).
            let paced = q.moving();
            assert!((paced.step / base.step - 2.0).abs() < 1e-4, "{preset:?}");
            assert!((base.resolution / paced.resolution - 2.0).abs() < 1e-4);
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(400), false);
            }
            assert_eq!(q.moving().step, base.step * PACING_RANGE.1);
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(5), false);
            }
            assert_eq!(q.moving(), q.still(), "never finer than a still frame");
            // Frames on budget leave the pacing where it is.
            q.moving_frame_took(Duration::from_millis(400), false);
            let settled = q.moving();
            q.moving_frame_took(MOVING_BUDGET, false);
            assert_eq!(q.moving(), settled);
            // Full quality only: no pacing.
            q.full_quality_only = true;
            q.moving_frame_took(Duration::from_millis(400), false);
            assert_eq!(q.moving(), q.still());
        }
    }

    #[test]
    fn moving_frames_take_a_coarser_level_when_pacing_cannot_keep_the_budget() {
        let mut q = coarse_steps();
        assert_eq!(q.moving_level_bias(), START_LEVEL_BIAS as f32);
        let slow = Duration::from_millis(400);
        // Resolution and step coarsen first; then each slow frame a level.
        q.moving_frame_took(slow, false);
        assert_eq!(q.moving_level_bias(), 1.0, "pacing not at its coarsest yet");
        q.moving_frame_took(slow, false);
        assert_eq!(q.moving().step, q.still().step * 2.0 * PACING_RANGE.1);
        let coarser = q.moving_level_bias();
        assert!(coarser > 1.0);
        q.moving_frame_took(slow, false);
        assert_eq!(q.moving_level_bias(), coarser + 1.0);
        // Not beyond the coarsest level a frame sampled.
        q.moving_frame_took(slow, true);
        assert_eq!(q.moving_level_bias(), coarser + 1.0);
        // Frames on budget, or just under it, keep the level.
        q.moving_frame_took(MOVING_BUDGET, false);
        q.moving_frame_took(MOVING_BUDGET.mul_f32(0.8), false);
        assert_eq!(q.moving_level_bias(), coarser + 1.0);
        // Fast frames: resolution and step come back first, then the levels,
        // down to the automatic choice.
        let fast = Duration::from_millis(5);
        q.moving_frame_took(fast, false);
        assert_eq!(q.moving_level_bias(), coarser + 1.0, "pacing first");
        for _ in 0..20 {
            q.moving_frame_took(fast, false);
        }
        assert_eq!(q.moving(), q.still());
        assert_eq!(q.moving_level_bias(), 0.0);
        // Full quality only: nothing learnt.
        q.full_quality_only = true;
        q.moving_frame_took(slow, false);
        assert_eq!(q.moving_level_bias(), 0.0);
    }

    #[test]
    fn moving_steps_take_rungs_and_pre_integrate_when_coarse() {
        for preset in [StepPreset::Fine, StepPreset::Coarse, StepPreset::Adaptive] {
            let mut q = QualityPolicy {
                preset,
                ..coarse_steps()
            };
            let still = q.still().step;
            let mut steps = Vec::new();
            // Frames slower and slower, then faster and faster: the pacing
            // factor sweeps its range.
            for ms in (1..=40).chain((1..=40).rev()) {
                q.moving_frame_took(Duration::from_millis(ms * 10), false);
                let moving = q.moving();
                let rungs = (moving.step / still).log2() * STEP_RUNGS_PER_DOUBLING;
                assert!(
                    (rungs - rungs.round()).abs() < 1e-3,
                    "{preset:?}: step {} is not a rung above {still}",
                    moving.step
                );
                assert!(moving.step >= still && moving.step <= 8.0 * still);
                assert_eq!(
                    moving.preintegrated,
                    moving.step > still && moving.step >= 1.0,
                    "{preset:?} at step {}",
                    moving.step
                );
                steps.push(moving.step.to_bits());
            }
            steps.sort_unstable();
            steps.dedup();
            assert!(
                steps.len() >= 4 && steps.len() <= 13,
                "{preset:?}: {} distinct steps",
                steps.len()
            );
            assert!(
                !q.still().preintegrated,
                "the panel decides for still frames"
            );
        }
        // The fine preset's first moving frame (twice its half-voxel step) is at
        // one voxel: pre-integrated.
        let q = coarse_steps();
        assert_eq!((q.moving().step, q.moving().preintegrated), (1.0, true));
    }

    #[test]
    fn with_gathers_moving_frames_keep_the_still_step_and_pace_their_resolution() {
        assert_eq!(
            QualityPolicy::default().coarse_steps,
            !raycaster::render::SimdLevel::automatic().has_gathers(),
            "the policy follows the frames' SIMD level"
        );
        for preset in [StepPreset::Fine, StepPreset::Coarse, StepPreset::Adaptive] {
            let mut q = QualityPolicy {
                preset,
                coarse_steps: false,
                ..QualityPolicy::default()
            };
            let still = q.still();
            let base = q.moving();
            assert_eq!((base.step, base.preintegrated), (still.step, false));
            assert_eq!(base.resolution, 0.5, "{preset:?}");
            // 4× the budget: half the resolution (cost ÷ 4).
            q.moving_frame_took(Duration::from_millis(200), false);
            let paced = q.moving();
            assert!((base.resolution / paced.resolution - 2.0).abs() < 1e-4);
            assert_eq!((paced.step, paced.preintegrated), (still.step, false));
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(400), false);
            }
            assert_eq!(q.moving().resolution, 0.5 / PACING_RANGE.1);
            assert_eq!(q.moving().step, still.step, "{preset:?}");
            for _ in 0..20 {
                q.moving_frame_took(Duration::from_millis(5), false);
            }
            assert_eq!(q.moving(), still, "never finer than a still frame");
            q.full_quality_only = true;
            q.moving_frame_took(Duration::from_millis(400), false);
            assert_eq!(q.moving(), still);
        }
    }

    #[test]
    fn frame_sizes_scale_and_never_vanish() {
        let half = FrameQuality {
            resolution: 0.5,
            step: 1.0,
            preintegrated: false,
        };
        assert_eq!(QualityPolicy::frame_size(half, 801, 600), (401, 300));
        assert_eq!(QualityPolicy::frame_size(half, 1, 1), (1, 1));
    }
}
