//! A linear ramp along x: value `x / (dims_x - 1)`.

use super::Scene;

/// The ramp scene (exact values, for tests).
pub struct Gradient {
    scale: f32,
}

impl Gradient {
    /// The ramp over a volume of `dims` (0 at x = 0, 1 at the last plane).
    pub fn new(dims: [u32; 3]) -> Self {
        Gradient {
            scale: 1.0 / dims[0].saturating_sub(1).max(1) as f32,
        }
    }
}

impl Scene for Gradient {
    fn fill_row(&self, x: u32, _y: u32, out: &mut [f32]) {
        out.fill(x as f32 * self.scale);
    }
}
