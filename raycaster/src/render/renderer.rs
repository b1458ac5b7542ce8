//! A renderer object whose worker threads live across frames.
//!
//! The parallel renderer's frame runs its render threads, compositing threads and
//! the read-ahead concurrently; they block on channels, so each needs a thread of
//! its own. A [`Renderer`] keeps a pool of exactly that many threads waiting
//! between frames and hands each frame to them, instead of starting and joining
//! them per frame (the viewer asks for a frame on every mouse move).

use parking_lot::Mutex;

use super::camera::Camera;
use super::counters::FrameStats;
use super::error::RenderError;
use super::frame::Frame;
use super::parallel::{ParallelOptions, TileSink, render_frame};
use super::prepared::RenderVolume;
use super::settings::RenderSettings;

/// The threads of one frame's jobs, kept between frames.
pub(crate) struct WorkerPool {
    pool: rayon::ThreadPool,
    /// (render threads, compositing threads) the pool is sized for.
    sized_for: (usize, usize),
}

impl WorkerPool {
    /// Threads for `render` render threads, `compositors` compositing threads
    /// and the read-ahead.
    fn new(render: usize, compositors: usize) -> WorkerPool {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(render + compositors + 1)
            .thread_name(|i| format!("render-worker-{i}"))
            .build()
            .expect("starting the render worker threads");
        WorkerPool {
            pool,
            sized_for: (render, compositors),
        }
    }

    /// The sizes `options` asks for (at least one of each).
    fn sizes(options: &ParallelOptions) -> (usize, usize) {
        (
            options.render_threads.max(1),
            options.compositing_threads.max(1),
        )
    }

    /// Runs `op`, which may spawn up to the frame's jobs for `options`, and waits
    /// until every spawned job has returned. Each job gets a thread of its own.
    pub fn scope<'scope, OP>(&self, options: &ParallelOptions, op: OP)
    where
        OP: FnOnce(&rayon::Scope<'scope>) + Send,
    {
        debug_assert_eq!(WorkerPool::sizes(options), self.sized_for);
        self.pool.scope(op);
    }
}

/// The parallel renderer with worker threads that live across frames.
///
/// One renderer renders one frame at a time (`&mut self`); the first frame, and a
/// frame whose options ask for other thread counts, start the threads.
#[derive(Default)]
pub struct Renderer {
    workers: Option<WorkerPool>,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("threads", &self.workers.as_ref().map(|w| w.sized_for))
            .finish()
    }
}

impl Renderer {
    /// A renderer with no threads yet.
    pub fn new() -> Renderer {
        Renderer::default()
    }

    /// Renders one frame into a [`Frame`].
    pub fn render(
        &mut self,
        volume: &RenderVolume<'_>,
        camera: &Camera,
        settings: &RenderSettings,
        options: &ParallelOptions,
    ) -> Result<Frame, RenderError> {
        let frame = Mutex::new(Frame::empty(
            camera.width(),
            camera.height(),
            settings.background,
        ));
        let stats = self
            .render_into(volume, camera, settings, options, &frame, &|| false)?
            .expect("a frame that cannot be cancelled completes");
        let mut frame = frame.into_inner();
        frame.stats = stats;
        Ok(frame)
    }

    /// Renders one frame, handing finished tiles to `sink` as they complete.
    /// `cancelled` is polled by the compositing threads; when it returns true no
    /// new task is sent, the frame stops early and `Ok(None)` is returned.
    pub fn render_into(
        &mut self,
        volume: &RenderVolume<'_>,
        camera: &Camera,
        settings: &RenderSettings,
        options: &ParallelOptions,
        sink: &dyn TileSink,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<FrameStats>, RenderError> {
        let workers = &mut self.workers;
        let sizes = WorkerPool::sizes(options);
        if workers.as_ref().is_none_or(|w| w.sized_for != sizes) {
            *workers = Some(WorkerPool::new(sizes.0, sizes.1));
        }
        let workers = workers.as_ref().expect("just started");
        render_frame(workers, volume, camera, settings, options, sink, cancelled)
    }
}
