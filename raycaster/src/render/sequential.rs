//! The sequential reference renderer: image order, one pixel at a time, each ray
//! walked brick by brick through the shared marching loop.
//!
//! It is deliberately simple and is the oracle every faster renderer is compared
//! with: for each pixel inside the volume's projected rectangle, find the brick
//! owning the ray's next sample, let the kernel march the samples that brick owns,
//! and repeat until the ray leaves the volume, terminates early or hits. It
//! marches with the scalar loop, the reference the packet kernels are compared
//! with, unless [`RenderSettings::simd`] names a packet level: then with that
//! kernel, a packet of one ray per brick visit, where the compositor has one
//! (the same bits; slower than the scalar loop here, so `auto` keeps it).

use std::time::Instant;

use super::camera::{Camera, PixelRect};
use super::cell_cache::CellCache;
use super::compositor::{Compositor, CompositorJob};
use super::counters::Counters;
use super::error::RenderError;
use super::frame::Frame;
use super::level::DepthBand;
use super::march::{BrickContext, march_brick};
use super::ownership::owned_samples;
use super::packet::{PacketItem, PacketWork};
use super::parallel::{check_levels, continue_in_level, level_plans};
use super::pixel::PixelState;
use super::prepared::{FramePlan, RenderVolume};
use super::progress::PixelProgress;
use super::sampler::VolumeSampler;
use super::settings::RenderSettings;
use super::simd::SimdLevel;
use super::state_buffer::{StateBuffer, StateBytes};
use crate::volume::{Sample, TypedVolume, VolumeData};

/// Renders one frame of `volume` seen by `camera`, on the calling thread.
pub fn render_sequential(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Frame, RenderError> {
    render_sequential_levels(&[(volume, None)], camera, settings)
}

/// Renders one frame of several pyramid levels on the calling thread: `passes`
/// are the levels, nearest band first, each sampling its depth band
/// ([`LevelChoice::bands`](super::level::LevelChoice::bands)), the reference of
/// [`Renderer::render_levels_into`](super::Renderer::render_levels_into). Like
/// it, the levels are rendered one after another over the whole image, each
/// continuing the pixels' states where the nearer one left them.
pub fn render_sequential_levels(
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Frame, RenderError> {
    render_sequential_noting(passes, camera, settings, &PixelProgress::new())
}

/// [`render_sequential_levels`], counting its finished pixels in `progress`
/// (read it from another thread).
pub fn render_sequential_noting(
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
    progress: &PixelProgress,
) -> Result<Frame, RenderError> {
    let start = Instant::now();
    let nearest = check_levels(passes, settings)?;
    let plans = level_plans(passes, camera, settings)?;
    progress.start(
        passes
            .iter()
            .map(|(volume, _)| pass_rect(volume, camera, passes.len()).map_or(0, |r| r.area()))
            .sum(),
    );
    let mut frame = Frame::try_empty(camera.width(), camera.height(), settings.background)?;
    let record = plans[0].compositor.run(StateBytes);
    let full = PixelRect::rows(camera.width(), 0, camera.height());
    let mut counters = Counters::default();
    let (mut bricks, mut transparent) = (0, 0);
    let mut incoming: Option<StateBuffer> = None;
    // Packets of one ray only where a level is named: under `auto` the scalar
    // loop is faster here (each brick visit of one ray pays the gathers'
    // set-up; docs/benchmarks.md, section 5).
    let packets = settings
        .simd
        .is_some_and(|level| level != SimdLevel::Scalar);
    for (i, (&(volume, _), plan)) in passes.iter().zip(&plans).enumerate() {
        let mut outgoing = (i + 1 < passes.len()).then(|| StateBuffer::new(full, record));
        let states = LevelStates {
            incoming: incoming.as_ref(),
            outgoing: outgoing.as_mut(),
        };
        counters += match volume.volume().data() {
            VolumeData::U8(data) => plan.compositor.run(SequentialPass {
                volume,
                data: &data,
                camera,
                plan,
                frame: &mut frame,
                states,
                packets,
                progress,
            }),
            VolumeData::U16(data) => plan.compositor.run(SequentialPass {
                volume,
                data: &data,
                camera,
                plan,
                frame: &mut frame,
                states,
                packets,
                progress,
            }),
        };
        bricks += volume.geometry().grid().block_count();
        transparent += plan.transparent_bricks(volume);
        incoming = outgoing;
    }
    frame.stats.counters = counters;
    frame.stats.bricks = bricks;
    frame.stats.bricks_transparent = transparent;
    frame.stats.threads = 1;
    frame.stats.level = nearest.volume().level_index();
    frame.stats.coarsest_level = passes.last().map_or(0, |(v, _)| v.volume().level_index());
    frame.stats.time = start.elapsed();
    Ok(frame)
}

/// Where a level of a frame of several takes its pixels' states from and
/// leaves them (both `None` in a frame of one level).
struct LevelStates<'b> {
    /// The nearer level's states; `None`: the compositor's start.
    incoming: Option<&'b StateBuffer>,
    /// Where the states go, unresolved, for the next level; `None`: resolved
    /// into the frame.
    outgoing: Option<&'b mut StateBuffer>,
}

/// The frame's pixels with compositor `C` (chosen once per frame).
struct SequentialPass<'p, 'v, 'd, T: Sample> {
    volume: &'p RenderVolume<'v>,
    data: &'p TypedVolume<'d, T>,
    camera: &'p Camera,
    plan: &'p FramePlan,
    frame: &'p mut Frame,
    states: LevelStates<'p>,
    /// Whether to march in the plan's packet kernel (a level named in the
    /// settings, not the scalar one).
    packets: bool,
    /// Counts the finished rows' pixels.
    progress: &'p PixelProgress,
}

impl<T: Sample> CompositorJob for SequentialPass<'_, '_, '_, T> {
    type Output = Counters;

    fn run<C: Compositor>(self, c: &C) -> Counters {
        let SequentialPass {
            volume,
            data,
            camera,
            plan,
            frame,
            mut states,
            packets,
            progress,
        } = self;
        let geometry = volume.geometry();
        let sampler = VolumeSampler::new(*data);
        let mut counters = Counters::default();
        let (lo, hi) = geometry.world_bounds();
        let projected = camera.project_box(lo, hi);
        let levels = if states.incoming.is_some() || states.outgoing.is_some() {
            2
        } else {
            1
        };
        let Some(rect) = pass_rect(volume, camera, levels) else {
            return counters;
        };
        let inside = |x: u32, y: u32| {
            projected.is_some_and(|r| x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1)
        };
        let last_voxel = geometry.last_voxel();
        let mut row = vec![PixelState::new(c.start()); (rect.x1 - rect.x0) as usize];
        // Pixels whose ray was marched (a frame of one level writes only those).
        let mut marched = vec![false; row.len()];
        for y in rect.y0..rect.y1 {
            let row_rect = PixelRect {
                y0: y,
                y1: y + 1,
                ..rect
            };
            match states.incoming {
                Some(incoming) => {
                    incoming.read(row_rect, &mut row);
                    for state in &mut row {
                        continue_in_level(c, plan, state);
                    }
                }
                None => row.fill(PixelState::new(c.start())),
            }
            marched.fill(states.incoming.is_some());
            for ((x, state), marched) in (rect.x0..rect.x1).zip(row.iter_mut()).zip(&mut marched) {
                if state.done || !inside(x, y) {
                    continue;
                }
                let Some(ray) = plan.pixel_ray(camera, geometry, x, y) else {
                    continue;
                };
                counters.rays += 1;
                *marched = true;
                state.next_sample = state.next_sample.max(ray.first);
                while !state.done {
                    let k = state.next_sample;
                    let b = geometry.owner(ray.position(k, last_voxel));
                    let brick = BrickContext::new(data, volume, plan, b);
                    // Ownership is contiguous along a ray, so the owned run starts at
                    // k; a run that does not (rounding at a brick corner) is cut to k.
                    let last = match owned_samples(&ray, geometry, b) {
                        Some((first, last)) if first <= k && k <= last => last,
                        _ => k,
                    };
                    // A packet kernel of one ray where one was asked for, or
                    // the scalar loop.
                    let rays = [Some(ray)];
                    let in_packets = packets
                        && PacketWork {
                            plan,
                            volume: &sampler,
                            brick: &brick,
                            rays: &rays,
                            states: std::slice::from_mut(state),
                            items: &[PacketItem {
                                pixel: 0,
                                first: k,
                                last,
                            }],
                            counters: &mut counters,
                        }
                        .march_in_lanes(c, plan.simd);
                    if !in_packets {
                        march_brick(
                            c,
                            plan,
                            &sampler,
                            &brick,
                            &CellCache::default(),
                            &ray,
                            k,
                            last,
                            state,
                            &mut counters,
                        );
                    }
                }
            }
            match states.outgoing.as_deref_mut() {
                Some(outgoing) => outgoing.write(row_rect, &row),
                None => {
                    let pixels = (rect.x0..rect.x1).zip(&row).zip(&marched);
                    for ((x, state), _) in pixels.filter(|(_, marched)| **marched) {
                        let i = frame.index(x, y);
                        frame.rgba[i] = c.resolve(&state.acc);
                        frame.depth[i] = c.depth(&state.acc);
                    }
                }
            }
            progress.add(u64::from(rect.x1 - rect.x0));
        }
        counters
    }
}

/// The pixels a pass over `volume` marches in a frame of `levels` levels: those
/// its box projects onto, or, in a frame of several levels (which carries every
/// pixel's state on, even where a level's box does not project), all of them;
/// `None` for none.
fn pass_rect(volume: &RenderVolume<'_>, camera: &Camera, levels: usize) -> Option<PixelRect> {
    if levels > 1 {
        return Some(PixelRect::rows(camera.width(), 0, camera.height()));
    }
    let (lo, hi) = volume.geometry().world_bounds();
    camera.project_box(lo, hi)
}
