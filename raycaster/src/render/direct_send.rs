//! Direct-send compositing of partial images: the classic sort-last scheme, kept
//! to compare with the relay ([`super::relay`]).
//!
//! Each rank renders its part alone, from fresh pixels, into a partial image of
//! premultiplied RGBA. The image's rows are cut into one strip per rank; every
//! rank sends each strip's owner its pixels in that strip, and the owner
//! composites the ranks' pixels with "over" in the parts' visibility order, then
//! sends its strip to rank 0. All ranks render at once (no pipeline), but only
//! emission–absorption DVR composites exactly this way, and early ray
//! termination stops at each part's boundary.

use std::time::Instant;

use super::camera::{Camera, PixelRect};
use super::error::RenderError;
use super::parallel::{FrameJob, LevelPass, ParallelOptions, render_tiles};
use super::partition::Partition;
use super::prepared::{FramePlan, RenderVolume};
use super::relay::{BandPixels, BandSink, Link, RankStats, link_error};
use super::renderer::WorkerPool;
use super::schedule::FrameSchedule;
use super::state_buffer::{Reader, put_u32};

/// Tag of a strip's pixels sent to its owner.
const STRIP_TAG: u32 = (1 << 20) + 8;

/// What [`render_direct_send`] needs from the relay's set-up.
pub(crate) struct DirectSend<'a> {
    pub link: &'a dyn Link,
    pub workers: &'a WorkerPool,
    pub volume: &'a RenderVolume<'a>,
    pub camera: &'a Camera,
    pub plan: &'a FramePlan,
    pub partition: &'a Partition,
    pub order: &'a [usize],
    pub options: &'a ParallelOptions,
}

/// The rows `y0..y1` of strip `r` of `ranks` over an image `height` rows high.
fn strip(r: usize, ranks: usize, height: u32) -> (u32, u32) {
    let h = u64::from(height);
    (
        (r as u64 * h / ranks as u64) as u32,
        ((r as u64 + 1) * h / ranks as u64) as u32,
    )
}

impl DirectSend<'_> {
    /// Renders this rank's part, exchanges strips and composites them; returns
    /// this rank's statistics and, on each rank, its composited strip.
    pub fn run(&self, own: &mut RankStats) -> Result<(PixelRect, BandPixels), RenderError> {
        let link = self.link;
        let (rank, ranks) = (link.rank(), link.ranks());
        let geometry = self.volume.geometry();
        let (width, height) = (self.camera.width(), self.camera.height());
        let tile = self.options.tile_size.max(1);
        let tiles_per_row = width.div_ceil(tile) as usize;
        // This rank's partial image: the tile rows its part projects into.
        let rendering = Instant::now();
        let partial = match self.partition.screen_rect(rank, self.camera, geometry) {
            Some(r) => {
                let rows = r.y0 / tile..r.y1.div_ceil(tile);
                let band = PixelRect::rows(width, rows.start * tile, (rows.end * tile).min(height));
                let schedule = FrameSchedule::new(
                    self.volume,
                    self.plan,
                    self.camera,
                    tile,
                    Some(&self.partition.parts()[rank]),
                );
                let sink = BandSink::new(band);
                own.counters += render_tiles(
                    self.workers,
                    &FrameJob {
                        volume: self.volume,
                        camera: self.camera,
                        plan: self.plan,
                        schedule: &schedule,
                        sink: &sink,
                        cancelled: &|| false,
                        tiles: rows.start as usize * tiles_per_row
                            ..rows.end as usize * tiles_per_row,
                        incoming: None,
                        outgoing: None,
                        read_ahead: true,
                        continues: false,
                        pass: LevelPass::ONLY,
                    },
                    self.options,
                )?
                .expect("a frame that cannot be cancelled completes");
                own.bands = 1;
                Some((band, sink.pixels.into_inner()))
            }
            None => None,
        };
        own.render += rendering.elapsed();
        let exchanging = Instant::now();
        // To each strip's owner, the partial image's rows in the strip.
        let rows_in = |owner: usize| -> Option<(PixelRect, &BandPixels)> {
            let (band, pixels) = partial.as_ref()?;
            let (y0, y1) = strip(owner, ranks, height);
            let (y0, y1) = (y0.max(band.y0), y1.min(band.y1));
            (y0 < y1).then_some((PixelRect::rows(width, y0, y1), pixels))
        };
        for owner in (0..ranks).filter(|&o| o != rank) {
            let mut message = Vec::new();
            if let Some((rect, pixels)) = rows_in(owner) {
                let band = partial.as_ref().expect("rows imply a partial image").0;
                put_u32(&mut message, rect.y0);
                put_u32(&mut message, rect.y1);
                pixels.encode_rows(&mut message, band, rect);
            }
            link.send(owner, STRIP_TAG, message)
                .map_err(|e| link_error(rank, &e))?;
        }
        // The strip this rank owns: every rank's rows, over in visibility order.
        let (y0, y1) = strip(rank, ranks, height);
        let mine = PixelRect::rows(width, y0, y1);
        let mut layers: Vec<Option<(PixelRect, BandPixels)>> = (0..ranks).map(|_| None).collect();
        for (from, layer) in layers.iter_mut().enumerate() {
            if from == rank {
                *layer = rows_in(rank).map(|(rect, pixels)| {
                    let band = partial.as_ref().expect("rows imply a partial image").0;
                    (rect, pixels.rows(band, rect))
                });
                continue;
            }
            let message = link
                .receive(from, STRIP_TAG)
                .map_err(|e| link_error(rank, &e))?;
            if message.is_empty() {
                continue;
            }
            let malformed =
                || RenderError::Distributed(format!("rank {from} sent a malformed strip"));
            let header = message.get(..8).ok_or_else(malformed)?;
            let mut r = Reader::new(header);
            let (a, b) = (r.u32(), r.u32());
            if !(y0 <= a && a < b && b <= y1) {
                return Err(malformed());
            }
            let rect = PixelRect::rows(width, a, b);
            if message.len() != 8 + rect.area() as usize * BandPixels::BYTES_PER_PIXEL {
                return Err(malformed());
            }
            *layer = Some((rect, BandPixels::decode(&message[8..], rect)));
        }
        let n = mine.area() as usize;
        let mut strip_pixels = BandPixels {
            rgba: vec![[0.0; 4]; n],
            depth: vec![f32::INFINITY; n],
        };
        for &p in self.order {
            let Some((rect, layer)) = &layers[p] else {
                continue;
            };
            let offset = ((rect.y0 - mine.y0) * width) as usize;
            for (i, (px, &d)) in layer.rgba.iter().zip(&layer.depth).enumerate() {
                let out = &mut strip_pixels.rgba[offset + i];
                let rest = 1.0 - out[3];
                for c in 0..4 {
                    out[c] += rest * px[c];
                }
                let depth = &mut strip_pixels.depth[offset + i];
                if depth.is_infinite() {
                    *depth = d;
                }
            }
        }
        own.relay += exchanging.elapsed();
        Ok((mine, strip_pixels))
    }
}
