//! What the CLI tests share: running the `raycaster` binary as a user would.

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `raycaster` binary with `args` in folder `dir`.
pub fn raycaster(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_raycaster"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the binary runs")
}

/// A run's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
