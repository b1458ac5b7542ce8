//! Dozens of spheres and boxes, some nearly transparent, some opaque: the kind of
//! scene the reference thesis benchmarked on.

use super::Scene;
use super::rng::SplitMix64;

/// Number of objects in the scene.
const OBJECT_COUNT: usize = 48;

#[derive(Clone, Copy, Debug)]
enum Shape {
    /// Radius in voxels; the value falls by a quarter from centre to surface.
    Sphere { radius: f32 },
    /// Half extents in voxels; constant value.
    Box { half: [f32; 3] },
}

#[derive(Clone, Copy, Debug)]
struct Object {
    shape: Shape,
    center: [f32; 3],
    value: f32,
    /// Inclusive voxel bounds on x and y, to skip the object on rows it misses.
    lo: [f32; 2],
    hi: [f32; 2],
}

/// The shapes scene.
pub struct Shapes {
    objects: Vec<Object>,
}

impl Shapes {
    /// The objects for a volume of `dims`, placed from `seed`.
    pub fn new(dims: [u32; 3], seed: u64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x5348_4150_4553); // "SHAPES"
        let size = dims.map(|d| d as f32);
        let smallest = size.iter().copied().fold(f32::MAX, f32::min);
        let objects = (0..OBJECT_COUNT)
            .map(|_| {
                let center = size.map(|s| rng.range(0.1, 0.9) * s);
                // A third nearly transparent, the rest opaque-ish.
                let value = if rng.range(0.0, 1.0) < 0.33 {
                    rng.range(0.12, 0.30)
                } else {
                    rng.range(0.55, 1.0)
                };
                let (shape, reach) = if rng.range(0.0, 1.0) < 0.6 {
                    let radius = rng.range(0.04, 0.14) * smallest;
                    (Shape::Sphere { radius }, [radius; 2])
                } else {
                    let half = size.map(|s| rng.range(0.03, 0.12) * s);
                    (Shape::Box { half }, [half[0], half[1]])
                };
                Object {
                    shape,
                    center,
                    value,
                    lo: [center[0] - reach[0], center[1] - reach[1]],
                    hi: [center[0] + reach[0], center[1] + reach[1]],
                }
            })
            .collect();
        Shapes { objects }
    }
}

impl Scene for Shapes {
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]) {
        out.fill(0.0);
        let (xf, yf) = (x as f32, y as f32);
        let last = out.len() as f32 - 1.0;
        for o in &self.objects {
            if xf < o.lo[0] || xf > o.hi[0] || yf < o.lo[1] || yf > o.hi[1] {
                continue;
            }
            let [cx, cy, cz] = o.center;
            match o.shape {
                Shape::Sphere { radius } => {
                    let dxy2 = (xf - cx) * (xf - cx) + (yf - cy) * (yf - cy);
                    let r2 = radius * radius;
                    if dxy2 > r2 {
                        continue;
                    }
                    let half = (r2 - dxy2).sqrt();
                    let z0 = (cz - half).ceil().max(0.0);
                    let z1 = (cz + half).floor().min(last);
                    let mut z = z0;
                    while z <= z1 {
                        let d2 = dxy2 + (z - cz) * (z - cz);
                        let v = o.value * (1.0 - 0.25 * d2 / r2);
                        let slot = &mut out[z as usize];
                        *slot = slot.max(v);
                        z += 1.0;
                    }
                }
                Shape::Box { half } => {
                    if (xf - cx).abs() > half[0] || (yf - cy).abs() > half[1] {
                        continue;
                    }
                    let z0 = (cz - half[2]).ceil().max(0.0) as usize;
                    let z1 = (cz + half[2]).floor().min(last);
                    if z1 < 0.0 {
                        continue;
                    }
                    for slot in out.iter_mut().take(z1 as usize + 1).skip(z0) {
                        *slot = slot.max(o.value);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixes_transparent_and_opaque_objects() {
        let s = Shapes::new([64; 3], 7);
        let faint = s.objects.iter().filter(|o| o.value < 0.31).count();
        let opaque = s.objects.iter().filter(|o| o.value >= 0.55).count();
        assert!(faint >= 5 && opaque >= 20, "faint {faint}, opaque {opaque}");
        let spheres = s
            .objects
            .iter()
            .filter(|o| matches!(o.shape, Shape::Sphere { .. }))
            .count();
        assert!(spheres > 10 && spheres < OBJECT_COUNT - 5);
    }

    #[test]
    fn other_seed_moves_the_objects() {
        let (a, b) = (Shapes::new([64; 3], 1), Shapes::new([64; 3], 2));
        assert_ne!(a.objects[0].center, b.objects[0].center);
    }
}
