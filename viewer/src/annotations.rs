//! What the viewer draws over its pictures to say where things are: the direction
//! each edge of the 3D view and of the slice views faces (patient letters R/L,
//! A/P, S/I for files placed in the patient, volume axes otherwise), a scale bar
//! in the file's units, and the crosshair's slice planes outlined in the 3D view.
//!
//! Everything here is computed from the camera of the frame on screen, so the
//! annotations follow the picture, not a camera that has moved on since.

use glam::Vec3;
use raycaster::render::Camera;
use raycaster::slice::{Axis, PlaneLayout};
use raycaster::volume::{Orientation, Volume};

use crate::slices::AXIS_COLOURS;

/// A component of a direction smaller than this (of a unit vector) is not named:
/// an axis about 12° off a patient axis is labelled with that axis alone.
const NAMED_COMPONENT: f32 = 0.2;

/// The scale bar spans at most this fraction of the view's width.
const SCALE_BAR_MAX_FRACTION: f32 = 0.25;

/// The labels of a picture's four edges: the direction (patient or volume) that
/// points towards each.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct EdgeLabels {
    /// Towards the left edge.
    pub left: String,
    /// Towards the right edge.
    pub right: String,
    /// Towards the top edge.
    pub top: String,
    /// Towards the bottom edge.
    pub bottom: String,
}

/// The name of the direction `world` (volume space: voxel index × spacing): the
/// patient letters of its larger components, largest first (`L`, `LA`), when the
/// volume is placed in the patient; otherwise its volume axes (`+x`, `+x−y`).
pub(crate) fn direction_label(world: Vec3, orientation: Option<&Orientation>) -> String {
    let world = world.normalize_or_zero();
    let components: [f32; 3] = match orientation {
        Some(o) => o.to_patient(world).map(|c| c as f32),
        None => world.to_array(),
    };
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| components[b].abs().total_cmp(&components[a].abs()));
    let mut label = String::new();
    for axis in order {
        let c = components[axis];
        if c.abs() < NAMED_COMPONENT {
            break;
        }
        match orientation {
            Some(_) => {
                let mut v = [0.0f64; 3];
                v[axis] = f64::from(c);
                if let Some(letter) = Orientation::letter(v) {
                    label.push(letter);
                }
            }
            None => {
                label.push(if c < 0.0 { '−' } else { '+' });
                label.push_str(["x", "y", "z"][axis]);
            }
        }
    }
    label
}

/// The edge labels of a picture taken with `camera` (mirrored cameras included:
/// the right edge is where the camera's right vector points on screen).
pub(crate) fn view_labels(camera: &Camera, orientation: Option<&Orientation>) -> EdgeLabels {
    let (right, up) = (camera.right(), camera.up());
    EdgeLabels {
        left: direction_label(-right, orientation),
        right: direction_label(right, orientation),
        top: direction_label(up, orientation),
        bottom: direction_label(-up, orientation),
    }
}

/// The edge labels of a slice view laid out by `layout`
/// ([`raycaster::slice::Slice`]).
pub(crate) fn slice_labels(layout: &PlaneLayout, orientation: Option<&Orientation>) -> EdgeLabels {
    let [right, up] = layout.right_and_up().map(Vec3::from);
    EdgeLabels {
        left: direction_label(-right, orientation),
        right: direction_label(right, orientation),
        top: direction_label(up, orientation),
        bottom: direction_label(-up, orientation),
    }
}

/// The unit of a volume's world lengths: millimetres for a volume placed in the
/// patient (every medical format gives its spacing in mm), voxels when the
/// spacing is one on every axis, the spacing's own units otherwise.
pub(crate) fn length_unit(volume: &Volume) -> &'static str {
    if volume.orientation().is_some() {
        "mm"
    } else if volume.spacing() == [1.0; 3] {
        "voxels"
    } else {
        "units"
    }
}

/// A scale bar: a round length and the fraction of the view's width it spans.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ScaleBar {
    /// Its length in world units.
    pub length: f64,
    /// Its length as a fraction of the view's width.
    pub fraction: f32,
    /// The length as people read it (`50 mm`).
    pub label: String,
}

/// The longest round length (1, 2 or 5 × 10ⁿ) that spans at most a quarter of
/// a view `width_pixels` wide whose pixels measure `world_per_pixel`; `None`
/// when the scale is not a positive finite number.
pub(crate) fn scale_bar(world_per_pixel: f32, width_pixels: u32, unit: &str) -> Option<ScaleBar> {
    let view = f64::from(world_per_pixel) * f64::from(width_pixels);
    if !(view.is_finite() && view > 0.0) {
        return None;
    }
    let most = view * f64::from(SCALE_BAR_MAX_FRACTION);
    let decade = 10f64.powf(most.log10().floor());
    let length = [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&l| l <= most * (1.0 + 1e-9))
        .unwrap_or(decade);
    let digits = (-length.log10().floor()).max(0.0) as usize;
    // One voxel, not "1 voxels" (units written as symbols stay: "1 mm").
    let unit = match unit.strip_suffix('s') {
        Some(one) if length == 1.0 => one,
        _ => unit,
    };
    Some(ScaleBar {
        length,
        fraction: (length / view) as f32,
        label: format!("{length:.digits$} {unit}"),
    })
}

/// The scale bar of a picture taken with `camera`: lengths measured in the plane
/// through `at` (the orbit's target) facing the camera.
pub(crate) fn view_scale_bar(camera: &Camera, at: Vec3, unit: &str) -> Option<ScaleBar> {
    // Pixels are square: a row's footprint measures the width as well.
    scale_bar(camera.pixel_footprint(at), camera.width(), unit)
}

/// The outline of each crosshair slice plane (x, y, z) inside the box of
/// `dims` voxels with `spacing`: four world corners in order around it.
pub(crate) fn plane_outlines(dims: [u32; 3], spacing: [f32; 3], voxel: [u32; 3]) -> [[Vec3; 4]; 3] {
    let hi = Vec3::from([0, 1, 2].map(|a| dims[a].saturating_sub(1) as f32 * spacing[a]));
    Axis::ALL.map(|axis| {
        let a = axis.index();
        let [u, v] = axis.in_plane();
        let corner = |cu: f32, cv: f32| {
            let mut p = Vec3::ZERO;
            p[a] = voxel[a] as f32 * spacing[a];
            p[u] = cu;
            p[v] = cv;
            p
        };
        [
            corner(0.0, 0.0),
            corner(hi[u], 0.0),
            corner(hi[u], hi[v]),
            corner(0.0, hi[v]),
        ]
    })
}

/// Draws the crosshair's slice planes as outlines over an RGBA picture taken
/// with `camera` (its size is the picture's). Edges that leave the view, or
/// pass behind a perspective camera, are left out.
pub(crate) fn draw_plane_outlines(rgba: &mut [u8], camera: &Camera, outlines: &[[Vec3; 4]; 3]) {
    let (w, h) = (camera.width(), camera.height());
    for (outline, colour) in outlines.iter().zip(AXIS_COLOURS) {
        for i in 0..4 {
            let (a, b) = (outline[i], outline[(i + 1) % 4]);
            if let (Some(pa), Some(pb)) = (camera.project(a), camera.project(b)) {
                draw_line(rgba, w, h, pa, pb, colour);
            }
        }
    }
}

/// A one-pixel line from `a` to `b` (continuous pixel coordinates), clipped to
/// the `w × h` picture.
fn draw_line(rgba: &mut [u8], w: u32, h: u32, a: [f32; 2], b: [f32; 2], colour: [u8; 3]) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let steps = dx.abs().max(dy.abs()).ceil();
    // Far off-screen ends (a plane seen edge-on near the camera) are not walked.
    if !steps.is_finite() || steps > 4.0 * (w + h) as f32 {
        return;
    }
    let steps = steps.max(1.0) as u32;
    for s in 0..=steps {
        let t = s as f32 / steps as f32;
        let (x, y) = (a[0] + dx * t, a[1] + dy * t);
        if x < 0.0 || y < 0.0 || x >= w as f32 || y >= h as f32 {
            continue;
        }
        let i = ((y as u32 * w + x as u32) * 4) as usize;
        rgba[i..i + 3].copy_from_slice(&colour);
        rgba[i + 3] = 255;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use raycaster::render::{Orbit, patient_axes};
    use raycaster::volume::PatientSpace;

    /// A volume whose x grows towards the patient's right, y anterior and z
    /// inferior (`RAI`, a mirror image of LPS).
    fn rai() -> Orientation {
        Orientation {
            axes: [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            origin: [0.0; 3],
        }
    }

    #[test]
    fn directions_are_named_by_their_larger_components() {
        let o = rai();
        assert_eq!(direction_label(Vec3::X, Some(&o)), "R");
        assert_eq!(direction_label(-Vec3::Z, Some(&o)), "S");
        // 30° from +x (R) towards +y (A): both named, the larger first.
        let oblique = Vec3::new(30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0);
        assert_eq!(direction_label(oblique, Some(&o)), "RA");
        // 5° off: one letter.
        let near = Vec3::new(5f32.to_radians().cos(), 0.0, 5f32.to_radians().sin());
        assert_eq!(direction_label(near, Some(&o)), "R");
        assert_eq!(direction_label(-Vec3::Y, None), "−y");
        assert_eq!(direction_label(oblique, None), "+x+y");
        let (o2, _) = Orientation::from_steps(
            PatientSpace::Ras,
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0; 3],
        )
        .unwrap();
        assert_eq!(direction_label(Vec3::X, Some(&o2)), "R");
    }

    #[test]
    fn a_patient_seen_from_the_front_has_its_right_on_the_left() {
        // The orbit in patient axes from the front (azimuth −90°: from anterior),
        // for a mirrored RAI volume and for plain LPS.
        for o in [
            rai(),
            Orientation::from_steps(
                PatientSpace::Lps,
                [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                [0.0; 3],
            )
            .unwrap()
            .0,
        ] {
            let orbit = Orbit::framing(
                Vec3::ZERO,
                Vec3::splat(10.0),
                (-90f32).to_radians(),
                0.0,
                Some(40.0),
            )
            .with_axes(patient_axes(Some(&o)));
            let camera = orbit.camera(64, 48).unwrap();
            let labels = view_labels(&camera, Some(&o));
            assert_eq!(
                labels,
                EdgeLabels {
                    left: "R".into(),
                    right: "L".into(),
                    top: "S".into(),
                    bottom: "I".into()
                },
                "{o:?}"
            );
        }
    }

    #[test]
    fn slice_views_are_labelled_by_their_columns_and_rows() {
        let o = rai();
        // Axial in voxel order: columns x (R), rows y (A) growing upwards.
        let plain = PlaneLayout::voxel_order(Axis::Z);
        let axial = slice_labels(&plain, Some(&o));
        assert_eq!((axial.right.as_str(), axial.left.as_str()), ("R", "L"));
        assert_eq!((axial.top.as_str(), axial.bottom.as_str()), ("A", "P"));
        // As radiologists read it: the patient's right on the left.
        let read = PlaneLayout::patient(Axis::Z, Some(&o)).0;
        let axial = slice_labels(&read, Some(&o));
        assert_eq!((axial.left.as_str(), axial.right.as_str()), ("R", "L"));
        assert_eq!((axial.top.as_str(), axial.bottom.as_str()), ("A", "P"));
        let sagittal = slice_labels(&PlaneLayout::voxel_order(Axis::X), None);
        assert_eq!(
            (sagittal.right.as_str(), sagittal.top.as_str()),
            ("+y", "+z")
        );
    }

    #[test]
    fn scale_bars_are_round_and_fit_a_quarter_of_the_view() {
        let bar = scale_bar(0.5, 400, "mm").unwrap(); // 200 mm wide: at most 50
        assert_eq!((bar.length, bar.label.as_str()), (50.0, "50 mm"));
        assert!((bar.fraction - 0.25).abs() < 1e-6);
        let bar = scale_bar(0.01, 300, "mm").unwrap(); // 3 mm: at most 0.75
        assert_eq!(bar.label, "0.5 mm");
        let bar = scale_bar(1.0, 130, "voxels").unwrap(); // at most 32.5
        assert_eq!(bar.label, "20 voxels");
        let bar = scale_bar(0.01, 500, "voxels").unwrap(); // at most 1.25
        assert_eq!(bar.label, "1 voxel");
        assert_eq!(scale_bar(0.01, 500, "units").unwrap().label, "1 unit");
        assert_eq!(scale_bar(0.01, 500, "mm").unwrap().label, "1 mm");
        assert_eq!(scale_bar(0.004, 500, "voxels").unwrap().label, "0.5 voxels");
        assert!(scale_bar(0.0, 100, "mm").is_none());
        assert!(scale_bar(f32::NAN, 100, "mm").is_none());
    }

    #[test]
    fn the_scale_bar_measures_what_the_camera_sees() {
        // Orthographic, 100 world units tall on 200 rows, 400 columns wide: the
        // view is 200 units wide, the bar 50 units = a quarter of the width.
        let orbit = Orbit {
            vfov_deg: None,
            ortho_height: 100.0,
            ..Orbit::framing(Vec3::ZERO, Vec3::ONE, 0.0, 0.0, None)
        };
        let camera = orbit.camera(400, 200).unwrap();
        let bar = view_scale_bar(&camera, orbit.target, "mm").unwrap();
        assert_eq!(bar.length, 50.0);
        assert!((bar.fraction - 0.25).abs() < 1e-5, "{}", bar.fraction);
    }

    #[test]
    fn plane_outlines_pass_through_the_crosshair_and_are_drawn() {
        let outlines = plane_outlines([11, 21, 31], [1.0, 0.5, 2.0], [5, 10, 15]);
        for p in outlines[0] {
            assert_eq!(p.x, 5.0);
        }
        for p in outlines[2] {
            assert_eq!(p.z, 30.0);
        }
        assert_eq!(outlines[1][2], Vec3::new(10.0, 5.0, 60.0));
        let orbit = Orbit::default_view(Vec3::ZERO, Vec3::new(10.0, 10.0, 60.0));
        let camera = orbit.camera(80, 60).unwrap();
        let mut rgba = vec![0u8; 80 * 60 * 4];
        draw_plane_outlines(&mut rgba, &camera, &outlines);
        for colour in AXIS_COLOURS {
            assert!(
                rgba.chunks(4).any(|p| p[..3] == colour),
                "a {colour:?} outline is drawn"
            );
        }
        // Lines far outside the picture are skipped, not walked.
        let mut small = vec![0u8; 4 * 4 * 4];
        draw_line(&mut small, 4, 4, [-1e9, 0.0], [1e9, 1.0], [1, 2, 3]);
        assert!(small.iter().all(|&b| b == 0));
        draw_line(&mut small, 4, 4, [0.5, 0.5], [3.5, 3.5], [1, 2, 3]);
        assert_eq!(small[..3], [1, 2, 3]);
        assert_eq!(small[(3 * 4 + 3) * 4..(3 * 4 + 3) * 4 + 3], [1, 2, 3]);
    }
}
