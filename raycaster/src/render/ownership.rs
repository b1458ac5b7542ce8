//! Which samples of a ray a brick owns: one interval of sample indices, found by
//! arithmetic per axis instead of by walking samples.
//!
//! Sample `k` belongs to the brick [`VolumeGeometry::owner`] gives for its
//! position ([`PixelRay::position`]). Each coordinate of that position is monotone
//! in `k`, and the owner is monotone in each coordinate, so along one axis the
//! samples owned by brick coordinate `b` form an interval; the brick's samples are
//! the intersection of its three axes' intervals. Each interval end is estimated
//! from the brick's face and then corrected with the exact owner function, so the
//! result is exactly the set of samples the owner function assigns to the brick —
//! the sequential and parallel renderers can rely on it to agree.

use glam::Vec3;

use super::geometry::VolumeGeometry;
use super::pixel::PixelRay;
use super::runs::ceil;

/// The first and last sample index of `ray` that brick `b` owns, if any, among
/// the samples the ray takes (`ray.first..ray.samples`: a clip region may cut
/// its front).
#[inline]
pub(crate) fn owned_samples(
    ray: &PixelRay,
    geometry: &VolumeGeometry,
    b: [u32; 3],
) -> Option<(u32, u32)> {
    let (first, last) = match guess(ray, geometry, b) {
        Guess::Owned(first, last) => (first, last),
        Guess::Missed => return None,
        Guess::Unsure => owned_per_axis(ray, geometry, b)?,
    };
    (last >= ray.first).then(|| (first.max(ray.first), last))
}

/// How far outside a brick's box a computed sample position can be while the
/// exact ray is inside, in voxels: rounding of `start + step·k` for coordinates
/// up to 2^14, with a wide margin.
pub(crate) const MISS_MARGIN: f32 = 0.05;

/// What the brick's box in sample space says.
enum Guess {
    /// These samples, confirmed at both ends.
    Owned(u32, u32),
    /// No sample: the ray misses the box grown by [`MISS_MARGIN`].
    Missed,
    /// Neither could be confirmed.
    Unsure,
}

/// The owned interval from the brick's box in sample space, when four reads of
/// the owner function confirm both its ends (the usual case): the owned samples
/// are one interval, so an owned first sample whose predecessor is not owned is
/// its start, and likewise at the end. A ray that misses the box grown by
/// [`MISS_MARGIN`] owns nothing. Anything else is [`Guess::Unsure`].
#[inline]
fn guess(ray: &PixelRay, geometry: &VolumeGeometry, b: [u32; 3]) -> Guess {
    // Samples k with enter ≤ k < exit: first = ceil(enter), end = ceil(exit).
    let (enter, exit) = sample_slab(ray, geometry, b, 0.0);
    let (first, end) = (ceil(enter), ceil(exit).min(ray.samples));
    if first >= end {
        let (enter, exit) = sample_slab(ray, geometry, b, MISS_MARGIN);
        return if ceil(enter) >= ceil(exit).min(ray.samples) {
            Guess::Missed
        } else {
            Guess::Unsure
        };
    }
    let last = end - 1;
    let last_voxel = geometry.last_voxel();
    let owns = |k: u32| geometry.owner(ray.position(k, last_voxel)) == b;
    let checked = owns(first)
        && owns(last)
        && (first == 0 || !owns(first - 1))
        && (last + 1 >= ray.samples || !owns(last + 1));
    if checked {
        Guess::Owned(first, last)
    } else {
        Guess::Unsure
    }
}

/// The sample-index interval `[enter, exit)` (clipped to the ray's samples) in
/// which the ray is inside brick `b`'s owned box grown by `margin` voxels.
#[inline]
fn sample_slab(ray: &PixelRay, geometry: &VolumeGeometry, b: [u32; 3], margin: f32) -> (f32, f32) {
    let counts = geometry.grid().counts();
    let side = geometry.brick_step();
    slab(
        ray,
        |a| {
            let (lower, upper) = owned_faces(b[a], counts[a], side);
            (lower - margin, upper + margin)
        },
        (0.0, ray.samples as f32),
    )
}

/// The part of the sample-index interval `[enter, exit)` given in which `ray` is
/// inside the box whose lower and upper face along axis `a` are `faces(a)`.
#[inline(always)]
pub(crate) fn slab(
    ray: &PixelRay,
    faces: impl Fn(usize) -> (f32, f32),
    (mut enter, mut exit): (f32, f32),
) -> (f32, f32) {
    // Plain comparisons: no NaN can arise (a zero step is skipped).
    let min = |a: f32, b: f32| if a < b { a } else { b };
    let max = |a: f32, b: f32| if a > b { a } else { b };
    let (inv_step, start) = (ray.inv_step.to_array(), ray.start.to_array());
    for a in 0..3 {
        let inv = inv_step[a];
        if inv == 0.0 {
            continue;
        }
        let (lower, upper) = faces(a);
        let (t0, t1) = ((lower - start[a]) * inv, (upper - start[a]) * inv);
        enter = max(enter, min(t0, t1));
        exit = min(exit, max(t0, t1));
    }
    (enter, exit)
}

/// The box of positions brick `b` owns: lower and upper corner. The first brick
/// of an axis owns everything below it, the last everything above (positions
/// are clamped into the volume), so those faces are infinite.
pub(crate) fn owned_box(geometry: &VolumeGeometry, b: [u32; 3]) -> [Vec3; 2] {
    let counts = geometry.grid().counts();
    let side = geometry.brick_step();
    let faces: [(f32, f32); 3] = std::array::from_fn(|a| owned_faces(b[a], counts[a], side));
    [
        Vec3::from_array(faces.map(|f| f.0)),
        Vec3::from_array(faces.map(|f| f.1)),
    ]
}

/// The lower and upper face of the positions brick coordinate `b` (of `count`
/// along the axis, `side` voxels apart) owns: see [`owned_box`].
#[inline(always)]
pub(crate) fn owned_faces(b: u32, count: u32, side: f32) -> (f32, f32) {
    let lower = if b == 0 {
        f32::NEG_INFINITY
    } else {
        b as f32 * side
    };
    let upper = if b + 1 >= count {
        f32::INFINITY
    } else {
        (b + 1) as f32 * side
    };
    (lower, upper)
}

/// The owned interval axis by axis, each end found exactly with the owner
/// function (see the module's documentation).
fn owned_per_axis(ray: &PixelRay, geometry: &VolumeGeometry, b: [u32; 3]) -> Option<(u32, u32)> {
    let last_voxel = geometry.last_voxel();
    let side = geometry.brick_step();
    let (mut lo, mut hi) = (0u32, ray.samples.checked_sub(1)?);
    for axis in 0..3 {
        let last = last_voxel[axis];
        let own = |k: u32| geometry.owner_along(ray.coordinate(k, axis, last), axis);
        let target = b[axis];
        let (own_lo, own_hi) = (own(lo), own(hi));
        if own_lo == target && own_hi == target {
            continue;
        }
        let step = ray.step[axis];
        let start = ray.start[axis];
        // The sample index where the ray crosses plane `c` of this axis, roughly.
        let crossing = |c: f32| (c - start) / step;
        if own_lo <= own_hi {
            // Non-decreasing along the ray (or constant and not the target).
            if own_lo > target || own_hi < target {
                return None;
            }
            // First sample at or past the brick's lower face, first past its upper.
            let first = if own_lo >= target {
                lo
            } else {
                first_where(lo, hi, crossing(target as f32 * side), |k| own(k) >= target)
            };
            let end = if own_hi <= target {
                hi + 1
            } else {
                first_where(lo, hi, crossing((target + 1) as f32 * side), |k| {
                    own(k) > target
                })
            };
            (lo, hi) = (first, end.checked_sub(1)?);
        } else {
            // Decreasing along the ray.
            if own_hi > target || own_lo < target {
                return None;
            }
            let first = if own_lo <= target {
                lo
            } else {
                first_where(lo, hi, crossing((target + 1) as f32 * side), |k| {
                    own(k) <= target
                })
            };
            let end = if own_hi >= target {
                hi + 1
            } else {
                first_where(lo, hi, crossing(target as f32 * side), |k| own(k) < target)
            };
            (lo, hi) = (first, end.checked_sub(1)?);
        }
        if lo > hi {
            return None;
        }
    }
    Some((lo, hi))
}

/// The first `k` in `lo..=hi` where the monotone predicate `holds` (false, then
/// true) is true, or `hi + 1` when it never is; `estimate` is a guess of it.
///
/// The guess is corrected a sample or two at a time, as it is almost always right
/// within one; a poor guess (a ray almost parallel to a face) falls back to a
/// binary search, so the answer is exact either way.
#[inline]
fn first_where(lo: u32, hi: u32, estimate: f32, holds: impl Fn(u32) -> bool) -> u32 {
    // NaN and infinities land on the ends (`as` saturates, NaN becomes 0).
    let end = hi + 1;
    let mut k = (estimate.max(lo as f32) as u32).clamp(lo, end);
    for _ in 0..3 {
        if k < end && !holds(k) {
            k += 1;
        } else if k > lo && holds(k - 1) {
            k -= 1;
        } else {
            return k;
        }
    }
    // Binary search over the whole interval: invariant "holds(a - 1) is false or
    // a = lo" and "holds(b) is true or b = end".
    let (mut a, mut b) = (lo, end);
    while a < b {
        let mid = a + (b - a) / 2;
        if holds(mid) {
            b = mid;
        } else {
            a = mid + 1;
        }
    }
    a
}

/// A crop box and a clip plane across a volume whose last voxel is `last`:
/// the clip region the ownership tests cut rays with.
#[cfg(test)]
pub(crate) fn test_cut(last: Vec3) -> super::clip::ClipRegion {
    use super::clip::{ClipPlane, ClipRegion, CropBox};
    ClipRegion {
        crop: Some(CropBox {
            lo: last * 0.2,
            hi: last * 0.9,
        }),
        planes: vec![ClipPlane {
            point: last * 0.5,
            normal: Vec3::new(0.3, -1.0, 0.5),
        }],
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

    /// Every sample of a ray is owned by exactly the brick the owner function
    /// names, and each brick's owned samples are the interval `owned_samples` says.
    fn check(geometry: &VolumeGeometry, ray: &Ray, dt: f32) {
        check_jittered(geometry, ray, dt, 0.0);
        check_jittered(geometry, ray, dt, 0.61);
    }

    fn check_jittered(geometry: &VolumeGeometry, ray: &Ray, dt: f32, jitter: f32) {
        let cut = test_cut(geometry.last_voxel());
        check_clipped(geometry, ray, dt, jitter, &ClipRegion::default());
        check_clipped(geometry, ray, dt, jitter, &cut);
    }

    fn check_clipped(
        geometry: &VolumeGeometry,
        ray: &Ray,
        dt: f32,
        jitter: f32,
        clip: &ClipRegion,
    ) {
        let Some(pixel) = PixelRay::new(ray, geometry, dt, jitter, clip) else {
            return;
        };
        let last = geometry.last_voxel();
        let grid = geometry.grid();
        for b in grid.iter() {
            let owned: Vec<u32> = (pixel.first..pixel.samples)
                .filter(|&k| geometry.owner(pixel.position(k, last)) == b)
                .collect();
            let expected = owned.first().map(|&f| (f, *owned.last().unwrap()));
            if let Some((f, l)) = expected {
                assert_eq!(owned.len() as u32, l - f + 1, "{b:?}: not one interval");
            }
            assert_eq!(
                owned_samples(&pixel, geometry, b),
                expected,
                "{b:?} {ray:?}"
            );
        }
    }

    #[test]
    fn owned_intervals_match_the_owner_of_every_sample() {
        let mut random = xorshift32(0x9e37_79b9);
        let mut next = move || (random() % 10_000) as f32 / 10_000.0;
        for (dims, side, spacing) in [
            ([33, 17, 25], 9, [1.0, 1.0, 1.0]),
            ([40, 40, 40], 8, [0.7, 1.3, 2.0]),
            ([9, 1, 12], 4, [1.0, 1.0, 1.0]),
        ] {
            let geometry = VolumeGeometry::new(BlockGrid::new(dims, side), spacing);
            let (lo, hi) = geometry.world_bounds();
            let centre = (lo + hi) * 0.5;
            for i in 0..60 {
                let origin =
                    centre + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * (hi - lo) * 3.0;
                let target = lo + Vec3::new(next(), next(), next()) * (hi - lo);
                let mut direction = (target - origin).normalize();
                // Axis-parallel and face-grazing rays too.
                if i % 7 == 0 {
                    direction = Vec3::new(direction.x, 0.0, 0.0).normalize_or(Vec3::X);
                }
                let ray = Ray { origin, direction };
                check(&geometry, &ray, 0.5 * geometry.min_spacing());
                check(&geometry, &ray, 1.3);
            }
            // A ray along a brick face.
            let face = Ray {
                origin: Vec3::new(-5.0, (side - 1) as f32 * spacing[1], 2.0 * spacing[2]),
                direction: Vec3::X,
            };
            check(&geometry, &face, 0.25);
        }
    }

    #[test]
    fn first_where_is_exact_for_any_estimate() {
        for threshold in [0u32, 1, 5, 17, 40, 41] {
            for estimate in [-3.0, 0.0, 4.5, 16.0, 39.0, 1e9, f32::NAN, f32::INFINITY] {
                let k = first_where(0, 40, estimate, |k| k >= threshold);
                assert_eq!(k, threshold.min(41), "{threshold} {estimate}");
            }
        }
        assert_eq!(first_where(10, 20, 0.0, |k| k >= 15), 15);
    }
}
