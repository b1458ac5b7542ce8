//! Which samples of a tile's rays a brick owns, eight neighbouring rays at a
//! time: [`owned_samples`] in SIMD lanes.
//!
//! A render thread asks it for every ray of its tile under the brick's screen
//! rectangle, once per (tile, brick) task; at 128³ with the default bricks a ray
//! meets about five bricks and takes three or four samples in each, so the
//! question costs as much as the samples (docs/benchmarks.md, section 5). In
//! lanes, one row of a tile is answered eight pixels at a time: the brick's box
//! in sample space ([`slab`](super::ownership::slab)) and the four reads of the
//! owner function that confirm its ends, each with the scalar code's operations
//! (no fused multiply-adds; `min`/`max` as `a < b ? a : b`), so every lane gets
//! the bits of [`owned_samples`]. What the box cannot confirm (a ray grazing a
//! face or a corner, an axis-parallel ray beside the brick, rays of more than
//! 2^24 samples) goes to [`owned_samples`] itself.

use std::ops::Range;

use super::geometry::VolumeGeometry;
use super::ownership::{owned_faces, owned_samples};
use super::packet::PacketItem;
use super::pixel::{PixelRay, PixelState};
use super::simd::SimdLevel;

/// Rays per group.
const GROUP: usize = 8;

/// The largest sample count whose indices the lanes handle exactly: every
/// index up to it is an `f32` and fits an `i32`.
#[cfg(any(target_arch = "x86_64", test))]
const MAX_LANE_SAMPLES: u32 = 1 << 24;

/// A tile's rays as ownership reads them, one array per field, pixel by pixel
/// (row by row), padded so that a group of eight can start at any pixel.
#[derive(Clone, Debug, Default)]
pub(crate) struct RayLanes {
    /// Sample 0's position per axis ([`PixelRay::start`]).
    start: [Vec<f32>; 3],
    /// The step per axis ([`PixelRay::step`]).
    step: [Vec<f32>; 3],
    /// `1 / step` per axis ([`PixelRay::inv_step`]).
    inv_step: [Vec<f32>; 3],
    /// The ray's sample count (0 for a pixel without a ray).
    samples: Vec<u32>,
}

impl RayLanes {
    /// The lanes of `rays` (a tile's, pixel by pixel).
    pub(crate) fn new(rays: &[Option<PixelRay>]) -> Self {
        let n = rays.len() + GROUP - 1;
        let zeros = || [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut lanes = RayLanes {
            start: zeros(),
            step: zeros(),
            inv_step: zeros(),
            samples: vec![0; n],
        };
        for (i, ray) in rays.iter().enumerate() {
            let Some(ray) = ray else {
                continue;
            };
            for a in 0..3 {
                lanes.start[a][i] = ray.start[a];
                lanes.step[a][i] = ray.step[a];
                lanes.inv_step[a][i] = ray.inv_step[a];
            }
            lanes.samples[i] = ray.samples;
        }
        lanes
    }

    /// Pixels (without the padding).
    #[cfg(target_arch = "x86_64")]
    fn len(&self) -> usize {
        self.samples.len().saturating_sub(GROUP - 1)
    }
}

/// One brick's ownership questions for a task.
pub(crate) struct BrickOwnership<'g> {
    geometry: &'g VolumeGeometry,
    brick: [u32; 3],
    /// The brick's constants, where the questions are answered in lanes (AVX2
    /// present: never off x86-64).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    lanes: Option<LaneFaces>,
}

impl<'g> BrickOwnership<'g> {
    /// Brick `brick`'s questions, answered in lanes where `level` has AVX2
    /// ([`Self::in_lanes`]).
    pub(crate) fn new(geometry: &'g VolumeGeometry, brick: [u32; 3], level: SimdLevel) -> Self {
        BrickOwnership {
            geometry,
            brick,
            lanes: Self::in_lanes(level).then(|| LaneFaces::new(geometry, brick)),
        }
    }

    /// Whether the questions are answered in lanes at `level` (which then
    /// needs the tile's [`RayLanes`]).
    pub(crate) fn in_lanes(level: SimdLevel) -> bool {
        cfg!(target_arch = "x86_64") && level.has_gathers() && level.is_available()
    }

    /// Appends to `items` the samples the brick owns of each ray among the
    /// tile's pixels `pixels` (consecutive indices into `rays`, `states` and
    /// `lanes`) that is not done: [`owned_samples`], from the pixel's next
    /// sample on. Pixels come in order.
    pub(crate) fn push_owned<S>(
        &self,
        lanes: &RayLanes,
        rays: &[Option<PixelRay>],
        states: &[PixelState<S>],
        pixels: Range<usize>,
        items: &mut Vec<PacketItem>,
    ) {
        let mut push = |pixel: usize, owned: Option<(u32, u32)>| {
            if let Some((first, last)) = owned {
                items.push(PacketItem {
                    pixel,
                    first: first.max(states[pixel].next_sample),
                    last,
                });
            }
        };
        let live = |i: usize| match (&rays[i], &states[i]) {
            (Some(ray), state) if !state.done => Some(ray),
            _ => None,
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(faces) = &self.lanes {
            assert!(pixels.end <= lanes.len() && pixels.end <= rays.len());
            let mut i0 = pixels.start;
            while i0 < pixels.end {
                let n = (pixels.end - i0).min(GROUP);
                if (i0..i0 + n).any(|i| live(i).is_some()) {
                    #[allow(unsafe_code)]
                    // SAFETY: `faces` exist only where AVX2 was detected
                    // (`SimdLevel::is_available`), and the lanes hold
                    // `i0 + 8` entries: `i0 < pixels.end ≤ len` and the padding.
                    let group = unsafe { x86::owned_group(lanes, i0, faces) };
                    for lane in 0..n {
                        let i = i0 + lane;
                        let Some(ray) = live(i) else {
                            continue;
                        };
                        let owned = match group.answer(lane) {
                            LaneAnswer::Owned(first, last) => {
                                (last >= ray.first).then(|| (first.max(ray.first), last))
                            }
                            LaneAnswer::Missed => None,
                            LaneAnswer::Unsure => owned_samples(ray, self.geometry, self.brick),
                        };
                        push(i, owned);
                    }
                }
                i0 += n;
            }
            return;
        }
        let _ = lanes;
        for i in pixels {
            if let Some(ray) = live(i) {
                push(i, owned_samples(ray, self.geometry, self.brick));
            }
        }
    }
}

/// The brick's constants for the lanes.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct LaneFaces {
    /// The owned box's lower and upper face per axis (infinite on the volume's
    /// outer faces), as [`owned_samples`] computes them.
    exact: [(f32, f32); 3],
    /// The same grown by the miss margin.
    grown: [(f32, f32); 3],
    /// The volume's last voxel per axis.
    last_voxel: [f32; 3],
    /// Per axis, the clamped positions whose owner along it is the brick's
    /// coordinate: `from ≤ c < below` (thresholds of
    /// [`VolumeGeometry::owner_along`], so no division per sample).
    owned_from: [f32; 3],
    /// See `owned_from`.
    owned_below: [f32; 3],
}

impl LaneFaces {
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fn new(geometry: &VolumeGeometry, brick: [u32; 3]) -> Self {
        let counts = geometry.grid().counts();
        let side = geometry.brick_step();
        let exact: [(f32, f32); 3] =
            std::array::from_fn(|a| owned_faces(brick[a], counts[a], side));
        let margin = super::ownership::MISS_MARGIN;
        let first_owned_by = |axis: usize, target: u32| {
            if target == 0 {
                f32::NEG_INFINITY
            } else if target >= counts[axis] {
                f32::INFINITY
            } else {
                first_owned_by(geometry, axis, target)
            }
        };
        LaneFaces {
            exact,
            grown: exact.map(|(lower, upper)| (lower - margin, upper + margin)),
            last_voxel: geometry.last_voxel().to_array(),
            owned_from: std::array::from_fn(|a| first_owned_by(a, brick[a])),
            owned_below: std::array::from_fn(|a| first_owned_by(a, brick[a] + 1)),
        }
    }
}

/// The smallest coordinate `c ≥ 0` along `axis` whose owner
/// ([`VolumeGeometry::owner_along`], non-decreasing in `c`) is at least brick
/// coordinate `target` (`1..count`): found from `target · step` an ulp at a
/// time, with the owner function itself, so exact. Infinite where no
/// coordinate's owner reaches `target` (the owner saturates at brick 2^24).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn first_owned_by(geometry: &VolumeGeometry, axis: usize, target: u32) -> f32 {
    if geometry.owner_along(f32::MAX, axis) < target {
        return f32::INFINITY;
    }
    let mut c = target as f32 * geometry.brick_step();
    while c > 0.0 && geometry.owner_along(c.next_down(), axis) >= target {
        c = c.next_down();
    }
    while geometry.owner_along(c, axis) < target {
        c = c.next_up();
    }
    c
}

/// What the lanes say of one ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LaneAnswer {
    /// These samples (before the ray's first is applied), confirmed at both ends.
    Owned(u32, u32),
    /// No sample.
    Missed,
    /// Ask [`owned_samples`].
    Unsure,
}

/// Eight rays' answers.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct GroupAnswers {
    first: [u32; GROUP],
    last: [u32; GROUP],
    /// Lanes confirmed owned (bits).
    owned: u32,
    /// Lanes to ask the scalar code (bits).
    unsure: u32,
}

impl GroupAnswers {
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fn answer(&self, lane: usize) -> LaneAnswer {
        if self.unsure >> lane & 1 == 1 {
            LaneAnswer::Unsure
        } else if self.owned >> lane & 1 == 1 {
            LaneAnswer::Owned(self.first[lane], self.last[lane])
        } else {
            LaneAnswer::Missed
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    use std::arch::x86_64::*;

    use super::{GROUP, GroupAnswers, LaneFaces, MAX_LANE_SAMPLES, RayLanes};

    /// The answers for the rays of pixels `i0..i0 + 8` (padding included).
    ///
    /// # Safety
    /// The CPU has AVX2, and `lanes` holds at least `i0 + 8` entries.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn owned_group(
        lanes: &RayLanes,
        i0: usize,
        faces: &LaneFaces,
    ) -> GroupAnswers {
        // SAFETY: every array of `lanes` has the same length, at least `i0 + 8`
        // (the caller's promise); unaligned loads of eight values.
        let load = |v: &Vec<f32>| unsafe { _mm256_loadu_ps(v.as_ptr().add(i0)) };
        let start = [0, 1, 2].map(|a| load(&lanes.start[a]));
        let step = [0, 1, 2].map(|a| load(&lanes.step[a]));
        let inv_step = [0, 1, 2].map(|a| load(&lanes.inv_step[a]));
        // SAFETY: as above, eight `u32`s.
        let samples = unsafe { _mm256_loadu_si256(lanes.samples.as_ptr().add(i0).cast()) };
        // Sample counts above 2^24 (or 2^31 read as negative): the scalar code.
        let big = _mm256_or_si256(
            _mm256_cmpgt_epi32(samples, _mm256_set1_epi32(MAX_LANE_SAMPLES as i32)),
            _mm256_cmpgt_epi32(_mm256_setzero_si256(), samples),
        );
        let samples_f = _mm256_cvtepi32_ps(samples);
        let (first, end) = sample_interval(&start, &inv_step, samples_f, samples, &faces.exact);
        let (grown_first, grown_end) =
            sample_interval(&start, &inv_step, samples_f, samples, &faces.grown);
        let miss = not(_mm256_cmpgt_epi32(end, first));
        let grown_miss = not(_mm256_cmpgt_epi32(grown_end, grown_first));
        let one = _mm256_set1_epi32(1);
        let last = _mm256_sub_epi32(end, one);
        let owns = |k: __m256i| owns(faces, &start, &step, k);
        let first_is_start = _mm256_or_si256(
            _mm256_cmpeq_epi32(first, _mm256_setzero_si256()),
            not(owns(_mm256_sub_epi32(first, one))),
        );
        let after = _mm256_add_epi32(last, one);
        let last_is_end =
            _mm256_or_si256(not(_mm256_cmpgt_epi32(samples, after)), not(owns(after)));
        let checked = _mm256_and_si256(
            _mm256_and_si256(owns(first), owns(last)),
            _mm256_and_si256(first_is_start, last_is_end),
        );
        let bits = |m: __m256i| _mm256_movemask_ps(_mm256_castsi256_ps(m)) as u32;
        let (miss, grown_miss, checked, big) =
            (bits(miss), bits(grown_miss), bits(checked), bits(big));
        let owned = !miss & checked & !big;
        let unsure = big | (miss & !grown_miss) | (!miss & !checked);
        let mut answers = GroupAnswers {
            first: [0; GROUP],
            last: [0; GROUP],
            owned: owned & 0xff,
            unsure: unsure & 0xff,
        };
        // SAFETY: each array holds eight `u32`s; unaligned stores.
        unsafe {
            _mm256_storeu_si256(answers.first.as_mut_ptr().cast(), first);
            _mm256_storeu_si256(answers.last.as_mut_ptr().cast(), last);
        }
        answers
    }

    /// All bits flipped.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn not(m: __m256i) -> __m256i {
        _mm256_xor_si256(m, _mm256_set1_epi32(-1))
    }

    /// `guess`'s first and end sample of the box `faces` in sample space:
    /// `ceil(enter)` and `min(ceil(exit), samples)` of
    /// [`slab`](crate::render::ownership::slab) from `(0, samples)`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn sample_interval(
        start: &[__m256; 3],
        inv_step: &[__m256; 3],
        samples_f: __m256,
        samples: __m256i,
        faces: &[(f32, f32); 3],
    ) -> (__m256i, __m256i) {
        let (mut enter, mut exit) = (_mm256_setzero_ps(), samples_f);
        for a in 0..3 {
            let inv = inv_step[a];
            let (lower, upper) = faces[a];
            let t0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(lower), start[a]), inv);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(upper), start[a]), inv);
            // `minps(a, b)` is `a < b ? a : b`, `maxps(a, b)` `a > b ? a : b`:
            // the scalar closures.
            let new_enter = _mm256_max_ps(enter, _mm256_min_ps(t0, t1));
            let new_exit = _mm256_min_ps(exit, _mm256_max_ps(t0, t1));
            // An axis with `inv == 0` is skipped (`!=`, unordered: NaN is not 0).
            let moves = _mm256_cmp_ps::<_CMP_NEQ_UQ>(inv, _mm256_setzero_ps());
            enter = _mm256_blendv_ps(enter, new_enter, moves);
            exit = _mm256_blendv_ps(exit, new_exit, moves);
        }
        (ceil(enter), _mm256_min_epu32(ceil(exit), samples))
    }

    /// `runs::ceil` for values up to 2^24 (larger ones give 2^24; NaN and
    /// negatives 0, as there).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn ceil(x: __m256) -> __m256i {
        let limit = _mm256_set1_ps(MAX_LANE_SAMPLES as f32);
        // `x > 0 ? x : 0`: NaN and negatives become 0.
        let c = _mm256_min_ps(_mm256_max_ps(x, _mm256_setzero_ps()), limit);
        let whole = _mm256_cvttps_epi32(c);
        let below = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_cvtepi32_ps(whole), c);
        // `below` is −1 where the whole part lies below `x`.
        _mm256_sub_epi32(whole, _mm256_castps_si256(below))
    }

    /// Whether the brick owns sample `k` of each lane's ray:
    /// `geometry.owner(ray.position(k, last_voxel)) == brick`, the position
    /// with the same operations and the owner by its thresholds (for `k` in
    /// `0..=2^24`; other lanes give no answer that matters).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn owns(faces: &LaneFaces, start: &[__m256; 3], step: &[__m256; 3], k: __m256i) -> __m256i {
        let kf = _mm256_cvtepi32_ps(k);
        let zero = _mm256_setzero_ps();
        let mut all = _mm256_set1_epi32(-1);
        for a in 0..3 {
            let last = _mm256_set1_ps(faces.last_voxel[a]);
            let clamp = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, zero), last);
            // `SamplePositions::at`: `(start + step·k).clamp(0, last)` (a
            // number: `maxps` gives 0 for NaN).
            let p = clamp(_mm256_add_ps(start[a], _mm256_mul_ps(step[a], kf)));
            let from = _mm256_cmp_ps::<_CMP_GE_OQ>(p, _mm256_set1_ps(faces.owned_from[a]));
            let below = _mm256_cmp_ps::<_CMP_LT_OQ>(p, _mm256_set1_ps(faces.owned_below[a]));
            all = _mm256_and_si256(all, _mm256_castps_si256(_mm256_and_ps(from, below)));
        }
        all
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::render::clip::ClipRegion;
    use crate::render::ray::Ray;
    use crate::render::test_rng::xorshift32;
    use crate::volume::BlockGrid;

    /// The items of `pixels` the scalar way.
    fn scalar_items(
        geometry: &VolumeGeometry,
        brick: [u32; 3],
        rays: &[Option<PixelRay>],
        states: &[PixelState<()>],
        pixels: Range<usize>,
    ) -> Vec<PacketItem> {
        let mut items = Vec::new();
        for i in pixels {
            let (Some(ray), state) = (&rays[i], &states[i]) else {
                continue;
            };
            if state.done {
                continue;
            }
            if let Some((first, last)) = owned_samples(ray, geometry, brick) {
                items.push(PacketItem {
                    pixel: i,
                    first: first.max(state.next_sample),
                    last,
                });
            }
        }
        items
    }

    /// On every level this machine has, `push_owned` gives the scalar items for
    /// every brick, for whole rows and for rows cut anywhere (groups of fewer
    /// than eight), with rays absent, done or started.
    #[test]
    fn lanes_give_the_scalar_owned_samples() {
        let mut random = xorshift32(0x2545_f491);
        let mut next = move || (random() % 10_000) as f32 / 10_000.0;
        let mut compared = [0usize; 2];
        for (dims, side, spacing) in [
            ([33, 17, 25], 9, [1.0, 1.0, 1.0]),
            ([40, 40, 40], 8, [0.7, 1.3, 2.0]),
            ([9, 1, 12], 4, [1.0, 1.0, 1.0]),
            ([64, 64, 64], 16, [1.0, 1.0, 1.0]),
        ] {
            let geometry = VolumeGeometry::new(BlockGrid::new(dims, side), spacing);
            let last = geometry.last_voxel();
            let (lo, hi) = geometry.world_bounds();
            let centre = (lo + hi) * 0.5;
            let cut = crate::render::ownership::test_cut(last);
            for round in 0..12 {
                // A "tile" of 37 rays from one eye through neighbouring targets,
                // some axis-parallel or along a brick face.
                let eye =
                    centre + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * (hi - lo) * 3.0;
                let target = lo + Vec3::new(next(), next(), next()) * (hi - lo);
                let spread = (hi - lo) * 0.05;
                let dt = if round % 2 == 0 {
                    0.5 * geometry.min_spacing()
                } else {
                    1.3
                };
                let clip = if round % 3 == 0 {
                    cut.clone()
                } else {
                    ClipRegion::default()
                };
                let mut rays = Vec::new();
                let mut states = Vec::new();
                for i in 0..37u32 {
                    let aim =
                        target + Vec3::new(i as f32 * 0.13, (i % 5) as f32 * 0.7, 0.0) * spread;
                    let mut direction = (aim - eye).normalize();
                    if i % 11 == 3 {
                        direction = Vec3::new(direction.x, 0.0, 0.0).normalize_or(Vec3::X);
                    }
                    let mut origin = eye;
                    if i % 13 == 5 {
                        origin = Vec3::new(-5.0, (side - 1) as f32 * spacing[1], 2.0 * spacing[2]);
                        direction = Vec3::X;
                    }
                    let jitter = if i % 2 == 0 { 0.0 } else { 0.61 };
                    let ray = Ray { origin, direction };
                    let pixel = if i % 9 == 7 {
                        None
                    } else {
                        PixelRay::new(&ray, &geometry, dt, jitter, &clip)
                    };
                    let mut state = PixelState::new(());
                    state.done = i % 10 == 4;
                    state.next_sample = if i % 4 == 1 { (i * 3) % 17 } else { 0 };
                    rays.push(pixel);
                    states.push(state);
                }
                let lanes = RayLanes::new(&rays);
                for b in geometry.grid().iter() {
                    for pixels in [0..37, 5..12, 3..4, 17..37, 0..0] {
                        let expected = scalar_items(&geometry, b, &rays, &states, pixels.clone());
                        for level in SimdLevel::ALL.into_iter().filter(|l| l.is_available()) {
                            let ownership = BrickOwnership::new(&geometry, b, level);
                            let mut items = Vec::new();
                            ownership.push_owned(
                                &lanes,
                                &rays,
                                &states,
                                pixels.clone(),
                                &mut items,
                            );
                            assert_eq!(items, expected, "{level:?} {b:?} {pixels:?}");
                            compared[usize::from(ownership.lanes.is_some())] += items.len();
                        }
                    }
                }
            }
        }
        assert!(compared[0] > 1000, "scalar items compared: {compared:?}");
        if SimdLevel::Avx2.is_available() {
            assert!(compared[1] > 1000, "lane items compared: {compared:?}");
        }
    }

    /// The lanes settle the usual rays themselves, axis-parallel ones and
    /// those starting at sample 0 included: the scalar code is asked only for
    /// what the box cannot settle (nothing of these rays, which stay clear of
    /// the bricks' faces where they cross them, but the bricks beside the
    /// axis-parallel ones), and every answer is the scalar one.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn lanes_settle_the_usual_rays_themselves() {
        if !SimdLevel::Avx2.is_available() {
            return;
        }
        let geometry = VolumeGeometry::new(BlockGrid::new([64, 64, 64], 16), [1.0; 3]);
        let eye = Vec3::new(-40.0, 23.0, 71.0);
        let mut world_rays: Vec<Ray> = (0..48)
            .map(|i| {
                // Through brick [1, 1, 1] (positions 15–30: 15 owned cells a brick).
                let aim = Vec3::new(
                    18.0 + (i % 8) as f32 * 1.7,
                    18.0 + (i / 8) as f32 * 1.6,
                    24.0,
                );
                Ray {
                    origin: eye,
                    direction: (aim - eye).normalize(),
                }
            })
            .collect();
        // Along each axis, through the first, inner and last bricks of the
        // other two.
        for (a, across) in [(0, [1, 2]), (1, [0, 2]), (2, [0, 1])] {
            for (u, v) in [(7.3, 50.6), (22.9, 3.3), (57.1, 40.2), (60.5, 61.7)] {
                let mut origin = Vec3::splat(0.0);
                origin[a] = -9.0;
                origin[across[0]] = u;
                origin[across[1]] = v;
                let mut direction = Vec3::ZERO;
                direction[a] = 1.0;
                world_rays.push(Ray { origin, direction });
            }
        }
        let rays: Vec<Option<PixelRay>> = world_rays
            .iter()
            .map(|ray| PixelRay::new(ray, &geometry, 0.5, 0.0, &ClipRegion::default()))
            .collect();
        assert!(rays.iter().all(Option::is_some));
        let lanes = RayLanes::new(&rays);
        let (mut owned, mut unsure) = (0, 0);
        for b in geometry.grid().iter() {
            let faces = LaneFaces::new(&geometry, b);
            for i0 in (0..rays.len()).step_by(GROUP) {
                #[allow(unsafe_code)]
                // SAFETY: AVX2 is present (checked above); the lanes hold the
                // rays and the padding.
                let group = unsafe { x86::owned_group(&lanes, i0, &faces) };
                let n = (rays.len() - i0).min(GROUP);
                for lane in 0..n {
                    let ray = rays[i0 + lane].as_ref().unwrap();
                    let expected = owned_samples(ray, &geometry, b);
                    match group.answer(lane) {
                        LaneAnswer::Owned(first, last) => {
                            owned += 1;
                            assert_eq!(Some((first, last)), expected, "{b:?} {lane}");
                        }
                        LaneAnswer::Missed => assert_eq!(expected, None, "{b:?} {lane}"),
                        // Axis-parallel rays skip the axes they do not move
                        // along, so the box does not settle the bricks beside
                        // them (as in `owned_samples`): those are asked, but
                        // the bricks they own samples of are not.
                        LaneAnswer::Unsure if i0 + lane >= 48 && expected.is_none() => {}
                        LaneAnswer::Unsure => unsure += 1,
                    }
                }
            }
        }
        // Each ray crosses four bricks or more.
        assert!(owned >= 4 * rays.len(), "owned {owned}");
        assert_eq!(unsure, 0, "owned {owned}");
    }

    /// Each threshold is where the owner function reaches its brick: the
    /// coordinate itself is owned by the brick or a later one, the float below
    /// it by an earlier one.
    #[test]
    fn thresholds_are_where_the_owner_changes() {
        for (dims, side) in [([100, 37, 64], 16), ([33, 17, 25], 9), ([40, 41, 7], 4)] {
            let geometry = VolumeGeometry::new(BlockGrid::new(dims, side), [1.0; 3]);
            let counts = geometry.grid().counts();
            for (axis, &count) in counts.iter().enumerate() {
                for target in 1..count {
                    let c = first_owned_by(&geometry, axis, target);
                    assert!(geometry.owner_along(c, axis) >= target, "{axis} {target}");
                    assert!(
                        geometry.owner_along(c.next_down(), axis) < target,
                        "{axis} {target}"
                    );
                }
            }
        }
    }

    /// Past brick 2^24 along an axis the owner function saturates: the
    /// threshold of a brick it never reaches is infinite (no endless search).
    #[test]
    fn thresholds_beyond_the_saturated_owner_are_infinite() {
        let geometry = VolumeGeometry::new(BlockGrid::new([(1 << 25) + 5, 2, 2], 2), [1.0; 3]);
        let last = 1 << 24;
        assert!(first_owned_by(&geometry, 0, last).is_finite());
        assert_eq!(first_owned_by(&geometry, 0, last + 1), f32::INFINITY);
        assert_eq!(first_owned_by(&geometry, 0, last + 1000), f32::INFINITY);
    }

    /// A ray of the given start, step and sample count (the fields ownership
    /// reads).
    fn ray_of(start: Vec3, step: Vec3, samples: u32) -> PixelRay {
        let inv = |s: f32| if s == 0.0 { 0.0 } else { 1.0 / s };
        PixelRay {
            origin: start,
            direction: step,
            view_dir: step.normalize_or(Vec3::X),
            t_enter: 0.0,
            dt: 1.0,
            first: 0,
            samples,
            last_fraction: 1.0,
            start,
            step,
            inv_step: Vec3::new(inv(step.x), inv(step.y), inv(step.z)),
        }
    }

    /// The rays the box cannot settle get the scalar answer: one whose only
    /// sample in a brick lies exactly on its lower face while the box in
    /// sample space, rounded, says it has none (found by search: a step of
    /// a few 64ths puts sample `k` exactly on the face, its inverse rounds
    /// the crossing past `k`), and rays of more samples than the lanes count
    /// exactly (2^24 and 2^31 or more).
    #[test]
    fn lanes_ask_the_scalar_code_what_the_box_cannot_settle() {
        let geometry = VolumeGeometry::new(BlockGrid::new([64, 64, 64], 16), [1.0; 3]);
        let brick = [1, 1, 0];
        // The bricks' lower face along x and y.
        let face = geometry.brick_step();
        let mut rays = Vec::new();
        for m in 5..64 {
            let dx = m as f32 / 64.0;
            for k in 1..20u32 {
                let sx = face - dx * k as f32;
                let exact = sx + dx * k as f32 == face;
                if !exact || (face - sx) * (1.0 / dx) <= k as f32 {
                    continue;
                }
                // Down through the face along y half a step after sample k.
                let dy = -0.25;
                let sy = face - dy * (k as f32 + 0.5);
                let ray = ray_of(Vec3::new(sx, sy, 8.5), Vec3::new(dx, dy, 0.01), 40);
                if owned_samples(&ray, &geometry, brick) == Some((k, k)) {
                    rays.push(Some(ray));
                }
            }
        }
        assert!(rays.len() >= 3, "{} rays found", rays.len());
        let through = ray_of(Vec3::new(3.5, 20.2, 8.5), Vec3::new(0.37, 0.011, 0.02), 0);
        for samples in [MAX_LANE_SAMPLES + 1, 1 << 31, u32::MAX] {
            rays.push(Some(PixelRay { samples, ..through }));
        }
        let states = vec![PixelState::new(()); rays.len()];
        let lanes = RayLanes::new(&rays);
        for b in geometry.grid().iter() {
            let expected = scalar_items(&geometry, b, &rays, &states, 0..rays.len());
            if b == brick {
                assert!(expected.len() >= rays.len() - 3, "{expected:?}");
            }
            for level in SimdLevel::ALL.into_iter().filter(|l| l.is_available()) {
                let mut items = Vec::new();
                BrickOwnership::new(&geometry, b, level).push_owned(
                    &lanes,
                    &rays,
                    &states,
                    0..rays.len(),
                    &mut items,
                );
                assert_eq!(items, expected, "{level:?} {b:?}");
            }
        }
    }
}
