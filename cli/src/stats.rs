//! Printing a frame's statistics: a table for people, JSON for scripts.

use raycaster::render::{FrameStats, LevelBand, RenderSettings};
use raycaster::volume::Volume;

/// The counters as an aligned table.
pub fn table(s: &FrameStats) -> String {
    let c = &s.counters;
    let secs = s.time.as_secs_f64();
    let pct = |part: u64, whole: u64| 100.0 * part as f64 / whole.max(1) as f64;
    let considered = c.samples + c.samples_skipped_empty;
    format!(
        "image            {}×{} ({} pixels)\n\
         rays cast        {}\n\
         samples taken    {} ({:.1} per ray; {:.1} % in SIMD lanes)\n\
         skipped (empty)  {} samples ({:.1} %){}\n\
         terminated early {} rays ({:.1} %)\n\
         tasks            {}\n\
         bricks           {} ({} transparent under the transfer function)\n\
         threads          {}\n\
         time             {:.3} s ({:.1} M samples/s, {:.1} M samples/s/thread)\n",
        s.width,
        s.height,
        u64::from(s.width) * u64::from(s.height),
        c.rays,
        c.samples,
        c.samples as f64 / c.rays.max(1) as f64,
        pct(c.samples_in_lanes, c.samples),
        c.samples_skipped_empty,
        pct(c.samples_skipped_empty, considered),
        // (The parallel renderer plans transparent bricks out: it never
        // visits one to skip it.)
        match c.brick_visits_skipped {
            0 => String::new(),
            n => format!(", {n} brick visits skipped whole"),
        },
        c.rays_terminated,
        pct(c.rays_terminated, c.rays),
        // (The sequential renderer marches ray by ray: no tasks to count.)
        if c.tasks + c.tasks_skipped_occluded == 0 {
            "none (rays marched one by one)".to_string()
        } else {
            format!(
                "{} marched (tile × brick), {} more skipped: their pixels had finished",
                c.tasks, c.tasks_skipped_occluded
            )
        },
        s.bricks,
        s.bricks_transparent,
        s.threads,
        secs,
        s.samples_per_second() / 1e6,
        s.samples_per_second() / 1e6 / f64::from(s.threads.max(1)),
    )
}

/// The counters and the main settings as one JSON object.
pub fn json(
    s: &FrameStats,
    volume: &Volume,
    settings: &RenderSettings,
    bands: &[LevelBand],
    bytes_read: u64,
) -> serde_json::Value {
    let c = &s.counters;
    let level = bands.first().map_or(0, |b| b.level);
    serde_json::json!({
        "volume": volume.path().display().to_string(),
        "dims": volume.dims(),
        "level": level,
        "coarsest_level": bands.last().map_or(0, |b| b.level),
        "levels": volume.level_count(),
        "level_dims": volume.level(level).dims(),
        "bytes_read": bytes_read,
        "width": s.width,
        "height": s.height,
        "mode": settings.mode.name(),
        "step": shortest(settings.step),
        // On or off as "ess" is; the threshold beside it (null when off).
        "ert": settings.early_termination.is_some(),
        "ert_threshold": settings.early_termination.map(shortest),
        "ess": settings.empty_space_skipping,
        // Whether the frame used it (DVR, a two-level scene's DVR objects).
        "preintegrated": settings.preintegrates(),
        "jitter": settings.jitter,
        "threads": s.threads,
        "rays": c.rays,
        "samples": c.samples,
        "samples_in_lanes": c.samples_in_lanes,
        "samples_skipped_empty": c.samples_skipped_empty,
        "rays_terminated": c.rays_terminated,
        "brick_visits": c.brick_visits,
        "brick_visits_skipped": c.brick_visits_skipped,
        "tasks": c.tasks,
        "tasks_skipped_occluded": c.tasks_skipped_occluded,
        "bricks": s.bricks,
        "bricks_transparent": s.bricks_transparent,
        "seconds": s.time.as_secs_f64(),
        "samples_per_second": s.samples_per_second(),
    })
}

/// `x` as the f64 its shortest decimal text reads as: 0.99, where the f32's
/// exact value printed as 0.9900000095367432.
fn shortest(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// The level line and the bytes read from storage, for [`table`]'s reader.
pub fn level_table(volume: &Volume, bands: &[LevelBand], bytes_read: u64) -> String {
    let dims = |level: usize| {
        let [x, y, z] = volume.level(level).dims();
        format!("{x}×{y}×{z}")
    };
    let levels = match bands {
        [first, .., last] => format!(
            "{}–{} of 0..={} (by depth, {} nearest, {} farthest)",
            first.level,
            last.level,
            volume.level_count() - 1,
            dims(first.level),
            dims(last.level)
        ),
        _ => {
            let level = bands.first().map_or(0, |b| b.level);
            format!(
                "{level} of 0..={} ({} voxels)",
                volume.level_count() - 1,
                dims(level)
            )
        }
    };
    format!(
        "level            {levels}\n\
         read from disk   {:.1} MB (this process, open and frame)\n",
        bytes_read as f64 / 1e6
    )
}
