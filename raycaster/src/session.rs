//! Sessions: everything that makes one frame, as a readable TOML file.
//!
//! A [`Session`] holds where the volume comes from (a file or a built-in scene),
//! the label volume and two-level scene if any, the image size, the exact camera,
//! the [`RenderSettings`] (mode and its parameters, transfer function, step,
//! early ray termination, empty-space skipping, shading, pre-integration, jitter,
//! crop box and clipping planes, background), the pyramid level choice and the
//! viewer's slice views ([`SliceViews`], which only the viewer uses). The
//! viewer saves what it shows as a session and `raycaster render --session`
//! renders it: the same settings and camera give the same pixels.
//!
//! Floats are written so that they read back to the same `f32` bits, which is
//! what makes a re-render pixel-identical. Relative paths in a session file are
//! relative to the file's folder, and [`Session::save`] writes them so (a path held
//! relative to the working directory becomes one relative to the saved file's folder,
//! or absolute).
//!
//! ```toml
//! version = 1
//!
//! [volume]
//! scene = "shapes"          # or: file = "lung1.vol"
//! size = 128
//! seed = 1
//!
//! [image]
//! width = 640
//! height = 480
//!
//! [camera]                  # an orbit about `target` (angles in radians) ...
//! target = [63.5, 63.5, 63.5]
//! distance = 350.0
//! azimuth_rad = -1.0471976
//! elevation_rad = 0.43633232
//! fov = 40.0                # or: ortho_height = 240.0
//! # ... or a look-at camera: position = [x, y, z], target, up = [0.0, 0.0, 1.0]
//!
//! [transfer]                # points = [[value, r, g, b, alpha], ...], or: preset = "shapes"
//! points = [[0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0, 0.5]]
//!
//! [render]
//! mode = "dvr"
//! step = 0.5
//! ```
//!
//! The whole format, with every key, is described in `docs/viewer.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use serde::Deserialize;

use crate::render::{
    Camera, CameraError, ClipPlane, ClipRegion, ControlPoint, CropBox, ImportanceSource,
    LevelChoice, Light, LookAtProblem, Membership, Mode, ModeParameters, Orbit, Projection,
    RenderSettings, SabellaDepth, SabellaMapping, SabellaOutput, SceneError, SegmentScene, Shading,
    TransferError, TransferFunction, check_domain, check_gradient_ramp, look_at_problem,
};
use crate::source::VolumeSource;
use crate::synth::SceneKind;
use crate::volume::{Access, write_file_atomically};

/// The session format's version, written as `version = 1`.
pub const SESSION_VERSION: u32 = 1;

/// The largest session file read, in bytes (4 MiB).
const SESSION_MAX: u64 = 4 << 20;

/// The largest image side a session may ask for: a camera's.
pub use crate::render::MAX_IMAGE_SIDE;

/// Everything needed to reproduce one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Session {
    /// The volume: a file or a built-in scene. A file's `access` is not stored
    /// (it does not change the picture); sessions read back with
    /// [`Access::Mapped`].
    pub source: VolumeSource,
    /// A label volume for a label scene, overriding the scene's `labels`.
    pub labels: Option<PathBuf>,
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// The camera.
    pub camera: SessionCamera,
    /// Mode, transfer function, two-level scene, clipping and the rest. `simd`
    /// (the marching kernel) is not stored: every kernel composites the same
    /// image; sessions read back with `None` (automatic).
    pub settings: RenderSettings,
    /// Which level of the volume's resolution pyramid to sample.
    pub level: LevelChoice,
    /// The viewer's slice views, when it saved them (`raycaster render` draws
    /// no slices and ignores them).
    pub slices: Option<SliceViews>,
}

/// The viewer's slice views: where the crosshair is, their window and zoom.
#[derive(Clone, Debug, PartialEq)]
pub struct SliceViews {
    /// The crosshair: a voxel of the full-resolution volume (the viewer clamps
    /// it into the volume it opens).
    pub crosshair: [u32; 3],
    /// The window the slices are shown with.
    pub window: SliceWindow,
    /// The slices' zoom about the crosshair, at least 1.
    pub zoom: f32,
}

/// The window of the slice views.
#[derive(Clone, Debug, PartialEq)]
pub enum SliceWindow {
    /// Fitted to the data (the transfer function's domain).
    Fitted,
    /// A named window (`raycaster::windows::NAMED_WINDOWS`: `lung`, `bone`, …).
    Named(String),
    /// A window set by hand, `[lo, hi]` in stored sample values.
    Values([f32; 2]),
}

/// The largest slice zoom a session may ask for (the viewer's slider's).
pub const MAX_SLICE_ZOOM: f32 = 8.0;

/// The camera of a session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SessionCamera {
    /// An orbit about a target, world up +z (what the viewer's mouse drives and
    /// what `raycaster render --azimuth --elevation` frames).
    Orbit(Orbit),
    /// A camera at `position` looking at `target` with the given up vector.
    LookAt {
        /// Where the camera is (world units).
        position: Vec3,
        /// The point it looks at.
        target: Vec3,
        /// The up direction.
        up: Vec3,
        /// Perspective or orthographic.
        projection: Projection,
    },
}

impl SessionCamera {
    /// The camera for an image of `width × height` pixels.
    pub fn camera(&self, width: u32, height: u32) -> Result<Camera, CameraError> {
        match *self {
            SessionCamera::Orbit(orbit) => orbit.camera(width, height),
            SessionCamera::LookAt {
                position,
                target,
                up,
                projection,
            } => Camera::look_at(position, target, up, projection, width, height),
        }
    }
}

/// What is wrong with a session (or its file).
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The file cannot be read.
    #[error("cannot read session {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The file cannot be written.
    #[error("cannot write session {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key or a value of the wrong type.
    #[error("session: {0}")]
    Syntax(String),
    /// A value out of range, inconsistent or missing.
    #[error("session: `{field}`: {what}")]
    Invalid {
        /// The key, with its table (`render.step`).
        field: String,
        /// What is wrong.
        what: String,
    },
    /// The embedded two-level scene.
    #[error("session: [scene]: {0}")]
    Scene(#[source] SceneError),
    /// What is wrong in a session file ([`Session::load`]).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong in it.
        source: Box<SessionError>,
    },
}

/// The `[slices]` section, checked.
fn slice_views(file: &SlicesFile) -> Result<SliceViews, SessionError> {
    let window = match &file.window {
        None => SliceWindow::Fitted,
        Some(WindowField::Name(name)) if name == "fitted" => SliceWindow::Fitted,
        Some(WindowField::Name(name)) => {
            if !crate::windows::NAMED_WINDOWS.iter().any(|w| w.name == name) {
                let known: Vec<&str> = crate::windows::NAMED_WINDOWS
                    .iter()
                    .map(|w| w.name)
                    .collect();
                return Err(invalid(
                    "slices.window",
                    format!(
                        "{name:?} is not a window (fitted, {}, or [lo, hi] in stored values)",
                        known.join(", ")
                    ),
                ));
            }
            SliceWindow::Named(name.clone())
        }
        Some(WindowField::Values([lo, hi])) => {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(invalid(
                    "slices.window",
                    format!("[{lo}, {hi}]: needs finite values with lo < hi"),
                ));
            }
            SliceWindow::Values([*lo, *hi])
        }
    };
    let zoom = file.zoom.unwrap_or(1.0);
    if !(1.0..=MAX_SLICE_ZOOM).contains(&zoom) {
        return Err(invalid(
            "slices.zoom",
            format!("{zoom}: must lie in 1..={MAX_SLICE_ZOOM}"),
        ));
    }
    Ok(SliceViews {
        crosshair: file.crosshair,
        window,
        zoom,
    })
}

fn invalid(field: &str, what: impl Into<String>) -> SessionError {
    SessionError::Invalid {
        field: field.to_string(),
        what: what.into(),
    }
}

// ---- the file as read ---------------------------------------------------------

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SessionFile {
    version: Option<u32>,
    volume: VolumeFile,
    image: ImageFile,
    camera: CameraFile,
    transfer: TransferFile,
    #[serde(default)]
    render: RenderFile,
    #[serde(default)]
    shading: ShadingFile,
    #[serde(default)]
    clip: ClipFile,
    scene: Option<toml::Table>,
    slices: Option<SlicesFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SlicesFile {
    crosshair: [u32; 3],
    window: Option<WindowField>,
    zoom: Option<f32>,
}

#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "a window is a preset name (a string) or `[low, high]`"
)]
enum WindowField {
    Name(String),
    Values([f32; 2]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct VolumeFile {
    file: Option<PathBuf>,
    scene: Option<String>,
    size: Option<u32>,
    seed: Option<u64>,
    labels: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ImageFile {
    width: u32,
    height: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    target: [f32; 3],
    distance: Option<f32>,
    azimuth_rad: Option<f32>,
    elevation_rad: Option<f32>,
    position: Option<[f32; 3]>,
    up: Option<[f32; 3]>,
    /// An orbit's axes (x, y, up as columns), when not the volume's own.
    axes: Option<[[f32; 3]; 3]>,
    fov: Option<f32>,
    ortho_height: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransferFile {
    preset: Option<String>,
    points: Option<Vec<[f32; 5]>>,
    domain: Option<[f32; 2]>,
    gradient: Option<[f32; 2]>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderFile {
    mode: Option<String>,
    step: Option<f32>,
    ert: Option<bool>,
    ert_threshold: Option<f32>,
    ess: Option<bool>,
    iso: Option<f32>,
    xray_gain: Option<f32>,
    context: Option<[f32; 2]>,
    importance: Option<String>,
    importance_weight: Option<f32>,
    importance_p: Option<[f32; 3]>,
    sabella_depth: Option<String>,
    sabella_hue: Option<[f32; 2]>,
    sabella_saturation: Option<[f32; 2]>,
    background: Option<[f32; 3]>,
    preintegrate: Option<bool>,
    jitter: Option<bool>,
    level: Option<LevelFile>,
    lod_bias: Option<f32>,
}

#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "`level` is `\"auto\"` or a level number (0 = full resolution)"
)]
enum LevelFile {
    Number(u32),
    Name(String),
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ShadingFile {
    enabled: Option<bool>,
    /// `"headlight"` or a direction `[x, y, z]`.
    light: Option<LightFile>,
    ambient: Option<f32>,
    diffuse: Option<f32>,
    specular: Option<f32>,
    shininess: Option<f32>,
    gradient_threshold: Option<f32>,
}

#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "`light` is `\"headlight\"` or a direction `[x, y, z]`"
)]
enum LightFile {
    Direction([f32; 3]),
    Name(String),
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ClipFile {
    crop: Option<[f32; 6]>,
    #[serde(default)]
    planes: Vec<[f32; 6]>,
}

// ---- checks --------------------------------------------------------------------

fn finite(field: &str, v: f32) -> Result<f32, SessionError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(field, format!("{v} is not a finite number")))
    }
}

fn finite_all<const N: usize>(field: &str, v: [f32; N]) -> Result<[f32; N], SessionError> {
    for x in v {
        finite(field, x)?;
    }
    Ok(v)
}

fn positive(field: &str, v: f32) -> Result<f32, SessionError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("{v} must be a positive number")))
    }
}

fn non_negative(field: &str, v: f32) -> Result<f32, SessionError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else if v == f32::INFINITY {
        // (A number beyond f32's range reads as infinity.)
        Err(invalid(
            field,
            "the number is too large (a 32-bit float holds up to 3.4e38)",
        ))
    } else {
        Err(invalid(field, format!("{v} must be a non-negative number")))
    }
}

/// An ambient, diffuse or specular factor: 0 to
/// [`crate::render::MAX_LIGHT_FACTOR`] (the rule of the render's own check).
fn light_factor(field: &str, v: f32) -> Result<f32, SessionError> {
    let v = non_negative(field, v)?;
    crate::render::check_light_factor(v).map_err(|what| invalid(field, what))?;
    Ok(v)
}

fn unit(field: &str, v: f32) -> Result<f32, SessionError> {
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(invalid(field, format!("{v} must lie in [0, 1]")))
    }
}

fn fov(field: &str, v: f32) -> Result<f32, SessionError> {
    if v > 0.0 && v < 180.0 {
        Ok(v)
    } else {
        Err(invalid(
            field,
            format!("{v} must lie strictly between 0 and 180 degrees"),
        ))
    }
}

fn path_field(field: &str, path: PathBuf, base: &Path) -> Result<PathBuf, SessionError> {
    if path.as_os_str().is_empty() {
        return Err(invalid(field, "the path is empty"));
    }
    Ok(base.join(path))
}

/// A session's `version`: present, and the one this raycaster reads.
fn check_version(version: Option<i64>) -> Result<(), SessionError> {
    match version {
        Some(v) if v == i64::from(SESSION_VERSION) => Ok(()),
        Some(v) => Err(invalid(
            "version",
            format!("version {v} is not known (this raycaster reads version {SESSION_VERSION})"),
        )),
        None => Err(invalid("version", "missing: write `version = 1`")),
    }
}

/// The tables every session has.
const REQUIRED_TABLES: [&str; 4] = ["volume", "image", "camera", "transfer"];

/// Refuses a number no 32-bit float holds, naming its key
/// ([`crate::text::toml_float_range`]).
fn check_float_range(text: &str) -> Result<(), SessionError> {
    crate::text::toml_float_range(text).map_err(|(key, what)| invalid(&key, what))
}

/// The session's outline, when the field-by-field reading finds a field
/// missing: a version this raycaster reads, and the tables every session has,
/// each said by name (the reading reports a missing table as TOML's "missing
/// field" at line 1, and an unknown version as whatever else is missing).
fn check_outline(text: &str) -> Result<(), SessionError> {
    // (Syntax errors are the field-by-field reading's to report.)
    let Ok(table) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    match table.get("version") {
        None => check_version(None)?,
        Some(toml::Value::Integer(v)) => check_version(Some(*v))?,
        // (A version that is no integer: the field's reading says so.)
        Some(_) => {}
    }
    if let Some(missing) = REQUIRED_TABLES.iter().find(|t| !table.contains_key(**t)) {
        return Err(invalid(
            missing,
            format!(
                "the [{missing}] table is missing (every session has [volume], [image], [camera] and [transfer]; docs/viewer.md, \"Sessions\")"
            ),
        ));
    }
    Ok(())
}

impl Session {
    /// Why the session's image cannot be rendered at its size, if it cannot:
    /// a side over [`MAX_IMAGE_SIDE`]. Reading accepts it, so that a size given
    /// elsewhere (`raycaster render --size`, the viewer's canvas) can take its
    /// place.
    pub fn image_size_problem(&self) -> Option<String> {
        [
            ("image.width", self.size[0]),
            ("image.height", self.size[1]),
        ]
        .into_iter()
        .find(|&(_, side)| !(1..=MAX_IMAGE_SIDE).contains(&side))
        .map(|(name, side)| format!("{name} = {side} pixels: must lie in 1..={MAX_IMAGE_SIDE}"))
    }

    /// Why the session's label volume has no use, if it has none: a label
    /// volume gives a label scene its objects, and the session has no
    /// two-level scene, or one whose objects come from value layers.
    pub fn labels_problem(&self) -> Option<&'static str> {
        self.labels.as_ref()?;
        match self
            .settings
            .segments
            .as_ref()
            .map(|scene| &scene.membership)
        {
            None => Some(
                "a label volume gives a two-level label scene its objects, and there is no scene",
            ),
            Some(Membership::Layers(_)) => Some(
                "the scene takes its objects from value layers (`layers =`), not from a label volume",
            ),
            Some(Membership::Labels(_)) => None,
        }
    }

    /// Reads a session file; relative paths in it are relative to its folder.
    /// The volume and label files must exist.
    pub fn load(path: &Path) -> Result<Session, SessionError> {
        let text =
            crate::files::read_text(path, SESSION_MAX).map_err(|source| SessionError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Self::parse_and_check(&text, path.parent().unwrap_or(Path::new(""))).map_err(|e| {
            SessionError::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            }
        })
    }

    /// [`Self::parse`], checking that the volume and label files exist.
    fn parse_and_check(text: &str, base: &Path) -> Result<Session, SessionError> {
        let session = Session::parse(text, base)?;
        // Said as the system says it (a loop of links is not a missing file).
        let reachable = |field: &str, path: &Path| match std::fs::metadata(path) {
            Ok(_) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(invalid(
                field,
                format!("{}: no such file or folder", path.display()),
            )),
            Err(e) => Err(invalid(field, format!("{}: {e}", path.display()))),
        };
        if let VolumeSource::File { path, .. } = &session.source {
            reachable("volume.file", path)?;
        }
        if let Some(labels) = &session.labels {
            reachable("volume.labels", labels)?;
        }
        Ok(session)
    }

    /// Parses a session; relative paths are joined to `base`. Nothing is read
    /// from disk except transfer-function files an embedded scene names.
    pub fn parse(text: &str, base: &Path) -> Result<Session, SessionError> {
        let text = crate::text::without_bom(text);
        let file: SessionFile = match toml::from_str(text) {
            Ok(file) => file,
            Err(e) => {
                // A missing table, or a version this raycaster does not read,
                // said by name rather than as "missing field" at line 1.
                if e.message().starts_with("missing field") {
                    check_outline(text)?;
                }
                return Err(SessionError::Syntax(crate::text::toml_error(text, &e)));
            }
        };
        check_version(file.version.map(i64::from))?;
        check_float_range(text)?;
        let source = volume_source(&file.volume, base)?;
        let labels = match &file.volume.labels {
            Some(p) => Some(path_field("volume.labels", p.clone(), base)?),
            None => None,
        };
        let size = [file.image.width, file.image.height];
        // (A side over the largest is refused where the size is rendered,
        // `Self::image_size_problem`: a smaller size can replace it.)
        for (name, side) in [("image.width", size[0]), ("image.height", size[1])] {
            if side == 0 {
                return Err(invalid(
                    name,
                    format!("0 pixels: must lie in 1..={MAX_IMAGE_SIDE}"),
                ));
            }
        }
        let camera = camera(&file.camera)?;
        // (Checked at a size a camera takes: the size's own problem is said
        // where it is rendered.)
        camera
            .camera(size[0].min(MAX_IMAGE_SIDE), size[1].min(MAX_IMAGE_SIDE))
            .map_err(|e| invalid("camera", e.to_string()))?;
        let transfer = transfer(&file.transfer, base)?;
        let (settings, level) = settings(&file, transfer, base)?;
        let slices = file.slices.as_ref().map(slice_views).transpose()?;
        let session = Session {
            source,
            labels,
            size,
            camera,
            settings,
            level,
            slices,
        };
        if let Some(problem) = session.labels_problem() {
            return Err(invalid("volume.labels", problem));
        }
        // Every field was checked as it was read; the renderers' own check
        // of the whole says what a rule of theirs alone refuses (a session
        // that reads renders).
        session
            .settings
            .check()
            .map_err(|e| invalid("render", e.to_string()))?;
        Ok(session)
    }

    /// The session as TOML that [`Session::parse`] reads back to an equal session
    /// (up to `simd` and a file's `access`, which are not stored). Refuses what a
    /// session cannot describe (Sabella's raw channels).
    pub fn to_toml(&self) -> Result<String, SessionError> {
        let s = &self.settings;
        let mut out = String::from("# raycaster session (docs/viewer.md)\n");
        let _ = writeln!(out, "version = {SESSION_VERSION}");

        out += "\n[volume]\n";
        match &self.source {
            VolumeSource::File { path, .. } => {
                let _ = writeln!(out, "file = {}", quote(&path.to_string_lossy()));
            }
            VolumeSource::BuiltIn { kind, size, seed } => {
                let _ = writeln!(out, "scene = {}", quote(kind.name()));
                let _ = writeln!(out, "size = {size}\nseed = {seed}");
            }
        }
        if let Some(labels) = &self.labels {
            let _ = writeln!(out, "labels = {}", quote(&labels.to_string_lossy()));
        }

        let [w, h] = self.size;
        let _ = writeln!(out, "\n[image]\nwidth = {w}\nheight = {h}");

        out += "\n[camera]\n";
        let projection = match self.camera {
            SessionCamera::Orbit(o) => {
                let _ = writeln!(out, "target = {}", list(o.target.to_array()));
                let _ = writeln!(out, "distance = {}", num(o.distance));
                let _ = writeln!(out, "azimuth_rad = {}", num(o.azimuth));
                let _ = writeln!(out, "elevation_rad = {}", num(o.elevation));
                if o.axes != Mat3::IDENTITY {
                    let columns = o.axes.to_cols_array_2d().map(list);
                    let _ = writeln!(out, "axes = [{}]", columns.join(", "));
                }
                match o.vfov_deg {
                    Some(vfov_deg) => Projection::Perspective { vfov_deg },
                    None => Projection::Orthographic {
                        height: o.ortho_height,
                    },
                }
            }
            SessionCamera::LookAt {
                position,
                target,
                up,
                projection,
            } => {
                let _ = writeln!(out, "position = {}", list(position.to_array()));
                let _ = writeln!(out, "target = {}", list(target.to_array()));
                let _ = writeln!(out, "up = {}", list(up.to_array()));
                projection
            }
        };
        match projection {
            Projection::Perspective { vfov_deg } => {
                let _ = writeln!(out, "fov = {}", num(vfov_deg));
            }
            Projection::Orthographic { height } => {
                let _ = writeln!(out, "ortho_height = {}", num(height));
            }
        }
        // An orbit keeps its orthographic height for zooming even in perspective.
        if let SessionCamera::Orbit(o) = self.camera
            && o.vfov_deg.is_some()
        {
            let _ = writeln!(out, "ortho_height = {}", num(o.ortho_height));
        }

        out += "\n[transfer]\n";
        let tf = &s.transfer;
        if let Some(d) = tf.domain {
            let _ = writeln!(out, "domain = {}", list(d));
        }
        if let Some(g) = tf.gradient_ramp {
            let _ = writeln!(out, "gradient = {}", list(g));
        }
        out += "points = [\n";
        for p in tf.points() {
            let [r, g, b] = p.color;
            let _ = writeln!(out, "  {},", list([p.value, r, g, b, p.alpha]));
        }
        out += "]\n";

        out += "\n[render]\n";
        let _ = writeln!(out, "mode = {}", quote(s.mode.name()));
        let _ = writeln!(out, "step = {}", num(s.step));
        let _ = writeln!(out, "ert = {}", s.early_termination.is_some());
        let threshold = s
            .early_termination
            .unwrap_or(crate::render::DEFAULT_ERT_THRESHOLD);
        let _ = writeln!(out, "ert_threshold = {}", num(threshold));
        let _ = writeln!(out, "ess = {}", s.empty_space_skipping);
        let _ = writeln!(out, "iso = {}", num(s.iso_value));
        let m = &s.mode_parameters;
        // (Absent: the automatic gain.)
        if let Some(gain) = m.xray_gain {
            let _ = writeln!(out, "xray_gain = {}", num(gain));
        }
        let _ = writeln!(out, "context = {}", list(m.context));
        let (name, weight, p) = match m.importance {
            ImportanceSource::Constant(w) => ("constant", Some(w), None),
            ImportanceSource::Intensity(w) => ("intensity", Some(w), None),
            ImportanceSource::Gradient(w) => ("gradient", Some(w), None),
            ImportanceSource::Silhouette(p) => ("silhouette", None, Some(p)),
            ImportanceSource::Lighting(p) => ("lighting", None, Some(p)),
        };
        let _ = writeln!(out, "importance = {}", quote(name));
        if let Some(w) = weight {
            let _ = writeln!(out, "importance_weight = {}", num(w));
        }
        if let Some(p) = p {
            let _ = writeln!(out, "importance_p = {}", list(p));
        }
        match m.sabella {
            SabellaOutput::Colours(mapping) => {
                let _ = writeln!(out, "sabella_depth = {}", quote(mapping.depth.name()));
                let _ = writeln!(out, "sabella_hue = {}", list(mapping.hue));
                let _ = writeln!(out, "sabella_saturation = {}", list(mapping.saturation));
            }
            SabellaOutput::Channels => {
                return Err(invalid(
                    "render.sabella_depth",
                    "Sabella's raw channels are not a picture; a session holds colours",
                ));
            }
        }
        let _ = writeln!(out, "background = {}", list(s.background));
        let _ = writeln!(out, "preintegrate = {}", s.preintegrated);
        let _ = writeln!(out, "jitter = {}", s.jitter);
        match self.level {
            LevelChoice::Auto { bias } => {
                let _ = writeln!(out, "level = \"auto\"\nlod_bias = {}", num(bias));
            }
            LevelChoice::Fixed(k) => {
                let _ = writeln!(out, "level = {k}");
            }
        }

        out += "\n[shading]\n";
        let shading = s.shading.unwrap_or_default();
        let _ = writeln!(out, "enabled = {}", s.shading.is_some());
        match shading.light {
            Light::Headlight => out += "light = \"headlight\"\n",
            Light::Fixed(d) => {
                let _ = writeln!(out, "light = {}", list(d.to_array()));
            }
        }
        let _ = writeln!(out, "ambient = {}", num(shading.ambient));
        let _ = writeln!(out, "diffuse = {}", num(shading.diffuse));
        let _ = writeln!(out, "specular = {}", num(shading.specular));
        let _ = writeln!(out, "shininess = {}", num(shading.shininess));
        let _ = writeln!(
            out,
            "gradient_threshold = {}",
            num(shading.gradient_threshold)
        );

        if !s.clip.is_empty() {
            out += "\n[clip]   # voxel coordinates\n";
            if let Some(CropBox { lo, hi }) = s.clip.crop {
                let _ = writeln!(out, "crop = {}", list([lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]));
            }
            if !s.clip.planes.is_empty() {
                let planes: Vec<String> = s
                    .clip
                    .planes
                    .iter()
                    .map(|p| {
                        let (q, n) = (p.point, p.normal);
                        list([q.x, q.y, q.z, n.x, n.y, n.z])
                    })
                    .collect();
                let _ = writeln!(out, "planes = [{}]", planes.join(", "));
            }
        }

        if let Some(scene) = &s.segments {
            // The scene's own format, as the table `[scene]`.
            let table: toml::Table = toml::from_str(&scene.to_toml())
                .map_err(|e| invalid("scene", format!("cannot embed the scene: {e}")))?;
            let mut wrapper = toml::Table::new();
            wrapper.insert("scene".into(), toml::Value::Table(table));
            let text = toml::to_string(&wrapper)
                .map_err(|e| invalid("scene", format!("cannot embed the scene: {e}")))?;
            out += "\n# The two-level scene (docs/segments.md).\n";
            if matches!(self.source, VolumeSource::BuiltIn { .. })
                && self.labels.is_none()
                && matches!(scene.membership, Membership::Labels(_))
            {
                out += "# (The built-in scene brings its own label volume: the scene's\n";
                out += "# `labels` file is not read while `[volume]` names a built-in scene.)\n";
            }
            out += &text;
        }

        if let Some(slices) = &self.slices {
            out += "\n[slices]                  # the viewer's slice views\n";
            let _ = writeln!(out, "crosshair = {:?}", slices.crosshair);
            match &slices.window {
                SliceWindow::Fitted => out += "window = \"fitted\"\n",
                SliceWindow::Named(name) => {
                    let _ = writeln!(out, "window = {}", quote(name));
                }
                SliceWindow::Values(v) => {
                    let _ = writeln!(out, "window = {}", list(*v));
                }
            }
            let _ = writeln!(out, "zoom = {}", num(slices.zoom));
        }
        Ok(out)
    }

    /// Writes the session to `path` atomically (a temporary file renamed into
    /// place: never half-written). Its file paths, held relative to the
    /// working directory, are written as `path`'s folder reaches them
    /// ([`crate::files::path_for_file_in`]): the file reads back the same
    /// files wherever it is saved.
    pub fn save(&self, path: &Path) -> Result<(), SessionError> {
        let text = self
            .with_paths_for(crate::files::parent_dir(path))
            .to_toml()?;
        write_file_atomically(path, text.as_bytes()).map_err(|source| SessionError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// The session with its file paths as a file in folder `dir` names them.
    fn with_paths_for(&self, dir: &Path) -> Session {
        let mut session = self.clone();
        if let VolumeSource::File { path, .. } = &mut session.source {
            *path = crate::files::path_for_file_in(dir, path);
        }
        if let Some(labels) = &mut session.labels {
            *labels = crate::files::path_for_file_in(dir, labels);
        }
        if let Some(scene) = &mut session.settings.segments {
            *scene = scene.with_paths_for(dir);
        }
        session
    }

    /// Checks the session's crop box and planes and those of its scene's
    /// objects against the box a volume samples at full resolution
    /// (`sampled`, [`crate::volume::Volume::sampled_box`]): a cut beside the
    /// volume is an error naming its field, as front ends refuse it before any
    /// frame (a coarse level's margin lets some pass).
    pub fn check_cuts(&self, sampled: [[f32; 3]; 2]) -> Result<(), SessionError> {
        let clip = &self.settings.clip;
        clip.check_overlaps(sampled, 1.0)
            .map_err(|e| invalid("clip.crop", e.to_string()))?;
        if let Some(scene) = &self.settings.segments {
            scene
                .check_cuts(sampled, 1.0)
                .map_err(|e| invalid("scene", e.to_string()))?;
        }
        Ok(())
    }

    /// The camera for the session's image size.
    pub fn camera(&self) -> Result<Camera, CameraError> {
        self.camera.camera(self.size[0], self.size[1])
    }
}

fn volume_source(v: &VolumeFile, base: &Path) -> Result<VolumeSource, SessionError> {
    match (&v.file, &v.scene) {
        (Some(_), Some(_)) => Err(invalid(
            "volume",
            "give either `file` or `scene` (a built-in scene), not both",
        )),
        (None, None) => Err(invalid(
            "volume",
            "give `file = \"PATH\"` or `scene = \"shapes\"` (a built-in scene)",
        )),
        (Some(path), None) => {
            if v.size.is_some() || v.seed.is_some() {
                return Err(invalid(
                    "volume",
                    "`size` and `seed` belong to built-in scenes, not files",
                ));
            }
            Ok(VolumeSource::File {
                path: path_field("volume.file", path.clone(), base)?,
                access: Access::Mapped,
            })
        }
        (None, Some(name)) => {
            let kind = SceneKind::ALL
                .into_iter()
                .find(|k| k.name() == name)
                .ok_or_else(|| {
                    invalid(
                        "volume.scene",
                        format!(
                            "unknown built-in scene {name:?} (shapes, shells, noise, gradient)"
                        ),
                    )
                })?;
            let size = v
                .size
                .ok_or_else(|| invalid("volume.size", "missing: voxels per axis"))?;
            if !(2..=1024).contains(&size) {
                return Err(invalid(
                    "volume.size",
                    format!("{size} voxels: must lie in 2..=1024"),
                ));
            }
            Ok(VolumeSource::BuiltIn {
                kind,
                size,
                seed: v.seed.unwrap_or(1),
            })
        }
    }
}

fn camera(c: &CameraFile) -> Result<SessionCamera, SessionError> {
    let target = Vec3::from(finite_all("camera.target", c.target)?);
    let projection = match (c.fov, c.ortho_height) {
        (Some(f), _) => Projection::Perspective {
            vfov_deg: fov("camera.fov", f)?,
        },
        (None, Some(h)) => Projection::Orthographic {
            height: positive("camera.ortho_height", h)?,
        },
        (None, None) => {
            return Err(invalid(
                "camera",
                "give `fov` (degrees, perspective) or `ortho_height` (orthographic)",
            ));
        }
    };
    match c.position {
        Some(position) => {
            if c.distance.is_some()
                || c.azimuth_rad.is_some()
                || c.elevation_rad.is_some()
                || c.axes.is_some()
            {
                return Err(invalid(
                    "camera",
                    "a look-at camera (`position`) takes no `distance`, `azimuth_rad`, `elevation_rad` or `axes`",
                ));
            }
            let position = Vec3::from(finite_all("camera.position", position)?);
            let up = Vec3::from(finite_all("camera.up", c.up.unwrap_or([0.0, 0.0, 1.0]))?);
            if !(position - target).length_squared().is_finite() {
                return Err(invalid(
                    "camera.position",
                    format!(
                        "[{}] is too far from the target for the view to be computed",
                        position
                            .to_array()
                            .map(crate::volume::number_text)
                            .join(", ")
                    ),
                ));
            }
            // (Said by field, as `raycaster render` says its flags.)
            match look_at_problem(position, target, up) {
                None => {}
                Some(LookAtProblem::SamePoint) => {
                    return Err(invalid(
                        "camera.position",
                        format!("{position} is the target too: the camera looks nowhere"),
                    ));
                }
                Some(LookAtProblem::UpNotADirection | LookAtProblem::UpAlongView) => {
                    return Err(invalid(
                        "camera.up",
                        format!(
                            "{up} is zero or along the view direction (from {position} to {target})"
                        ),
                    ));
                }
            }
            Ok(SessionCamera::LookAt {
                position,
                target,
                up,
                projection,
            })
        }
        None => {
            if c.up.is_some_and(|u| u != [0.0, 0.0, 1.0]) {
                return Err(invalid(
                    "camera.up",
                    "an orbit camera has +z up; give `position` for another up vector",
                ));
            }
            let get = |name: &str, v: Option<f32>| {
                v.ok_or_else(|| {
                    invalid(
                        &format!("camera.{name}"),
                        "missing (an orbit camera needs distance, azimuth_rad and elevation_rad; a look-at camera, position)",
                    )
                })
            };
            let distance = positive("camera.distance", get("distance", c.distance)?)?;
            // (Its square, the view's length squared, must be a number.)
            if !(distance * distance).is_finite() {
                return Err(invalid(
                    "camera.distance",
                    format!(
                        "{} is too far from the target for the view to be computed; give a distance nearer the volume's size",
                        crate::volume::number_text(distance)
                    ),
                ));
            }
            let azimuth = finite("camera.azimuth_rad", get("azimuth_rad", c.azimuth_rad)?)?;
            let elevation = finite(
                "camera.elevation_rad",
                get("elevation_rad", c.elevation_rad)?,
            )?;
            if elevation.abs() >= std::f32::consts::FRAC_PI_2 {
                return Err(invalid(
                    "camera.elevation_rad",
                    format!("{elevation} must lie strictly between −π/2 and π/2"),
                ));
            }
            let (vfov_deg, ortho_height) = match projection {
                Projection::Perspective { vfov_deg } => (
                    Some(vfov_deg),
                    match c.ortho_height {
                        Some(h) => positive("camera.ortho_height", h)?,
                        None => distance,
                    },
                ),
                Projection::Orthographic { height } => (None, height),
            };
            let axes = match c.axes {
                Some(columns) => {
                    let axes = Mat3::from_cols_array_2d(&columns);
                    if !(axes.is_finite() && axes.determinant().abs() > 1e-3) {
                        return Err(invalid(
                            "camera.axes",
                            "must be three finite directions that are not coplanar",
                        ));
                    }
                    axes
                }
                None => Mat3::IDENTITY,
            };
            Ok(SessionCamera::Orbit(Orbit {
                target,
                distance,
                azimuth,
                elevation,
                vfov_deg,
                ortho_height,
                axes,
            }))
        }
    }
}

fn transfer(t: &TransferFile, base: &Path) -> Result<TransferFunction, SessionError> {
    let tf_error = |e: TransferError| invalid("transfer", e.to_string());
    let mut tf = match (&t.preset, &t.points) {
        (Some(_), Some(_)) => {
            return Err(invalid(
                "transfer",
                "give either `preset` (a name or a transfer-function file) or `points`, not both",
            ));
        }
        (None, None) => {
            return Err(invalid(
                "transfer",
                "give `points = [[value, r, g, b, alpha], ...]` or `preset = \"NAME\"`",
            ));
        }
        (Some(name), None) if base.join(name).is_file() => {
            TransferFunction::load(&base.join(name)).map_err(tf_error)?
        }
        (Some(name), None) => {
            TransferFunction::preset(name).map_err(|e| invalid("transfer.preset", e.to_string()))?
        }
        (None, Some(points)) => {
            let points = points
                .iter()
                .map(|&[value, r, g, b, alpha]| ControlPoint {
                    value,
                    color: [r, g, b],
                    alpha,
                })
                .collect();
            TransferFunction::new(points).map_err(|e| invalid("transfer.points", e.to_string()))?
        }
    };
    if let Some(d) = t.domain {
        check_domain(d).map_err(|e| invalid("transfer.domain", e))?;
        tf.domain = Some(d);
    }
    if let Some(g) = t.gradient {
        check_gradient_ramp(g).map_err(|e| invalid("transfer.gradient", e))?;
        tf.gradient_ramp = Some(g);
    }
    Ok(tf)
}

fn settings(
    file: &SessionFile,
    transfer: TransferFunction,
    base: &Path,
) -> Result<(RenderSettings, LevelChoice), SessionError> {
    let r = &file.render;
    let defaults = RenderSettings::default();
    let mode = match &r.mode {
        None => Mode::Dvr,
        Some(name) => Mode::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Mode::ALL.iter().map(|m| m.name()).collect();
                invalid(
                    "render.mode",
                    format!("unknown mode {name:?} ({})", names.join(", ")),
                )
            })?,
    };
    let step = positive("render.step", r.step.unwrap_or(defaults.step))?;
    let threshold = r
        .ert_threshold
        .unwrap_or(crate::render::DEFAULT_ERT_THRESHOLD);
    if !(threshold > 0.0 && threshold <= 1.0) {
        return Err(invalid(
            "render.ert_threshold",
            format!("{threshold} must lie in (0, 1]"),
        ));
    }
    let early_termination = r.ert.unwrap_or(true).then_some(threshold);
    let iso = unit("render.iso", finite("render.iso", r.iso.unwrap_or(0.5))?)?;
    let xray_gain = r
        .xray_gain
        .map(|g| positive("render.xray_gain", g))
        .transpose()?;
    let mut context = ModeParameters::default().context;
    if let Some([kt, ks]) = r.context {
        context = [
            non_negative("render.context", kt)?,
            non_negative("render.context", ks)?,
        ];
    }
    let importance = importance(r)?;
    let mut mapping = SabellaMapping::default();
    if let Some(name) = &r.sabella_depth {
        mapping.depth = SabellaDepth::parse(name).ok_or_else(|| {
            invalid(
                "render.sabella_depth",
                format!("unknown depth {name:?} (peak, centroid)"),
            )
        })?;
    }
    if let Some(hue) = r.sabella_hue {
        mapping.hue = finite_all("render.sabella_hue", hue)?;
    }
    if let Some(sat) = r.sabella_saturation {
        for v in sat {
            unit("render.sabella_saturation", v)?;
        }
        mapping.saturation = sat;
    }
    let background = r.background.unwrap_or([0.0; 3]);
    for v in background {
        unit("render.background", v)?;
    }
    let level = match &r.level {
        None => LevelChoice::Auto { bias: 0.0 },
        Some(LevelFile::Number(k)) => LevelChoice::Fixed(*k),
        Some(LevelFile::Name(name)) if name == "auto" => LevelChoice::Auto { bias: 0.0 },
        Some(LevelFile::Name(name)) => {
            return Err(invalid(
                "render.level",
                format!("{name:?}: give \"auto\" or a level number (0 = full resolution)"),
            ));
        }
    };
    let level = match (level, r.lod_bias) {
        (LevelChoice::Auto { .. }, Some(bias)) => LevelChoice::Auto {
            bias: finite("render.lod_bias", bias)?,
        },
        // The neutral bias a session saved with `level = "auto"` writes stays
        // harmless when the level is edited to a number.
        (LevelChoice::Fixed(_), Some(bias)) if bias != 0.0 => {
            return Err(invalid(
                "render.lod_bias",
                "shifts the automatic level only; it takes `level = \"auto\"`",
            ));
        }
        (level, _) => level,
    };
    let shading = shading(&file.shading)?;
    let clip = clip(&file.clip)?;
    let segments = match &file.scene {
        None => None,
        Some(table) => {
            let mut table = table.clone();
            // A label scene takes the session's label volume unless it names one.
            if let Some(labels) = &file.volume.labels
                && !table.contains_key("labels")
                && !table.contains_key("layers")
            {
                let labels = labels.to_string_lossy().into_owned();
                table.insert("labels".into(), toml::Value::String(labels));
            }
            Some(SegmentScene::from_table(table, base).map_err(SessionError::Scene)?)
        }
    };
    let settings = RenderSettings {
        mode,
        mode_parameters: ModeParameters {
            xray_gain,
            context,
            importance,
            sabella: SabellaOutput::Colours(mapping),
        },
        step,
        early_termination,
        empty_space_skipping: file.render.ess.unwrap_or(true),
        shading,
        iso_value: iso,
        background,
        transfer,
        segments,
        simd: None,
        preintegrated: r.preintegrate.unwrap_or(false),
        jitter: r.jitter.unwrap_or(false),
        clip,
    };
    Ok((settings, level))
}

fn importance(r: &RenderFile) -> Result<ImportanceSource, SessionError> {
    let name = r.importance.as_deref().unwrap_or("constant");
    let weight = || {
        if r.importance_p.is_some() {
            return Err(invalid(
                "render.importance_p",
                format!("importance {name:?} takes `importance_weight`, not `importance_p`"),
            ));
        }
        non_negative(
            "render.importance_weight",
            r.importance_weight.unwrap_or(1.0),
        )
    };
    let p = || {
        if r.importance_weight.is_some() {
            return Err(invalid(
                "render.importance_weight",
                format!("importance {name:?} takes `importance_p`, not `importance_weight`"),
            ));
        }
        let p = r.importance_p.ok_or_else(|| {
            invalid(
                "render.importance_p",
                format!("missing: importance {name:?} takes three parameters"),
            )
        })?;
        for v in p {
            non_negative("render.importance_p", v)?;
        }
        Ok(p)
    };
    Ok(match name {
        "constant" => ImportanceSource::Constant(weight()?),
        "intensity" => ImportanceSource::Intensity(weight()?),
        "gradient" => ImportanceSource::Gradient(weight()?),
        "silhouette" => ImportanceSource::Silhouette(p()?),
        "lighting" => ImportanceSource::Lighting(p()?),
        other => {
            return Err(invalid(
                "render.importance",
                format!(
                    "unknown importance {other:?} (constant, intensity, gradient, silhouette, lighting)"
                ),
            ));
        }
    })
}

fn shading(s: &ShadingFile) -> Result<Option<Shading>, SessionError> {
    let d = Shading::default();
    let light = match &s.light {
        None => Light::Headlight,
        Some(LightFile::Name(name)) if name == "headlight" => Light::Headlight,
        Some(LightFile::Name(name)) => {
            return Err(invalid(
                "shading.light",
                format!("{name:?}: give \"headlight\" or a direction [x, y, z]"),
            ));
        }
        Some(LightFile::Direction(v)) => {
            let v = Vec3::from(finite_all("shading.light", *v)?);
            if let Some(problem) = crate::render::light_direction_problem(v) {
                return Err(invalid("shading.light", problem));
            }
            Light::Fixed(v)
        }
    };
    let shading = Shading {
        light,
        ambient: light_factor("shading.ambient", s.ambient.unwrap_or(d.ambient))?,
        diffuse: light_factor("shading.diffuse", s.diffuse.unwrap_or(d.diffuse))?,
        specular: light_factor("shading.specular", s.specular.unwrap_or(d.specular))?,
        shininess: non_negative("shading.shininess", s.shininess.unwrap_or(d.shininess))?,
        gradient_threshold: non_negative(
            "shading.gradient_threshold",
            s.gradient_threshold.unwrap_or(d.gradient_threshold),
        )?,
        fade_width: d.fade_width,
    };
    Ok(s.enabled.unwrap_or(true).then_some(shading))
}

fn clip(c: &ClipFile) -> Result<ClipRegion, SessionError> {
    let crop = match c.crop {
        None => None,
        Some(v) => {
            let v = finite_all("clip.crop", v)?;
            Some(CropBox {
                lo: Vec3::new(v[0], v[1], v[2]),
                hi: Vec3::new(v[3], v[4], v[5]),
            })
        }
    };
    let mut planes = Vec::with_capacity(c.planes.len());
    for &p in &c.planes {
        let p = finite_all("clip.planes", p)?;
        planes.push(ClipPlane {
            point: Vec3::new(p[0], p[1], p[2]),
            normal: Vec3::new(p[3], p[4], p[5]),
        });
    }
    let region = ClipRegion { crop, planes };
    region
        .validate()
        .map_err(|e| invalid("clip", e.to_string()))?;
    Ok(region)
}

// ---- writing -------------------------------------------------------------------

fn quote(s: &str) -> String {
    toml::Value::String(s.to_owned()).to_string()
}

/// `v` as a TOML float that reads back (as f64, then cast to f32) to the same
/// bits: the shortest form when it does, else the exact f64 value.
fn num(v: f32) -> String {
    let short = format!("{v:?}");
    let back = short.parse::<f64>().map(|x| x as f32);
    if back.is_ok_and(|b| b.to_bits() == v.to_bits()) {
        short
    } else {
        format!("{:?}", f64::from(v))
    }
}

fn list<const N: usize>(v: [f32; N]) -> String {
    let items: Vec<String> = v.iter().map(|&x| num(x)).collect();
    format!("[{}]", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{GlobalMode, LocalMode, Membership, ObjectStyle};

    fn sample() -> Session {
        let mut transfer = TransferFunction::preset("shapes").unwrap();
        transfer.domain = Some([3.0, 250.0]);
        Session {
            source: VolumeSource::BuiltIn {
                kind: SceneKind::Shapes,
                size: 48,
                seed: 7,
            },
            labels: None,
            size: [96, 64],
            camera: SessionCamera::Orbit(Orbit {
                target: Vec3::new(23.5, 23.1, 22.9),
                distance: 101.37,
                azimuth: 0.1_f32.mul_add(3.0, 1.0),
                elevation: -0.3,
                vfov_deg: Some(37.5),
                ortho_height: 55.5,
                axes: Mat3::from_cols(Vec3::X, -Vec3::Y, -Vec3::Z),
            }),
            settings: RenderSettings {
                mode: Mode::Sabella,
                mode_parameters: ModeParameters {
                    xray_gain: Some(2.5),
                    context: [1.25, 0.5],
                    importance: ImportanceSource::Lighting([1.0, 2.0, 0.5]),
                    sabella: SabellaOutput::Colours(SabellaMapping {
                        depth: SabellaDepth::Centroid,
                        ..SabellaMapping::default()
                    }),
                },
                step: 0.75,
                early_termination: None,
                empty_space_skipping: false,
                shading: Some(Shading {
                    light: Light::Fixed(Vec3::new(1.0, -2.0, 0.5)),
                    ..Shading::default()
                }),
                iso_value: 0.35,
                background: [0.1, 0.2, 0.3],
                transfer,
                segments: None,
                simd: None,
                preintegrated: true,
                jitter: true,
                clip: ClipRegion {
                    crop: Some(CropBox {
                        lo: Vec3::new(1.0, 2.0, 3.0),
                        hi: Vec3::new(40.0, 41.5, 42.0),
                    }),
                    planes: vec![ClipPlane {
                        point: Vec3::splat(24.0),
                        normal: Vec3::new(0.0, 1.0, -1.0),
                    }],
                },
            },
            level: LevelChoice::Auto { bias: 0.5 },
            slices: Some(SliceViews {
                crosshair: [3, 40, 17],
                window: SliceWindow::Values([-12.5, 300.25]),
                zoom: 2.5,
            }),
        }
    }

    fn round_trip(s: &Session) -> Session {
        let text = s.to_toml().unwrap();
        Session::parse(&text, Path::new("")).unwrap_or_else(|e| panic!("{e}\n{text}"))
    }

    #[test]
    fn a_session_reads_back_equal() {
        let s = sample();
        assert_eq!(round_trip(&s), s);
    }

    #[test]
    fn the_automatic_xray_gain_reads_back_automatic_and_a_given_one_given() {
        let mut s = sample();
        s.settings.mode_parameters.xray_gain = None;
        let text = s.to_toml().unwrap();
        assert!(!text.contains("xray_gain"), "{text}");
        assert_eq!(round_trip(&s).settings.mode_parameters.xray_gain, None);
        // A session written before the gain was automatic always has it.
        s.settings.mode_parameters.xray_gain = Some(1.0);
        let text = s.to_toml().unwrap();
        assert!(text.contains("xray_gain = 1"), "{text}");
        assert_eq!(round_trip(&s).settings.mode_parameters.xray_gain, Some(1.0));
    }

    #[test]
    fn slice_views_read_back_equal_and_are_optional() {
        let mut s = sample();
        for window in [
            SliceWindow::Fitted,
            SliceWindow::Named("lung".into()),
            SliceWindow::Values([0.1, 0.2]),
        ] {
            s.slices = Some(SliceViews {
                crosshair: [0, 7, 99],
                window,
                zoom: 1.0,
            });
            assert_eq!(round_trip(&s), s);
        }
        s.slices = None;
        let text = s.to_toml().unwrap();
        assert!(!text.contains("[slices]"));
        assert_eq!(round_trip(&s), s);
        // Only the crosshair is needed: a fitted window, no zoom.
        let short = format!("{text}\n[slices]\ncrosshair = [1, 2, 3]\n");
        let read = Session::parse(&short, Path::new("")).unwrap();
        assert_eq!(
            read.slices,
            Some(SliceViews {
                crosshair: [1, 2, 3],
                window: SliceWindow::Fitted,
                zoom: 1.0,
            })
        );
    }

    #[test]
    fn every_mode_camera_and_level_reads_back_equal() {
        for mode in Mode::ALL {
            let mut s = sample();
            s.settings.mode = mode;
            assert_eq!(round_trip(&s), s, "{mode:?}");
        }
        let mut s = sample();
        s.camera = SessionCamera::LookAt {
            position: Vec3::new(-50.0, 10.25, 70.0),
            target: Vec3::splat(24.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            projection: Projection::Orthographic { height: 80.0 },
        };
        s.level = LevelChoice::Fixed(2);
        s.settings.shading = None;
        s.settings.early_termination = Some(0.95);
        s.settings.clip = ClipRegion::default();
        s.source = VolumeSource::File {
            path: PathBuf::from("/data/lung1.vol"),
            access: Access::Mapped,
        };
        s.labels = Some(PathBuf::from("/data/lung1.labels.vol"));
        s.settings.segments = Some(label_scene());
        assert_eq!(round_trip(&s), s);
        s.settings.segments = None;
        if let SessionCamera::Orbit(mut o) = sample().camera {
            o.vfov_deg = None;
            let mut s = sample();
            s.camera = SessionCamera::Orbit(o);
            assert_eq!(round_trip(&s), s);
        }
        for importance in [
            ImportanceSource::Constant(0.5),
            ImportanceSource::Intensity(2.0),
            ImportanceSource::Gradient(3.0),
            ImportanceSource::Silhouette([1.0, 0.2, 0.8]),
        ] {
            let mut s = sample();
            s.settings.mode_parameters.importance = importance;
            assert_eq!(round_trip(&s), s, "{importance:?}");
        }
    }

    #[test]
    fn floats_keep_their_bits() {
        // Values whose shortest decimal form is fine, and arbitrary bit patterns.
        let mut x = 0x3f80_0001_u32;
        for _ in 0..20_000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let v = f32::from_bits(x);
            if !v.is_finite() {
                continue;
            }
            let back = num(v).parse::<f64>().unwrap() as f32;
            assert_eq!(back.to_bits(), v.to_bits(), "{v:?} written {}", num(v));
        }
        assert_eq!(num(0.5), "0.5");
        assert_eq!(num(0.1), "0.1");
    }

    /// A one-object label scene (its labels file `l.vol` beside `base`).
    fn label_scene() -> SegmentScene {
        SegmentScene::parse(
            "labels = \"l.vol\"\n[[object]]\nid = 1\nmode = \"dvr\"\ntf = \"shapes\"\n",
            Path::new("/data"),
        )
        .unwrap()
    }

    #[test]
    fn a_label_volume_without_a_label_scene_is_refused() {
        let mut s = sample();
        s.labels = Some(PathBuf::from("/data/v.labels.vol"));
        let refused = |s: &Session| {
            Session::parse(&s.to_toml().unwrap(), Path::new("/"))
                .unwrap_err()
                .to_string()
        };
        assert!(refused(&s).contains("there is no scene"), "{}", refused(&s));
        s.settings.segments = Some(SegmentScene {
            membership: Membership::Layers(vec![[0.05, 0.35], [0.35, 1.0]]),
            ..label_scene()
        });
        assert!(
            refused(&s).contains("value layers (`layers =`), not from a label volume"),
            "{}",
            refused(&s)
        );
        s.settings.segments = Some(label_scene());
        assert_eq!(s.labels_problem(), None);
        assert_eq!(round_trip(&s), s);
    }

    #[test]
    fn a_two_level_scene_is_embedded_and_reads_back_equal() {
        let mut s = sample();
        s.settings.segments = Some(SegmentScene {
            membership: Membership::Layers(vec![[0.05, 0.35], [0.35, 1.0]]),
            objects: vec![
                ObjectStyle {
                    name: "glass".into(),
                    id: 1,
                    visible: true,
                    transfer: TransferFunction::preset("cloud").unwrap(),
                    mode: LocalMode::Sabella {
                        output: SabellaOutput::default(),
                    },
                    clip: ClipRegion::default(),
                },
                ObjectStyle {
                    name: "solid \"core\"".into(),
                    id: 2,
                    visible: false,
                    transfer: TransferFunction::preset("opaque").unwrap(),
                    mode: LocalMode::FirstHit { iso: 0.4 },
                    clip: ClipRegion {
                        crop: Some(CropBox {
                            lo: Vec3::ZERO,
                            hi: Vec3::splat(20.0),
                        }),
                        planes: vec![],
                    },
                },
            ],
            global: GlobalMode::Mip,
        });
        let text = s.to_toml().unwrap();
        assert!(text.contains("[scene]"), "{text}");
        assert_eq!(round_trip(&s), s);
    }

    /// A label scene over a built-in scene uses the scene's own labels: the
    /// saved file says that its `labels` path is not read (it named a file
    /// that does not exist, unexplained), and reads back equal.
    #[test]
    fn a_label_scene_of_a_built_in_scene_says_its_labels_file_is_not_read() {
        let note = "is not read while `[volume]` names a built-in scene";
        let mut s = sample();
        assert!(matches!(s.source, VolumeSource::BuiltIn { .. }));
        s.settings.segments = Some(label_scene());
        let text = s.to_toml().unwrap();
        assert!(text.contains(note), "{text}");
        assert_eq!(round_trip(&s), s);
        // A label volume of the session's own is read: no note.
        s.labels = Some(PathBuf::from("/data/v.labels.vol"));
        assert!(!s.to_toml().unwrap().contains(note));
        // Nor over a file.
        s.labels = None;
        s.source = VolumeSource::File {
            path: PathBuf::from("/data/v.vol"),
            access: Access::Mapped,
        };
        assert!(!s.to_toml().unwrap().contains(note));
    }

    #[test]
    fn relative_paths_resolve_against_the_session_folder() {
        let mut s = sample();
        s.source = VolumeSource::File {
            path: PathBuf::from("data/v.vol"),
            access: Access::Mapped,
        };
        s.labels = Some(PathBuf::from("v.labels.vol"));
        s.settings.segments = Some(label_scene());
        let back = Session::parse(&s.to_toml().unwrap(), Path::new("/sessions")).unwrap();
        assert_eq!(
            back.source,
            VolumeSource::File {
                path: PathBuf::from("/sessions/data/v.vol"),
                access: Access::Mapped
            }
        );
        assert_eq!(back.labels, Some(PathBuf::from("/sessions/v.labels.vol")));
    }

    #[test]
    fn a_session_saved_in_another_folder_names_its_files_from_there() {
        let dir = tempfile::tempdir().unwrap();
        let root = std::fs::canonicalize(dir.path()).unwrap();
        std::fs::create_dir_all(root.join("data")).unwrap();
        std::fs::create_dir_all(root.join("s/deep")).unwrap();
        std::fs::write(root.join("data/v.vol"), b"x").unwrap();
        std::fs::write(root.join("data/v.labels.vol"), b"x").unwrap();
        // The paths as the process holds them: relative to its working folder.
        let cwd = std::env::current_dir().unwrap();
        let up: PathBuf = cwd.components().skip(1).map(|_| "..").collect();
        let held = |p: &str| up.join(root.strip_prefix("/").unwrap()).join(p);
        let mut s = sample();
        s.source = VolumeSource::File {
            path: held("data/v.vol"),
            access: Access::Mapped,
        };
        s.labels = Some(held("data/v.labels.vol"));
        let mut scene = label_scene();
        scene.membership = Membership::Labels(held("data/v.labels.vol"));
        s.settings.segments = Some(scene);
        let path = root.join("s/deep/view.toml");
        s.save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("file = \"../../data/v.vol\""), "{text}");
        assert!(
            text.contains("labels = \"../../data/v.labels.vol\""),
            "{text}"
        );
        let back = Session::load(&path).unwrap();
        let VolumeSource::File { path: read, .. } = &back.source else {
            panic!("a file")
        };
        let same = |a: &Path, b: &Path| {
            std::fs::canonicalize(a).unwrap() == std::fs::canonicalize(b).unwrap()
        };
        assert!(same(read, &root.join("data/v.vol")), "{}", read.display());
        assert!(same(
            back.labels.as_deref().unwrap(),
            &root.join("data/v.labels.vol")
        ));
    }

    #[test]
    fn saving_writes_a_file_that_loads_and_missing_volumes_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        let s = sample();
        s.save(&path).unwrap();
        assert_eq!(Session::load(&path).unwrap(), s);
        let mut f = sample();
        f.source = VolumeSource::File {
            path: PathBuf::from("missing.vol"),
            access: Access::Mapped,
        };
        f.save(&path).unwrap();
        let e = Session::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("volume.file") && e.contains("missing.vol"),
            "{e}"
        );
        let e = Session::load(&dir.path().join("none.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.toml"), "{e}");
        // A loop of links is said as one, not as a missing file.
        let (a, b) = (dir.path().join("a.vol"), dir.path().join("b.vol"));
        std::os::unix::fs::symlink(&b, &a).unwrap();
        std::os::unix::fs::symlink(&a, &b).unwrap();
        f.source = VolumeSource::File {
            path: a,
            access: Access::Mapped,
        };
        f.save(&path).unwrap();
        let e = Session::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("symbolic links") && !e.contains("no such"),
            "{e}"
        );
        let mut c = sample();
        c.settings.mode_parameters.sabella = SabellaOutput::Channels;
        assert!(c.save(&path).is_err(), "raw channels are refused");
    }

    /// The sample session with `line` (a `key = value` in `[table]`) replaced or
    /// added, parsed.
    fn with(table: &str, line: &str) -> Result<Session, SessionError> {
        let text = sample().to_toml().unwrap();
        let key = line.split('=').next().unwrap().trim();
        let mut out = String::new();
        let mut current = String::new();
        let mut done = false;
        let mut skipping = false;
        for l in text.lines() {
            if skipping {
                // The rest of a multi-line value that was replaced.
                skipping = l != "]";
                continue;
            }
            if l.starts_with('[') {
                if current == table && !done {
                    out += line;
                    out += "\n";
                    done = true;
                }
                current = l[1..l.find(']').unwrap()].to_string();
            } else if current == table && l.split('=').next().unwrap().trim() == key {
                out += line;
                out += "\n";
                done = true;
                skipping = l.ends_with('[');
                continue;
            }
            out += l;
            out += "\n";
        }
        if !done {
            out += &format!("[{table}]\n{line}\n");
        }
        Session::parse(&out, Path::new(""))
    }

    /// A look-at camera that looks nowhere, or up its own view, is said by
    /// field (before: "view direction and up vector must be finite …").
    #[test]
    fn an_impossible_look_at_camera_is_refused_by_field() {
        let mut s = sample();
        s.camera = SessionCamera::LookAt {
            position: Vec3::new(0.0, 0.0, 100.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            projection: Projection::Perspective { vfov_deg: 40.0 },
        };
        let text = s.to_toml().unwrap();
        assert!(round_trip(&s) == s);
        for (from, to, field) in [
            (
                "position = [0.0, 0.0, 100.0]",
                "position = [0.0, 0.0, 0.0]",
                "camera.position",
            ),
            ("up = [0.0, 1.0, 0.0]", "up = [0.0, 0.0, -3.0]", "camera.up"),
            ("up = [0.0, 1.0, 0.0]", "up = [0.0, 0.0, 0.0]", "camera.up"),
        ] {
            assert!(text.contains(from), "{from}: {text}");
            match Session::parse(&text.replace(from, to), Path::new("")) {
                Err(SessionError::Invalid { field: f, what }) => assert_eq!(f, field, "{what}"),
                other => panic!("{to}: {other:?}"),
            }
        }
    }

    #[test]
    fn bad_fields_are_refused_by_name() {
        for (table, line, field) in [
            ("render", "step = nan", "render.step"),
            ("render", "step = -0.5", "render.step"),
            ("render", "mode = \"dvrr\"", "render.mode"),
            ("render", "iso = 1.5", "render.iso"),
            ("render", "xray_gain = 0.0", "render.xray_gain"),
            ("render", "ert_threshold = 1.5", "render.ert_threshold"),
            ("render", "sabella_depth = \"deep\"", "render.sabella_depth"),
            (
                "render",
                "background = [0.0, 2.0, 0.0]",
                "render.background",
            ),
            ("render", "level = \"coarse\"", "render.level"),
            ("render", "importance = \"random\"", "render.importance"),
            ("camera", "distance = -3.0", "camera.distance"),
            ("camera", "distance = 1e30", "camera.distance"),
            ("camera", "fov = 180.0", "camera.fov"),
            ("camera", "azimuth_rad = inf", "camera.azimuth_rad"),
            ("camera", "elevation_rad = 2.0", "camera.elevation_rad"),
            ("image", "width = 0", "image.width"),
            ("volume", "scene = \"teapot\"", "volume.scene"),
            ("volume", "size = 1", "volume.size"),
            ("volume", "file = \"a.vol\"", "volume"),
            ("transfer", "domain = [5.0, 1.0]", "transfer.domain"),
            ("render", "step = 1e300", "render.step"),
            ("camera", "target = [1.0, 2.0, -1e300]", "camera.target"),
            ("transfer", "points = []", "transfer.points"),
            (
                "transfer",
                "points = [[0.5, 1.0, 1.0, 1.0, 2.0]]",
                "transfer.points",
            ),
            ("shading", "light = [0.0, 0.0, 0.0]", "shading.light"),
            ("shading", "light = [1e-30, 0.0, 0.0]", "shading.light"),
            ("shading", "ambient = -1.0", "shading.ambient"),
            ("shading", "diffuse = 1e39", "shading.diffuse"),
            ("shading", "ambient = 1e30", "shading.ambient"),
            ("shading", "specular = 100.5", "shading.specular"),
            ("clip", "planes = [[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]]", "clip"),
            ("clip", "crop = [5.0, 0.0, 0.0, 1.0, 9.0, 9.0]", "clip"),
            ("slices", "window = \"liver\"", "slices.window"),
            ("slices", "window = [300.0, 200.0]", "slices.window"),
            ("slices", "zoom = 0.5", "slices.zoom"),
            ("slices", "zoom = nan", "slices.zoom"),
        ] {
            match with(table, line) {
                Err(SessionError::Invalid { field: f, what }) => {
                    assert_eq!(f, field, "{line}: {what}");
                }
                other => panic!("{table}: {line}: {other:?}"),
            }
        }
        // A number beyond an f32 is said as written (it was "inf"); one too
        // small for it reads as 0, as on the command line.
        let e = with("render", "step = 1e300").unwrap_err().to_string();
        assert!(e.contains("1e300 is too large"), "{e}");
        let e = with("render", "step = 1e-300").unwrap_err().to_string();
        assert!(e.contains("render.step") && e.contains("0 must be"), "{e}");
        for (table, line, word) in [
            ("render", "stpe = 0.5", "stpe"),
            ("render", "step = \"fine\"", "step"),
            ("camera", "target = [1.0, 2.0]", "target"),
        ] {
            let e = with(table, line).unwrap_err();
            assert!(
                matches!(e, SessionError::Syntax(_)) && e.to_string().contains(word),
                "{line}: {e}"
            );
        }
        let e = Session::parse(
            &sample()
                .to_toml()
                .unwrap()
                .replace("version = 1", "version = 2"),
            Path::new(""),
        )
        .unwrap_err();
        assert!(e.to_string().contains("version"), "{e}");
        // The outline first: the version, then each missing table by name.
        for (text, said) in [
            ("", "`version`: missing: write `version = 1`"),
            ("version = 2\n", "version 2 is not known"),
            ("version = 1\n", "the [volume] table is missing"),
        ] {
            let e = Session::parse(text, Path::new("")).unwrap_err().to_string();
            assert!(e.contains(said), "{text:?}: {e}");
        }
        let without_transfer = sample().to_toml().unwrap();
        let start = without_transfer.find("[transfer]").unwrap();
        let end = without_transfer[start + 1..]
            .find("\n[")
            .map_or(without_transfer.len(), |i| start + 1 + i);
        let without_transfer =
            format!("{}{}", &without_transfer[..start], &without_transfer[end..]);
        let e = Session::parse(&without_transfer, Path::new(""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`transfer`: the [transfer] table is missing (every session has"),
            "{e}"
        );
        assert_eq!(e.lines().count(), 1, "one line: {e}");
        let e = Session::parse(
            &format!(
                "{}\n[scene]\nglobal = \"sideways\"\nlayers = [[0.0, 1.0]]\n",
                sample().to_toml().unwrap()
            ),
            Path::new(""),
        )
        .unwrap_err();
        assert!(
            matches!(e, SessionError::Scene(_)) && e.to_string().contains("sideways"),
            "{e}"
        );
    }

    #[test]
    fn a_label_scene_takes_the_sessions_label_volume_and_scene_errors_name_keys_not_lines() {
        let head = "version = 1\n[volume]\nscene = \"shells\"\nsize = 32\nlabels = \"l.vol\"\n\
                    [image]\nwidth = 8\nheight = 8\n[camera]\ntarget = [15.5, 15.5, 15.5]\n\
                    distance = 90.0\nazimuth_rad = 0.0\nelevation_rad = 0.0\nfov = 40.0\n\
                    [transfer]\npreset = \"shells\"\n";
        let scene = "[scene]\nglobal = \"dvr\"\n[[scene.object]]\nid = 1\ntf = \"shells\"\n";
        // (It was refused: "give either labels or layers".)
        let s = Session::parse(&format!("{head}{scene}"), Path::new("/data")).unwrap();
        assert_eq!(
            s.settings.segments.unwrap().membership,
            Membership::Labels(PathBuf::from("/data/l.vol"))
        );
        // A scene's own label volume stays its own.
        let own = scene.replace(
            "[[scene.object]]",
            "labels = \"other.vol\"\n[[scene.object]]",
        );
        let s = Session::parse(&format!("{head}{own}"), Path::new("/data")).unwrap();
        assert_eq!(
            s.settings.segments.unwrap().membership,
            Membership::Labels(PathBuf::from("/data/other.vol"))
        );
        // A bad key far down the file: named, without the line of a rebuilt
        // table (it said "line 5").
        let padding = "# a comment\n".repeat(30);
        let bad = format!("{head}{padding}{scene}colour = 3\n");
        let e = Session::parse(&bad, Path::new("/data"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour") && !e.contains("line"), "{e}");
        // A value of the wrong type is quoted with its key.
        let bad = format!("{head}{padding}{}", scene.replace("id = 1", "id = 300"));
        let e = Session::parse(&bad, Path::new("/data"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`id = 300`") && !e.contains("line"), "{e}");
    }

    #[test]
    fn a_level_number_keeps_a_neutral_lod_bias_and_refuses_another() {
        for (bias, read) in [(0.0f32, true), (0.5, false)] {
            let mut s = sample();
            s.level = LevelChoice::Auto { bias };
            let text = s.to_toml().unwrap();
            assert!(text.contains("level = \"auto\""), "{text}");
            // The user edits the level to a number.
            let edited = text.replace("level = \"auto\"", "level = 1");
            match Session::parse(&edited, Path::new("")) {
                Ok(back) => {
                    assert!(read, "bias {bias}");
                    assert_eq!(back.level, LevelChoice::Fixed(1));
                }
                Err(e) => {
                    assert!(!read, "bias {bias}: {e}");
                    assert!(e.to_string().contains("render.lod_bias"), "{e}");
                }
            }
        }
    }

    #[test]
    fn a_hand_written_session_takes_a_preset_and_defaults() {
        let s = Session::parse(
            "version = 1\n[volume]\nscene = \"shells\"\nsize = 32\n[image]\nwidth = 8\nheight = 8\n\
             [camera]\ntarget = [15.5, 15.5, 15.5]\ndistance = 90.0\nazimuth_rad = 0.0\n\
             elevation_rad = 0.0\nfov = 40.0\n[transfer]\npreset = \"shells\"\n",
            Path::new(""),
        )
        .unwrap();
        assert_eq!(
            s.settings.transfer,
            TransferFunction::preset("shells").unwrap()
        );
        let d = RenderSettings::default();
        assert_eq!(s.settings.mode, Mode::Dvr);
        assert_eq!(s.settings.step, d.step);
        assert_eq!(s.settings.shading, d.shading);
        assert_eq!(s.settings.early_termination, d.early_termination);
        assert_eq!(s.level, LevelChoice::default());
        let e = Session::parse(
            "version = 1\n[volume]\nscene = \"shells\"\nsize = 32\n[image]\nwidth = 8\nheight = 8\n\
             [camera]\ntarget = [15.5, 15.5, 15.5]\ndistance = 90.0\nazimuth_rad = 0.0\n\
             elevation_rad = 0.0\nfov = 40.0\n[transfer]\npreset = \"shels\"\n",
            Path::new(""),
        )
        .unwrap_err();
        assert!(e.to_string().contains("transfer.preset"), "{e}");
    }
}
