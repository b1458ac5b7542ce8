//! Fractal value noise (fBm) shaped into a cloud: dense in the middle, thinning out.

use super::rng::mix;
use super::{Scene, smoothstep};

const OCTAVES: usize = 5;
const BASE_FREQUENCY: u32 = 4;

/// One octave: a lattice of random values, `freq + 2` per axis.
struct Octave {
    freq: u32,
    values: Vec<f32>,
}

impl Octave {
    fn new(freq: u32, seed: u64) -> Self {
        let n = freq as usize + 2;
        let values = (0..n * n * n)
            .map(|i| {
                (mix(seed ^ (i as u64).wrapping_mul(0x2545_f491_4f6c_dd1d)) >> 40) as f32
                    / (1u64 << 24) as f32
            })
            .collect();
        Octave { freq, values }
    }

    /// Smoothly interpolated lattice value at `p` in `[0, 1]³`.
    fn at(&self, p: [f32; 3]) -> f32 {
        let n = self.freq as usize + 2;
        let q = p.map(|c| c * self.freq as f32);
        let i = q.map(|c| (c.floor() as usize).min(self.freq as usize));
        let t = [0, 1, 2].map(|a| smoothstep(0.0, 1.0, q[a] - i[a] as f32));
        let v = |dx: usize, dy: usize, dz: usize| {
            self.values[((i[0] + dx) * n + i[1] + dy) * n + i[2] + dz]
        };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(v(0, 0, 0), v(1, 0, 0), t[0]);
        let x10 = lerp(v(0, 1, 0), v(1, 1, 0), t[0]);
        let x01 = lerp(v(0, 0, 1), v(1, 0, 1), t[0]);
        let x11 = lerp(v(0, 1, 1), v(1, 1, 1), t[0]);
        lerp(lerp(x00, x10, t[1]), lerp(x01, x11, t[1]), t[2])
    }
}

/// The noise scene.
pub struct Noise {
    inv_size: [f32; 3],
    octaves: Vec<Octave>,
}

impl Noise {
    /// The cloud for a volume of `dims` from `seed`.
    pub fn new(dims: [u32; 3], seed: u64) -> Self {
        let octaves = (0..OCTAVES)
            .map(|o| Octave::new(BASE_FREQUENCY << o, mix(seed ^ o as u64)))
            .collect();
        Noise {
            inv_size: dims.map(|d| 1.0 / d.saturating_sub(1).max(1) as f32),
            octaves,
        }
    }

    fn value(&self, p: [f32; 3]) -> f32 {
        let (mut sum, mut amp, mut norm) = (0.0, 1.0, 0.0);
        for o in &self.octaves {
            sum += amp * o.at(p);
            norm += amp;
            amp *= 0.5;
        }
        let n = sum / norm;
        let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
        let falloff = 1.0 - smoothstep(0.2, 0.5, r);
        ((n * (0.4 + 0.6 * falloff) - 0.35) / 0.35).clamp(0.0, 1.0) * falloff
    }
}

impl Scene for Noise {
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]) {
        let (px, py) = (x as f32 * self.inv_size[0], y as f32 * self.inv_size[1]);
        for (z, o) in out.iter_mut().enumerate() {
            *o = self.value([px, py, z as f32 * self.inv_size[2]]);
        }
    }
}
