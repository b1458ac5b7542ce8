//! The compositing modes of a run of samples: each a [`Compositor`] over one
//! [`Accumulation`]. A plain frame uses one of them for whole rays; two-level
//! compositing uses them for the segments of its objects ([`LocalCompositor`]).

use std::sync::Arc;

use glam::{Vec3, Vec4};

use super::compositor::{Compositor, SamplePoint};
use super::gather_gradients::march_gradients;
use super::optics::{
    importance_composite, light_vectors, over, partial_step, shading_intensity, smoothstep,
};
use super::packet::{DvrLanes, PacketWork, march_dvr};
use super::sabella::SabellaOutput;
use super::segments::{ImportanceSource, LocalMode};
use super::shading::Shading;
use super::simd::SimdLevel;
use super::state_buffer::{Reader, StateCodec, put_f32, put_u32};
use super::transfer::{PIECE_LENGTHS, PreintegratedTable, TransferTable};
use crate::volume::Sample;

/// What a run of samples has accumulated (every local mode uses some fields).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Accumulation {
    /// Premultiplied colour (opacity-compositing modes, first hit).
    pub color: [f32; 3],
    /// Opacity.
    pub alpha: f32,
    /// Maximum (MIP) or sum (average, X-ray: each value times the part of a
    /// step its sample stands for) of raw values.
    pub value: f32,
    /// Accumulated importance (importance-aware compositing).
    pub importance: f32,
    /// First-hit depth, `∞` without a hit.
    pub depth: f32,
    /// The index of the sample the run expects next: one past the last it
    /// folded, or where it starts (pre-integrated DVR notices skipped samples
    /// by it).
    pub next_index: u32,
    /// Sabella: the relative depth of the peak value.
    pub peak_depth: f32,
    /// Sabella: the sum of normalised values. Average and X-ray: the steps
    /// folded into `value` (a ray's last sample stands for a part of one).
    pub weight: f32,
    /// Sabella: the sum of normalised values times relative depths.
    pub weighted_depth: f32,
}

impl Accumulation {
    /// Nothing accumulated, with `value` as the start of the value fold.
    pub fn starting_at(value: f32) -> Self {
        Accumulation {
            color: [0.0; 3],
            alpha: 0.0,
            value,
            importance: 0.0,
            depth: f32::INFINITY,
            next_index: 0,
            peak_depth: 0.0,
            weight: 0.0,
            weighted_depth: 0.0,
        }
    }

    fn rgba(&self) -> [f32; 4] {
        let [r, g, b] = self.color;
        [r, g, b, self.alpha]
    }
}

impl StateCodec for Accumulation {
    const BYTES: usize = 44;

    fn encode(&self, out: &mut Vec<u8>) {
        for v in [
            self.color[0],
            self.color[1],
            self.color[2],
            self.alpha,
            self.value,
        ] {
            put_f32(out, v);
        }
        put_f32(out, self.importance);
        put_f32(out, self.depth);
        put_u32(out, self.next_index);
        for v in [self.peak_depth, self.weight, self.weighted_depth] {
            put_f32(out, v);
        }
    }

    fn decode(r: &mut Reader<'_>) -> Self {
        Accumulation {
            color: [r.f32(), r.f32(), r.f32()],
            alpha: r.f32(),
            value: r.f32(),
            importance: r.f32(),
            depth: r.f32(),
            next_index: r.u32(),
            peak_depth: r.f32(),
            weight: r.f32(),
            weighted_depth: r.f32(),
        }
    }
}

/// Colour and uncorrected opacity of value `v` as one premultiplied RGBA (the
/// one-sample modes: MIP, average).
fn classify_once(table: &TransferTable, v: f32) -> [f32; 4] {
    let [r, g, b, _] = table.lookup(v);
    let a = table.alpha0(v);
    [r * a, g * a, b * a, a]
}

/// Colour and step-corrected opacity of a sample with gradient `gradient` (used
/// by 2D tables), or `None` when it is transparent.
#[inline]
fn classify<T: Sample>(
    table: &TransferTable,
    s: &SamplePoint<'_, T>,
    gradient: Vec3,
) -> Option<([f32; 3], f32)> {
    let [r, g, b, a] = if table.is_2d() {
        table.lookup_2d(s.value, gradient.length())
    } else {
        table.lookup(s.value)
    };
    let a = partial_step(a, s.fraction);
    (a > 0.0).then_some(([r, g, b], a))
}

/// [`classify`] with the sample's gradient, which it returns too (the modes that
/// always need it); `None` for a transparent sample, whose gradient is never
/// computed when the table is 1D.
#[inline]
fn classify_with_gradient<T: Sample>(
    table: &TransferTable,
    s: &SamplePoint<'_, T>,
) -> Option<([f32; 3], f32, Vec3)> {
    if !table.is_2d() && table.lookup(s.value)[3] <= 0.0 {
        return None;
    }
    let gradient = s.gradient();
    classify(table, s, gradient).map(|(color, a)| (color, a, gradient))
}

#[inline]
fn shade(shading: Option<&Shading>, color: [f32; 3], gradient: Vec3, view_dir: Vec3) -> [f32; 3] {
    match shading {
        Some(sh) => sh.shade(color, gradient, view_dir),
        None => color,
    }
}

/// How many times a pre-integrated segment may be halved where the field bends
/// along it ([`Dvr::split_segment`]): into four pieces at most, the lengths the
/// table has shading weights for. Measured on `shapes` 128³ at step 1
/// (docs/benchmarks.md §6, shaded at the midpoint): no halving 43.0 dB against
/// the step-0.05 reference, one 49.3, two 51.5, three 51.8.
const SEGMENT_HALVINGS: u32 = PIECE_LENGTHS as u32 - 1;

/// A part of a pre-integrated piece whose share of its light is below this is
/// not shaded on its own ([`Dvr::shade_piece`]): its gradient is not read.
const UNSHADED_SHARE: f32 = 0.02;

/// A segment whose midpoint's value is off the line between its ends by more
/// than this many pre-integration bins is halved.
const SPLIT_BEND_BINS: f32 = 1.0;

/// A segment whose ends' values are more than this many pre-integration bins
/// apart is halved.
const SPLIT_SPAN_BINS: f32 = 16.0;

/// The opacity of a piece of a step halved `depth` times (0 to
/// [`SEGMENT_HALVINGS`]) whose whole step would have opacity `a`:
/// `1 − (1 − a)^(2^−depth)`, by square roots rather than a power.
#[inline]
fn piece_alpha(a: f32, depth: u32) -> f32 {
    if depth == 0 {
        return a;
    }
    let mut transparency = 1.0 - a.min(1.0);
    for _ in 0..depth {
        transparency = transparency.sqrt();
    }
    1.0 - transparency
}

/// A segment is halved where the field's slope at one of its ends, carried
/// over the segment, misses the other end's value by more than this many
/// pre-integration bins ([`Dvr::split_segment`]). Measured at step 1 against
/// the step-0.05 reference (docs/benchmarks.md §6): on the lung CT 50.2 dB
/// without this test, 54.7 at 1 bin, 55.6 at ½, 56.3 at ¼; on `shapes` 57.9,
/// 58.2, 58.4, 58.7.
const SPLIT_SLOPE_BINS: f32 = 0.5;

/// One end of a pre-integrated segment: where it is, the value there and, once
/// asked, the field's slope along the segment's step.
#[derive(Clone, Copy, Debug)]
struct SegmentEnd {
    position: Vec3,
    value: f32,
    /// The derivative of the trilinear field along [`Segment::step`]: raw
    /// value per step.
    slope: Option<f32>,
}

impl SegmentEnd {
    /// The end at `position` of value `value`, its slope not known yet.
    fn at(position: Vec3, value: f32) -> Self {
        SegmentEnd {
            position,
            value,
            slope: None,
        }
    }

    /// The field's slope along `step` here (read once).
    #[inline]
    fn slope<T: Sample>(&mut self, s: &SamplePoint<'_, T>, step: Vec3) -> f32 {
        let position = self.position;
        *self.slope.get_or_insert_with(|| s.slope_at(position, step))
    }
}

/// A pre-integrated segment, or a piece of one ([`Dvr::split_segment`]).
#[derive(Clone, Copy, Debug)]
struct Segment {
    /// Front and back.
    ends: [SegmentEnd; 2],
    /// The whole step the segment is (a piece of): the unit of the ends'
    /// slopes.
    step: Vec3,
}

impl Segment {
    /// The whole step from `front` to `back`.
    fn new(front: SegmentEnd, back: SegmentEnd) -> Self {
        Segment {
            ends: [front, back],
            step: back.position - front.position,
        }
    }
}

/// Front-to-back emission–absorption, shaded when asked.
#[derive(Clone, Debug)]
pub(crate) struct Dvr {
    table: Arc<TransferTable>,
    shading: Option<Shading>,
    /// With pre-integration: the opacity at which the frame's early ray
    /// termination stops a ray, where a segment crossing it is cut
    /// ([`Dvr::composite_segment`]); `∞` without termination.
    stop_at: f32,
}

impl Dvr {
    /// Composites a pre-integrated segment (or piece) of colour `color` and
    /// opacity `a`, cut where the opacity reaches `stop`.
    ///
    /// Early ray termination stops a ray at the first sample that takes its
    /// opacity to the threshold: a fine step overshoots it by little, a step of
    /// a voxel by much — the surface behind the threshold shows through, and
    /// the coarse image is lighter than the fine one (on `shapes` at step 1,
    /// this was most of the difference from the step-0.05 reference unshaded:
    /// docs/benchmarks.md §6). A pre-integrated segment stands for a continuous
    /// stretch of the ray, so the ray stops inside it, where the opacity
    /// reaches the threshold: the part up to there (its colour the segment's)
    /// has opacity `(stop − α)/(1 − α)`. The ray's opacity is then exactly
    /// `stop`; later pieces add nothing.
    #[inline]
    fn composite_segment(&self, st: &mut Accumulation, color: [f32; 3], a: f32, stop: f32) {
        if st.alpha >= stop {
            return;
        }
        if st.alpha + (1.0 - st.alpha) * a >= stop {
            let part = (stop - st.alpha) / (1.0 - st.alpha);
            over(&mut st.color, &mut st.alpha, color, part);
            st.alpha = stop;
        } else {
            over(&mut st.color, &mut st.alpha, color, a);
        }
    }

    /// The shaded colour of a visible piece from `p0` to `p1`, of table colour
    /// `color`: each of its front end, midpoint and back end is shaded with its
    /// own gradient, weighted by `weights`, the shares of the piece's light
    /// that come from around them (the front quarter, the middle half, the
    /// back quarter: [`PreintegratedTable::shading_weights`]). Across a surface
    /// the light comes from where the opacity rises, which can lie anywhere
    /// along the piece; one gradient at the midpoint can lie in the flat field
    /// before it, whose colour is unshaded. A part with less than
    /// [`UNSHADED_SHARE`] of the light is left out (its gradient never read),
    /// the others' weights scaled to sum to one.
    #[inline]
    fn shade_piece<T: Sample>(
        shading: &Shading,
        s: &SamplePoint<'_, T>,
        [p0, p1]: [Vec3; 2],
        weights: [f32; 3],
        color: [f32; 3],
    ) -> [f32; 3] {
        // The three points' gradients in lanes (a part left out: none), shaded
        // at once: each lane with `Shading::shade`'s operations and bits.
        let points = [p0, (p0 + p1) * 0.5, p1];
        let mut g = [Vec3::ZERO; 3];
        for i in 0..3 {
            if weights[i] >= UNSHADED_SHARE {
                g[i] = s.gradient_ahead(points[i]);
            }
        }
        let axes = [
            Vec4::new(g[0].x, g[1].x, g[2].x, 0.0),
            Vec4::new(g[0].y, g[1].y, g[2].y, 0.0),
            Vec4::new(g[0].z, g[1].z, g[2].z, 0.0),
        ];
        let lit = shading.shade_lanes(
            color.map(Vec4::splat),
            axes,
            shading.ray_lights(s.view_dir()),
        );
        let (mut sum, mut used) = ([0.0f32; 3], 0.0f32);
        for (i, w) in weights.into_iter().enumerate() {
            if w >= UNSHADED_SHARE {
                let lit = [lit[0][i], lit[1][i], lit[2][i]];
                for (acc, c) in sum.iter_mut().zip(lit) {
                    *acc += w * c;
                }
                used += w;
            }
        }
        sum.map(|c| c / used)
    }

    /// A sample with pre-integration: it stands for the segment to the next
    /// sample (see [`Dvr::range_empty`]), preceded by the segment from the
    /// sample before when that one was skipped.
    #[inline(never)]
    fn sample_preintegrated<T: Sample>(
        &self,
        pre: &PreintegratedTable,
        st: &mut Accumulation,
        s: &SamplePoint<'_, T>,
        stop: f32,
    ) {
        let k = s.index;
        let here = SegmentEnd::at(s.position, s.value);
        if k > st.next_index
            && let Some(before) = s.value_before()
        {
            // The sample before was skipped as empty: its segment ends here.
            let p = s.ray().position(k - 1, s.volume().last());
            let segment = Segment::new(SegmentEnd::at(p, before), here);
            self.split_segment(pre, st, s, segment, SEGMENT_HALVINGS, stop);
        }
        st.next_index = k + 1;
        if s.fraction < 1.0 {
            // The ray's last sample stands for a constant partial step (its value
            // lies in its own cell's range: see `range_empty`).
            let [r, g, b, a] = pre.lookup(s.value, s.value);
            if a > 0.0 {
                let color = shade(self.shading.as_ref(), [r, g, b], s.gradient(), s.view_dir());
                self.composite_segment(st, color, partial_step(a, s.fraction), stop);
            }
        } else {
            // The back end's value comes with its slope (the same reads).
            let p = s.ray().position(k + 1, s.volume().last());
            let (value, slope) = s.value_and_slope_at(p, p - s.position);
            let back = SegmentEnd {
                position: p,
                value,
                slope: Some(slope),
            };
            self.split_segment(pre, st, s, Segment::new(here, back), SEGMENT_HALVINGS, stop);
        }
    }

    /// Composites `segment`, a step halved `SEGMENT_HALVINGS − halvings`
    /// times: pre-integrated whole where the field is close to linear along
    /// it, else as its two halves (their shared end's value read from the
    /// volume), down to `halvings` more times; cut at opacity `stop`
    /// ([`Dvr::composite_segment`]) and shaded by [`Dvr::shade_piece`].
    ///
    /// The table assumes the value goes linearly from front to back. Across a
    /// surface it does not: it stays flat, rises over about a voxel and flattens
    /// again, and a segment of a voxel or more that straddles the rise puts the
    /// surface's opacity at the wrong depth and in the wrong proportion (the
    /// stripes on flat faces at step 1). A segment is halved when its midpoint's
    /// value is more than [`SPLIT_BEND_BINS`] table bins off the line between
    /// its ends, when its ends are more than [`SPLIT_SPAN_BINS`] bins apart (an
    /// S-shaped rise can pass through the line at the midpoint), or when the
    /// field's slope at either end, carried over the segment, misses the
    /// other end's value by more than [`SPLIT_SLOPE_BINS`] bins (a curve the
    /// midpoint does not show: the field inside the voxels of a CT scan). A
    /// segment transparent as a whole (every value between its ends is) is
    /// neither composited nor halved, as without halving.
    fn split_segment<T: Sample>(
        &self,
        pre: &PreintegratedTable,
        st: &mut Accumulation,
        s: &SamplePoint<'_, T>,
        segment: Segment,
        halvings: u32,
        stop: f32,
    ) {
        let [mut front, mut back] = segment.ends;
        let (p0, v0, p1, v1) = (front.position, front.value, back.position, back.value);
        // Whether the segment is visible at all is the nearest bins' word, as
        // for skipping (`range_empty`); what it composites is interpolated.
        let at = pre.locate(v0, v1);
        if pre.entry(at)[3] <= 0.0 {
            return;
        }
        // Halved `depth` times: a piece of `2^−depth` steps.
        let depth = SEGMENT_HALVINGS - halvings;
        let mid = (p0 + p1) * 0.5;
        if halvings > 0 {
            let bin = pre.bin_width();
            // The midpoint's slope only where its halves may be halved again.
            let (vm, slope_m) = if halvings > 1 {
                let (v, slope) = s.value_and_slope_at(mid, segment.step);
                (v, Some(slope))
            } else {
                (s.value_at(mid), None)
            };
            let length = 1.0 / (1u32 << depth) as f32;
            let (s0, s1) = (front.slope(s, segment.step), back.slope(s, segment.step));
            let chord = v1 - v0;
            let off_slope = (s0 * length - chord).abs().max((s1 * length - chord).abs());
            if (vm - (v0 + v1) * 0.5).abs() > SPLIT_BEND_BINS * bin
                || chord.abs() > SPLIT_SPAN_BINS * bin
                || off_slope > SPLIT_SLOPE_BINS * bin
            {
                let middle = SegmentEnd {
                    position: mid,
                    value: vm,
                    slope: slope_m,
                };
                for ends in [[front, middle], [middle, back]] {
                    let half = Segment {
                        ends,
                        step: segment.step,
                    };
                    self.split_segment(pre, st, s, half, halvings - 1, stop);
                }
                return;
            }
        }
        let [r, g, b, a] = pre.entry_interpolated(at);
        let color = match &self.shading {
            Some(sh) => {
                let weights = pre.shading_weights(at, depth as usize);
                Self::shade_piece(sh, s, [p0, p1], weights, [r, g, b])
            }
            None => [r, g, b],
        };
        self.composite_segment(st, color, piece_alpha(a, depth), stop);
    }

    /// [`Compositor::sample`], with pre-integrated segments cut at opacity
    /// `stop` instead of the frame's threshold (a two-level object's segment:
    /// [`LocalCompositor::sample_in_segment`]).
    #[inline(always)]
    fn sample_stopping_at<T: Sample>(
        &self,
        st: &mut Accumulation,
        s: &SamplePoint<'_, T>,
        stop: f32,
    ) {
        if let Some(pre) = self.table.preintegrated() {
            self.sample_preintegrated(pre, st, s, stop);
            return;
        }
        self.sample_plain(st, s);
    }

    /// A plain (not pre-integrated) sample: classified, shaded and composited
    /// for its step.
    #[inline(always)]
    fn sample_plain<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let [r, g, b, a] = self.table.lookup(s.value);
        if a <= 0.0 {
            return;
        }
        let (color, a) = if self.shading.is_some() || self.table.is_2d() {
            let gradient = s.gradient();
            let a = if self.table.is_2d() {
                self.table.lookup_2d(s.value, gradient.length())[3]
            } else {
                a
            };
            let color = shade(self.shading.as_ref(), [r, g, b], gradient, s.view_dir());
            (color, a)
        } else {
            ([r, g, b], a)
        };
        over(
            &mut st.color,
            &mut st.alpha,
            color,
            partial_step(a, s.fraction),
        );
    }
}

impl Compositor for Dvr {
    type State = Accumulation;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    /// Whether every value in `lo..=hi` is transparent.
    ///
    /// With pre-integration this stays exact, skipping included. Sample `k`
    /// stands for the segment from its value to sample `k + 1`'s (the ray's last
    /// sample for a constant partial step), shaded with gradients read on the
    /// ray between the two samples ([`Dvr::shade_piece`]; the last sample: its
    /// own), or for its halves where the field bends between them
    /// ([`Dvr::split_segment`]: values read between the two samples, on the
    /// ray). Gradients and values are functions of the position alone.
    /// Skipping sample `k` (it lies in an empty cell or a transparent brick, so
    /// its value is in a transparent range) drops that segment, which can be
    /// visible only when sample `k + 1` is marched:
    /// - if sample `k + 1` is skipped too, every cell the ray crosses between
    ///   them is empty: the run walker marches a run it would skip otherwise
    ///   ([`Compositor::composites_segments`]; within one brick visit, and a
    ///   brick is never crossed between two samples: the plan turns skipping off
    ///   for steps of a brick or more). The field is continuous along the ray, so
    ///   every value between the two samples' lies in one of those cells'
    ///   transparent ranges, and the whole linear segment is transparent
    ///   (so it is not halved either: [`Dvr::split_segment`]);
    /// - if sample `k + 1` is marched, it sees that the sample before it was not
    ///   (the state's `next_index`) and composites the dropped segment first,
    ///   from [`SamplePoint::value_before`] to its own value, shaded at the same
    ///   points — what the unskipped ray composites, in the same order.
    ///
    /// A visible sample's own segment is never dropped: it is composited when the
    /// sample is marched, whatever follows. So the rule for bricks and cells is
    /// the ordinary one.
    #[inline]
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        self.table.is_transparent(lo, hi)
    }
    #[inline]
    fn composites_segments(&self) -> bool {
        self.table.preintegrated().is_some()
    }
    // Always inlined into the marching loop (a transparent sample costs a
    // table read); pre-integration is a call.
    #[inline(always)]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        self.sample_stopping_at(st, s, self.stop_at);
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        st.alpha
    }
    fn march_packets<T: Sample>(
        &self,
        work: &mut PacketWork<'_, '_, T, Accumulation>,
        level: SimdLevel,
    ) -> bool {
        // The packet kernel composites plain samples of a 1D table; a 2D
        // table's opacity needs every visible sample's gradient.
        if self.table.preintegrated().is_some() {
            return false;
        }
        if self.table.is_2d() {
            return march_gradients(self, &self.table, work, level);
        }
        let lanes = DvrLanes {
            table: &self.table,
            shading: self.shading,
            runs_compositor: self,
        };
        march_dvr(&lanes, work, level);
        true
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        st.rgba()
    }
}

/// Maximum intensity projection: the largest value, classified.
#[derive(Clone, Debug)]
pub(crate) struct Mip {
    table: Arc<TransferTable>,
}

impl Compositor for Mip {
    type State = Accumulation;
    const READS_ONLY_VALUES: bool = true;
    const STATE_SKIPS: bool = true;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(f32::NEG_INFINITY)
    }
    fn range_empty(&self, _lo: u16, _hi: u16) -> bool {
        false
    }
    #[inline]
    fn below_interest(&self, st: &Accumulation, hi: u16) -> bool {
        f32::from(hi) <= st.value
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        st.value = st.value.max(s.value);
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        if st.value.is_finite() {
            classify_once(&self.table, st.value)
        } else {
            [0.0; 4]
        }
    }
}

/// Average intensity projection: the mean value, classified.
#[derive(Clone, Debug)]
pub(crate) struct Average {
    table: Arc<TransferTable>,
}

/// The weight of a sample standing for no part of a step (the one sample of a
/// ray crossing a volume one voxel thick: no depth): a power of two, so that
/// such a ray's mean is its value to the bit, and too small to matter beside a
/// ray's other samples (a last sample of no step is otherwise rare: a ray
/// whose length is a whole number of steps).
const NO_STEP_WEIGHT: f32 = f32::EPSILON;

impl Average {
    /// Adds raw value `v` of a sample standing for `fraction` of a step to
    /// the sum (average and X-ray).
    #[inline]
    fn fold(st: &mut Accumulation, v: f32, fraction: f32) {
        let weight = fraction.max(NO_STEP_WEIGHT);
        st.value += v * weight;
        st.weight += weight;
    }
}

impl Compositor for Average {
    type State = Accumulation;
    const READS_ONLY_VALUES: bool = true;
    fn skips_anything(&self) -> bool {
        false
    }
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    fn range_empty(&self, _lo: u16, _hi: u16) -> bool {
        false
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        Average::fold(st, s.value, s.fraction);
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        // (A ray's only sample may stand for no part of a step.)
        if st.weight > 0.0 {
            classify_once(&self.table, st.value / st.weight)
        } else {
            [0.0; 4]
        }
    }
}

/// X-ray: the sum of normalised values times the step, as opacity
/// `1 − exp(−gain·Σ)`, coloured by the mean value.
#[derive(Clone, Debug)]
pub(crate) struct XRay {
    table: Arc<TransferTable>,
    gain: f32,
    domain: [f32; 2],
}

impl Compositor for XRay {
    type State = Accumulation;
    const READS_ONLY_VALUES: bool = true;
    fn skips_anything(&self) -> bool {
        false
    }
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    fn range_empty(&self, _lo: u16, _hi: u16) -> bool {
        false
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        Average::fold(st, s.value, s.fraction);
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        if st.weight <= 0.0 {
            return [0.0; 4];
        }
        let steps = st.weight;
        let [r, g, b, _] = self.table.lookup(st.value / steps);
        let width = self.domain[1] - self.domain[0];
        let sum = (st.value - steps * self.domain[0]) / width * self.table.step_ratio();
        let a = 1.0 - (-self.gain * sum.max(0.0)).exp();
        [r * a, g * a, b * a, a]
    }
}

/// The first sample at or above the iso-value; the hit is refined linearly
/// between it and the sample before, then shaded as an opaque surface.
#[derive(Clone, Debug)]
pub(crate) struct FirstHit {
    table: Arc<TransferTable>,
    shading: Option<Shading>,
    iso_raw: f32,
}

impl Compositor for FirstHit {
    type State = Accumulation;
    const READS_ONLY_VALUES: bool = true;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    #[inline]
    fn range_empty(&self, _lo: u16, hi: u16) -> bool {
        f32::from(hi) < self.iso_raw
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let iso = self.iso_raw;
        if s.value < iso || st.depth.is_finite() {
            return;
        }
        let mut t_hit = s.t();
        if let Some(before) = s.value_before()
            && before < iso
            && s.value > before
        {
            t_hit = s.t() - s.ray().dt + (iso - before) / (s.value - before) * s.ray().dt;
        }
        let [r, g, b, _] = self.table.lookup(iso);
        st.color = match &self.shading {
            Some(sh) => sh.shade([r, g, b], s.gradient_at(s.position_at(t_hit)), s.view_dir()),
            None => [r, g, b],
        };
        st.alpha = 1.0;
        st.depth = t_hit;
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        st.alpha
    }
    #[inline]
    fn finished(&self, st: &Accumulation) -> bool {
        st.depth.is_finite()
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        st.rgba()
    }
    fn depth(&self, st: &Accumulation) -> f32 {
        st.depth
    }
}

/// Importance-aware compositing (de Moura Pinto & Freitas).
#[derive(Clone, Debug)]
pub(crate) struct Importance {
    table: Arc<TransferTable>,
    shading: Option<Shading>,
    source: ImportanceSource,
    domain: [f32; 2],
}

impl Importance {
    fn importance<T: Sample>(&self, s: &SamplePoint<'_, T>, gradient: Vec3) -> f32 {
        let g = gradient.length().min(1.0);
        let n = gradient.normalize_or_zero();
        let normalised = (s.value - self.domain[0]) / (self.domain[1] - self.domain[0]);
        match self.source {
            ImportanceSource::Constant(w) => w,
            ImportanceSource::Intensity(w) => w * normalised,
            ImportanceSource::Gradient(w) => w * g,
            ImportanceSource::Silhouette([p1, p2, p3]) => {
                g.powf(p1) * smoothstep(p2, p3, 1.0 - n.dot(s.view_dir()).abs())
            }
            ImportanceSource::Lighting([p1, p2, p3]) => {
                let (l, h) = light_vectors(None, s.view_dir());
                3.0 - n.dot(h).abs().powf(p1) - n.dot(l).abs().powf(p2) - (1.0 - g).powf(p3)
            }
        }
    }
}

impl Compositor for Importance {
    type State = Accumulation;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    #[inline]
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        // A transparent sample keeps colour, opacity and importance.
        self.table.is_transparent(lo, hi)
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let Some((color, a, gradient)) = classify_with_gradient(&self.table, s) else {
            return;
        };
        let color = shade(self.shading.as_ref(), color, gradient, s.view_dir());
        let (c, alpha, i) = importance_composite(
            st.color,
            st.alpha,
            st.importance,
            color.map(|c| c * a),
            a,
            self.importance(s, gradient),
        );
        st.color = c;
        st.alpha = alpha;
        st.importance = i;
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        st.alpha
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        st.rgba()
    }
    /// A transparent sample composites nothing.
    fn gradient_kernel_table(&self) -> Option<&TransferTable> {
        Some(&self.table)
    }
}

/// Context-preserving rendering (Bruckner et al.):
/// `α = α_tf · |g|^((κt · s(P) · (1 − |P − E|) · (1 − α_{i−1}))^κs)`.
#[derive(Clone, Debug)]
pub(crate) struct ContextPreserving {
    table: Arc<TransferTable>,
    shading: Option<Shading>,
    kt: f32,
    ks: f32,
}

impl Compositor for ContextPreserving {
    type State = Accumulation;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    #[inline]
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        self.table.is_transparent(lo, hi)
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let Some((color, a, gradient)) = classify_with_gradient(&self.table, s) else {
            return;
        };
        let shading = self.shading.as_ref();
        let color = shade(shading, color, gradient, s.view_dir());
        let intensity = shading_intensity(shading, gradient, s.view_dir());
        let exponent = (self.kt * intensity * (1.0 - s.depth()) * (1.0 - st.alpha))
            .max(0.0)
            .powf(self.ks);
        let a = a * gradient.length().min(1.0).powf(exponent);
        over(&mut st.color, &mut st.alpha, color, a);
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        st.alpha
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        st.rgba()
    }
    /// A transparent sample composites nothing.
    fn gradient_kernel_table(&self) -> Option<&TransferTable> {
        Some(&self.table)
    }
}

/// Non-photorealistic: Gooch-style tone shading (cool to warm by `N·L`) and
/// silhouette darkening `color·exp(−8·sil)`, `sil = smoothstep(0.6, 1, 1 − |V·N|)`.
#[derive(Clone, Debug)]
pub(crate) struct Silhouette {
    table: Arc<TransferTable>,
}

impl Silhouette {
    fn tone(color: [f32; 3], gradient: Vec3, view_dir: Vec3) -> [f32; 3] {
        const COOL: [f32; 3] = [0.3, 0.35, 0.6];
        const WARM: [f32; 3] = [1.0, 0.9, 0.7];
        let magnitude = gradient.length();
        if magnitude <= 1e-3 {
            return color;
        }
        let ndl = (gradient / magnitude).dot(-view_dir);
        let k = (1.0 + ndl.abs()) / 2.0;
        let dark = (-8.0 * smoothstep(0.6, 1.0, 1.0 - ndl.abs())).exp();
        [0, 1, 2].map(|i| color[i] * (COOL[i] + (WARM[i] - COOL[i]) * k) * dark)
    }
}

impl Compositor for Silhouette {
    type State = Accumulation;
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(0.0)
    }
    #[inline]
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        self.table.is_transparent(lo, hi)
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let Some((color, a, gradient)) = classify_with_gradient(&self.table, s) else {
            return;
        };
        let color = Silhouette::tone(color, gradient, s.view_dir());
        over(&mut st.color, &mut st.alpha, color, a);
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        st.alpha
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        st.rgba()
    }
    /// A transparent sample composites nothing.
    fn gradient_kernel_table(&self) -> Option<&TransferTable> {
        Some(&self.table)
    }
}

/// Sabella's colouring: the peak value `M` and its relative depth `D`, the
/// value-weighted centroid depth `C` and the intensity `I` accumulated with the
/// transfer function's opacities; resolved to colours by a
/// [`SabellaMapping`](super::sabella::SabellaMapping) or kept as channels
/// ([`super::sabella::SabellaChannels`]). Every sample counts (`M` and `C` are
/// over the whole ray): no skipping, no early termination.
#[derive(Clone, Debug)]
pub(crate) struct Sabella {
    table: Arc<TransferTable>,
    domain: [f32; 2],
    output: SabellaOutput,
}

impl Sabella {
    /// `[M, D, C, I]` of a state (zero for a ray that took no sample).
    fn channels(&self, st: &Accumulation) -> [f32; 4] {
        if !st.value.is_finite() {
            return [0.0; 4];
        }
        let m = ((st.value - self.domain[0]) / (self.domain[1] - self.domain[0])).clamp(0.0, 1.0);
        let c = if st.weight > 0.0 {
            (st.weighted_depth / st.weight).clamp(0.0, 1.0)
        } else {
            st.peak_depth
        };
        [m, st.peak_depth, c, st.alpha]
    }
}

impl Compositor for Sabella {
    type State = Accumulation;
    const READS_ONLY_VALUES: bool = true;
    fn skips_anything(&self) -> bool {
        false
    }
    fn start(&self) -> Accumulation {
        Accumulation::starting_at(f32::NEG_INFINITY)
    }
    fn range_empty(&self, _lo: u16, _hi: u16) -> bool {
        false
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        let depth = s.relative_depth();
        if s.value > st.value {
            st.value = s.value;
            st.peak_depth = depth;
        }
        let v = ((s.value - self.domain[0]) / (self.domain[1] - self.domain[0])).clamp(0.0, 1.0);
        st.weight += v;
        st.weighted_depth += v * depth;
        let a = partial_step(self.table.lookup(s.value)[3], s.fraction);
        st.alpha += (1.0 - st.alpha) * a;
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        let channels = self.channels(st);
        match &self.output {
            SabellaOutput::Colours(mapping) => mapping.rgba(channels),
            SabellaOutput::Channels => channels,
        }
    }
}

/// One of the local modes, chosen per object (two-level compositing).
#[derive(Clone, Debug)]
pub(crate) enum LocalCompositor {
    /// Emission–absorption.
    Dvr(Dvr),
    /// Maximum intensity projection.
    Mip(Mip),
    /// Average intensity projection.
    Average(Average),
    /// Sum of values.
    XRay(XRay),
    /// First hit.
    FirstHit(FirstHit),
    /// Importance-aware compositing.
    Importance(Importance),
    /// Context-preserving rendering.
    ContextPreserving(ContextPreserving),
    /// Tone shading and silhouettes.
    Silhouette(Silhouette),
    /// Sabella's colouring.
    Sabella(Sabella),
}

/// Calls `$body` with `$c` bound to the concrete compositor of `$local`.
macro_rules! with_local {
    ($local:expr, $c:ident => $body:expr) => {
        match $local {
            LocalCompositor::Dvr($c) => $body,
            LocalCompositor::Mip($c) => $body,
            LocalCompositor::Average($c) => $body,
            LocalCompositor::XRay($c) => $body,
            LocalCompositor::FirstHit($c) => $body,
            LocalCompositor::Importance($c) => $body,
            LocalCompositor::ContextPreserving($c) => $body,
            LocalCompositor::Silhouette($c) => $body,
            LocalCompositor::Sabella($c) => $body,
        }
    };
}
pub(crate) use with_local;

impl LocalCompositor {
    /// The compositor of `mode` over transfer table `table` (its opacities
    /// corrected for the frame's step), with `domain` the raw values the table
    /// spans and `shading` for the modes that shade, for a volume whose
    /// diagonal is `diagonal` level-0 voxels (the automatic X-ray gain's:
    /// [`super::auto_xray_gain`]).
    pub fn new(
        mode: LocalMode,
        table: Arc<TransferTable>,
        shading: Option<Shading>,
        domain: [f32; 2],
        diagonal: f32,
    ) -> Self {
        match mode {
            LocalMode::Dvr => LocalCompositor::Dvr(Dvr {
                table,
                shading,
                stop_at: f32::INFINITY,
            }),
            LocalMode::Mip => LocalCompositor::Mip(Mip { table }),
            LocalMode::Average => LocalCompositor::Average(Average { table }),
            LocalMode::XRay { gain } => LocalCompositor::XRay(XRay {
                table,
                gain: gain.unwrap_or_else(|| super::auto_xray_gain(diagonal)),
                domain,
            }),
            LocalMode::FirstHit { iso } => LocalCompositor::FirstHit(FirstHit {
                table,
                shading,
                iso_raw: domain[0] + iso * (domain[1] - domain[0]),
            }),
            LocalMode::Importance { source } => LocalCompositor::Importance(Importance {
                table,
                shading,
                source,
                domain,
            }),
            LocalMode::ContextPreserving { kt, ks } => {
                LocalCompositor::ContextPreserving(ContextPreserving {
                    table,
                    shading,
                    kt,
                    ks,
                })
            }
            LocalMode::Silhouette => LocalCompositor::Silhouette(Silhouette { table }),
            LocalMode::Sabella { output } => LocalCompositor::Sabella(Sabella {
                table,
                domain,
                output,
            }),
        }
    }

    /// With early ray termination at opacity `threshold` (`None`: none), which
    /// pre-integrated DVR segments stop at exactly ([`Dvr::composite_segment`]);
    /// other modes are unchanged.
    pub fn stopping_at(mut self, threshold: Option<f32>) -> Self {
        if let LocalCompositor::Dvr(dvr) = &mut self {
            dvr.stop_at = threshold.unwrap_or(f32::INFINITY);
        }
        self
    }

    /// [`Compositor::sample`] in a two-level object's segment, whose
    /// pre-integrated DVR pieces stop at local opacity `stop` (where the global
    /// opacity reaches the frame's threshold).
    #[inline]
    pub fn sample_in_segment<T: Sample>(
        &self,
        st: &mut Accumulation,
        s: &SamplePoint<'_, T>,
        stop: f32,
    ) {
        match self {
            LocalCompositor::Dvr(dvr) => dvr.sample_stopping_at(st, s, stop),
            other => other.sample(st, s),
        }
    }
}

impl Compositor for LocalCompositor {
    type State = Accumulation;
    fn start(&self) -> Accumulation {
        with_local!(self, c => c.start())
    }
    fn range_empty(&self, lo: u16, hi: u16) -> bool {
        with_local!(self, c => c.range_empty(lo, hi))
    }
    fn composites_segments(&self) -> bool {
        with_local!(self, c => c.composites_segments())
    }
    fn skips_anything(&self) -> bool {
        with_local!(self, c => c.skips_anything())
    }
    #[inline]
    fn sample<T: Sample>(&self, st: &mut Accumulation, s: &SamplePoint<'_, T>) {
        with_local!(self, c => c.sample(st, s))
    }
    #[inline]
    fn opacity(&self, st: &Accumulation) -> f32 {
        with_local!(self, c => c.opacity(st))
    }
    fn resolve(&self, st: &Accumulation) -> [f32; 4] {
        with_local!(self, c => c.resolve(st))
    }
    fn depth(&self, st: &Accumulation) -> f32 {
        with_local!(self, c => c.depth(st))
    }
    fn march_packets<T: Sample>(
        &self,
        work: &mut PacketWork<'_, '_, T, Accumulation>,
        level: SimdLevel,
    ) -> bool {
        with_local!(self, c => c.march_packets(work, level))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::optics::corrected_alpha;

    #[test]
    fn a_piece_has_the_opacity_of_its_fraction_of_a_step() {
        for a in [0.0f32, 1e-6, 0.01, 0.3, 0.5, 0.9, 0.999, 0.999_999, 1.0] {
            for depth in 0..=SEGMENT_HALVINGS {
                let fraction = 1.0 / (1u32 << depth) as f32;
                let piece = piece_alpha(a, depth);
                let expected = corrected_alpha(a, fraction);
                assert!(
                    (piece - expected).abs() < 1e-6,
                    "{a} {depth}: {piece} {expected}"
                );
                // 2^depth pieces, one behind the other, are the whole step.
                let whole = 1.0 - (1.0 - piece).powi(1 << depth);
                assert!((whole - a).abs() < 1e-5, "{a} {depth}: {whole}");
            }
        }
        assert_eq!(piece_alpha(0.37, 0), 0.37);
    }
}
