//! Rays and the ray–box intersection (the slab method of Williams et al. 2003).

use glam::Vec3;

/// A ray `origin + t·direction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction (not necessarily unit length).
    pub direction: Vec3,
}

impl Ray {
    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }

    /// The parameter interval `[t0, t1]` (with `t0 ≥ 0`) in which the ray is inside
    /// the closed box `[lo, hi]`, or `None` when it misses.
    ///
    /// Robust for directions with zero components: a ray parallel to a slab is inside
    /// it for all `t` when its origin lies between the planes (inclusive), outside
    /// otherwise. A zero direction gives `t1 = ∞` when the origin is inside.
    #[inline]
    pub fn intersect_box(&self, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
        let mut t0 = 0.0f32;
        let mut t1 = f32::INFINITY;
        for a in 0..3 {
            let (o, d) = (self.origin[a], self.direction[a]);
            if d == 0.0 {
                if o < lo[a] || o > hi[a] {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d;
            let (mut near, mut far) = ((lo[a] - o) * inv, (hi[a] - o) * inv);
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            t0 = t0.max(near);
            t1 = t1.min(far);
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }
}

/// The 8 corners of the box `[lo, hi]` (corner `i` takes `hi` on axis `a` where
/// bit `a` of `i` is set).
#[inline]
pub(crate) fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const LO: Vec3 = Vec3::ZERO;
    const HI: Vec3 = Vec3::new(2.0, 3.0, 4.0);

    #[test]
    fn hits_through_the_middle() {
        let r = Ray {
            origin: Vec3::new(-1.0, 1.5, 2.0),
            direction: Vec3::X,
        };
        assert_eq!(r.intersect_box(LO, HI), Some((1.0, 3.0)));
    }

    #[test]
    fn origin_inside_starts_at_zero() {
        let r = Ray {
            origin: Vec3::new(1.0, 1.0, 1.0),
            direction: Vec3::new(0.0, 0.0, -1.0),
        };
        assert_eq!(r.intersect_box(LO, HI), Some((0.0, 1.0)));
    }

    #[test]
    fn parallel_rays_inside_on_or_outside_a_face() {
        let on_face = Ray {
            origin: Vec3::new(-1.0, 3.0, 1.0),
            direction: Vec3::X,
        };
        assert_eq!(on_face.intersect_box(LO, HI), Some((1.0, 3.0)));
        let outside = Ray {
            origin: Vec3::new(-1.0, 3.0001, 1.0),
            direction: Vec3::X,
        };
        assert_eq!(outside.intersect_box(LO, HI), None);
    }

    #[test]
    fn misses_behind_and_beside() {
        let behind = Ray {
            origin: Vec3::new(5.0, 1.0, 1.0),
            direction: Vec3::X,
        };
        assert_eq!(behind.intersect_box(LO, HI), None);
        let beside = Ray {
            origin: Vec3::new(-1.0, -1.0, 1.0),
            direction: Vec3::new(1.0, 0.2, 0.0),
        };
        assert_eq!(beside.intersect_box(LO, HI), None);
    }

    #[test]
    fn grazing_an_edge_touches_it() {
        let r = Ray {
            origin: Vec3::new(-1.0, -1.0, 1.0),
            direction: Vec3::new(1.0, 1.0, 0.0),
        };
        assert_eq!(r.intersect_box(LO, HI), Some((1.0, 3.0)));
        let corner = Ray {
            origin: Vec3::new(-1.0, 2.0, 1.0),
            direction: Vec3::new(1.0, 1.0, 0.0),
        };
        assert_eq!(corner.intersect_box(LO, HI), Some((1.0, 1.0)));
    }
}
