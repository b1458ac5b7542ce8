//! Every file of the hostile corpus (`volumes/hostile/corpus.rs`) through `volgen
//! info` and `volgen convert`: a clean error or a valid result, never a panic, a
//! hang or partial output.

#[path = "../../volumes/hostile/corpus.rs"]
mod corpus;
#[path = "../../volumes/hostile/harness.rs"]
mod harness;

use std::path::Path;
use std::time::{Duration, Instant};

use harness::{assert_clean_error, run_limited};

/// `volgen args` in `dir` under a time limit: exit code and stderr.
fn run(dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    run_limited(env!("CARGO_BIN_EXE_volgen"), dir, args, limit)
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
