//! Every file of the hostile corpus (`volumes/hostile/corpus.rs`) through
//! `raycaster render` as a volume, a transfer function or a two-level scene: a
//! clean error or a valid image, never a panic, a hang or partial output.

#[path = "../../volumes/hostile/corpus.rs"]
mod corpus;
#[path = "../../volumes/hostile/harness.rs"]
mod harness;

use std::path::Path;
use std::time::{Duration, Instant};

use corpus::Kind;
use harness::{assert_clean_error, run_limited};

/// `raycaster args` in `dir` under a time limit: exit code and stderr.
fn run(dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    run_limited(env!("CARGO_BIN_EXE_raycaster"), dir, args, limit)
}

#[test]
fn every_corpus_file_renders_or_is_refused_cleanly() {
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases = corpus::write(d);
    let out = tempfile::tempdir().unwrap();
    let good = d.join("good.vol");
    let good = good.to_str().unwrap();
    let limit = Duration::from_secs(20);
    for (i, case) in cases.iter().enumerate() {
        let file = case.path.to_str().unwrap();
        let name = case.path.file_name().unwrap().to_string_lossy();
        let png = out.path().join(format!("out{i}.png"));
        let png = png.to_str().unwrap();
        let mut args = vec!["render", "--size", "24", "-q", "-o", png];
        match case.kind {
            Kind::Volume => args.push(file),
            Kind::Transfer => args.extend(["--scene-size", "16", "--tf", file]),
            Kind::Scene => args.extend([good, "--segments", file]),
        }
        let (code, err) = run(d, &args, limit);
        if case.valid {
            assert_eq!(code, Some(0), "{name}: {err}");
            assert!(Path::new(png).exists(), "{name}: no image");
        } else {
            assert_eq!(code, Some(1), "{name} was not refused: {err}");
            assert_clean_error(&name, &err);
            assert!(!Path::new(png).exists(), "{name} failed but wrote an image");
        }
        let left: Vec<_> = std::fs::read_dir(out.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{name} left {left:?}");
    }
    assert!(
        start.elapsed() < Duration::from_secs(60),
        "the corpus took {:?}",
        start.elapsed()
    );
}
