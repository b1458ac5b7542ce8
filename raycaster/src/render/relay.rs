//! Distributed rendering: ranks (processes, on one machine or many) each render
//! one convex part of the volume and hand unfinished pixels on, front to back.
//!
//! Every rank opens the same volume and computes the same [`Partition`] (a
//! k-d split of the brick grid balanced by the bricks the transfer function
//! leaves visible) and the parts' visibility order for the camera. The image is
//! cut into bands of tile rows. For each band, the ranks whose part projects
//! into it form a chain in visibility order: the first starts the band's
//! pixels, renders its part's bricks into them with the object-parallel
//! renderer and sends the pixels' compositing *states* to the next; the last
//! resolves them into RGBA. Rank 0 gathers the resolved bands.
//!
//! Handing on states instead of finished partial images is what keeps the
//! result exact for every compositing mode, two-level scenes included (none
//! needs an associative "over" of partial results), and keeps early ray
//! termination global: a ray that became opaque in a front part is skipped by
//! the parts behind it. Bands make it a pipeline: while a rank renders band
//! `b`, the rank behind it renders band `b − 1`.

use std::ops::Range;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use parking_lot::Mutex;

use super::camera::{Camera, PixelRect};
use super::counters::{Counters, FrameStats};
use super::direct_send::DirectSend;
use super::error::RenderError;
use super::frame::Frame;
use super::level::DepthBand;
use super::parallel::{
    FrameJob, LevelPass, ParallelOptions, TileSink, check_levels, level_plans, render_tiles,
};
use super::partition::{BrickBox, Partition};
use super::prepared::{FramePlan, RenderVolume};
use super::renderer::Renderer;
use super::schedule::FrameSchedule;
use super::settings::RenderSettings;
use super::state_buffer::{Reader, StateBuffer, StateBytes, put_f32, put_u32};

/// Point-to-point messages between the ranks of a distributed frame (MPI in
/// the `raycaster` binary, channels in [`channel_links`]).
///
/// Messages between two ranks with the same tag arrive in the order sent.
pub trait Link {
    /// This process's rank, `0..ranks()`.
    fn rank(&self) -> usize;
    /// How many ranks render the frame.
    fn ranks(&self) -> usize;
    /// Sends `message` to rank `to` with `tag`.
    fn send(&self, to: usize, tag: u32, message: Vec<u8>) -> Result<(), LinkError>;
    /// The next message from rank `from` with `tag` (waits for it).
    fn receive(&self, from: usize, tag: u32) -> Result<Vec<u8>, LinkError>;
    /// Waits until every message sent has left (sends may return before);
    /// called once at the end of a frame.
    fn flush(&self) -> Result<(), LinkError> {
        Ok(())
    }
}

/// A message could not be sent or received.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct LinkError(pub String);

/// Parameters of a distributed frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DistributedOptions {
    /// Threads and tiles of each rank's renderer.
    pub parallel: ParallelOptions,
    /// Bands of tile rows the image is cut into for the pipeline (`None`:
    /// [`default_bands`]).
    pub bands: Option<u32>,
    /// How the parts' pixels become one image.
    pub compositing: Compositing,
}

/// How the parts of a distributed frame become one image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Compositing {
    /// Pixel states handed on front to back, band by band: exact for every
    /// mode, early ray termination global.
    #[default]
    Relay,
    /// Partial images of premultiplied RGBA composited with "over" by strip
    /// owners (sort-last direct send): plain DVR without pre-integration only, early ray termination
    /// per part; for comparison.
    DirectSend,
}

/// Bands of a frame on `ranks` ranks: one rank needs no pipeline; more ranks
/// get four bands each, so a rank waits for at most a quarter of its share
/// before its first band arrives.
pub fn default_bands(ranks: usize) -> u32 {
    if ranks <= 1 { 1 } else { 4 * ranks as u32 }
}

/// What one rank did in a distributed frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RankStats {
    /// The rank.
    pub rank: u32,
    /// Its part of the brick grid.
    pub part: [u32; 6],
    /// Bricks of its part the frame renders (not empty under the transfer
    /// function): what the partition balances.
    pub bricks: u64,
    /// Work counters of its render threads.
    pub counters: Counters,
    /// Bands it rendered.
    pub bands: u32,
    /// Time rendering bands.
    pub render: Duration,
    /// Time sending and waiting for pixel states (the compositing cost).
    pub relay: Duration,
}

/// A distributed frame as one rank sees it.
#[derive(Clone, Debug)]
pub struct DistributedFrame {
    /// The image: on rank 0 only.
    pub frame: Option<Frame>,
    /// Every rank's statistics on rank 0 (by rank); this rank's elsewhere.
    pub ranks: Vec<RankStats>,
    /// Rank 0: time receiving and assembling the resolved bands.
    pub gather: Duration,
}

/// Tag of a band's states (the band number).
const MAX_BANDS: u32 = 1 << 20;
/// Tag of a rank's resolved bands, sent to rank 0.
const FINAL_TAG: u32 = MAX_BANDS;
/// Tag of a rank's statistics, sent to rank 0.
const STATS_TAG: u32 = MAX_BANDS + 1;

/// Renders one frame as rank `link.rank()` of `link.ranks()`. Every rank calls
/// it with the same volume, camera, settings and options; rank 0 gets the
/// image. The image equals [`super::render_parallel`]'s: the same samples in
/// the same order per pixel, with each part's bricks rendered where they are.
pub fn render_distributed(
    link: &dyn Link,
    renderer: &mut Renderer,
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    options: &DistributedOptions,
) -> Result<DistributedFrame, RenderError> {
    render_distributed_levels(link, renderer, &[(volume, None)], camera, settings, options)
}

/// Like [`render_distributed`] for a frame of several pyramid levels, nearest
/// band first ([`LevelChoice::bands`](super::LevelChoice::bands)); the image
/// equals [`Renderer::render_levels`]'s. Each level is partitioned among the
/// ranks like a frame of its own; for each band of rows the chain runs through
/// the nearest level's ranks in visibility order, then the next level's, and so
/// on, the first rank of a level continuing the states where the last rank of
/// the nearer level left them. Direct-send compositing takes one level.
pub fn render_distributed_levels(
    link: &dyn Link,
    renderer: &mut Renderer,
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
    options: &DistributedOptions,
) -> Result<DistributedFrame, RenderError> {
    let start = Instant::now();
    check_levels(passes, settings)?;
    let (rank, ranks) = (link.rank(), link.ranks().max(1));
    let plans = level_plans(passes, camera, settings)?;
    let partitions: Vec<Partition> = passes
        .iter()
        .zip(&plans)
        .map(|(&(volume, _), plan)| Partition::balanced(volume, plan, ranks))
        .collect();
    let part = partitions[0].parts()[rank];
    let mut own = RankStats {
        rank: rank as u32,
        part: [part.lo, part.hi].concat().try_into().expect("six"),
        bricks: partitions.iter().map(|p| p.weights()[rank]).sum(),
        ..RankStats::default()
    };
    let (width, height) = (camera.width(), camera.height());
    let summary = FrameSummary::of(passes, &plans, camera, options, ranks, start);
    if options.compositing == Compositing::DirectSend {
        if !settings.direct_send_composites() {
            return Err(RenderError::DirectSendMode);
        }
        let [(volume, None)] = passes else {
            return Err(RenderError::Levels(
                "direct-send compositing samples one level per frame",
            ));
        };
        let (rect, pixels) = DirectSend {
            link,
            workers: renderer.workers_for(&options.parallel)?,
            volume,
            camera,
            plan: &plans[0],
            partition: &partitions[0],
            order: &partitions[0].visibility_order(camera, volume.geometry()),
            options: &options.parallel,
        }
        .run(&mut own)?;
        return gather(link, own, vec![(rect, pixels)], settings, &summary);
    }
    let tile = options.parallel.tile_size.max(1);
    // Per level: this rank's schedule, and every rank's screen rectangle in
    // visibility order.
    let levels: Vec<LevelParts> = passes
        .iter()
        .zip(&plans)
        .zip(&partitions)
        .map(|((&(volume, _), plan), partition)| {
            let geometry = volume.geometry();
            let part = partition.parts()[rank];
            LevelParts {
                order: partition.visibility_order(camera, geometry),
                rects: (0..ranks)
                    .map(|p| partition.screen_rect(p, camera, geometry))
                    .collect(),
                schedule: FrameSchedule::new(volume, plan, camera, tile, Some(&part)),
            }
        })
        .collect();
    let tiles_per_row = width.div_ceil(tile) as usize;
    let bands = band_rows(
        height.div_ceil(tile),
        options.bands.unwrap_or_else(|| default_bands(ranks)),
    );
    let record = plans[0].compositor.run(StateBytes);
    let workers = renderer.workers_for(&options.parallel)?;
    // Resolved bands: their rows and pixels, for rank 0.
    let mut finals: Vec<(PixelRect, BandPixels)> = Vec::new();
    let mut read_ahead = vec![true; passes.len()];
    for (b, rows) in bands.iter().enumerate() {
        let rect = PixelRect::rows(width, rows.start * tile, (rows.end * tile).min(height));
        // The band's chain: (level, rank), nearest level first.
        let chain: Vec<(usize, usize)> = levels
            .iter()
            .enumerate()
            .flat_map(|(level, parts)| {
                chain(&parts.order, &parts.rects, &rect)
                    .into_iter()
                    .map(move |r| (level, r))
            })
            .collect();
        for (position, &(level, _)) in chain.iter().enumerate().filter(|(_, (_, r))| *r == rank) {
            let incoming = match position {
                0 => None,
                _ => {
                    let waited = Instant::now();
                    let message = link
                        .receive(chain[position - 1].1, b as u32)
                        .map_err(|e| link_error(rank, &e))?;
                    own.relay += waited.elapsed();
                    Some(
                        StateBuffer::from_bytes(message, rect, record)
                            .map_err(|e| RenderError::Distributed(format!("rank {rank}: {e}")))?,
                    )
                }
            };
            let last = position + 1 == chain.len();
            let outgoing = (!last).then(|| Mutex::new(StateBuffer::new(rect, record)));
            let sink = BandSink::new(rect);
            let rendering = Instant::now();
            let counters = render_tiles(
                workers,
                &FrameJob {
                    volume: passes[level].0,
                    camera,
                    plan: &plans[level],
                    schedule: &levels[level].schedule,
                    sink: &sink,
                    cancelled: &|| false,
                    tiles: rows.start as usize * tiles_per_row..rows.end as usize * tiles_per_row,
                    incoming: incoming.as_ref(),
                    outgoing: outgoing.as_ref(),
                    read_ahead: std::mem::take(&mut read_ahead[level]),
                    continues: position > 0 && chain[position - 1].0 != level,
                    pass: LevelPass::ONLY,
                },
                &options.parallel,
            )?
            .expect("a frame that cannot be cancelled completes");
            own.render += rendering.elapsed();
            own.counters += counters;
            own.bands += 1;
            match outgoing {
                Some(states) => {
                    let sending = Instant::now();
                    link.send(
                        chain[position + 1].1,
                        b as u32,
                        states.into_inner().to_bytes(),
                    )
                    .map_err(|e| link_error(rank, &e))?;
                    own.relay += sending.elapsed();
                }
                None => finals.push((rect, sink.pixels.into_inner())),
            }
        }
    }
    gather(link, own, finals, settings, &summary)
}

/// One level of a distributed frame as this rank renders it.
struct LevelParts {
    /// The ranks' parts front to back.
    order: Vec<usize>,
    /// Each rank's part's screen rectangle.
    rects: Vec<Option<PixelRect>>,
    /// This rank's bricks of the level.
    schedule: FrameSchedule,
}

/// What the frame's statistics say besides the counters.
struct FrameSummary {
    width: u32,
    height: u32,
    bricks: u64,
    bricks_transparent: u64,
    threads: u32,
    level: u32,
    coarsest_level: u32,
    start: Instant,
}

impl FrameSummary {
    fn of(
        passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
        plans: &[FramePlan],
        camera: &Camera,
        options: &DistributedOptions,
        ranks: usize,
        start: Instant,
    ) -> Self {
        let level = |i: usize| passes[i].0.volume().level_index();
        FrameSummary {
            width: camera.width(),
            height: camera.height(),
            bricks: passes
                .iter()
                .map(|(v, _)| v.geometry().grid().block_count())
                .sum(),
            bricks_transparent: passes
                .iter()
                .zip(plans)
                .map(|((v, _), plan)| plan.transparent_bricks(v))
                .sum(),
            threads: (options.parallel.render_threads.max(1) * ranks) as u32,
            level: level(0),
            coarsest_level: level(passes.len() - 1),
            start,
        }
    }
}

/// Sends this rank's resolved rows and statistics to rank 0, where the image
/// is assembled.
fn gather(
    link: &dyn Link,
    own: RankStats,
    finals: Vec<(PixelRect, BandPixels)>,
    settings: &RenderSettings,
    summary: &FrameSummary,
) -> Result<DistributedFrame, RenderError> {
    let (rank, ranks) = (link.rank(), link.ranks().max(1));
    let (width, height) = (summary.width, summary.height);
    if rank != 0 {
        // One message per band (a whole image could pass MPI's 2 GiB count
        // limit), then an empty one.
        let mut sent = Ok(());
        for (rect, pixels) in finals.iter().filter(|(r, _)| r.y0 < r.y1) {
            let mut message = Vec::new();
            put_u32(&mut message, rect.y0);
            put_u32(&mut message, rect.y1);
            pixels.encode_rows(&mut message, *rect, *rect);
            sent = sent.and_then(|()| link.send(0, FINAL_TAG, message));
        }
        sent.and_then(|()| link.send(0, FINAL_TAG, Vec::new()))
            .and_then(|()| link.send(0, STATS_TAG, own.to_bytes()))
            .and_then(|()| link.flush())
            .map_err(|e| link_error(rank, &e))?;
        return Ok(DistributedFrame {
            frame: None,
            ranks: vec![own],
            gather: Duration::ZERO,
        });
    }
    let gathering = Instant::now();
    let mut frame = Frame::empty(width, height, settings.background);
    for (rect, pixels) in &finals {
        pixels.write_into(&mut frame, *rect);
    }
    let mut all = vec![own];
    for from in 1..ranks {
        let malformed = || RenderError::Distributed(format!("rank {from} sent malformed pixels"));
        loop {
            let message = link
                .receive(from, FINAL_TAG)
                .map_err(|e| link_error(rank, &e))?;
            if message.is_empty() {
                break;
            }
            let mut header = Reader::new(message.get(..8).ok_or_else(malformed)?);
            let (y0, y1) = (header.u32(), header.u32());
            let rect = PixelRect::rows(width, y0, y1);
            if !(y0 < y1 && y1 <= height)
                || message.len() != 8 + rect.area() as usize * BandPixels::BYTES_PER_PIXEL
            {
                return Err(malformed());
            }
            BandPixels::decode(&message[8..], rect).write_into(&mut frame, rect);
        }
        let stats = link
            .receive(from, STATS_TAG)
            .map_err(|e| link_error(rank, &e))?;
        all.push(RankStats::from_bytes(&stats).ok_or_else(|| {
            RenderError::Distributed(format!("rank {from} sent malformed statistics"))
        })?);
    }
    link.flush().map_err(|e| link_error(rank, &e))?;
    let gather = gathering.elapsed();
    let mut counters = Counters::default();
    for r in &all {
        counters += r.counters;
    }
    frame.stats = FrameStats {
        width,
        height,
        counters,
        bricks: summary.bricks,
        bricks_transparent: summary.bricks_transparent,
        threads: summary.threads,
        time: summary.start.elapsed(),
        level: summary.level,
        coarsest_level: summary.coarsest_level,
    };
    Ok(DistributedFrame {
        frame: Some(frame),
        ranks: all,
        gather,
    })
}

pub(crate) fn link_error(rank: usize, e: &LinkError) -> RenderError {
    RenderError::Distributed(format!("rank {rank}: {e}"))
}

/// `rows` tile rows cut into `bands` bands of (almost) equal height.
fn band_rows(rows: u32, bands: u32) -> Vec<Range<u32>> {
    let n = bands.clamp(1, rows.max(1)).min(MAX_BANDS);
    (0..n).map(|i| i * rows / n..(i + 1) * rows / n).collect()
}

/// The ranks that take part in band `rect`, front to back: those whose part
/// projects into it; rank 0 alone (resolving untouched pixels) when none does.
fn chain(order: &[usize], rects: &[Option<PixelRect>], rect: &PixelRect) -> Vec<usize> {
    let chain: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&r| rects[r].is_some_and(|p| p.intersect(rect).is_some()))
        .collect();
    if chain.is_empty() { vec![0] } else { chain }
}

/// A band's resolved pixels.
#[derive(Debug, Default)]
pub(crate) struct BandPixels {
    pub rgba: Vec<[f32; 4]>,
    pub depth: Vec<f32>,
}

impl BandPixels {
    pub const BYTES_PER_PIXEL: usize = 20;

    /// Appends the pixels of full-width `rows` (inside `band`, which these
    /// pixels cover).
    pub fn encode_rows(&self, out: &mut Vec<u8>, band: PixelRect, rows: PixelRect) {
        let w = (band.x1 - band.x0) as usize;
        let from = (rows.y0 - band.y0) as usize * w;
        let to = (rows.y1 - band.y0) as usize * w;
        out.reserve((to - from) * Self::BYTES_PER_PIXEL);
        for (px, &d) in self.rgba[from..to].iter().zip(&self.depth[from..to]) {
            for v in px.iter().copied().chain([d]) {
                put_f32(out, v);
            }
        }
    }

    /// The pixels of full-width `rows` (inside `band`, which these pixels
    /// cover).
    pub fn rows(&self, band: PixelRect, rows: PixelRect) -> BandPixels {
        let w = (band.x1 - band.x0) as usize;
        let range = (rows.y0 - band.y0) as usize * w..(rows.y1 - band.y0) as usize * w;
        BandPixels {
            rgba: self.rgba[range.clone()].to_vec(),
            depth: self.depth[range].to_vec(),
        }
    }

    /// Pixels of `rect` from bytes of [`Self::encode_rows`].
    pub fn decode(bytes: &[u8], rect: PixelRect) -> BandPixels {
        let mut r = Reader::new(bytes);
        let n = rect.area() as usize;
        let mut pixels = BandPixels {
            rgba: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
        };
        for _ in 0..n {
            pixels.rgba.push([r.f32(), r.f32(), r.f32(), r.f32()]);
            pixels.depth.push(r.f32());
        }
        pixels
    }

    /// Writes the pixels (of `rect`) into `frame`.
    pub fn write_into(&self, frame: &mut Frame, rect: PixelRect) {
        let w = (rect.x1 - rect.x0) as usize;
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            let start = frame.index(rect.x0, y);
            frame.rgba[start..start + w].copy_from_slice(&self.rgba[row * w..(row + 1) * w]);
            frame.depth[start..start + w].copy_from_slice(&self.depth[row * w..(row + 1) * w]);
        }
    }
}

/// Collects a band's finished tiles.
pub(crate) struct BandSink {
    rect: PixelRect,
    pub pixels: Mutex<BandPixels>,
}

impl BandSink {
    pub fn new(rect: PixelRect) -> Self {
        let n = rect.area() as usize;
        BandSink {
            rect,
            pixels: Mutex::new(BandPixels {
                rgba: vec![[0.0; 4]; n],
                depth: vec![f32::INFINITY; n],
            }),
        }
    }
}

impl TileSink for BandSink {
    fn tile_finished(&self, rect: PixelRect, rgba: &[[f32; 4]], depth: &[f32]) {
        let mut pixels = self.pixels.lock();
        let band_w = (self.rect.x1 - self.rect.x0) as usize;
        let w = (rect.x1 - rect.x0) as usize;
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            let start = (y - self.rect.y0) as usize * band_w + (rect.x0 - self.rect.x0) as usize;
            pixels.rgba[start..start + w].copy_from_slice(&rgba[row * w..(row + 1) * w]);
            pixels.depth[start..start + w].copy_from_slice(&depth[row * w..(row + 1) * w]);
        }
    }
}

impl RankStats {
    const WORDS: usize = 18;

    fn to_bytes(self) -> Vec<u8> {
        let c = self.counters;
        let mut out = Vec::with_capacity(Self::WORDS * 8);
        let words: [u64; Self::WORDS] = [
            u64::from(self.rank),
            u64::from(self.part[0]),
            u64::from(self.part[1]),
            u64::from(self.part[2]),
            u64::from(self.part[3]),
            u64::from(self.part[4]),
            u64::from(self.part[5]),
            self.bricks,
            c.rays,
            c.samples,
            c.rays_terminated,
            c.samples_skipped_empty,
            c.brick_visits,
            c.brick_visits_skipped,
            c.tasks_skipped_occluded,
            c.tasks,
            u64::from(self.bands),
            c.samples_in_lanes,
        ];
        for w in words {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.extend_from_slice(&(self.render.as_nanos() as u64).to_le_bytes());
        out.extend_from_slice(&(self.relay.as_nanos() as u64).to_le_bytes());
        out
    }

    fn from_bytes(bytes: &[u8]) -> Option<RankStats> {
        if bytes.len() != (Self::WORDS + 2) * 8 {
            return None;
        }
        let w: Vec<u64> = bytes
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        let part = [w[1], w[2], w[3], w[4], w[5], w[6]].map(|v| v as u32);
        Some(RankStats {
            rank: w[0] as u32,
            part,
            bricks: w[7],
            counters: Counters {
                rays: w[8],
                samples: w[9],
                rays_terminated: w[10],
                samples_skipped_empty: w[11],
                brick_visits: w[12],
                brick_visits_skipped: w[13],
                tasks_skipped_occluded: w[14],
                tasks: w[15],
                samples_in_lanes: w[17],
            },
            bands: w[16] as u32,
            render: Duration::from_nanos(w[18]),
            relay: Duration::from_nanos(w[19]),
        })
    }

    /// Its part as a brick box.
    pub fn part_box(&self) -> BrickBox {
        BrickBox {
            lo: [self.part[0], self.part[1], self.part[2]],
            hi: [self.part[3], self.part[4], self.part[5]],
        }
    }
}

/// One end of the in-process links of [`channel_links`].
#[derive(Debug)]
pub struct ChannelLink {
    rank: usize,
    peers: Vec<Sender<(usize, u32, Vec<u8>)>>,
    inbox: Receiver<(usize, u32, Vec<u8>)>,
    /// Messages received while waiting for another.
    early: Mutex<Vec<(usize, u32, Vec<u8>)>>,
    timeout: Duration,
}

/// `n` linked ranks in one process (threads), for running and testing the
/// distributed protocol without MPI. A receive waits at most `timeout`.
pub fn channel_links(n: usize, timeout: Duration) -> Vec<ChannelLink> {
    let (senders, receivers): (Vec<_>, Vec<_>) =
        (0..n).map(|_| crossbeam_channel::unbounded()).unzip();
    receivers
        .into_iter()
        .enumerate()
        .map(|(rank, inbox)| ChannelLink {
            rank,
            peers: senders.clone(),
            inbox,
            early: Mutex::new(Vec::new()),
            timeout,
        })
        .collect()
}

impl Link for ChannelLink {
    fn rank(&self) -> usize {
        self.rank
    }

    fn ranks(&self) -> usize {
        self.peers.len()
    }

    fn send(&self, to: usize, tag: u32, message: Vec<u8>) -> Result<(), LinkError> {
        self.peers
            .get(to)
            .ok_or_else(|| LinkError(format!("no rank {to}")))?
            .send((self.rank, tag, message))
            .map_err(|_| LinkError(format!("rank {to} has stopped")))
    }

    fn receive(&self, from: usize, tag: u32) -> Result<Vec<u8>, LinkError> {
        let mut early = self.early.lock();
        if let Some(i) = early.iter().position(|m| m.0 == from && m.1 == tag) {
            return Ok(early.remove(i).2);
        }
        loop {
            match self.inbox.recv_timeout(self.timeout) {
                Ok((f, t, message)) if f == from && t == tag => return Ok(message),
                Ok(other) => early.push(other),
                Err(RecvTimeoutError::Timeout) => {
                    return Err(LinkError(format!(
                        "no message from rank {from} (tag {tag}) within {:?}",
                        self.timeout
                    )));
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(LinkError(format!("rank {from} has stopped")));
                }
            }
        }
    }
}
