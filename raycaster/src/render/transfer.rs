//! Transfer functions: control points → RGBA lookup tables, 2D (value × gradient
//! magnitude) tables, opacity correction and O(1) transparency queries.
//!
//! A [`TransferFunction`] is what a user edits: control points over the normalised
//! value range `[0, 1]` of a domain of raw sample values, optionally with a
//! gradient-magnitude opacity ramp that makes it two-dimensional. A
//! [`TransferTable`] is what the renderer uses for one frame: the function sampled
//! into a table, with opacities corrected for the frame's step (thesis:
//! `α = 1 − (1 − α0)^(s/s0)`) and a prefix sum over "opacity > 0" that answers
//! "is every value in `[lo, hi]` transparent?" with two reads.

use std::path::Path;
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::optics::{corrected_alpha, smoothstep};
use super::truncate::truncate_clamped;

/// Entries in a frame's 1D table.
pub const TABLE_SIZE: usize = 1024;
/// Gradient-magnitude bins of a 2D table.
pub const GRADIENT_BINS: usize = 64;
/// Gradient magnitude (normalised value per voxel) mapped to the last bin.
pub const GRADIENT_RANGE: f32 = 0.5;

/// One control point: at normalised value `value`, colour `color` and opacity
/// `alpha` per reference step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlPoint {
    /// Position in the domain, 0 = its low end, 1 = its high end.
    pub value: f32,
    /// Linear RGB in `[0, 1]`.
    pub color: [f32; 3],
    /// Opacity per reference step, `[0, 1]`.
    pub alpha: f32,
}

/// A transfer function: piecewise-linear colour and opacity over a value domain.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFunction {
    points: Vec<ControlPoint>,
    /// Raw sample values mapped to normalised 0 and 1; `None` = the sample type's
    /// whole range (0..255 or 0..65535).
    pub domain: Option<[f32; 2]>,
    /// Two-dimensional variant: opacity is multiplied by
    /// `smoothstep(g0, g1, |∇f|)`, with `|∇f|` in normalised value per voxel.
    pub gradient_ramp: Option<[f32; 2]>,
}

/// What is wrong with a transfer function (or its file).
#[derive(Debug, thiserror::Error)]
pub enum TransferError {
    /// Fewer than one control point.
    #[error("a transfer function needs at least one control point")]
    NoPoints,
    /// A number is out of range or not finite.
    #[error("{}{what}", line_prefix(*line))]
    Invalid {
        /// 1-based line number (0 for points given in code).
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// No preset has this name.
    #[error("unknown transfer function preset {0:?} ({hint}known: {known})", hint = did_you_mean(.0), known = preset_names())]
    UnknownPreset(String),
    /// The file cannot be read.
    #[error("cannot read transfer function file {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// What is wrong with the text of a file ([`TransferFunction::load`]).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong in it.
        source: Box<TransferError>,
    },
}

/// The largest transfer-function or scene file read, in bytes (1 MiB).
pub const TEXT_MAX: u64 = 1 << 20;

/// Checks a raw value domain: finite and strictly increasing.
pub fn check_domain([lo, hi]: [f32; 2]) -> Result<(), String> {
    if lo.is_finite() && hi.is_finite() && lo < hi {
        Ok(())
    } else {
        Err(format!(
            "domain [{lo}, {hi}] must be finite and increasing (lo < hi)"
        ))
    }
}

/// Checks a gradient ramp: finite, 0 ≤ g0 < g1.
pub fn check_gradient_ramp([g0, g1]: [f32; 2]) -> Result<(), String> {
    if g0.is_finite() && g1.is_finite() && g0 >= 0.0 && g0 < g1 {
        Ok(())
    } else {
        Err(format!(
            "gradient ramp [{g0}, {g1}] needs finite numbers with 0 ≤ g0 < g1"
        ))
    }
}

/// The named presets: (name, what it suits).
pub const PRESETS: [(&str, &str); 8] = [
    (
        "shapes",
        "the synthetic `shapes` scene: faint blue glass, opaque orange solids",
    ),
    ("ct-bone", "CT-like data: bone only, ivory and opaque"),
    ("ct-skin", "CT-like data: translucent skin over opaque bone"),
    (
        "shells",
        "the synthetic `shells` scene: one colour per shell",
    ),
    ("cloud", "the synthetic `noise` scene: a soft bluish cloud"),
    (
        "opaque",
        "every non-background value fully opaque (sample-count experiments)",
    ),
    ("grayscale", "a linear grey ramp with a linear opacity ramp"),
    ("rainbow", "hue over the value range with rising opacity"),
];

fn preset_names() -> String {
    PRESETS.map(|(n, _)| n).join(", ")
}

/// `did you mean ct-bone? ` for a near miss of a preset name, else nothing.
fn did_you_mean(name: &str) -> String {
    closest_preset(name).map_or_else(String::new, |p| format!("did you mean {p}? "))
}

/// The preset whose name is closest to `name` when it is a near miss: at most two
/// edits away (ignoring case), or a name that starts with it.
pub fn closest_preset(name: &str) -> Option<&'static str> {
    let lower = name.to_ascii_lowercase();
    PRESETS
        .iter()
        .map(|(p, _)| (edit_distance(&lower, p), *p))
        .filter(|&(d, p)| d <= 2 || (lower.len() >= 2 && p.starts_with(lower.as_str())))
        .min_by_key(|&(d, _)| d)
        .map(|(_, p)| p)
}

/// Levenshtein distance between two short strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let cost = usize::from(ca != cb);
            let next = (row[j + 1] + 1).min(row[j] + 1).min(prev + cost);
            prev = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

fn p(value: f32, color: [f32; 3], alpha: f32) -> ControlPoint {
    ControlPoint {
        value,
        color,
        alpha,
    }
}

impl TransferFunction {
    /// A function from control points (sorted here by value).
    pub fn new(mut points: Vec<ControlPoint>) -> Result<TransferFunction, TransferError> {
        if points.is_empty() {
            return Err(TransferError::NoPoints);
        }
        for q in &points {
            check_point(q, 0)?;
        }
        points.sort_by(|a, b| a.value.total_cmp(&b.value));
        Ok(TransferFunction {
            points,
            domain: None,
            gradient_ramp: None,
        })
    }

    /// Whether `name` (of a `--tf` or a scene's `tf`) means a file: it exists
    /// beside `base` (`name` relative to it), or it is no preset and looks like
    /// a path (a `/` or an extension), so that a missing file is reported as
    /// one rather than as an unknown preset.
    pub fn names_a_file(name: &str, base: &Path) -> bool {
        let is_preset = PRESETS.iter().any(|(p, _)| *p == name);
        !is_preset
            && (base.join(name).exists()
                || name.contains('/')
                || Path::new(name).extension().is_some())
    }

    /// The preset called `name` (see [`PRESETS`]).
    pub fn preset(name: &str) -> Result<TransferFunction, TransferError> {
        const BLUE: [f32; 3] = [0.35, 0.55, 1.0];
        const ORANGE: [f32; 3] = [1.0, 0.55, 0.2];
        const IVORY: [f32; 3] = [1.0, 0.95, 0.85];
        const SKIN: [f32; 3] = [0.95, 0.65, 0.5];
        let points = match name {
            "shapes" => vec![
                p(0.0, BLUE, 0.0),
                p(0.08, BLUE, 0.0),
                p(0.12, BLUE, 0.06),
                p(0.31, BLUE, 0.06),
                p(0.36, ORANGE, 0.0),
                p(0.40, ORANGE, 0.0),
                p(0.55, [1.0, 0.6, 0.25], 0.7),
                p(0.8, [1.0, 0.8, 0.45], 0.95),
                p(1.0, [1.0, 1.0, 0.9], 1.0),
            ],
            "ct-bone" => vec![
                p(0.0, IVORY, 0.0),
                p(0.38, IVORY, 0.0),
                p(0.5, [0.9, 0.8, 0.7], 0.4),
                p(0.65, IVORY, 0.95),
                p(1.0, [1.0, 1.0, 1.0], 1.0),
            ],
            "ct-skin" => vec![
                p(0.0, SKIN, 0.0),
                p(0.15, SKIN, 0.0),
                p(0.22, SKIN, 0.04),
                p(0.32, SKIN, 0.04),
                p(0.38, IVORY, 0.0),
                p(0.5, [0.9, 0.8, 0.7], 0.4),
                p(0.7, IVORY, 1.0),
                p(1.0, [1.0, 1.0, 1.0], 1.0),
            ],
            "shells" => vec![
                p(0.0, [0.9, 0.2, 0.2], 0.0),
                p(0.08, [0.9, 0.2, 0.2], 0.0),
                p(0.1, [0.9, 0.2, 0.2], 0.6),
                p(0.2, [0.9, 0.3, 0.2], 0.6),
                p(0.25, [0.2, 0.8, 0.3], 0.0),
                p(0.33, [0.2, 0.8, 0.3], 0.0),
                p(0.35, [0.2, 0.8, 0.3], 0.3),
                p(0.45, [0.3, 0.9, 0.4], 0.3),
                p(0.5, [0.2, 0.4, 0.9], 0.0),
                p(0.58, [0.2, 0.4, 0.9], 0.0),
                p(0.6, [0.2, 0.4, 0.9], 0.15),
                p(0.7, [0.3, 0.5, 1.0], 0.15),
                p(0.75, [0.9, 0.9, 0.9], 0.0),
                p(0.83, [0.9, 0.9, 0.9], 0.0),
                p(0.85, [0.9, 0.9, 0.9], 0.05),
                p(1.0, [1.0, 1.0, 1.0], 0.05),
            ],
            "cloud" => vec![
                p(0.0, [0.6, 0.7, 1.0], 0.0),
                p(0.25, [0.6, 0.7, 1.0], 0.0),
                p(0.5, [0.8, 0.85, 1.0], 0.04),
                p(1.0, [1.0, 1.0, 1.0], 0.4),
            ],
            "opaque" => vec![
                p(0.0, [1.0; 3], 0.0),
                p(0.04, [1.0; 3], 0.0),
                p(0.05, [0.9, 0.9, 0.9], 1.0),
                p(1.0, [1.0; 3], 1.0),
            ],
            "grayscale" => vec![p(0.0, [0.0; 3], 0.0), p(1.0, [1.0; 3], 0.5)],
            "rainbow" => vec![
                p(0.0, [0.2, 0.0, 1.0], 0.0),
                p(0.1, [0.2, 0.0, 1.0], 0.0),
                p(0.3, [0.0, 0.6, 1.0], 0.05),
                p(0.5, [0.0, 1.0, 0.3], 0.15),
                p(0.7, [1.0, 0.9, 0.0], 0.4),
                p(1.0, [1.0, 0.1, 0.0], 0.9),
            ],
            other => return Err(TransferError::UnknownPreset(other.to_string())),
        };
        TransferFunction::new(points)
    }

    /// Parses the text format (one item per line, `#` starts a comment):
    ///
    /// ```text
    /// domain 0 4095            # optional: raw values mapped to 0 and 1
    /// gradient 0.02 0.1        # optional: 2D, opacity × smoothstep(0.02, 0.1, |∇f|)
    /// point 0.0  0 0 0  0      # value  r g b  alpha   (all in [0, 1])
    /// point 1.0  1 1 1  0.8
    /// ```
    pub fn parse(text: &str) -> Result<TransferFunction, TransferError> {
        let mut points = Vec::new();
        let mut domain = None;
        let mut gradient_ramp = None;
        for (i, raw_line) in crate::text::without_bom(text).lines().enumerate() {
            let line = i + 1;
            let content = raw_line.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let mut words = content.split_whitespace();
            let keyword = words.next().unwrap_or("");
            // The keyword first: an unknown one was said as its next word not
            // being a number (`foo = 1`: "\"=\" is not a finite number").
            if !matches!(keyword, "point" | "domain" | "gradient") {
                let toml = content.contains('=') || content.starts_with('[');
                let hint = if toml {
                    "; this looks like TOML: a session is given with --session, a scene with --segments"
                } else {
                    ""
                };
                return Err(invalid(
                    line,
                    format!(
                        "unknown keyword {keyword:?} (expected point, domain or gradient){hint}"
                    ),
                ));
            }
            let numbers = words
                .map(|w| {
                    w.parse::<f32>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| invalid(line, format!("{w:?} is not a finite number")))
                })
                .collect::<Result<Vec<f32>, _>>()?;
            let expect = |n: usize| {
                if numbers.len() == n {
                    Ok(())
                } else {
                    Err(invalid(
                        line,
                        format!("{keyword} takes {n} numbers, found {}", numbers.len()),
                    ))
                }
            };
            match keyword {
                "point" => {
                    expect(5)?;
                    let q = p(numbers[0], [numbers[1], numbers[2], numbers[3]], numbers[4]);
                    check_point(&q, line)?;
                    points.push(q);
                }
                "domain" => {
                    expect(2)?;
                    check_domain([numbers[0], numbers[1]]).map_err(|e| invalid(line, e))?;
                    if domain.is_some() {
                        return Err(invalid(line, "a second domain line (give one)".into()));
                    }
                    domain = Some([numbers[0], numbers[1]]);
                }
                _ => {
                    expect(2)?;
                    check_gradient_ramp([numbers[0], numbers[1]]).map_err(|e| invalid(line, e))?;
                    if gradient_ramp.is_some() {
                        return Err(invalid(line, "a second gradient line (give one)".into()));
                    }
                    gradient_ramp = Some([numbers[0], numbers[1]]);
                }
            }
        }
        let mut tf = TransferFunction::new(points)?;
        tf.domain = domain;
        tf.gradient_ramp = gradient_ramp;
        Ok(tf)
    }

    /// Reads and parses a transfer-function file (format of [`Self::parse`]).
    pub fn load(path: &Path) -> Result<TransferFunction, TransferError> {
        let text = crate::files::read_text(path, TEXT_MAX).map_err(|source| TransferError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        TransferFunction::parse(&text).map_err(|e| TransferError::InFile {
            path: path.to_path_buf(),
            source: Box::new(e),
        })
    }

    /// The text form that [`Self::parse`] reads back.
    pub fn to_text(&self) -> String {
        let mut out = String::from("# raycaster transfer function\n");
        if let Some([a, b]) = self.domain {
            out += &format!("domain {a} {b}\n");
        }
        if let Some([a, b]) = self.gradient_ramp {
            out += &format!("gradient {a} {b}\n");
        }
        for q in &self.points {
            let [r, g, b] = q.color;
            out += &format!("point {} {r} {g} {b} {}\n", q.value, q.alpha);
        }
        out
    }

    /// The control points, sorted by value.
    pub fn points(&self) -> &[ControlPoint] {
        &self.points
    }

    /// Colour and opacity (per reference step) at normalised value `x`, linearly
    /// interpolated between control points and constant beyond the end points;
    /// transparent black for a NaN `x` (no value).
    pub fn evaluate(&self, x: f32) -> [f32; 4] {
        if x.is_nan() {
            return [0.0; 4];
        }
        let pts = &self.points;
        let rgba = |q: &ControlPoint| [q.color[0], q.color[1], q.color[2], q.alpha];
        let first = &pts[0];
        if x <= first.value {
            return rgba(first);
        }
        for w in pts.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            if x <= b.value {
                let f = if b.value > a.value {
                    (x - a.value) / (b.value - a.value)
                } else {
                    1.0
                };
                let (ca, cb) = (rgba(a), rgba(b));
                return [0, 1, 2, 3].map(|i| ca[i] + (cb[i] - ca[i]) * f);
            }
        }
        rgba(pts.last().expect("at least one point"))
    }
}

/// `line N: ` for errors of a file line, nothing for values given in code (line 0).
fn line_prefix(line: usize) -> String {
    if line > 0 {
        format!("line {line}: ")
    } else {
        String::new()
    }
}

fn invalid(line: usize, what: String) -> TransferError {
    TransferError::Invalid { line, what }
}

fn check_point(q: &ControlPoint, line: usize) -> Result<(), TransferError> {
    let in_unit = |v: f32| (0.0..=1.0).contains(&v);
    if !in_unit(q.value) || !q.color.iter().all(|&c| in_unit(c)) || !in_unit(q.alpha) {
        return Err(invalid(
            line,
            format!(
                "control point at {} (colour {:?}, alpha {}): value, colour and alpha must lie in [0, 1]",
                q.value, q.color, q.alpha
            ),
        ));
    }
    Ok(())
}

/// A transfer function sampled for one frame.
#[derive(Clone, Debug)]
pub struct TransferTable {
    /// RGB and step-corrected opacity per entry.
    entries: Vec<[f32; 4]>,
    /// Uncorrected opacity per entry (one-sample modes: MIP, average).
    alpha0: Vec<f32>,
    /// `opaque_prefix[i]` = entries below `i` with opacity > 0.
    opaque_prefix: Vec<u32>,
    /// Bit `i % 32` of word `i / 32`: entry `i`'s step-corrected opacity is
    /// above 0.
    visible_bits: [u32; TABLE_SIZE / 32],
    /// Raw value of entry 0 and entries per raw unit.
    offset: f32,
    scale: f32,
    /// Corrected opacity factor per gradient bin (2D tables).
    gradient: Option<GradientRamp>,
    /// The step the opacities are corrected for, in reference steps.
    step_ratio: f32,
    /// Pre-integrated segments (front value, back value), when asked for.
    preintegrated: Option<Arc<PreintegratedTable>>,
    /// For samples of at most [`RAW_PREFIX_MAX`]: per raw value `v`, the
    /// opaque prefix sums at and after its entry (`opaque_prefix[index(v)]`,
    /// `opaque_prefix[index(v) + 1]`), so that [`Self::is_transparent`], asked
    /// for every cell a ray crosses, reads two entries instead of converting
    /// two values. Empty for wider samples.
    raw_prefix: Vec<[u32; 2]>,
}

/// Bit `i % 32` of word `i / 32`: whether `entries[i]`'s opacity is above 0.
fn visible_bits(entries: &[[f32; 4]]) -> [u32; TABLE_SIZE / 32] {
    let mut bits = [0u32; TABLE_SIZE / 32];
    for (i, entry) in entries.iter().enumerate().take(TABLE_SIZE) {
        bits[i / 32] |= u32::from(entry[3] > 0.0) << (i % 32);
    }
    bits
}

/// `prefix[i]` = the entries below `i` whose opacity `alpha0` is above 0.
fn opaque_prefix(alpha0: &[f32]) -> Vec<u32> {
    let mut prefix = Vec::with_capacity(alpha0.len() + 1);
    let mut count = 0u32;
    prefix.push(0);
    for &a in alpha0 {
        count += u32::from(a > 0.0);
        prefix.push(count);
    }
    prefix
}

/// The largest sample type whose raw values get [`TransferTable`]'s
/// per-value prefix sums: u8 (2 KiB of them; u16's would take 512 KiB).
const RAW_PREFIX_MAX: u16 = 255;

#[derive(Clone, Debug)]
struct GradientRamp {
    /// `smoothstep(g0, g1, g)` per bin.
    factor: Vec<f32>,
    /// Bins per unit of gradient magnitude.
    scale: f32,
}

impl TransferTable {
    /// Samples `tf` for samples whose full range is `0..=type_max`, with opacities
    /// corrected for a step of `step_ratio` reference steps.
    pub fn new(tf: &TransferFunction, type_max: u16, step_ratio: f32) -> TransferTable {
        let [d0, d1] = tf.domain.unwrap_or([0.0, f32::from(type_max)]);
        let n = TABLE_SIZE;
        let mut entries = Vec::with_capacity(n);
        let mut alpha0 = Vec::with_capacity(n);
        for i in 0..n {
            let [r, g, b, a] = tf.evaluate(i as f32 / (n - 1) as f32);
            entries.push([r, g, b, corrected_alpha(a, step_ratio)]);
            alpha0.push(a);
        }
        let opaque_prefix = opaque_prefix(&alpha0);
        let gradient = tf.gradient_ramp.map(|[g0, g1]| GradientRamp {
            factor: (0..GRADIENT_BINS)
                .map(|i| {
                    smoothstep(
                        g0,
                        g1,
                        i as f32 / (GRADIENT_BINS - 1) as f32 * GRADIENT_RANGE,
                    )
                })
                .collect(),
            scale: (GRADIENT_BINS - 1) as f32 / GRADIENT_RANGE,
        });
        let visible_bits = visible_bits(&entries);
        let mut table = TransferTable {
            entries,
            alpha0,
            opaque_prefix,
            visible_bits,
            offset: d0,
            scale: (n - 1) as f32 / (d1 - d0),
            gradient,
            step_ratio,
            preintegrated: None,
            raw_prefix: Vec::new(),
        };
        if type_max <= RAW_PREFIX_MAX {
            table.raw_prefix = table.raw_prefix_up_to(type_max);
        }
        table
    }

    /// [`Self::raw_prefix`] for raw values `0..=type_max`.
    fn raw_prefix_up_to(&self, type_max: u16) -> Vec<[u32; 2]> {
        (0..=type_max)
            .map(|v| {
                let i = self.index(f32::from(v));
                [self.opaque_prefix[i], self.opaque_prefix[i + 1]]
            })
            .collect()
    }

    /// This table with a pre-integrated table over (front, back) value pairs for
    /// `tf` (the function this table was built from), taken from the process-wide
    /// cache when `tf`, the sample type and the step are unchanged (a moving
    /// camera never rebuilds it). 2D (gradient) functions get none: their opacity
    /// depends on the gradient at each point of a segment, which two values
    /// cannot describe.
    pub fn with_preintegration(mut self, tf: &TransferFunction, type_max: u16) -> TransferTable {
        if tf.gradient_ramp.is_none() {
            self.preintegrated = Some(PreintegratedTable::cached(tf, type_max, self.step_ratio));
        }
        self
    }

    /// A table whose entries are visible where an entry of any of `tables`
    /// is (each entry's opacity the largest of theirs; transparent over a
    /// range of values where all are), for a kernel that
    /// asks only which samples some table shows; `None` when they map values
    /// to entries differently (another domain) or there is none.
    pub(crate) fn visible_under_any(tables: &[&TransferTable]) -> Option<TransferTable> {
        let (first, rest) = tables.split_first()?;
        let same_map = |t: &TransferTable| {
            t.offset == first.offset
                && t.scale == first.scale
                && t.entries.len() == first.entries.len()
        };
        if !rest.iter().all(|t| same_map(t)) {
            return None;
        }
        let mut union = TransferTable::clone(first);
        union.preintegrated = None;
        for t in rest {
            for (u, e) in union.entries.iter_mut().zip(&t.entries) {
                u[3] = u[3].max(e[3]);
            }
            for (u, a) in union.alpha0.iter_mut().zip(&t.alpha0) {
                *u = u.max(*a);
            }
            for (u, b) in union.visible_bits.iter_mut().zip(&t.visible_bits) {
                *u |= b;
            }
        }
        // Transparent ranges too: transparent under every table.
        union.opaque_prefix = opaque_prefix(&union.alpha0);
        if let Some(type_max) = union.raw_prefix.len().checked_sub(1) {
            union.raw_prefix = union.raw_prefix_up_to(type_max as u16);
        }
        Some(union)
    }

    /// A table visible wherever a value may be visible under one of `tables`,
    /// which may map values to entries differently (objects whose functions
    /// have domains of their own): its map covers all of theirs, and each of
    /// its entries is visible when an entry of any table that the entry's
    /// values read, or the entry beside it either way (against rounding), is.
    /// For tables that map values apart ([`Self::visible_under_any`] is exact
    /// where they share one). A filter for kernels that fold the samples it
    /// shows with each object's own table; not exact (it may show more), so
    /// not for range emptiness. `None` without tables or with a map that is
    /// not finite and increasing.
    pub(crate) fn visible_somewhere_under_any(tables: &[&TransferTable]) -> Option<TransferTable> {
        let first = tables.first()?;
        let last = (TABLE_SIZE - 1) as f32;
        let increasing = |t: &&TransferTable| {
            t.entries.len() == TABLE_SIZE && t.scale.is_finite() && t.scale > 0.0
        };
        if !tables.iter().all(increasing) {
            return None;
        }
        let lo = tables
            .iter()
            .map(|t| t.offset)
            .fold(f32::INFINITY, f32::min);
        let hi = tables
            .iter()
            .map(|t| t.offset + last / t.scale)
            .fold(f32::NEG_INFINITY, f32::max);
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return None;
        }
        let scale = last / (hi - lo);
        let mut union = TransferTable::clone(first);
        union.preintegrated = None;
        union.offset = lo;
        union.scale = scale;
        for u in 0..TABLE_SIZE {
            // The values entry `u` reads: `index` rounds to the nearest entry,
            // and clamps below the first and above the last.
            let from = if u == 0 {
                f32::NEG_INFINITY
            } else {
                lo + (u as f32 - 0.5) / scale
            };
            let to = if u == TABLE_SIZE - 1 {
                f32::INFINITY
            } else {
                lo + (u as f32 + 0.5) / scale
            };
            let (mut corrected, mut alpha0) = (0.0f32, 0.0f32);
            for t in tables {
                let (i0, i1) = (t.index(from).saturating_sub(1), t.index(to) + 1);
                for i in i0..=i1.min(TABLE_SIZE - 1) {
                    corrected = corrected.max(t.entries[i][3]);
                    alpha0 = alpha0.max(t.alpha0[i]);
                }
            }
            union.entries[u][3] = corrected;
            union.alpha0[u] = alpha0;
        }
        union.visible_bits = visible_bits(&union.entries);
        union.opaque_prefix = opaque_prefix(&union.alpha0);
        if let Some(type_max) = union.raw_prefix.len().checked_sub(1) {
            union.raw_prefix = union.raw_prefix_up_to(type_max as u16);
        }
        Some(union)
    }

    /// The pre-integrated table, if this table has one.
    #[inline]
    pub(crate) fn preintegrated(&self) -> Option<&PreintegratedTable> {
        self.preintegrated.as_deref()
    }

    /// The table entry that raw value `v` reads (nearest entry; monotone in `v`).
    #[inline]
    pub fn index(&self, v: f32) -> usize {
        // NaN maps to entry 0.
        truncate_clamped(
            (v - self.offset) * self.scale + 0.5,
            (TABLE_SIZE - 1) as f32,
        ) as usize
    }

    /// Every entry's RGB and step-corrected opacity, as [`Self::index`] numbers
    /// them.
    #[inline]
    pub(crate) fn entries(&self) -> &[[f32; 4]] {
        &self.entries
    }

    /// Which entries' step-corrected opacity (`entries()[i][3]`) is above 0:
    /// bit `i % 32` of word `i / 32`.
    #[cfg(any(target_arch = "x86_64", test))]
    #[inline]
    pub(crate) fn visible_bits(&self) -> &[u32; TABLE_SIZE / 32] {
        &self.visible_bits
    }

    /// The offset and scale [`Self::index`] maps a raw value with:
    /// `(v − offset)·scale + 0.5`, clamped and truncated.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    pub(crate) fn index_map(&self) -> (f32, f32) {
        (self.offset, self.scale)
    }

    /// RGB and step-corrected opacity for raw value `v` (1D part only).
    #[inline]
    pub fn lookup(&self, v: f32) -> [f32; 4] {
        self.entries[self.index(v)]
    }

    /// The uncorrected opacity (per reference step) for raw value `v`.
    #[inline]
    pub fn alpha0(&self, v: f32) -> f32 {
        self.alpha0[self.index(v)]
    }

    /// Whether opacity depends on the gradient magnitude too.
    #[inline]
    pub fn is_2d(&self) -> bool {
        self.gradient.is_some()
    }

    /// Opacity factor of the 2D ramp for gradient magnitude `g` (1 for 1D tables).
    /// The step correction is applied to the product in [`Self::lookup_2d`].
    #[inline]
    fn gradient_factor(&self, g: f32) -> f32 {
        match &self.gradient {
            Some(ramp) => {
                let i = (g * ramp.scale + 0.5)
                    .max(0.0)
                    .min((GRADIENT_BINS - 1) as f32);
                ramp.factor[i as usize]
            }
            None => 1.0,
        }
    }

    /// RGB and step-corrected opacity for raw value `v` and gradient magnitude `g`.
    #[inline]
    pub fn lookup_2d(&self, v: f32, g: f32) -> [f32; 4] {
        let i = self.index(v);
        let [r, gr, b, _] = self.entries[i];
        let a0 = self.alpha0[i] * self.gradient_factor(g);
        [r, gr, b, corrected_alpha(a0, self.step_ratio)]
    }

    /// The step the opacities are corrected for, in reference steps.
    pub fn step_ratio(&self) -> f32 {
        self.step_ratio
    }

    /// Whether every raw value in `[lo, hi]` maps to opacity 0 (whatever the
    /// gradient): two reads of the prefix sum.
    #[inline]
    pub fn is_transparent(&self, lo: u16, hi: u16) -> bool {
        if let (Some(a), Some(b)) = (
            self.raw_prefix.get(usize::from(lo)),
            self.raw_prefix.get(usize::from(hi)),
        ) {
            return b[1] == a[0];
        }
        let (a, b) = (self.index(f32::from(lo)), self.index(f32::from(hi)));
        self.opaque_prefix[b + 1] == self.opaque_prefix[a]
    }
}

/// Bins per axis of a pre-integrated table: front and back values are quantised
/// to 256 levels over the transfer function's domain (measured in
/// `docs/benchmarks.md`: 512 bins cost four times the build time and memory for
/// no visible gain at the steps pre-integration is for).
pub const PREINTEGRATION_BINS: usize = 256;

/// The lengths of segment pieces a pre-integrated table has shading weights
/// for: a whole step, its half and its quarter (a segment is halved at most
/// twice where the field bends along it).
pub(crate) const PIECE_LENGTHS: usize = 3;

/// Points of the fine grid the integral functions are sampled on.
const FINE: usize = 4096;

/// Extinction (per reference step) standing for opacity 1: large enough that any
/// step above 0.002 reference steps gives opacity 1.0 in f32.
const TAU_OPAQUE: f64 = 1.0e4;

/// A pre-integrated transfer table (Engel, Kraus and Ertl 2001): for a segment of
/// one step along which the raw value goes linearly from `front` to `back`, its
/// opacity and colour, for the step of the [`TransferTable`] it belongs to.
///
/// With extinction `τ(v) = −ln(1 − α0(v))` per reference step and the integral
/// functions `T(v) = ∫ τ` and `K(v) = ∫ τ·c` over the value axis (prefix sums on a
/// fine grid, linear between its points, extended with the end points' values
/// beyond the domain), a segment of `r` reference steps has
/// `α = 1 − exp(−r·(T(b) − T(f))/(b − f))` — exact for a linear ramp — and colour
/// `c = (K(b) − K(f))/(T(b) − T(f))`, the extinction-weighted mean colour. The
/// colour ignores attenuation inside the segment (the usual approximation; exact
/// for a constant colour). A constant segment (`f = b`) gives exactly the
/// ordinary corrected lookup of value `f`. Building is O(bins²) evaluations of
/// these closed forms, never an O(bins³) integration.
///
/// For shading, each entry also says where along the segment its light comes
/// from ([`Self::shading_weights`]), for pieces of each of
/// [`PIECE_LENGTHS`] lengths.
#[derive(Clone, Debug)]
pub(crate) struct PreintegratedTable {
    /// `bins × bins` entries, front-major: RGB (not premultiplied) and opacity.
    entries: Vec<[f32; 4]>,
    /// Per piece length (a step, a half, a quarter), in the entries' order: the
    /// shares of the front and back quarters in the segment's emission, in
    /// units of `1/65535` ([`Self::shading_weights`]).
    weights: [Vec<[u16; 2]>; PIECE_LENGTHS],
    /// Bins per axis.
    bins: usize,
    /// Raw value of bin 0 and bins per raw unit.
    offset: f32,
    scale: f32,
    /// `1 − α0` and colour on the fine grid, and the integral functions `T`
    /// and `K` there (f64: differences of large sums).
    transparency: Vec<f64>,
    big_t: Vec<f64>,
    big_k: Vec<[f64; 3]>,
    color: Vec<[f64; 3]>,
    /// Fine-grid points per bin.
    fine_per_bin: f64,
    /// Reference steps per step.
    step_ratio: f64,
}

/// Extinction per reference step of transparency `s = 1 − α0` (capped for
/// `α0 = 1`).
fn extinction(s: f64) -> f64 {
    if s > 0.0 {
        (-s.ln()).min(TAU_OPAQUE)
    } else {
        TAU_OPAQUE
    }
}

/// `∫₀^f τ` over a fine cell whose transparency goes linearly from `s0` to `s1`
/// (`τ = −ln s`; `∫ ln s = s·ln s − s`), finite where it reaches 0.
fn cell_extinction(s0: f64, s1: f64, f: f64) -> f64 {
    let g = |s: f64| if s > 0.0 { s * s.ln() - s } else { 0.0 };
    let end = s0 + (s1 - s0) * f;
    if (s1 - s0).abs() < 1e-9 {
        f * extinction((s0 + end) / 2.0)
    } else {
        (-(g(end) - g(s0)) / (s1 - s0)).min(f * TAU_OPAQUE)
    }
}

/// The key of a cached pre-integrated table.
type PreintegrationKey = (TransferFunction, u16, u32);

/// The last few pre-integrated tables built (most recent last).
static PREINTEGRATION_CACHE: Mutex<Vec<(PreintegrationKey, Arc<PreintegratedTable>)>> =
    Mutex::new(Vec::new());

/// Tables the cache keeps (a viewer alternating two steps or functions).
const PREINTEGRATION_CACHE_SIZE: usize = 4;

impl PreintegratedTable {
    /// The table of `tf` for samples `0..=type_max` and a step of `step_ratio`
    /// reference steps: built with [`PREINTEGRATION_BINS`] bins.
    pub fn new(tf: &TransferFunction, type_max: u16, step_ratio: f32) -> PreintegratedTable {
        Self::with_bins(tf, type_max, step_ratio, PREINTEGRATION_BINS)
    }

    /// [`Self::new`] from the process-wide cache (built on a miss).
    pub fn cached(tf: &TransferFunction, type_max: u16, step_ratio: f32) -> Arc<Self> {
        let key = (tf.clone(), type_max, step_ratio.to_bits());
        let mut cache = PREINTEGRATION_CACHE
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(i) = cache.iter().position(|(k, _)| *k == key) {
            let hit = cache.remove(i);
            let table = hit.1.clone();
            cache.push(hit);
            return table;
        }
        // Built under the lock: two frames asking at once build it once.
        let table = Arc::new(Self::new(tf, type_max, step_ratio));
        if cache.len() >= PREINTEGRATION_CACHE_SIZE {
            cache.remove(0);
        }
        cache.push((key, table.clone()));
        table
    }

    /// The table with `bins` bins per axis (2 or more).
    pub fn with_bins(
        tf: &TransferFunction,
        type_max: u16,
        step_ratio: f32,
        bins: usize,
    ) -> PreintegratedTable {
        let [d0, d1] = tf.domain.unwrap_or([0.0, f32::from(type_max)]);
        let mut transparency = Vec::with_capacity(FINE);
        let mut color = Vec::with_capacity(FINE);
        for i in 0..FINE {
            let [r, g, b, a] = tf.evaluate(i as f32 / (FINE - 1) as f32);
            transparency.push((1.0 - f64::from(a)).max(0.0));
            color.push([r, g, b].map(f64::from));
        }
        // Prefix sums of τ (exact per fine cell for a linear opacity, finite even
        // where it reaches 1) and of τ·c (the cell's mean colour).
        let mut big_t = vec![0.0; FINE];
        let mut big_k = vec![[0.0; 3]; FINE];
        for i in 1..FINE {
            let cell = cell_extinction(transparency[i - 1], transparency[i], 1.0);
            big_t[i] = big_t[i - 1] + cell;
            for c in 0..3 {
                big_k[i][c] = big_k[i - 1][c] + cell * (color[i - 1][c] + color[i][c]) / 2.0;
            }
        }
        let mut table = PreintegratedTable {
            entries: Vec::new(),
            weights: Default::default(),
            bins,
            offset: d0,
            scale: (bins - 1) as f32 / (d1 - d0),
            transparency,
            big_t,
            big_k,
            color,
            fine_per_bin: (FINE - 1) as f64 / (bins - 1) as f64,
            step_ratio: f64::from(step_ratio),
        };
        let mut entries = vec![[0.0f32; 4]; bins * bins];
        entries
            .par_chunks_mut(bins)
            .enumerate()
            .for_each(|(front, row)| {
                for (back, e) in row.iter_mut().enumerate() {
                    *e = table.segment_fine(
                        front as f64 * table.fine_per_bin,
                        back as f64 * table.fine_per_bin,
                    );
                }
            });
        table.entries = entries;
        let mut weights: [Vec<[u16; 2]>; PIECE_LENGTHS] =
            std::array::from_fn(|_| vec![[0; 2]; bins * bins]);
        let [w0, w1, w2] = &mut weights;
        w0.par_chunks_mut(bins)
            .zip(w1.par_chunks_mut(bins))
            .zip(w2.par_chunks_mut(bins))
            .enumerate()
            .for_each(|(front, ((r0, r1), r2))| {
                for back in 0..bins {
                    let shares = table.shares_fine(
                        front as f64 * table.fine_per_bin,
                        back as f64 * table.fine_per_bin,
                    );
                    for (row, [f, b]) in [&mut *r0, &mut *r1, &mut *r2].into_iter().zip(shares) {
                        row[back] = [quantise_share(f), quantise_share(b)];
                    }
                }
            });
        table.weights = weights;
        table
    }

    /// Bins per axis.
    #[cfg(test)]
    pub fn bins(&self) -> usize {
        self.bins
    }

    /// At fine-grid position `u` (any real: constant beyond the grid): the
    /// extinction `τ`, the colour and the integral functions `T` and `K`.
    fn at(&self, u: f64) -> (f64, [f64; 3], f64, [f64; 3]) {
        let last = (FINE - 1) as f64;
        let (i, f, outside) = if u <= 0.0 {
            (0, 0.0, u)
        } else if u >= last {
            (FINE - 2, 1.0, u - last)
        } else {
            let i = (u as usize).min(FINE - 2);
            (i, u - i as f64, 0.0)
        };
        let lerp = |a: f64, b: f64| a + (b - a) * f;
        let (s0, s1) = (self.transparency[i], self.transparency[i + 1]);
        let tau = extinction(lerp(s0, s1));
        let color = [0, 1, 2].map(|c| lerp(self.color[i][c], self.color[i + 1][c]));
        let part = cell_extinction(s0, s1, f);
        let t = self.big_t[i] + part + outside * tau;
        let k = [0, 1, 2].map(|c| {
            let mean = (self.color[i][c] + color[c]) / 2.0;
            self.big_k[i][c] + part * mean + outside * tau * color[c]
        });
        (tau, color, t, k)
    }

    /// The segment from fine-grid position `uf` to `ub` (see the type's doc).
    fn segment_fine(&self, uf: f64, ub: f64) -> [f32; 4] {
        let d = ub - uf;
        let (mean_tau, color) = if d.abs() < 1e-9 {
            let (tau, color, _, _) = self.at(uf);
            (tau, color)
        } else {
            let (_, cf, tf, kf) = self.at(uf);
            let (_, cb, tb, kb) = self.at(ub);
            let dt = tb - tf;
            let color = if dt.abs() > 1e-12 {
                [0, 1, 2].map(|c| ((kb[c] - kf[c]) / dt).clamp(0.0, 1.0))
            } else {
                [0, 1, 2].map(|c| (cf[c] + cb[c]) / 2.0)
            };
            (dt / d, color)
        };
        let a = 1.0 - (-self.step_ratio * mean_tau.max(0.0)).exp();
        [color[0] as f32, color[1] as f32, color[2] as f32, a as f32]
    }

    /// For the segment from fine-grid position `uf` to `ub`, per piece length
    /// (a step, a half, a quarter: the value still going linearly from `uf` to
    /// `ub` along it): the shares of its front quarter and of its back quarter
    /// in the light it sends to the eye, the rest coming from its middle half.
    ///
    /// The share of a part is the drop in transmittance across it, the part's
    /// opacity as seen from the segment's front: with optical depth
    /// `D(u) = r·(T(v(u)) − T(uf))/(ub − uf)` at fraction `u` along it,
    /// transmittance `exp(−D(u))`; exact for the linear ramp, for any function.
    /// Shares are of the whole segment's opacity; a transparent segment gets
    /// the transparent limit (`D` linear: ¼, ½, ¼).
    fn shares_fine(&self, uf: f64, ub: f64) -> [[f64; 2]; PIECE_LENGTHS] {
        let d = ub - uf;
        // Optical depth per reference step up to fractions ¼, ¾ and 1.
        let depth_at: [f64; 3] = if d.abs() < 1e-9 {
            let tau = self.at(uf).0;
            [0.25, 0.75, 1.0].map(|u| tau * u)
        } else {
            let t0 = self.integral(uf);
            [0.25, 0.75, 1.0].map(|u| (self.integral(uf + d * u) - t0) / d)
        };
        // Transmittance up to ¼, ¾ and 1 of a whole step; a half step's is its
        // square root, a quarter's the root of that.
        let mut transmittance = depth_at.map(|depth| (-self.step_ratio * depth.max(0.0)).exp());
        std::array::from_fn(|piece| {
            if piece > 0 {
                transmittance = transmittance.map(f64::sqrt);
            }
            let [q1, q3, all] = transmittance;
            let total = 1.0 - all;
            if total > 1e-9 {
                [(1.0 - q1) / total, (q3 - all) / total]
            } else {
                [0.25, 0.25]
            }
        })
    }

    /// The integral function `T` at fine-grid position `u`, linear within a
    /// fine cell (the exact value is [`Self::at`]'s; this is for the shading
    /// weights, which need no more) and extended beyond the grid by the end
    /// points' extinction.
    fn integral(&self, u: f64) -> f64 {
        let last = FINE - 1;
        if u <= 0.0 {
            u * extinction(self.transparency[0])
        } else if u >= last as f64 {
            self.big_t[last] + (u - last as f64) * extinction(self.transparency[last])
        } else {
            let i = (u as usize).min(last - 1);
            let f = u - i as f64;
            self.big_t[i] + (self.big_t[i + 1] - self.big_t[i]) * f
        }
    }

    /// The shares of the front quarter, the middle half and the back quarter
    /// of the segment at `at` (its value going linearly from front to back) in
    /// the light it sends to the eye ([`Self::shares_fine`]), for a step halved
    /// `halved` times (0 to 2): where to shade it. Beyond the domain they are
    /// computed; inside, the nearest bins' (as [`Self::entry`]).
    #[inline]
    pub fn shading_weights(&self, at: TablePosition, halved: usize) -> [f32; 3] {
        let [uf, ub] = at.bins;
        let [f, b] = if at.inside {
            let [f, b] = self.weights[halved][self.nearest_entry(at)];
            [f, b].map(|w| f32::from(w) / f32::from(u16::MAX))
        } else {
            let shares = self.shares_fine(
                f64::from(uf) * self.fine_per_bin,
                f64::from(ub) * self.fine_per_bin,
            );
            shares[halved].map(|w| w as f32)
        };
        [f, (1.0 - f - b).max(0.0), b]
    }

    /// [`Self::entry`] interpolated bilinearly between the four nearest bins'
    /// entries (colours premultiplied for the blend) instead of the nearest
    /// one: the value pairs are not quantised to the bins. Beyond the domain,
    /// the computed entry (as [`Self::entry`]).
    #[inline]
    pub fn entry_interpolated(&self, at: TablePosition) -> [f32; 4] {
        if !at.inside {
            return self.entry(at);
        }
        let [uf, ub] = at.bins;
        let (bins, max) = (self.bins, (self.bins - 1) as f32);
        let (uf, ub) = (uf.clamp(0.0, max), ub.clamp(0.0, max));
        let [i, j] = [uf, ub].map(|u| truncate_clamped(u, max - 1.0) as usize);
        let (fi, fj) = (uf - i as f32, ub - j as f32);
        let corners = [
            (i, j, (1.0 - fi) * (1.0 - fj)),
            (i, j + 1, (1.0 - fi) * fj),
            (i + 1, j, fi * (1.0 - fj)),
            (i + 1, j + 1, fi * fj),
        ];
        let mut sum = [0.0f32; 4];
        for (front_bin, back_bin, w) in corners {
            let [r, g, b, a] = self.entries[front_bin * bins + back_bin];
            let wa = w * a;
            sum = [
                sum[0] + wa * r,
                sum[1] + wa * g,
                sum[2] + wa * b,
                sum[3] + wa,
            ];
        }
        let a = sum[3];
        if a > 0.0 {
            [sum[0] / a, sum[1] / a, sum[2] / a, a]
        } else {
            [0.0; 4]
        }
    }

    /// Where the segment whose raw value goes linearly from `front` to `back`
    /// lies in the table: located once, then looked up ([`Self::entry`],
    /// [`Self::entry_interpolated`]) and shaded ([`Self::shading_weights`]).
    #[inline]
    pub fn locate(&self, front: f32, back: f32) -> TablePosition {
        let max = (self.bins - 1) as f32;
        // NaN (never produced by trilinear reads) reads as the domain's low end.
        let uf = ((front - self.offset) * self.scale).max(-1.0e9);
        let ub = ((back - self.offset) * self.scale).max(-1.0e9);
        // Also false for NaN.
        let inside = (-0.5..max + 0.5).contains(&uf) && (-0.5..max + 0.5).contains(&ub);
        TablePosition {
            bins: [uf, ub],
            inside,
        }
    }

    /// The index of the entry nearest `at` (one inside the table).
    #[inline]
    fn nearest_entry(&self, at: TablePosition) -> usize {
        let (bins, max) = (self.bins, (self.bins - 1) as f32);
        let [i, j] = at.bins.map(|u| truncate_clamped(u + 0.5, max) as usize);
        i * bins + j
    }

    /// The width of one bin in raw values.
    pub fn bin_width(&self) -> f32 {
        1.0 / self.scale
    }

    /// RGB and opacity of a segment whose raw value goes linearly from `front` to
    /// `back`: [`Self::entry`] of where it lies.
    #[inline]
    pub fn lookup(&self, front: f32, back: f32) -> [f32; 4] {
        self.entry(self.locate(front, back))
    }

    /// RGB and opacity of the segment at `at`: the nearest bins' entry when
    /// both ends lie in the domain, else computed from the integral functions
    /// (the function is constant beyond its domain).
    #[inline]
    pub fn entry(&self, at: TablePosition) -> [f32; 4] {
        let [uf, ub] = at.bins;
        if at.inside {
            self.entries[self.nearest_entry(at)]
        } else {
            self.segment_fine(
                f64::from(uf) * self.fine_per_bin,
                f64::from(ub) * self.fine_per_bin,
            )
        }
    }
}

/// Where a segment's front and back values lie in a [`PreintegratedTable`]
/// ([`PreintegratedTable::locate`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TablePosition {
    /// The values in bins (bin `i` at `i`).
    bins: [f32; 2],
    /// Both within half a bin of the table's ends (false for NaN).
    inside: bool,
}

/// A share in `0..=1` as a fraction of `u16::MAX`.
fn quantise_share(share: f64) -> u16 {
    (share.clamp(0.0, 1.0) * f64::from(u16::MAX)).round() as u16
}

#[cfg(test)]
mod tests {
    #[test]
    fn near_miss_presets_get_a_suggestion_and_bad_domains_are_refused() {
        let e = TransferFunction::preset("ct-bon").unwrap_err().to_string();
        assert!(e.contains("did you mean ct-bone?"), "{e}");
        let e = TransferFunction::preset("CT_SKIN").unwrap_err().to_string();
        assert!(e.contains("did you mean ct-skin?"), "{e}");
        let e = TransferFunction::preset("zzzzzz").unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
        for bad in ["domain 5 5", "domain 9 1", "domain nan 1", "domain 0 inf"] {
            let text = format!("{bad}\npoint 0 1 1 1 1\n");
            assert!(TransferFunction::parse(&text).is_err(), "{bad}");
        }
        assert!(check_domain([0.0, 1.0]).is_ok());
        assert!(check_gradient_ramp([0.1, f32::NAN]).is_err());
        // A file saved with a byte-order mark reads as without one.
        let text = "point 0 0 0 0 0\npoint 1 1 1 1 1\n";
        assert_eq!(
            TransferFunction::parse(&format!("\u{feff}{text}")).unwrap(),
            TransferFunction::parse(text).unwrap()
        );
    }

    use super::*;

    #[test]
    fn every_preset_builds_and_parses_back() {
        for (name, _) in PRESETS {
            let tf = TransferFunction::preset(name).unwrap();
            assert_eq!(
                TransferFunction::parse(&tf.to_text()).unwrap(),
                tf,
                "{name}"
            );
        }
        assert!(matches!(
            TransferFunction::preset("nope"),
            Err(TransferError::UnknownPreset(_))
        ));
    }

    #[test]
    fn evaluation_interpolates_between_points() {
        let tf = TransferFunction::new(vec![p(0.2, [0.0; 3], 0.0), p(0.6, [1.0, 0.5, 0.0], 0.8)])
            .unwrap();
        assert_eq!(tf.evaluate(0.0), [0.0; 4]);
        let mid = tf.evaluate(0.4);
        assert!((mid[0] - 0.5).abs() < 1e-6 && (mid[3] - 0.4).abs() < 1e-6);
        assert_eq!(tf.evaluate(1.0), [1.0, 0.5, 0.0, 0.8]);
        // No value is nothing (it was the top of the range).
        assert_eq!(tf.evaluate(f32::NAN), [0.0; 4]);
    }

    #[test]
    fn opacity_correction_matches_the_formula() {
        assert!((corrected_alpha(0.5, 2.0) - 0.75).abs() < 1e-6);
        assert!((corrected_alpha(0.5, 0.5) - (1.0 - 0.5f32.sqrt())).abs() < 1e-6);
        assert_eq!(corrected_alpha(1.0, 0.1), 1.0);
        assert_eq!(corrected_alpha(0.0, 3.0), 0.0);
    }

    #[test]
    fn transparency_queries_agree_with_a_scan() {
        let tf = TransferFunction::preset("shapes").unwrap();
        let table = TransferTable::new(&tf, 255, 0.5);
        for lo in (0u16..=255).step_by(5) {
            for hi in (lo..=255).step_by(7) {
                let scan = (lo..=hi).all(|v| table.lookup(f32::from(v))[3] == 0.0)
                    && (0..20).all(|k| {
                        let v = f32::from(lo) + (f32::from(hi - lo)) * k as f32 / 19.0;
                        table.lookup(v)[3] == 0.0
                    });
                assert_eq!(table.is_transparent(lo, hi), scan, "[{lo}, {hi}]");
            }
        }
    }

    #[test]
    fn u8_tables_answer_transparency_from_raw_values_as_from_their_entries() {
        for (preset, domain) in [
            ("shapes", None),
            ("shapes", Some([40.0, 90.0])),
            ("ct-bone", Some([-20.0, 300.0])),
            ("grayscale", Some([200.0, 201.0])),
        ] {
            let mut tf = TransferFunction::preset(preset).unwrap();
            tf.domain = domain;
            let table = TransferTable::new(&tf, 255, 0.5);
            assert_eq!(table.raw_prefix.len(), 256);
            for lo in 0u16..=255 {
                for hi in lo..=255 {
                    let (a, b) = (table.index(f32::from(lo)), table.index(f32::from(hi)));
                    let by_entries = table.opaque_prefix[b + 1] == table.opaque_prefix[a];
                    assert_eq!(
                        table.is_transparent(lo, hi),
                        by_entries,
                        "{preset} {domain:?} [{lo}, {hi}]"
                    );
                }
            }
        }
        // u16 tables keep the conversions.
        let tf = TransferFunction::preset("shapes").unwrap();
        assert!(TransferTable::new(&tf, u16::MAX, 0.5).raw_prefix.is_empty());
    }

    #[test]
    fn a_table_visible_under_any_is_transparent_where_every_table_is() {
        for type_max in [255u16, 4095] {
            let domain = Some([0.0, f32::from(type_max)]);
            let tables: Vec<TransferTable> = ["shapes", "cloud", "ct-bone"]
                .into_iter()
                .map(|name| {
                    let mut tf = TransferFunction::preset(name).unwrap();
                    tf.domain = domain;
                    TransferTable::new(&tf, type_max, 0.5)
                })
                .collect();
            let all: Vec<&TransferTable> = tables.iter().collect();
            let union = TransferTable::visible_under_any(&all).unwrap();
            let step = usize::from(type_max / 64).max(1);
            let mut differ = 0;
            for lo in (0..=type_max).step_by(step) {
                for hi in (lo..=type_max).step_by(step) {
                    let every = tables.iter().all(|t| t.is_transparent(lo, hi));
                    assert_eq!(
                        union.is_transparent(lo, hi),
                        every,
                        "{type_max} [{lo}, {hi}]"
                    );
                    differ += usize::from(every != tables[0].is_transparent(lo, hi));
                }
            }
            // The first table alone would answer otherwise somewhere.
            assert!(differ > 0, "{type_max}");
        }
    }

    #[test]
    fn domain_maps_raw_values() {
        let mut tf = TransferFunction::preset("grayscale").unwrap();
        tf.domain = Some([1000.0, 2000.0]);
        let table = TransferTable::new(&tf, u16::MAX, 1.0);
        assert_eq!(table.lookup(500.0), [0.0; 4]);
        assert_eq!(table.lookup(3000.0)[0], 1.0);
        assert!((table.lookup(1500.0)[0] - 0.5).abs() < 1e-3);
    }

    #[test]
    fn bad_files_name_the_line() {
        let cases = [
            ("point 0 0 0 0", "takes 5 numbers"),
            ("point 0 0 0 0 2", "must lie in [0, 1]"),
            ("point 0 0 0 0 nan", "not a finite number"),
            ("domain 5 1\npoint 0 0 0 0 0", "increasing"),
            ("colour 1", "unknown keyword"),
            // The keyword is said, not its next word (it said "\"=\" is not a
            // finite number"), and TOML is named as such.
            ("foo = 1", "unknown keyword \"foo\""),
            ("version = 1\n[volume]", "this looks like TOML"),
            // One domain and one gradient line (the last one won).
            (
                "domain 0 1\ndomain 0 2\npoint 0 0 0 0 0",
                "line 2: a second domain line",
            ),
            (
                "gradient 0 1\ngradient 0 2\npoint 0 0 0 0 0",
                "a second gradient line",
            ),
            ("# nothing", "at least one control point"),
        ];
        for (text, needle) in cases {
            let e = TransferFunction::parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?} gave {e}");
        }
    }

    #[test]
    fn gradient_ramp_scales_opacity() {
        let mut tf = TransferFunction::preset("opaque").unwrap();
        tf.gradient_ramp = Some([0.1, 0.2]);
        let table = TransferTable::new(&tf, 255, 1.0);
        assert!(table.is_2d());
        assert_eq!(table.lookup_2d(200.0, 0.0)[3], 0.0);
        assert_eq!(table.lookup_2d(200.0, 0.3)[3], 1.0);
    }

    /// Walks a segment of `r` reference steps along which the value goes
    /// linearly from normalised `f` to `b` in fine steps, calling `visit` with
    /// each step's position along it, function value, the transmittance before
    /// it and its absorbed fraction; returns the transmittance after it.
    fn walk_segment(
        tf: &TransferFunction,
        f: f32,
        b: f32,
        r: f64,
        mut visit: impl FnMut(f64, [f32; 4], f64, f64),
    ) -> f64 {
        let n = 20_000;
        let mut transmittance = 1.0f64;
        for i in 0..n {
            let x = (i as f64 + 0.5) / n as f64;
            let v = f64::from(f) + (f64::from(b) - f64::from(f)) * x;
            let rgba = tf.evaluate(v as f32);
            let tau = -(1.0 - f64::from(rgba[3]).min(1.0 - 1e-12)).ln() * r / n as f64;
            let absorbed = 1.0 - (-tau).exp();
            visit(x, rgba, transmittance, absorbed);
            transmittance *= 1.0 - absorbed;
        }
        transmittance
    }

    /// The true emission–absorption integral of a segment of `r` reference steps
    /// whose normalised value goes linearly from `f` to `b`, by brute force
    /// (premultiplied RGB and opacity).
    fn brute_force(tf: &TransferFunction, f: f32, b: f32, r: f64) -> [f64; 4] {
        let mut color = [0.0f64; 3];
        let transmittance = walk_segment(tf, f, b, r, |_, [cr, cg, cb, _], t, absorbed| {
            for (acc, c) in color.iter_mut().zip([cr, cg, cb]) {
                *acc += t * absorbed * f64::from(c);
            }
        });
        [color[0], color[1], color[2], 1.0 - transmittance]
    }

    #[test]
    fn a_constant_segment_is_the_ordinary_corrected_lookup() {
        let tf = TransferFunction::preset("shapes").unwrap();
        for ratio in [0.25, 1.0, 2.0] {
            let table = TransferTable::new(&tf, 255, ratio);
            let pre = PreintegratedTable::new(&tf, 255, ratio);
            let bins = pre.bins();
            for i in 0..bins {
                let x = i as f32 / (bins - 1) as f32;
                let raw = x * 255.0;
                let [r, g, b, a] = tf.evaluate(x);
                let got = pre.lookup(raw, raw);
                let want = [r, g, b, corrected_alpha(a, ratio)];
                for c in 0..4 {
                    assert!(
                        (got[c] - want[c]).abs() < 2e-3,
                        "bin {i} ratio {ratio}: {got:?} vs {want:?}"
                    );
                }
                // The 1D table rounds to its own 1024 entries: close, not equal.
                let ordinary = table.lookup(raw);
                assert!(
                    (got[3] - ordinary[3]).abs() < 0.02,
                    "{got:?} vs {ordinary:?}"
                );
            }
        }
    }

    #[test]
    fn entries_match_a_brute_force_integral() {
        let tf = TransferFunction::preset("shapes").unwrap();
        let bins = 256;
        let pre = PreintegratedTable::with_bins(&tf, 255, 1.0, bins);
        let raw = |i: usize| i as f32 * 255.0 / (bins - 1) as f32;
        let norm = |i: usize| i as f32 / (bins - 1) as f32;
        // Across the glass ramp, through the orange band, a thin feature jumped
        // over (0.05 → 0.37 crosses the glass), downwards, and out of the domain.
        for (i, j) in [
            (20, 90),
            (100, 180),
            (13, 94),
            (180, 60),
            (0, 255),
            (150, 151),
        ] {
            let got = pre.lookup(raw(i), raw(j));
            let want = brute_force(&tf, norm(i), norm(j), 1.0);
            // Opacity is exact up to the table's quadrature.
            assert!(
                (f64::from(got[3]) - want[3]).abs() < 2e-3,
                "({i}, {j}): α {} vs {}",
                got[3],
                want[3]
            );
            // Colour ignores attenuation inside the segment: premultiplied within
            // a few per cent of the true integral at this step.
            for c in 0..3 {
                let premultiplied = f64::from(got[c] * got[3]);
                assert!(
                    (premultiplied - want[c]).abs() < 0.06,
                    "({i}, {j}) channel {c}: {premultiplied} vs {}",
                    want[c]
                );
            }
        }
        // A jump over the glass from transparent to transparent is not transparent.
        assert!(pre.lookup(raw(13), raw(94))[3] > 0.02);
        assert_eq!(pre.lookup(raw(0), raw(15))[3], 0.0);
    }

    /// The shares of a segment's front quarter, middle half and back quarter
    /// in its light: the drop in transmittance across each, as a fraction of
    /// the segment's opacity, by brute force.
    fn brute_force_shares(tf: &TransferFunction, f: f32, b: f32, r: f64) -> [f64; 3] {
        let mut shares = [0.0f64; 3];
        let transmittance = walk_segment(tf, f, b, r, |x, _, t, absorbed| {
            let part = if x < 0.25 {
                0
            } else if x < 0.75 {
                1
            } else {
                2
            };
            shares[part] += t * absorbed;
        });
        shares.map(|w| w / (1.0 - transmittance))
    }

    #[test]
    fn interpolated_lookups_blend_the_nearest_bins() {
        let tf = TransferFunction::preset("shapes").unwrap();
        let pre = PreintegratedTable::new(&tf, 255, 1.0);
        let bins = pre.bins();
        let raw = |i: f32| i * 255.0 / (bins - 1) as f32;
        // At bin centres: the entry itself (a transparent one's colour aside).
        for (i, j) in [(20, 90), (100, 180), (255, 60), (0, 0), (150, 151)] {
            let (f, b) = (raw(i as f32), raw(j as f32));
            let got = pre.entry_interpolated(pre.locate(f, b));
            let want = pre.lookup(f, b);
            let channels = if want[3] > 0.0 { 0..4 } else { 3..4 };
            for c in channels {
                assert!(
                    (got[c] - want[c]).abs() < 1e-5,
                    "({i}, {j}): {got:?} vs {want:?}"
                );
            }
        }
        // Between bins: opacity and premultiplied colour bilinear in the four.
        let (f, b) = (raw(120.25), raw(170.75));
        let got = pre.entry_interpolated(pre.locate(f, b));
        let e = |i: usize, j: usize| pre.lookup(raw(i as f32), raw(j as f32));
        let w = [
            (120, 170, 0.75 * 0.25),
            (120, 171, 0.75 * 0.75),
            (121, 170, 0.25 * 0.25),
            (121, 171, 0.25 * 0.75),
        ];
        let alpha: f32 = w.iter().map(|&(i, j, w)| w * e(i, j)[3]).sum();
        assert!((got[3] - alpha).abs() < 1e-5, "{got:?} vs {alpha}");
        for c in 0..3 {
            let premultiplied: f32 = w.iter().map(|&(i, j, w)| w * e(i, j)[3] * e(i, j)[c]).sum();
            assert!(
                (got[c] * got[3] - premultiplied).abs() < 1e-5,
                "channel {c}"
            );
        }
        // It differs from the nearest bins' entry there.
        assert_ne!(got, pre.lookup(f, b));
        // Beyond the domain, the computed entry; transparent stays transparent.
        assert_eq!(
            pre.entry_interpolated(pre.locate(300.0, 400.0)),
            pre.lookup(300.0, 400.0)
        );
        let transparent = pre.locate(raw(1.5), raw(10.5));
        assert_eq!(pre.entry_interpolated(transparent)[3], 0.0);
    }

    #[test]
    fn shading_weights_match_a_brute_force_integral() {
        let tf = TransferFunction::preset("shapes").unwrap();
        let bins = 256;
        let raw = |i: usize| i as f32 * 255.0 / (bins - 1) as f32;
        let norm = |i: usize| i as f32 / (bins - 1) as f32;
        for ratio in [1.0, 0.4] {
            let pre = PreintegratedTable::with_bins(&tf, 255, ratio, bins);
            // Into the glass ramp, across the orange band (opaque: its light
            // comes from where it starts), out of it backwards, a thin feature
            // jumped over, constant.
            for (i, j) in [
                (20, 90),
                (100, 180),
                (180, 100),
                (13, 94),
                (0, 255),
                (150, 150),
            ] {
                for halvings in 0..PIECE_LENGTHS {
                    let got = pre.shading_weights(pre.locate(raw(i), raw(j)), halvings);
                    let length = f64::from(ratio) / f64::from(1u32 << halvings);
                    let want = brute_force_shares(&tf, norm(i), norm(j), length);
                    for part in 0..3 {
                        assert!(
                            (f64::from(got[part]) - want[part]).abs() < 0.01,
                            "({i}, {j}) ratio {ratio} halved {halvings}: {got:?} vs {want:?}"
                        );
                    }
                    assert!((got.iter().sum::<f32>() - 1.0).abs() < 1e-4, "{got:?}");
                }
            }
        }
        // A segment that starts in the opaque end of the function sends most
        // of its light from its front; one going into it, from further back.
        let pre = PreintegratedTable::with_bins(&tf, 255, 1.0, bins);
        let [front, _, back] = pre.shading_weights(pre.locate(raw(255), raw(60)), 0);
        assert!(front > 0.7 && back < 0.01, "{front} {back}");
        let [front, _, back] = pre.shading_weights(pre.locate(raw(60), raw(255)), 0);
        assert!(back > front, "{front} {back}");
        // A transparent segment gets the even split.
        let even = pre.shading_weights(pre.locate(raw(0), raw(10)), 0);
        for (got, want) in even.into_iter().zip([0.25, 0.5, 0.25]) {
            assert!((got - want).abs() < 1e-4, "{even:?}");
        }
        // Beyond the domain they are computed, the function constant there
        // (opaque above it).
        let [front, _, _] = pre.shading_weights(pre.locate(300.0, 400.0), 1);
        assert!(front > 0.99, "{front}");
    }

    #[test]
    fn a_constant_colour_segment_is_exact_and_values_beyond_the_domain_are_constant() {
        let mut tf = TransferFunction::new(vec![
            p(0.0, [0.2, 0.4, 0.6], 0.0),
            p(1.0, [0.2, 0.4, 0.6], 0.9),
        ])
        .unwrap();
        tf.domain = Some([1000.0, 2000.0]);
        let pre = PreintegratedTable::new(&tf, u16::MAX, 0.5);
        let got = pre.lookup(1100.0, 1900.0);
        let want = brute_force(&tf, 0.1, 0.9, 0.5);
        for c in 0..3 {
            assert!(
                (f64::from(got[c] * got[3]) - want[c]).abs() < 2e-3,
                "{got:?} {want:?}"
            );
        }
        // From 500 (below the domain: value 0) to 1500 (0.5): half the segment is
        // transparent, the rest ramps from 0 to 0.5.
        let out = pre.lookup(500.0, 1500.0);
        let half = brute_force(&tf, 0.0, 0.5, 0.25);
        assert!(
            (f64::from(out[3]) - half[3]).abs() < 2e-3,
            "{out:?} vs {half:?}"
        );
        // Both beyond the top: the constant end value.
        let top = pre.lookup(2500.0, 3000.0);
        assert!((top[3] - corrected_alpha(0.9, 0.5)).abs() < 1e-4, "{top:?}");
    }

    #[test]
    fn a_union_table_shows_what_any_of_its_tables_shows() {
        let a = TransferTable::new(&TransferFunction::preset("shapes").unwrap(), 255, 0.7);
        let b = TransferTable::new(&TransferFunction::preset("ct-bone").unwrap(), 255, 0.7);
        let union = TransferTable::visible_under_any(&[&a, &b]).unwrap();
        for i in 0..TABLE_SIZE {
            let visible = |t: &TransferTable| t.visible_bits()[i / 32] >> (i % 32) & 1 == 1;
            let either = visible(&a) || visible(&b);
            assert_eq!(visible(&union), either, "entry {i}");
            assert_eq!(union.entries()[i][3] > 0.0, either, "entry {i}");
        }
        // Some entry is visible under one table only, both ways.
        let only = |x: &TransferTable, y: &TransferTable| {
            (0..TABLE_SIZE).any(|i| x.entries()[i][3] > 0.0 && y.entries()[i][3] <= 0.0)
        };
        assert!(only(&a, &b) && only(&b, &a));
        // Another domain maps values to other entries: no union.
        let mut tf = TransferFunction::preset("shapes").unwrap();
        tf.domain = Some([10.0, 200.0]);
        let c = TransferTable::new(&tf, 255, 0.7);
        assert!(TransferTable::visible_under_any(&[&a, &c]).is_none());
        assert!(TransferTable::visible_under_any(&[]).is_none());
        assert!(TransferTable::visible_somewhere_under_any(&[]).is_none());
    }

    #[test]
    fn a_filter_over_tables_of_other_domains_shows_every_value_any_of_them_shows() {
        let visible = |t: &TransferTable, v: f32| t.entries()[t.index(v)][3] > 0.0;
        for (type_max, domains) in [
            (255u16, [[10.0f32, 200.0], [60.0, 90.0], [0.0, 255.0]]),
            (
                65535,
                [[1000.0, 2400.0], [2300.0, 2310.0], [-500.0, 70000.0]],
            ),
        ] {
            let tables: Vec<TransferTable> = ["shapes", "ct-bone", "cloud"]
                .into_iter()
                .zip(domains)
                .map(|(name, domain)| {
                    let mut tf = TransferFunction::preset(name).unwrap();
                    tf.domain = Some(domain);
                    TransferTable::new(&tf, type_max, 0.7)
                })
                .collect();
            for n in [2, 3] {
                let all: Vec<&TransferTable> = tables[..n].iter().collect();
                assert!(TransferTable::visible_under_any(&all).is_none());
                let filter = TransferTable::visible_somewhere_under_any(&all).unwrap();
                let (mut shown, mut hidden) = (0, 0);
                // Values between the raw ones too (trilinear samples), and
                // beyond the type's range.
                let top = f32::from(type_max);
                let count = 200_000;
                for i in 0..=count {
                    let v = -0.1 * top + 1.2 * top * i as f32 / count as f32;
                    let any = all.iter().any(|t| visible(t, v));
                    assert!(!any || visible(&filter, v), "{type_max} {n} value {v}");
                    shown += usize::from(any);
                    hidden += usize::from(!visible(&filter, v));
                }
                // It filters: values no table shows are left out somewhere.
                assert!(shown > 0 && hidden > 0, "{type_max} {n}: {shown} {hidden}");
                for v in [f32::NAN, f32::NEG_INFINITY, f32::INFINITY] {
                    let any = all.iter().any(|t| visible(t, v));
                    assert!(!any || visible(&filter, v), "{v}");
                }
            }
        }
    }

    #[test]
    fn preintegrated_tables_are_cached_and_2d_functions_get_none() {
        let tf = TransferFunction::preset("rainbow").unwrap();
        let a = TransferTable::new(&tf, 255, 0.7).with_preintegration(&tf, 255);
        let b = TransferTable::new(&tf, 255, 0.7).with_preintegration(&tf, 255);
        let (pa, pb) = (a.preintegrated.unwrap(), b.preintegrated.unwrap());
        assert!(Arc::ptr_eq(&pa, &pb));
        let c = TransferTable::new(&tf, 255, 0.8).with_preintegration(&tf, 255);
        assert!(!Arc::ptr_eq(&pa, c.preintegrated.as_ref().unwrap()));
        let mut tf2 = tf.clone();
        tf2.gradient_ramp = Some([0.1, 0.2]);
        let d = TransferTable::new(&tf2, 255, 0.7).with_preintegration(&tf2, 255);
        assert!(d.preintegrated().is_none());
    }
}
