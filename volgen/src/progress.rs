//! Progress bars on a terminal (quiet when piped) and Ctrl-C as a clean cancel.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Set by Ctrl-C; long jobs check it between batches and remove their partial output.
pub static CANCEL: AtomicBool = AtomicBool::new(false);

/// Makes Ctrl-C, SIGTERM and SIGHUP request a clean cancel instead of killing the
/// process mid-write: the job stops at its next batch and removes its partial
/// output. A second signal exits at once (exit status 130); a partial file it
/// leaves is removed by the next run writing the same file.
pub fn install_signal_handler() {
    // A second handler cannot be installed; the first one is all we need.
    let _ = ctrlc::set_handler(|| {
        if CANCEL.swap(true, Ordering::Relaxed) {
            eprintln!("interrupted again: stopping now");
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
            "{msg:>10} [{bar:40.cyan/blue}] {percent:>3}% {human_pos}/{human_len} voxels, {per_sec}, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(message.to_string());
    bar
}
