//! The asynchronous front end: a renderer thread that owns a prepared volume and
//! renders frames on request, superseding unfinished ones.
//!
//! [`RenderFront::request`] returns at once with the frame's id. A newer request
//! cancels the frame in progress (the compositing threads stop handing out work)
//! and queued requests that were never started are dropped: stale frames are never
//! rendered. Finished tiles land in the shared [`FrameBuffer`] as they complete, so
//! a viewer can show a frame while it fills in. Every request ends with exactly one
//! [`FrameEvent`]: done (with its statistics), superseded, or failed. Dropping the
//! front (or [`RenderFront::shutdown`]) cancels the frame in progress and joins
//! every thread.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender};
use parking_lot::Mutex;

use super::camera::{Camera, PixelRect};
use super::counters::FrameStats;
use super::error::RenderError;
use super::level::{DepthBand, LevelChoice};
use super::parallel::{ParallelOptions, TileSink};
use super::pixel::over_background;
use super::prepared::{FramePlan, RenderVolume};
use super::renderer::Renderer;
use super::schedule::FrameSchedule;
use super::settings::RenderSettings;
use crate::volume::Volume;

/// What to render: a copy of the camera and settings (never shared).
#[derive(Clone, Debug)]
pub struct FrameRequest {
    /// The camera (its size is the frame's size).
    pub camera: Camera,
    /// Render settings.
    pub settings: RenderSettings,
    /// Threads and tiles.
    pub options: ParallelOptions,
    /// Which level of the volume's resolution pyramid to sample.
    pub level: LevelChoice,
}

/// How a requested frame ended.
#[derive(Clone, Debug)]
pub enum FrameEvent {
    /// The frame is complete in the frame buffer.
    Done {
        /// The request's id.
        id: u64,
        /// Its statistics.
        stats: FrameStats,
    },
    /// A newer request or shutdown replaced it (it may be partly drawn).
    Superseded {
        /// The request's id.
        id: u64,
    },
    /// The settings were invalid.
    Failed {
        /// The request's id.
        id: u64,
        /// What was wrong.
        error: String,
    },
}

impl FrameEvent {
    /// The id of the request this event ends.
    pub fn id(&self) -> u64 {
        match self {
            FrameEvent::Done { id, .. }
            | FrameEvent::Superseded { id }
            | FrameEvent::Failed { id, .. } => *id,
        }
    }
}

/// The image being shown: 8-bit RGBA, rows from the top.
#[derive(Clone, Debug, Default)]
pub struct FrameBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels (alpha 255).
    pub pixels: Vec<[u8; 4]>,
    /// The request whose tiles were written last.
    pub frame_id: u64,
    /// Tiles of that request written so far.
    pub tiles_written: u64,
}

impl FrameBuffer {
    /// The image as 8-bit RGB (alpha dropped): what is saved, or measured.
    pub fn to_image(&self) -> super::RgbImage {
        let rgb = self
            .pixels
            .iter()
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        super::RgbImage::new(self.width, self.height, rgb)
    }

    /// This image scaled (nearest pixel) to `width × height` as a camera of
    /// the new size sees it: the field of view is vertical, so the picture is
    /// scaled by the ratio of the heights about the centre, whatever the widths
    /// (a window made narrower crops the sides, a wider one adds black ones);
    /// black where there was no image.
    pub fn rescaled(&self, width: u32, height: u32) -> FrameBuffer {
        let n = width as usize * height as usize;
        let pixels = if self.width == 0 || self.height == 0 || self.pixels.is_empty() {
            vec![[0, 0, 0, 255]; n]
        } else {
            // Source pixels per new pixel, both ways.
            let scale = f64::from(self.height) / f64::from(height);
            let (sw, sh) = (f64::from(self.width), f64::from(self.height));
            let mut out = Vec::with_capacity(n);
            for y in 0..height {
                let sy = ((f64::from(y) + 0.5) * scale).clamp(0.0, sh - 1.0) as usize;
                for x in 0..width {
                    // Centre to centre; within half a pixel of the old edge
                    // (sizes rounded apart) the edge pixel.
                    let sx = sw / 2.0 + (f64::from(x) + 0.5 - f64::from(width) / 2.0) * scale;
                    out.push(if sx > -0.5 && sx < sw + 0.5 {
                        self.pixels[sy * self.width as usize + sx.clamp(0.0, sw - 1.0) as usize]
                    } else {
                        [0, 0, 0, 255]
                    });
                }
            }
            out
        };
        FrameBuffer {
            width,
            height,
            pixels,
            ..FrameBuffer::default()
        }
    }
}

/// Called (from renderer threads) after a tile lands or a frame ends, e.g. to wake
/// a UI event loop.
pub type Notify = Arc<dyn Fn() + Send + Sync>;

enum Command {
    Render { id: u64, request: Box<FrameRequest> },
    Shutdown,
}

/// A renderer thread with its volume, driven by requests.
pub struct RenderFront {
    commands: Sender<Command>,
    latest: Arc<AtomicU64>,
    events: Receiver<FrameEvent>,
    framebuffer: Arc<Mutex<FrameBuffer>>,
    thread: Option<JoinHandle<()>>,
    /// The smallest of the levels' [`RenderVolume::preintegrated_skipping_below`].
    preintegrated_skipping_below: f32,
}

impl RenderFront {
    /// Starts the renderer thread for `volume`, prepared with bricks of
    /// `brick_side` (see [`RenderVolume::new`]); waits until it is prepared.
    pub fn new(
        volume: Arc<Volume>,
        brick_side: Option<u32>,
        notify: Option<Notify>,
    ) -> Result<Self, RenderError> {
        RenderFront::with_labels(volume, None, brick_side, notify)
    }

    /// Like [`RenderFront::new`], with a label volume attached for two-level scenes
    /// whose objects come from labels (see [`RenderVolume::with_labels`]).
    pub fn with_labels(
        volume: Arc<Volume>,
        labels: Option<Arc<Volume>>,
        brick_side: Option<u32>,
        notify: Option<Notify>,
    ) -> Result<Self, RenderError> {
        let (command_tx, command_rx) = crossbeam_channel::unbounded();
        let (event_tx, event_rx) = crossbeam_channel::unbounded();
        let (ready_tx, ready_rx) = crossbeam_channel::bounded(1);
        let latest = Arc::new(AtomicU64::new(0));
        let framebuffer = Arc::new(Mutex::new(FrameBuffer::default()));
        let worker = Worker {
            latest: latest.clone(),
            events: event_tx,
            framebuffer: framebuffer.clone(),
            notify,
        };
        let thread = std::thread::Builder::new()
            .name("renderer".into())
            .spawn(move || {
                // Every level of the pyramid (those the labels have too), prepared
                // once: preparing reads nothing, and each level keeps the cells its
                // frames computed.
                let count = match labels.as_deref() {
                    Some(l) => volume.level_count().min(l.level_count()),
                    None => volume.level_count(),
                };
                let prepared: Result<Vec<RenderVolume<'_>>, RenderError> = (0..count)
                    .map(|k| {
                        let level = RenderVolume::new(volume.level(k), brick_side)?;
                        match labels.as_deref() {
                            Some(labels) => level.with_labels(labels.level(k)),
                            None => Ok(level),
                        }
                    })
                    .collect();
                match prepared {
                    Ok(levels) => {
                        let limit = levels
                            .iter()
                            .map(RenderVolume::preintegrated_skipping_below)
                            .fold(f32::INFINITY, f32::min);
                        let _ = ready_tx.send(Ok(limit));
                        worker.serve(&volume, &levels, &command_rx);
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                    }
                }
            })
            .map_err(|e| RenderError::Threads {
                count: 1,
                reason: e.to_string(),
            })?;
        match ready_rx.recv() {
            Ok(Ok(limit)) => Ok(RenderFront {
                commands: command_tx,
                latest,
                events: event_rx,
                framebuffer,
                thread: Some(thread),
                preintegrated_skipping_below: limit,
            }),
            Ok(Err(e)) => {
                let _ = thread.join();
                Err(e)
            }
            Err(_) => panic!("the renderer thread died while preparing the volume"),
        }
    }

    /// The step (in voxels of any level) below which pre-integrated frames keep
    /// empty-space skipping: the smallest
    /// [`RenderVolume::preintegrated_skipping_below`] of the prepared levels.
    /// Coarser pre-integrated frames render without it, which can make them
    /// several times slower than plain ones.
    pub fn preintegrated_skipping_below(&self) -> f32 {
        self.preintegrated_skipping_below
    }

    /// Requests a frame; returns its id at once. Any frame in progress is cancelled.
    pub fn request(&self, request: FrameRequest) -> u64 {
        let id = self.latest.fetch_add(1, Ordering::SeqCst) + 1;
        self.commands
            .send(Command::Render {
                id,
                request: Box::new(request),
            })
            .expect("the renderer thread runs until shutdown");
        id
    }

    /// How requests ended, in order.
    pub fn events(&self) -> &Receiver<FrameEvent> {
        &self.events
    }

    /// The image being rendered or last rendered.
    pub fn framebuffer(&self) -> &Arc<Mutex<FrameBuffer>> {
        &self.framebuffer
    }

    /// Cancels the frame in progress and joins the renderer (and its threads).
    pub fn shutdown(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(thread) = self.thread.take() {
            // A fresh id that no request has: the frame in progress is superseded.
            self.latest.fetch_add(1, Ordering::SeqCst);
            let _ = self.commands.send(Command::Shutdown);
            thread.join().expect("the renderer thread does not panic");
        }
    }
}

impl Drop for RenderFront {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The renderer thread's side.
struct Worker {
    latest: Arc<AtomicU64>,
    events: Sender<FrameEvent>,
    framebuffer: Arc<Mutex<FrameBuffer>>,
    notify: Option<Notify>,
}

impl Worker {
    fn emit(&self, event: FrameEvent) {
        // The front may be gone already (dropped during shutdown): nobody listens.
        let _ = self.events.send(event);
        if let Some(n) = &self.notify {
            n();
        }
    }

    fn serve(&self, volume: &Volume, levels: &[RenderVolume<'_>], commands: &Receiver<Command>) {
        // The render and compositing threads wait here between frames.
        let mut renderer = Renderer::new();
        while let Ok(mut command) = commands.recv() {
            // Only the newest command counts; older renders are superseded unstarted.
            while let Ok(newer) = commands.try_recv() {
                if let Command::Render { id, .. } = command {
                    self.emit(FrameEvent::Superseded { id });
                }
                command = newer;
            }
            let (id, request) = match command {
                Command::Shutdown => return,
                Command::Render { id, request } => (id, request),
            };
            if self.latest.load(Ordering::SeqCst) != id {
                self.emit(FrameEvent::Superseded { id });
                continue;
            }
            // A file truncated under its mapping: no frame reads it (a read of a
            // missing byte would end the process). Level 0's labels are the
            // whole label volume: its check covers its levels.
            let labels = levels.first().and_then(RenderVolume::labels);
            if let Err(e) = std::iter::once(volume)
                .chain(labels)
                .try_for_each(Volume::check_whole)
            {
                self.emit(FrameEvent::Failed {
                    id,
                    error: crate::errors::error_text(&e),
                });
                continue;
            }
            let bands =
                request
                    .level
                    .frame_bands(volume, &request.camera, &request.settings, levels.len());
            let passes: Vec<(&RenderVolume<'_>, Option<DepthBand>)> = bands
                .iter()
                .map(|band| (&levels[band.level], band.depth))
                .collect();
            let level = bands[0].level;
            let event = self.render(&mut renderer, &passes, id, &request);
            let done = matches!(event, FrameEvent::Done { .. });
            self.emit(event);
            // Idle after a coarse frame: have the OS read the next finer level's
            // bricks of this view, so refining or zooming in finds them cached.
            if done && level > 0 && commands.is_empty() {
                prefetch_view(&levels[level - 1], &request, || !commands.is_empty());
            }
        }
    }

    fn render(
        &self,
        renderer: &mut Renderer,
        passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
        id: u64,
        request: &FrameRequest,
    ) -> FrameEvent {
        let (w, h) = (request.camera.width(), request.camera.height());
        {
            let mut fb = self.framebuffer.lock();
            if (fb.width, fb.height) != (w, h) {
                // The last picture, scaled, stays under the new frame's tiles: a
                // frame of another size (interactive ↔ full quality) never starts
                // from black.
                *fb = fb.rescaled(w, h);
            }
            fb.frame_id = id;
            fb.tiles_written = 0;
        }
        let sink = FrameBufferSink {
            worker: self,
            id,
            background: request.settings.background,
        };
        let cancelled = || self.latest.load(Ordering::Relaxed) != id;
        match renderer.render_levels_into(
            passes,
            &request.camera,
            &request.settings,
            &request.options,
            &sink,
            &cancelled,
        ) {
            Ok(Some(stats)) => FrameEvent::Done { id, stats },
            Ok(None) => FrameEvent::Superseded { id },
            Err(e) => FrameEvent::Failed {
                id,
                error: e.to_string(),
            },
        }
    }
}

/// Asks the OS to read the bricks `request`'s view needs from `volume` (in the
/// frame's visibility order), until `interrupted` holds.
fn prefetch_view(
    volume: &RenderVolume<'_>,
    request: &FrameRequest,
    interrupted: impl Fn() -> bool,
) {
    let Ok(plan) = FramePlan::new(volume, &request.settings) else {
        return;
    };
    let schedule = FrameSchedule::new(
        volume,
        &plan,
        &request.camera,
        request.options.tile_size,
        None,
    );
    super::read_ahead::read_ahead(
        volume,
        schedule.bricks.iter().map(|b| b.coords),
        interrupted,
    );
}

/// Writes finished tiles into the shared frame buffer.
struct FrameBufferSink<'w> {
    worker: &'w Worker,
    id: u64,
    background: [f32; 3],
}

impl TileSink for FrameBufferSink<'_> {
    fn tile_finished(&self, rect: PixelRect, rgba: &[[f32; 4]], _depth: &[f32]) {
        {
            let mut fb = self.worker.framebuffer.lock();
            if fb.frame_id != self.id {
                return;
            }
            let w = (rect.x1 - rect.x0) as usize;
            let width = fb.width as usize;
            for (row, y) in (rect.y0..rect.y1).enumerate() {
                let start = y as usize * width + rect.x0 as usize;
                for (dst, src) in fb.pixels[start..start + w]
                    .iter_mut()
                    .zip(&rgba[row * w..(row + 1) * w])
                {
                    let [r, g, b] = over_background(*src, self.background);
                    *dst = [r, g, b, 255];
                }
            }
            fb.tiles_written += 1;
        }
        if let Some(n) = &self.worker.notify {
            n();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rescaled_frame_keeps_the_picture_not_black() {
        // 2×2: red, green / blue, white.
        let fb = FrameBuffer {
            width: 2,
            height: 2,
            pixels: vec![
                [255, 0, 0, 255],
                [0, 255, 0, 255],
                [0, 0, 255, 255],
                [255, 255, 255, 255],
            ],
            ..FrameBuffer::default()
        };
        let big = fb.rescaled(4, 6);
        assert_eq!((big.width, big.height, big.pixels.len()), (4, 6, 24));
        assert_eq!(big.pixels[0], [255, 0, 0, 255]);
        assert_eq!(big.pixels[3], [0, 255, 0, 255]);
        assert_eq!(big.pixels[5 * 4], [0, 0, 255, 255]);
        assert_eq!(big.pixels[23], [255, 255, 255, 255]);
        // One pixel: the picture's centre (the lower right of the four).
        let small = fb.rescaled(1, 1);
        assert_eq!(small.pixels, vec![[255, 255, 255, 255]]);
        assert_eq!(
            FrameBuffer::default().rescaled(3, 2).pixels,
            vec![[0, 0, 0, 255]; 6]
        );
    }

    #[test]
    fn a_window_of_another_shape_keeps_the_picture_where_the_camera_sees_it() {
        // 4×2, columns 10, 20, 30, 40.
        let fb = FrameBuffer {
            width: 4,
            height: 2,
            pixels: (0..8).map(|i| [10 * (i % 4 + 1), 0, 0, 255]).collect(),
            ..FrameBuffer::default()
        };
        let red = |b: &FrameBuffer| -> Vec<u8> { b.pixels.iter().map(|p| p[0]).collect() };
        // Narrower, same height: the middle two columns, unstretched.
        assert_eq!(red(&fb.rescaled(2, 2)), [20, 30, 20, 30]);
        // Wider, same height: the picture in the middle, black at the sides.
        assert_eq!(
            red(&fb.rescaled(6, 2)),
            [0, 10, 20, 30, 40, 0, 0, 10, 20, 30, 40, 0]
        );
        // Twice the size both ways: each pixel doubled.
        assert_eq!(
            red(&fb.rescaled(8, 4))[..8],
            [10, 10, 20, 20, 30, 30, 40, 40]
        );
    }
}
