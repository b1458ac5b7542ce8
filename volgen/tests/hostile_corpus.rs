//! Every file of the hostile corpus (`volumes/hostile/corpus.rs`) through `volgen
//! info` and `volgen convert`: a clean error or a valid result, never a panic, a
//! hang or partial output.

#[path = "../../volumes/hostile/corpus.rs"]
mod corpus;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Exit code (None: killed by a signal) and stderr of `volgen args`, failing the
/// test when it runs longer than `limit`.
fn run(dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_volgen"))
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
            panic!("volgen {args:?} hung (over {limit:?})");
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

fn partials(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect()
}

#[test]
fn every_corpus_file_gets_a_clean_error_or_a_valid_result() {
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = tempfile::tempdir().unwrap();
    let cases = corpus::write(d);
    assert!(cases.len() > 40, "{} cases", cases.len());
    let limit = Duration::from_secs(20);
    for (i, case) in cases
        .iter()
        .filter(|c| c.kind == corpus::Kind::Volume)
        .enumerate()
    {
        let file = case.path.to_str().unwrap();
        let name = case.path.file_name().unwrap().to_string_lossy();
        let (code, err) = run(d, &["info", file, "-q"], limit);
        assert!(matches!(code, Some(0 | 1)), "info {name}: {code:?} {err}");
        if code == Some(1) {
            assert_clean_error(&format!("info {name}"), &err);
        } else {
            assert!(err.is_empty(), "info {name}: {err}");
        }
        if case.valid {
            assert_eq!(code, Some(0), "info {name}: {err}");
        }

        let target = out.path().join(format!("out{i}.vol"));
        let (code, err) = run(
            d,
            &["convert", file, "-o", target.to_str().unwrap(), "-q"],
            limit,
        );
        assert!(
            matches!(code, Some(0 | 1)),
            "convert {name}: {code:?} {err}"
        );
        if code == Some(0) {
            // Accepted: the output is a whole, readable volume.
            let (c, e) = run(d, &["info", target.to_str().unwrap(), "-q"], limit);
            assert_eq!(c, Some(0), "convert {name} wrote a bad file: {e}");
        } else {
            assert_clean_error(&format!("convert {name}"), &err);
            assert!(!target.exists(), "convert {name} failed but wrote output");
        }
        if case.valid {
            assert_eq!(code, Some(0), "convert {name}: {err}");
        }
        assert!(
            partials(out.path()).is_empty(),
            "convert {name} left partials"
        );
        assert!(partials(d).is_empty(), "convert {name} left partials");
    }
    assert!(
        start.elapsed() < Duration::from_secs(60),
        "the corpus took {:?}",
        start.elapsed()
    );
}
