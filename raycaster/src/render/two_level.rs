//! Two-level compositing: local compositing inside a segment (a run of samples of
//! one object) and global compositing of the segments' results.
//!
//! The open segment's state ([`SegmentState`]) is part of the pixel state, so a
//! segment crossing brick boundaries — or tiles travelling between threads —
//! composites exactly as in the sequential renderer.

use std::sync::Arc;

use glam::Vec3;

use super::segments::{GlobalMode, ImportanceSource, LocalMode, Membership, SegmentScene};
use super::shading::{Light, Shading};
use super::transfer::{TransferFunction, TransferTable};

/// No object: the segment is not open.
pub const NO_OBJECT: u16 = u16::MAX;

/// The open segment of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentState {
    /// Object id of the open segment, or [`NO_OBJECT`].
    pub object: u16,
    /// Local premultiplied colour.
    pub color: [f32; 3],
    /// Local opacity.
    pub alpha: f32,
    /// Local value: maximum (MIP) or raw sum (average, X-ray).
    pub value: f32,
    /// Samples folded into `value`.
    pub count: u32,
    /// Accumulated importance (importance-aware compositing).
    pub importance: f32,
    /// First hit found (first-hit mode).
    pub hit: bool,
}

impl Default for SegmentState {
    fn default() -> Self {
        SegmentState {
            object: NO_OBJECT,
            color: [0.0; 3],
            alpha: 0.0,
            value: f32::NEG_INFINITY,
            count: 0,
            importance: 0.0,
            hit: false,
        }
    }
}

/// One object prepared for a frame.
#[derive(Clone, Debug)]
pub struct ObjectPlan {
    /// Its transfer function, sampled and corrected for the step (shared by the
    /// objects that use the same function, so the tables stay in cache).
    pub table: Arc<TransferTable>,
    /// Local mode.
    pub mode: LocalMode,
    /// First-hit iso-value in raw units.
    pub iso_raw: f32,
    /// Raw domain of its transfer function.
    pub domain: [f32; 2],
    /// Local DVR with a 1D transfer function (the fast path).
    dvr_1d: bool,
}

/// A segment scene prepared for a frame.
#[derive(Clone, Debug)]
pub struct SegmentPlan {
    /// Visible objects by id.
    objects: Vec<Option<ObjectPlan>>,
    /// The distinct transfer tables of the visible objects (emptiness tests ask
    /// each table once, however many objects share it).
    tables: Vec<Arc<TransferTable>>,
    /// Value layers in raw units (layer i = object i + 1), or `None` for labels.
    layers: Option<Vec<[f32; 2]>>,
    /// No two layers overlap (the usual case): a value in the current layer needs
    /// no other test.
    disjoint: bool,
    /// Global compositing.
    pub global: GlobalMode,
    /// Every visible object composites by emission–absorption: transparent
    /// samples contribute nothing, so empty space may be skipped and early ray
    /// termination can look inside the open segment.
    pub all_dvr: bool,
}

impl SegmentPlan {
    /// Prepares `scene` for samples of `type_max` with the data's raw `domain`.
    pub fn new(
        scene: &SegmentScene,
        type_max: u16,
        domain: [f32; 2],
        step_ratio: f32,
    ) -> SegmentPlan {
        let mut objects = vec![None; 256];
        let mut tables: Vec<(&TransferFunction, Arc<TransferTable>)> = Vec::new();
        for o in scene.objects.iter().filter(|o| o.visible) {
            let table = match tables.iter().find(|(tf, _)| **tf == o.transfer) {
                Some((_, t)) => t.clone(),
                None => {
                    let t = Arc::new(TransferTable::new(&o.transfer, type_max, step_ratio));
                    tables.push((&o.transfer, t.clone()));
                    t
                }
            };
            let d = o.transfer.domain.unwrap_or(domain);
            let iso = match o.mode {
                LocalMode::FirstHit { iso } => iso,
                _ => 0.5,
            };
            objects[o.id as usize] = Some(ObjectPlan {
                table,
                mode: o.mode,
                iso_raw: d[0] + iso * (d[1] - d[0]),
                domain: d,
                dvr_1d: o.mode == LocalMode::Dvr && o.transfer.gradient_ramp.is_none(),
            });
        }
        let layers = match &scene.membership {
            Membership::Layers(layers) => Some(
                layers
                    .iter()
                    .map(|[lo, hi]| {
                        [
                            domain[0] + lo * (domain[1] - domain[0]),
                            domain[0] + hi * (domain[1] - domain[0]),
                        ]
                    })
                    .collect(),
            ),
            Membership::Labels(_) => None,
        };
        let all_dvr = objects
            .iter()
            .flatten()
            .all(|o| o.mode.is_emission_absorption());
        let disjoint = layers.as_deref().is_none_or(|l: &[[f32; 2]]| {
            l.iter()
                .enumerate()
                .all(|(i, a)| l[i + 1..].iter().all(|b| a[1] <= b[0] || b[1] <= a[0]))
        });
        SegmentPlan {
            objects,
            tables: tables.into_iter().map(|(_, t)| t).collect(),
            layers,
            disjoint,
            global: scene.global,
            all_dvr,
        }
    }

    /// The visible object `id`, if any.
    #[inline]
    pub fn object(&self, id: u16) -> Option<&ObjectPlan> {
        self.objects.get(id as usize).and_then(Option::as_ref)
    }

    /// Whether ids come from a label volume.
    pub fn uses_labels(&self) -> bool {
        self.layers.is_none()
    }

    /// The layer object of raw value `v` (0 when in no layer); `current` (the open
    /// segment's object) is tried first, as consecutive samples mostly stay in it.
    #[inline]
    pub fn layer_of(&self, v: f32, current: u16) -> u16 {
        let layers = self.layers.as_deref().unwrap_or(&[]);
        let n = layers.len();
        if let Some(&[lo, hi]) = layers.get((current as usize).wrapping_sub(1)) {
            let last = current as usize == n;
            // Layers may overlap: the first match wins, so the hint only counts
            // when no earlier layer holds `v`.
            if v >= lo
                && (v < hi || (last && v <= hi))
                && (self.disjoint
                    || !layers[..current as usize - 1]
                        .iter()
                        .any(|&[l, h]| v >= l && v < h))
            {
                return current;
            }
        }
        for (i, &[lo, hi]) in layers.iter().enumerate() {
            if v >= lo && (v < hi || (i + 1 == n && v <= hi)) {
                return (i + 1) as u16;
            }
        }
        0
    }

    /// Whether every visible object is transparent over raw values `[lo, hi]`.
    pub fn is_transparent(&self, lo: u16, hi: u16) -> bool {
        self.tables.iter().all(|t| t.is_transparent(lo, hi))
    }
}

/// What a sample offers the local modes.
pub struct SampleContext {
    /// Raw value.
    pub value: f32,
    /// Gradient (normalised value per voxel) when the mode needs it.
    pub gradient: Vec3,
    /// Unit ray direction.
    pub view_dir: Vec3,
    /// Distance from the eye normalised by the ray's exit distance.
    pub depth: f32,
    /// Step in reference steps.
    pub step_ratio: f32,
    /// The part of a step this sample stands for (below 1 only for a ray's last).
    pub fraction: f32,
}

impl ObjectPlan {
    /// Whether a sample of raw value `v` leaves the segment unchanged whatever its
    /// gradient: a transparent sample (1D transfer function) of an object that
    /// composites by opacity (DVR, context-preserving, silhouette, importance —
    /// importance-aware compositing with `α_s = 0` keeps colour, opacity and
    /// importance).
    #[inline]
    pub fn ignores(&self, v: f32) -> bool {
        match self.mode {
            LocalMode::Dvr
            | LocalMode::ContextPreserving { .. }
            | LocalMode::Silhouette
            | LocalMode::Importance { .. } => !self.table.is_2d() && self.table.lookup(v)[3] <= 0.0,
            LocalMode::Mip
            | LocalMode::Average
            | LocalMode::XRay { .. }
            | LocalMode::FirstHit { .. } => false,
        }
    }

    /// Whether this object's mode needs the gradient at samples it sees.
    pub fn needs_gradient(&self, shading: bool) -> bool {
        match self.mode {
            LocalMode::Dvr | LocalMode::FirstHit { .. } => shading || self.table.is_2d(),
            LocalMode::Importance { .. }
            | LocalMode::ContextPreserving { .. }
            | LocalMode::Silhouette => true,
            LocalMode::Mip | LocalMode::Average | LocalMode::XRay { .. } => false,
        }
    }

    /// The plain DVR fast path (local DVR with a 1D transfer function): folds the
    /// sample and returns `Some(contributed)`, or `None` when the object needs
    /// [`Self::sample`].
    #[inline]
    pub fn sample_dvr_1d(
        &self,
        seg: &mut SegmentState,
        v: f32,
        fraction: f32,
        shade: impl FnOnce([f32; 3]) -> [f32; 3],
    ) -> Option<bool> {
        if !self.dvr_1d {
            return None;
        }
        let [r, g, b, a] = self.table.lookup(v);
        if a <= 0.0 {
            return Some(false);
        }
        let a = if fraction < 1.0 {
            1.0 - (1.0 - a).powf(fraction)
        } else {
            a
        };
        over(seg, shade([r, g, b]), a);
        Some(true)
    }

    /// Folds one sample into the open segment `seg`.
    pub fn sample(&self, seg: &mut SegmentState, s: &SampleContext, shading: Option<&Shading>) {
        let t = &self.table;
        match self.mode {
            LocalMode::Mip => {
                seg.value = seg.value.max(s.value);
                seg.count += 1;
            }
            LocalMode::Average | LocalMode::XRay { .. } => {
                seg.value = if seg.count == 0 {
                    s.value
                } else {
                    seg.value + s.value
                };
                seg.count += 1;
            }
            LocalMode::FirstHit { .. } => {
                if !seg.hit && s.value >= self.iso_raw {
                    let [r, g, b, _] = t.lookup(self.iso_raw);
                    seg.color = shade(shading, [r, g, b], s);
                    seg.alpha = 1.0;
                    seg.hit = true;
                }
            }
            LocalMode::Dvr => {
                let Some((color, a)) = classify(t, s, shading) else {
                    return;
                };
                over(seg, color, a);
            }
            LocalMode::ContextPreserving { kt, ks } => {
                let Some((color, a)) = classify(t, s, shading) else {
                    return;
                };
                // α = α_tf · |g|^((κt · s(P) · (1 − |P − E|) · (1 − α_{i−1}))^κs)
                let intensity = shading_intensity(shading, s);
                let exponent = (kt * intensity * (1.0 - s.depth) * (1.0 - seg.alpha))
                    .max(0.0)
                    .powf(ks);
                let a = a * s.gradient.length().min(1.0).powf(exponent);
                over(seg, color, a);
            }
            LocalMode::Silhouette => {
                let Some((color, a)) = classify(t, s, None) else {
                    return;
                };
                over(seg, tone_and_silhouette(color, s), a);
            }
            LocalMode::Importance { source } => {
                let Some((color, a)) = classify(t, s, shading) else {
                    return;
                };
                let importance = importance(
                    source,
                    s,
                    (s.value - self.domain[0]) / (self.domain[1] - self.domain[0]),
                );
                let premultiplied = color.map(|c| c * a);
                let (c, alpha, i) = importance_composite(
                    seg.color,
                    seg.alpha,
                    seg.importance,
                    premultiplied,
                    a,
                    importance,
                );
                seg.color = c;
                seg.alpha = alpha;
                seg.importance = i;
            }
        }
    }

    /// The finished segment's premultiplied colour and opacity.
    pub fn result(&self, seg: &SegmentState, step_ratio: f32) -> ([f32; 3], f32) {
        let classify_value = |v: f32| {
            let [r, g, b, _] = self.table.lookup(v);
            let a = self.table.alpha0(v);
            ([r * a, g * a, b * a], a)
        };
        match self.mode {
            LocalMode::Mip if seg.count > 0 => classify_value(seg.value),
            LocalMode::Average if seg.count > 0 => classify_value(seg.value / seg.count as f32),
            LocalMode::XRay { gain } if seg.count > 0 => {
                let mean = seg.value / seg.count as f32;
                let [r, g, b, _] = self.table.lookup(mean);
                let width = self.domain[1] - self.domain[0];
                let sum = (seg.value - seg.count as f32 * self.domain[0]) / width * step_ratio;
                let a = 1.0 - (-gain * sum.max(0.0)).exp();
                ([r * a, g * a, b * a], a)
            }
            LocalMode::Mip | LocalMode::Average | LocalMode::XRay { .. } => ([0.0; 3], 0.0),
            _ => (seg.color, seg.alpha),
        }
    }
}

/// Colour (shaded when asked) and step-corrected opacity of a sample, or `None`
/// when it is transparent.
fn classify(
    t: &TransferTable,
    s: &SampleContext,
    shading: Option<&Shading>,
) -> Option<([f32; 3], f32)> {
    let [r, g, b, a] = if t.is_2d() {
        t.lookup_2d(s.value, s.gradient.length(), s.step_ratio)
    } else {
        t.lookup(s.value)
    };
    // The last sample of a ray stands for a fraction of a step.
    let a = if s.fraction < 1.0 {
        1.0 - (1.0 - a).powf(s.fraction)
    } else {
        a
    };
    (a > 0.0).then(|| (shade(shading, [r, g, b], s), a))
}

fn shade(shading: Option<&Shading>, color: [f32; 3], s: &SampleContext) -> [f32; 3] {
    match shading {
        Some(sh) => sh.shade(color, s.gradient, s.view_dir),
        None => color,
    }
}

/// `c += (1 − α)·a·color; α += (1 − α)·a`.
#[inline]
fn over(seg: &mut SegmentState, color: [f32; 3], a: f32) {
    let w = (1.0 - seg.alpha) * a;
    for (acc, c) in seg.color.iter_mut().zip(color) {
        *acc += w * c;
    }
    seg.alpha += w;
}

fn light_vectors(s: &SampleContext, shading: Option<&Shading>) -> (Vec3, Vec3) {
    let to_light = match shading.map(|sh| sh.light) {
        Some(Light::Fixed(d)) => -d.normalize_or_zero(),
        _ => -s.view_dir,
    };
    let half = (to_light - s.view_dir).normalize_or_zero();
    (to_light, half)
}

/// Blinn-Phong intensity `c_d|L·N| + c_s|H·N|^c_e + c_a` (1 without shading).
fn shading_intensity(shading: Option<&Shading>, s: &SampleContext) -> f32 {
    let Some(sh) = shading else { return 1.0 };
    let n = s.gradient.normalize_or_zero();
    let (l, h) = light_vectors(s, shading);
    sh.diffuse * n.dot(l).abs() + sh.specular * n.dot(h).abs().powf(sh.shininess) + sh.ambient
}

/// Gooch-style tone shading (cool to warm by `N·L`) and silhouette darkening
/// `color·exp(−8·sil)`, `sil = smoothstep(0.6, 1, 1 − |V·N|)`.
fn tone_and_silhouette(color: [f32; 3], s: &SampleContext) -> [f32; 3] {
    const COOL: [f32; 3] = [0.3, 0.35, 0.6];
    const WARM: [f32; 3] = [1.0, 0.9, 0.7];
    let magnitude = s.gradient.length();
    if magnitude <= 1e-3 {
        return color;
    }
    let n = s.gradient / magnitude;
    let ndl = n.dot(-s.view_dir);
    let k = (1.0 + ndl.abs()) / 2.0;
    let sil = smoothstep(0.6, 1.0, 1.0 - ndl.abs());
    let dark = (-8.0 * sil).exp();
    [0, 1, 2].map(|i| color[i] * (COOL[i] + (WARM[i] - COOL[i]) * k) * dark)
}

fn importance(source: ImportanceSource, s: &SampleContext, normalised: f32) -> f32 {
    let g = s.gradient.length().min(1.0);
    let n = s.gradient.normalize_or_zero();
    match source {
        ImportanceSource::Constant(w) => w,
        ImportanceSource::Intensity(w) => w * normalised,
        ImportanceSource::Gradient(w) => w * g,
        ImportanceSource::Silhouette([p1, p2, p3]) => {
            g.powf(p1) * smoothstep(p2, p3, 1.0 - n.dot(s.view_dir).abs())
        }
        ImportanceSource::Lighting([p1, p2, p3]) => {
            let (l, h) = light_vectors(s, None);
            3.0 - n.dot(h).abs().powf(p1) - n.dot(l).abs().powf(p2) - (1.0 - g).powf(p3)
        }
    }
}

/// One step of importance-aware compositing (de Moura Pinto & Freitas) of a
/// sample with premultiplied colour `cs`, opacity `a_s` and importance `i_s` into
/// the accumulation `(c_i, a_i, i_i)`:
/// `vis = 1 − exp(I_i − I_s)`; `m = 1` if `I_s ≤ I_i` or `1 − α_i ≥ vis`, else
/// `(1 − vis)/α_i`; `C' = m·C_i + (1 − m·α_i)·C_s`; `α' = m·α_i(1 − α_s) + α_s`;
/// `α_{i+1} = α_i(1 − α_s) + α_s`; `C_{i+1} = α_{i+1}·C'/α'`;
/// `I_{i+1} = max(I_i, ln(α_s + (1 − α_s)·exp(I_i − I_s)) + I_s)`.
pub fn importance_composite(
    c_i: [f32; 3],
    a_i: f32,
    i_i: f32,
    c_s: [f32; 3],
    a_s: f32,
    i_s: f32,
) -> ([f32; 3], f32, f32) {
    let vis = 1.0 - (i_i - i_s).exp();
    let m = if i_s <= i_i || 1.0 - a_i >= vis {
        1.0
    } else {
        (1.0 - vis) / a_i
    };
    let a_mod = m * a_i * (1.0 - a_s) + a_s;
    let a_next = a_i * (1.0 - a_s) + a_s;
    let c_next = if a_mod == 0.0 {
        [0.0; 3]
    } else {
        [0, 1, 2].map(|k| a_next * (m * c_i[k] + (1.0 - m * a_i) * c_s[k]) / a_mod)
    };
    let i_next = i_i.max((a_s + (1.0 - a_s) * (i_i - i_s).exp()).ln() + i_s);
    (c_next, a_next, i_next)
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Composites the open segment of `(color, alpha)` globally and closes it.
pub fn close_segment(
    plan: &SegmentPlan,
    seg: &mut SegmentState,
    color: &mut [f32; 3],
    alpha: &mut f32,
    step_ratio: f32,
) {
    if let Some(object) = plan.object(seg.object) {
        let (c, a) = object.result(seg, step_ratio);
        match plan.global {
            GlobalMode::Dvr => {
                let w = 1.0 - *alpha;
                for (acc, v) in color.iter_mut().zip(c) {
                    *acc += w * v;
                }
                *alpha += w * a;
            }
            GlobalMode::Mip => {
                if a > *alpha {
                    *color = c;
                    *alpha = a;
                }
            }
        }
    }
    *seg = SegmentState::default();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn importance_at_or_below_the_accumulated_one_is_plain_compositing() {
        let (ci, ai) = ([0.2, 0.1, 0.05], 0.4);
        let (cs, a_s) = ([0.3, 0.3, 0.3], 0.5);
        let (c, a, i) = importance_composite(ci, ai, 2.0, cs, a_s, 1.5);
        for k in 0..3 {
            assert!((c[k] - (ci[k] + (1.0 - ai) * cs[k])).abs() < 1e-6);
        }
        assert!((a - (ai + (1.0 - ai) * a_s)).abs() < 1e-6);
        assert!(i >= 2.0);
    }

    #[test]
    fn an_opaque_sample_sets_the_importance_and_a_more_important_one_shows_through() {
        let (_, a, i) = importance_composite([0.5; 3], 0.9, 0.2, [0.1; 3], 1.0, 3.0);
        assert!((i - 3.0).abs() < 1e-6, "{i}");
        assert!((a - 1.0).abs() < 1e-6);
        // A more important sample behind a dense, unimportant front: its colour
        // weighs more than plain compositing would give it.
        let (c, _, _) = importance_composite([0.9, 0.0, 0.0], 0.9, 0.0, [0.0, 0.5, 0.0], 0.5, 5.0);
        let plain = 0.1 * 0.5;
        assert!(c[1] > plain * 2.0, "{c:?}");
    }
}
