//! How a slice's voxels lie in its image: which in-plane axis runs along the
//! columns, which along the rows, and which way each grows.
//!
//! By default a volume placed in the patient ([`Orientation`]) is shown as
//! radiologists read it: axial slices seen from the feet (the patient's right
//! on the image's left, anterior at the top), coronal slices from the front
//! (right on the left, superior at the top), sagittal slices from the
//! patient's left (anterior on the left, superior at the top). Other volumes,
//! and oriented ones asked to, keep voxel order ([`PlaneLayout::voxel_order`]).

use super::Axis;
use crate::volume::Orientation;

/// Where the two in-plane volume axes of a slice run in its image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneLayout {
    /// The volume axis (0 x, 1 y, 2 z) along the image's columns.
    pub columns: usize,
    /// Whether that axis's coordinate grows to the right (else to the left).
    pub grows_right: bool,
    /// The volume axis along the image's rows.
    pub rows: usize,
    /// Whether that axis's coordinate grows upwards (else downwards).
    pub grows_up: bool,
}

/// The anatomical plane of a slice of a volume placed in the patient.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnatomicalPlane {
    /// Perpendicular to the patient's feet–head axis.
    Axial,
    /// Perpendicular to the back–front axis.
    Coronal,
    /// Perpendicular to the right–left axis.
    Sagittal,
}

impl AnatomicalPlane {
    /// The plane's name (`axial`, `coronal`, `sagittal`).
    pub fn name(self) -> &'static str {
        match self {
            AnatomicalPlane::Axial => "axial",
            AnatomicalPlane::Coronal => "coronal",
            AnatomicalPlane::Sagittal => "sagittal",
        }
    }

    /// The patient axes (LPS: 0 L, 1 P, 2 S) along the image's columns and
    /// rows, and whether each grows to the right and upwards, as the plane
    /// is read.
    fn reading(self) -> [(usize, bool); 2] {
        match self {
            // From the feet: L to the right, P downwards.
            AnatomicalPlane::Axial => [(0, true), (1, false)],
            // From the front: L to the right, S upwards.
            AnatomicalPlane::Coronal => [(0, true), (2, true)],
            // From the patient's left: P to the right, S upwards.
            AnatomicalPlane::Sagittal => [(1, true), (2, true)],
        }
    }
}

impl PlaneLayout {
    /// Voxel order: columns along the first in-plane axis ([`Axis::in_plane`])
    /// growing to the right, rows along the second growing upwards (so +z,
    /// world up, points up in x and y slices).
    pub fn voxel_order(axis: Axis) -> PlaneLayout {
        let [u, v] = axis.in_plane();
        PlaneLayout {
            columns: u,
            grows_right: true,
            rows: v,
            grows_up: true,
        }
    }

    /// The layout radiologists read a slice perpendicular to `axis` of a
    /// volume placed in the patient by `orientation` in (see the module's
    /// description), and the slice's anatomical plane; voxel order and `None`
    /// without an orientation, or where the volume's axes are so oblique that
    /// two of them lie nearest the same patient axis.
    pub fn patient(
        axis: Axis,
        orientation: Option<&Orientation>,
    ) -> (PlaneLayout, Option<AnatomicalPlane>) {
        let plain = (PlaneLayout::voxel_order(axis), None);
        let Some(orientation) = orientation else {
            return plain;
        };
        // Each voxel axis's nearest patient axis, and whether it grows along it.
        let [Some(x), Some(y), Some(z)] = orientation.axes.map(Orientation::nearest_axis) else {
            return plain;
        };
        let nearest = [x, y, z];
        let plane = match nearest[axis.index()].0 {
            0 => AnatomicalPlane::Sagittal,
            1 => AnatomicalPlane::Coronal,
            _ => AnatomicalPlane::Axial,
        };
        let [(across, right), (down_up, up)] = plane.reading();
        let [u, v] = axis.in_plane();
        let along = |patient: usize| [u, v].into_iter().find(|&a| nearest[a].0 == patient);
        let (Some(columns), Some(rows)) = (along(across), along(down_up)) else {
            return plain;
        };
        let layout = PlaneLayout {
            columns,
            grows_right: nearest[columns].1 == right,
            rows,
            grows_up: nearest[rows].1 == up,
        };
        (layout, Some(plane))
    }

    /// The image column of coordinate `c` along the column axis, in an image
    /// `width` columns wide; also the coordinate of image column `c` (the map
    /// is its own inverse).
    pub fn column(&self, c: u32, width: u32) -> u32 {
        if self.grows_right {
            c
        } else {
            width.saturating_sub(1).saturating_sub(c)
        }
    }

    /// The image row (from the top) of coordinate `c` along the row axis, in
    /// an image `height` rows high; also the coordinate of image row `c`.
    pub fn row(&self, c: u32, height: u32) -> u32 {
        if self.grows_up {
            height.saturating_sub(1).saturating_sub(c)
        } else {
            c
        }
    }

    /// The volume direction (a unit vector along a volume axis) that points
    /// to the image's right and the one that points up.
    pub fn right_and_up(&self) -> [[f32; 3]; 2] {
        let unit = |axis: usize, positive: bool| {
            let mut d = [0.0; 3];
            d[axis] = if positive { 1.0 } else { -1.0 };
            d
        };
        [
            unit(self.columns, self.grows_right),
            unit(self.rows, self.grows_up),
        ]
    }

    /// Whether the slice perpendicular to `axis`, laid out so, comes toward
    /// the viewer as its index grows (else it goes away, into the screen).
    /// Toward the viewer is the image's right crossed with its up, in the
    /// patient for a volume placed by `orientation` (axial slices are seen
    /// from the feet, so toward the viewer is inferior), in volume space
    /// otherwise.
    pub fn index_grows_toward_viewer(&self, axis: Axis, orientation: Option<&Orientation>) -> bool {
        let physical = |d: [f32; 3]| match orientation {
            Some(o) => glam::DVec3::from(o.to_patient(glam::Vec3::from(d))),
            None => glam::Vec3::from(d).as_dvec3(),
        };
        let [right, up] = self.right_and_up().map(physical);
        let mut along = [0.0; 3];
        along[axis.index()] = 1.0;
        right.cross(up).dot(physical(along)) > 0.0
    }

    /// The letters (`L`, `R`, `P`, `A`, `S`, `I`) of the patient directions
    /// nearest the image's left and its top, for a volume placed by
    /// `orientation`.
    pub fn left_and_top(&self, orientation: &Orientation) -> [char; 2] {
        let [right, up] = self.right_and_up().map(glam::Vec3::from);
        [-right, up].map(|d| Orientation::letter(orientation.to_patient(d)).unwrap_or('?'))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::PatientSpace;

    fn oriented(space: PatientSpace, steps: [[f64; 3]; 3]) -> Orientation {
        Orientation::from_steps(space, steps, [0.0; 3]).unwrap().0
    }

    /// Walking one image column to the right and one row down moves in the
    /// patient as the plane is read: for axial slices to the patient's left
    /// and posterior, coronal left and inferior, sagittal posterior and
    /// inferior; whatever way the volume's axes run.
    #[test]
    fn patient_slices_read_as_radiologists_read_them() {
        let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let volumes = [
            ("LPS", oriented(PatientSpace::Lps, identity)),
            ("RAS", oriented(PatientSpace::Ras, identity)),
            // Axes permuted and flipped: x anterior, y inferior, z left (LPS).
            (
                "AIL",
                oriented(
                    PatientSpace::Lps,
                    [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]],
                ),
            ),
            // Slightly oblique: 10° about z.
            (
                "oblique",
                oriented(
                    PatientSpace::Lps,
                    [[0.985, 0.174, 0.0], [-0.174, 0.985, 0.0], [0.0, 0.0, 1.0]],
                ),
            ),
        ];
        for (name, o) in &volumes {
            let mut planes = Vec::new();
            for axis in Axis::ALL {
                let (layout, plane) = PlaneLayout::patient(axis, Some(o));
                let plane = plane.unwrap_or_else(|| panic!("{name} {axis}: no plane"));
                planes.push(plane);
                // The patient direction (LPS) of one column right and one row down.
                let [right, up] = layout.right_and_up();
                let patient = |d: [f32; 3]| o.to_patient(glam::Vec3::from(d));
                let (r, down) = (patient(right), patient(up).map(|c| -c));
                let expected: ([f64; 3], [f64; 3]) = match plane {
                    AnatomicalPlane::Axial => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
                    AnatomicalPlane::Coronal => ([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
                    AnatomicalPlane::Sagittal => ([0.0, 1.0, 0.0], [0.0, 0.0, -1.0]),
                };
                let dot =
                    |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
                assert!(
                    dot(r, expected.0) > 0.9,
                    "{name} {axis} {plane:?}: right is {r:?}"
                );
                assert!(
                    dot(down, expected.1) > 0.9,
                    "{name} {axis} {plane:?}: down is {down:?}"
                );
                assert_ne!(layout.columns, layout.rows);
                assert!(layout.columns != axis.index() && layout.rows != axis.index());
            }
            let axial = Axis::ALL
                .into_iter()
                .map(|a| PlaneLayout::patient(a, Some(o)))
                .find(|(_, p)| *p == Some(AnatomicalPlane::Axial))
                .unwrap()
                .0;
            assert_eq!(axial.left_and_top(o), ['R', 'A'], "{name}");
            // Toward the viewer: inferior in axial slices (seen from the
            // feet), anterior in coronal ones, left in sagittal ones; LPS.
            for axis in Axis::ALL {
                let (layout, plane) = PlaneLayout::patient(axis, Some(o));
                let toward: [f64; 3] = match plane.unwrap() {
                    AnatomicalPlane::Axial => [0.0, 0.0, -1.0],
                    AnatomicalPlane::Coronal => [0.0, -1.0, 0.0],
                    AnatomicalPlane::Sagittal => [1.0, 0.0, 0.0],
                };
                let mut along = [0.0f32; 3];
                along[axis.index()] = 1.0;
                let grows = o.to_patient(glam::Vec3::from(along));
                let dot: f64 = grows.iter().zip(toward).map(|(a, b)| a * b).sum();
                assert_eq!(
                    layout.index_grows_toward_viewer(axis, Some(o)),
                    dot > 0.0,
                    "{name} {axis}"
                );
                // Voxel order turns the same way in the patient.
                let plain = PlaneLayout::voxel_order(axis);
                let [r, u] = plain
                    .right_and_up()
                    .map(|d| o.to_patient(glam::Vec3::from(d)));
                let out = glam::DVec3::from(r).cross(glam::DVec3::from(u));
                assert_eq!(
                    plain.index_grows_toward_viewer(axis, Some(o)),
                    out.dot(glam::DVec3::from(grows)) > 0.0,
                    "{name} {axis} voxel order"
                );
            }
            planes.sort_by_key(|p| p.name());
            assert_eq!(
                planes,
                [
                    AnatomicalPlane::Axial,
                    AnatomicalPlane::Coronal,
                    AnatomicalPlane::Sagittal
                ],
                "{name}"
            );
        }
    }

    #[test]
    fn without_an_orientation_slices_keep_voxel_order() {
        for axis in Axis::ALL {
            let (layout, plane) = PlaneLayout::patient(axis, None);
            assert_eq!((layout, plane), (PlaneLayout::voxel_order(axis), None));
            // x slices show y to the right and z up (+x comes out of the
            // screen), y slices x and z (+y goes in), z slices x and y.
            assert_eq!(
                layout.index_grows_toward_viewer(axis, None),
                axis != Axis::Y,
                "{axis}"
            );
            assert_eq!([layout.columns, layout.rows], axis.in_plane());
            // Columns as they come, rows from the top down.
            assert_eq!(layout.column(2, 10), 2);
            assert_eq!(layout.row(2, 10), 7);
        }
        let flipped = PlaneLayout {
            columns: 0,
            grows_right: false,
            rows: 1,
            grows_up: false,
        };
        assert_eq!(flipped.column(2, 10), 7);
        assert_eq!(flipped.row(2, 10), 2);
        for c in 0..10 {
            assert_eq!(flipped.column(flipped.column(c, 10), 10), c);
        }
    }
}
