//! Progress bars on a terminal (quiet when piped) and Ctrl-C as a clean cancel.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};

/// Set by Ctrl-C; long jobs check it between batches and remove their partial output.
pub static CANCEL: AtomicBool = AtomicBool::new(false);

/// Makes Ctrl-C, SIGTERM and SIGHUP request a clean cancel instead of killing the
/// process mid-write: the job stops at its next batch, removes its partial
/// output and the process exits with status 130. A second signal (`timeout`
/// sends two) exits at once, with the same status, deleting the partial
/// outputs first.
pub fn install_signal_handler() {
    // A second handler cannot be installed; the first one is all we need.
    let _ = ctrlc::set_handler(|| {
        if CANCEL.swap(true, Ordering::Relaxed) {
            raycaster::files::remove_partial_outputs();
            eprintln!("interrupted again: stopping now; no output was written");
            std::process::exit(130);
        }
    });
}

/// A voxel-count progress bar on stderr, hidden when `quiet` or stderr is not a terminal.
pub fn voxel_bar(total: u64, message: &str, quiet: bool) -> ProgressBar {
    let target = if quiet || !std::io::stderr().is_terminal() {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some(total), target);
    bar.set_style(
        ProgressStyle::with_template(
            "{msg:>10} [{bar:40.cyan/blue}] {percent:>3}% {human_pos}/{human_len} voxels, {rate}, {left}",
        )
        .expect("valid template")
        .with_key("rate", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&rate_text(s.pos(), s.elapsed().as_secs_f64()));
        })
        .with_key("left", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let len = s.len().unwrap_or(0);
            let _ = w.write_str(&time_left_text(s.pos(), len, s.elapsed().as_secs_f64()));
        })
        .progress_chars("=> "),
    );
    bar.set_message(message.to_string());
    bar
}

/// A byte-count progress bar on stderr (decompression), hidden like [`voxel_bar`].
pub fn byte_bar(total: u64, message: &str, quiet: bool) -> ProgressBar {
    let target = if quiet || !std::io::stderr().is_terminal() {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some(total), target);
    bar.set_style(
        ProgressStyle::with_template(
            "{msg:>10} [{bar:40.cyan/blue}] {percent:>3}% {bytes}/{total_bytes}, {binary_bytes_per_sec}, {left}",
        )
        .expect("valid template")
        .with_key("left", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let len = s.len().unwrap_or(0);
            let _ = w.write_str(&time_left_text(s.pos(), len, s.elapsed().as_secs_f64()));
        })
        .progress_chars("=> "),
    );
    bar.set_message(message.to_string());
    bar
}

/// `61.5 M voxels/s`: the mean rate since the start (steadier than indicatif's
/// recent-steps estimate, and in units people read).
pub fn rate_text(done: u64, secs: f64) -> String {
    if secs <= 0.0 || done == 0 {
        return "… voxels/s".to_string();
    }
    let rate = done as f64 / secs;
    if rate >= 1e9 {
        format!("{:.2} G voxels/s", rate / 1e9)
    } else if rate >= 1e6 {
        format!("{:.1} M voxels/s", rate / 1e6)
    } else if rate >= 1e3 {
        format!("{:.1} k voxels/s", rate / 1e3)
    } else {
        format!("{rate:.0} voxels/s")
    }
}

/// `about 42 s left` from the mean rate so far; `estimating…` until there is one,
/// so the estimate never sits at 0 s while work remains.
pub fn time_left_text(done: u64, total: u64, secs: f64) -> String {
    if done == 0 || secs < 0.5 || total <= done {
        return if total > 0 && done >= total {
            "done".to_string()
        } else {
            "estimating…".to_string()
        };
    }
    let left = (total - done) as f64 * secs / done as f64;
    if left >= 120.0 {
        format!("about {:.0} min left", left / 60.0)
    } else {
        format!("about {:.0} s left", left.max(1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_and_time_left_read_well() {
        assert_eq!(rate_text(61_500_000, 1.0), "61.5 M voxels/s");
        assert_eq!(rate_text(2_500_000_000, 1.0), "2.50 G voxels/s");
        assert_eq!(rate_text(500, 1.0), "500 voxels/s");
        assert_eq!(rate_text(0, 0.0), "… voxels/s");
        assert_eq!(time_left_text(0, 100, 3.0), "estimating…");
        assert_eq!(time_left_text(50, 100, 10.0), "about 10 s left");
        // Nearly done: at least one second, never 0 s while work remains.
        assert_eq!(time_left_text(999_999, 1_000_000, 10.0), "about 1 s left");
        assert_eq!(time_left_text(10, 1000, 60.0), "about 99 min left");
        assert_eq!(time_left_text(100, 100, 10.0), "done");
    }
}
