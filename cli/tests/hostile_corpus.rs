//! Every file of the hostile corpus (`volumes/hostile/corpus.rs`) through
//! `raycaster render` as a volume, a transfer function or a two-level scene: a
//! clean error or a valid image, never a panic, a hang or partial output.

#[path = "../../volumes/hostile/corpus.rs"]
mod corpus;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use corpus::Kind;

fn run(dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_raycaster"))
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
            panic!("raycaster {args:?} hung (over {limit:?})");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn assert_clean_error(what: &str, err: &str) {
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
