//! Nested spherical shells, each in its own value range, with an open octant so the
//! inner shells show; label `i + 1` marks shell `i`.

use super::Scene;

/// `(inner radius, outer radius)` of each shell as a fraction of the largest radius,
/// and the value range its samples take (from inside to outside of the shell).
const SHELLS: [(f32, f32, f32, f32); 4] = [
    (0.20, 0.32, 0.10, 0.20),
    (0.40, 0.52, 0.35, 0.45),
    (0.60, 0.72, 0.60, 0.70),
    (0.80, 0.92, 0.85, 0.95),
];

/// The shells scene.
pub struct Shells {
    center: [f32; 3],
    radius: f32,
}

impl Shells {
    /// Shells centred in a volume of `dims`, the outermost touching 0.92 of the
    /// half of the smallest side.
    pub fn new(dims: [u32; 3]) -> Self {
        let center = dims.map(|d| (d as f32 - 1.0) * 0.5);
        let radius = dims
            .iter()
            .map(|&d| d as f32 * 0.5)
            .fold(f32::MAX, f32::min);
        Shells { center, radius }
    }

    /// Which shell voxel `(x, y, z)` is in, and where across it (0 inside, 1 outside).
    fn locate(&self, x: u32, y: u32, z: u32) -> Option<(usize, f32)> {
        let d = [x as f32, y as f32, z as f32];
        let rel = [0, 1, 2].map(|a| d[a] - self.center[a]);
        if rel[0] < 0.0 && rel[1] < 0.0 && rel[2] > 0.0 {
            return None; // the open octant
        }
        let r = (rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt() / self.radius;
        SHELLS
            .iter()
            .position(|&(r0, r1, _, _)| r >= r0 && r < r1)
            .map(|i| (i, (r - SHELLS[i].0) / (SHELLS[i].1 - SHELLS[i].0)))
    }
}

impl Scene for Shells {
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]) {
        for (z, o) in out.iter_mut().enumerate() {
            *o = match self.locate(x, y, z as u32) {
                Some((i, t)) => SHELLS[i].2 + (SHELLS[i].3 - SHELLS[i].2) * t,
                None => 0.0,
            };
        }
    }

    fn fill_label_row(&self, x: u32, y: u32, out: &mut [u8]) {
        for (z, o) in out.iter_mut().enumerate() {
            *o = self.locate(x, y, z as u32).map_or(0, |(i, _)| i as u8 + 1);
        }
    }

    fn has_labels(&self) -> bool {
        true
    }
}
