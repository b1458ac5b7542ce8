//! How far the sequential renderer is through a frame, readable from another
//! thread while it renders (a command's progress line).

use std::sync::atomic::{AtomicU64, Ordering};

/// The pixels of a frame the sequential renderer has finished, of those it
/// will march (over all the frame's levels): set before the first pixel,
/// counted row by row.
#[derive(Debug, Default)]
pub struct PixelProgress {
    done: AtomicU64,
    total: AtomicU64,
}

impl PixelProgress {
    /// Nothing done, nothing known yet.
    pub fn new() -> Self {
        PixelProgress::default()
    }

    /// The share of the frame done, in `[0, 1]` (0 before the renderer has
    /// said how many pixels it will march, 1 for a frame of none).
    pub fn fraction(&self) -> f64 {
        let total = self.total.load(Ordering::Relaxed);
        let done = self.done.load(Ordering::Relaxed);
        if total == 0 {
            return if done == 0 { 0.0 } else { 1.0 };
        }
        done.min(total) as f64 / total as f64
    }

    /// Pixels finished so far.
    pub fn done(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }

    /// Pixels the frame marches (0 until the renderer has started).
    pub fn total(&self) -> u64 {
        self.total.load(Ordering::Relaxed)
    }

    pub(crate) fn start(&self, total: u64) {
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
    }

    pub(crate) fn add(&self, pixels: u64) {
        self.done.fetch_add(pixels, Ordering::Relaxed);
    }
}
