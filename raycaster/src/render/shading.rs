//! Blinn-Phong shading, applied where the gradient is strong enough to define a
//! surface normal (the thesis's threshold). Above the threshold it fades in: a
//! gradient at the threshold leaves the colour as it is, one
//! [`Shading::fade_width`] above it or more is fully lit. A hard switch drew
//! bands wherever a smooth field's gradient magnitude sits near the threshold
//! (an 8-bit ramp of about 100 voxels: its central differences alternate
//! between just below and just above 0.01). A frame widens the fade to cover
//! its data's quantisation ([`Shading::covering_quantum`]).

use glam::{Vec3, Vec4};

use super::optics::{light_vectors, specular_power, specular_power_lanes};

/// How many quantisation steps of the data (one raw unit over the transfer
/// function's domain) a frame's fade spans at least: the central differences
/// of quantised data jitter by half a step, which then moves the fade's weight
/// by about 4 % (over a narrower fade, bands of lit and unlit samples).
pub const FADE_QUANTA: f32 = 12.0;

/// Where the light comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// A light at the eye, shining along each ray.
    Headlight,
    /// A directional light shining along this world direction.
    Fixed(Vec3),
}

/// Blinn-Phong parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// The light.
    pub light: Light,
    /// Ambient coefficient.
    pub ambient: f32,
    /// Diffuse coefficient.
    pub diffuse: f32,
    /// Specular coefficient (white highlights).
    pub specular: f32,
    /// Specular exponent.
    pub shininess: f32,
    /// Gradient magnitude (normalised value per voxel) at and below which
    /// samples are left unshaded.
    pub gradient_threshold: f32,
    /// Over how much gradient magnitude above the threshold shading fades in
    /// (linearly, to full); 0 switches it on at once. A frame widens it to
    /// [`FADE_QUANTA`] quantisation steps of its data.
    pub fade_width: f32,
}

impl Default for Shading {
    fn default() -> Self {
        Shading {
            light: Light::Headlight,
            ambient: 0.3,
            diffuse: 0.7,
            specular: 0.25,
            shininess: 24.0,
            gradient_threshold: 0.01,
            fade_width: 0.03,
        }
    }
}

impl Shading {
    /// The fade's slope: shading's weight per unit of gradient magnitude above
    /// the threshold (infinite for a width of 0: full at once).
    #[inline]
    pub(crate) fn fade_rate(&self) -> f32 {
        1.0 / self.fade_width
    }

    /// The shading of a frame whose data is quantised in steps of `quantum`
    /// (normalised value: one raw unit over the transfer function's domain):
    /// the fade spans at least [`FADE_QUANTA`] of them (`0.047` for 8-bit data
    /// over its whole range, `0.005` for CT over 3000 HU: the default 0.03
    /// then).
    pub(crate) fn covering_quantum(self, quantum: f32) -> Shading {
        let widest = FADE_QUANTA * quantum;
        Shading {
            fade_width: if self.fade_width > 0.0 && widest > self.fade_width {
                widest
            } else {
                self.fade_width
            },
            ..self
        }
    }

    /// The colour `color` lit at a point with (unnormalised) gradient `gradient`,
    /// seen along the unit ray direction `view_dir`. Two-sided: `|N·L|`, `|N·H|`.
    /// Weighted by the fade above the threshold: `c + (lit − c)·weight`.
    #[inline]
    pub fn shade(&self, color: [f32; 3], gradient: Vec3, view_dir: Vec3) -> [f32; 3] {
        let magnitude = gradient.length();
        if magnitude <= self.gradient_threshold {
            return color;
        }
        let weight = ((magnitude - self.gradient_threshold) * self.fade_rate()).min(1.0);
        // `|normal · v|` as `|gradient · v| / magnitude`: one division per
        // light vector instead of three for the normal.
        let cosine = |v: Vec3| (gradient.dot(v) / magnitude).abs();
        let (diffuse, facing) = match self.light {
            // The headlight's half vector is its light vector: one dot product.
            Light::Headlight => {
                let d = cosine(-view_dir);
                (d, d)
            }
            Light::Fixed(_) => {
                let (to_light, half) = light_vectors(Some(self.light), view_dir);
                (cosine(to_light), cosine(half))
            }
        };
        let specular = self.specular * specular_power(facing, self.shininess);
        let k = self.ambient + self.diffuse * diffuse;
        color.map(|c| c + ((c * k + specular).min(1.0) - c) * weight)
    }

    /// The unit vectors towards the light and halfway to the eye for a ray of
    /// unit direction `view_dir`, once per ray for [`Self::shade_lanes`].
    #[inline]
    pub(crate) fn ray_lights(&self, view_dir: Vec3) -> (Vec3, Vec3) {
        light_vectors(Some(self.light), view_dir)
    }

    /// [`Self::shade`] of four samples of one ray at once: lane `i` of `color`
    /// and `gradient` (per channel, per axis) is one sample, `lights` the ray's
    /// [`Self::ray_lights`]. Each lane takes `shade`'s operations, so has its
    /// bits.
    #[inline(always)]
    pub(crate) fn shade_lanes(
        &self,
        color: [Vec4; 3],
        [gx, gy, gz]: [Vec4; 3],
        (to_light, half): (Vec3, Vec3),
    ) -> [Vec4; 3] {
        // `Vec3::length`: `(x·x + y·y) + z·z`, then the root.
        let magnitude = (gx * gx + gy * gy + gz * gz).sqrt();
        let lit = !magnitude.cmple(Vec4::splat(self.gradient_threshold));
        let weight = ((magnitude - Vec4::splat(self.gradient_threshold))
            * Vec4::splat(self.fade_rate()))
        .min(Vec4::ONE);
        // `shade`'s `|gradient · v| / magnitude`.
        let dot = |v: Vec3| {
            ((gx * Vec4::splat(v.x) + gy * Vec4::splat(v.y) + gz * Vec4::splat(v.z)) / magnitude)
                .abs()
        };
        let diffuse = dot(to_light);
        let facing = match self.light {
            Light::Headlight => diffuse,
            Light::Fixed(_) => dot(half),
        };
        let specular = Vec4::splat(self.specular) * specular_power_lanes(facing, self.shininess);
        let k = Vec4::splat(self.ambient) + Vec4::splat(self.diffuse) * diffuse;
        color.map(|c| Vec4::select(lit, c + ((c * k + specular).min(Vec4::ONE) - c) * weight, c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_the_headlight_is_fully_lit() {
        let s = Shading::default();
        let lit = s.shade([0.5; 3], Vec3::new(0.0, 0.0, -3.0), Vec3::Z);
        let expected = 0.5 * (s.ambient + s.diffuse) + s.specular;
        assert!((lit[0] - expected).abs() < 1e-6);
        // Two-sided: the opposite normal lights the same.
        assert_eq!(lit, s.shade([0.5; 3], Vec3::new(0.0, 0.0, 3.0), Vec3::Z));
    }

    #[test]
    fn grazing_light_leaves_ambient_and_weak_gradients_are_unshaded() {
        let s = Shading {
            specular: 0.0,
            ..Shading::default()
        };
        let grazing = s.shade([1.0; 3], Vec3::X, Vec3::Z);
        assert!((grazing[0] - s.ambient).abs() < 1e-6);
        assert_eq!(s.shade([0.7; 3], Vec3::X * 1e-4, Vec3::Z), [0.7; 3]);
    }

    /// Shading fades in above the threshold: no step where the magnitude
    /// crosses it (the bands of an 8-bit ramp), full from `fade_width` above
    /// it on, and the lanes take the same weights.
    #[test]
    fn shading_fades_in_between_the_threshold_and_full_shading() {
        let s = Shading::default();
        let t = s.gradient_threshold;
        let color = [0.6, 0.4, 0.2];
        // A normal at 60° to the headlight: lit darker than the colour.
        let direction = Vec3::new(0.0, 0.75f32.sqrt(), -0.5);
        let at = |m: f32| s.shade(color, direction * m, Vec3::Z);
        let full = at(10.0);
        assert!(full[0] < color[0] - 0.05, "{full:?}");
        assert_eq!(at(t), color);
        // Just above the threshold: within a hair of the unshaded colour (the
        // hard switch jumped to `full` here).
        let above = at(t * 1.001);
        assert!((above[0] - color[0]).abs() < 1e-3, "{above:?}");
        let w = s.fade_width;
        assert!((at(t + w)[0] - full[0]).abs() < 1e-6);
        let mut previous = color[0];
        for i in 1..=30 {
            let m = t + w * i as f32 / 30.0;
            let r = at(m)[0];
            assert!(
                r < previous && r >= full[0] - 1e-6,
                "{m}: {r} after {previous}"
            );
            previous = r;
        }
        // Halfway through the fade: halfway between.
        let half = at(t + w / 2.0);
        assert!(
            (half[0] - (color[0] + full[0]) / 2.0).abs() < 1e-5,
            "{half:?}"
        );
        // The lanes: the same bits, lane by lane.
        let magnitudes = [t * 0.5, t * 1.3, t * 2.9, t * 7.0];
        let g = [0, 1, 2].map(|a| Vec4::from_array(magnitudes.map(|m| (direction * m)[a])));
        let lanes = s.shade_lanes(
            [
                Vec4::splat(color[0]),
                Vec4::splat(color[1]),
                Vec4::splat(color[2]),
            ],
            g,
            s.ray_lights(Vec3::Z),
        );
        for (i, m) in magnitudes.into_iter().enumerate() {
            let one = at(m);
            for c in 0..3 {
                assert_eq!(
                    lanes[c].to_array()[i].to_bits(),
                    one[c].to_bits(),
                    "{m} {c}"
                );
            }
        }
    }

    /// A threshold and a fade of 0 shade every sample with a gradient fully;
    /// a frame's data widens a fade (not a hard switch) to its quantisation.
    #[test]
    fn a_zero_threshold_and_fade_shade_fully_at_once() {
        let s = Shading {
            gradient_threshold: 0.0,
            fade_width: 0.0,
            ..Shading::default()
        };
        let full = Shading::default().shade([0.5; 3], Vec3::Z * 5.0, Vec3::Z);
        assert_eq!(s.shade([0.5; 3], Vec3::Z * 1e-6, Vec3::Z), full);
        assert_eq!(s.shade([0.5; 3], Vec3::ZERO, Vec3::Z), [0.5; 3]);
        assert_eq!(s.covering_quantum(1.0 / 255.0).fade_width, 0.0);
        let d = Shading::default();
        assert_eq!(
            d.covering_quantum(1.0 / 255.0).fade_width,
            FADE_QUANTA * (1.0 / 255.0)
        );
        assert_eq!(d.covering_quantum(1.0 / 3000.0).fade_width, 0.03);
    }
}
