//! Blinn-Phong shading, applied where the gradient is strong enough to define a
//! surface normal (the thesis's threshold).

use glam::{Vec3, Vec4};

use super::optics::{light_vectors, specular_power, specular_power_lanes};

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
    /// Gradient magnitude (normalised value per voxel) below which samples are
    /// left unshaded.
    pub gradient_threshold: f32,
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
        }
    }
}

impl Shading {
    /// The colour `color` lit at a point with (unnormalised) gradient `gradient`,
    /// seen along the unit ray direction `view_dir`. Two-sided: `|N·L|`, `|N·H|`.
    #[inline]
    pub fn shade(&self, color: [f32; 3], gradient: Vec3, view_dir: Vec3) -> [f32; 3] {
        let magnitude = gradient.length();
        if magnitude <= self.gradient_threshold {
            return color;
        }
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
        color.map(|c| (c * k + specular).min(1.0))
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
        color.map(|c| Vec4::select(lit, (c * k + specular).min(Vec4::ONE), c))
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
}
