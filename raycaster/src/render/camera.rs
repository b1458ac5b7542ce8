//! Cameras: the thesis's (OSPRay's) perspective camera and an orthographic one.
//!
//! A camera has a position P, a unit view direction D and an up vector U. With
//! `r = D × U` and `u = r × D` (both normalised), the image plane at distance 1 has
//! height `Sy = 2·tan(F/2)` for the vertical field of view F (perspective) or the
//! given height (orthographic), and width `Sx = Sy·aspect`. Pixel `(x, y)` (y down)
//! looks through `D + sx·r + sy·u` with `sx, sy` its centre on that plane.

use glam::{Vec3, Vec4};

use super::ray::{Ray, box_corners};

/// How the camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from the camera position; vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees, in (0, 180).
        vfov_deg: f32,
    },
    /// Parallel rays along the view direction; the image's height in world units.
    Orthographic {
        /// Height of the view in world units.
        height: f32,
    },
}

/// A camera for an image of `width × height` pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    position: Vec3,
    direction: Vec3,
    right: Vec3,
    up: Vec3,
    projection: Projection,
    width: u32,
    height: u32,
    /// Half the image plane's size: (Sx/2, Sy/2).
    half_plane: [f32; 2],
}

/// A box's eight corners ([`box_corners`]' order) less a point, per axis in two
/// sets of four lanes.
struct CornerLanes {
    axes: [[Vec4; 2]; 3],
}

impl CornerLanes {
    /// The corners of `[lo, hi]` less `eye`.
    #[inline]
    fn new(lo: Vec3, hi: Vec3, eye: Vec3) -> Self {
        let (lo, hi) = (lo - eye, hi - eye);
        CornerLanes {
            axes: [
                [Vec4::new(lo.x, hi.x, lo.x, hi.x); 2],
                [Vec4::new(lo.y, lo.y, hi.y, hi.y); 2],
                [Vec4::splat(lo.z), Vec4::splat(hi.z)],
            ],
        }
    }

    /// Each corner's `dot(v)`, as `Vec3::dot`: `(x·vx + y·vy) + z·vz`.
    #[inline]
    fn dot(&self, v: Vec3) -> [Vec4; 2] {
        let [x, y, z] = &self.axes;
        [0, 1].map(|h| x[h] * v.x + y[h] * v.y + z[h] * v.z)
    }
}

/// A half-open rectangle of pixels `x0..x1 × y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRect {
    /// Rows `y0..y1` of an image `width` pixels wide.
    pub(crate) fn rows(width: u32, y0: u32, y1: u32) -> PixelRect {
        PixelRect {
            x0: 0,
            y0,
            x1: width,
            y1,
        }
    }

    /// Number of pixels inside.
    pub fn area(&self) -> u64 {
        u64::from(self.x1 - self.x0) * u64::from(self.y1 - self.y0)
    }

    /// The overlap of two rectangles, if any.
    pub fn intersect(&self, other: &PixelRect) -> Option<PixelRect> {
        let r = PixelRect {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }
}

/// What makes a look-at view impossible, for callers that name their own
/// fields or flags in the message ([`look_at_problem`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LookAtProblem {
    /// The position is the target: the camera looks nowhere.
    SamePoint,
    /// The up vector is zero or not finite.
    UpNotADirection,
    /// The up vector lies along the view direction.
    UpAlongView,
}

/// `v` scaled to length 1, for any finite non-zero `v`: normalised, or where
/// its squared length overflows or vanishes in 32-bit floats (a long or tiny
/// vector), scaled by its largest coordinate first. (Only then: the bits of
/// every other camera, and so every image, stay as they were.)
fn unit_vector(v: Vec3) -> Option<Vec3> {
    if !v.is_finite() {
        return None;
    }
    v.try_normalize().or_else(|| {
        let largest = v.abs().max_element();
        (largest > 0.0)
            .then(|| (v / largest).try_normalize())
            .flatten()
    })
}

/// Why a camera at `position` looking at `target` with `up` has no view
/// ([`Camera::look_at`] refuses it as [`CameraError::DegenerateBasis`]), or
/// `None`. (A view too long to compute is the caller's to check first.)
pub fn look_at_problem(position: Vec3, target: Vec3, up: Vec3) -> Option<LookAtProblem> {
    let Some(view) = unit_vector(target - position) else {
        return Some(LookAtProblem::SamePoint);
    };
    let Some(up) = unit_vector(up) else {
        return Some(LookAtProblem::UpNotADirection);
    };
    (view.cross(up).length() < 1e-6).then_some(LookAtProblem::UpAlongView)
}

/// Why a camera cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// The image has no pixels.
    #[error("image size {0}×{1} has no pixels")]
    EmptyImage(u32, u32),
    /// Direction or up is zero, not finite, or they are parallel.
    #[error("view direction and up vector must be finite, non-zero and not parallel")]
    DegenerateBasis,
    /// The image is wider or taller than [`MAX_IMAGE_SIDE`].
    #[error("image size {0}×{1} is too large: at most {MAX_IMAGE_SIDE} pixels a side")]
    ImageTooLarge(u32, u32),
    /// The position is not finite, or so far out that its distances overflow.
    #[error(
        "camera position must be finite, each coordinate within ±{MAX_CAMERA_DISTANCE:e} (beyond, distances overflow 32-bit floats)"
    )]
    BadPosition,
    /// The field of view or orthographic height is out of range.
    #[error("field of view must be in (0°, 180°) and orthographic height positive")]
    BadProjection,
}

/// The widest and tallest image a camera makes (the command line's and the
/// sessions' limit too): a 16384² frame takes about 19 GB while it renders.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// The farthest a camera may stand from the origin along each axis: the
/// squares of distances beyond overflow 32-bit floats.
pub const MAX_CAMERA_DISTANCE: f32 = 1e18;

impl Camera {
    /// A camera at `position` looking along `direction` with `up` roughly upward.
    pub fn new(
        position: Vec3,
        direction: Vec3,
        up: Vec3,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera, CameraError> {
        if width == 0 || height == 0 {
            return Err(CameraError::EmptyImage(width, height));
        }
        if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(CameraError::ImageTooLarge(width, height));
        }
        if !(position.is_finite() && position.abs().max_element() <= MAX_CAMERA_DISTANCE) {
            return Err(CameraError::BadPosition);
        }
        let direction = unit_vector(direction).ok_or(CameraError::DegenerateBasis)?;
        let right = unit_vector(up)
            .and_then(|up| direction.cross(up).try_normalize())
            .ok_or(CameraError::DegenerateBasis)?;
        let up = right.cross(direction);
        let plane_height = match projection {
            Projection::Perspective { vfov_deg } if vfov_deg > 0.0 && vfov_deg < 180.0 => {
                2.0 * (vfov_deg.to_radians() / 2.0).tan()
            }
            Projection::Orthographic { height } if height > 0.0 && height.is_finite() => height,
            _ => return Err(CameraError::BadProjection),
        };
        let aspect = width as f32 / height as f32;
        Ok(Camera {
            position,
            direction,
            right,
            up,
            projection,
            width,
            height,
            half_plane: [plane_height * aspect / 2.0, plane_height / 2.0],
        })
    }

    /// A camera at `position` looking at `target`.
    pub fn look_at(
        position: Vec3,
        target: Vec3,
        up: Vec3,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera, CameraError> {
        // (`new` checks the position before it normalises the direction.)
        Camera::new(position, target - position, up, projection, width, height)
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The camera position.
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The unit view direction.
    pub fn direction(&self) -> Vec3 {
        self.direction
    }

    /// The unit up vector of the image plane (orthogonal to the direction).
    pub fn up(&self) -> Vec3 {
        self.up
    }

    /// The unit right vector of the image plane.
    pub fn right(&self) -> Vec3 {
        self.right
    }

    /// The projection.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// The same camera for another image size (aspect follows the new size).
    pub fn with_size(&self, width: u32, height: u32) -> Result<Camera, CameraError> {
        let camera = Camera::new(
            self.position,
            self.direction,
            self.up,
            self.projection,
            width,
            height,
        )?;
        // A mirrored camera stays mirrored.
        Ok(if camera.right.dot(self.right) < 0.0 {
            camera.mirrored()
        } else {
            camera
        })
    }

    /// This camera seeing the mirror image: its right vector reversed, so the
    /// picture is flipped left to right (how a volume whose axes are a mirror
    /// image of the patient's is shown as the anatomy is).
    pub fn mirrored(mut self) -> Camera {
        self.right = -self.right;
        self
    }

    /// The ray through the centre of pixel `(x, y)` (y counts rows from the top),
    /// with a unit direction so that `t` measures world distance.
    #[inline]
    pub fn ray(&self, x: u32, y: u32) -> Ray {
        let sx = ((x as f32 + 0.5) / self.width as f32 * 2.0 - 1.0) * self.half_plane[0];
        let sy = (1.0 - (y as f32 + 0.5) / self.height as f32 * 2.0) * self.half_plane[1];
        let offset = self.right * sx + self.up * sy;
        match self.projection {
            Projection::Perspective { .. } => Ray {
                origin: self.position,
                direction: (self.direction + offset).normalize(),
            },
            Projection::Orthographic { .. } => Ray {
                origin: self.position + offset,
                direction: self.direction,
            },
        }
    }

    /// Continuous pixel coordinates of world point `p`, or `None` when it lies on
    /// or behind the camera plane of a perspective camera.
    pub fn project(&self, p: Vec3) -> Option<[f32; 2]> {
        let v = p - self.position;
        match self.projection {
            Projection::Perspective { .. } => self.project_at_depth(v, v.dot(self.direction)),
            Projection::Orthographic { .. } => {
                Some(self.pixel_of(v.dot(self.right), v.dot(self.up)))
            }
        }
    }

    /// [`Self::project`] of the point `v` from the eye of a perspective camera,
    /// `depth` its `v.dot(direction)`.
    #[inline]
    fn project_at_depth(&self, v: Vec3, depth: f32) -> Option<[f32; 2]> {
        if depth <= 1e-6 {
            return None;
        }
        Some(self.pixel_of(v.dot(self.right) / depth, v.dot(self.up) / depth))
    }

    /// A point's image-plane coordinates (`v.dot(right)`, `v.dot(up)`, over
    /// its depth for a perspective camera) in pixels.
    #[inline]
    fn pixel_of(&self, sx: f32, sy: f32) -> [f32; 2] {
        [
            (sx / self.half_plane[0] + 1.0) / 2.0 * self.width as f32,
            (1.0 - sy / self.half_plane[1]) / 2.0 * self.height as f32,
        ]
    }

    /// The pixels whose centre rays can hit the box `[lo, hi]`: the bounding
    /// rectangle of its projected corners, widened by a pixel, clipped to the image.
    /// `None` when the box projects entirely outside the image.
    ///
    /// For a perspective camera, a box wholly behind the camera plane is `None`;
    /// a box reaching across it is cut at a depth `δ` no ray can hit the box in
    /// front of (half the box's distance from the camera times the cosine of the
    /// widest ray's angle to the view), and the cut part projected: its corners
    /// in front and the points where its edges cross depth `δ`. A box holding the
    /// camera (or within a hair of it) covers the whole image.
    pub fn project_box(&self, lo: Vec3, hi: Vec3) -> Option<PixelRect> {
        let image = PixelRect {
            x0: 0,
            y0: 0,
            x1: self.width,
            y1: self.height,
        };
        let corners = box_corners(lo, hi);
        let mut min = [f32::INFINITY; 2];
        let mut max = [f32::NEG_INFINITY; 2];
        // Plain comparisons: `f32::min` and `max` as they treat a NaN `q` (the
        // bound kept), which the bounds never are; without their NaN
        // handling, a fifth of this function's time.
        let mut add = |q: [f32; 2]| {
            for a in 0..2 {
                min[a] = if q[a] < min[a] { q[a] } else { min[a] };
                max[a] = if q[a] > max[a] { q[a] } else { max[a] };
            }
        };
        match self.projection {
            Projection::Orthographic { .. } => {
                for p in corners {
                    add(self
                        .project(p)
                        .expect("orthographic projections always exist"));
                }
            }
            Projection::Perspective { .. } => {
                // Each corner's depth once (the bits `project` computes), four
                // corners in lanes at a time.
                let lanes = CornerLanes::new(lo, hi, self.position);
                let depth_lanes = lanes.dot(self.direction);
                let depths: [f32; 8] =
                    std::array::from_fn(|i| depth_lanes[i / 4].to_array()[i % 4]);
                // Rounding of sample positions, with a wide margin.
                let hair = 1e-4 * (hi - lo).max_element().max(1e-3);
                if depths.iter().all(|&d| d < -hair) {
                    return None;
                }
                let reach = (self.position - self.position.clamp(lo, hi)).length();
                if reach <= hair {
                    return Some(image);
                }
                let widest = (1.0 + self.half_plane[0].powi(2) + self.half_plane[1].powi(2))
                    .sqrt()
                    .recip();
                let cut = (reach * widest * 0.5).max(2e-6);
                // No edge crosses depth `cut` when every corner lies beyond it
                // (the usual case: the box well in front of the camera).
                let crossing = depths.iter().any(|&d| d < cut);
                if !crossing {
                    // Every corner in front of the cut: each projected in
                    // lanes, with `project_at_depth`'s operations.
                    let (sx, sy) = (lanes.dot(self.right), lanes.dot(self.up));
                    let (w, h) = (self.width as f32, self.height as f32);
                    for half in 0..2 {
                        let (x, y) = (sx[half] / depth_lanes[half], sy[half] / depth_lanes[half]);
                        let px = (x / self.half_plane[0] + 1.0) / 2.0 * w;
                        let py = (1.0 - y / self.half_plane[1]) / 2.0 * h;
                        add([px.min_element(), py.min_element()]);
                        add([px.max_element(), py.max_element()]);
                    }
                } else {
                    for (i, &p) in corners.iter().enumerate() {
                        let dp = depths[i];
                        if dp >= cut {
                            add(self.project_at_depth(p - self.position, dp)?);
                        }
                        // Edges to the corners differing in one coordinate.
                        for bit in [1, 2, 4] {
                            let j = i | bit;
                            if j == i {
                                continue;
                            }
                            let (q, dq) = (corners[j], depths[j]);
                            if (dp < cut) != (dq < cut) {
                                let at = p + (q - p) * ((cut - dp) / (dq - dp));
                                match self.project(at) {
                                    Some(point) => add(point),
                                    None => return Some(image),
                                }
                            }
                        }
                    }
                }
                if min[0] > max[0] {
                    return None;
                }
            }
        }
        let to_pixel = |v: f32, limit: u32| v.clamp(0.0, limit as f32) as u32;
        // The bounds (never NaN) brought within 4 pixels of the image first,
        // which changes no pixel, so that floor and ceil are exact through
        // `i32` (a libm call each otherwise, on baseline x86-64).
        let near = |v: f32, limit: u32| v.clamp(-4.0, limit as f32 + 4.0);
        let floor = |v: f32| {
            let t = v as i32 as f32;
            if t > v { t - 1.0 } else { t }
        };
        let ceil = |v: f32| {
            let t = v as i32 as f32;
            if t < v { t + 1.0 } else { t }
        };
        let rect = PixelRect {
            x0: to_pixel(floor(near(min[0], self.width)) - 1.0, self.width),
            y0: to_pixel(floor(near(min[1], self.height)) - 1.0, self.height),
            x1: to_pixel(ceil(near(max[0], self.width)) + 1.0, self.width),
            y1: to_pixel(ceil(near(max[1], self.height)) + 1.0, self.height),
        };
        rect.intersect(&image)
    }

    /// The world size of one pixel's footprint at point `p`: its depth along the
    /// view times the pixel's angular size (perspective; 0 at or behind the camera
    /// plane), or the view height over the image height (orthographic).
    pub fn pixel_footprint(&self, p: Vec3) -> f32 {
        let pixel = 2.0 * self.half_plane[1] / self.height as f32;
        match self.projection {
            Projection::Perspective { .. } => {
                (p - self.position).dot(self.direction).max(0.0) * pixel
            }
            Projection::Orthographic { .. } => pixel,
        }
    }

    /// A key that orders points front to back: distance from a perspective camera,
    /// depth along the view direction for an orthographic one.
    pub fn depth_key(&self, p: Vec3) -> f32 {
        match self.projection {
            Projection::Perspective { .. } => (p - self.position).length(),
            Projection::Orthographic { .. } => (p - self.position).dot(self.direction),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn perspective() -> Camera {
        Camera::look_at(
            Vec3::new(0.0, -10.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            Projection::Perspective { vfov_deg: 60.0 },
            64,
            48,
        )
        .unwrap()
    }

    #[test]
    fn centre_ray_looks_at_the_target_and_corners_span_the_fov() {
        let cam = Camera::look_at(
            Vec3::new(0.0, -10.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            Projection::Perspective { vfov_deg: 90.0 },
            2,
            2,
        )
        .unwrap();
        // Pixel centres of a 2×2 image sit at ±1/2 of the half plane (tan 45° = 1).
        let top_left = cam.ray(0, 0).direction;
        let expected = Vec3::new(-0.5, 1.0, 0.5).normalize();
        assert!((top_left - expected).length() < 1e-6, "{top_left}");
    }

    #[test]
    fn a_box_in_front_projects_to_its_corners_bounding_pixels() {
        // The rectangle as `f32::min`, `max`, `floor` and `ceil` make it from
        // the projected corners, against `project_box`'s own arithmetic;
        // boxes inside, across and beyond the image's edges.
        let cam = perspective();
        let mut random = crate::render::test_rng::xorshift32(0x9e37_79b9);
        let mut unit = move || random() as f32 / u32::MAX as f32;
        for _ in 0..2000 {
            let centre = Vec3::new(unit() * 24.0 - 12.0, unit() * 8.0, unit() * 18.0 - 9.0);
            let half = Vec3::new(unit(), unit(), unit()) * 3.0 + 0.01;
            let (lo, hi) = (centre - half, centre + half);
            let mut min = [f32::INFINITY; 2];
            let mut max = [f32::NEG_INFINITY; 2];
            for p in box_corners(lo, hi) {
                let q = cam.project(p).unwrap();
                for a in 0..2 {
                    min[a] = min[a].min(q[a]);
                    max[a] = max[a].max(q[a]);
                }
            }
            let to_pixel = |v: f32, limit: u32| v.clamp(0.0, limit as f32) as u32;
            let expected = PixelRect {
                x0: to_pixel(min[0].floor() - 1.0, 64),
                y0: to_pixel(min[1].floor() - 1.0, 48),
                x1: to_pixel(max[0].ceil() + 1.0, 64),
                y1: to_pixel(max[1].ceil() + 1.0, 48),
            }
            .intersect(&PixelRect {
                x0: 0,
                y0: 0,
                x1: 64,
                y1: 48,
            });
            assert_eq!(cam.project_box(lo, hi), expected, "box {lo} .. {hi}");
        }
    }

    #[test]
    fn projection_inverts_the_pixel_ray() {
        let cam = perspective();
        for (x, y) in [(0, 0), (63, 47), (10, 30)] {
            let ray = cam.ray(x, y);
            let q = cam.project(ray.at(7.0)).unwrap();
            assert!((q[0] - (x as f32 + 0.5)).abs() < 1e-3, "{q:?}");
            assert!((q[1] - (y as f32 + 0.5)).abs() < 1e-3, "{q:?}");
        }
    }

    #[test]
    fn orthographic_rays_are_parallel_and_project_back() {
        let cam = Camera::look_at(
            Vec3::new(0.0, -10.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            Projection::Orthographic { height: 4.0 },
            40,
            40,
        )
        .unwrap();
        let a = cam.ray(0, 0);
        let b = cam.ray(39, 39);
        assert_eq!(a.direction, b.direction);
        let q = cam.project(b.at(3.0)).unwrap();
        assert!((q[0] - 39.5).abs() < 1e-3 && (q[1] - 39.5).abs() < 1e-3);
    }

    #[test]
    fn box_rect_contains_every_hitting_pixel() {
        let cam = perspective();
        let (lo, hi) = (Vec3::new(-1.0, -1.0, -0.5), Vec3::new(2.0, 1.0, 1.5));
        let rect = cam.project_box(lo, hi).unwrap();
        for y in 0..cam.height() {
            for x in 0..cam.width() {
                let hits = cam.ray(x, y).intersect_box(lo, hi).is_some();
                let inside = x >= rect.x0 && x < rect.x1 && y >= rect.y0 && y < rect.y1;
                assert!(
                    !hits || inside,
                    "pixel {x},{y} hits but lies outside {rect:?}"
                );
            }
        }
        assert!(rect.area() < 64 * 48 / 2, "rect too loose: {rect:?}");
    }

    #[test]
    fn box_behind_the_camera_across_its_plane_or_around_it() {
        let cam = perspective();
        // Wholly behind: no pixel.
        let behind = cam.project_box(Vec3::new(-1.0, -20.0, -1.0), Vec3::new(1.0, -19.0, 1.0));
        assert_eq!(behind, None);
        let around = cam
            .project_box(Vec3::splat(-20.0), Vec3::splat(20.0))
            .unwrap();
        assert_eq!(around.area(), 64 * 48);
        // Boxes across the camera plane, beside the camera, around it and in
        // front: every pixel whose ray hits one lies in its rectangle, and boxes
        // off to the side of the camera cover little of the image or none.
        let eye = cam.position();
        let (forward, right, up) = (cam.direction(), cam.right(), cam.up());
        let mut small = 0;
        for i in 0..200 {
            let f = |k: u32| ((i * k + 7) % 97) as f32 / 97.0;
            let centre = eye
                + forward * (f(13) * 6.0 - 2.0)
                + right * (f(29) * 12.0 - 6.0)
                + up * (f(31) * 12.0 - 6.0);
            let half = Vec3::new(0.2 + f(37), 0.2 + f(41), 0.2 + f(43));
            let (lo, hi) = (centre - half, centre + half);
            let rect = cam.project_box(lo, hi);
            let mut hit = 0;
            for y in 0..cam.height() {
                for x in 0..cam.width() {
                    if cam.ray(x, y).intersect_box(lo, hi).is_none() {
                        continue;
                    }
                    hit += 1;
                    let r = rect.unwrap_or_else(|| panic!("box {lo} {hi} is hit but has no rect"));
                    assert!(
                        x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1,
                        "pixel {x},{y} hits box {lo} {hi} but lies outside {r:?}"
                    );
                }
            }
            small += usize::from(rect.is_none_or(|r| r.area() < 64 * 48 / 2) && hit < 64 * 48 / 2);
        }
        assert!(small > 100, "only {small} of 200 boxes have tight rects");
    }

    #[test]
    fn look_at_problems_are_the_bases_look_at_refuses() {
        let p = Projection::Perspective { vfov_deg: 60.0 };
        let at = Vec3::new(0.0, 0.0, 9.0);
        for (target, up, problem) in [
            (at, Vec3::Y, Some(LookAtProblem::SamePoint)),
            (Vec3::ZERO, Vec3::ZERO, Some(LookAtProblem::UpNotADirection)),
            (Vec3::ZERO, Vec3::NAN, Some(LookAtProblem::UpNotADirection)),
            (Vec3::ZERO, -3.0 * Vec3::Z, Some(LookAtProblem::UpAlongView)),
            (Vec3::ZERO, Vec3::Y, None),
        ] {
            assert_eq!(look_at_problem(at, target, up), problem, "{target} {up}");
            let refused = Camera::look_at(at, target, up, p, 4, 4).is_err();
            assert_eq!(refused, problem.is_some(), "{target} {up}");
        }
    }

    #[test]
    fn degenerate_cameras_are_errors() {
        let p = Projection::Perspective { vfov_deg: 60.0 };
        assert_eq!(
            Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Z, p, 4, 4),
            Err(CameraError::DegenerateBasis)
        );
        assert_eq!(
            Camera::new(Vec3::ZERO, Vec3::X, Vec3::Z, p, 0, 4),
            Err(CameraError::EmptyImage(0, 4))
        );
        // A frame too large to allocate (an abort before), and a position
        // whose distances overflow (said as a degenerate basis before).
        assert_eq!(
            Camera::new(Vec3::ZERO, Vec3::X, Vec3::Z, p, 65536, 4),
            Err(CameraError::ImageTooLarge(65536, 4))
        );
        assert!(Camera::new(Vec3::ZERO, Vec3::X, Vec3::Z, p, 16384, 16384).is_ok());
        assert_eq!(
            Camera::look_at(Vec3::new(1e20, 0.0, 0.0), Vec3::ZERO, Vec3::Z, p, 4, 4),
            Err(CameraError::BadPosition)
        );
        assert!(Camera::look_at(Vec3::new(1e18, 0.0, 0.0), Vec3::ZERO, Vec3::Z, p, 4, 4).is_ok());
        // A far target and a long up vector are directions like any other
        // (their squared lengths overflowed: said as a degenerate basis).
        let far = Camera::look_at(
            Vec3::ZERO,
            Vec3::new(1e20, 0.0, 0.0),
            1e20 * Vec3::Z,
            p,
            4,
            4,
        )
        .unwrap();
        assert!((far.direction() - Vec3::X).length() < 1e-6);
        assert!((far.up() - Vec3::Z).length() < 1e-6);
        assert_eq!(
            look_at_problem(Vec3::ZERO, Vec3::new(1e20, 0.0, 0.0), 1e20 * Vec3::Z),
            None
        );
        let wide = Projection::Perspective { vfov_deg: 180.0 };
        assert_eq!(
            Camera::new(Vec3::ZERO, Vec3::X, Vec3::Z, wide, 4, 4),
            Err(CameraError::BadProjection)
        );
    }
}
