//! One pixel's ray and its compositing state.
//!
//! Sample `k` of a ray sits at `t = t_enter + k·dt`, where `t_enter` is where the ray
//! enters the *whole* volume's box (engineering guide, invariant 2). Bricks only
//! choose which `k` they handle, so splitting the volume never moves, drops or
//! doubles a sample.

use glam::{Vec3, Vec3A, Vec4};

use super::clip::ClipRegion;
use super::geometry::VolumeGeometry;
use super::level::DepthBand;
use super::ray::Ray;

/// A pixel's ray through the volume, in voxel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelRay {
    /// Ray origin in voxel coordinates.
    pub origin: Vec3,
    /// Voxel-coordinate change per unit of `t` (world distance).
    pub direction: Vec3,
    /// The world-space unit direction (for shading).
    pub view_dir: Vec3,
    /// The parameter of sample 0 (world distance): where the ray enters the
    /// volume's box, moved on by the ray's start jitter (a fraction of `dt`).
    pub t_enter: f32,
    /// World distance between samples.
    pub dt: f32,
    /// The first sample the ray takes: 0, or with a [`ClipRegion`] the first
    /// whose `t` lies in the kept region.
    pub first: u32,
    /// One past the last sample the ray takes (the number of samples inside the
    /// box, or the end of the kept region's): sample `k` stands for the segment
    /// `[t_k, t_k + dt)`, clipped at the exit.
    pub samples: u32,
    /// The last sample's segment length as a fraction of `dt`, in `(0, 1]`
    /// (0 only for a ray that merely touches the box).
    pub last_fraction: f32,
    /// Voxel position of sample 0 (unclamped): `origin + direction·t_enter`.
    pub start: Vec3,
    /// Voxel distance between samples: `direction·dt`.
    pub step: Vec3,
    /// `1 / step` per axis, 0 on an axis the ray does not move along.
    pub inv_step: Vec3,
}

impl PixelRay {
    /// The volume part of world ray `ray` (unit direction), sampled every `dt`
    /// from `jitter·dt` (`jitter` in `[0, 1)`) after its entry into the box; `None`
    /// when the ray misses the volume's box.
    ///
    /// A jittered ray starts later: the part of the box before its first sample
    /// is not sampled (it is shorter than a step, and sample `k` at
    /// `t_enter + (jitter + k)·dt` stands for the step after it as always). A ray
    /// shorter than its jitter is not jittered.
    ///
    /// With a non-empty `clip` region (voxel coordinates of `geometry`), the ray
    /// keeps the samples whose `t` lies in the part `[c0, c1)` of the ray inside
    /// the region, at their places: `first..samples`; the last kept one stands
    /// for the rest of the region, `(c1 − t_last)/dt` of a step. A ray keeping no
    /// sample is `None`, like one that misses the box.
    pub fn new(
        ray: &Ray,
        geometry: &VolumeGeometry,
        dt: f32,
        jitter: f32,
        clip: &ClipRegion,
    ) -> Option<PixelRay> {
        let (lo, hi) = geometry.world_bounds();
        let (t_box, t_exit) = ray.intersect_box(lo, hi)?;
        let offset = jitter * dt;
        let t_enter = if t_box + offset < t_exit {
            t_box + offset
        } else {
            t_box
        };
        PixelRay::kept(ray, geometry, dt, t_enter, (t_box, t_exit), clip, None)
    }

    /// Like [`Self::new`] for one level of a frame of several
    /// ([`DepthBand`]): samples are anchored where the ray enters the box of all
    /// the frame's levels (plus `jitter` of the finest level's step), and the ray
    /// keeps those in the band's part of it (and in `clip`).
    pub fn in_band(
        ray: &Ray,
        geometry: &VolumeGeometry,
        dt: f32,
        jitter: f32,
        clip: &ClipRegion,
        band: &DepthBand,
    ) -> Option<PixelRay> {
        let (lo, hi) = geometry.world_bounds();
        let (t_box, t_exit) = ray.intersect_box(lo, hi)?;
        let anchor = band.anchor(ray.origin, ray.direction, dt, jitter)?;
        if anchor >= t_exit {
            return None;
        }
        let interval = band.ray_interval(ray.origin, ray.direction, anchor, dt)?;
        PixelRay::kept(
            ray,
            geometry,
            dt,
            anchor,
            (t_box, t_exit),
            clip,
            Some(interval),
        )
    }

    /// The ray sampled every `dt` from `t_enter` up to `t_exit`, keeping the
    /// samples in `[t_box, t_exit)` whose `t` also lies in `clip`'s part of the ray
    /// and in `interval`.
    fn kept(
        ray: &Ray,
        geometry: &VolumeGeometry,
        dt: f32,
        t_enter: f32,
        (t_box, t_exit): (f32, f32),
        clip: &ClipRegion,
        interval: Option<(f32, f32)>,
    ) -> Option<PixelRay> {
        let length = t_exit - t_enter;
        // Samples cover [t_enter, t_exit): ceil(L/dt) of them, at least one; the
        // last stands for the remaining length only. A huge count can only come
        // from a degenerate ray: cap it rather than wrap.
        let samples = ((length / dt).ceil().min(u32::MAX as f32 - 1.0) as u32).max(1);
        let last_fraction = ((length - (samples - 1) as f32 * dt) / dt).clamp(0.0, 1.0);
        let inv_spacing = geometry.spacing().recip();
        let origin = (ray.origin - geometry.origin()) * inv_spacing;
        let direction = ray.direction * inv_spacing;
        let step = direction * dt;
        let whole = PixelRay {
            origin,
            direction,
            view_dir: ray.direction,
            t_enter,
            dt,
            first: 0,
            samples,
            last_fraction,
            start: origin + direction * t_enter,
            step,
            inv_step: Vec3::select(step.cmpeq(Vec3::ZERO), Vec3::ZERO, step.recip()),
        };
        if clip.is_empty() && interval.is_none() {
            return Some(whole);
        }
        let voxel_ray = Ray { origin, direction };
        let (mut c0, mut c1) = if clip.is_empty() {
            (t_box, t_exit)
        } else {
            clip.interval(&voxel_ray, t_box, t_exit)?
        };
        if let Some((b0, b1)) = interval {
            (c0, c1) = (c0.max(b0), c1.min(b1));
            if c0 >= c1 {
                return None;
            }
        }
        let first = whole.first_at_or_after(c0);
        let (samples, last_fraction) = if c1 >= t_exit {
            (samples, last_fraction)
        } else {
            let end = whole.first_at_or_after(c1);
            // An end on a sample (a coarser level's, where two levels of a frame
            // meet) leaves the last kept sample a whole step.
            let fraction = if end > 0 && end < samples && whole.t(end) == c1 {
                1.0
            } else if end > 0 {
                ((c1 - whole.t(end - 1)) / dt).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (end, fraction)
        };
        (first < samples).then_some(PixelRay {
            first,
            samples,
            last_fraction,
            ..whole
        })
    }

    /// The first sample index `k` in `0..=samples` with `t(k) ≥ t` (`samples`
    /// when none): estimated, then corrected with [`Self::t`] itself, which is
    /// monotone in `k`.
    fn first_at_or_after(&self, t: f32) -> u32 {
        let estimate = ((t - self.t_enter) / self.dt).ceil();
        let mut k = if estimate.is_nan() {
            0
        } else {
            estimate.clamp(0.0, self.samples as f32) as u32
        };
        while k > 0 && self.t(k - 1) >= t {
            k -= 1;
        }
        while k < self.samples && self.t(k) < t {
            k += 1;
        }
        k
    }

    /// The parameter of sample `k`.
    #[inline]
    pub fn t(&self, k: u32) -> f32 {
        self.t_enter + k as f32 * self.dt
    }

    /// The voxel position of sample `k`, clamped into the box `[0, last]` (rounding
    /// can put the first and last samples a hair outside). Each coordinate is
    /// monotone in `k` (one product and one sum, both rounded monotonically), which
    /// makes brick ownership along a ray one interval of `k`
    /// ([`super::ownership::owned_samples`]).
    #[inline]
    pub fn position(&self, k: u32, last: Vec3) -> Vec3 {
        self.positions(last).at(k).into()
    }

    /// [`Self::position`] for many `k`: the ray's start, step and box converted
    /// to SIMD lanes once (the marching loop's form).
    #[inline]
    pub(crate) fn positions(&self, last: Vec3) -> SamplePositions {
        SamplePositions {
            start: self.start.into(),
            step: self.step.into(),
            last: last.into(),
        }
    }

    /// Coordinate `axis` of [`Self::position`] (the same arithmetic, one axis).
    #[inline]
    pub fn coordinate(&self, k: u32, axis: usize, last: f32) -> f32 {
        let (start, step) = (self.start.to_array(), self.step.to_array());
        (start[axis] + step[axis] * k as f32).clamp(0.0, last)
    }
}

/// A ray's sample positions in SIMD lanes ([`PixelRay::positions`]): the one
/// definition of where sample `k` lies, each coordinate's operations the scalar
/// ones.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SamplePositions {
    start: Vec3A,
    step: Vec3A,
    last: Vec3A,
}

impl SamplePositions {
    /// The position of sample `k`, clamped into the box `[0, last]`.
    #[inline(always)]
    pub(crate) fn at(&self, k: u32) -> Vec3A {
        (self.start + self.step * k as f32).clamp(Vec3A::ZERO, self.last)
    }

    /// The positions `start + step·k`, clamped into the box `[0, last]`.
    #[cfg(test)]
    pub(crate) fn new(start: Vec3A, step: Vec3A, last: Vec3A) -> Self {
        SamplePositions { start, step, last }
    }

    /// The ray's first position, its step and the box's far corner, for kernels
    /// that compute [`Self::at`] in lanes of their own.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(crate) fn parts(&self) -> ([f32; 3], [f32; 3], [f32; 3]) {
        (
            self.start.to_array(),
            self.step.to_array(),
            self.last.to_array(),
        )
    }

    /// The positions of samples `k..k + 4`, per axis in four lanes: [`Self::at`]
    /// for each, with its operations.
    #[inline(always)]
    pub(crate) fn at_lanes(&self, k: u32) -> [Vec4; 3] {
        let ks = Vec4::from_array([0, 1, 2, 3].map(|i| k.saturating_add(i) as f32));
        let (start, step, last) = (self.start, self.step, self.last);
        [0, 1, 2].map(|a| {
            (Vec4::splat(start[a]) + Vec4::splat(step[a]) * ks)
                .max(Vec4::ZERO)
                .min(Vec4::splat(last[a]))
        })
    }
}

/// The ray-start jitter of pixel `(x, y)`, in `[0, 1)`: interleaved gradient
/// noise (Jimenez 2014), a blue-noise-like per-pixel pattern that needs no state,
/// so the sequential and parallel renderers give every pixel the same value.
#[inline]
pub fn ray_jitter(x: u32, y: u32) -> f32 {
    // In f64 so that large coordinates keep their fraction.
    let f = (0.067_110_56 * f64::from(x) + 0.005_837_15 * f64::from(y)).fract();
    let j = (52.982_918_9 * f).fract() as f32;
    // f64 → f32 rounding may give exactly 1.0.
    if j < 1.0 { j } else { 0.0 }
}

/// What a pixel has accumulated so far (`acc`, the compositor's state) and where
/// its ray stands; travels with its tile between bricks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PixelState<S> {
    /// The compositor's state.
    pub acc: S,
    /// The next sample index this pixel expects.
    pub next_sample: u32,
    /// The ray is finished: terminated early, hit, or past its last sample.
    pub done: bool,
}

impl<S> PixelState<S> {
    /// The state of a pixel whose ray has not started, the compositor's being
    /// `start`.
    pub fn new(start: S) -> Self {
        PixelState {
            acc: start,
            next_sample: 0,
            done: false,
        }
    }
}

/// Composites premultiplied `rgba` over `background` and quantises to 8 bits.
#[inline]
#[allow(clippy::manual_clamp)] // max/min, not clamp: NaN must become 0
pub fn over_background(rgba: [f32; 4], background: [f32; 3]) -> [u8; 3] {
    let rest = 1.0 - rgba[3];
    // (Three calls, not `[0, 1, 2].map`: the map stayed a call of its own.)
    let channel = |c: usize| {
        let v = rgba[c] + rest * background[c];
        (v * 255.0 + 0.5).max(0.0).min(255.0) as u8
    };
    [channel(0), channel(1), channel(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_in_lanes_are_the_scalar_positions() {
        let mut next = crate::render::test_rng::xorshift32(0x1234_5677);
        let mut unit = || (next() % 2_000_001) as f32 / 1_000_000.0 - 1.0;
        let mut clamped = 0;
        for _ in 0..2_000 {
            let positions = SamplePositions {
                start: Vec3A::new(unit() * 40.0, unit() * 40.0, unit() * 40.0),
                step: Vec3A::new(unit(), unit(), unit()) * 0.3,
                last: Vec3A::new(31.0, 17.0, 40.0),
            };
            let k = (unit().abs() * 300.0) as u32;
            let lanes = positions.at_lanes(k);
            for (i, k) in (k..k + 4).enumerate() {
                let scalar = positions.at(k);
                for a in 0..3 {
                    assert_eq!(lanes[a][i].to_bits(), scalar[a].to_bits(), "{k} {a}");
                    clamped += usize::from(scalar[a] == 0.0 || scalar[a] == positions.last[a]);
                }
            }
        }
        assert!(clamped > 100, "the clamp was exercised {clamped} times");
    }
}
