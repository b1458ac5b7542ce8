//! What the hostile-corpus tests of `raycaster` and `volgen` share (included by
//! both with `#[path]`): running a binary under a time limit, and the rule for a
//! clean error message.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Exit code (`None`: killed by a signal) and stderr of `exe args` run in `dir`,
/// failing the test when it runs longer than `limit`.
pub fn run_limited(exe: &str, dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(exe)
        .current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return (status.code(), err);
        }
        if start.elapsed() > limit {
            child.kill().unwrap();
            child.wait().unwrap();
            let name = Path::new(exe)
                .file_name()
                .unwrap_or_default()
                .to_string_lossy();
            panic!("{name} {args:?} hung (over {limit:?})");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Asserts an error message is one clean line: `error: `, no Rust debug text, no
/// cause said twice, no temporary file names.
pub fn assert_clean_error(what: &str, err: &str) {
    assert!(err.starts_with("error: "), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    for debug in ["Some(", "None", " { ", "Os {", "kind: "] {
        assert!(!err.contains(debug), "{what}: debug text in {err}");
    }
    assert!(!err.contains(".partial"), "{what}: temporary name in {err}");
    let parts: Vec<&str> = err.trim().split(": ").map(str::trim).collect();
    for (i, p) in parts.iter().enumerate() {
        if p.len() > 12 {
            assert!(
                !parts[i + 1..].contains(p),
                "{what}: `{p}` said twice in {err}"
            );
        }
    }
}
