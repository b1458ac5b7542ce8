//! Whether the system lets this process start the threads it needs: checked
//! before any work, so a thread the system refuses (an address-space or
//! process limit) is said once, with what to do, before anything is read or
//! written. (The renderer also returns an error where a frame's thread is
//! refused, `RenderError::Threads`, but only once the frame has started.)

use anyhow::{Result, bail};

/// Starts rayon's global pool where it has not started yet, saying a system
/// refusing its threads (an address-space or process limit) as an error:
/// started at its first use, it panicked. Called after the memory checks
/// (its threads' malloc arenas take address space under `ulimit -v`).
pub fn start_worker_pool() -> Result<()> {
    static STARTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    if STARTED.swap(true, std::sync::atomic::Ordering::Relaxed) {
        return Ok(());
    }
    match rayon::ThreadPoolBuilder::new().build_global() {
        Ok(()) => Ok(()),
        // (Started by an earlier parallel step: running.)
        Err(e) if e.to_string().contains("already") => Ok(()),
        Err(e) => {
            bail!("cannot start the worker threads: {e}; raise the limit (ulimit -v, ulimit -u)")
        }
    }
}

/// Starts `count` threads that wait together, then lets them go: an error
/// naming the count where the system refuses one (an address-space or
/// process limit), said before a frame whose threads would fail to start.
pub fn check_threads(count: usize) -> Result<()> {
    let gate = std::sync::RwLock::new(());
    let closed = gate.write().unwrap_or_else(|e| e.into_inner());
    let failure = std::thread::scope(|s| {
        let mut failure = None;
        for started in 0..count {
            let spawned = std::thread::Builder::new().spawn_scoped(s, || drop(gate.read()));
            if let Err(e) = spawned {
                failure = Some((started, e));
                break;
            }
        }
        drop(closed);
        failure
    });
    match failure {
        None => Ok(()),
        Some((started, e)) => bail!(
            "cannot start {count} threads: the system refused thread {} ({e}); give fewer with --threads, or raise the limit (ulimit -v, ulimit -u)",
            started + 1
        ),
    }
}
