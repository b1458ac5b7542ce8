//! Reconstruction inside one brick: trilinear values and central-difference
//! gradients, addressed locally, with a whole-volume fallback for the few
//! neighbour reads that leave the brick.
//!
//! Positions are in voxel coordinates (voxel centres at integers, the volume box is
//! `[0, dims − 1]`). Every read is clamped to the volume, so nothing outside it is
//! ever addressed.

use glam::Vec3;

use crate::volume::{BlockGrid, BrickView, Layout, Sample, TypedVolume};

/// Trilinear interpolation in one brick, by local coordinates.
#[derive(Clone, Copy, Debug)]
pub struct BrickSampler<'a, T: Sample> {
    view: BrickView<'a, T>,
    origin: Vec3,
    /// Last voxel inside the brick, as local coordinates.
    last: Vec3,
    /// Largest lower cell corner per axis (extent − 2, or 0 for a one-voxel axis).
    max_cell: [u32; 3],
    /// Stride to the upper corner per axis (0 on a one-voxel axis).
    corner_stride: [usize; 3],
}

impl<'a, T: Sample> BrickSampler<'a, T> {
    /// A sampler over `view`.
    pub fn new(view: BrickView<'a, T>) -> Self {
        let extent = view.extent();
        let strides = view.strides();
        BrickSampler {
            view,
            origin: Vec3::from(view.origin().map(|o| o as f32)),
            last: Vec3::from(extent.map(|e| (e - 1) as f32)),
            max_cell: extent.map(|e| e.saturating_sub(2)),
            corner_stride: [0, 1, 2].map(|a| if extent[a] > 1 { strides[a] } else { 0 }),
        }
    }

    /// The brick's first voxel, in volume voxel coordinates.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// Whether volume position `p` can be interpolated from this brick alone.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        let l = p - self.origin;
        l.cmpge(Vec3::ZERO).all() && l.cmple(self.last).all()
    }

    /// The trilinearly interpolated value at volume position `p`, which must lie
    /// inside the brick ([`Self::contains`]).
    #[inline]
    pub fn value(&self, p: Vec3) -> f32 {
        self.value_local(p - self.origin)
    }

    /// The trilinearly interpolated value at local position `l` (inside the brick).
    #[inline]
    pub fn value_local(&self, l: Vec3) -> f32 {
        let [sx, sy, _] = self.view.strides();
        // Float → int casts saturate, so a hair below 0 becomes cell 0.
        let ix = (l.x as u32).min(self.max_cell[0]);
        let iy = (l.y as u32).min(self.max_cell[1]);
        let iz = (l.z as u32).min(self.max_cell[2]);
        let (fx, fy, fz) = (l.x - ix as f32, l.y - iy as f32, l.z - iz as f32);
        let base = ix as usize * sx + iy as usize * sy + iz as usize;
        let [ox, oy, oz] = self.corner_stride;
        // One bounds check for the whole cell: every corner lies in this slice.
        let s = &self.view.samples_from(base)[..=ox + oy + oz];
        let v = |o: usize| f32::from(s[o].to_u16());
        let c00 = lerp(v(0), v(oz), fz);
        let c01 = lerp(v(oy), v(oy + oz), fz);
        let c10 = lerp(v(ox), v(ox + oz), fz);
        let c11 = lerp(v(ox + oy), v(ox + oy + oz), fz);
        lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx)
    }
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Values anywhere in the volume: for neighbour reads that leave the current brick
/// (gradients at brick faces, the sample before a first hit).
#[derive(Clone, Copy, Debug)]
pub struct VolumeSampler<'a, T: Sample> {
    volume: TypedVolume<'a, T>,
    /// The stored brick grid, for bricked storage.
    grid: BlockGrid,
    /// The whole volume as one view, for linear storage.
    whole: Option<BrickSampler<'a, T>>,
    /// The last voxel of the volume.
    last: Vec3,
}

impl<'a, T: Sample> VolumeSampler<'a, T> {
    /// A sampler over `volume`.
    pub fn new(volume: TypedVolume<'a, T>) -> Self {
        let dims = volume.dims();
        let (grid, whole) = match volume.layout() {
            Layout::Linear => {
                let side = dims.iter().copied().max().unwrap_or(2).max(2);
                let grid = BlockGrid::new(dims, side);
                (
                    grid,
                    Some(BrickSampler::new(volume.brick(&grid, [0, 0, 0]))),
                )
            }
            Layout::Bricked { .. } => (volume.natural_grid(2), None),
        };
        VolumeSampler {
            volume,
            grid,
            whole,
            last: Vec3::from(dims.map(|d| (d - 1) as f32)),
        }
    }

    /// The volume box's upper corner in voxel coordinates (`dims − 1`).
    pub fn last(&self) -> Vec3 {
        self.last
    }

    /// The trilinear value at `p`, clamped into the volume.
    pub fn value(&self, p: Vec3) -> f32 {
        let p = p.clamp(Vec3::ZERO, self.last);
        if let Some(whole) = &self.whole {
            return whole.value(p);
        }
        let step = self.grid.step() as f32;
        let counts = self.grid.counts();
        let b = [0, 1, 2].map(|a| ((p[a] / step) as u32).min(counts[a] - 1));
        BrickSampler::new(self.volume.brick(&self.grid, b)).value(p)
    }

    /// The gradient at `p` by central differences over one voxel,
    /// `(f(p + e) − f(p − e)) / 2` per axis, in raw value per voxel; one-sided at
    /// the volume's faces. Reads come from `local` when it covers them.
    #[inline]
    pub fn gradient(&self, local: &BrickSampler<'a, T>, p: Vec3) -> Vec3 {
        let mut g = [0f32; 3];
        for (a, e) in [Vec3::X, Vec3::Y, Vec3::Z].into_iter().enumerate() {
            let hi = (p + e).min(self.last);
            let lo = (p - e).max(Vec3::ZERO);
            let h = hi[a] - lo[a];
            if h > 0.0 {
                g[a] = (self.read_near(local, hi) - self.read_near(local, lo)) / h;
            }
        }
        Vec3::from(g)
    }

    /// The value at `q` (inside the volume), from `local` when it covers `q`.
    #[inline]
    fn read_near(&self, local: &BrickSampler<'a, T>, q: Vec3) -> f32 {
        if local.contains(q) {
            local.value(q)
        } else {
            self.value(q)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(dims: [u32; 3]) -> Vec<u16> {
        let [dx, dy, dz] = dims;
        let mut out = Vec::new();
        for x in 0..dx {
            for y in 0..dy {
                for z in 0..dz {
                    out.push((3 * x + 5 * y + 7 * z) as u16);
                }
            }
        }
        out
    }

    #[test]
    fn trilinear_reproduces_a_linear_field_everywhere() {
        let dims = [9, 6, 7];
        let samples = ramp(dims);
        let vol = TypedVolume::new(&samples, dims, Layout::Linear);
        let sampler = VolumeSampler::new(vol);
        let grid = BlockGrid::new(dims, 4);
        for b in grid.iter() {
            let brick = BrickSampler::new(vol.brick(&grid, b));
            let o = grid.origin(b);
            let e = grid.extent(b);
            for i in 0..50 {
                let f = i as f32 / 49.0;
                let p = Vec3::new(
                    o[0] as f32 + f * (e[0] - 1) as f32,
                    o[1] as f32 + (1.0 - f) * (e[1] - 1) as f32,
                    o[2] as f32 + (f * 3.0).fract() * (e[2] - 1) as f32,
                );
                let exact = 3.0 * p.x + 5.0 * p.y + 7.0 * p.z;
                assert!((brick.value(p) - exact).abs() < 1e-3, "{p}");
                assert!((sampler.value(p) - exact).abs() < 1e-3, "{p}");
                let g = sampler.gradient(&brick, p);
                assert!((g - Vec3::new(3.0, 5.0, 7.0)).length() < 1e-3, "{p}: {g}");
            }
        }
    }

    #[test]
    fn one_voxel_axes_and_out_of_volume_reads_are_safe() {
        let dims = [1, 3, 1];
        let samples = [10u8, 20, 40];
        let vol = TypedVolume::new(&samples, dims, Layout::Linear);
        let sampler = VolumeSampler::new(vol);
        assert_eq!(sampler.value(Vec3::new(0.0, 1.5, 0.0)), 30.0);
        assert_eq!(sampler.value(Vec3::new(-5.0, 9.0, 3.0)), 40.0);
        let whole = BrickSampler::new(vol.brick(&BlockGrid::new(dims, 3), [0, 0, 0]));
        let g = sampler.gradient(&whole, Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(g, Vec3::new(0.0, 10.0, 0.0));
    }
}
