//! Where a volume sits in the world and how it is cut into bricks for rendering.
//!
//! Voxel centres sit at integer voxel coordinates; the volume's box is
//! `[0, dims − 1]` in voxels and `[0, (dims − 1)·spacing]` in world units. A brick
//! *owns* the cells `[b·step, (b+1)·step]` per axis (the last one up to `dims − 1`):
//! every sample position belongs to exactly one brick, found by [`Self::owner`].

use glam::{UVec3, Vec3, Vec3A};

use super::camera::Camera;
use super::error::RenderError;
use super::truncate::{MAX_TRUNCATED, truncate_clamped};
use crate::volume::BlockGrid;

/// The most samples one ray may take: 2^22 (a 16384³ volume's diagonal at step 0.007).
pub const MAX_SAMPLES_PER_RAY: f64 = (1u64 << 22) as f64;

/// The most samples one frame may take (before early termination and empty-space
/// skipping): 2^42, hours of work on any machine.
pub const MAX_SAMPLES_PER_FRAME: f64 = (1u64 << 42) as f64;

/// The samples a ray takes along a world length `length`, stepping `step` times
/// `min_spacing`: rounded up, plus one. (What [`check_sample_budget`] counts per
/// ray, along the volume's diagonal.)
pub fn samples_over(length: f64, min_spacing: f32, step: f32) -> f64 {
    (length / (f64::from(step) * f64::from(min_spacing))).ceil() + 1.0
}

/// The world diagonal of a volume of `dims` voxels at `spacing` (voxel centre
/// to voxel centre).
pub fn world_diagonal(dims: [u32; 3], spacing: [f32; 3]) -> f64 {
    (0..3)
        .map(|a| (f64::from(dims[a].max(1) - 1) * f64::from(spacing[a])).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Refuses a frame whose rays could take more samples than [`MAX_SAMPLES_PER_RAY`]
/// each or [`MAX_SAMPLES_PER_FRAME`] together, at `step` (in units of the smallest
/// spacing) over the pixels `camera` sees the volume in. Such a frame comes from an
/// absurd spacing (a header with pixdim 1e-45) or step, and would render "forever".
pub fn check_sample_budget(
    geometry: &VolumeGeometry,
    step: f32,
    camera: &Camera,
) -> Result<(), RenderError> {
    let per_ray = geometry.max_samples_per_ray(step);
    let (lo, hi) = geometry.world_bounds();
    let pixels = camera
        .project_box(lo, hi)
        .map_or(0, |r| u64::from(r.x1 - r.x0) * u64::from(r.y1 - r.y0));
    let per_frame = per_ray * pixels as f64;
    // NaN compares false: written so that NaN counts as over the limit.
    if per_ray <= MAX_SAMPLES_PER_RAY && per_frame <= MAX_SAMPLES_PER_FRAME {
        return Ok(());
    }
    let s = geometry.spacing();
    Err(RenderError::SampleBudget {
        per_ray,
        per_frame,
        max_ray: MAX_SAMPLES_PER_RAY,
        max_frame: MAX_SAMPLES_PER_FRAME,
        spacing: s.to_array(),
        ratio: f64::from(s.max_element()) / f64::from(s.min_element()),
        step,
    })
}

/// A volume's placement and its rendering brick grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeGeometry {
    grid: BlockGrid,
    origin: Vec3,
    spacing: Vec3,
    last: Vec3,
    /// The box rays sample, in voxel coordinates (`[0, last]` unless a pyramid
    /// level's is set: [`Self::sampling`]).
    sampled: (Vec3, Vec3),
    /// That box in world coordinates ([`Self::world_bounds`], asked per ray).
    world: (Vec3, Vec3),
    step: f32,
}

impl VolumeGeometry {
    /// The geometry of a volume with `spacing` cut by `grid`, voxel `(0, 0, 0)` at
    /// the world origin.
    pub fn new(grid: BlockGrid, spacing: [f32; 3]) -> Self {
        Self::placed(grid, spacing, [0.0; 3])
    }

    /// Like [`Self::new`] with voxel `(0, 0, 0)` at world position `origin` (pyramid
    /// levels sit half a coarse voxel inside level 0's box).
    pub fn placed(grid: BlockGrid, spacing: [f32; 3], origin: [f32; 3]) -> Self {
        let last = Vec3::from(grid.dims().map(|d| (d - 1) as f32));
        VolumeGeometry {
            grid,
            origin: Vec3::from(origin),
            spacing: Vec3::from(spacing),
            last,
            sampled: (Vec3::ZERO, last),
            world: (Vec3::ZERO, Vec3::ZERO),
            step: grid.step() as f32,
        }
        .sampling([[0.0; 3], last.to_array()])
    }

    /// The same geometry with rays sampling the box `[lo, hi]` (voxel
    /// coordinates) instead of `[0, dims − 1]`: a pyramid level samples the
    /// full-resolution volume's box ([`crate::volume::Volume::sampled_box`]),
    /// which reaches up to half a coarse voxel past its own voxel centres. Reads
    /// there clamp to the edge voxels, and the edge bricks own those samples.
    pub fn sampling(mut self, [lo, hi]: [[f32; 3]; 2]) -> Self {
        self.sampled = (Vec3::from(lo), Vec3::from(hi));
        self.world = (
            self.origin + self.sampled.0 * self.spacing,
            self.origin + self.sampled.1 * self.spacing,
        );
        self
    }

    /// The brick grid.
    pub fn grid(&self) -> &BlockGrid {
        &self.grid
    }

    /// Voxel spacing per axis.
    pub fn spacing(&self) -> Vec3 {
        self.spacing
    }

    /// The smallest spacing: the world length of one step unit.
    pub fn min_spacing(&self) -> f32 {
        self.spacing.min_element()
    }

    /// The last voxel's coordinates, `dims − 1`: the voxel box's upper corner.
    pub fn last_voxel(&self) -> Vec3 {
        self.last
    }

    /// World position of voxel `(0, 0, 0)`.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// The world box rays sample: the volume's ([`Self::sampling`]).
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        self.world
    }

    /// The most samples one ray can take through the volume at `step` (in units of
    /// the smallest spacing): the world diagonal over the world step, rounded up.
    /// Infinite or huge for absurd spacings (one axis 1e-45 of another).
    pub fn max_samples_per_ray(&self, step: f32) -> f64 {
        let (lo, hi) = self.world_bounds();
        samples_over(f64::from((hi - lo).length()), self.min_spacing(), step)
    }

    /// The positions whose samples brick `b` takes, in voxel coordinates: the
    /// cells it owns, grown to the sampled box at the volume's faces
    /// ([`Self::sampling`]; samples there read the edge voxels).
    pub fn brick_voxel_box(&self, b: [u32; 3]) -> (Vec3, Vec3) {
        let lo = Vec3::from(b.map(|c| c as f32)) * self.step;
        let hi = (lo + Vec3::splat(self.step)).min(self.last);
        let b = UVec3::from(b);
        let last_brick = UVec3::from(self.grid.counts()) - UVec3::ONE;
        (
            Vec3::select(b.cmpeq(UVec3::ZERO), self.sampled.0, lo),
            Vec3::select(b.cmpeq(last_brick), self.sampled.1, hi),
        )
    }

    /// The cells brick `b` owns, in world coordinates.
    pub fn brick_world_box(&self, b: [u32; 3]) -> (Vec3, Vec3) {
        let (lo, hi) = self.brick_voxel_box(b);
        (
            self.origin + lo * self.spacing,
            self.origin + hi * self.spacing,
        )
    }

    /// The brick owning voxel position `p` (clamped into the volume first).
    #[inline]
    pub fn owner(&self, p: Vec3) -> [u32; 3] {
        // `owner_along` per axis, the clamp and the division in lanes.
        let q = (Vec3A::from(p).clamp(Vec3A::ZERO, self.last.into()) / self.step).to_array();
        let counts = self.grid.counts();
        [0, 1, 2].map(|a| owner_of(q[a], counts[a]))
    }

    /// Coordinate `axis` of the brick owning a position whose coordinate `axis` is
    /// `c` (inside the volume): [`Self::owner`] one axis at a time, non-decreasing
    /// in `c`.
    #[inline]
    pub fn owner_along(&self, c: f32, axis: usize) -> u32 {
        owner_of(c / self.step, self.grid.counts()[axis])
    }

    /// The brick side in owned cells (the grid's step) as a float.
    #[inline]
    pub fn brick_step(&self) -> f32 {
        self.step
    }
}

/// The brick coordinate holding a coordinate that lies at `q` brick steps along
/// an axis of `count` bricks (the last brick owns everything beyond).
#[inline(always)]
fn owner_of(q: f32, count: u32) -> u32 {
    truncate_clamped(q, MAX_TRUNCATED).min(count - 1)
}
