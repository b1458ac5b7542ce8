//! Segmented volumes for two-level rendering (Hauser et al. 2001): which object
//! each sample belongs to, and how each object is rendered.
//!
//! Objects come from a label volume (u8 ids, nearest-neighbour lookup, never
//! interpolated across ids) or from value layers (intervals of the normalised
//! value; layer `i` is object `i + 1`). Each object has its own transfer function
//! and local compositing mode; segment results are composited globally. Scenes are
//! read from a small TOML description ([`SegmentScene::parse`]).

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use super::clip::{ClipPlane, ClipRegion, CropBox};
use super::error::RenderError;
use super::sabella::{SabellaDepth, SabellaMapping, SabellaOutput};
use super::transfer::{
    ControlPoint, TransferError, TransferFunction, check_domain, check_gradient_ramp,
};

/// How the samples of one segment are combined.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LocalMode {
    /// Emission–absorption, shaded.
    Dvr,
    /// Maximum value of the segment, classified by the transfer function.
    Mip,
    /// Mean value of the segment, classified.
    Average,
    /// Sum of normalised values × step: opacity `1 − exp(−gain·Σ)`.
    XRay {
        /// Scale of the sum; `None`: [`super::auto_xray_gain`] of the volume
        /// rendered, as the plain X-ray mode's.
        gain: Option<f32>,
    },
    /// First sample at or above the iso-value (normalised), shaded, opaque.
    FirstHit {
        /// Iso-value over the object's transfer-function domain.
        iso: f32,
    },
    /// Importance-aware compositing (de Moura Pinto & Freitas).
    Importance {
        /// Where a sample's importance comes from.
        source: ImportanceSource,
    },
    /// Context-preserving rendering (Bruckner et al.).
    ContextPreserving {
        /// κt: depth of the virtual clip.
        kt: f32,
        /// κs: sharpness of the transition.
        ks: f32,
    },
    /// Non-photorealistic: tone shading and silhouette darkening.
    Silhouette,
    /// Sabella's colouring: peak value, its depth or the centroid, and
    /// intensity as hue, saturation and value.
    Sabella {
        /// Colours by a mapping, or the raw channels.
        output: SabellaOutput,
    },
}

impl LocalMode {
    /// The mode's name in scene descriptions.
    pub fn name(self) -> &'static str {
        match self {
            LocalMode::Dvr => "dvr",
            LocalMode::Mip => "mip",
            LocalMode::Average => "average",
            LocalMode::XRay { .. } => "xray",
            LocalMode::FirstHit { .. } => "first-hit",
            LocalMode::Importance { .. } => "importance",
            LocalMode::ContextPreserving { .. } => "context",
            LocalMode::Silhouette => "silhouette",
            LocalMode::Sabella { .. } => "sabella",
        }
    }

    /// Whether transparent samples contribute nothing (so empty space can be
    /// skipped without changing the segment's result).
    pub fn is_emission_absorption(self) -> bool {
        matches!(self, LocalMode::Dvr)
    }
}

/// Importance of a sample for importance-aware compositing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ImportanceSource {
    /// A constant per object.
    Constant(f32),
    /// The normalised value, times a weight.
    Intensity(f32),
    /// The gradient magnitude, times a weight.
    Gradient(f32),
    /// `|g|^p1 · smoothstep(p2, p3, 1 − |V·N|)`.
    Silhouette([f32; 3]),
    /// `3 − (N·H)^p1 − (N·L)^p2 − (1 − |g|)^p3`.
    Lighting([f32; 3]),
}

/// How segment results are combined along a ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlobalMode {
    /// Front-to-back emission–absorption of the segments.
    Dvr,
    /// The most opaque segment.
    Mip,
}

/// Where object ids come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Membership {
    /// A label volume (`.vol` with u8 labels, same dimensions as the data).
    Labels(PathBuf),
    /// Intervals `[lo, hi)` of the value normalised over the data's domain; the
    /// last interval includes its upper end.
    Layers(Vec<[f32; 2]>),
}

/// One object's appearance.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectStyle {
    /// Name for people.
    pub name: String,
    /// Object id (label value; layer index + 1).
    pub id: u8,
    /// Hidden objects are clipped away.
    pub visible: bool,
    /// Transfer function (1D, or 2D with a gradient ramp).
    pub transfer: TransferFunction,
    /// Local compositing.
    pub mode: LocalMode,
    /// The part of the volume where the object shows (level-0 voxel
    /// coordinates; everything by default): its samples outside belong to no
    /// object.
    pub clip: ClipRegion,
}

/// A segmented scene: membership, objects, global compositing.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentScene {
    /// Where object ids come from.
    pub membership: Membership,
    /// The objects; ids without a style are transparent.
    pub objects: Vec<ObjectStyle>,
    /// Global compositing.
    pub global: GlobalMode,
}

/// What is wrong with a scene description.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file cannot be read.
    #[error("cannot read scene {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// TOML syntax or an unknown/mistyped field.
    #[error("scene description: {0}")]
    Syntax(String),
    /// A value out of range or inconsistent.
    #[error("scene description: {0}")]
    Invalid(String),
    /// What is wrong in a scene file ([`SegmentScene::load`]).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong in it.
        source: Box<SceneError>,
    },
    /// An object's transfer function.
    #[error("scene description: object {object:?}: {source}")]
    Transfer {
        /// The object's name.
        object: String,
        /// The error.
        source: TransferError,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    global: Option<String>,
    #[serde(default)]
    labels: Option<PathBuf>,
    /// Read as lists of any length, so `[0.1, 0.5, 0.9]` is refused, not cut to two.
    #[serde(default)]
    layers: Option<Vec<Vec<f32>>>,
    #[serde(default, rename = "object")]
    objects: Vec<ObjectFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectFile {
    name: Option<String>,
    id: Option<u8>,
    #[serde(default = "yes")]
    visible: bool,
    tf: Option<TransferSpec>,
    #[serde(default = "dvr")]
    mode: String,
    iso: Option<f32>,
    gain: Option<f32>,
    kt: Option<f32>,
    ks: Option<f32>,
    importance: Option<String>,
    weight: Option<f32>,
    p: Option<[f32; 3]>,
    depth: Option<String>,
    /// `[x0, y0, z0, x1, y1, z1]` in voxels.
    crop: Option<[f32; 6]>,
    /// `[[px, py, pz, nx, ny, nz], ...]` in voxels.
    #[serde(default)]
    clip: Vec<[f32; 6]>,
}

/// An object's transfer function: a preset name or file, or written inline.
enum TransferSpec {
    Named(String),
    Inline(InlineTransfer),
}

/// What `tf` takes, said where it holds something else.
const TF_FORMS: &str = "`tf` is a preset name or file path (a string) or an inline table `{ points = [[value, r, g, b, alpha], ...] }`";

// (By hand, not `untagged`: an inline table's own error, such as a point of
// four numbers, was swallowed into the generic one.)
impl<'de> Deserialize<'de> for TransferSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            toml::Value::String(name) => Ok(TransferSpec::Named(name)),
            table @ toml::Value::Table(_) => table
                .try_into::<InlineTransfer>()
                .map(TransferSpec::Inline)
                .map_err(|e| D::Error::custom(format!("`tf` inline table: {}", e.message()))),
            other => Err(D::Error::custom(format!(
                "{TF_FORMS}, not a {}",
                other.type_str()
            ))),
        }
    }
}

/// `tf = { points = [[value, r, g, b, alpha], ...], domain = [lo, hi], gradient = [g0, g1] }`
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InlineTransfer {
    points: Vec<[f32; 5]>,
    domain: Option<[f32; 2]>,
    gradient: Option<[f32; 2]>,
}

impl InlineTransfer {
    fn build(&self) -> Result<TransferFunction, TransferError> {
        let mut tf = TransferFunction::new(
            self.points
                .iter()
                .map(|&[value, r, g, b, alpha]| ControlPoint {
                    value,
                    color: [r, g, b],
                    alpha,
                })
                .collect(),
        )?;
        if let Some(d) = self.domain {
            check_domain(d).map_err(|what| TransferError::Invalid { line: 0, what })?;
        }
        if let Some(g) = self.gradient {
            check_gradient_ramp(g).map_err(|what| TransferError::Invalid { line: 0, what })?;
        }
        tf.domain = self.domain;
        tf.gradient_ramp = self.gradient;
        Ok(tf)
    }
}

fn yes() -> bool {
    true
}

fn dvr() -> String {
    "dvr".into()
}

impl SegmentScene {
    /// Reads a scene file; relative paths (labels, transfer-function files) are
    /// relative to the file's directory.
    pub fn load(path: &Path) -> Result<SegmentScene, SceneError> {
        let text = crate::files::read_text(path, super::transfer::TEXT_MAX).map_err(|source| {
            SceneError::Io {
                path: path.to_path_buf(),
                source,
            }
        })?;
        SegmentScene::parse(&text, path.parent().unwrap_or(Path::new("."))).map_err(|e| {
            SceneError::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            }
        })
    }

    /// Parses a scene description:
    ///
    /// ```toml
    /// global = "dvr"                        # or "mip"
    /// layers = [[0.05, 0.35], [0.35, 1.0]]  # or: labels = "scene.labels.vol"
    ///
    /// [[object]]
    /// name = "glass"                        # object 1 (layer 0, or label 1)
    /// tf = "shapes"                         # preset or transfer-function file
    /// mode = "importance"                   # dvr mip average xray first-hit
    ///                                       # importance context silhouette
    /// importance = "silhouette"             # constant intensity gradient
    ///                                       # silhouette lighting
    /// p = [1.0, 0.2, 0.8]                   # parameters: iso gain kt ks weight p
    /// ```
    ///
    /// The whole format is described in `docs/segments.md`.
    pub fn parse(text: &str, base: &Path) -> Result<SegmentScene, SceneError> {
        let text = crate::text::without_bom(text);
        let file: SceneFile = toml::from_str(text)
            .map_err(|e| SceneError::Syntax(crate::text::toml_error(text, &e)))?;
        crate::text::toml_float_range(text)
            .map_err(|(key, what)| SceneError::Invalid(format!("`{key}`: {what}")))?;
        Self::from_file(file, base)
    }

    /// [`Self::parse`] of a scene already read as a TOML table (a session's
    /// `[scene]`): what is wrong in it is said by key, without a line (the
    /// table's lines are not the file's).
    pub fn from_table(table: toml::Table, base: &Path) -> Result<SegmentScene, SceneError> {
        let text = toml::to_string(&table).map_err(|e| SceneError::Syntax(e.to_string()))?;
        // Read from the table written again: an error's place in it quotes
        // the key (its line number would be this text's).
        let file: SceneFile = toml::from_str(&text)
            .map_err(|e| SceneError::Syntax(crate::text::toml_error_unnumbered(&text, &e)))?;
        Self::from_file(file, base)
    }

    /// The scene `file` describes, its relative paths joined to `base`.
    fn from_file(file: SceneFile, base: &Path) -> Result<SegmentScene, SceneError> {
        let membership = match (file.labels, file.layers) {
            (Some(labels), None) => {
                if labels.as_os_str().is_empty() {
                    return Err(SceneError::Invalid(
                        "`labels` is empty; name the label volume file".into(),
                    ));
                }
                Membership::Labels(base.join(labels))
            }
            (None, Some(layers)) => {
                let mut pairs = Vec::with_capacity(layers.len());
                for (i, layer) in layers.iter().enumerate() {
                    match layer[..] {
                        [lo, hi] => pairs.push([lo, hi]),
                        _ => {
                            return Err(SceneError::Invalid(format!(
                                "layer {i} has {} numbers; a layer is one interval [lo, hi]",
                                layer.len()
                            )));
                        }
                    }
                }
                let layers = pairs;
                check_layers(&layers).map_err(SceneError::Invalid)?;
                Membership::Layers(layers)
            }
            _ => {
                return Err(SceneError::Invalid(
                    "give either `labels = \"FILE\"` or `layers = [[lo, hi], ...]`".into(),
                ));
            }
        };
        let global = match file.global.as_deref().unwrap_or("dvr") {
            "dvr" => GlobalMode::Dvr,
            "mip" => GlobalMode::Mip,
            other => {
                return Err(SceneError::Invalid(format!(
                    "unknown global mode {other:?} (dvr, mip)"
                )));
            }
        };
        let mut objects = Vec::new();
        for (i, o) in file.objects.into_iter().enumerate() {
            let id = o.id.unwrap_or((i + 1) as u8);
            let name = o.name.clone().unwrap_or_else(|| format!("object {id}"));
            let transfer = match &o.tf {
                Some(TransferSpec::Inline(inline)) => inline.build(),
                // Anything at that path is read as a file (a named pipe is refused).
                Some(TransferSpec::Named(tf)) if TransferFunction::names_a_file(tf, base) => {
                    TransferFunction::load(&base.join(tf))
                }
                Some(TransferSpec::Named(tf)) => TransferFunction::preset(tf),
                None => TransferFunction::preset("shapes"),
            }
            .map_err(|source| SceneError::Transfer {
                object: name.clone(),
                source,
            })?;
            let mode =
                local_mode(&o).map_err(|e| SceneError::Invalid(format!("object {name:?}: {e}")))?;
            let clip = ClipRegion {
                crop: o.crop.map(|c| CropBox {
                    lo: Vec3::new(c[0], c[1], c[2]),
                    hi: Vec3::new(c[3], c[4], c[5]),
                }),
                planes: o
                    .clip
                    .iter()
                    .map(|p| ClipPlane {
                        point: Vec3::new(p[0], p[1], p[2]),
                        normal: Vec3::new(p[3], p[4], p[5]),
                    })
                    .collect(),
            };
            clip.validate()
                .map_err(|e| SceneError::Invalid(format!("object {name:?}: {e}")))?;
            if objects.iter().any(|s: &ObjectStyle| s.id == id) {
                return Err(SceneError::Invalid(format!(
                    "object id {id} is defined twice"
                )));
            }
            // A layer object's id is its layer's index + 1: another id can
            // never show (0 holds the values in no layer, transparent).
            if let Membership::Layers(layers) = &membership {
                check_layer_id(id, layers.len())
                    .map_err(|e| SceneError::Invalid(format!("object {name:?}: {e}")))?;
            }
            objects.push(ObjectStyle {
                name,
                id,
                visible: o.visible,
                transfer,
                mode,
                clip,
            });
        }
        let scene = SegmentScene {
            membership,
            objects,
            global,
        };
        // (Each value was checked as it was read; the renderers' check of
        // the whole scene says what a rule of theirs alone refuses.)
        scene
            .check()
            .map_err(|e| SceneError::Invalid(e.to_string()))?;
        Ok(scene)
    }

    /// Checks each object's crop box and planes against the box a volume
    /// samples (`sampled`, at a level `scale` times level 0's voxels, as
    /// [`ClipRegion::check_overlaps`] takes them): an object cut away whole
    /// (its crop beside the volume) is an error naming it, as the frame's own
    /// cut is.
    pub fn check_cuts(&self, sampled: [[f32; 3]; 2], scale: f32) -> Result<(), RenderError> {
        for o in &self.objects {
            let checked = o
                .clip
                .validate()
                .and_then(|()| o.clip.check_overlaps(sampled, scale));
            if let Err(e) = checked {
                return Err(RenderError::ObjectClip {
                    object: o.name.clone(),
                    source: Box::new(e),
                });
            }
        }
        Ok(())
    }

    /// The scene with its label volume's path (held relative to the working
    /// directory) as a file in folder `dir` names it
    /// ([`crate::files::path_for_file_in`]): what a scene saved there writes.
    pub fn with_paths_for(&self, dir: &Path) -> SegmentScene {
        let mut scene = self.clone();
        if let Membership::Labels(path) = &mut scene.membership {
            *path = crate::files::path_for_file_in(dir, path);
        }
        scene
    }

    /// The scene as a description [`SegmentScene::parse`] reads back to an equal
    /// scene: transfer functions are written inline, a label path as given.
    pub fn to_toml(&self) -> String {
        use std::fmt::Write;
        let quote = |s: &str| toml::Value::String(s.to_owned()).to_string();
        let pair = |[a, b]: [f32; 2]| format!("[{a:?}, {b:?}]");
        let mut out = String::from("# raycaster two-level scene (docs/segments.md)\n");
        let global = match self.global {
            GlobalMode::Dvr => "dvr",
            GlobalMode::Mip => "mip",
        };
        let _ = writeln!(out, "global = {}", quote(global));
        match &self.membership {
            Membership::Labels(path) => {
                let _ = writeln!(out, "labels = {}", quote(&path.to_string_lossy()));
            }
            Membership::Layers(layers) => {
                let list: Vec<String> = layers.iter().map(|&l| pair(l)).collect();
                let _ = writeln!(out, "layers = [{}]", list.join(", "));
            }
        }
        for o in &self.objects {
            let _ = writeln!(out, "\n[[object]]");
            let _ = writeln!(out, "name = {}", quote(&o.name));
            let _ = writeln!(out, "id = {}", o.id);
            let _ = writeln!(out, "visible = {}", o.visible);
            let points: Vec<String> = o
                .transfer
                .points()
                .iter()
                .map(|p| {
                    let [r, g, b] = p.color;
                    format!("[{:?}, {r:?}, {g:?}, {b:?}, {:?}]", p.value, p.alpha)
                })
                .collect();
            let mut tf = format!("tf = {{ points = [{}]", points.join(", "));
            if let Some(d) = o.transfer.domain {
                let _ = write!(tf, ", domain = {}", pair(d));
            }
            if let Some(g) = o.transfer.gradient_ramp {
                let _ = write!(tf, ", gradient = {}", pair(g));
            }
            let _ = writeln!(out, "{tf} }}");
            let _ = writeln!(out, "mode = {}", quote(o.mode.name()));
            match o.mode {
                LocalMode::XRay { gain: Some(gain) } => {
                    let _ = writeln!(out, "gain = {gain:?}");
                }
                LocalMode::FirstHit { iso } => {
                    let _ = writeln!(out, "iso = {iso:?}");
                }
                LocalMode::ContextPreserving { kt, ks } => {
                    let _ = writeln!(out, "kt = {kt:?}\nks = {ks:?}");
                }
                LocalMode::Importance { source } => {
                    let (name, weight, p) = match source {
                        ImportanceSource::Constant(w) => ("constant", Some(w), None),
                        ImportanceSource::Intensity(w) => ("intensity", Some(w), None),
                        ImportanceSource::Gradient(w) => ("gradient", Some(w), None),
                        ImportanceSource::Silhouette(p) => ("silhouette", None, Some(p)),
                        ImportanceSource::Lighting(p) => ("lighting", None, Some(p)),
                    };
                    let _ = writeln!(out, "importance = {}", quote(name));
                    if let Some(w) = weight {
                        let _ = writeln!(out, "weight = {w:?}");
                    }
                    if let Some([a, b, c]) = p {
                        let _ = writeln!(out, "p = [{a:?}, {b:?}, {c:?}]");
                    }
                }
                LocalMode::Sabella {
                    output: SabellaOutput::Colours(mapping),
                } => {
                    let _ = writeln!(out, "depth = {}", quote(mapping.depth.name()));
                }
                // (No gain: the automatic one.)
                LocalMode::XRay { gain: None }
                | LocalMode::Dvr
                | LocalMode::Mip
                | LocalMode::Average
                | LocalMode::Silhouette
                | LocalMode::Sabella { .. } => {}
            }
            let six = |v: [f32; 6]| {
                let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
                format!("[{}]", items.join(", "))
            };
            if let Some(CropBox { lo, hi }) = o.clip.crop {
                let _ = writeln!(out, "crop = {}", six([lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]));
            }
            if !o.clip.planes.is_empty() {
                let planes: Vec<String> = o
                    .clip
                    .planes
                    .iter()
                    .map(|p| {
                        let (q, n) = (p.point, p.normal);
                        six([q.x, q.y, q.z, n.x, n.y, n.z])
                    })
                    .collect();
                let _ = writeln!(out, "clip = [{}]", planes.join(", "));
            }
        }
        out
    }

    /// What makes the scene show nothing, or less than it names, with its
    /// label volume `labels` (`None` for value layers): no visible object, or
    /// an object whose id no voxel of the labels holds (above their largest).
    /// One line each, for people.
    pub fn warnings(&self, labels: Option<&crate::volume::Volume>) -> Vec<String> {
        let visible: Vec<&ObjectStyle> = self.objects.iter().filter(|o| o.visible).collect();
        if visible.is_empty() {
            let what = if self.objects.is_empty() {
                "no [[object]]"
            } else {
                "no visible [[object]]"
            };
            return vec![format!(
                "the scene has {what}: nothing shows (an object gives an id its transfer function and mode)"
            )];
        }
        let Some(labels) = labels else {
            return Vec::new();
        };
        let largest = labels
            .ranges()
            .as_slice()
            .iter()
            .map(|r| r[1])
            .max()
            .unwrap_or(0);
        visible
            .iter()
            .filter(|o| u16::from(o.id) > largest)
            .map(|o| {
                format!(
                    "object {:?} (id {}) shows nothing: the ids of {} go up to {largest}",
                    o.name,
                    o.id,
                    labels.path().display()
                )
            })
            .collect()
    }

    /// The style of object `id`, if any.
    pub fn object(&self, id: u8) -> Option<&ObjectStyle> {
        self.objects.iter().find(|o| o.id == id)
    }
}

/// Checks a scene's layers: at least one, at most 255, each an increasing
/// interval inside `[0, 1]`.
pub(crate) fn check_layers(layers: &[[f32; 2]]) -> Result<(), String> {
    if layers.is_empty() {
        return Err("`layers` is empty; give at least one [lo, hi] interval".into());
    }
    for (i, [lo, hi]) in layers.iter().enumerate() {
        if !(0.0..=1.0).contains(lo) || !(0.0..=1.0).contains(hi) || lo >= hi {
            return Err(format!(
                "layer {i} [{lo}, {hi}] must be an increasing interval inside [0, 1]"
            ));
        }
    }
    if layers.len() > 255 {
        return Err("at most 255 layers".into());
    }
    Ok(())
}

/// Checks a layer object's id against the scene's `n` layers: a layer
/// object's id is its layer's index + 1 (another id can never show; 0 holds
/// the values in no layer, transparent).
pub(crate) fn check_layer_id(id: u8, n: usize) -> Result<(), String> {
    if (1..=n).contains(&usize::from(id)) {
        return Ok(());
    }
    let ids = if n == 1 {
        "id 1".to_string()
    } else {
        format!("ids 1 to {n}")
    };
    let layer_s = if n == 1 { "layer" } else { "layers" };
    Err(format!(
        "id {id} names no layer: the scene has {n} {layer_s} ({ids}; layer i is object i + 1)"
    ))
}

fn local_mode(o: &ObjectFile) -> Result<LocalMode, String> {
    let unit = |name: &str, v: Option<f32>, default: f32| {
        let v = v.unwrap_or(default);
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(format!("{name} = {v} must be a non-negative finite number"))
        }
    };
    // A parameter of another mode is a mistake (a mode changed, its
    // parameter left): said, not ignored.
    let given = [
        ("gain", o.gain.is_some(), "xray"),
        ("iso", o.iso.is_some(), "first-hit"),
        ("kt", o.kt.is_some(), "context"),
        ("ks", o.ks.is_some(), "context"),
        ("depth", o.depth.is_some(), "sabella"),
        ("weight", o.weight.is_some(), "importance"),
        ("importance", o.importance.is_some(), "importance"),
        ("p", o.p.is_some(), "importance"),
    ];
    let known = given.iter().any(|(_, _, m)| *m == o.mode)
        || ["dvr", "mip", "average", "silhouette"].contains(&o.mode.as_str());
    if let Some((name, _, mode)) = given
        .iter()
        .find(|(_, set, mode)| known && *set && *mode != o.mode)
    {
        return Err(format!(
            "`{name}` applies to mode {mode:?}; this object's mode is {:?}",
            o.mode
        ));
    }
    Ok(match o.mode.as_str() {
        "dvr" => LocalMode::Dvr,
        "mip" => LocalMode::Mip,
        "average" => LocalMode::Average,
        "xray" => LocalMode::XRay {
            gain: o.gain.map(|g| unit("gain", Some(g), g)).transpose()?,
        },
        "first-hit" => {
            let iso = unit("iso", o.iso, 0.5)?;
            if iso > 1.0 {
                return Err(format!("iso = {iso} must lie in [0, 1]"));
            }
            LocalMode::FirstHit { iso }
        }
        "context" => LocalMode::ContextPreserving {
            kt: unit("kt", o.kt, 1.5)?,
            ks: unit("ks", o.ks, 0.4)?,
        },
        "silhouette" => LocalMode::Silhouette,
        "sabella" => {
            let name = o.depth.as_deref().unwrap_or("peak");
            let depth = SabellaDepth::parse(name)
                .ok_or_else(|| format!("unknown depth {name:?} (peak, centroid)"))?;
            LocalMode::Sabella {
                output: SabellaOutput::Colours(SabellaMapping {
                    depth,
                    ..SabellaMapping::default()
                }),
            }
        }
        "importance" => {
            let w = unit("weight", o.weight, 1.0)?;
            let p = o.p.unwrap_or([1.0, 0.3, 0.9]);
            if let Some(bad) = p.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                return Err(format!(
                    "p = [{}, {}, {}]: {bad} is not a non-negative finite number",
                    p[0], p[1], p[2]
                ));
            }
            // Each source takes `weight` or `p`, not both: the other is a
            // leftover of an edit, said as the mode's parameters are.
            let name = o.importance.as_deref().unwrap_or("constant");
            let takes_p = matches!(name, "silhouette" | "lighting");
            let known = takes_p || matches!(name, "constant" | "intensity" | "gradient");
            if known && takes_p && o.weight.is_some() {
                return Err(format!(
                    "`weight` applies to importance constant, intensity or gradient; this object's importance is {name:?} (it takes `p`)"
                ));
            }
            if known && !takes_p && o.p.is_some() {
                return Err(format!(
                    "`p` applies to importance silhouette or lighting; this object's importance is {name:?} (it takes `weight`)"
                ));
            }
            let source = match name {
                "constant" => ImportanceSource::Constant(w),
                "intensity" => ImportanceSource::Intensity(w),
                "gradient" => ImportanceSource::Gradient(w),
                "silhouette" => ImportanceSource::Silhouette(p),
                "lighting" => ImportanceSource::Lighting(p),
                other => {
                    return Err(format!(
                        "unknown importance {other:?} (constant, intensity, gradient, silhouette, lighting)"
                    ));
                }
            };
            LocalMode::Importance { source }
        }
        other => {
            return Err(format!(
                "unknown mode {other:?} (dvr, mip, average, xray, first-hit, importance, context, silhouette, sabella)"
            ));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_number_beyond_an_f32_is_said_too_large_by_its_key() {
        for (text, key) in [
            ("layers = [[0.0, 1e300]]\n[[object]]\n", "`layers`"),
            (
                "layers = [[0.0, 1.0]]\n[[object]]\nmode = \"importance\"\nweight = 1e300\n",
                "`object.weight`",
            ),
        ] {
            let e = SegmentScene::parse(text, Path::new(""))
                .unwrap_err()
                .to_string();
            assert!(e.contains(key) && e.contains("1e300 is too large"), "{e}");
        }
    }

    #[test]
    fn a_parameter_of_another_importance_source_is_named() {
        let scene = |object: &str| {
            SegmentScene::parse(
                &format!("layers = [[0, 1]]\n[[object]]\nmode = \"importance\"\n{object}\n"),
                Path::new(""),
            )
        };
        let e = scene("p = [1, 2, 3]").unwrap_err().to_string();
        assert!(
            e.contains("`p` applies to importance silhouette or lighting; this object's importance is \"constant\""),
            "{e}"
        );
        let e = scene("importance = \"lighting\"\nweight = 2")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`weight` applies to importance constant"), "{e}");
        scene("importance = \"lighting\"\np = [1, 2, 3]").unwrap();
        scene("importance = \"gradient\"\nweight = 2").unwrap();
    }

    #[test]
    fn a_parameter_of_another_mode_is_named() {
        let scene = |object: &str| {
            SegmentScene::parse(
                &format!("layers = [[0, 1]]\n[[object]]\n{object}\n"),
                Path::new(""),
            )
            .map(|_| ())
            .map_err(|e| e.to_string())
        };
        let e = scene("mode = \"dvr\"\ngain = 0.5").unwrap_err();
        assert!(
            e.contains("`gain` applies to mode \"xray\"; this object's mode is \"dvr\""),
            "{e}"
        );
        let e = scene("mode = \"first-hit\"\nkt = 2").unwrap_err();
        assert!(e.contains("`kt` applies to mode \"context\""), "{e}");
        // An unknown mode is named as that, whatever else is given.
        let e = scene("mode = \"dvrr\"\ngain = 0.5").unwrap_err();
        assert!(e.contains("unknown mode \"dvrr\""), "{e}");
        scene("mode = \"xray\"\ngain = 0.5").unwrap();
        scene("mode = \"importance\"\nimportance = \"silhouette\"\np = [1, 0.3, 0.9]").unwrap();
    }

    #[test]
    fn sabella_objects_and_object_regions_parse_and_read_back() {
        let text = r#"
            layers = [[0.0, 1.0]]
            [[object]]
            mode = "sabella"
            depth = "centroid"
            crop = [1, 2, 3, 10, 20, 30]
            clip = [[5, 5, 5, 0, 0, -1], [1, 1, 1, 1, 0, 0]]
        "#;
        let s = SegmentScene::parse(text, Path::new(".")).unwrap();
        let o = &s.objects[0];
        assert_eq!(
            o.mode,
            LocalMode::Sabella {
                output: SabellaOutput::Colours(SabellaMapping {
                    depth: SabellaDepth::Centroid,
                    ..SabellaMapping::default()
                })
            }
        );
        assert_eq!(o.clip.planes.len(), 2);
        assert_eq!(o.clip.crop.unwrap().hi, Vec3::new(10.0, 20.0, 30.0));
        assert_eq!(
            SegmentScene::parse(&s.to_toml(), Path::new(".")).unwrap(),
            s
        );
        let bad = text.replace("\"centroid\"", "\"middle\"");
        let e = SegmentScene::parse(&bad, Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("unknown depth \"middle\""), "{e}");
        let inverted = text.replace("[1, 2, 3, 10, 20, 30]", "[1, 2, 3, 10, 0, 30]");
        let e = SegmentScene::parse(&inverted, Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("inverted"), "{e}");
    }

    #[test]
    fn a_scene_parses_with_defaults_and_paths_relative_to_it() {
        let text = r#"
            global = "mip"
            layers = [[0.0, 0.4], [0.4, 1.0]]
            [[object]]
            name = "soft"
            tf = "cloud"
            mode = "context"
            kt = 2.0
            [[object]]
            mode = "importance"
            importance = "silhouette"
            visible = false
        "#;
        let s = SegmentScene::parse(text, Path::new("/data")).unwrap();
        assert_eq!(s.global, GlobalMode::Mip);
        assert_eq!(
            s.membership,
            Membership::Layers(vec![[0.0, 0.4], [0.4, 1.0]])
        );
        assert_eq!(
            s.objects[0].mode,
            LocalMode::ContextPreserving { kt: 2.0, ks: 0.4 }
        );
        assert_eq!(s.objects[1].id, 2);
        assert!(!s.objects[1].visible);
        let labels = SegmentScene::parse("labels = \"l.vol\"", Path::new("/data")).unwrap();
        assert_eq!(
            labels.membership,
            Membership::Labels(PathBuf::from("/data/l.vol"))
        );
    }

    #[test]
    fn a_written_scene_reads_back_equal() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes");
        let mut checked = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_none_or(|e| e != "toml") {
                continue;
            }
            let mut scene = SegmentScene::load(&path).unwrap();
            if let Some(o) = scene.objects.first_mut() {
                o.transfer.domain = Some([3.0, 250.0]);
                o.transfer.gradient_ramp = Some([0.01, 0.2]);
                o.name = "with \"quotes\"".into();
            }
            let text = scene.to_toml();
            let back = SegmentScene::parse(&text, Path::new("/elsewhere"))
                .unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display()));
            assert_eq!(back, scene, "{}", path.display());
            checked += 1;
        }
        assert!(checked >= 12);
    }

    #[test]
    fn mistakes_are_named() {
        let cases = [
            ("layers = [[0.5, 0.2]]", "increasing"),
            ("", "either"),
            ("layers = [[0, 1]]\ncolour = 1", "unknown field"),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"fancy\"",
                "unknown mode",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\ntf = \"nope\"",
                "unknown transfer function preset",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nid = 1\n[[object]]\nid = 1",
                "twice",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"first-hit\"\niso = 3",
                "iso",
            ),
            // Hostile values: NaN/Inf/negative parameters, bad domains, bad layers.
            ("layers = [[0.1, 0.5, 0.9]]", "3 numbers"),
            ("layers = []", "empty"),
            ("labels = \"\"", "empty"),
            ("labels = 5", "invalid type"),
            ("layers = [[nan, 0.5]]", "increasing"),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"importance\"\nimportance = \"lighting\"\np = [1.0, nan, 1.0]",
                "p = ",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"importance\"\nimportance = \"silhouette\"\np = [-1.0, 0.1, 1.0]",
                "p = ",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"xray\"\ngain = inf",
                "gain",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"context\"\nkt = -2",
                "kt",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\nmode = \"importance\"\nweight = nan",
                "weight",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], domain = [5, 5] }",
                "domain",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], domain = [9, 1] }",
                "domain",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], domain = [nan, 1] }",
                "domain",
            ),
            (
                "layers = [[0, 1]]\n[[object]]\ntf = { points = [[0, 1, 1, 1, 1]], gradient = [0.1, inf] }",
                "gradient",
            ),
        ];
        for (text, needle) in cases {
            let e = SegmentScene::parse(text, Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
    }
}
