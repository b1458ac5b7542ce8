//! Which resolution level of a volume's pyramid a frame samples.
//!
//! The automatic choice takes the coarsest level whose voxel, at the point of the
//! volume nearest to the camera, projects to at most one pixel; a bias shifts it
//! (+1: one level coarser). Volumes without a pyramid always render level 0.

use std::str::FromStr;

use glam::Vec3;

use super::camera::Camera;
use crate::volume::Volume;

/// How to pick the level a frame samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LevelChoice {
    /// The coarsest level whose voxels project to at most a pixel, shifted by
    /// `bias` levels (positive: coarser).
    Auto {
        /// Levels added to the automatic choice.
        bias: f32,
    },
    /// This level (clamped to the coarsest the volume has).
    Fixed(u32),
}

impl Default for LevelChoice {
    fn default() -> Self {
        LevelChoice::Auto { bias: 0.0 }
    }
}

impl FromStr for LevelChoice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(LevelChoice::default());
        }
        s.parse::<u32>().map(LevelChoice::Fixed).map_err(|_| {
            format!("level must be `auto` or a level number (0 = full resolution), not {s:?}")
        })
    }
}

impl LevelChoice {
    /// The level of `volume` to render for `camera` (0 ..= the coarsest level).
    pub fn resolve(self, volume: &Volume, camera: &Camera) -> usize {
        let coarsest = volume.level_count() - 1;
        match self {
            LevelChoice::Fixed(k) => (k as usize).min(coarsest),
            LevelChoice::Auto { bias } => {
                let spacing = Vec3::from(volume.spacing());
                let hi = Vec3::from(volume.dims().map(|d| (d - 1) as f32)) * spacing;
                let nearest = camera.position().clamp(Vec3::ZERO, hi);
                let ratio = camera.pixel_footprint(nearest) / spacing.min_element();
                let level = if ratio > 0.0 {
                    ratio.log2().floor() + bias
                } else {
                    bias
                };
                if level.is_finite() && level > 0.0 {
                    (level as usize).min(coarsest)
                } else {
                    0
                }
            }
        }
    }
}
