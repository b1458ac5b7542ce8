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
use super::level::DepthBand;
use super::parallel::{ParallelOptions, TileSink, render_levels_frame};
use super::prepared::RenderVolume;
use super::settings::RenderSettings;

/// One of a frame's jobs: runs until the frame is done.
pub(crate) type FrameJobFn<'a> = Box<dyn FnOnce() + Send + 'a>;

/// Where a frame's jobs run: threads started for the frame, or threads kept
/// between frames.
pub(crate) enum WorkerPool {
    /// A thread per job, started and joined for each frame.
    PerFrame,
    /// A pool of waiting threads, sized for (render, compositing) threads.
    Kept {
        /// The threads.
        pool: rayon::ThreadPool,
        /// (render threads, compositing threads) the pool is sized for.
        sized_for: (usize, usize),
    },
}

impl WorkerPool {
    /// Threads for `render` render threads, `compositors` compositing threads
    /// and the read-ahead.
    /// An error where the system refuses them (it panicked).
    fn kept(render: usize, compositors: usize) -> Result<WorkerPool, RenderError> {
        let count = render + compositors + 1;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(count)
            .thread_name(|i| format!("render-worker-{i}"))
            .spawn_handler(|thread| {
                let mut builder = std::thread::Builder::new();
                if let Some(name) = thread.name() {
                    builder = builder.name(name.to_owned());
                }
                if let Some(size) = thread.stack_size() {
                    builder = builder.stack_size(size);
                }
                spawn_checked(thread.index(), || builder.spawn(|| thread.run()))?;
                Ok(())
            })
            .build()
            .map_err(|e| RenderError::Threads {
                count,
                reason: e.to_string(),
            })?;
        Ok(WorkerPool::Kept {
            pool,
            sized_for: (render, compositors),
        })
    }

    /// The sizes `options` asks for (at least one of each).
    fn sizes(options: &ParallelOptions) -> (usize, usize) {
        (
            options.render_threads.max(1),
            options.compositing_threads.max(1),
        )
    }

    /// Runs `jobs` concurrently, each on a thread of its own, and returns when
    /// all have returned. They are at most the frame's jobs for the options the
    /// pool is sized for (jobs block on one another, so none may wait for a
    /// thread).
    ///
    /// Where the system refuses a thread (threads started per frame), the jobs
    /// not yet started are dropped and `refused` is called, which must make the
    /// started ones return (the frame's jobs take it as a cancel; the dropped
    /// jobs' channel ends close); then the refusal is returned.
    pub fn run_all(
        &self,
        jobs: Vec<FrameJobFn<'_>>,
        refused: &(dyn Fn() + Sync),
    ) -> Result<(), RenderError> {
        match self {
            WorkerPool::PerFrame => {
                let count = jobs.len();
                std::thread::scope(|scope| {
                    for (i, job) in jobs.into_iter().enumerate() {
                        // (A refused job is dropped by the failed start, and
                        // the jobs after it when the loop ends.)
                        let started = spawn_checked(i, || {
                            std::thread::Builder::new().spawn_scoped(scope, job)
                        });
                        if let Err(e) = started {
                            refused();
                            return Err(RenderError::Threads {
                                count,
                                reason: e.to_string(),
                            });
                        }
                    }
                    Ok(())
                })
            }
            WorkerPool::Kept { pool, sized_for } => {
                assert!(
                    jobs.len() <= sized_for.0 + sized_for.1 + 1,
                    "more jobs than worker threads"
                );
                pool.scope(|scope| {
                    for job in jobs {
                        scope.spawn(move |_| job());
                    }
                });
                Ok(())
            }
        }
    }
}

/// Starts thread `i` of a set with `spawn`. Tests make the system refuse
/// threads from a given one on ([`tests::refuse_threads_from`]).
fn spawn_checked<H>(i: usize, spawn: impl FnOnce() -> std::io::Result<H>) -> std::io::Result<H> {
    #[cfg(test)]
    if i >= tests::REFUSED_FROM.get() {
        return Err(std::io::Error::other(format!(
            "thread {i} refused by the test"
        )));
    }
    #[cfg(not(test))]
    let _ = i;
    spawn()
}

/// The parallel renderer with worker threads that live across frames.
///
/// One renderer renders one frame at a time (`&mut self`); the first frame, and a
/// frame whose options ask for other thread counts, start the threads.
#[derive(Default)]
pub struct Renderer {
    workers: Option<WorkerPool>,
    /// Start threads for each frame instead (the one-frame functions).
    per_frame: bool,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field(
                "kept_threads",
                &match &self.workers {
                    Some(WorkerPool::Kept { sized_for, .. }) => Some(*sized_for),
                    _ => None,
                },
            )
            .finish()
    }
}

impl Renderer {
    /// A renderer with no threads yet.
    pub fn new() -> Renderer {
        Renderer::default()
    }

    /// A renderer that starts and joins its threads for every frame (what
    /// [`super::render_parallel`] does for a single frame).
    pub fn per_frame() -> Renderer {
        Renderer {
            workers: None,
            per_frame: true,
        }
    }

    /// Renders one frame into a [`Frame`].
    pub fn render(
        &mut self,
        volume: &RenderVolume<'_>,
        camera: &Camera,
        settings: &RenderSettings,
        options: &ParallelOptions,
    ) -> Result<Frame, RenderError> {
        self.render_levels(&[(volume, None)], camera, settings, options)
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
        self.render_levels_into(
            &[(volume, None)],
            camera,
            settings,
            options,
            sink,
            cancelled,
        )
    }

    /// Renders one frame of several pyramid levels, nearest band first
    /// ([`LevelChoice::bands`](super::LevelChoice::bands): each level samples its
    /// band of depths), handing the farthest level's finished tiles to `sink`.
    /// One level without a band is [`Self::render_into`]'s frame; the sequential
    /// reference is [`super::render_sequential_levels`].
    pub fn render_levels_into(
        &mut self,
        passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
        camera: &Camera,
        settings: &RenderSettings,
        options: &ParallelOptions,
        sink: &dyn TileSink,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<FrameStats>, RenderError> {
        // (Before the thread counts, as the sequential renderer says it.)
        settings.check()?;
        let workers = self.workers_for(options)?;
        render_levels_frame(workers, passes, camera, settings, options, sink, cancelled)
    }

    /// Renders one frame of several pyramid levels into a [`Frame`]
    /// ([`Self::render_levels_into`]).
    pub fn render_levels(
        &mut self,
        passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
        camera: &Camera,
        settings: &RenderSettings,
        options: &ParallelOptions,
    ) -> Result<Frame, RenderError> {
        let frame = Mutex::new(Frame::try_empty(
            camera.width(),
            camera.height(),
            settings.background,
        )?);
        let stats = self
            .render_levels_into(passes, camera, settings, options, &frame, &|| false)?
            .expect("a frame that cannot be cancelled completes");
        let mut frame = frame.into_inner();
        frame.stats = stats;
        Ok(frame)
    }

    /// The worker threads for frames with `options`, started when missing or
    /// sized for other options (an error where the system refuses them).
    pub(crate) fn workers_for(
        &mut self,
        options: &ParallelOptions,
    ) -> Result<&WorkerPool, RenderError> {
        options.check()?;
        let sizes = WorkerPool::sizes(options);
        let fits = match &self.workers {
            Some(WorkerPool::PerFrame) => true,
            Some(WorkerPool::Kept { sized_for, .. }) => *sized_for == sizes,
            None => false,
        };
        if !fits {
            self.workers = Some(if self.per_frame {
                WorkerPool::PerFrame
            } else {
                WorkerPool::kept(sizes.0, sizes.1)?
            });
        }
        Ok(self.workers.as_ref().expect("just started"))
    }
}

#[cfg(test)]
pub(super) mod tests {
    use std::cell::Cell;

    use glam::Vec3;

    use super::*;
    use crate::render::camera::Projection;
    use crate::render::parallel::{MAX_THREADS, render_parallel};
    use crate::render::sequential::render_sequential;
    use crate::synth::{SceneKind, synthesize};
    use crate::volume::{SampleType, Volume};

    thread_local! {
        /// The first thread the "system" refuses to start on this (the test's)
        /// thread: [`spawn_checked`] reads it.
        pub(super) static REFUSED_FROM: Cell<usize> = const { Cell::new(usize::MAX) };
    }

    /// Makes threads from the `first`th on (of each set started from this
    /// thread) fail to start, as an address-space or process limit would;
    /// `usize::MAX`: none.
    fn refuse_threads_from(first: usize) {
        REFUSED_FROM.set(first);
    }

    fn shapes() -> Volume {
        let scene = SceneKind::Shapes.build([40; 3], 1);
        synthesize(scene.as_ref(), "shapes", [40; 3], [1.0; 3], SampleType::U8).unwrap()
    }

    fn camera() -> Camera {
        let projection = Projection::Perspective { vfov_deg: 50.0 };
        Camera::look_at(
            Vec3::new(-45.0, 60.0, 75.0),
            Vec3::splat(20.0),
            Vec3::Z,
            projection,
            48,
            40,
        )
        .unwrap()
    }

    fn options() -> ParallelOptions {
        ParallelOptions {
            render_threads: 3,
            compositing_threads: 2,
            tile_size: 8,
        }
    }

    fn assert_refused(result: Result<Frame, RenderError>, count: usize, what: &str) {
        match result {
            Err(RenderError::Threads { count: c, reason }) => {
                assert_eq!(c, count, "{what}");
                assert!(reason.contains("refused by the test"), "{what}: {reason}");
            }
            Err(e) => panic!("{what}: another error: {e}"),
            Ok(_) => panic!("{what}: rendered although a thread was refused"),
        }
    }

    #[test]
    fn a_thread_refused_at_any_point_of_a_frame_is_an_error_and_every_started_one_ends() {
        let volume = shapes();
        let prepared = RenderVolume::new(&volume, Some(8)).unwrap();
        let (camera, settings, options) = (camera(), RenderSettings::default(), options());
        // The read-ahead, three render threads, two compositing threads.
        let jobs = 6;
        for first in 0..jobs {
            refuse_threads_from(first);
            let result = Renderer::per_frame().render(&prepared, &camera, &settings, &options);
            assert_refused(result, jobs, &format!("thread {first} refused"));
        }
        refuse_threads_from(usize::MAX);
        let frame = Renderer::per_frame()
            .render(&prepared, &camera, &settings, &options)
            .unwrap();
        let reference = render_sequential(&prepared, &camera, &settings).unwrap();
        assert!(frame.stats.counters.samples > 0);
        assert_eq!(
            frame.stats.counters.samples,
            reference.stats.counters.samples
        );
    }

    #[test]
    fn settings_and_thread_counts_out_of_range_are_errors_before_any_thread() {
        let volume = shapes();
        let prepared = RenderVolume::new(&volume, Some(8)).unwrap();
        let (camera, settings) = (camera(), RenderSettings::default());
        // Counts whose threads cannot exist (a capacity overflow or memory
        // exhaustion before): refused by name; the thread hook sees none.
        refuse_threads_from(0);
        for (options, field) in [
            (
                ParallelOptions {
                    compositing_threads: usize::MAX,
                    ..options()
                },
                "options.compositing_threads",
            ),
            (
                ParallelOptions {
                    render_threads: MAX_THREADS + 1,
                    ..options()
                },
                "options.render_threads",
            ),
        ] {
            for mut renderer in [Renderer::new(), Renderer::per_frame()] {
                match renderer.render(&prepared, &camera, &settings, &options) {
                    Err(RenderError::Setting { field: f, .. }) => assert_eq!(f, field),
                    other => panic!("{field}: {:?}", other.map(|_| ())),
                }
            }
        }
        refuse_threads_from(usize::MAX);
        // A setting out of range is the same error from both renderers (the
        // sequential one said a NaN step as a sample budget).
        for change in [
            (|s: &mut RenderSettings| s.step = f32::NAN) as fn(&mut RenderSettings),
            |s| s.step = 0.0,
            |s| s.transfer.domain = Some([5.0, 5.0]),
            |s| s.background = [f32::NAN; 3],
        ] {
            let mut bad = settings.clone();
            change(&mut bad);
            let sequential = render_sequential(&prepared, &camera, &bad).map(|_| ());
            let parallel = render_parallel(&prepared, &camera, &bad, &options()).map(|_| ());
            let (s, p) = (sequential.unwrap_err(), parallel.unwrap_err());
            assert_eq!(s.to_string(), p.to_string());
            assert!(!s.to_string().contains("samples"), "{s}");
        }
    }

    #[test]
    fn a_kept_pool_the_system_refuses_is_an_error_and_the_next_frame_starts_it_again() {
        let volume = shapes();
        let prepared = RenderVolume::new(&volume, Some(8)).unwrap();
        let (camera, settings, options) = (camera(), RenderSettings::default(), options());
        let mut renderer = Renderer::new();
        for first in [0, 4] {
            refuse_threads_from(first);
            let result = renderer.render(&prepared, &camera, &settings, &options);
            assert_refused(result, 6, &format!("pool thread {first} refused"));
        }
        refuse_threads_from(usize::MAX);
        let frame = renderer
            .render(&prepared, &camera, &settings, &options)
            .unwrap();
        let reference = render_sequential(&prepared, &camera, &settings).unwrap();
        assert_eq!(
            frame.stats.counters.samples,
            reference.stats.counters.samples
        );
    }
}
