//! The object-parallel brick renderer with compositing threads (the thesis's
//! design, after Matsui et al. 2004 and Hsu 1993).
//!
//! Per frame, a [`FrameSchedule`] orders the non-empty bricks front to back and
//! queues them per tile. Compositing threads own the tiles: each seeds one task per
//! tile, receives finished tiles, and sends the tile's next brick — or, when its
//! queue is empty, resolves the tile into the frame (frames fill in progressively).
//! A brick whose covered pixels in a tile have all terminated is never sent
//! (global early ray termination). Render threads take (tile, brick) tasks from a
//! shared channel and march the tile's rays through that brick with the same
//! kernel as the sequential renderer. Tiles move by value through the channels; at
//! most one task per tile is in flight, so each tile sees its bricks in order.

use std::num::NonZeroUsize;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender};
use parking_lot::Mutex;

use super::camera::{Camera, PixelRect};
use super::cell_cache::CellCache;
use super::compositor::{Compositor, CompositorJob};
use super::counters::{Counters, FrameStats};
use super::error::RenderError;
use super::frame::Frame;
use super::level::DepthBand;
use super::march::{BrickContext, march_brick};
use super::ownership_lanes::BrickOwnership;
use super::packet::{PacketItem, PacketWork};
use super::pixel::PixelState;
use super::prepared::{FramePlan, RenderVolume};
use super::renderer::{FrameJobFn, Renderer, WorkerPool};
use super::sampler::VolumeSampler;
use super::schedule::FrameSchedule;
use super::settings::RenderSettings;
use super::state_buffer::{StateBuffer, StateBytes};
use super::tile::Tile;
use crate::volume::{Sample, TypedVolume, VolumeData};

/// Thread and tile parameters of the parallel renderer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParallelOptions {
    /// Threads that march rays (0 counts as 1; at most [`MAX_THREADS`]).
    pub render_threads: usize,
    /// Threads that own tiles and hand out their bricks (0 counts as 1; at
    /// most [`MAX_THREADS`]).
    pub compositing_threads: usize,
    /// Tile side in pixels (0 counts as 1; a tile larger than the image is
    /// the image).
    pub tile_size: u32,
}

/// The most render threads, and the most compositing threads, a frame may
/// ask for (the command line's limit too).
pub const MAX_THREADS: usize = 1024;

impl ParallelOptions {
    /// Checks the thread counts (at most [`MAX_THREADS`] each); every
    /// parallel frame does.
    pub fn check(&self) -> Result<(), RenderError> {
        for (field, n) in [
            ("options.render_threads", self.render_threads),
            ("options.compositing_threads", self.compositing_threads),
        ] {
            if n > MAX_THREADS {
                return Err(RenderError::Setting {
                    field: field.into(),
                    what: format!("{n} threads: at most {MAX_THREADS}"),
                });
            }
        }
        Ok(())
    }
}

/// The default tile side (pixels).
pub const DEFAULT_TILE_SIZE: u32 = 16;

impl Default for ParallelOptions {
    /// One render thread per core (the compositing thread mostly waits) and one
    /// compositing thread; tiles of [`DEFAULT_TILE_SIZE`].
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(1, NonZeroUsize::get);
        ParallelOptions {
            render_threads: cores,
            compositing_threads: 1,
            tile_size: DEFAULT_TILE_SIZE,
        }
    }
}

/// Receives tiles as they finish.
pub trait TileSink: Sync {
    /// Tile `rect` is final: premultiplied RGBA and first-hit depth per pixel, row
    /// by row.
    fn tile_finished(&self, rect: PixelRect, rgba: &[[f32; 4]], depth: &[f32]);

    /// The share of the frame done, in `[0, 1]`, each time a tile ends: its
    /// scheduled (tile, brick) tasks over all of them, level by level in a
    /// frame of several (whose nearer levels hand their tiles on without
    /// [`Self::tile_finished`]). For progress displays; ignored by default.
    fn progress(&self, _share: f64) {}
}

/// Renders one frame with the object-parallel renderer into a [`Frame`], on
/// threads started for this frame only (a [`Renderer`] keeps them across frames).
pub fn render_parallel(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    options: &ParallelOptions,
) -> Result<Frame, RenderError> {
    Renderer::per_frame().render(volume, camera, settings, options)
}

impl TileSink for Mutex<Frame> {
    fn tile_finished(&self, rect: PixelRect, rgba: &[[f32; 4]], depth: &[f32]) {
        let mut frame = self.lock();
        let w = (rect.x1 - rect.x0) as usize;
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            let start = frame.index(rect.x0, y);
            frame.rgba[start..start + w].copy_from_slice(&rgba[row * w..(row + 1) * w]);
            frame.depth[start..start + w].copy_from_slice(&depth[row * w..(row + 1) * w]);
        }
    }
}

/// Renders one frame, handing finished tiles to `sink` as they complete, on
/// threads started for this frame only (a [`Renderer`] keeps them across frames).
/// `cancelled` is polled by the compositing threads; when it returns true no new
/// task is sent, the frame stops early and `Ok(None)` is returned.
pub fn render_parallel_into(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    options: &ParallelOptions,
    sink: &dyn TileSink,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<Option<FrameStats>, RenderError> {
    Renderer::per_frame().render_into(volume, camera, settings, options, sink, cancelled)
}

/// Renders one frame on `workers` (render threads, compositing threads and the
/// read-ahead, all waiting in the pool between frames).
pub(crate) fn render_frame(
    workers: &WorkerPool,
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    options: &ParallelOptions,
    sink: &dyn TileSink,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<Option<FrameStats>, RenderError> {
    let start = Instant::now();
    let plan = FramePlan::new(volume, settings)?;
    super::geometry::check_sample_budget(volume.geometry(), settings.step, camera)?;
    let schedule = FrameSchedule::new(volume, &plan, camera, options.tile_size, None);
    let counters = render_tiles(
        workers,
        &FrameJob {
            volume,
            camera,
            plan: &plan,
            schedule: &schedule,
            sink,
            cancelled,
            tiles: 0..schedule.tiles.len(),
            incoming: None,
            outgoing: None,
            read_ahead: true,
            continues: false,
            pass: LevelPass::ONLY,
        },
        options,
    )?;
    Ok(counters.map(|counters| FrameStats {
        width: camera.width(),
        height: camera.height(),
        counters,
        bricks: volume.geometry().grid().block_count(),
        bricks_transparent: schedule
            .transparent
            .unwrap_or_else(|| plan.transparent_bricks(volume)),
        threads: options.render_threads as u32,
        time: start.elapsed(),
        level: volume.volume().level_index(),
        coarsest_level: volume.volume().level_index(),
    }))
}

/// Renders one frame of several levels on `workers`: `passes` are the levels,
/// nearest band first, each sampling its depth band
/// ([`LevelChoice::bands`](super::level::LevelChoice::bands)). The levels are
/// rendered one after another over the whole image, each continuing the pixels'
/// states where the nearer one left them (a ray terminated in a nearer band
/// stays terminated); the farthest resolves the pixels into `sink`. One pass
/// without a band is [`render_frame`].
pub(crate) fn render_levels_frame(
    workers: &WorkerPool,
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
    options: &ParallelOptions,
    sink: &dyn TileSink,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<Option<FrameStats>, RenderError> {
    let nearest = check_levels(passes, settings)?;
    if let [(volume, None)] = passes {
        return render_frame(workers, volume, camera, settings, options, sink, cancelled);
    }
    let start = Instant::now();
    let plans = level_plans(passes, camera, settings)?;
    let full = PixelRect::rows(camera.width(), 0, camera.height());
    let record = plans[0].compositor.run(StateBytes);
    let mut incoming: Option<StateBuffer> = None;
    let mut total = Counters::default();
    let (mut bricks, mut transparent) = (0, 0);
    for (i, (&(volume, _), plan)) in passes.iter().zip(&plans).enumerate() {
        let schedule = FrameSchedule::new(volume, plan, camera, options.tile_size, None);
        let last = i + 1 == passes.len();
        let outgoing = (!last).then(|| Mutex::new(StateBuffer::new(full, record)));
        let counters = render_tiles(
            workers,
            &FrameJob {
                volume,
                camera,
                plan,
                schedule: &schedule,
                sink,
                cancelled,
                tiles: 0..schedule.tiles.len(),
                incoming: incoming.as_ref(),
                outgoing: outgoing.as_ref(),
                read_ahead: true,
                continues: true,
                pass: LevelPass {
                    index: i,
                    count: passes.len(),
                },
            },
            options,
        )?;
        let Some(counters) = counters else {
            return Ok(None);
        };
        total += counters;
        bricks += volume.geometry().grid().block_count();
        transparent += schedule
            .transparent
            .unwrap_or_else(|| plan.transparent_bricks(volume));
        incoming = outgoing.map(Mutex::into_inner);
    }
    let coarsest = passes.last().map_or(nearest, |&(v, _)| v);
    Ok(Some(FrameStats {
        width: camera.width(),
        height: camera.height(),
        counters: total,
        bricks,
        bricks_transparent: transparent,
        threads: options.render_threads as u32,
        time: start.elapsed(),
        level: nearest.volume().level_index(),
        coarsest_level: coarsest.volume().level_index(),
    }))
}

/// The nearest level of a frame of `passes`, or why they make no frame: a
/// setting out of range ([`RenderSettings::check`]), no level, several for a
/// two-level scene (whose segments would be cut where the levels meet; such
/// scenes sample one level per frame), or several that are not distinct levels
/// of one volume, finest first, each with its depth band.
pub(crate) fn check_levels<'p, 'v>(
    passes: &'p [(&'p RenderVolume<'v>, Option<DepthBand>)],
    settings: &RenderSettings,
) -> Result<&'p RenderVolume<'v>, RenderError> {
    settings.check()?;
    match passes {
        [] => Err(RenderError::Levels("a frame needs a level to sample")),
        [_, _, ..] if settings.segments.is_some() => Err(RenderError::Levels(
            "two-level scenes sample one level per frame",
        )),
        [_, _, ..] if passes.iter().any(|(_, band)| band.is_none()) => Err(RenderError::Levels(
            "a frame of several levels needs a depth band for each level (LevelChoice::bands)",
        )),
        [_, _, ..] if !levels_of_one_volume(passes) => Err(RenderError::Levels(
            "the levels of a frame are levels of one volume, finest first, each once",
        )),
        [(nearest, _), ..] => Ok(nearest),
    }
}

/// Whether `passes` are distinct levels of one pyramid, finest first: the
/// same full-resolution size and level-0 spacing, levels increasing.
fn levels_of_one_volume(passes: &[(&RenderVolume<'_>, Option<DepthBand>)]) -> bool {
    let level0 = |v: &RenderVolume<'_>| {
        let volume = v.volume();
        let scale = volume.level_scale();
        (volume.full_dims(), volume.spacing().map(|s| s / scale))
    };
    let first = level0(passes[0].0);
    passes
        .windows(2)
        .all(|pair| pair[0].0.volume().level_index() < pair[1].0.volume().level_index())
        && passes.iter().all(|(v, _)| level0(v) == first)
}

/// The plans of a frame's levels (each for its band), every level's sample
/// budget checked.
pub(crate) fn level_plans(
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
) -> Result<Vec<FramePlan>, RenderError> {
    passes
        .iter()
        .map(|&(volume, band)| {
            super::geometry::check_sample_budget(volume.geometry(), settings.step, camera)?;
            Ok(FramePlan::new(volume, settings)?.in_band(band))
        })
        .collect()
}

/// A pixel's state as the next (coarser) level of a frame takes it over: its
/// samples are counted from that level's first, and it is finished only if it
/// terminated (early termination or a hit), not because the nearer level's
/// band ended.
#[inline]
pub(crate) fn continue_in_level<C: Compositor>(
    c: &C,
    plan: &FramePlan,
    state: &mut PixelState<C::State>,
) {
    state.next_sample = 0;
    state.done = c.opacity(&state.acc) >= plan.ert_threshold || c.finished(&state.acc);
}

/// Runs `job`'s tiles on `workers`: the summed counters, or `None` if cancelled;
/// an error where the system refuses a thread of the frame.
pub(crate) fn render_tiles(
    workers: &WorkerPool,
    job: &FrameJob<'_>,
    options: &ParallelOptions,
) -> Result<Option<Counters>, RenderError> {
    match job.volume.volume().data() {
        VolumeData::U8(data) => job.plan.compositor.run(ParallelPass {
            job,
            workers,
            data: &data,
            options,
        }),
        VolumeData::U16(data) => job.plan.compositor.run(ParallelPass {
            job,
            workers,
            data: &data,
            options,
        }),
    }
}

/// A (tile, brick) task: the tile travels with it.
struct Task<S> {
    tile: Tile<S>,
    brick: u32,
}

/// What comes after a tile's task: its next brick, or its queue is done.
enum NextTask<S> {
    March(Task<S>),
    Done(Tile<S>),
}

/// Everything one frame's threads share (read only).
pub(crate) struct FrameJob<'f> {
    pub volume: &'f RenderVolume<'f>,
    pub camera: &'f Camera,
    pub plan: &'f FramePlan,
    pub schedule: &'f FrameSchedule,
    /// Receives finished tiles' pixels (not with `outgoing`).
    pub sink: &'f dyn TileSink,
    pub cancelled: &'f (dyn Fn() -> bool + Sync),
    /// The tiles to render (indices into the schedule's tiles): all of them, or
    /// a band of a distributed frame.
    pub tiles: std::ops::Range<usize>,
    /// The pixels' states to start from (another process rendered the parts
    /// in front); `None`: the compositor's start state.
    pub incoming: Option<&'f StateBuffer>,
    /// Where finished tiles' states go instead of `sink`, unresolved (a part
    /// behind, on another process, continues them).
    pub outgoing: Option<&'f Mutex<StateBuffer>>,
    /// Whether to ask the OS to read the schedule's bricks ahead.
    pub read_ahead: bool,
    /// The incoming states come from another level of the frame
    /// ([`continue_in_level`]).
    pub continues: bool,
    /// Which of the frame's level passes this is (for its progress).
    pub pass: LevelPass,
}

/// A job's place among the level passes of its frame: pass `index` of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LevelPass {
    pub index: usize,
    pub count: usize,
}

impl LevelPass {
    /// The one pass of a frame of one level.
    pub const ONLY: LevelPass = LevelPass { index: 0, count: 1 };
}

/// A job's tasks ended so far (a tile's whole queue when it ends) of all its
/// tiles' queues.
struct TaskProgress {
    total: u64,
    done: AtomicU64,
}

/// A frame's threads with the frame's compositor (chosen once per frame).
struct ParallelPass<'p, 'f, 'd, T: Sample> {
    job: &'p FrameJob<'f>,
    workers: &'p WorkerPool,
    data: &'p TypedVolume<'d, T>,
    options: &'p ParallelOptions,
}

impl<T: Sample> CompositorJob for ParallelPass<'_, '_, '_, T> {
    type Output = Result<Option<Counters>, RenderError>;
    fn run<C: Compositor>(self, c: &C) -> Result<Option<Counters>, RenderError> {
        self.job.run(self.workers, c, self.data, self.options)
    }
}

impl FrameJob<'_> {
    /// Runs the frame's threads; the summed counters, or `None` if cancelled.
    /// Where the system refuses one of them, the started ones stop as if the
    /// frame were cancelled and the refusal is returned.
    fn run<T: Sample, C: Compositor>(
        &self,
        workers: &WorkerPool,
        c: &C,
        data: &TypedVolume<'_, T>,
        options: &ParallelOptions,
    ) -> Result<Option<Counters>, RenderError> {
        let refused = AtomicBool::new(false);
        let cancelled = || refused.load(Ordering::Relaxed) || (self.cancelled)();
        let job = FrameJob {
            cancelled: &cancelled,
            tiles: self.tiles.clone(),
            ..*self
        };
        job.run_threads(workers, c, data, options, &|| {
            refused.store(true, Ordering::Relaxed)
        })
    }

    /// [`Self::run`]'s threads; `refused` is called where the system refuses
    /// one.
    fn run_threads<T: Sample, C: Compositor>(
        &self,
        workers: &WorkerPool,
        c: &C,
        data: &TypedVolume<'_, T>,
        options: &ParallelOptions,
        refused: &(dyn Fn() + Sync),
    ) -> Result<Option<Counters>, RenderError> {
        let compositors = options.compositing_threads.max(1);
        let (task_tx, task_rx) = crossbeam_channel::unbounded::<Task<C::State>>();
        type Channel<S> = (Vec<Sender<Tile<S>>>, Vec<Receiver<Tile<S>>>);
        let (result_txs, result_rxs): Channel<C::State> = (0..compositors)
            .map(|_| crossbeam_channel::unbounded())
            .unzip();
        let (total_tx, total_rx) = crossbeam_channel::unbounded::<Option<Counters>>();
        let progress = TaskProgress {
            total: self
                .tiles
                .clone()
                .map(|t| self.schedule.tiles[t].bricks.len() as u64)
                .sum(),
            done: AtomicU64::new(0),
        };
        let progress = &progress;
        let mut jobs: Vec<FrameJobFn<'_>> = Vec::new();
        if self.read_ahead {
            jobs.push(Box::new(|| self.read_ahead()));
        }
        for _ in 0..options.render_threads.max(1) {
            let task_rx = task_rx.clone();
            let result_txs = result_txs.clone();
            jobs.push(Box::new(move || {
                self.render_tasks(c, data, &task_rx, &result_txs)
            }));
        }
        drop(result_txs);
        for (k, results) in result_rxs.into_iter().enumerate() {
            let task_tx = task_tx.clone();
            let total_tx = total_tx.clone();
            jobs.push(Box::new(move || {
                let counters = self.composite(
                    c,
                    k as u32,
                    compositors as u32,
                    &task_tx,
                    &results,
                    progress,
                );
                let _ = total_tx.send(counters);
            }));
        }
        drop(task_tx);
        workers.run_all(jobs, refused)?;
        drop(total_tx);
        let mut total = Some(Counters::default());
        for counters in total_rx.iter() {
            match (counters, total.as_mut()) {
                (Some(c), Some(t)) => *t += c,
                _ => total = None,
            }
        }
        Ok(total)
    }

    /// Asks the OS to read the frame's bricks in the order the frame visits them
    /// (front to back, visible and non-empty only; bricks of bricked files, the
    /// rows of linear files: [`super::read_ahead`]), so that render threads find
    /// them in the page cache instead of stalling on page faults; returns when
    /// every request is made or the frame is cancelled.
    fn read_ahead(&self) {
        super::read_ahead::read_ahead(
            self.volume,
            self.schedule.bricks.iter().map(|s| s.coords),
            self.cancelled,
        );
    }

    /// A render thread: march each task's tile through its brick, send it back.
    fn render_tasks<T: Sample, C: Compositor>(
        &self,
        c: &C,
        data: &TypedVolume<'_, T>,
        tasks: &Receiver<Task<C::State>>,
        results: &[Sender<Tile<C::State>>],
    ) {
        let geometry = self.volume.geometry();
        let sampler = VolumeSampler::new(*data);
        let volume_rect = self.schedule.volume_rect.unwrap_or(PixelRect {
            x0: 0,
            y0: 0,
            x1: 0,
            y1: 0,
        });
        let mut items: Vec<PacketItem> = Vec::new();
        for task in tasks.iter() {
            let Task {
                mut tile,
                mut brick,
            } = task;
            // March the tile through its queue's bricks while it has one to
            // march; hand it back when its queue is done or the frame cancelled.
            while !(self.cancelled)() {
                tile.prepare_rays(self.camera, geometry, self.plan, &volume_rect);
                let scheduled = self.schedule.bricks[brick as usize];
                let context = BrickContext::new(data, self.volume, self.plan, scheduled.coords);
                let mut counters = tile.counters;
                counters.tasks += 1;
                items.clear();
                if let Some(r) = tile.rect.intersect(&scheduled.rect) {
                    let ownership = BrickOwnership::new(geometry, scheduled.coords, self.plan.simd);
                    for y in r.y0..r.y1 {
                        let row = tile.local(r.x0, y);
                        ownership.push_owned(
                            &tile.ray_lanes,
                            &tile.rays,
                            &tile.states,
                            row..row + (r.x1 - r.x0) as usize,
                            &mut items,
                        );
                    }
                }
                let in_packets = PacketWork {
                    plan: self.plan,
                    volume: &sampler,
                    brick: &context,
                    rays: &tile.rays,
                    states: &mut tile.states,
                    items: &items,
                    counters: &mut counters,
                }
                .march_in_lanes(c, self.plan.simd);
                if !in_packets {
                    let cell = CellCache::default();
                    for item in &items {
                        let (Some(ray), state) =
                            (&tile.rays[item.pixel], &mut tile.states[item.pixel])
                        else {
                            continue;
                        };
                        march_brick(
                            c,
                            self.plan,
                            &sampler,
                            &context,
                            &cell,
                            ray,
                            item.first,
                            item.last,
                            state,
                            &mut counters,
                        );
                    }
                }
                tile.counters = counters;
                tile.next += 1;
                match self.next_task(tile) {
                    NextTask::March(task) => (tile, brick) = (task.tile, task.brick),
                    NextTask::Done(done) => {
                        tile = done;
                        break;
                    }
                }
            }
            // The compositor may have stopped listening (cancelled): nothing to do.
            let _ = results[tile.compositor as usize].send(tile);
        }
    }

    /// A compositing thread: owns tiles `k, k + n, k + 2n, …`; returns their summed
    /// counters, or `None` if the frame was cancelled.
    fn composite<C: Compositor>(
        &self,
        c: &C,
        k: u32,
        n: u32,
        tasks: &Sender<Task<C::State>>,
        results: &Receiver<Tile<C::State>>,
        progress: &TaskProgress,
    ) -> Option<Counters> {
        let mut counters = Counters::default();
        let mut in_flight = 0usize;
        for index in self.tiles.clone().skip(k as usize).step_by(n as usize) {
            let queue = &self.schedule.tiles[index];
            let mut tile = Tile::new(index as u32, k, queue.rect, c.start());
            if let Some(incoming) = self.incoming {
                incoming.read(queue.rect, &mut tile.states);
                if self.continues {
                    for state in &mut tile.states {
                        continue_in_level(c, self.plan, state);
                    }
                }
            }
            match self.next_task(tile) {
                NextTask::March(task) => {
                    in_flight += 1;
                    tasks
                        .send(task)
                        .expect("render threads outlive the compositors");
                }
                NextTask::Done(tile) => {
                    self.finish(c, &tile, progress);
                    counters += tile.counters;
                }
            }
        }
        let mut cancelled = false;
        while in_flight > 0 {
            let tile = results.recv().expect("render threads return every tile");
            in_flight -= 1;
            cancelled = cancelled || (self.cancelled)();
            if cancelled {
                continue;
            }
            // Not cancelled when the render thread gave it back: its queue is done.
            self.finish(c, &tile, progress);
            counters += tile.counters;
        }
        (!cancelled).then_some(counters)
    }

    /// The tile's next task, skipping bricks whose covered pixels have all
    /// terminated; or the tile back when its queue is done. Render threads ask
    /// after each task, so a tile stays with one thread (and in its caches)
    /// from its first brick to its last, without a round trip through the
    /// compositing thread per brick.
    fn next_task<S: Copy>(&self, mut tile: Tile<S>) -> NextTask<S> {
        let queue = &self.schedule.tiles[tile.index as usize].bricks;
        // A tile whose every pixel is finished skips the rest of its queue at
        // once (close to a large volume, a tile's queue holds up to hundreds of
        // thousands of bricks, each covering most of the tile).
        if tile.next < queue.len() && tile.all_finished() {
            let rest = queue.len() - tile.next;
            tile.counters.tasks_skipped_occluded += rest as u64;
            tile.next = queue.len();
        }
        while let Some(&brick) = queue.get(tile.next) {
            if !tile.finished_within(&self.schedule.bricks[brick as usize].rect) {
                return NextTask::March(Task { tile, brick });
            }
            tile.counters.tasks_skipped_occluded += 1;
            tile.next += 1;
        }
        NextTask::Done(tile)
    }

    /// Resolves a finished tile's pixels and hands them to the sink, or hands
    /// on its states unresolved; then tells the sink how far the frame is.
    fn finish<C: Compositor>(&self, c: &C, tile: &Tile<C::State>, progress: &TaskProgress) {
        if let Some(outgoing) = self.outgoing {
            outgoing.lock().write(tile.rect, &tile.states);
        } else {
            let rgba: Vec<[f32; 4]> = tile.states.iter().map(|s| c.resolve(&s.acc)).collect();
            let depth: Vec<f32> = tile.states.iter().map(|s| c.depth(&s.acc)).collect();
            self.sink.tile_finished(tile.rect, &rgba, &depth);
        }
        let queue = self.schedule.tiles[tile.index as usize].bricks.len() as u64;
        let done = progress.done.fetch_add(queue, Ordering::Relaxed) + queue;
        let pass_share = if progress.total == 0 {
            1.0
        } else {
            done.min(progress.total) as f64 / progress.total as f64
        };
        let LevelPass { index, count } = self.pass;
        self.sink
            .progress((index as f64 + pass_share) / count.max(1) as f64);
    }
}
