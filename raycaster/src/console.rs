//! Standard output and standard error of the command-line programs, written
//! without panicking.
//!
//! `println!` panics when standard output cannot take the line (a full disk,
//! `/dev/full`, a closed pipe with SIGPIPE ignored): the programs call these
//! functions instead (their `println!`-like macros do). A failed write to
//! standard output is kept, and later ones are skipped, so the command goes on
//! to finish its files (a benchmark piped to `head` still writes its CSV);
//! [`stdout_failure`] says at the end what went wrong, for the one error line
//! and the exit status. Standard error has nowhere to report its own failure:
//! those writes are dropped.

use std::fmt;
use std::io::Write;
use std::sync::Mutex;

/// The first failure of a write to standard output, if any.
static STDOUT_FAILURE: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes `args` and a newline to standard output, unless an earlier write
/// failed; a failure is kept for [`stdout_failure`].
pub fn print_line(args: fmt::Arguments<'_>) {
    write_out(|out| writeln!(out, "{args}"));
}

/// Writes `args` to standard output (no newline), as [`print_line`].
pub fn print(args: fmt::Arguments<'_>) {
    write_out(|out| write!(out, "{args}"));
}

fn write_out(write: impl FnOnce(&mut std::io::StdoutLock<'_>) -> std::io::Result<()>) {
    let mut failure = STDOUT_FAILURE.lock().unwrap_or_else(|e| e.into_inner());
    if failure.is_some() {
        return;
    }
    let mut out = std::io::stdout().lock();
    // (A line is flushed by itself when the output is a terminal; a file or
    // pipe is flushed here too, so that a full disk is seen now, not at exit.)
    if let Err(e) = write(&mut out).and_then(|()| out.flush()) {
        *failure = Some(e);
    }
}

/// Writes `args` and a newline to standard error; a failure is dropped.
pub fn eprint_line(args: fmt::Arguments<'_>) {
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}

/// Writes `args` to standard error (no newline); a failure is dropped.
pub fn eprint(args: fmt::Arguments<'_>) {
    let _ = write!(std::io::stderr().lock(), "{args}");
}

/// What failed when writing standard output, said for an `error:` line;
/// `None` when every write went through, or when the reader closed the pipe
/// (`| head`: it took what it wanted, as with any Unix tool).
pub fn stdout_failure() -> Option<String> {
    let failure = STDOUT_FAILURE.lock().unwrap_or_else(|e| e.into_inner());
    match failure.as_ref() {
        Some(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Some(format!(
            "standard output: {e}; the output printed is incomplete"
        )),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_pipe_is_no_failure_and_a_full_disk_is_one() {
        let full = std::io::Error::from_raw_os_error(28);
        *STDOUT_FAILURE.lock().unwrap() = Some(full);
        let said = stdout_failure().unwrap();
        assert!(
            said.starts_with("standard output: No space left on device"),
            "{said}"
        );
        // Later lines are skipped, not written after the failure.
        print_line(format_args!("not written"));
        assert!(stdout_failure().is_some());
        *STDOUT_FAILURE.lock().unwrap() = Some(std::io::ErrorKind::BrokenPipe.into());
        assert_eq!(stdout_failure(), None);
        *STDOUT_FAILURE.lock().unwrap() = None;
    }
}
