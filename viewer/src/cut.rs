//! The "Cut" panel: crop sliders per axis and one clipping plane set by an
//! offset and two angles, turned into the library's [`ClipRegion`] and back.
//!
//! Crop bounds are fractions 0..1 of each axis, snapped to whole voxels (a
//! slider at 0.5 on a 160-voxel axis cuts at voxel 80); with every bound at
//! its end the region has no crop box. The plane keeps the half-space its
//! normal points into: the normal has azimuth `a` (about +z, from +x) and
//! elevation `e` (from the xy plane), `(cos e cos a, cos e sin a, sin e)`; the
//! plane passes through the volume's centre moved `offset` × half its diagonal
//! along the normal (offset −1..1: −1 keeps everything, 1 nothing).

use glam::Vec3;
use raycaster::render::{ClipPlane, ClipRegion, CropBox};

/// What the Cut panel shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CutValues {
    /// Lower crop bound per axis, a fraction 0..1 of the axis.
    pub lo: [f32; 3],
    /// Upper crop bound per axis, a fraction 0..1 of the axis.
    pub hi: [f32; 3],
    /// Whether the clipping plane cuts.
    pub plane: bool,
    /// The plane's offset from the centre along its normal, in half diagonals (−1..1).
    pub offset: f32,
    /// The normal's azimuth, degrees (−180..180).
    pub azimuth: f32,
    /// The normal's elevation, degrees (−90..90).
    pub elevation: f32,
}

impl Default for CutValues {
    fn default() -> CutValues {
        CutValues {
            lo: [0.0; 3],
            hi: [1.0; 3],
            plane: false,
            offset: 0.0,
            azimuth: 0.0,
            elevation: 0.0,
        }
    }
}

/// The last voxel index per axis as a float (at least 1, so fractions divide).
fn extent(dims: [u32; 3]) -> Vec3 {
    Vec3::from(dims.map(|d| d.saturating_sub(1).max(1) as f32))
}

/// The voxel a crop fraction cuts at on an axis whose last index is `last`.
pub(crate) fn crop_voxel(fraction: f32, last: f32) -> f32 {
    (fraction.clamp(0.0, 1.0) * last).round()
}

/// The unit normal of azimuth `azimuth` and elevation `elevation` (degrees).
pub(crate) fn normal(azimuth: f32, elevation: f32) -> Vec3 {
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

impl CutValues {
    /// The region these values keep in a volume of `dims` voxels (level 0)
    /// `spacing` apart. The plane's angles and offset are measured in world
    /// space (the voxels' spacing counts: 45° on a CT of 5 mm slices 0.6 mm
    /// apart in-plane is 45° in the body, not 7°); the region, like `--clip`,
    /// holds it in voxels.
    pub(crate) fn region(&self, dims: [u32; 3], spacing: [f32; 3]) -> ClipRegion {
        let last = extent(dims);
        let mut lo = Vec3::ZERO;
        let mut hi = Vec3::ZERO;
        for a in 0..3 {
            let (l, h) = (
                crop_voxel(self.lo[a], last[a]),
                crop_voxel(self.hi[a], last[a]),
            );
            // Crossed sliders keep the voxels between them, never an inverted
            // box; sliders that meet keep one voxel's slab (a flat box holds
            // no sample, and sessions and `--crop` refuse it).
            lo[a] = l.min(h);
            hi[a] = l.max(h);
            if hi[a] == lo[a] {
                if hi[a] < last[a] {
                    hi[a] += 1.0;
                } else {
                    lo[a] -= 1.0;
                }
            }
        }
        let crop = (lo != Vec3::ZERO || hi != last).then_some(CropBox { lo, hi });
        let planes = if self.plane {
            // In world space (voxel 0 at the origin), then in voxels: a point
            // divides by the spacing, a normal multiplies by it.
            let spacing = world_scale(spacing);
            let n = normal(self.azimuth, self.elevation);
            let size = last * spacing;
            let point = size / 2.0 + n * (self.offset.clamp(-1.0, 1.0) * size.length() / 2.0);
            vec![ClipPlane {
                point: point / spacing,
                normal: (n * spacing).normalize_or_zero(),
            }]
        } else {
            Vec::new()
        };
        ClipRegion { crop, planes }
    }

    /// [`Self::region`] after the panel showed `before` for the region `kept`
    /// (a session's, restored bit for bit): the bounds and the plane whose
    /// controls did not move keep `kept`'s values (a session's crop at z 0.7
    /// stays 0.7 when the x slider moves; snapped it became 1), the others
    /// are the panel's. An axis whose kept and moved bounds would cross takes
    /// the panel's two.
    pub(crate) fn region_after(
        &self,
        before: &CutValues,
        kept: &ClipRegion,
        dims: [u32; 3],
        spacing: [f32; 3],
    ) -> ClipRegion {
        let mut region = self.region(dims, spacing);
        let last = extent(dims);
        let kept_crop = kept.crop.unwrap_or(CropBox {
            lo: Vec3::ZERO,
            hi: last,
        });
        let mut crop = region.crop.unwrap_or(CropBox {
            lo: Vec3::ZERO,
            hi: last,
        });
        for a in 0..3 {
            let lo = if self.lo[a] == before.lo[a] {
                kept_crop.lo[a]
            } else {
                crop.lo[a]
            };
            let hi = if self.hi[a] == before.hi[a] {
                kept_crop.hi[a]
            } else {
                crop.hi[a]
            };
            // (Crossed or met sliders: the panel's rule for them.)
            if self.lo[a] < self.hi[a] && lo < hi {
                (crop.lo[a], crop.hi[a]) = (lo, hi);
            }
        }
        region.crop = (crop.lo != Vec3::ZERO || crop.hi != last).then_some(crop);
        let plane_unmoved = (self.plane, self.offset, self.azimuth, self.elevation)
            == (
                before.plane,
                before.offset,
                before.azimuth,
                before.elevation,
            );
        if plane_unmoved
            && let (Some(first), Some(kept_first)) =
                (region.planes.first_mut(), kept.planes.first())
        {
            *first = *kept_first;
        }
        region
    }

    /// The panel's values for `region` in a volume of `dims` voxels `spacing`
    /// apart: the crop box as fractions and the region's first plane (others
    /// are not shown), its angles and offset in world space ([`Self::region`]'s
    /// inverse).
    pub(crate) fn from_region(region: &ClipRegion, dims: [u32; 3], spacing: [f32; 3]) -> CutValues {
        let last = extent(dims);
        let mut values = CutValues::default();
        if let Some(CropBox { lo, hi }) = region.crop {
            for a in 0..3 {
                values.lo[a] = (lo[a] / last[a]).clamp(0.0, 1.0);
                values.hi[a] = (hi[a] / last[a]).clamp(0.0, 1.0);
            }
        }
        if let Some(p) = region.planes.first() {
            let spacing = world_scale(spacing);
            let n = (p.normal / spacing).normalize_or_zero();
            if n != Vec3::ZERO {
                values.plane = true;
                // (+ 0: a signed zero picks no side, -180° against 180°.)
                values.azimuth = (n.y + 0.0).atan2(n.x + 0.0).to_degrees();
                values.elevation = n.z.clamp(-1.0, 1.0).asin().to_degrees();
                let size = last * spacing;
                let from_centre = p.point * spacing - size / 2.0;
                values.offset = (from_centre.dot(n) / (size.length() / 2.0)).clamp(-1.0, 1.0);
            }
        }
        values
    }
}

/// `spacing` as a world scale per axis: positive and finite (1 where it is
/// not, so a broken spacing cuts as voxels do).
fn world_scale(spacing: [f32; 3]) -> Vec3 {
    Vec3::from(spacing.map(|s| if s.is_finite() && s > 0.0 { s } else { 1.0 }))
}

/// What each crop row says: the voxels `region` keeps along x, y and z of a
/// volume of `dims` voxels, `x 0 .. 24 of 0 .. 47 voxels` (a session's box
/// may end between voxels: up to two decimals then).
pub(crate) fn kept_voxels(region: &ClipRegion, dims: [u32; 3]) -> [String; 3] {
    let last = extent(dims);
    let number = |v: f32| {
        let text = format!("{v:.2}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    std::array::from_fn(|a| {
        let (lo, hi) = region.crop.map_or((0.0, last[a]), |c| (c.lo[a], c.hi[a]));
        format!(
            "{} {} .. {} of 0 .. {} voxels",
            ["x", "y", "z"][a],
            number(lo),
            number(hi),
            number(last[a])
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows say the voxels the frame's region keeps: crossed sliders what
    /// lies between them, sliders that meet one voxel's slab (46 .. 47 at the
    /// top), a session's box between voxels with a decimal.
    #[test]
    fn crop_rows_say_the_voxels_the_region_keeps() {
        let dims = [48, 40, 48];
        let values = CutValues {
            lo: [0.0, 0.75, 1.0],
            hi: [0.5, 0.25, 1.0],
            ..CutValues::default()
        };
        assert_eq!(
            kept_voxels(&values.region(dims, [1.0; 3]), dims),
            [
                "x 0 .. 24 of 0 .. 47 voxels",
                "y 10 .. 29 of 0 .. 39 voxels",
                "z 46 .. 47 of 0 .. 47 voxels",
            ]
        );
        let whole = kept_voxels(&CutValues::default().region(dims, [1.0; 3]), dims);
        assert_eq!(whole[1], "y 0 .. 39 of 0 .. 39 voxels");
        let session = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::new(0.0, 229.95, 0.0),
                hi: Vec3::new(511.0, 511.0, 47.0),
            }),
            planes: Vec::new(),
        };
        assert_eq!(
            kept_voxels(&session, [512, 512, 48])[1],
            "y 229.95 .. 511 of 0 .. 511 voxels"
        );
    }

    #[test]
    fn full_sliders_and_no_plane_cut_nothing() {
        assert!(CutValues::default().region([160; 3], [1.0; 3]).is_empty());
    }

    #[test]
    fn crop_fractions_snap_to_voxels() {
        let v = CutValues {
            lo: [0.0, 0.25, 0.0],
            hi: [1.0, 0.5, 1.0],
            ..CutValues::default()
        };
        let r = v.region([161, 161, 11], [1.0; 3]);
        let crop = r.crop.unwrap();
        assert_eq!(crop.lo, Vec3::new(0.0, 40.0, 0.0));
        assert_eq!(crop.hi, Vec3::new(160.0, 80.0, 10.0));
        assert!(r.planes.is_empty());
        assert_eq!(CutValues::from_region(&r, [161, 161, 11], [1.0; 3]), v);
    }

    #[test]
    fn a_moved_slider_leaves_a_restored_sessions_other_bounds_and_plane_as_they_were() {
        let (dims, spacing) = ([11, 21, 31], [1.0, 1.0, 2.0]);
        let kept = ClipRegion {
            crop: Some(CropBox {
                lo: Vec3::new(0.0, 2.3, 0.7),
                hi: Vec3::new(10.0, 17.6, 29.2),
            }),
            planes: vec![ClipPlane {
                point: Vec3::new(5.1, 9.7, 14.9),
                normal: Vec3::new(0.3, -0.2, 0.9),
            }],
        };
        let before = CutValues::from_region(&kept, dims, spacing);
        // Unmoved: the region itself.
        let same = before.region_after(&before, &kept, dims, spacing);
        assert_eq!(same, kept);
        // The x slider moved: x snaps, y and z and the plane stay.
        let mut moved = before;
        moved.lo[0] = 0.5;
        let after = moved.region_after(&before, &kept, dims, spacing);
        let crop = after.crop.unwrap();
        assert_eq!(crop.lo, Vec3::new(5.0, 2.3, 0.7));
        assert_eq!(crop.hi, kept.crop.unwrap().hi);
        assert_eq!(after.planes, kept.planes);
        // The plane moved: the panel's plane, the crop kept.
        let mut turned = before;
        turned.azimuth += 10.0;
        let after = turned.region_after(&before, &kept, dims, spacing);
        assert_eq!(after.crop, kept.crop);
        assert_ne!(after.planes, kept.planes);
        assert_eq!(after.planes, turned.region(dims, spacing).planes);
        // A moved bound past a kept one: the panel's two.
        let mut crossed = before;
        crossed.hi[2] = 0.0;
        let crop = crossed
            .region_after(&before, &kept, dims, spacing)
            .crop
            .unwrap();
        let panel = crossed.region(dims, spacing).crop.unwrap();
        assert_eq!((crop.lo.z, crop.hi.z), (panel.lo.z, panel.hi.z));
        assert!(
            crossed
                .region_after(&before, &kept, dims, spacing)
                .validate()
                .is_ok()
        );
    }

    #[test]
    fn a_signed_zero_in_a_normal_moves_no_slider() {
        let azimuth = |normal: Vec3| {
            let region = ClipRegion {
                crop: None,
                planes: vec![ClipPlane {
                    point: Vec3::splat(5.0),
                    normal,
                }],
            };
            CutValues::from_region(&region, [11; 3], [1.0; 3]).azimuth
        };
        assert_eq!(
            azimuth(Vec3::new(-1.0, -0.0, 0.0)),
            azimuth(Vec3::new(-1.0, 0.0, 0.0))
        );
        assert_eq!(
            azimuth(Vec3::new(-0.0, -0.0, -1.0)),
            azimuth(Vec3::new(0.0, 0.0, -1.0))
        );
    }

    #[test]
    fn crossed_sliders_keep_one_plane() {
        let v = CutValues {
            lo: [0.75, 0.0, 0.0],
            hi: [0.25, 1.0, 1.0],
            ..CutValues::default()
        };
        let crop = v.region([101; 3], [1.0; 3]).crop.unwrap();
        assert_eq!((crop.lo.x, crop.hi.x), (25.0, 75.0));
        assert!(v.region([101; 3], [1.0; 3]).validate().is_ok());
    }

    #[test]
    fn sliders_that_meet_keep_a_slab_of_one_voxel() {
        for (at, slab) in [(0.0, (0.0, 1.0)), (0.5, (50.0, 51.0)), (1.0, (99.0, 100.0))] {
            let v = CutValues {
                lo: [at, 0.0, 0.0],
                hi: [at, 1.0, 1.0],
                ..CutValues::default()
            };
            let region = v.region([101; 3], [1.0; 3]);
            let crop = region.crop.unwrap();
            assert_eq!((crop.lo.x, crop.hi.x), slab, "sliders at {at}");
            assert!(region.validate().is_ok());
        }
    }

    #[test]
    fn the_plane_points_along_its_angles_and_round_trips() {
        let v = CutValues {
            plane: true,
            offset: 0.5,
            azimuth: 90.0,
            elevation: 0.0,
            ..CutValues::default()
        };
        let r = v.region([101; 3], [1.0; 3]);
        let p = r.planes[0];
        assert!((p.normal - Vec3::Y).length() < 1e-6, "{}", p.normal);
        let half = Vec3::splat(100.0).length() / 2.0;
        assert!(
            (p.point.y - (50.0 + 0.5 * half)).abs() < 1e-3,
            "{}",
            p.point
        );
        let back = CutValues::from_region(&r, [101; 3], [1.0; 3]);
        assert!(back.plane);
        assert!((back.azimuth - 90.0).abs() < 1e-3);
        assert!(back.elevation.abs() < 1e-3);
        assert!((back.offset - 0.5).abs() < 1e-5);
        let up = normal(10.0, 90.0);
        assert!((up - Vec3::Z).length() < 1e-6);
    }

    /// On a volume of 5 mm slices 0.5 mm apart in-plane, a plane at 45°
    /// elevation is at 45° in the body: its voxel-space normal points mostly
    /// along z (it was at 45° in voxels, 6° in the body); it round-trips, and
    /// offset 0 cuts through the volume's centre.
    #[test]
    fn the_plane_is_turned_in_world_space() {
        let (dims, spacing) = ([201, 201, 41], [0.5, 0.5, 5.0]);
        let v = CutValues {
            plane: true,
            offset: 0.0,
            azimuth: 0.0,
            elevation: 45.0,
            ..CutValues::default()
        };
        let p = v.region(dims, spacing).planes[0];
        let world = (p.normal / Vec3::from(spacing)).normalize();
        assert!(
            (world - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-5,
            "{world}"
        );
        assert!(p.normal.z > 0.99, "voxel normal {}", p.normal);
        assert!((p.point - Vec3::new(100.0, 100.0, 20.0)).length() < 1e-3);
        let back = CutValues::from_region(&v.region(dims, spacing), dims, spacing);
        assert!((back.elevation - 45.0).abs() < 1e-3 && back.azimuth.abs() < 1e-3);
        let moved = CutValues { offset: 0.5, ..v };
        let back = CutValues::from_region(&moved.region(dims, spacing), dims, spacing);
        assert!((back.offset - 0.5).abs() < 1e-5, "{}", back.offset);
        // With unit spacing, world and voxels agree.
        let unit = v.region(dims, [1.0; 3]).planes[0];
        assert!((unit.normal - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6);
    }
}
