//! Two-level compositing (Hauser et al. 2001): a compositor that owns one local
//! compositor per object, composites each segment (a run of samples of one
//! object) locally and the segments' results globally.
//!
//! The open segment is part of the pixel state ([`SegmentedState`]), so a segment
//! crossing brick boundaries — or tiles travelling between threads — composites
//! exactly as in the sequential renderer.

use std::sync::Arc;

use super::clip::ClipRegion;
use super::compositor::{Compositor, SampleGradient, SamplePoint, SampleSite};
use super::gather::shades_per_lane;
use super::gather_gradients::{march_gradients, march_gradients_every_sample};
use super::gather_layers::march_shaded_layers;
use super::gather_values::march_values;
use super::local::{Accumulation, LocalCompositor};
use super::optics::over_premultiplied;
use super::packet::PacketWork;
use super::segments::{GlobalMode, LocalMode, Membership, SegmentScene};
use super::shading::Shading;
use super::simd::SimdLevel;
use super::state_buffer::{Reader, StateCodec, put_f32, put_u32};
use super::transfer::{TransferFunction, TransferTable};
use crate::volume::Sample;

/// The packet kernel of a two-level scene.
#[derive(Clone, Debug)]
enum SceneKernel {
    /// The value kernel: gathered values, a gradient read through the cell
    /// cache where an object asks for one.
    Values,
    /// Every visible object is DVR that reads each visible sample's gradient
    /// (shaded, or a 2D function), and segments composite by maximum (not
    /// [`TwoLevel::direct`]), so the cell cache reads each value's corners
    /// anyway and gathered values alone only add (`shapes-layers10`: 0.249 s
    /// against 0.214 s for the scalar loop): the gradient kernel folding every
    /// sample, with a table visible where any object's is (0.202 s).
    Gradients(Arc<TransferTable>),
    /// The same scenes where a table is pre-integrated or the tables map
    /// values differently: the scalar loop.
    Scalar,
    /// A scene composited directly ([`TwoLevel::direct`]) whose objects read
    /// each visible sample's gradient: the gradient kernel folding the
    /// samples visible under any object's table, each with its gradient
    /// gathered (the others composite nothing).
    VisibleGradients(Arc<TransferTable>),
    /// A layer scene composited directly whose objects are shaded DVR with
    /// 1D tables and no clip regions: the plain DVR gather kernel, each lane
    /// taking its layer's table entry ([`march_shaded_layers`]), with the
    /// table visible where any object's is (objects of domains of their own:
    /// each lane's index, gradient factor and fade its own, `layer_looks`).
    ShadedLayers(Arc<TransferTable>, Shading),
}

/// No object: no segment is open.
pub(crate) const NO_OBJECT: u16 = u16::MAX;

/// The ray's one segment of a scene composited directly
/// ([`TwoLevel::direct`]): every object's samples fold into it.
const EVERY_OBJECT: u16 = u16::MAX - 1;

/// A pixel of a two-level frame: the segments composited so far and the open one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SegmentedState {
    /// Globally composited premultiplied colour.
    color: [f32; 3],
    /// Globally composited opacity.
    alpha: f32,
    /// Object of the open segment, or [`NO_OBJECT`].
    object: u16,
    /// The open segment's local accumulation.
    segment: Accumulation,
    /// Depth of the first local hit, `∞` without one.
    depth: f32,
    /// One past the last sample index folded (skipped samples leave a gap).
    next_index: u32,
}

impl SegmentedState {
    /// The ray's one segment of a scene composited directly, which every
    /// object's samples fold into.
    #[inline(always)]
    pub(crate) fn direct_segment(&mut self) -> &mut Accumulation {
        debug_assert_eq!(self.object, EVERY_OBJECT);
        &mut self.segment
    }
}

impl StateCodec for SegmentedState {
    const BYTES: usize = 26 + Accumulation::BYTES;

    fn encode(&self, out: &mut Vec<u8>) {
        for v in [self.color[0], self.color[1], self.color[2], self.alpha] {
            put_f32(out, v);
        }
        out.extend_from_slice(&self.object.to_le_bytes());
        self.segment.encode(out);
        put_f32(out, self.depth);
        put_u32(out, self.next_index);
    }

    fn decode(r: &mut Reader<'_>) -> Self {
        SegmentedState {
            color: [r.f32(), r.f32(), r.f32()],
            alpha: r.f32(),
            object: r.u16(),
            segment: Accumulation::decode(r),
            depth: r.f32(),
            next_index: r.u32(),
        }
    }
}

/// A segment scene prepared for a frame: the two-level compositor.
#[derive(Clone, Debug)]
pub(crate) struct TwoLevel {
    /// Visible objects' local compositors, by id.
    objects: Vec<Option<LocalCompositor>>,
    /// The distinct transfer tables of the visible objects (emptiness tests ask
    /// each table once, however many objects share it).
    tables: Vec<Arc<TransferTable>>,
    /// Value layers in raw units (layer i = object i + 1; a layer from 0 or to 1
    /// is open below or above), or `None` for labels.
    layers: Option<Vec<[f32; 2]>>,
    /// No two layers overlap (the usual case): a value in the current layer needs
    /// no other test.
    disjoint: bool,
    /// Global compositing.
    global: GlobalMode,
    /// A table visible where any visible object's is, when their tables map
    /// values alike: one test of a range for all.
    visible_under_any: Option<Arc<TransferTable>>,
    /// Every visible object is plain DVR (no pre-integrated table) and the
    /// segments composite by DVR too: "over" is associative, so compositing
    /// each segment locally and the segments globally is compositing every
    /// sample directly with its object's table. The ray keeps one open
    /// segment ([`EVERY_OBJECT`]) that each object's samples fold into; a
    /// change of object closes nothing, and transparent samples (of any
    /// object, or of none) need not be seen.
    direct: bool,
    /// What marches the scene on a packet level.
    kernel: SceneKernel,
    /// Per object id, what its gradients are multiplied by: the frame's domain
    /// over its function's (1 without a domain of its own); empty when all
    /// are 1.
    gradient_factors: Vec<f32>,
    /// Per layer id (0: no layer), the table of its visible object, for
    /// [`SceneKernel::ShadedLayers`] (empty otherwise).
    layer_tables: Vec<Option<Arc<TransferTable>>>,
    /// Per layer id, for [`SceneKernel::ShadedLayers`] of objects whose
    /// functions have domains of their own: its object's gradient factor and
    /// shading fade rate (`[factor, rate]`; each lane's entry then read at
    /// its table's own index). Empty where every object's are the frame's.
    layer_looks: Vec<[f32; 2]>,
    /// Per object id: where the object shows (voxels of the level rendered),
    /// `None` everywhere; empty when no object has a region.
    clips: Vec<Option<ClipRegion>>,
    /// The frame's early-termination opacity, `∞` without: pre-integrated DVR
    /// segments stop where the global opacity reaches it
    /// ([`TwoLevel::segment_stop`]).
    stop_at: f32,
}

impl TwoLevel {
    /// Prepares `scene` for samples of `type_max` with the data's raw `domain`,
    /// opacities corrected for `step_ratio` reference steps; `shading` as the
    /// frame gives it (each object's fade widened to its function's
    /// quantisation, [`Shading::covering_quantum`]); `preintegrate` gives
    /// the tables of DVR objects pre-integrated segments; objects' clip regions
    /// are moved to a level whose voxels span `level_scale` level-0 voxels;
    /// `early_termination` is the frame's threshold; X-ray objects without a
    /// gain take the automatic one of a volume whose diagonal is `diagonal`
    /// level-0 voxels.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &SegmentScene,
        type_max: u16,
        domain: [f32; 2],
        step_ratio: f32,
        shading: Option<Shading>,
        preintegrate: bool,
        level_scale: f32,
        early_termination: Option<f32>,
        diagonal: f32,
    ) -> TwoLevel {
        let mut objects = vec![None; 256];
        let mut object_tables: Vec<Option<Arc<TransferTable>>> = vec![None; 256];
        let mut gradient_factors = vec![1.0f32; 256];
        let mut looks = vec![[1.0f32, 0.0]; 256];
        // Shading fades in over the data's quantisation at least, in the
        // units of each object's function.
        let covering = |[d0, d1]: [f32; 2]| shading.map(|s| s.covering_quantum(1.0 / (d1 - d0)));
        // An object's function without a domain of its own spans the frame's
        // (the data's fitted values, or `--domain`), as the plain modes' does.
        let spanning = |tf: &TransferFunction| {
            let mut tf = tf.clone();
            tf.domain = Some(tf.domain.unwrap_or(domain));
            tf
        };
        let mut tables: Vec<(&TransferFunction, Arc<TransferTable>)> = Vec::new();
        for o in scene.objects.iter().filter(|o| o.visible) {
            let table = match tables.iter().find(|(tf, _)| **tf == o.transfer) {
                Some((_, t)) => t.clone(),
                None => {
                    let transfer = spanning(&o.transfer);
                    let mut t = TransferTable::new(&transfer, type_max, step_ratio);
                    // One table per function: pre-integrated when any DVR object
                    // uses it (other modes ignore that part).
                    let dvr = scene
                        .objects
                        .iter()
                        .any(|p| p.visible && p.mode == LocalMode::Dvr && p.transfer == o.transfer);
                    if preintegrate && dvr {
                        t = t.with_preintegration(&transfer, type_max);
                    }
                    let t = Arc::new(t);
                    tables.push((&o.transfer, t.clone()));
                    t
                }
            };
            let d = o.transfer.domain.unwrap_or(domain);
            // Gradients come in the frame domain's units; an object whose
            // function has a domain of its own reads them in its own, as
            // the plain mode of that function does.
            gradient_factors[o.id as usize] = (domain[1] - domain[0]) / (d[1] - d[0]);
            looks[o.id as usize] = [
                gradient_factors[o.id as usize],
                covering(d).map_or(0.0, |s| s.fade_rate()),
            ];
            object_tables[o.id as usize] = Some(table.clone());
            objects[o.id as usize] = Some(LocalCompositor::new(
                o.mode,
                table,
                covering(d),
                d,
                diagonal,
            ));
        }
        let layers: Option<Vec<[f32; 2]>> = match &scene.membership {
            Membership::Layers(layers) => Some(
                layers
                    .iter()
                    .map(|&[lo, hi]| {
                        // A layer from 0 takes the values below the domain too,
                        // one to 1 those above it, as a transfer function is
                        // constant beyond its domain: `[0, 1]` holds every value.
                        let raw = |x: f32| domain[0] + x * (domain[1] - domain[0]);
                        [
                            if lo <= 0.0 {
                                f32::NEG_INFINITY
                            } else {
                                raw(lo)
                            },
                            if hi >= 1.0 { f32::INFINITY } else { raw(hi) },
                        ]
                    })
                    .collect(),
            ),
            Membership::Labels(_) => None,
        };
        let all_dvr = scene
            .objects
            .iter()
            .filter(|o| o.visible)
            .all(|o| o.mode == LocalMode::Dvr);
        let disjoint = layers.as_deref().is_none_or(|l: &[[f32; 2]]| {
            l.iter()
                .enumerate()
                .all(|(i, a)| l[i + 1..].iter().all(|b| a[1] <= b[0] || b[1] <= a[0]))
        });
        let mut clips = Vec::new();
        if scene.objects.iter().any(|o| !o.clip.is_empty()) {
            clips = vec![None; 256];
            for o in scene.objects.iter().filter(|o| !o.clip.is_empty()) {
                clips[o.id as usize] = Some(o.clip.at_level(level_scale));
            }
        }
        if gradient_factors.iter().all(|&f| f == 1.0) {
            gradient_factors.clear();
        }
        let gradients_everywhere = shading.is_some() || tables.iter().any(|(_, t)| t.is_2d());
        let all: Vec<&TransferTable> = tables.iter().map(|(_, t)| &**t).collect();
        let preintegrated = all.iter().any(|t| t.preintegrated().is_some());
        let visible_under_any = TransferTable::visible_under_any(&all).map(Arc::new);
        // The kernels' filter: exact where the tables share a map, else a
        // superset (objects with domains of their own).
        let filter = match &visible_under_any {
            Some(exact) => Some(Arc::clone(exact)),
            None => TransferTable::visible_somewhere_under_any(&all).map(Arc::new),
        };
        let direct = all_dvr && scene.global == GlobalMode::Dvr && !preintegrated;
        // Objects' tables map values apart, or their gradients are read
        // rescaled: the layer kernel takes each lane's own.
        let per_lane = visible_under_any.is_none() || !gradient_factors.is_empty();
        let kernel = if !(all_dvr && gradients_everywhere) {
            SceneKernel::Values
        } else if preintegrated {
            SceneKernel::Scalar
        } else {
            let layered = layers.is_some() && clips.is_empty() && all.iter().all(|t| !t.is_2d());
            // Objects of domains of their own: each lane's table index,
            // gradient factor and fade its own (AVX2, a whole exponent).
            let layered = layered && (!per_lane || shading.as_ref().is_some_and(shades_per_lane));
            match (filter, covering(domain)) {
                (None, _) => SceneKernel::Scalar,
                (Some(t), Some(shading)) if direct && layered => {
                    SceneKernel::ShadedLayers(t, shading)
                }
                (Some(t), _) if direct => SceneKernel::VisibleGradients(t),
                (Some(t), _) => SceneKernel::Gradients(t),
            }
        };
        let (layer_tables, layer_looks) = match (&kernel, &layers) {
            (SceneKernel::ShadedLayers(..), Some(layers)) => {
                object_tables.truncate(layers.len() + 1);
                looks.truncate(layers.len() + 1);
                (object_tables, if per_lane { looks } else { Vec::new() })
            }
            _ => (Vec::new(), Vec::new()),
        };
        TwoLevel {
            clips,
            objects,
            kernel,
            tables: tables.into_iter().map(|(_, t)| t).collect(),
            layers,
            disjoint,
            global: scene.global,
            direct,
            gradient_factors,
            layer_tables,
            layer_looks,
            visible_under_any,
            stop_at: early_termination.unwrap_or(f32::INFINITY),
        }
    }

    /// The local opacity at which the open segment takes the global opacity
    /// (`global_alpha` before it) to the frame's threshold: where its
    /// pre-integrated DVR pieces stop ([`LocalCompositor::sample_in_segment`]).
    #[inline]
    fn segment_stop(&self, global_alpha: f32) -> f32 {
        match self.global {
            GlobalMode::Dvr if global_alpha >= self.stop_at => 0.0,
            GlobalMode::Dvr => (self.stop_at - global_alpha) / (1.0 - global_alpha),
            GlobalMode::Mip => self.stop_at,
        }
    }

    /// The visible object `id`, if any.
    #[inline]
    fn object(&self, id: u16) -> Option<&LocalCompositor> {
        self.objects.get(id as usize).and_then(Option::as_ref)
    }

    /// Folds sample `s` into `segment` by `object` (of id `id`), its
    /// gradients in the object's units; `stop` as
    /// [`LocalCompositor::sample_in_segment`].
    #[inline(always)]
    fn fold<T: Sample>(
        &self,
        id: u16,
        object: &LocalCompositor,
        segment: &mut Accumulation,
        s: &SamplePoint<'_, T>,
        stop: f32,
    ) {
        match self.gradient_factors.get(id as usize) {
            Some(&factor) if factor != 1.0 => {
                fold_rescaled(object, segment, s, stop, factor);
            }
            _ => object.sample_in_segment(segment, s, stop),
        }
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

    /// The layer of raw value `v` (tried in layer `hint` first) and the colour
    /// and step-corrected opacity its object's table gives entry `index`
    /// (`index(v)`; every table maps values alike); transparent in no layer
    /// or a hidden object's. For [`SceneKernel::ShadedLayers`].
    #[inline(always)]
    pub(crate) fn layer_entry(&self, v: f32, hint: u16, index: usize) -> (u16, [f32; 4]) {
        let layer = self.layer_of(v, hint);
        let entry = match self.layer_tables.get(layer as usize) {
            Some(Some(table)) => table.entries()[index],
            _ => [0.0; 4],
        };
        (layer, entry)
    }

    /// [`Self::layer_entry`] of a scene whose objects' functions have
    /// domains of their own: the entry at the layer's table's own index of
    /// `v`, with the object's gradient factor and fade rate
    /// (`layer_looks`; `[1, 0]` in no layer).
    #[inline(always)]
    pub(crate) fn layer_entry_own(&self, v: f32, hint: u16) -> (u16, [f32; 4], [f32; 2]) {
        let layer = self.layer_of(v, hint);
        match self.layer_tables.get(layer as usize) {
            Some(Some(table)) => (
                layer,
                table.entries()[table.index(v)],
                self.layer_looks[layer as usize],
            ),
            _ => (layer, [0.0; 4], [1.0, 0.0]),
        }
    }

    /// Whether [`SceneKernel::ShadedLayers`] takes each lane's index, factor
    /// and rate ([`Self::layer_entry_own`]).
    #[inline]
    pub(crate) fn layers_per_lane(&self) -> bool {
        !self.layer_looks.is_empty()
    }

    /// Whether every visible object is transparent over raw values `[lo, hi]`.
    #[inline]
    pub fn is_transparent(&self, lo: u16, hi: u16) -> bool {
        match &self.visible_under_any {
            Some(table) => table.is_transparent(lo, hi),
            None => self.tables.iter().all(|t| t.is_transparent(lo, hi)),
        }
    }
}

/// [`TwoLevel::fold`] of an object whose gradients are the frame's times
/// `factor`: the sample's own gradient (read now: it is a function of the
/// position, the same bits whichever kernel read it) and those read near it
/// (pre-integrated pieces) rescaled.
#[inline(never)]
fn fold_rescaled<T: Sample>(
    object: &LocalCompositor,
    segment: &mut Accumulation,
    s: &SamplePoint<'_, T>,
    stop: f32,
    factor: f32,
) {
    let site = SampleSite {
        gradient_scale: s.site.gradient_scale * factor,
        ..*s.site
    };
    let point = SamplePoint {
        value: s.value,
        position: s.position,
        index: s.index,
        fraction: s.fraction,
        gradient: SampleGradient::Known(s.gradient() * factor),
        site: &site,
    };
    object.sample_in_segment(segment, &point, stop);
}

impl Compositor for TwoLevel {
    type State = SegmentedState;

    fn start(&self) -> SegmentedState {
        SegmentedState {
            color: [0.0; 3],
            alpha: 0.0,
            object: if self.direct { EVERY_OBJECT } else { NO_OBJECT },
            segment: Accumulation::starting_at(0.0),
            depth: f32::INFINITY,
            next_index: 0,
        }
    }

    /// Empty for every object, when the scene is composited directly
    /// ([`TwoLevel::direct`]: transparent samples change nothing). Otherwise
    /// every sample is seen: a skipped run could join two segments that a
    /// sample of no object (or another object) between them splits (under
    /// `global = "mip"` the pair's maximum differs from the whole's), or have
    /// a pre-integrated step after it composited with the next object's
    /// table, so the picture would change with the brick and cell layout.
    #[inline]
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        self.direct && self.is_transparent(lo, hi)
    }

    /// When a DVR object's table is pre-integrated.
    fn composites_segments(&self) -> bool {
        self.tables.iter().any(|t| t.preintegrated().is_some())
    }

    /// Samples are folded into the open segment of their object; a change of
    /// object closes the segment (composited globally).
    #[inline]
    fn sample<T: Sample>(&self, st: &mut SegmentedState, s: &SamplePoint<'_, T>) {
        let mut id = if self.uses_labels() {
            s.label()
        } else {
            self.layer_of(s.value, st.object)
        };
        // An object shows only inside its region: elsewhere its samples belong
        // to no object.
        if let Some(Some(region)) = self.clips.get(id as usize)
            && !region.contains(s.position)
        {
            id = NO_OBJECT;
        }
        if st.object == EVERY_OBJECT {
            // Composited directly: the sample folds into the ray's one
            // segment with its object's table (plain DVR: it ignores `stop`).
            if let Some(object) = self.object(id) {
                self.fold(id, object, &mut st.segment, s, f32::INFINITY);
            }
            st.next_index = s.index + 1;
            return;
        }
        if id != st.object {
            self.close(st);
            st.object = id;
            if let Some(object) = self.object(id) {
                st.segment = object.start();
                // A segment starts at its first sample: the sample before belongs
                // to the previous segment, which composited the step between
                // them — unless it was skipped as empty; then a pre-integrated
                // DVR object composites that step itself (with its own table).
                st.segment.next_index = s.index.min(st.next_index);
            }
        }
        st.next_index = s.index + 1;
        if let Some(object) = self.object(id) {
            let stop = self.segment_stop(st.alpha);
            self.fold(id, object, &mut st.segment, s, stop);
            if st.depth.is_infinite() {
                st.depth = st.segment.depth;
            }
        }
    }

    /// The global opacity, counting the open segment's as if it closed now.
    #[inline]
    fn opacity(&self, st: &SegmentedState) -> f32 {
        if st.object == EVERY_OBJECT {
            // Nothing composited globally yet: the segment's is the ray's.
            return st.segment.alpha;
        }
        let Some(object) = self.object(st.object) else {
            return st.alpha;
        };
        let open = object.opacity(&st.segment);
        let global = match self.global {
            GlobalMode::Dvr => st.alpha + (1.0 - st.alpha) * open,
            GlobalMode::Mip => st.alpha.max(open),
        };
        // A segment stopped where the global opacity reaches the threshold
        // (`segment_stop`) reaches it, rounding aside.
        if open >= self.segment_stop(st.alpha) {
            global.max(self.stop_at)
        } else {
            global
        }
    }

    /// Composites the open segment globally and closes it.
    fn close(&self, st: &mut SegmentedState) {
        if st.object == EVERY_OBJECT {
            let segment = &st.segment;
            over_premultiplied(&mut st.color, &mut st.alpha, segment.color, segment.alpha);
        } else if let Some(object) = self.object(st.object) {
            let [r, g, b, a] = object.resolve(&st.segment);
            match self.global {
                GlobalMode::Dvr => over_premultiplied(&mut st.color, &mut st.alpha, [r, g, b], a),
                GlobalMode::Mip => {
                    if a > st.alpha {
                        st.color = [r, g, b];
                        st.alpha = a;
                    }
                }
            }
        }
        st.object = NO_OBJECT;
    }

    fn resolve(&self, st: &SegmentedState) -> [f32; 4] {
        let mut closed = *st;
        self.close(&mut closed);
        let [r, g, b] = closed.color;
        [r, g, b, closed.alpha]
    }

    fn depth(&self, st: &SegmentedState) -> f32 {
        st.depth
    }

    /// The value kernel ([`march_values`]), unless every object reads a
    /// gradient at each visible sample: the samples' values gathered, each
    /// folded here (a change of object closes a segment whatever its
    /// opacity), a gradient read through the cell cache where an object's
    /// compositor asks for one. When every object reads gradients and the
    /// tables map values alike (none pre-integrated), the gradient kernel
    /// folding every sample ([`march_gradients_every_sample`]): the samples
    /// visible under any object's table get their gradients gathered.
    fn march_packets<T: Sample>(
        &self,
        work: &mut PacketWork<'_, '_, T, SegmentedState>,
        level: SimdLevel,
    ) -> bool {
        match &self.kernel {
            SceneKernel::Values => march_values(self, work, level),
            SceneKernel::Gradients(table) => march_gradients_every_sample(self, table, work, level),
            SceneKernel::VisibleGradients(table) => march_gradients(self, table, work, level),
            SceneKernel::ShadedLayers(table, shading) => {
                march_shaded_layers(self, table, *shading, work, level)
            }
            SceneKernel::Scalar => false,
        }
    }
}
