//! The compositing interface: how the samples of a ray become a pixel.
//!
//! Every mode — the plain ones and two-level compositing — is a [`Compositor`] with
//! its own per-pixel state. The marching loop ([`super::march::march_brick`]) is
//! generic over it and is chosen once per frame ([`FrameCompositor::run`]), never
//! per sample.

use glam::Vec3;

use super::cell_cache::CellCache;
use super::gather_gradients::march_gradients;
use super::gather_values::march_values;
use super::local::{LocalCompositor, with_local};
use super::march::BrickContext;
use super::packet::PacketWork;
use super::pixel::PixelRay;
use super::sampler::VolumeSampler;
use super::simd::SimdLevel;
use super::state_buffer::StateCodec;
use super::transfer::TransferTable;
use super::two_level::TwoLevel;
use crate::volume::Sample;

/// How samples along a ray are composited into one pixel.
///
/// The loop calls [`Compositor::sample`] for every sample it reads, front to back;
/// it stops the ray once [`Compositor::opacity`] reaches the early-termination
/// threshold or [`Compositor::finished`] holds, then calls [`Compositor::close`]
/// (also when the ray leaves the volume) and finally [`Compositor::resolve`].
pub(crate) trait Compositor: Sync {
    /// What one pixel accumulates; travels with its tile between bricks and
    /// threads.
    type State: Copy + Send + std::fmt::Debug + StateCodec;

    /// The state of a pixel whose ray has not started.
    fn start(&self) -> Self::State;

    /// Whether no sample with a raw value in `lo..=hi` can change any pixel,
    /// whatever it accumulated: the one emptiness rule of both the frame plan's
    /// brick dropping and the loop's cell skipping.
    fn range_empty(&self, lo: u16, hi: u16) -> bool;

    /// Whether [`Compositor::below_interest`] can ever hold (the loop asks it per
    /// skippable cell only then).
    const STATE_SKIPS: bool = false;

    /// Whether [`Compositor::sample`] reads nothing of a sample but its value,
    /// position, index, fraction and ray, and what the volume holds elsewhere
    /// (the value before it, a gradient at a point it chooses): never the
    /// gradient at the sample through the ray's cell cache. Its samples'
    /// values then come from the value kernel ([`super::gather_values`]) on
    /// the levels that have one.
    const READS_ONLY_VALUES: bool = false;

    /// Whether empty-space skipping can skip anything of this compositor's:
    /// [`Compositor::range_empty`] holds for some range, or
    /// [`Compositor::below_interest`] for some state. Where neither ever
    /// does (every sample counts: average, X-ray), the loop walks no cells
    /// (it would skip none of them).
    #[inline]
    fn skips_anything(&self) -> bool {
        true
    }

    /// Whether each sample stands for the segment to the next one (pre-integrated
    /// transfer functions). Skipping two consecutive samples then drops the
    /// segment between them, which is empty only when every cell the ray crosses
    /// between them is: the run walker marches a run it would skip when a
    /// non-empty cell lies between it and the sample before or after
    /// ([`super::runs::SampleRuns`]).
    #[inline]
    fn composites_segments(&self) -> bool {
        false
    }

    /// Whether no sample of at most raw value `hi` can change `state` (the
    /// state-dependent part of empty-space skipping, e.g. MIP's running maximum).
    #[inline]
    fn below_interest(&self, _state: &Self::State, _hi: u16) -> bool {
        false
    }

    /// Folds one sample into `state`.
    fn sample<T: Sample>(&self, state: &mut Self::State, sample: &SamplePoint<'_, T>);

    /// The opacity that early ray termination compares with its threshold (0 for
    /// modes whose result is only known at the end).
    #[inline]
    fn opacity(&self, _state: &Self::State) -> f32 {
        0.0
    }

    /// Whether nothing later on the ray can change `state` (a first hit).
    #[inline]
    fn finished(&self, _state: &Self::State) -> bool {
        false
    }

    /// Closes what is still open when the ray ends (a two-level segment).
    #[inline]
    fn close(&self, _state: &mut Self::State) {}

    /// The pixel's premultiplied RGBA (before the background).
    fn resolve(&self, state: &Self::State) -> [f32; 4];

    /// The depth of the first hit (world distance from the ray origin), `∞` when
    /// there is none.
    fn depth(&self, _state: &Self::State) -> f32 {
        f32::INFINITY
    }

    /// The 1D table of a compositor that reads a visible sample's gradient
    /// and composites nothing for a sample whose entry in it is transparent:
    /// it takes the gradient kernel ([`march_gradients`]). `None` (the
    /// default) for the others.
    fn gradient_kernel_table(&self) -> Option<&TransferTable> {
        None
    }

    /// Marches a task's rays in packets of SIMD lanes at `level` (never
    /// [`SimdLevel::Scalar`]) when this compositor has a packet kernel for the
    /// frame, with the results and counts of [`super::march::march_brick`] for
    /// each ray; `false` leaves them to that loop. By default the gradient
    /// kernel for a [`Self::gradient_kernel_table`], else the value kernel for
    /// a compositor that [`Self::READS_ONLY_VALUES`].
    fn march_packets<T: Sample>(
        &self,
        work: &mut PacketWork<'_, '_, T, Self::State>,
        level: SimdLevel,
    ) -> bool
    where
        Self: Sized,
    {
        match self.gradient_kernel_table() {
            Some(table) => march_gradients(self, table, work, level),
            None => Self::READS_ONLY_VALUES && march_values(self, work, level),
        }
    }
}

/// What the samples of one ray's visit to one brick share, built once per visit.
pub(crate) struct SampleSite<'s, T: Sample> {
    pub(crate) ray: &'s PixelRay,
    pub(crate) brick: &'s BrickContext<'s, T>,
    pub(crate) volume: &'s VolumeSampler<'s, T>,
    /// The ray's current cell, with its corners and (once asked) differences.
    pub(crate) cell: &'s CellCache,
    pub(crate) gradient_scale: Vec3,
}

impl<'s, T: Sample> SampleSite<'s, T> {
    /// Sample `k` of the site's ray, of value `value` at voxel position
    /// `position`; the ray's last sample stands for its fraction of a step.
    #[inline(always)]
    pub(crate) fn point(&'s self, k: u32, position: Vec3, value: f32) -> SamplePoint<'s, T> {
        let ray = self.ray;
        SamplePoint {
            value,
            position,
            index: k,
            fraction: if k == ray.samples - 1 {
                ray.last_fraction
            } else {
                1.0
            },
            gradient: SampleGradient::FromLastValue,
            site: self,
        }
    }
}

/// Where a sample's gradient comes from: the same bits each way (the gradient
/// is a function of the position).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum SampleGradient {
    /// The site's cell cache, whose last value was this sample's (the scalar
    /// loop reads each value through it).
    FromLastValue,
    /// Computed by the kernel already.
    Known(Vec3),
    /// Read through the site's cell cache at the sample's position (a kernel
    /// that read the value elsewhere: [`SamplePoint::gradient_ahead`]).
    AtPosition,
}

/// One sample as a compositor sees it: its value, where it is, and what it may
/// ask for (gradient, label, depth) computed only when asked.
pub(crate) struct SamplePoint<'s, T: Sample> {
    /// Raw (interpolated) value.
    pub value: f32,
    /// Voxel position.
    pub position: Vec3,
    /// Index of the sample along its ray.
    pub index: u32,
    /// The part of a step this sample stands for (below 1 only for a ray's last).
    pub fraction: f32,
    /// Where [`Self::gradient`] comes from.
    pub(crate) gradient: SampleGradient,
    /// The ray, the brick and the cell the sample lies in.
    pub(crate) site: &'s SampleSite<'s, T>,
}

impl<'s, T: Sample> SamplePoint<'s, T> {
    /// The sample's ray.
    #[inline]
    pub(crate) fn ray(&self) -> &'s PixelRay {
        self.site.ray
    }

    /// The whole volume's sampler.
    #[inline]
    pub(crate) fn volume(&self) -> &'s VolumeSampler<'s, T> {
        self.site.volume
    }

    /// The gradient at the sample in normalised value per world unit of the
    /// smallest spacing.
    #[inline]
    pub fn gradient(&self) -> Vec3 {
        let site = self.site;
        match self.gradient {
            SampleGradient::FromLastValue => {
                site.cell
                    .gradient_here(site.volume, &site.brick.sampler, self.position)
                    * site.gradient_scale
            }
            SampleGradient::Known(gradient) => gradient,
            SampleGradient::AtPosition => self.gradient_at_position(),
        }
    }

    /// [`Self::gradient`] read through the site's cell cache at the sample's
    /// position. Out of line, so that the scalar loop's inlined
    /// [`Self::gradient`] stays small (inlined, it cost the two-level scalar
    /// loop 1.3 % more instructions).
    #[inline(never)]
    fn gradient_at_position(&self) -> Vec3 {
        self.gradient_ahead(self.position)
    }

    /// The gradient at voxel position `p` (near the sample).
    #[inline]
    pub fn gradient_at(&self, p: Vec3) -> Vec3 {
        let site = self.site;
        site.cell.gradient(site.volume, &site.brick.sampler, p) * site.gradient_scale
    }

    /// [`Self::gradient_at`] a position on the ray ahead of the sample, whose
    /// cell the ray's cell cache keeps for the next samples
    /// ([`CellCache::gradient_ahead`]).
    #[inline]
    pub(crate) fn gradient_ahead(&self, p: Vec3) -> Vec3 {
        let site = self.site;
        site.cell
            .gradient_ahead(site.volume, &site.brick.sampler, p)
            * site.gradient_scale
    }

    /// The unit world direction of the ray.
    #[inline]
    pub fn view_dir(&self) -> Vec3 {
        self.ray().view_dir
    }

    /// The sample's ray parameter (world distance from the ray origin).
    #[inline]
    pub fn t(&self) -> f32 {
        self.ray().t(self.index)
    }

    /// Distance from the eye normalised by where the ray leaves the volume.
    #[inline]
    pub fn depth(&self) -> f32 {
        (self.t() / self.ray().t(self.ray().samples).max(1e-6)).min(1.0)
    }

    /// Where the sample lies between the ray's first sample (0) and the end of
    /// its last (1): the depth inside the (cut) volume along this ray.
    #[inline]
    pub fn relative_depth(&self) -> f32 {
        let ray = self.ray();
        let start = ray.t(ray.first);
        let end = ray.t(ray.samples - 1) + ray.last_fraction * ray.dt;
        if end > start {
            ((self.t() - start) / (end - start)).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The object id of the label volume at the sample (0 without labels).
    #[inline]
    pub fn label(&self) -> u16 {
        self.site.brick.label_at(self.position)
    }

    /// The value of the sample before this one on the ray, if the ray takes one
    /// (not before its first sample, nor before the front of a clip region).
    pub fn value_before(&self) -> Option<f32> {
        if self.index <= self.ray().first {
            return None;
        }
        let k = self.index - 1;
        Some(self.value_at(self.ray().position(k, self.volume().last())))
    }

    /// The trilinear value at voxel position `p` (inside the volume), from the
    /// brick when it holds `p`.
    #[inline]
    pub fn value_at(&self, p: Vec3) -> f32 {
        if self.site.brick.sampler.contains(p) {
            self.site.brick.sampler.value(p)
        } else {
            self.volume().value(p)
        }
    }

    /// [`Self::value_at`] (the same bits) and the trilinear field's derivative
    /// along `d` there, in raw value per length of `d`
    /// ([`super::sampler::BrickSampler::value_and_slope_local`]).
    #[inline]
    pub fn value_and_slope_at(&self, p: Vec3, d: Vec3) -> (f32, f32) {
        if self.site.brick.sampler.contains(p) {
            self.site.brick.sampler.value_and_slope(p, d)
        } else {
            self.volume().value_and_slope(p, d)
        }
    }

    /// The slope of [`Self::value_and_slope_at`] (the same bits), from the
    /// ray's cell cache when `p` lies in its cell.
    #[inline]
    pub fn slope_at(&self, p: Vec3, d: Vec3) -> f32 {
        let site = self.site;
        match site.cell.slope_in_cell(&site.brick.sampler, p, d) {
            Some(slope) => slope,
            None => self.value_and_slope_at(p, d).1,
        }
    }

    /// The voxel position at ray parameter `t`, clamped into the volume.
    #[inline]
    pub fn position_at(&self, t: f32) -> Vec3 {
        (self.ray().origin + self.ray().direction * t).clamp(Vec3::ZERO, self.volume().last())
    }
}

/// The compositor of a frame, chosen once per frame: a plain mode or two-level
/// compositing.
#[derive(Clone, Debug)]
pub(crate) enum FrameCompositor {
    /// One local mode for whole rays.
    Plain(LocalCompositor),
    /// Two-level compositing of a segmented volume.
    TwoLevel(TwoLevel),
}

/// Work generic over the compositor, handed to [`FrameCompositor::run`].
pub(crate) trait CompositorJob {
    /// What the work returns.
    type Output;
    /// Does the work with compositor `c`.
    fn run<C: Compositor>(self, c: &C) -> Self::Output;
}

impl FrameCompositor {
    /// Runs `job` with the concrete compositor: the one dispatch of a frame.
    pub fn run<J: CompositorJob>(&self, job: J) -> J::Output {
        match self {
            FrameCompositor::Plain(local) => with_local!(local, c => job.run(c)),
            FrameCompositor::TwoLevel(c) => job.run(c),
        }
    }

    /// [`Compositor::range_empty`] of the frame's compositor (per brick or cell,
    /// not per sample).
    pub fn range_empty(&self, lo: u16, hi: u16) -> bool {
        struct RangeEmpty(u16, u16);
        impl CompositorJob for RangeEmpty {
            type Output = bool;
            fn run<C: Compositor>(self, c: &C) -> bool {
                c.range_empty(self.0, self.1)
            }
        }
        self.run(RangeEmpty(lo, hi))
    }
}
