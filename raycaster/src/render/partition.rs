//! Cutting a volume's brick grid into convex parts for distributed rendering:
//! a k-d split balanced by the bricks that hold something visible, and the
//! parts' front-to-back order for a camera.
//!
//! Each part is a box of whole bricks. Parts are disjoint and together cover
//! the grid, so every sample of a ray is owned by exactly one part; a split
//! plane is crossed by a ray at most once, so walking the k-d tree from the
//! side of the plane the rays start on gives an order in which every ray meets
//! the parts (the classic k-d tree visibility order).

use super::camera::{Camera, PixelRect, Projection};
use super::error::RenderError;
use super::geometry::VolumeGeometry;
use super::prepared::{FramePlan, RenderVolume};
use super::settings::RenderSettings;

/// A box of bricks: grid coordinates `lo..hi` per axis (half-open).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickBox {
    /// First brick per axis.
    pub lo: [u32; 3],
    /// One past the last brick per axis.
    pub hi: [u32; 3],
}

impl BrickBox {
    /// Whether the box holds no brick.
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| self.lo[a] >= self.hi[a])
    }

    /// Whether brick `b` lies in the box.
    #[inline]
    pub fn contains(&self, b: [u32; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= b[a] && b[a] < self.hi[a])
    }

    /// Bricks in the box.
    pub fn brick_count(&self) -> u64 {
        (0..3)
            .map(|a| u64::from(self.hi[a].saturating_sub(self.lo[a])))
            .product()
    }
}

/// A node of the k-d tree.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Node {
    /// Part number.
    Leaf(usize),
    /// Bricks with coordinate `axis` below `at` go to node `low`, the rest to
    /// node `high`.
    Split {
        axis: usize,
        at: u32,
        low: usize,
        high: usize,
    },
}

/// The brick grid cut into parts by a k-d tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    parts: Vec<BrickBox>,
    /// Per part: the bricks a frame renders (not droppable as empty).
    weights: Vec<u64>,
    /// Per part: the smallest box of its rendered bricks (`None`: none).
    occupied: Vec<Option<BrickBox>>,
    nodes: Vec<Node>,
}

impl Partition {
    /// Cuts `volume`'s brick grid into `parts` boxes for frames with `settings`
    /// (see `Partition::balanced`).
    pub fn new(
        volume: &RenderVolume<'_>,
        settings: &RenderSettings,
        parts: usize,
    ) -> Result<Partition, RenderError> {
        let plan = FramePlan::new(volume, settings)?;
        Ok(Partition::balanced(volume, &plan, parts))
    }

    /// Cuts the grid of `volume` into `parts` boxes (at least 1), balancing the
    /// bricks `plan` renders (non-empty under its transfer function): each split
    /// cuts the longer axis of a box where the two sides' shares of rendered
    /// bricks come closest to their shares of parts. A box one brick thick on
    /// every axis is not cut further; the parts it cannot give are empty.
    pub(crate) fn balanced(volume: &RenderVolume<'_>, plan: &FramePlan, parts: usize) -> Partition {
        let grid = volume.geometry().grid();
        let counts = grid.counts();
        let weight_of = |b: [u32; 3]| -> u64 { u64::from(!plan.brick_droppable(volume, b)) };
        let mut partition = Partition {
            parts: vec![
                BrickBox {
                    lo: [0; 3],
                    hi: [0; 3],
                };
                parts.max(1)
            ],
            weights: vec![0; parts.max(1)],
            occupied: vec![None; parts.max(1)],
            nodes: Vec::new(),
        };
        let whole = BrickBox {
            lo: [0; 3],
            hi: counts,
        };
        partition.split(whole, 0, parts.max(1), &weight_of);
        for (p, part) in partition.parts.iter().enumerate() {
            let mut occupied: Option<BrickBox> = None;
            let mut weight = 0;
            for_each_brick(part, |b| {
                if weight_of(b) == 0 {
                    return;
                }
                weight += 1;
                let o = occupied.get_or_insert(BrickBox { lo: b, hi: b });
                o.lo = [0, 1, 2].map(|a| o.lo[a].min(b[a]));
                o.hi = [0, 1, 2].map(|a| o.hi[a].max(b[a]));
            });
            partition.weights[p] = weight;
            partition.occupied[p] = occupied.map(|o| BrickBox {
                lo: o.lo,
                hi: o.hi.map(|c| c + 1),
            });
        }
        partition
    }

    /// Builds the subtree of `region` for parts `first..first + n`; returns its
    /// node index.
    fn split(
        &mut self,
        region: BrickBox,
        first: usize,
        n: usize,
        weight_of: &dyn Fn([u32; 3]) -> u64,
    ) -> usize {
        let node = self.nodes.len();
        self.nodes.push(Node::Leaf(first));
        let extent = [0, 1, 2].map(|a| region.hi[a].saturating_sub(region.lo[a]));
        let axis = (0..3).max_by_key(|&a| (extent[a], 2 - a)).unwrap_or(0);
        if n == 1 || extent[axis] < 2 {
            // One part, or a box that cannot be cut: the rest stay empty.
            self.parts[first] = region;
            return node;
        }
        let n_low = n / 2;
        let n_high = n - n_low;
        // Rendered bricks per slab along the axis.
        let mut slabs = vec![0u64; extent[axis] as usize];
        for_each_brick(&region, |b| {
            slabs[(b[axis] - region.lo[axis]) as usize] += weight_of(b);
        });
        let total: u64 = slabs.iter().sum();
        // Cut after slab c (1..extent): low share / n_low closest to high / n_high;
        // with nothing rendered, cut the bricks themselves in that proportion.
        let mut best = (u128::MAX, 1u32);
        let mut low = 0u64;
        for c in 1..extent[axis] {
            low += slabs[c as usize - 1];
            let (l, h) = if total == 0 {
                (u64::from(c), u64::from(extent[axis] - c))
            } else {
                (low, total - low)
            };
            let imbalance =
                (u128::from(l) * n_high as u128).abs_diff(u128::from(h) * n_low as u128);
            if imbalance < best.0 {
                best = (imbalance, c);
            }
        }
        let at = region.lo[axis] + best.1;
        let mut low_box = region;
        low_box.hi[axis] = at;
        let mut high_box = region;
        high_box.lo[axis] = at;
        let low = self.split(low_box, first, n_low, weight_of);
        let high = self.split(high_box, first + n_low, n_high, weight_of);
        self.nodes[node] = Node::Split {
            axis,
            at,
            low,
            high,
        };
        node
    }

    /// The parts, by part number.
    pub fn parts(&self) -> &[BrickBox] {
        &self.parts
    }

    /// Per part, the bricks a frame renders (its balancing weight).
    pub fn weights(&self) -> &[u64] {
        &self.weights
    }

    /// The part numbers front to back for `camera`: every ray meets the parts
    /// it crosses in this order.
    pub fn visibility_order(&self, camera: &Camera, geometry: &VolumeGeometry) -> Vec<usize> {
        // The side of a split plane rays start on: the eye's side (perspective),
        // or the side the common direction leaves (orthographic).
        let eye = (camera.position() - geometry.origin()) / geometry.spacing();
        let direction = camera.direction() / geometry.spacing();
        let step = geometry.brick_step();
        let low_first = |axis: usize, at: u32| -> bool {
            match camera.projection() {
                Projection::Perspective { .. } => eye[axis] < at as f32 * step,
                Projection::Orthographic { .. } => direction[axis] >= 0.0,
            }
        };
        let mut order = Vec::with_capacity(self.parts.len());
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            match self.nodes[n] {
                Node::Leaf(part) => order.push(part),
                Node::Split {
                    axis,
                    at,
                    low,
                    high,
                } => {
                    let (near, far) = if low_first(axis, at) {
                        (low, high)
                    } else {
                        (high, low)
                    };
                    stack.push(far);
                    stack.push(near);
                }
            }
        }
        // Parts a box too thin to cut left empty come last (they hold nothing).
        for p in 0..self.parts.len() {
            if !order.contains(&p) {
                order.push(p);
            }
        }
        order
    }

    /// The pixels part `p`'s rendered bricks can cover for `camera` (`None` when
    /// it renders nothing or projects outside the image).
    pub fn screen_rect(
        &self,
        p: usize,
        camera: &Camera,
        geometry: &VolumeGeometry,
    ) -> Option<PixelRect> {
        let occupied = self.occupied[p]?;
        let last = [occupied.hi[0] - 1, occupied.hi[1] - 1, occupied.hi[2] - 1];
        let (lo, _) = geometry.brick_world_box(occupied.lo);
        let (_, hi) = geometry.brick_world_box(last);
        camera.project_box(lo.min(hi), hi.max(lo))
    }
}

/// Calls `f` for every brick of `region`.
fn for_each_brick(region: &BrickBox, mut f: impl FnMut([u32; 3])) {
    for z in region.lo[2]..region.hi[2] {
        for y in region.lo[1]..region.hi[1] {
            for x in region.lo[0]..region.hi[0] {
                f([x, y, z]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{SceneKind, synthesize};
    use crate::volume::SampleType;
    use glam::Vec3;

    fn shapes(n: u32) -> crate::volume::Volume {
        let scene = SceneKind::Shapes.build([n; 3], 1);
        synthesize(scene.as_ref(), "shapes", [n; 3], [1.0; 3], SampleType::U8).unwrap()
    }

    #[test]
    fn parts_cover_the_grid_once_and_balance_the_rendered_bricks() {
        let volume = shapes(96);
        let prepared = RenderVolume::new(&volume, Some(9)).unwrap();
        let plan = FramePlan::new(&prepared, &RenderSettings::default()).unwrap();
        let grid = prepared.geometry().grid();
        for n in [1, 2, 3, 4, 5, 8] {
            let partition = Partition::balanced(&prepared, &plan, n);
            assert_eq!(partition.parts().len(), n);
            let mut owners = vec![0u32; grid.block_count() as usize];
            for part in partition.parts() {
                for_each_brick(part, |b| owners[grid.index(b) as usize] += 1);
            }
            assert!(owners.iter().all(|&o| o == 1), "{n} parts");
            let total: u64 = partition.weights().iter().sum();
            let rendered = (0..owners.len())
                .filter(|&i| !plan.brick_droppable(&prepared, grid.coords(i as u64)))
                .count() as u64;
            assert_eq!(total, rendered);
            let ideal = total as f64 / n as f64;
            for &w in partition.weights() {
                assert!(
                    (w as f64 - ideal).abs() <= 0.35 * ideal + 8.0,
                    "{n} parts: weights {:?}",
                    partition.weights()
                );
            }
        }
    }

    #[test]
    fn visibility_order_puts_the_part_nearer_along_every_ray_first() {
        let volume = shapes(64);
        let prepared = RenderVolume::new(&volume, Some(9)).unwrap();
        let geometry = prepared.geometry();
        let plan = FramePlan::new(&prepared, &RenderSettings::default()).unwrap();
        let partition = Partition::balanced(&prepared, &plan, 5);
        let part_of = |p: Vec3| {
            let b = geometry.owner(p);
            partition
                .parts()
                .iter()
                .position(|part| part.contains(b))
                .unwrap()
        };
        let (lo, hi) = geometry.world_bounds();
        let centre = (lo + hi) / 2.0;
        let eyes = [
            Vec3::new(-80.0, 20.0, 30.0),
            Vec3::new(150.0, -40.0, 90.0),
            centre + Vec3::new(3.0, -2.0, 1.0),
        ];
        for eye in eyes {
            for projection in [
                Projection::Perspective { vfov_deg: 60.0 },
                Projection::Orthographic { height: 120.0 },
            ] {
                let camera = Camera::look_at(eye, centre, Vec3::Z, projection, 24, 24).unwrap();
                let order = partition.visibility_order(&camera, geometry);
                let rank: Vec<usize> = (0..order.len())
                    .map(|p| order.iter().position(|&q| q == p).unwrap())
                    .collect();
                for y in 0..24 {
                    for x in 0..24 {
                        let ray = camera.ray(x, y);
                        let Some((t0, t1)) = ray.intersect_box(lo, hi) else {
                            continue;
                        };
                        let mut last = 0;
                        for i in 0..200 {
                            let t = t0 + (t1 - t0) * (i as f32 + 0.5) / 200.0;
                            let v = (ray.origin + ray.direction * t - geometry.origin())
                                / geometry.spacing();
                            let r = rank[part_of(v)];
                            assert!(r >= last, "ray ({x}, {y}) goes back to an earlier part");
                            last = r;
                        }
                    }
                }
            }
        }
    }
}
