//! Mouse navigation: orbit with the left button, pan with the middle button or
//! shift + left, zoom with the wheel, reset and axis-aligned views.

use std::f32::consts::{FRAC_PI_2, PI};

use glam::Vec3;
use raycaster::render::Orbit;

/// Radians of rotation per logical pixel of drag.
const ROTATE_PER_PIXEL: f32 = 0.01;
/// Wheel delta (Slint's logical pixels) of one notch of a mouse wheel: Slint
/// makes winit's line deltas 60 pixels a line. (Under Xvfb an `xdotool click
/// 4` arrives twice, as a button and as a scroll valuator: two notches.)
pub(crate) const WHEEL_NOTCH: f32 = 60.0;

/// Zoom factor per wheel notch.
const ZOOM_PER_NOTCH: f32 = 1.15;
/// The wheel zooms in at most this much from the framing of the volume (a
/// voxel of a 128³ volume then spans hundreds of pixels)…
const MAX_ZOOM_IN: f32 = 100.0;
/// …and out at most this much (the volume then a twentieth of the view).
const MAX_ZOOM_OUT: f32 = 20.0;
/// Elevation of the top and bottom views: just short of the pole.
const POLE: f32 = FRAC_PI_2 - 1e-3;

/// What a drag does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DragKind {
    /// Rotate about the target.
    Orbit,
    /// Move the target in the image plane.
    Pan,
}

/// An axis-aligned view direction: the camera looks from this side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisView {
    /// From +x (or −x when `negative`), etc.
    X {
        /// From the negative side.
        negative: bool,
    },
    /// From +y.
    Y {
        /// From the negative side.
        negative: bool,
    },
    /// From +z (top) or −z (bottom).
    Z {
        /// From the negative side (the bottom).
        negative: bool,
    },
}

impl AxisView {
    /// Parses the button labels `+x`, `-x`, `+y`, `-y`, `+z`, `-z`.
    pub fn parse(label: &str) -> Option<AxisView> {
        let (sign, axis) = label.split_at_checked(1)?;
        let negative = match sign {
            "+" => false,
            "-" => true,
            _ => return None,
        };
        match axis {
            "x" => Some(AxisView::X { negative }),
            "y" => Some(AxisView::Y { negative }),
            "z" => Some(AxisView::Z { negative }),
            _ => None,
        }
    }

    /// Azimuth and elevation (radians) of the camera for this view.
    fn angles(self) -> (f32, f32) {
        match self {
            AxisView::X { negative } => (if negative { PI } else { 0.0 }, 0.0),
            AxisView::Y { negative } => (if negative { -FRAC_PI_2 } else { FRAC_PI_2 }, 0.0),
            // Top and bottom views keep +y up on screen: look from -y's azimuth.
            AxisView::Z { negative } => (-FRAC_PI_2, if negative { -POLE } else { POLE }),
        }
    }
}

/// The camera the mouse drives.
#[derive(Clone, Debug)]
pub struct Navigator {
    orbit: Orbit,
    home: Orbit,
    drag: Option<(DragKind, f32, f32)>,
}

impl Navigator {
    /// Frames the box `[lo, hi]` from the default view.
    pub fn new(lo: Vec3, hi: Vec3) -> Navigator {
        Navigator::from_home(Orbit::default_view(lo, hi))
    }

    /// Starts at `home`, where reset returns.
    pub fn from_home(home: Orbit) -> Navigator {
        Navigator {
            orbit: home,
            home,
            drag: None,
        }
    }

    /// The current orbit.
    pub fn orbit(&self) -> &Orbit {
        &self.orbit
    }

    /// Moves the camera to `orbit` (a restored session); reset still returns to
    /// the framing of the volume.
    pub fn set_orbit(&mut self, orbit: Orbit) {
        self.orbit = orbit;
        self.drag = None;
    }

    /// Whether a drag is in progress.
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// Back to the default view.
    pub fn reset(&mut self) {
        self.orbit = self.home;
    }

    /// Looks along an axis, keeping the distance and target.
    pub fn axis_view(&mut self, view: AxisView) {
        let (azimuth, elevation) = view.angles();
        self.orbit.azimuth = azimuth;
        self.orbit.elevation = elevation;
    }

    /// A button went down at `(x, y)` (logical pixels).
    pub fn begin_drag(&mut self, kind: DragKind, x: f32, y: f32) {
        self.drag = Some((kind, x, y));
    }

    /// The pointer moved to `(x, y)` over a view `view_height` pixels high; returns
    /// whether the camera changed.
    pub fn drag_to(&mut self, x: f32, y: f32, view_height: f32) -> bool {
        let Some((kind, x0, y0)) = self.drag else {
            return false;
        };
        let (dx, dy) = (x - x0, y - y0);
        if dx == 0.0 && dy == 0.0 {
            return false;
        }
        self.drag = Some((kind, x, y));
        match kind {
            DragKind::Orbit => self
                .orbit
                .rotate(-dx * ROTATE_PER_PIXEL, dy * ROTATE_PER_PIXEL),
            DragKind::Pan => {
                let h = view_height.max(1.0);
                self.orbit.pan(-dx / h, dy / h);
            }
        }
        true
    }

    /// The button went up.
    pub fn end_drag(&mut self) {
        self.drag = None;
    }

    /// The wheel turned by `delta` units (positive: away from the user, zoom
    /// in); returns whether the camera changed. The distance stays within
    /// [`MAX_ZOOM_IN`] and [`MAX_ZOOM_OUT`] of the volume's framing (before,
    /// the wheel zoomed out to a dot and in to an empty view).
    pub fn wheel(&mut self, delta: f32) -> bool {
        if delta == 0.0 || !delta.is_finite() {
            return false;
        }
        let home = self.home.distance;
        let d = self.orbit.distance;
        let wanted = d * ZOOM_PER_NOTCH.powf(-delta / WHEEL_NOTCH);
        // (A restored session may lie beyond the limits: the wheel brings it
        // back, never further out.)
        let limits = ((home / MAX_ZOOM_IN).min(d), (home * MAX_ZOOM_OUT).max(d));
        let factor = wanted.clamp(limits.0, limits.1) / d;
        if factor == 1.0 || !factor.is_finite() {
            return false;
        }
        self.orbit.zoom(factor);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn navigator() -> Navigator {
        Navigator::new(Vec3::ZERO, Vec3::splat(100.0))
    }

    #[test]
    fn a_horizontal_drag_orbits_about_the_target_keeping_the_distance() {
        let mut n = navigator();
        let before = *n.orbit();
        n.begin_drag(DragKind::Orbit, 10.0, 10.0);
        assert!(n.drag_to(60.0, 10.0, 400.0));
        let after = *n.orbit();
        assert!((after.azimuth - before.azimuth).abs() > 0.4);
        assert_eq!(after.elevation, before.elevation);
        assert_eq!(after.target, before.target);
        assert!((after.distance - before.distance).abs() < 1e-3);
        n.end_drag();
        assert!(!n.drag_to(80.0, 10.0, 400.0), "no drag without a button");
    }

    #[test]
    fn panning_moves_the_target_and_reset_restores_the_view() {
        let mut n = navigator();
        let home = *n.orbit();
        n.begin_drag(DragKind::Pan, 0.0, 0.0);
        n.drag_to(100.0, 0.0, 400.0);
        assert!((n.orbit().target - home.target).length() > 1.0);
        assert_eq!(n.orbit().distance, home.distance);
        n.reset();
        assert_eq!(*n.orbit(), home);
    }

    #[test]
    fn the_wheel_zooms_in_and_out_symmetrically() {
        let mut n = navigator();
        let d = n.orbit().distance;
        assert!(n.wheel(120.0));
        assert!(n.orbit().distance < d);
        n.wheel(-120.0);
        assert!((n.orbit().distance - d).abs() < 1e-3);
        assert!(!n.wheel(f32::NAN));
    }

    #[test]
    fn the_wheel_stops_at_its_limits_and_comes_back() {
        let mut n = navigator();
        let home = n.orbit().distance;
        for _ in 0..200 {
            n.wheel(120.0);
        }
        assert!((n.orbit().distance - home / MAX_ZOOM_IN).abs() < home * 1e-5);
        assert!(!n.wheel(120.0), "no closer");
        assert!(n.wheel(-120.0), "out again");
        for _ in 0..200 {
            n.wheel(-120.0);
        }
        assert!((n.orbit().distance - home * MAX_ZOOM_OUT).abs() < home * 1e-3);
        assert!(!n.wheel(-120.0), "no farther");
        assert!(n.wheel(120.0));
        // A camera beyond the limits (a restored session) only comes back.
        let mut far = *n.orbit();
        far.distance = home * 50.0;
        n.set_orbit(far);
        assert!(!n.wheel(-120.0), "no farther out");
        assert!(n.wheel(120.0));
        assert!(n.orbit().distance < home * 50.0);
    }

    #[test]
    fn axis_views_look_along_the_axes() {
        let mut n = navigator();
        for (label, dir) in [
            ("+x", Vec3::X),
            ("-x", -Vec3::X),
            ("+y", Vec3::Y),
            ("-y", -Vec3::Y),
            ("+z", Vec3::Z),
            ("-z", -Vec3::Z),
        ] {
            n.axis_view(AxisView::parse(label).unwrap());
            let from = (n.orbit().position() - n.orbit().target).normalize();
            assert!(from.dot(dir) > 0.999, "{label}: {from}");
        }
        assert_eq!(AxisView::parse("x"), None);
        assert_eq!(AxisView::parse("+w"), None);
    }
}
