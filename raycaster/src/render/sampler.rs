//! Reconstruction inside one brick: trilinear values and central-difference
//! gradients, addressed locally, with a whole-volume fallback for the few
//! neighbour reads that leave the brick.
//!
//! Positions are in voxel coordinates (voxel centres at integers, the volume box is
//! `[0, dims − 1]`). Every read is clamped to the volume, so nothing outside it is
//! ever addressed.

use glam::{Vec3, Vec3A, Vec4};

use super::cell_cache::CornerLanes;
use super::truncate::truncate_clamped;
use crate::volume::{BlockGrid, BrickView, Layout, Sample, TypedVolume};

/// Trilinear interpolation in one brick, by local coordinates.
#[derive(Clone, Copy, Debug)]
pub struct BrickSampler<'a, T: Sample> {
    view: BrickView<'a, T>,
    origin: Vec3,
    /// Last voxel inside the brick, as local coordinates.
    last: Vec3,
    /// `origin` in SIMD lanes, for the marching loop's cell cache.
    origin_lanes: Vec3A,
    /// Largest lower cell corner per axis (extent − 2, or 0 for a one-voxel
    /// axis), as floats in SIMD lanes.
    max_cell_lanes: Vec3A,
    /// Stride to the upper corner per axis (0 on a one-voxel axis).
    corner_stride: [usize; 3],
}

impl<'a, T: Sample> BrickSampler<'a, T> {
    /// A sampler over `view`.
    pub fn new(view: BrickView<'a, T>) -> Self {
        let extent = view.extent();
        let strides = view.strides();
        let origin = Vec3::from(view.origin().map(|o| o as f32));
        let max_cell = extent.map(|e| e.saturating_sub(2));
        BrickSampler {
            view,
            origin,
            last: Vec3::from(extent.map(|e| (e - 1) as f32)),
            origin_lanes: origin.into(),
            max_cell_lanes: Vec3A::from(max_cell.map(|m| m as f32)),
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
        let cell = self.cell_at(l);
        trilinear(&self.corners(cell), cell_fraction(l, cell))
    }

    /// The cell whose interpolation gives the value at local position `l`
    /// (inside the brick): its integer parts, clamped to the brick's cells (a
    /// hair below 0 becomes cell 0, as with a saturating cast).
    #[inline]
    fn cell_at(&self, l: Vec3) -> [u32; 3] {
        let max = self.max_cell_lanes;
        [
            truncate_clamped(l.x, max.x),
            truncate_clamped(l.y, max.y),
            truncate_clamped(l.z, max.z),
        ]
    }

    /// [`Self::value`] and the slope along `d` ([`Self::value_and_slope_local`]).
    #[inline]
    pub fn value_and_slope(&self, p: Vec3, d: Vec3) -> (f32, f32) {
        self.value_and_slope_local(p - self.origin, d)
    }

    /// [`Self::value_local`] (the same bits) and the derivative of the
    /// trilinear field along `d` there: `∇f · d`, `f`'s gradient taken in the
    /// cell that holds `l` (its corners' differences, interpolated in the other
    /// two axes), in raw value per length of `d`.
    #[inline]
    pub fn value_and_slope_local(&self, l: Vec3, d: Vec3) -> (f32, f32) {
        let cell = self.cell_at(l);
        let c = self.corners(cell);
        let f = cell_fraction(l, cell);
        (trilinear(&c, f), CornerLanes::new(&c).slope(f.into(), d))
    }

    /// [`Self::origin`] as voxel indices.
    #[inline]
    pub(crate) fn origin_voxel(&self) -> [u32; 3] {
        self.view.origin()
    }

    /// [`Self::origin`] in SIMD lanes.
    #[inline]
    pub(crate) fn origin_lanes(&self) -> Vec3A {
        self.origin_lanes
    }

    /// The largest lower cell corner per axis (local cells `0..=max_cell`), as
    /// floats in SIMD lanes.
    #[inline]
    pub(crate) fn max_cell_lanes(&self) -> Vec3A {
        self.max_cell_lanes
    }

    /// The brick's samples from its first voxel on, the strides between
    /// neighbours per axis, the stride to a cell's upper corner per axis (0 on
    /// a one-voxel axis) and the brick's extent: how [`Self::corners`]
    /// addresses a cell, for kernels that read corners in lanes of their own.
    pub(crate) fn addressing(&self) -> (&'a [T], [usize; 3], [usize; 3], [u32; 3]) {
        (
            self.view.samples_from(0),
            self.view.strides(),
            self.corner_stride,
            self.view.extent(),
        )
    }

    /// The eight corner values of local cell `cell` (each coordinate at most
    /// [`Self::max_cell_lanes`]), in [`Corners`] order.
    #[inline(always)]
    pub(crate) fn corners(&self, [ix, iy, iz]: [u32; 3]) -> Corners {
        let [sx, sy, _] = self.view.strides();
        let base = ix as usize * sx + iy as usize * sy + iz as usize;
        let [ox, oy, oz] = self.corner_stride;
        // One bounds check for the whole cell: every corner lies in this slice.
        let s = &self.view.samples_from(base)[..=ox + oy + oz];
        let v = |o: usize| f32::from(s[o].to_u16());
        [
            v(0),
            v(oz),
            v(oy),
            v(oy + oz),
            v(ox),
            v(ox + oz),
            v(ox + oy),
            v(ox + oy + oz),
        ]
    }

    /// The central differences at the corners of local cell `cell` when the
    /// 4×4×4 voxels around it lie in this brick, else `None` (near the brick's
    /// faces).
    #[inline]
    pub(crate) fn corner_differences(&self, [ix, iy, iz]: [u32; 3]) -> Option<CornerDifferences> {
        let extent = self.view.extent();
        if ix == 0 || iy == 0 || iz == 0 {
            return None;
        }
        if ix + 2 >= extent[0] || iy + 2 >= extent[1] || iz + 2 >= extent[2] {
            return None;
        }
        let [sx, sy, _] = self.view.strides();
        let base = (ix - 1) as usize * sx + (iy - 1) as usize * sy + (iz - 1) as usize;
        let block = &self.view.samples_from(base)[..3 * sx + 3 * sy + 4];
        let v = |x: usize, y: usize, z: usize| {
            // Constants at every call: the check folds away.
            assert!(x < 4 && y < 4 && z < 4, "outside the cell's block");
            let at = x * sx + y * sy + z;
            // SAFETY: x, y, z ≤ 3, so `at` ≤ 3·sx + 3·sy + 3 < block.len() (the
            // slice above was cut to that length, so the sum does not overflow).
            #[allow(unsafe_code)] // measured: one bounds check per cell instead of 12
            let sample = unsafe { block.get_unchecked(at) };
            f32::from(sample.to_u16())
        };
        let run = |x: usize, y: usize| [v(x, y, 0), v(x, y, 1), v(x, y, 2), v(x, y, 3)];
        let pair = |x: usize, y: usize| [v(x, y, 1), v(x, y, 2)];
        Some(differences(&Neighbourhood::from_columns(run, pair)))
    }
}

/// The 32 voxels around a cell that its corners' central differences read, in
/// z-runs: block coordinates with the cell's lower corner at (1, 1, 1). A voxel
/// is a value `V`: an `f32`, or one per lane in the packet kernels.
pub(crate) struct Neighbourhood<V> {
    /// Columns (1..=2, 1..=2), z from 0 to 3: `inner[x − 1][y − 1][z]`.
    pub inner: [[[V; 4]; 2]; 2],
    /// Column (0, 1..=2), z 1..=2: `x_below[y − 1][z − 1]`.
    pub x_below: [[V; 2]; 2],
    /// Column (3, 1..=2), z 1..=2.
    pub x_above: [[V; 2]; 2],
    /// Column (1..=2, 0), z 1..=2: `y_below[x − 1][z − 1]`.
    pub y_below: [[V; 2]; 2],
    /// Column (1..=2, 3), z 1..=2.
    pub y_above: [[V; 2]; 2],
}

impl<V: Copy> Neighbourhood<V> {
    /// The neighbourhood from its block's z-runs: `run(x, y)` the whole column
    /// (z 0..=3), `pair(x, y)` its middle two voxels (z 1..=2).
    #[inline(always)]
    pub(crate) fn from_columns(
        run: impl Fn(usize, usize) -> [V; 4],
        pair: impl Fn(usize, usize) -> [V; 2],
    ) -> Self {
        Neighbourhood {
            inner: [[run(1, 1), run(1, 2)], [run(2, 1), run(2, 2)]],
            x_below: [pair(0, 1), pair(0, 2)],
            x_above: [pair(3, 1), pair(3, 2)],
            y_below: [pair(1, 0), pair(2, 0)],
            y_above: [pair(1, 3), pair(2, 3)],
        }
    }
}

/// The central differences `v(c + e) − v(c − e)` along x, y, z at a cell's
/// corners, in [`Corners`] order.
pub(crate) type CornerDifferences = [Vec3A; 8];

impl<V: Copy> Neighbourhood<V> {
    /// The central differences at the cell's corners per axis (`[x, y, z]`,
    /// each in [`Corners`] order), with `sub(a, b)` = a − b: the one definition
    /// the tests hold [`differences`] to.
    #[cfg(test)]
    pub(crate) fn differences_by(&self, sub: impl Fn(V, V) -> V) -> [[V; 8]; 3] {
        let x = std::array::from_fn(|c| {
            let (x, y, z) = (c >> 2, (c >> 1) & 1, c & 1);
            if x == 0 {
                sub(self.inner[1][y][z + 1], self.x_below[y][z])
            } else {
                sub(self.x_above[y][z], self.inner[0][y][z + 1])
            }
        });
        let y = std::array::from_fn(|c| {
            let (x, y, z) = (c >> 2, (c >> 1) & 1, c & 1);
            if y == 0 {
                sub(self.inner[x][1][z + 1], self.y_below[x][z])
            } else {
                sub(self.y_above[x][z], self.inner[x][0][z + 1])
            }
        });
        let z = std::array::from_fn(|c| {
            let column = &self.inner[c >> 2][(c >> 1) & 1];
            sub(column[(c & 1) + 2], column[c & 1])
        });
        [x, y, z]
    }
}

/// The corner differences of a cell from its [`Neighbourhood`]
/// ([`Neighbourhood::differences_by`]'s, assembled four corners at a time).
///
/// Four corners at a time in SIMD lanes (those of the cell's lower x face, then
/// its upper, each in [`Corners`] order), one lane per `(y, z)`: each axis's
/// differences are one subtraction of two such quads, each quad two z-pairs of
/// the neighbourhood. The voxels are integers, so every difference is exact and
/// equals `differences_by`'s whichever way it is computed.
#[inline(always)]
pub(crate) fn differences(n: &Neighbourhood<f32>) -> CornerDifferences {
    // Lanes (y, z) = (0, 0), (0, 1), (1, 0), (1, 1) of the corners at x.
    let quad = |[a0, a1]: [f32; 2], [b0, b1]: [f32; 2]| Vec4::new(a0, a1, b0, b1);
    let mid = |x: usize, y: usize| [n.inner[x][y][1], n.inner[x][y][2]];
    let lanes = |x: usize| {
        let [front, back] = &n.inner[x];
        let dz = quad([front[2], front[3]], [back[2], back[3]])
            - quad([front[0], front[1]], [back[0], back[1]]);
        let dy = quad(mid(x, 1), n.y_above[x]) - quad(n.y_below[x], mid(x, 0));
        (dy, dz)
    };
    let ((dy0, dz0), (dy1, dz1)) = (lanes(0), lanes(1));
    let dx0 = quad(mid(1, 0), mid(1, 1)) - quad(n.x_below[0], n.x_below[1]);
    let dx1 = quad(n.x_above[0], n.x_above[1]) - quad(mid(0, 0), mid(0, 1));
    std::array::from_fn(|c| {
        let (dx, dy, dz) = if c < 4 {
            (dx0, dy0, dz0)
        } else {
            (dx1, dy1, dz1)
        };
        Vec3A::new(dx[c & 3], dy[c & 3], dz[c & 3])
    })
}

/// A cell's eight corner values, x slowest: (0,0,0), (0,0,1), (0,1,0), (0,1,1),
/// (1,0,0), (1,0,1), (1,1,0), (1,1,1).
pub(crate) type Corners = [f32; 8];

/// The position of local point `l` inside its cell `cell`, per axis.
#[inline]
pub(crate) fn cell_fraction(l: Vec3, cell: [u32; 3]) -> [f32; 3] {
    // Through i32: one instruction per axis in the baseline instruction set
    // (the same value as `as f32` of the u32, for any cell of a volume).
    [
        l.x - cell[0] as i32 as f32,
        l.y - cell[1] as i32 as f32,
        l.z - cell[2] as i32 as f32,
    ]
}

/// The cell holding local point `l` (`l` ≥ 0: its coordinates' integer
/// parts); a coordinate below zero gives a cell no brick has.
#[inline]
pub(crate) fn cell_of(l: Vec3) -> [u32; 3] {
    [l.x as i32 as u32, l.y as i32 as u32, l.z as i32 as u32]
}

/// Trilinear interpolation of a cell's corners at `[fx, fy, fz]`: z, then y,
/// then x (every kernel interpolates in this order, so their values agree to the
/// bit).
#[inline]
pub(crate) fn trilinear(c: &Corners, [fx, fy, fz]: [f32; 3]) -> f32 {
    let c00 = lerp(c[0], c[1], fz);
    let c01 = lerp(c[2], c[3], fz);
    let c10 = lerp(c[4], c[5], fz);
    let c11 = lerp(c[6], c[7], fz);
    lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx)
}

/// The central-difference gradient inside a cell from the differences at its
/// corners ([`differences`]): trilinear per axis (in one vector, the three axes'
/// operations each as [`trilinear`]'s), halved.
///
/// Trilinear interpolation is linear in the corner values and a shift by one
/// voxel keeps the weights, so this is `(f(p + e) − f(p − e)) / 2` of the
/// trilinear field `f` — six trilinear reads — computed from the cell's
/// 32-voxel neighbourhood, and once per cell rather than once per sample.
#[inline]
pub(crate) fn gradient_from_differences(d: &CornerDifferences, [fx, fy, fz]: [f32; 3]) -> Vec3 {
    let lerp3 = |a: Vec3A, b: Vec3A, t: f32| a + (b - a) * t;
    let c00 = lerp3(d[0], d[1], fz);
    let c01 = lerp3(d[2], d[3], fz);
    let c10 = lerp3(d[4], d[5], fz);
    let c11 = lerp3(d[6], d[7], fz);
    Vec3::from(lerp3(lerp3(c00, c01, fy), lerp3(c10, c11, fy), fx) * 0.5)
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
    /// Largest lower corner of a cell whose neighbourhood lies in the volume
    /// (`dims − 3` per axis; cells from 1 to it have central differences).
    last_inner_cell: [i64; 3],
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
            last_inner_cell: dims.map(|d| i64::from(d) - 3),
        }
    }

    /// The whole volume as one brick, for linear storage.
    pub(crate) fn whole(&self) -> Option<&BrickSampler<'a, T>> {
        self.whole.as_ref()
    }

    /// For bricked storage, how the voxels just beyond `local`'s faces are
    /// addressed from it when `local` is a whole stored brick: the file's
    /// samples, the index of `local`'s first sample in them, and per axis what
    /// a step across the brick's upper face adds to the in-brick offset (and a
    /// step below its lower face takes away): the brick stride less `side − 1`
    /// voxel strides (the bricks overlap by one voxel). `None` for linear
    /// storage or any other view.
    pub(crate) fn stored_brick_layout(
        &self,
        local: &BrickSampler<'a, T>,
    ) -> Option<(&'a [T], usize, [usize; 3])> {
        if self.whole.is_some() {
            return None;
        }
        let grid = &self.grid;
        let (step, side, counts) = (grid.step(), grid.side() as usize, grid.counts());
        let origin = local.view.origin();
        if origin.iter().any(|&o| o % step != 0) {
            return None;
        }
        let b = origin.map(|o| o / step);
        let strides = [side * side, side, 1];
        if (0..3).any(|a| b[a] >= counts[a])
            || local.view.extent() != grid.extent(b)
            || local.view.strides() != strides
        {
            return None;
        }
        let [_, n1, n2] = counts.map(|c| c as usize);
        let brick_len = side * side * side;
        let per_brick = [n1 * n2 * brick_len, n2 * brick_len, brick_len];
        let index = grid.index(b) as usize * brick_len;
        let samples = self.volume.samples();
        // The view is that brick's samples (not a copy).
        if !std::ptr::eq(
            samples.get(index..)?.as_ptr(),
            local.view.samples_from(0).as_ptr(),
        ) {
            return None;
        }
        Some((
            samples,
            index,
            [0, 1, 2].map(|a| per_brick[a] - (side - 1) * strides[a]),
        ))
    }

    /// The largest lower corner of a cell whose 4×4×4 neighbourhood lies in
    /// the volume, per axis (`dims − 3`; cells from 1 to it have central
    /// differences).
    pub(crate) fn last_inner_cell(&self) -> [i64; 3] {
        self.last_inner_cell
    }

    /// The volume box's upper corner in voxel coordinates (`dims − 1`).
    pub fn last(&self) -> Vec3 {
        self.last
    }

    /// `p` clamped into the volume, and the brick that interpolates there
    /// (the whole volume for linear storage).
    fn brick_holding(&self, p: Vec3) -> (BrickSampler<'a, T>, Vec3) {
        let p = p.clamp(Vec3::ZERO, self.last);
        if let Some(whole) = self.whole {
            return (whole, p);
        }
        let step = self.grid.step() as f32;
        let counts = self.grid.counts();
        let b = [0, 1, 2].map(|a| ((p[a] / step) as u32).min(counts[a] - 1));
        (BrickSampler::new(self.volume.brick(&self.grid, b)), p)
    }

    /// The trilinear value at `p`, clamped into the volume.
    pub fn value(&self, p: Vec3) -> f32 {
        let (brick, p) = self.brick_holding(p);
        brick.value(p)
    }

    /// [`Self::value`] (the same bits) and the trilinear field's derivative
    /// along `d` there ([`BrickSampler::value_and_slope_local`]).
    pub fn value_and_slope(&self, p: Vec3, d: Vec3) -> (f32, f32) {
        let (brick, p) = self.brick_holding(p);
        brick.value_and_slope(p, d)
    }

    /// The gradient at `p` by central differences over one voxel,
    /// `(f(p + e) − f(p − e)) / 2` per axis, in raw value per voxel; one-sided in
    /// the cells at the volume's faces. Reads come from `local` when it covers
    /// them.
    ///
    /// Inside, it is [`gradient_from_differences`] of `p`'s cell: a function of
    /// `p` and the voxels alone, whichever brick asks (the cell caches of the
    /// scalar kernel and the packet kernels compute the same bits).
    #[inline]
    pub fn gradient(&self, local: &BrickSampler<'a, T>, p: Vec3) -> Vec3 {
        let cell = cell_of(p);
        if let Some(d) = self.corner_differences(local, cell) {
            return gradient_from_differences(&d, cell_fraction(p, cell));
        }
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

    /// The central differences at the corners of volume cell `cell`
    /// ([`BrickSampler::corner_differences`]), read from `local` where it holds
    /// the cell's neighbourhood; `None` for the cells at the volume's faces,
    /// whose neighbourhood leaves the volume.
    #[inline]
    pub(crate) fn corner_differences(
        &self,
        local: &BrickSampler<'a, T>,
        cell: [u32; 3],
    ) -> Option<CornerDifferences> {
        let inner = self.last_inner_cell;
        if (0..3).any(|a| cell[a] == 0 || i64::from(cell[a]) > inner[a]) {
            return None;
        }
        // Linear storage: the whole volume holds every neighbourhood.
        if let Some(whole) = &self.whole {
            return whole.corner_differences(cell);
        }
        let origin = local.view.origin();
        if (0..3).all(|a| cell[a] >= origin[a])
            && let Some(d) = local.corner_differences([0, 1, 2].map(|a| cell[a] - origin[a]))
        {
            return Some(d);
        }
        // Bricked storage across a brick's face: each voxel from the brick
        // `BlockGrid::brick_of_voxel` gives (the one `TypedVolume::voxel` reads),
        // addressed by per-axis offsets computed once per cell.
        let [ox, oy, oz] = self.block_offsets(cell);
        let samples = self.volume.samples();
        let v = |x: usize, y: usize, z: usize| f32::from(samples[ox[x] + oy[y] + oz[z]].to_u16());
        let run = |x: usize, y: usize| [v(x, y, 0), v(x, y, 1), v(x, y, 2), v(x, y, 3)];
        let pair = |x: usize, y: usize| [v(x, y, 1), v(x, y, 2)];
        Some(differences(&Neighbourhood::from_columns(run, pair)))
    }

    /// For bricked storage, the sample offsets of the 4×4×4 voxels around cell
    /// `cell` (whose lower corner has block coordinates (1, 1, 1)) split per
    /// axis: voxel `(x, y, z)` of the block is sample `ox[x] + oy[y] + oz[z]`,
    /// in the brick [`BlockGrid::brick_of_voxel`] assigns it. `cell` must be an
    /// inner cell (its block lies in the volume).
    #[inline]
    fn block_offsets(&self, cell: [u32; 3]) -> [[usize; 4]; 3] {
        let grid = &self.grid;
        let (step, side) = (grid.step(), grid.side() as usize);
        let counts = grid.counts();
        let brick_len = side * side * side;
        // A brick index is `(bx·ny + by)·nz + bz`; a local voxel `(lx·s + ly)·s + lz`.
        let scale = [
            (
                counts[1] as usize * counts[2] as usize * brick_len,
                side * side,
            ),
            (counts[2] as usize * brick_len, side),
            (brick_len, 1),
        ];
        std::array::from_fn(|a| {
            let (per_brick, per_voxel) = scale[a];
            let first = cell[a] - 1;
            let mut brick = (first / step).min(counts[a] - 1);
            let mut local = first - brick * step;
            std::array::from_fn(|d| {
                if d > 0 {
                    // The next voxel: the next brick's first when this one's
                    // owned voxels end (`brick_of_voxel` = `g / step`, capped).
                    local += 1;
                    if local == step && brick + 1 < counts[a] {
                        brick += 1;
                        local = 0;
                    }
                }
                brick as usize * per_brick + local as usize * per_voxel
            })
        })
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
pub(crate) mod tests {
    use super::*;
    use crate::render::test_rng::xorshift32;

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

    /// `samples` (linear, `dims`) stored in bricks of side `side`.
    pub(crate) fn to_bricks<T: Sample>(samples: &[T], dims: [u32; 3], side: u32) -> Vec<T> {
        let linear = TypedVolume::new(samples, dims, Layout::Linear);
        let grid = BlockGrid::new(dims, side);
        let s = side as usize;
        let mut out = vec![T::from_u16_saturating(0); grid.iter().count() * s * s * s];
        for b in grid.iter() {
            let (o, e) = (grid.origin(b), grid.extent(b));
            let start = grid.index(b) as usize * s * s * s;
            for x in 0..e[0] {
                for y in 0..e[1] {
                    for z in 0..e[2] {
                        let at = start + (x as usize * s + y as usize) * s + z as usize;
                        out[at] = linear.voxel([o[0] + x, o[1] + y, o[2] + z]);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn the_gradient_equals_central_differences_of_trilinear_reads_whichever_brick_asks() {
        let dims = [20, 18, 22];
        let mut next = xorshift32(0x2545_f491);
        let samples: Vec<u16> = (0..20 * 18 * 22).map(|_| (next() % 4096) as u16).collect();
        let linear = TypedVolume::new(&samples, dims, Layout::Linear);
        let bricked_samples = to_bricks(&samples, dims, 8);
        let bricked = TypedVolume::new(&bricked_samples, dims, Layout::Bricked { side: 8 });
        let whole = VolumeSampler::new(linear);
        let whole_brick = BrickSampler::new(linear.brick(&BlockGrid::new(dims, 22), [0, 0, 0]));
        let (mut inside, mut total, mut from_neighbours) = (0, 0, 0);
        for volume in [linear, bricked] {
            let sampler = VolumeSampler::new(volume);
            let grid = volume.natural_grid(8);
            for b in grid.iter() {
                let brick = BrickSampler::new(volume.brick(&grid, b));
                let o = Vec3::from(grid.origin(b).map(|v| v as f32));
                let e = Vec3::from(grid.extent(b).map(|v| (v - 1) as f32));
                for _ in 0..200 {
                    let f = Vec3::new(
                        (next() % 10_000) as f32 / 9_999.0,
                        (next() % 10_000) as f32 / 9_999.0,
                        (next() % 10_000) as f32 / 9_999.0,
                    );
                    let p = o + f * e;
                    total += 1;
                    let g = sampler.gradient(&brick, p);
                    // A function of the position alone: the same bits from the
                    // brick, from the whole volume, in either storage.
                    assert_eq!(g, whole.gradient(&whole_brick, p), "{p}");
                    let cell = [p.x as u32, p.y as u32, p.z as u32];
                    if sampler.corner_differences(&brick, cell).is_none() {
                        continue;
                    }
                    inside += 1;
                    let local = [0, 1, 2].map(|a| cell[a] - o[a] as u32);
                    if brick.corner_differences(local).is_none() {
                        from_neighbours += 1;
                    }
                    let central = |a: Vec3| (sampler.value(p + a) - sampler.value(p - a)) / 2.0;
                    let expected = Vec3::new(central(Vec3::X), central(Vec3::Y), central(Vec3::Z));
                    assert!(
                        (g - expected).abs().max_element() < 1e-2,
                        "{p}: {g} vs {expected}"
                    );
                }
            }
        }
        assert!(inside > total / 2, "{inside} of {total} inside");
        assert!(inside < total, "the volume's faces take the one-sided path");
        assert!(
            from_neighbours > total / 10,
            "{from_neighbours} across brick faces"
        );
    }

    #[test]
    fn differences_in_quads_equal_differences_by_axis() {
        let mut next = xorshift32(0x51ed_270b);
        for _ in 0..2_000 {
            let mut v = || (next() % 65_536) as f32;
            let inner = [0; 2].map(|_| [0; 2].map(|_| [0; 4].map(|_| v())));
            let mut pairs = || [0; 2].map(|_| [0; 2].map(|_| v()));
            let n = Neighbourhood {
                inner,
                x_below: pairs(),
                x_above: pairs(),
                y_below: pairs(),
                y_above: pairs(),
            };
            let [x, y, z] = n.differences_by(|a, b| a - b);
            let expected: CornerDifferences = std::array::from_fn(|c| Vec3A::new(x[c], y[c], z[c]));
            assert_eq!(differences(&n), expected);
        }
    }

    #[test]
    fn corner_differences_across_brick_faces_equal_the_linear_volumes_for_every_cell() {
        // Sizes whose last brick is whole, short, or one voxel past a whole
        // number of steps (the capped `brick_of_voxel` of the last brick).
        for (dims, side) in [([15, 9, 12], 4), ([22, 16, 13], 8), ([17, 17, 18], 5)] {
            let mut next = xorshift32(0x9e37_79b9 ^ dims[0]);
            let samples: Vec<u16> = (0..dims.iter().product::<u32>())
                .map(|_| (next() % 4096) as u16)
                .collect();
            let linear = TypedVolume::new(&samples, dims, Layout::Linear);
            let bricked_samples = to_bricks(&samples, dims, side);
            let bricked =
                TypedVolume::new(&bricked_samples, dims, Layout::Bricked { side: side as u8 });
            let (whole, across) = (VolumeSampler::new(linear), VolumeSampler::new(bricked));
            let whole_brick = BrickSampler::new(linear.brick(&BlockGrid::new(dims, 64), [0, 0, 0]));
            // A brick that holds none of the cells, so every read goes across.
            let grid = bricked.natural_grid(2);
            let far = BrickSampler::new(bricked.brick(&grid, [0, 0, 0]));
            let mut checked = 0;
            for x in 0..dims[0] - 1 {
                for y in 0..dims[1] - 1 {
                    for z in 0..dims[2] - 1 {
                        let cell = [x, y, z];
                        let expected = whole.corner_differences(&whole_brick, cell);
                        assert_eq!(across.corner_differences(&far, cell), expected, "{cell:?}");
                        checked += usize::from(expected.is_some());
                    }
                }
            }
            assert!(checked > 0);
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
