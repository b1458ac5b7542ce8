//! `viewer [FILE]`: the interactive volume viewer.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use raycaster::synth::SceneKind;
use viewer::{Source, Viewer};

/// Interactive CPU volume viewer for huge bricked, memory-mapped volumes.
///
/// Left drag orbits, middle or shift + left drag pans, the wheel zooms; keys: R
/// resets the view, 1/2/3 (or X/Y/Z; shift for the negative side) look along an
/// axis, S (or Ctrl+S) saves a screenshot, Ctrl+Z and Ctrl+Y undo and redo
/// edits of the transfer function. Without FILE it shows a generated scene
/// at once. "Save session" writes the view as a
/// TOML file that `viewer --session` restores and `raycaster render --session`
/// renders pixel for pixel.
#[derive(Parser)]
#[command(version, about, long_about)]
struct Args {
    /// The volume to open: a `.vol` file (mapped, never read whole), or a scan in
    /// NRRD, NIfTI-1, MetaImage or a DICOM series folder (converted in RAM up to
    /// 1 GiB of samples; convert bigger ones with `volgen convert`).
    file: Option<PathBuf>,

    /// Built-in scene shown without FILE: shapes, shells, noise or gradient.
    #[arg(long, default_value = "shapes", value_parser = parse_scene)]
    scene: SceneKind,

    /// Edge of the built-in scene in voxels.
    #[arg(long, default_value_t = viewer::loader::BUILT_IN_SIZE,
          value_parser = clap::value_parser!(u32).range(8..=1024))]
    scene_size: u32,

    /// A two-level scene description (TOML) to load at start.
    #[arg(long, value_name = "SCENE.toml")]
    segments: Option<PathBuf>,

    /// A session to restore at start (saved with "Save session"): its volume,
    /// camera, transfer function, mode, settings and scene.
    #[arg(long, value_name = "S.toml", conflicts_with_all = ["file", "segments", "scene", "scene_size"])]
    session: Option<PathBuf>,
}

fn parse_scene(s: &str) -> Result<SceneKind, String> {
    SceneKind::ALL
        .into_iter()
        .find(|k| k.name() == s)
        .ok_or_else(|| format!("unknown scene {s:?} (shapes, shells, noise, gradient)"))
}

fn main() -> ExitCode {
    // A volume file truncated while mapped: an error line, not a bus error.
    raycaster::files::guard_mapped_reads("the viewer stopped");
    raycaster::files::fail_writes_past_the_file_size_limit();
    let args = Args::parse();
    let source = match (args.session, args.file) {
        (Some(session), _) => Source::Session(session),
        (None, Some(path)) => Source::File(path),
        (None, None) => Source::BuiltIn(args.scene, args.scene_size),
    };
    let result = Viewer::new(source, args.segments).and_then(|v| v.run());
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", raycaster::errors::error_text(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}
