//! Where a volume sits in the world and how it is cut into bricks for rendering.
//!
//! Voxel centres sit at integer voxel coordinates; the volume's box is
//! `[0, dims − 1]` in voxels and `[0, (dims − 1)·spacing]` in world units. A brick
//! *owns* the cells `[b·step, (b+1)·step]` per axis (the last one up to `dims − 1`):
//! every sample position belongs to exactly one brick, found by [`Self::owner`].

use glam::Vec3;

use crate::volume::BlockGrid;

/// A volume's placement and its rendering brick grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeGeometry {
    grid: BlockGrid,
    origin: Vec3,
    spacing: Vec3,
    last: Vec3,
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
        VolumeGeometry {
            grid,
            origin: Vec3::from(origin),
            spacing: Vec3::from(spacing),
            last: Vec3::from(grid.dims().map(|d| (d - 1) as f32)),
            step: grid.step() as f32,
        }
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

    /// The volume's world box.
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        (self.origin, self.origin + self.last * self.spacing)
    }

    /// The cells brick `b` owns, in voxel coordinates.
    pub fn brick_voxel_box(&self, b: [u32; 3]) -> (Vec3, Vec3) {
        let lo = Vec3::from(b.map(|c| c as f32)) * self.step;
        (lo, (lo + Vec3::splat(self.step)).min(self.last))
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
        let [nx, ny, nz] = self.grid.counts();
        let q = p.clamp(Vec3::ZERO, self.last) / self.step;
        [
            (q.x as u32).min(nx - 1),
            (q.y as u32).min(ny - 1),
            (q.z as u32).min(nz - 1),
        ]
    }
}
