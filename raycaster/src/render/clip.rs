//! Cutting a volume open: an axis-aligned crop box and clipping planes.
//!
//! The kept part of the volume is the crop box intersected with the half-spaces the
//! planes keep: a convex region. A pixel's ray therefore crosses it in one interval
//! of its parameter `t`, found once when the ray is made
//! ([`super::pixel::PixelRay::new`]); the ray keeps the samples whose `t` lies in
//! that interval, at their global places (sample `k` stays at `t_enter + k·dt`),
//! and nothing per sample tests the region. Bricks entirely outside it are left
//! out of the frame.

use glam::Vec3;

use super::error::RenderError;
use super::ray::Ray;
use crate::volume::{full_resolution_coordinate, level_coordinate};

/// The most clipping planes a [`ClipRegion`] takes.
pub const MAX_CLIP_PLANES: usize = 6;

/// A clipping plane: keeps the half-space its normal points into,
/// `(p − point)·normal ≥ 0`, in volume voxel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipPlane {
    /// A point on the plane (voxel coordinates).
    pub point: Vec3,
    /// The plane's normal (voxel coordinates, any non-zero length), pointing
    /// into the kept half-space.
    pub normal: Vec3,
}

/// An axis-aligned box in volume voxel coordinates: the part of the volume a crop
/// keeps (voxel centres sit at integer coordinates; the whole volume is
/// `[0, dims − 1]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CropBox {
    /// The lower corner.
    pub lo: Vec3,
    /// The upper corner (at least `lo` on every axis).
    pub hi: Vec3,
}

/// What of a volume a frame shows: everything by default, or the part inside a
/// crop box and on the kept side of every clipping plane.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClipRegion {
    /// The crop box, if any.
    pub crop: Option<CropBox>,
    /// Up to [`MAX_CLIP_PLANES`] clipping planes.
    pub planes: Vec<ClipPlane>,
}

/// How far outside the kept region a sample's computed position can be while its
/// ray parameter is inside, in voxels: rounding of positions for coordinates up to
/// 2^14, with a wide margin (bricks are left out of a frame only beyond it).
const CUT_MARGIN: f32 = 0.05;

impl ClipRegion {
    /// Whether the region keeps the whole volume (no box, no planes).
    pub fn is_empty(&self) -> bool {
        self.crop.is_none() && self.planes.is_empty()
    }

    /// Checks the region: finite numbers, a box with `lo ≤ hi`, at most
    /// [`MAX_CLIP_PLANES`] planes with non-zero normals.
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |why: String| Err(RenderError::Clip(why));
        if let Some(CropBox { lo, hi }) = self.crop {
            if !(lo.is_finite() && hi.is_finite()) {
                return bad(format!("crop box {lo} – {hi} is not finite"));
            }
            // (A box flat along an axis holds no sample: an empty picture.
            // `raycaster render --crop` refuses it the same way.)
            if lo.cmpge(hi).any() {
                return bad(format!(
                    "crop box {lo} – {hi} is empty or inverted (lo ≥ hi along an axis)"
                ));
            }
        }
        if self.planes.len() > MAX_CLIP_PLANES {
            return bad(format!(
                "{} clipping planes (at most {MAX_CLIP_PLANES})",
                self.planes.len()
            ));
        }
        for p in &self.planes {
            if !(p.point.is_finite() && p.normal.is_finite()) {
                return bad(format!(
                    "clipping plane through {} with normal {} is not finite",
                    p.point, p.normal
                ));
            }
            if p.normal == Vec3::ZERO {
                return bad(format!(
                    "clipping plane through {} has a zero normal",
                    p.point
                ));
            }
        }
        Ok(())
    }

    /// Refuses a crop box that lies outside the volume along an axis (its
    /// picture would be empty; `raycaster render --crop` refuses it the same
    /// way, by the flag's name). (A clipping plane with the whole volume on its
    /// cut side is kept: the viewer's plane slider reaches past the volume, and
    /// the frame is background.) The region is in full-resolution
    /// voxels, as [`RenderSettings::clip`](super::RenderSettings::clip) holds
    /// it; `sampled` is the box the level rendered samples, in its voxels
    /// ([`crate::volume::Volume::sampled_box`]), which span `scale` (`2^k`)
    /// full-resolution ones ([`Self::at_level`]).
    pub fn check_overlaps(&self, sampled: [[f32; 3]; 2], scale: f32) -> Result<(), RenderError> {
        let level = self.at_level(scale);
        let [first, last] = sampled.map(Vec3::from);
        // The sampled box's upper corner in full-resolution voxels.
        let full = sampled[1].map(|c| full_resolution_coordinate(c, scale));
        if let (Some(CropBox { lo, hi }), Some(at_level)) = (self.crop, level.crop) {
            for (a, name) in ["x", "y", "z"].into_iter().enumerate() {
                // (Half a voxel of slack, in the level's voxels.)
                if at_level.hi[a] < first[a] - 0.5 || at_level.lo[a] > last[a] + 0.5 {
                    return Err(RenderError::Clip(format!(
                        "crop box {lo} – {hi} lies outside the volume along {name} (0..{} voxels)",
                        full[a]
                    )));
                }
            }
        }
        Ok(())
    }

    /// The region in the voxel coordinates of a pyramid level whose voxels span
    /// `scale` (`2^k`) level-0 voxels, the region being in level-0 voxels: level
    /// `k`'s voxel `(0, 0, 0)` sits at `(scale − 1)/2` level-0 voxels.
    pub fn at_level(&self, scale: f32) -> ClipRegion {
        if scale == 1.0 {
            return self.clone();
        }
        let map = |p: Vec3| Vec3::from(p.to_array().map(|c| level_coordinate(c, scale)));
        ClipRegion {
            crop: self.crop.map(|c| CropBox {
                lo: map(c.lo),
                hi: map(c.hi),
            }),
            planes: self
                .planes
                .iter()
                .map(|p| ClipPlane {
                    point: map(p.point),
                    normal: p.normal,
                })
                .collect(),
        }
    }

    /// The parameter interval `[t0, t1]` of `ray` (voxel coordinates, `t` as the
    /// caller measures it) inside the region, clipped to `[t_min, t_max]`; `None`
    /// when it is empty.
    pub(crate) fn interval(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (t_min, t_max);
        if let Some(CropBox { lo, hi }) = self.crop {
            // `intersect_box` starts at t = 0: the ray's box interval is within.
            let (b0, b1) = ray.intersect_box(lo, hi)?;
            t0 = t0.max(b0);
            t1 = t1.min(b1);
        }
        for p in &self.planes {
            // (o + t·d − q)·n ≥ 0  ⇔  a + t·b ≥ 0.
            let a = (ray.origin - p.point).dot(p.normal);
            let b = ray.direction.dot(p.normal);
            if b == 0.0 {
                if a < 0.0 {
                    return None;
                }
            } else if b > 0.0 {
                t0 = t0.max(-a / b);
            } else {
                t1 = t1.min(-a / b);
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// Whether voxel position `p` lies in the region (on its boundary included).
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        if let Some(CropBox { lo, hi }) = self.crop
            && (p.cmplt(lo).any() || p.cmpgt(hi).any())
        {
            return false;
        }
        self.planes
            .iter()
            .all(|plane| (p - plane.point).dot(plane.normal) >= 0.0)
    }

    /// Whether the voxel box `[lo, hi]` lies entirely outside the region (by more
    /// than a rounding margin): outside the crop box, or wholly on the cut side of
    /// one plane. Conservative: a box cut away only by several planes together is
    /// kept.
    pub(crate) fn cuts_away(&self, lo: Vec3, hi: Vec3) -> bool {
        if let Some(crop) = self.crop
            && (hi.cmplt(crop.lo - CUT_MARGIN).any() || lo.cmpgt(crop.hi + CUT_MARGIN).any())
        {
            return true;
        }
        self.planes.iter().any(|p| p.cuts_away(lo, hi))
    }

    /// The first of the region's planes that keeps nothing of the box the
    /// volume samples (`sampled`, full-resolution voxels:
    /// [`crate::volume::Volume::sampled_box`]), which then renders background:
    /// what front ends warn of.
    pub fn plane_keeping_nothing(&self, sampled: [[f32; 3]; 2]) -> Option<ClipPlane> {
        let [lo, hi] = sampled.map(Vec3::from);
        self.planes.iter().copied().find(|p| p.cuts_away(lo, hi))
    }

    /// Whether the region keeps nothing of the box the volume samples
    /// (`sampled`, as for [`Self::plane_keeping_nothing`]): the box, the crop
    /// box and the planes' half-spaces have no point in common, by more than
    /// a rounding margin. (They are convex: a common part has a corner where
    /// three of their faces meet, so the corners are what is tried.)
    pub fn keeps_nothing_of(&self, sampled: [[f32; 3]; 2]) -> bool {
        let [mut lo, mut hi] = sampled.map(Vec3::from);
        if let Some(crop) = &self.crop {
            lo = lo.max(crop.lo);
            hi = hi.min(crop.hi);
        }
        if (lo - hi).max_element() > CUT_MARGIN {
            return true;
        }
        // Every face as `n·p ≥ c` with a unit normal `n`.
        let mut faces: Vec<(Vec3, f32)> = Vec::with_capacity(6 + self.planes.len());
        for axis in 0..3 {
            let n = Vec3::AXES[axis];
            faces.push((n, lo[axis]));
            faces.push((-n, -hi[axis]));
        }
        for p in &self.planes {
            let n = p.normal.normalize_or_zero();
            faces.push((n, n.dot(p.point)));
        }
        let kept = |q: Vec3| faces.iter().all(|&(n, c)| n.dot(q) - c >= -CUT_MARGIN);
        let f = faces.len();
        for i in 0..f {
            for j in i + 1..f {
                for k in j + 1..f {
                    let ([a, b, c], rhs) = (
                        [faces[i].0, faces[j].0, faces[k].0],
                        Vec3::new(faces[i].1, faces[j].1, faces[k].1),
                    );
                    let m = glam::Mat3::from_cols(a, b, c).transpose();
                    if m.determinant().abs() < 1e-6 {
                        continue;
                    }
                    if kept(m.inverse() * rhs) {
                        return false;
                    }
                }
            }
        }
        true
    }
}

impl ClipPlane {
    /// Whether the voxel box `[lo, hi]` lies wholly on the plane's cut side,
    /// by more than a rounding margin.
    fn cuts_away(&self, lo: Vec3, hi: Vec3) -> bool {
        let n = self.normal.normalize_or_zero();
        // The box corner farthest along the normal.
        let corner = Vec3::select(n.cmpge(Vec3::ZERO), hi, lo);
        (corner - self.point).dot(n) < -CUT_MARGIN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray_x() -> Ray {
        Ray {
            origin: Vec3::new(-10.0, 2.0, 2.0),
            direction: Vec3::X,
        }
    }

    #[test]
    fn a_region_keeps_nothing_only_where_box_crop_and_planes_share_no_point() {
        let sampled = [[0.0, 0.0, 0.0], [63.0, 63.0, 63.0]];
        let plane = |point: [f32; 3], normal: [f32; 3]| ClipPlane {
            point: Vec3::from(point),
            normal: Vec3::from(normal),
        };
        let region = |crop: Option<([f32; 3], [f32; 3])>, planes: Vec<ClipPlane>| ClipRegion {
            crop: crop.map(|(lo, hi)| CropBox {
                lo: Vec3::from(lo),
                hi: Vec3::from(hi),
            }),
            planes,
        };
        // Each plane keeps half; together, opposite sides of two parallel
        // planes keep nothing, and with a gap between them something.
        let apart = region(
            None,
            vec![
                plane([40.0; 3], [1.0, 0.0, 0.0]),
                plane([20.0; 3], [-1.0, 0.0, 0.0]),
            ],
        );
        assert!(apart.plane_keeping_nothing(sampled).is_none());
        assert!(apart.keeps_nothing_of(sampled));
        let gap = region(
            None,
            vec![
                plane([20.0; 3], [1.0, 0.0, 0.0]),
                plane([40.0; 3], [-1.0, 0.0, 0.0]),
            ],
        );
        assert!(!gap.keeps_nothing_of(sampled));
        // A crop box beside an oblique plane's kept side, and inside it.
        let diagonal = plane([32.0; 3], [1.0, 1.0, 1.0]);
        let low_corner = region(Some(([0.0; 3], [10.0; 3])), vec![diagonal]);
        assert!(low_corner.plane_keeping_nothing(sampled).is_none());
        assert!(low_corner.keeps_nothing_of(sampled));
        let high_corner = region(Some(([50.0; 3], [63.0; 3])), vec![diagonal]);
        assert!(!high_corner.keeps_nothing_of(sampled));
        // Three oblique planes meeting beyond the box's corner keep only that
        // corner's neighbourhood; pushed past it, nothing.
        let corner = |at: f32| {
            region(
                None,
                vec![
                    plane([at, 0.0, 0.0], [1.0, 0.2, 0.0]),
                    plane([0.0, at, 0.0], [0.0, 1.0, 0.2]),
                    plane([0.0, 0.0, at], [0.2, 0.0, 1.0]),
                ],
            )
        };
        assert!(!corner(60.0).keeps_nothing_of(sampled));
        assert!(corner(80.0).keeps_nothing_of(sampled));
        // Nothing cut: the whole box.
        assert!(!ClipRegion::default().keeps_nothing_of(sampled));
    }

    #[test]
    fn box_and_planes_cut_one_interval() {
        let region = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::new(2.0, 0.0, 0.0),
                hi: Vec3::new(12.0, 5.0, 5.0),
            }),
            planes: vec![ClipPlane {
                point: Vec3::new(8.0, 0.0, 0.0),
                normal: Vec3::new(-2.0, 0.0, 0.0),
            }],
        };
        assert_eq!(region.interval(&ray_x(), 10.0, 30.0), Some((12.0, 18.0)));
        // A plane keeping nothing of the ray, and one parallel to it.
        let mut away = region.clone();
        away.planes.push(ClipPlane {
            point: Vec3::new(20.0, 0.0, 0.0),
            normal: Vec3::X,
        });
        assert_eq!(away.interval(&ray_x(), 10.0, 30.0), None);
        let parallel = ClipRegion {
            crop: None,
            planes: vec![ClipPlane {
                point: Vec3::new(0.0, 3.0, 0.0),
                normal: Vec3::Y,
            }],
        };
        assert_eq!(parallel.interval(&ray_x(), 10.0, 30.0), None);
        let parallel_kept = ClipRegion {
            crop: None,
            planes: vec![ClipPlane {
                point: Vec3::new(0.0, 1.0, 0.0),
                normal: Vec3::Y,
            }],
        };
        assert_eq!(
            parallel_kept.interval(&ray_x(), 10.0, 30.0),
            Some((10.0, 30.0))
        );
    }

    #[test]
    fn bricks_outside_are_cut_away() {
        let region = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::splat(8.0),
                hi: Vec3::splat(16.0),
            }),
            planes: vec![ClipPlane {
                point: Vec3::splat(12.0),
                normal: Vec3::new(1.0, 1.0, 0.0),
            }],
        };
        assert!(region.cuts_away(Vec3::ZERO, Vec3::splat(7.0)));
        // Touching the box, but behind the plane; then in front of it.
        assert!(region.cuts_away(Vec3::ZERO, Vec3::splat(8.0)));
        assert!(!region.cuts_away(Vec3::new(0.0, 15.0, 0.0), Vec3::new(8.0, 30.0, 8.0)));
        // Inside the box but behind the plane.
        assert!(region.cuts_away(Vec3::splat(8.0), Vec3::new(11.0, 12.0, 16.0)));
        assert!(!region.cuts_away(Vec3::splat(8.0), Vec3::new(12.0, 12.0, 16.0)));
        assert!(!ClipRegion::default().cuts_away(Vec3::ZERO, Vec3::ONE));
    }

    #[test]
    fn validation_names_the_problem() {
        let inverted = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::splat(3.0),
                hi: Vec3::new(5.0, 2.0, 5.0),
            }),
            planes: Vec::new(),
        };
        assert!(
            inverted
                .validate()
                .unwrap_err()
                .to_string()
                .contains("inverted")
        );
        let flat = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::new(0.0, 0.0, 4.0),
                hi: Vec3::new(9.0, 9.0, 4.0),
            }),
            planes: Vec::new(),
        };
        let e = flat.validate().unwrap_err().to_string();
        assert!(e.contains("is empty or inverted"), "{e}");
        // A box beside the volume (32 voxels a side) along y; one that
        // overlaps it, or reaches past its end by under half a voxel (where a
        // coarser level's voxels lie), is kept.
        let boxed = |lo: [f32; 3], hi: [f32; 3]| ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::from(lo),
                hi: Vec3::from(hi),
            }),
            planes: Vec::new(),
        };
        let e = boxed([0.0, 40.0, 0.0], [9.0, 50.0, 9.0])
            .check_overlaps([[0.0; 3], [31.0; 3]], 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lies outside the volume along y (0..31 voxels)"),
            "{e}"
        );
        assert!(
            boxed([0.0, 20.0, 0.0], [9.0, 50.0, 9.0])
                .check_overlaps([[0.0; 3], [31.0; 3]], 1.0)
                .is_ok()
        );
        assert!(
            boxed([0.0, 31.4, 0.0], [9.0, 50.0, 9.0])
                .check_overlaps([[0.0; 3], [31.0; 3]], 1.0)
                .is_ok()
        );
        assert!(
            boxed([-9.0, 0.0, 0.0], [-1.0, 9.0, 9.0])
                .check_overlaps([[0.0; 3], [31.0; 3]], 1.0)
                .is_err()
        );
        // The box is in full-resolution voxels whatever level is rendered: a
        // box in the far half of a 512-voxel axis overlaps pyramid level 3
        // (64 voxels of 8), and one past the volume's end does not.
        // lung1 (512 × 512 × 48) at level 3: 64 × 64 × 6 voxels of 8, sampled
        // from the full-resolution box's faces.
        const LUNG_LEVEL_3: [[f32; 3]; 2] = [[-0.4375; 3], [63.4375, 63.4375, 5.4375]];
        let far = boxed([0.0, 229.95, 0.0], [511.0, 511.0, 47.0]);
        assert!(far.check_overlaps(LUNG_LEVEL_3, 8.0).is_ok());
        assert!(
            far.check_overlaps([[0.0; 3], [511.0, 511.0, 47.0]], 1.0)
                .is_ok()
        );
        assert!(
            boxed([0.0, 511.0, 0.0], [9.0, 511.0, 9.0])
                .check_overlaps(LUNG_LEVEL_3, 8.0)
                .is_ok()
        );
        let e = boxed([0.0, 530.0, 0.0], [9.0, 600.0, 9.0])
            .check_overlaps(LUNG_LEVEL_3, 8.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lies outside the volume along y (0..511 voxels)"),
            "{e}"
        );
        // A plane with the whole volume on its cut side keeps nothing (kept:
        // the frame is background), one facing the other way everything.
        let planes = |x: f32, nx: f32| ClipRegion {
            crop: None,
            planes: vec![
                ClipPlane {
                    point: Vec3::splat(16.0),
                    normal: Vec3::Y,
                },
                ClipPlane {
                    point: Vec3::new(x, 0.0, 0.0),
                    normal: Vec3::new(nx, 0.0, 0.0),
                },
            ],
        };
        let cube = [[0.0; 3], [31.0; 3]];
        assert_eq!(
            planes(40.0, 1.0)
                .plane_keeping_nothing(cube)
                .map(|p| p.point.x),
            Some(40.0)
        );
        assert!(planes(40.0, 1.0).check_overlaps(cube, 1.0).is_ok());
        assert_eq!(planes(40.0, -1.0).plane_keeping_nothing(cube), None);
        assert_eq!(planes(30.5, 1.0).plane_keeping_nothing(cube), None);
        let zero = ClipRegion {
            crop: None,
            planes: vec![ClipPlane {
                point: Vec3::ZERO,
                normal: Vec3::ZERO,
            }],
        };
        assert!(
            zero.validate()
                .unwrap_err()
                .to_string()
                .contains("zero normal")
        );
        let nan = ClipRegion {
            crop: None,
            planes: vec![ClipPlane {
                point: Vec3::new(f32::NAN, 0.0, 0.0),
                normal: Vec3::X,
            }],
        };
        assert!(nan.validate().is_err());
        let many = ClipRegion {
            crop: None,
            planes: vec![
                ClipPlane {
                    point: Vec3::ZERO,
                    normal: Vec3::X
                };
                7
            ],
        };
        assert!(many.validate().is_err());
        assert!(ClipRegion::default().validate().is_ok());
    }
}
