//! The sequential reference renderer: image order, one pixel at a time, each ray
//! walked brick by brick through the shared marching loop.
//!
//! It is deliberately simple and is the oracle every faster renderer is compared
//! with: for each pixel inside the volume's projected rectangle, find the brick
//! owning the ray's next sample, let the kernel march the samples that brick owns,
//! and repeat until the ray leaves the volume, terminates early or hits.

use std::time::Instant;

use super::camera::Camera;
use super::compositor::{Compositor, CompositorJob};
use super::counters::Counters;
use super::error::RenderError;
use super::frame::Frame;
use super::march::{BrickContext, march_brick};
use super::ownership::owned_samples;
use super::pixel::{PixelRay, PixelState, ray_jitter};
use super::prepared::{FramePlan, RenderVolume};
use super::sampler::VolumeSampler;
use super::settings::RenderSettings;
use crate::volume::{Sample, TypedVolume, VolumeData};

/// Renders one frame of `volume` seen by `camera`, on the calling thread.
pub fn render_sequential(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Frame, RenderError> {
    let start = Instant::now();
    let plan = FramePlan::new(volume, settings)?;
    super::geometry::check_sample_budget(volume.geometry(), settings.step, camera)?;
    let mut frame = Frame::empty(camera.width(), camera.height(), settings.background);
    let counters = match volume.volume().data() {
        VolumeData::U8(data) => plan.compositor.run(SequentialPass {
            volume,
            data: &data,
            camera,
            plan: &plan,
            frame: &mut frame,
        }),
        VolumeData::U16(data) => plan.compositor.run(SequentialPass {
            volume,
            data: &data,
            camera,
            plan: &plan,
            frame: &mut frame,
        }),
    };
    frame.stats.counters = counters;
    frame.stats.bricks = volume.geometry().grid().block_count();
    frame.stats.bricks_transparent = plan.transparent_bricks();
    frame.stats.threads = 1;
    frame.stats.level = volume.volume().level_index();
    frame.stats.time = start.elapsed();
    Ok(frame)
}

/// The frame's pixels with compositor `C` (chosen once per frame).
struct SequentialPass<'p, 'v, 'd, T: Sample> {
    volume: &'p RenderVolume<'v>,
    data: &'p TypedVolume<'d, T>,
    camera: &'p Camera,
    plan: &'p FramePlan,
    frame: &'p mut Frame,
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
        } = self;
        let geometry = volume.geometry();
        let sampler = VolumeSampler::new(*data);
        let mut counters = Counters::default();
        let (lo, hi) = geometry.world_bounds();
        let Some(rect) = camera.project_box(lo, hi) else {
            return counters;
        };
        let last_voxel = geometry.last_voxel();
        for y in rect.y0..rect.y1 {
            for x in rect.x0..rect.x1 {
                let jitter = if plan.jitter { ray_jitter(x, y) } else { 0.0 };
                let Some(ray) =
                    PixelRay::new(&camera.ray(x, y), geometry, plan.dt, jitter, &plan.clip)
                else {
                    continue;
                };
                counters.rays += 1;
                let mut state = PixelState::starting(c.start(), &ray);
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
                    march_brick(
                        c,
                        plan,
                        &sampler,
                        &brick,
                        &ray,
                        k,
                        last,
                        &mut state,
                        &mut counters,
                    );
                }
                let i = frame.index(x, y);
                frame.rgba[i] = c.resolve(&state.acc);
                frame.depth[i] = c.depth(&state.acc);
            }
        }
        counters
    }
}
