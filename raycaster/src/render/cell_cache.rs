//! The cell a ray is in: its corner values, and the central differences at its
//! corners once a sample there asks for a gradient, kept while the ray's next
//! samples stay in the same cell.
//!
//! At a step of 0.2 voxel a ray takes about five samples per cell it crosses;
//! each used to load the cell's 8 corners for its value and the 32-voxel
//! neighbourhood for its gradient. With the cache a sample costs the two
//! trilinear interpolations only, and the loads happen once per cell. The values
//! and gradients are the bits of [`BrickSampler::value_local`] and
//! [`VolumeSampler::gradient`], which the tests check.

use std::cell::Cell;

use glam::{Vec3, Vec3A, Vec4, Vec4Swizzles};

use super::sampler::{BrickSampler, CornerDifferences, Corners, VolumeSampler};
use super::truncate::{MAX_TRUNCATED, truncate_clamped};
use crate::volume::Sample;

/// What the cache knows of its cell's gradient.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Differences {
    /// Not asked for yet.
    Unknown,
    /// In [`CellCache::differences`].
    Known,
    /// The cell touches the volume's faces: gradients take the one-sided path.
    AtVolumeFace,
}

/// A cell's corners in SIMD lanes for [`super::sampler::trilinear`]: its
/// z-interpolation's four starts (`[c0, c2, c4, c6]`) and the differences to
/// their ends (`[c1 − c0, c3 − c2, c5 − c4, c7 − c6]`), computed once per cell.
/// Each lane then runs `a + (b − a)·t` exactly as `trilinear` does, so the value
/// has its bits.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CornerLanes {
    starts: Vec4,
    spans: Vec4,
}

impl CornerLanes {
    #[inline]
    pub(crate) fn new(c: &Corners) -> Self {
        let starts = Vec4::new(c[0], c[2], c[4], c[6]);
        CornerLanes {
            starts,
            spans: Vec4::new(c[1], c[3], c[5], c[7]) - starts,
        }
    }

    /// `trilinear` at fraction `f` of the cell: z in four lanes, then y in
    /// two, then x.
    #[inline(always)]
    fn trilinear(self, f: Vec3A) -> f32 {
        // [c00, c01, c10, c11]
        let z = self.starts + self.spans * Vec4::splat(f.z);
        // [lerp(c00, c01, fy), lerp(c10, c11, fy)] in lanes 0 and 1.
        let (front, back) = (z.xzxz(), z.ywyw());
        let y = front + (back - front) * Vec4::splat(f.y);
        y.x + (y.y - y.x) * f.x
    }

    /// The derivative along `d` of [`Self::trilinear`]'s interpolant at
    /// fraction `f` of the cell: the cell's gradient (its corners' differences
    /// interpolated in the other two axes) dotted with `d`.
    #[inline(always)]
    pub(crate) fn slope(self, f: Vec3A, d: Vec3) -> f32 {
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let [c00, c01, c10, c11] = (self.starts + self.spans * Vec4::splat(f.z)).to_array();
        let [z0, z1, z2, z3] = self.spans.to_array();
        let dx = lerp(c10, c11, f.y) - lerp(c00, c01, f.y);
        let dy = lerp(c01 - c00, c11 - c10, f.x);
        let dz = lerp(lerp(z0, z1, f.y), lerp(z2, z3, f.y), f.x);
        dx * d.x + dy * d.y + dz * d.z
    }

    /// [`Self::trilinear`] at four fractions of the cell at once (`f[axis]`
    /// holds each axis for the four), each lane with `trilinear`'s operations
    /// and so its bits.
    #[inline(always)]
    pub(crate) fn trilinear_lanes(self, [fx, fy, fz]: [Vec4; 3]) -> Vec4 {
        let z = |start: f32, span: f32| Vec4::splat(start) + Vec4::splat(span) * fz;
        let (s, d) = (self.starts, self.spans);
        let (c00, c01, c10, c11) = (z(s.x, d.x), z(s.y, d.y), z(s.z, d.z), z(s.w, d.w));
        let y0 = c00 + (c01 - c00) * fy;
        let y1 = c10 + (c11 - c10) * fy;
        y0 + (y1 - y0) * fx
    }
}

/// A cell's corner differences laid out for the gradient's interpolation, as
/// [`CornerLanes`] for the value: the z-interpolations' starts (corners 0, 2, 4,
/// 6) and spans to their ends, each read straight into a register (no copy of
/// the whole table per sample). The gradient has
/// [`super::sampler::gradient_from_differences`]' bits.
#[derive(Debug, Default)]
struct DifferenceLanes {
    starts: [Cell<Vec3A>; 4],
    spans: [Cell<Vec3A>; 4],
}

impl DifferenceLanes {
    #[inline]
    fn set(&self, d: &CornerDifferences) {
        for i in 0..4 {
            self.starts[i].set(d[2 * i]);
            self.spans[i].set(d[2 * i + 1] - d[2 * i]);
        }
    }

    /// The gradient at fraction `f` of the cell.
    #[inline(always)]
    fn gradient(&self, f: Vec3A) -> Vec3 {
        let z = |i: usize| self.starts[i].get() + self.spans[i].get() * f.z;
        let lerp = |a: Vec3A, b: Vec3A, t: f32| a + (b - a) * t;
        let (c00, c01, c10, c11) = (z(0), z(1), z(2), z(3));
        Vec3::from(lerp(lerp(c00, c01, f.y), lerp(c10, c11, f.y), f.x) * 0.5)
    }
}

/// One ray's current cell in one brick.
///
/// Its state lives in [`Cell`]s, so that the loop's samples can share it by
/// reference ([`super::compositor::SampleSite`], built once per brick visit)
/// while each sample's [`Self::value`] moves it on.
#[derive(Debug)]
pub(crate) struct CellCache {
    /// The cell's lower corner in brick-local voxels (`u32::MAX`: none yet):
    /// `lower` as indices, kept because entering converts it anyway (deriving
    /// it again for each cell's differences measured 4 instructions per sample
    /// more).
    cell: Cell<[u32; 3]>,
    /// The same corner as floats (infinite: none yet), for the test of a
    /// position against the cell without conversions.
    lower: Cell<Vec3A>,
    /// Its corner values, laid out for the trilinear interpolation.
    corners: Cell<CornerLanes>,
    /// The central differences at its corners, when `state` is `Known`.
    differences: DifferenceLanes,
    state: Cell<Differences>,
    /// Where the position of the last [`Self::value`] lies in the cell (its
    /// [`super::sampler::cell_fraction`]), when that position is in the cached
    /// cell: the gradient of the same sample ([`Self::gradient_here`]) needs no
    /// second test.
    here: Cell<Option<Vec3A>>,
}

impl Default for CellCache {
    fn default() -> Self {
        CellCache {
            cell: Cell::new([u32::MAX; 3]),
            lower: Cell::new(Vec3A::INFINITY),
            corners: Cell::new(CornerLanes::new(&[0.0; 8])),
            differences: DifferenceLanes::default(),
            state: Cell::new(Differences::Unknown),
            here: Cell::new(None),
        }
    }
}

impl CellCache {
    /// Where local position `l` lies in the cached cell (its
    /// [`super::sampler::cell_fraction`]), if it lies there.
    ///
    /// `l − lower` is exact for positions in or near the brick, and a rounding
    /// never changes a difference's sign, so the test is `cell_of(l) == cell`
    /// except where the difference rounds up to 1 (a position a hair below the
    /// next cell), which is merely not cached.
    #[inline(always)]
    fn fraction_in_cell(&self, l: Vec3A) -> Option<Vec3A> {
        let f = l - self.lower.get();
        (f.cmpge(Vec3A::ZERO) & f.cmplt(Vec3A::ONE))
            .all()
            .then_some(f)
    }

    /// The trilinear value at volume position `p` (inside `sampler`'s brick),
    /// making `p`'s cell the cached one.
    #[inline(always)]
    pub fn value<T: Sample>(&self, sampler: &BrickSampler<'_, T>, p: Vec3A) -> f32 {
        let l = p - sampler.origin_lanes();
        match self.fraction_in_cell(l) {
            Some(f) => {
                self.here.set(Some(f));
                self.corners.get().trilinear(f)
            }
            None => self.enter(sampler, l),
        }
    }

    /// [`Self::value`] at local position `l` outside the cached cell: makes its
    /// cell the cached one (unless `l` lies on the brick's upper face, or below
    /// its first voxel).
    ///
    /// The cell's corner is `floor(l)`, which is [`super::sampler::cell_of`]`(l)`
    /// for `l ≥ 0`, computed in lanes; a single conversion per axis addresses
    /// the corners.
    #[inline(never)]
    fn enter<T: Sample>(&self, sampler: &BrickSampler<'_, T>, l: Vec3A) -> f32 {
        let lower = l.floor();
        if !Self::is_cell(sampler, lower) {
            // Not one of the brick's cells: the cell below its upper face (or its
            // first cell), not cached.
            self.here.set(None);
            return sampler.value_local(l.into());
        }
        let corners = self.corners_of(sampler, lower);
        // `l − floor(l)`: exact, in [0, 1) (see `fraction_in_cell`).
        let f = l - lower;
        self.here.set(Some(f));
        corners.trilinear(f)
    }

    /// Whether `lower` (whole numbers) is the lower corner of one of the brick's
    /// cells: what [`Self::corners_of`] takes.
    #[inline(always)]
    pub fn is_cell<T: Sample>(sampler: &BrickSampler<'_, T>, lower: Vec3A) -> bool {
        (lower.cmpge(Vec3A::ZERO) & lower.cmple(sampler.max_cell_lanes())).all()
    }

    /// The corners of the brick's cell with lower corner `lower` (one that
    /// [`Self::is_cell`]), making it the cached cell.
    #[inline(always)]
    pub fn corners_of<T: Sample>(
        &self,
        sampler: &BrickSampler<'_, T>,
        lower: Vec3A,
    ) -> CornerLanes {
        if lower.cmpne(self.lower.get()).any() {
            let cell = lower.to_array().map(|c| truncate_clamped(c, MAX_TRUNCATED));
            self.cell.set(cell);
            self.lower.set(lower);
            self.corners.set(CornerLanes::new(&sampler.corners(cell)));
            self.state.set(Differences::Unknown);
        }
        self.corners.get()
    }

    /// The gradient at volume position `p` ([`VolumeSampler::gradient`]), from
    /// the cached cell when `p` lies in it.
    #[inline]
    pub fn gradient<T: Sample>(
        &self,
        volume: &VolumeSampler<'_, T>,
        sampler: &BrickSampler<'_, T>,
        p: Vec3,
    ) -> Vec3 {
        // (A point just below the brick, whose coordinates would truncate into
        // its first cell, is not in the cell: the test is on the fraction.)
        let f = self.fraction_in_cell((p - sampler.origin()).into());
        self.gradient_in_cell(volume, sampler, p, f)
    }

    /// [`Self::gradient`] at `p`, the position of the last [`Self::value`].
    #[inline]
    pub fn gradient_here<T: Sample>(
        &self,
        volume: &VolumeSampler<'_, T>,
        sampler: &BrickSampler<'_, T>,
        p: Vec3,
    ) -> Vec3 {
        self.gradient_in_cell(volume, sampler, p, self.here.get())
    }

    /// The slope along `d` at volume position `p` ([`CornerLanes::slope`]),
    /// when `p` lies in the cached cell.
    #[inline]
    pub fn slope_in_cell<T: Sample>(
        &self,
        sampler: &BrickSampler<'_, T>,
        p: Vec3,
        d: Vec3,
    ) -> Option<f32> {
        let f = self.fraction_in_cell((p - sampler.origin()).into())?;
        Some(self.corners.get().slope(f, d))
    }

    /// [`Self::gradient`] at volume position `p`, making `p`'s cell the cached
    /// one when it is one of the brick's cells (it need not be: the cells at
    /// the brick's upper faces take the volume's path). For gradients read on
    /// the ray ahead of the current sample (a pre-integrated segment's): the
    /// next samples enter those cells, and their values and gradients then
    /// find them cached. The position of the last [`Self::value`] is
    /// forgotten ([`Self::gradient_here`] then takes the volume's path, the
    /// same bits).
    #[inline]
    pub fn gradient_ahead<T: Sample>(
        &self,
        volume: &VolumeSampler<'_, T>,
        sampler: &BrickSampler<'_, T>,
        p: Vec3,
    ) -> Vec3 {
        let l = Vec3A::from(p - sampler.origin());
        if let Some(f) = self.fraction_in_cell(l) {
            return self.gradient_in_cell(volume, sampler, p, Some(f));
        }
        let lower = l.floor();
        if !Self::is_cell(sampler, lower) {
            return volume.gradient(sampler, p);
        }
        self.corners_of(sampler, lower);
        self.here.set(None);
        // `l − floor(l)`: exact, in [0, 1) (see `fraction_in_cell`).
        self.gradient_in_cell(volume, sampler, p, Some(l - lower))
    }

    /// The gradient at `p`, which lies at fraction `f` of the cached cell, or
    /// outside it (`None`: the volume's own gradient).
    #[inline]
    pub(crate) fn gradient_in_cell<T: Sample>(
        &self,
        volume: &VolumeSampler<'_, T>,
        sampler: &BrickSampler<'_, T>,
        p: Vec3,
        f: Option<Vec3A>,
    ) -> Vec3 {
        // (A fresh cache has no cell, and then `f` is `None`.)
        let Some(f) = f else {
            return volume.gradient(sampler, p);
        };
        match self.differences(volume, sampler) {
            Some(d) => d.gradient(f),
            None => volume.gradient(sampler, p),
        }
    }

    /// The cached cell's corner differences (computed at the first call per
    /// cell), or `None` where the cell touches the volume's faces (gradients
    /// there take [`VolumeSampler::gradient`]'s one-sided path). Only after a
    /// cell was entered ([`Self::value`], [`Self::corners_of`]).
    #[inline]
    fn differences<T: Sample>(
        &self,
        volume: &VolumeSampler<'_, T>,
        sampler: &BrickSampler<'_, T>,
    ) -> Option<&DifferenceLanes> {
        match self.state.get() {
            Differences::Known => {}
            Differences::AtVolumeFace => return None,
            Differences::Unknown => {
                let (origin, cell) = (sampler.origin_voxel(), self.cell.get());
                let global = [0, 1, 2].map(|a| cell[a] + origin[a]);
                match volume.corner_differences(sampler, global) {
                    Some(d) => {
                        self.differences.set(&d);
                        self.state.set(Differences::Known);
                    }
                    None => {
                        self.state.set(Differences::AtVolumeFace);
                        return None;
                    }
                }
            }
        }
        Some(&self.differences)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::{gradient_from_differences, trilinear};
    use crate::render::test_rng::xorshift32;

    #[test]
    fn corner_and_difference_lanes_interpolate_with_the_samplers_bits() {
        let mut next = xorshift32(0x2545_f491);
        for _ in 0..20_000 {
            let corners: Corners = std::array::from_fn(|_| (next() % 65_536) as f32);
            let f = [0; 3].map(|_| (next() % 1_000_001) as f32 / 1_000_000.0);
            let lanes = CornerLanes::new(&corners).trilinear(Vec3A::from(f));
            assert_eq!(
                lanes.to_bits(),
                trilinear(&corners, f).to_bits(),
                "{corners:?} {f:?}"
            );
            // Four fractions at once: lane i holds fraction `f` moved by i / 7.
            let moved = |i: usize| f.map(|x| (x + i as f32 / 7.0).fract());
            let four = CornerLanes::new(&corners).trilinear_lanes(
                [0, 1, 2].map(|a| Vec4::from_array([0, 1, 2, 3].map(|i| moved(i)[a]))),
            );
            for i in 0..4 {
                assert_eq!(four[i].to_bits(), trilinear(&corners, moved(i)).to_bits());
            }
            let differences: CornerDifferences = std::array::from_fn(|_| {
                Vec3A::from([0; 3].map(|_| (next() % 131_071) as f32 - 65_535.0))
            });
            let lanes = DifferenceLanes::default();
            lanes.set(&differences);
            let g = lanes.gradient(Vec3A::from(f));
            let expected = gradient_from_differences(&differences, f);
            assert_eq!(
                g.to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits)
            );
        }
    }
    use crate::volume::{BlockGrid, Layout, TypedVolume};

    /// The dimensions and random one-byte samples of a small volume (two bricks
    /// per axis at a brick side of 6).
    fn random_volume(seed: u32) -> ([u32; 3], Vec<u8>) {
        let dims = [13, 11, 12];
        let mut next = xorshift32(seed);
        (
            dims,
            (0..13 * 11 * 12).map(|_| (next() % 251) as u8).collect(),
        )
    }

    /// Walks the diagonal of each brick of [`random_volume`]`(seed)` in `steps`
    /// steps, upper face included, with a fresh cache per brick:
    /// `visit(volume, brick, cache, position, step)`.
    fn walk_brick_diagonals(
        seed: u32,
        steps: u32,
        mut visit: impl FnMut(&VolumeSampler<'_, u8>, &BrickSampler<'_, u8>, &CellCache, Vec3, Vec3),
    ) {
        let (dims, samples) = random_volume(seed);
        let volume = TypedVolume::new(&samples, dims, Layout::Linear);
        let sampler = VolumeSampler::new(volume);
        let grid = BlockGrid::new(dims, 6);
        for b in grid.iter() {
            let brick = BrickSampler::new(volume.brick(&grid, b));
            let o = Vec3::from(grid.origin(b).map(|v| v as f32));
            let step = Vec3::from(grid.extent(b).map(|v| (v - 1) as f32)) / steps as f32;
            let cache = CellCache::default();
            for k in 0..=steps {
                visit(&sampler, &brick, &cache, o + step * k as f32, step);
            }
        }
    }

    /// The slope of the trilinear field along a direction
    /// ([`CornerLanes::slope`]) is the same bits from the cache and from a
    /// fresh read of the brick or the volume, comes with `value_local`'s value,
    /// and is the field's derivative (a central difference inside the cell).
    #[test]
    fn slopes_equal_the_fields_derivative_from_the_cache_and_from_fresh_reads() {
        let (mut cached, mut differenced) = (0, 0);
        for seed in [3, 17] {
            walk_brick_diagonals(seed, 9, |volume, brick, cache, p, step| {
                let d = Vec3::new(step.x, -0.5 * step.y, 0.25 + step.z);
                let value = cache.value(brick, p.into());
                let (v, slope) = brick.value_and_slope(p, d);
                assert_eq!(v.to_bits(), brick.value(p).to_bits(), "{p}");
                assert_eq!(v.to_bits(), value.to_bits(), "{p}");
                // (On a cell's face the slope is one-sided: the brick's last
                // cell and the volume's next one differ there.)
                let (vv, vs) = volume.value_and_slope(p, d);
                assert_eq!(vv.to_bits(), v.to_bits(), "{p}");
                let f = p - p.floor();
                if f.cmpgt(Vec3::ZERO).all() {
                    assert_eq!(vs.to_bits(), slope.to_bits(), "{p}");
                }
                if let Some(from_cache) = cache.slope_in_cell(brick, p, d) {
                    assert_eq!(from_cache.to_bits(), slope.to_bits(), "{p}");
                    cached += 1;
                }
                let l = p - brick.origin();
                let h = 1e-2 / d.length();
                if f.min_element() > 0.05
                    && f.max_element() < 0.95
                    && l.floor() == (l + d * h).floor()
                    && l.floor() == (l - d * h).floor()
                {
                    let central =
                        (brick.value_local(l + d * h) - brick.value_local(l - d * h)) / (2.0 * h);
                    assert!(
                        (central - slope).abs() < 0.05 + 1e-3 * slope.abs(),
                        "{p}: {central} {slope}"
                    );
                    differenced += 1;
                }
            });
        }
        assert!(cached > 20 && differenced > 10, "{cached} {differenced}");
    }

    /// Gradients read ahead of the current sample (pre-integrated segments)
    /// move the cache to their cells and still give the samplers' bits; so do
    /// the values and gradients after them (the current sample's included,
    /// whose position the cache then forgets).
    #[test]
    fn gradients_read_ahead_equal_the_samplers_bit_for_bit_and_keep_their_cells() {
        let (mut kept, mut ahead) = (0, 0);
        // Samples a tenth of the diagonal apart, each reading gradients at the
        // segment's midpoint and end (the next sample).
        walk_brick_diagonals(0x85eb_ca6b, 10, |sampler, brick, cache, p, step| {
            assert_eq!(cache.value(brick, p.into()), brick.value(p), "{p}");
            for q in [p + step * 0.5, p + step] {
                let q = q.clamp(Vec3::ZERO, sampler.last());
                assert_eq!(
                    cache.gradient_ahead(sampler, brick, q),
                    sampler.gradient(brick, q),
                    "{q}"
                );
                ahead += 1;
                let l = Vec3A::from(q - brick.origin());
                kept += usize::from(cache.fraction_in_cell(l).is_some());
            }
            // The current sample's gradient after the cache moved on.
            assert_eq!(
                cache.gradient_here(sampler, brick, p),
                sampler.gradient(brick, p),
                "{p}"
            );
        });
        // Positions inside the brick's cells are kept (the upper faces' are not).
        assert!(kept > ahead / 2, "{kept} of {ahead} kept");
    }

    #[test]
    fn cached_values_and_gradients_equal_the_samplers_bit_for_bit() {
        let (mut hits, mut taken) = (0, 0);
        // A ray across each brick's diagonal at a step of 0.05 of it.
        walk_brick_diagonals(0x9e37_79b9, 20, |sampler, brick, cache, p, _| {
            let before = cache.cell.get();
            let value = cache.value(brick, p.into());
            hits += usize::from(before == cache.cell.get());
            taken += 1;
            assert_eq!(value, brick.value(p), "{p}");
            assert_eq!(
                cache.gradient_here(sampler, brick, p),
                sampler.gradient(brick, p)
            );
            assert_eq!(
                cache.gradient(sampler, brick, p),
                sampler.gradient(brick, p)
            );
            // Other positions: in the cell or outside it, below the brick
            // included (a first hit's refined position may lie there).
            for offset in [
                Vec3::new(0.3, -0.2, 0.1),
                Vec3::new(-0.4, 0.0, 0.0),
                Vec3::new(0.05, 0.05, -0.6),
            ] {
                let q = (p + offset).clamp(Vec3::ZERO, sampler.last());
                assert_eq!(
                    cache.gradient(sampler, brick, q),
                    sampler.gradient(brick, q),
                    "{q}"
                );
            }
        });
        assert!(
            hits > taken / 3,
            "{hits} of {taken} samples in the cached cell"
        );
        let (dims, samples) = random_volume(0x9e37_79b9);
        let volume = TypedVolume::new(&samples, dims, Layout::Linear);
        let sampler = VolumeSampler::new(volume);
        let grid = BlockGrid::new(dims, 6);
        // A point just below a brick truncates into the brick's first cell: the
        // cache must not extrapolate that cell's differences to it.
        let b = [1, 1, 1];
        let brick = BrickSampler::new(volume.brick(&grid, b));
        let o = Vec3::from(grid.origin(b).map(|v| v as f32));
        let cache = CellCache::default();
        let p = o + 0.5;
        cache.value(&brick, p.into());
        assert_eq!(
            cache.gradient(&sampler, &brick, p),
            sampler.gradient(&brick, p)
        );
        let below = o + Vec3::new(-0.4, 0.5, 0.5);
        assert_eq!(
            cache.gradient(&sampler, &brick, below),
            sampler.gradient(&brick, below)
        );
    }
}
