//! Progress reporting and cancellation for long library jobs (generation, conversion).

use std::sync::atomic::{AtomicBool, Ordering};

/// Hooks a long job calls: a progress callback (units done since the last call) and a
/// cancellation flag checked between batches.
#[derive(Clone, Copy, Default)]
pub struct Job<'a> {
    on_progress: Option<&'a (dyn Fn(u64) + Sync)>,
    cancel: Option<&'a AtomicBool>,
}

impl<'a> Job<'a> {
    /// A job that reports nothing and is never cancelled.
    pub fn silent() -> Self {
        Job::default()
    }

    /// Calls `on_progress(n)` whenever `n` more units are done.
    pub fn with_progress(mut self, on_progress: &'a (dyn Fn(u64) + Sync)) -> Self {
        self.on_progress = Some(on_progress);
        self
    }

    /// Stops the job (with an error, leaving no output) once `flag` is set.
    pub fn with_cancel(mut self, flag: &'a AtomicBool) -> Self {
        self.cancel = Some(flag);
        self
    }

    /// Reports `n` more units done.
    pub fn advance(&self, n: u64) {
        if let Some(f) = self.on_progress {
            f(n);
        }
    }

    /// Whether the job was asked to stop.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.is_some_and(|f| f.load(Ordering::Relaxed))
    }
}
