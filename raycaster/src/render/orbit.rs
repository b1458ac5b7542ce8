//! An orbit camera controller: rotate about a target, zoom, pan (what the viewer's
//! mouse drives), and automatic framing of a box.
//!
//! The angles are measured in the orbit's axes: by default the volume's x, y, z,
//! with up +z (the slice axis of CT-like data); for a volume placed in the patient
//! ([`crate::volume::Orientation`]) the patient's L, P, S directions, so the anatomy
//! stands upright and azimuth −90° looks at the patient's face. The camera sits at
//! `target + distance·A·(cos e·cos a, cos e·sin a, sin e)` for azimuth a, elevation
//! e and axes A, looking at the target.

use std::f32::consts::FRAC_PI_2;

use glam::{Mat3, Vec3};

use super::camera::{Camera, CameraError, Projection};
use crate::volume::Orientation;

/// Highest elevation, just short of the pole so the up vector stays defined.
const MAX_ELEVATION: f32 = FRAC_PI_2 - 1e-3;

/// An orbit about a target point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The point the camera looks at and rotates about.
    pub target: Vec3,
    /// Distance from the target (world units).
    pub distance: f32,
    /// Azimuth about +z, radians (0 looks from +x).
    pub azimuth: f32,
    /// Elevation above the xy plane, radians.
    pub elevation: f32,
    /// Perspective field of view (degrees) or `None` for orthographic.
    pub vfov_deg: Option<f32>,
    /// Orthographic view height (world units), used when `vfov_deg` is `None`.
    pub ortho_height: f32,
    /// The directions (world) in which azimuth 0, azimuth 90° and up point: the
    /// columns of a rotation, or of a mirror image of one (a volume whose axes
    /// are a mirror image of the patient's), whose pictures are then mirrored
    /// so that they show the anatomy as it is. [`Mat3::IDENTITY`] by default.
    pub axes: Mat3,
}

/// The orbit axes that put a volume's patient directions L, P, S where an orbit
/// has x, y and up: the identity without an orientation.
pub fn patient_axes(orientation: Option<&Orientation>) -> Mat3 {
    match orientation {
        Some(o) => Mat3::from_cols(
            o.to_volume([1.0, 0.0, 0.0]),
            o.to_volume([0.0, 1.0, 0.0]),
            o.to_volume([0.0, 0.0, 1.0]),
        ),
        None => Mat3::IDENTITY,
    }
}

impl Orbit {
    /// An orbit that frames the box `[lo, hi]` from the given angles (radians): the
    /// box's bounding sphere fills the view with a small margin. `vfov_deg` is a
    /// perspective camera's vertical field of view in degrees; `None` makes an
    /// orthographic view.
    pub fn framing(
        lo: Vec3,
        hi: Vec3,
        azimuth: f32,
        elevation: f32,
        vfov_deg: Option<f32>,
    ) -> Orbit {
        let target = (lo + hi) / 2.0;
        let radius = ((hi - lo).length() / 2.0).max(1e-3);
        let margin = 1.08;
        let distance = match vfov_deg {
            Some(f) => radius * margin / (f.to_radians() / 2.0).sin().max(1e-3),
            None => radius * 3.0,
        };
        Orbit {
            target,
            distance,
            azimuth,
            elevation: elevation.clamp(-MAX_ELEVATION, MAX_ELEVATION),
            vfov_deg,
            ortho_height: 2.0 * radius * margin,
            axes: Mat3::IDENTITY,
        }
    }

    /// This orbit with its angles measured in `axes` (see [`patient_axes`]).
    pub fn with_axes(mut self, axes: Mat3) -> Orbit {
        self.axes = axes;
        self
    }

    /// The default view of a box: from the front-right, a little above.
    pub fn default_view(lo: Vec3, hi: Vec3) -> Orbit {
        Orbit::framing(
            lo,
            hi,
            (-60f32).to_radians(),
            25f32.to_radians(),
            Some(40.0),
        )
    }

    /// The camera position.
    pub fn position(&self) -> Vec3 {
        let (se, ce) = self.elevation.sin_cos();
        let (sa, ca) = self.azimuth.sin_cos();
        self.target + self.distance * (self.axes * Vec3::new(ce * ca, ce * sa, se))
    }

    /// The camera for an image of `width × height`.
    pub fn camera(&self, width: u32, height: u32) -> Result<Camera, CameraError> {
        let projection = match self.vfov_deg {
            Some(vfov_deg) => Projection::Perspective { vfov_deg },
            None => Projection::Orthographic {
                height: self.ortho_height,
            },
        };
        let camera = Camera::look_at(
            self.position(),
            self.target,
            self.axes.z_axis,
            projection,
            width,
            height,
        )?;
        Ok(if self.axes.determinant() < 0.0 {
            camera.mirrored()
        } else {
            camera
        })
    }

    /// Rotates by `d_azimuth` and `d_elevation` radians (elevation stops short of
    /// the poles).
    pub fn rotate(&mut self, d_azimuth: f32, d_elevation: f32) {
        self.azimuth = (self.azimuth + d_azimuth).rem_euclid(std::f32::consts::TAU);
        self.elevation = (self.elevation + d_elevation).clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// Moves toward the target by `factor` (< 1 zooms in, > 1 out); also scales the
    /// orthographic height.
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).max(1e-3);
            self.ortho_height = (self.ortho_height * factor).max(1e-3);
        }
    }

    /// Moves the target (and camera) in the image plane by fractions of the view:
    /// `dx = 1` moves one view width to the right.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let Ok(cam) = self.camera(1, 1) else { return };
        let view_height = match self.vfov_deg {
            Some(f) => 2.0 * self.distance * (f.to_radians() / 2.0).tan(),
            None => self.ortho_height,
        };
        self.target += (cam.right() * dx + cam.up() * dy) * view_height;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_keeps_every_corner_in_view() {
        let (lo, hi) = (Vec3::ZERO, Vec3::new(255.0, 127.0, 63.0));
        for vfov in [Some(30.0), Some(60.0), None] {
            let orbit = Orbit::framing(lo, hi, 0.7, 0.4, vfov);
            let cam = orbit.camera(100, 80).unwrap();
            for p in crate::render::ray::box_corners(lo, hi) {
                let q = cam.project(p).unwrap();
                assert!(
                    q[0] >= 0.0 && q[0] <= 100.0 && q[1] >= 0.0 && q[1] <= 80.0,
                    "{q:?}"
                );
            }
        }
    }

    #[test]
    fn rotation_keeps_distance_and_clamps_elevation() {
        let mut o = Orbit::default_view(Vec3::ZERO, Vec3::ONE);
        let d = (o.position() - o.target).length();
        o.rotate(1.0, 10.0);
        assert!((o.position() - o.target).length() - d < 1e-4);
        assert!(o.elevation < FRAC_PI_2);
        assert!(o.camera(8, 8).is_ok(), "camera at the pole must stay valid");
    }

    #[test]
    fn zoom_and_pan_move_as_asked() {
        let mut o = Orbit::default_view(Vec3::ZERO, Vec3::ONE);
        let d = o.distance;
        o.zoom(0.5);
        assert!((o.distance - d / 2.0).abs() < 1e-6);
        o.zoom(f32::NAN);
        assert!((o.distance - d / 2.0).abs() < 1e-6);
        let before = o.target;
        let right = o.camera(1, 1).unwrap().right();
        o.pan(0.25, 0.0);
        assert!((o.target - before).normalize().dot(right) > 0.999);
    }
}
