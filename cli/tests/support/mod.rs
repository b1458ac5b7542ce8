//! What the CLI tests share: running the `raycaster` binary as a user would,
//! and writing the volumes it reads.
// Each test binary uses some of these.
#![allow(dead_code)]

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

/// Writes built-in scene `kind` (its `seed`) as a bricked (side 16) u8 `.vol` of
/// `n³` voxels in `format`, with its resolution pyramid where the format has one.
pub fn write_scene(
    path: &Path,
    kind: raycaster::synth::SceneKind,
    n: u32,
    seed: u64,
    format: raycaster::volume::Format,
) {
    let scene = kind.build([n; 3], seed);
    let header = raycaster::volume::Header::new(
        [n; 3],
        [1.0; 3],
        raycaster::volume::Layout::Bricked { side: 16 },
        raycaster::volume::SampleType::U8,
        raycaster::volume::Content::Scalar,
        format,
    );
    raycaster::generate::generate(
        scene.as_ref(),
        &header,
        path,
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap();
}

/// Writes a linear u8 label volume of `n³` voxels, every id 1, at `path`.
pub fn write_labels(path: &Path, n: u32) {
    let header = raycaster::volume::Header::new(
        [n; 3],
        [1.0; 3],
        raycaster::volume::Layout::Linear,
        raycaster::volume::SampleType::U8,
        raycaster::volume::Content::Labels,
        raycaster::volume::Format::Extended,
    );
    let mut bytes = header.encode().unwrap();
    bytes.resize(bytes.len() + (n as usize).pow(3), 1);
    std::fs::write(path, bytes).unwrap();
}
