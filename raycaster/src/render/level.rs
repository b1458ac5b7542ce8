//! Which resolution level of a volume's pyramid a frame samples.
//!
//! The automatic choice takes the coarsest level whose voxel, at the point of the
//! volume nearest to the camera, projects to at most one pixel along every axis
//! (measured along the axis of the largest spacing: a CT's 5 mm slices, where
//! its pixels are 0.6 mm); a bias shifts it (+1: one level coarser). Volumes
//! without a pyramid always render level 0.

use std::str::FromStr;

use glam::Vec3;

use super::camera::{Camera, Projection};
use super::ray::box_corners;
use super::settings::RenderSettings;
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
    /// The coarsest level of `volume`, when this is a fixed level past it: the
    /// frame then renders the coarsest (a warning's matter, not an error).
    pub fn past_coarsest(self, volume: &Volume) -> Option<usize> {
        let coarsest = volume.level_count().saturating_sub(1);
        match self {
            LevelChoice::Fixed(k) if k as usize > coarsest => Some(coarsest),
            _ => None,
        }
    }

    /// The one level of `volume` to render for `camera` (0 ..= the coarsest
    /// level): for [`LevelChoice::Auto`], the level at the volume's point nearest
    /// to the camera (what frames of a single level sample: two-level scenes,
    /// direct-send compositing; the nearest band of [`Self::bands`], which lets
    /// the level change with depth).
    pub fn resolve(self, volume: &Volume, camera: &Camera) -> usize {
        let coarsest = volume.level_count() - 1;
        match self {
            LevelChoice::Fixed(k) => (k as usize).min(coarsest),
            LevelChoice::Auto { bias } => {
                let spacing = Vec3::from(volume.spacing());
                let hi = Vec3::from(volume.dims().map(|d| (d - 1) as f32)) * spacing;
                let nearest = camera.position().clamp(Vec3::ZERO, hi);
                let ratio = camera.pixel_footprint(nearest) / coarsest_spacing(volume);
                level_of_ratio(ratio, bias, coarsest)
            }
        }
    }

    /// The levels a frame of `volume` seen by `camera` samples, nearest first:
    /// each level in the band of depths (along the view) where its voxel is the
    /// coarsest that projects to at most a pixel (shifted by the bias), from
    /// [`Self::resolve`]'s level nearest to the camera to the level at the
    /// volume's farthest corner.
    ///
    /// A perspective view deep enough to span several levels gets several bands,
    /// consecutive levels meeting at the depths `2^(k − bias)·spacing / pixel
    /// angle`; an orthographic view, a [`LevelChoice::Fixed`] level and a volume
    /// without a pyramid get one band of [`Self::resolve`]'s level, unbounded (a
    /// frame of one band is exactly the frame of that level).
    pub fn bands(self, volume: &Volume, camera: &Camera) -> Vec<LevelBand> {
        let single = |level| vec![LevelBand { level, depth: None }];
        let coarsest = volume.level_count() - 1;
        let LevelChoice::Auto { bias } = self else {
            return single(self.resolve(volume, camera));
        };
        if coarsest == 0 || matches!(camera.projection(), Projection::Orthographic { .. }) {
            return single(self.resolve(volume, camera));
        }
        // Depth of a point along the view, and the footprint per unit of depth.
        let eye = camera.position();
        let axis = camera.direction();
        let per_depth = camera.pixel_footprint(eye + axis);
        let spacing = coarsest_spacing(volume);
        // The depths the levels' boxes span (all of them: coarse boxes can reach
        // half a coarse voxel beyond level 0's).
        let (lo, hi) = levels_box(volume);
        let far = box_corners(lo, hi)
            .iter()
            .fold(f32::NEG_INFINITY, |f, &p| f.max((p - eye).dot(axis)));
        let level_at = |z: f32| level_of_ratio(z.max(0.0) * per_depth / spacing, bias, coarsest);
        // The nearest band is [`Self::resolve`]'s level (at the volume's point
        // nearest to the camera); the farthest, the level at the farthest corner.
        let first = self.resolve(volume, camera);
        let last = level_at(far).max(first);
        if first == last || !(per_depth > 0.0 && spacing > 0.0) {
            return single(first);
        }
        // Level k starts where z·per_depth/spacing reaches 2^(k − bias).
        let start = |k: usize| (k as f32 - bias).exp2() * spacing / per_depth;
        (first..=last)
            .map(|k| LevelBand {
                level: k,
                depth: Some(DepthBand {
                    eye,
                    axis,
                    near: if k == first {
                        f32::NEG_INFINITY
                    } else {
                        start(k)
                    },
                    far: if k == last {
                        f32::INFINITY
                    } else {
                        start(k + 1)
                    },
                    anchor_lo: lo,
                    anchor_hi: hi,
                    finer_levels: (k - first) as u32,
                }),
            })
            .collect()
    }

    /// The levels a frame with `settings` samples, of the first `levels` levels of
    /// `volume` (those prepared: with a label volume, the levels both have):
    /// [`Self::bands`], or for a two-level scene one level, [`Self::resolve`]'s
    /// (its segments would be cut where levels meet). What `raycaster render` and
    /// the viewer both render.
    pub fn frame_bands(
        self,
        volume: &Volume,
        camera: &Camera,
        settings: &RenderSettings,
        levels: usize,
    ) -> Vec<LevelBand> {
        let coarsest = levels.max(1) - 1;
        let single = || {
            vec![LevelBand {
                level: self.resolve(volume, camera).min(coarsest),
                depth: None,
            }]
        };
        if settings.segments.is_some() {
            return single();
        }
        let bands = self.bands(volume, camera);
        if bands.iter().any(|b| b.level > coarsest) {
            return single();
        }
        bands
    }
}

/// The largest of `volume`'s spacings (level 0): a level's voxels project to at
/// most a pixel when they do along that axis. (The finest axis, the measure
/// before, let a CT of 5 mm slices 0.6 mm pixels apart drop to 20 mm slices in
/// a 256-pixel frame, losing its ribs.)
fn coarsest_spacing(volume: &Volume) -> f32 {
    volume.spacing().into_iter().fold(0.0, f32::max)
}

/// The level for a voxel-to-pixel `ratio` (pixel footprint over the level-0
/// spacing): `floor(log2 ratio) + bias`, clamped to `0..=coarsest`.
fn level_of_ratio(ratio: f32, bias: f32, coarsest: usize) -> usize {
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

/// The world box holding every level of `volume`'s pyramid (a coarse level's box
/// sits half a coarse voxel inside level 0's, and may reach beyond it where a
/// dimension was odd).
fn levels_box(volume: &Volume) -> (Vec3, Vec3) {
    (0..volume.level_count()).fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), k| {
            let level = volume.level(k);
            let origin = Vec3::from(level.origin());
            let last = Vec3::from(level.dims().map(|d| (d - 1) as f32));
            let top = origin + last * Vec3::from(level.spacing());
            (lo.min(origin), hi.max(top))
        },
    )
}

/// One level of a frame and the depths it samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelBand {
    /// The pyramid level.
    pub level: usize,
    /// The depths it samples; `None`: all (a frame of one level).
    pub depth: Option<DepthBand>,
}

/// The part of a frame of several levels that one level samples: the points whose
/// depth along the view, `(p − eye)·axis`, lies in `[near, far)`.
///
/// Every level of the frame places its samples on one lattice per ray, anchored
/// where the ray enters the box of all levels (moved on by the ray's jitter):
/// level `k`'s step is `2^k` times the finest level's, so a coarser level's
/// samples are a subset of a finer one's. A boundary between two levels is moved
/// to the coarser level's first sample at or beyond it (`DepthBand::ray_interval`):
/// the finer level's last sample there stands for a whole step, and the coarser
/// level's first sample takes over exactly where it ends — no gap and no overlap
/// (no crack) between levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthBand {
    eye: Vec3,
    axis: Vec3,
    near: f32,
    far: f32,
    anchor_lo: Vec3,
    anchor_hi: Vec3,
    /// Levels between the frame's finest and this one: this level's step is
    /// `2^finer_levels` times the finest's.
    finer_levels: u32,
}

impl DepthBand {
    /// Whether the world box `[lo, hi]` may hold a sample of this band with step
    /// `dt` (the band's far end moves by up to one coarser step).
    pub(crate) fn may_hold(&self, lo: Vec3, hi: Vec3, dt: f32) -> bool {
        let (mut near, mut far) = (f32::INFINITY, f32::NEG_INFINITY);
        for p in box_corners(lo, hi) {
            let z = (p - self.eye).dot(self.axis);
            near = near.min(z);
            far = far.max(z);
        }
        let margin = 2.0 * dt + 1e-4 * (near.abs() + far.abs());
        far >= self.near - margin && near <= self.far + margin
    }

    /// Where samples of a ray starting at `origin` in world direction `direction`
    /// (unit) are anchored with a step of `dt` (this level's) and a `jitter` in
    /// `[0, 1)` of the finest level's step: the parameter of the finest level's
    /// first sample; `None` when the ray misses every level's box.
    pub(crate) fn anchor(
        &self,
        origin: Vec3,
        direction: Vec3,
        dt: f32,
        jitter: f32,
    ) -> Option<f32> {
        let ray = super::ray::Ray { origin, direction };
        let (t, _) = ray.intersect_box(self.anchor_lo, self.anchor_hi)?;
        let finest_dt = dt / (1u64 << self.finer_levels) as f32;
        Some(t + jitter * finest_dt)
    }

    /// The parameter interval `[t0, t1)` of the ray this level samples, for a ray
    /// anchored at `anchor` with this level's step `dt`: the band's depths, each
    /// end moved to its coarser level's lattice (`t0` to this level's, `t1` to the
    /// next coarser level's, step `2·dt`).
    pub(crate) fn ray_interval(
        &self,
        origin: Vec3,
        direction: Vec3,
        anchor: f32,
        dt: f32,
    ) -> Option<(f32, f32)> {
        let z0 = (origin - self.eye).dot(self.axis);
        let c = direction.dot(self.axis);
        let (t_near, t_far) = if c > 0.0 {
            ((self.near - z0) / c, (self.far - z0) / c)
        } else if z0 >= self.near && z0 < self.far {
            (f32::NEG_INFINITY, f32::INFINITY)
        } else {
            return None;
        };
        let snap = |t: f32, step: f32| {
            if t.is_finite() {
                let k = ((t - anchor) / step).ceil().max(0.0);
                anchor + k * step
            } else {
                t
            }
        };
        Some((snap(t_near, dt), snap(t_far, 2.0 * dt)))
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::render::clip::ClipRegion;
    use crate::render::geometry::VolumeGeometry;
    use crate::render::pixel::PixelRay;
    use crate::render::ray::Ray;
    use crate::volume::BlockGrid;

    /// Level `k` of a volume of `dims` with unit spacing, placed as a pyramid
    /// places it (dims halved rounding up, voxel 0 half a coarse voxel in).
    fn level_geometry(dims: [u32; 3], k: u32) -> VolumeGeometry {
        let scale = (1u32 << k) as f32;
        let level_dims = dims.map(|d| (0..k).fold(d, |d, _| d.div_ceil(2)));
        VolumeGeometry::placed(
            BlockGrid::new(level_dims, 16),
            [scale; 3],
            [(scale - 1.0) / 2.0; 3],
        )
    }

    /// Where the samples a ray keeps end: the next sample's `t` when the last
    /// stands for a whole step, else the last one's plus the part it stands for.
    fn end_of(ray: &PixelRay) -> f32 {
        if ray.last_fraction == 1.0 {
            ray.t(ray.samples)
        } else {
            ray.t(ray.samples - 1) + ray.last_fraction * ray.dt
        }
    }

    /// Floats in `[low, high)` on a lattice of 2^20 steps. Proptest 1.12's own `f32`
    /// range sampler trips a debug assertion of its own (`self.low - result <
    /// initial.step`) on rare draws of ranges whose upper bound is the larger in
    /// magnitude, so float ranges are drawn from integers instead.
    fn float_in(low: f32, high: f32) -> impl Strategy<Value = f32> {
        const STEPS: u32 = 1 << 20;
        (0..STEPS).prop_map(move |k| low + (high - low) * (k as f32 / STEPS as f32))
    }

    proptest! {
        /// Three levels meeting at two depths: along every ray, each level's last
        /// sample ends exactly where the next level's first begins (no gap, no
        /// overlap), that sample lies on the finer level's lattice too, and every
        /// sample lies in its level's band of depths up to one coarser step.
        #[test]
        fn levels_meet_without_a_gap_or_an_overlap(
            eye in prop::array::uniform3(float_in(-60.0, -5.0)),
            target in prop::array::uniform3(float_in(20.0, 80.0)),
            jitter in float_in(0.0, 1.0),
            step in prop::sample::select(vec![0.2f32, 0.5, 1.0]),
            depths in (float_in(30.0, 70.0), float_in(5.0, 40.0)),
        ) {
            let dims = [97, 80, 101];
            let eye = Vec3::from(eye);
            let axis = (Vec3::from(target) - eye).normalize();
            let levels: Vec<VolumeGeometry> = (0..3).map(|k| level_geometry(dims, k)).collect();
            let (lo, hi) = levels.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), g| {
                    let (a, b) = g.world_bounds();
                    (lo.min(a), hi.max(b))
                },
            );
            let bounds = [f32::NEG_INFINITY, depths.0, depths.0 + depths.1, f32::INFINITY];
            let band = |k: usize| DepthBand {
                eye,
                axis,
                near: bounds[k],
                far: bounds[k + 1],
                anchor_lo: lo,
                anchor_hi: hi,
                finer_levels: k as u32,
            };
            for i in 0..64 {
                let wobble = Vec3::new((i % 8) as f32 - 3.5, (i / 8) as f32 - 3.5, 1.0) * 0.05;
                let ray = Ray { origin: eye, direction: (axis + wobble).normalize() };
                let rays: Vec<Option<PixelRay>> = (0..3)
                    .map(|k| {
                        let dt = step * (1u32 << k) as f32;
                        PixelRay::in_band(&ray, &levels[k], dt, jitter, &ClipRegion::default(), &band(k))
                    })
                    .collect();
                for (k, r) in rays.iter().enumerate() {
                    let Some(r) = r else { continue };
                    let b = band(k);
                    for s in [r.first, r.samples - 1] {
                        let depth = (ray.at(r.t(s)) - eye).dot(axis);
                        prop_assert!(depth >= b.near - 1e-3 && depth < b.far + 2.0 * r.dt + 1e-3,
                            "level {k} sample {s} at depth {depth} outside {}..{}", b.near, b.far);
                    }
                }
                for k in 0..2 {
                    let Some(fine) = &rays[k] else { continue };
                    // Where the finer level stops at its band's end (not at its
                    // box's) inside the coarser level's box, the coarser begins.
                    let end = end_of(fine);
                    let (_, exit) = ray.intersect_box(levels[k].world_bounds().0, levels[k].world_bounds().1).unwrap();
                    let (c, d) = levels[k + 1].world_bounds();
                    let p = ray.at(end);
                    if end >= exit - 1e-3 || !(p.cmpge(c).all() && p.cmple(d).all()) {
                        continue;
                    }
                    let Some(coarse) = &rays[k + 1] else {
                        return Err(TestCaseError::fail(format!("level {} takes nothing after level {k} at {end}", k + 1)));
                    };
                    prop_assert_eq!(coarse.t(coarse.first), end, "level {} begins where level {} ends", k + 1, k);
                    prop_assert_eq!(fine.last_fraction, 1.0);
                    prop_assert_eq!(fine.t(2 * coarse.first), end, "nested lattices");
                }
            }
        }
    }
}
