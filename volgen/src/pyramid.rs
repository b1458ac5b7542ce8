//! `volgen pyramid`: add a resolution pyramid to an existing `.vol` file.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::volume::{Volume, level_dims, pyramid_sidecar_path, pyramid_voxels};

use crate::generate::describe_size;
use crate::progress::{CANCEL, voxel_bar};
use raycaster::text::counted;

/// Add a resolution pyramid to a .vol file, in a sidecar FILE.pyramid beside it.
///
/// Levels 1, 2, … each halve the previous level on every axis (the mean of 2×2×2
/// voxels; the most frequent id for label volumes) down to at most 64 voxels per axis, so
/// the renderer and the viewer show a large volume at once and refine it. The
/// sidecar is written atomically and remembers the file's length and modification
/// time: it is ignored (and can be rebuilt) when the file changes. `volgen generate`
/// and `volgen convert` embed the pyramid in the files they write. Example:
///
///   volgen pyramid big.vol
#[derive(Args, Debug)]
pub struct PyramidArgs {
    /// The .vol file.
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Rebuild a sidecar that exists and is up to date.
    #[arg(long)]
    force: bool,
    /// Print nothing but errors (no progress bar).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: PyramidArgs) -> anyhow::Result<()> {
    if let Some(problem) = raycaster::import::vol_only_problem(&a.file) {
        anyhow::bail!("{}: {problem}", a.file.display());
    }
    raycaster::files::guard_mapped_file(&a.file);
    let volume = Volume::open(&a.file)?;
    let dims = volume.dims();
    if level_dims(dims).is_empty() {
        if !a.quiet {
            println!(
                "{}: {} needs no pyramid (at most 64 voxels per axis)",
                a.file.display(),
                describe_size(dims)
            );
        }
        return Ok(());
    }
    let embedded = volume.header().pyramid_offset.is_some();
    // (An embedded pyramid is read before any sidecar: one written with
    // --force would never be read.)
    if volume.level_count() > 1 && (embedded || !a.force) {
        if !a.quiet {
            let levels = counted(volume.level_count() as u64 - 1, "level");
            let place = if embedded {
                "in the file; nothing to do (`volgen convert` rewrites the file with a fresh one)"
                    .to_string()
            } else {
                format!(
                    "in {} (--force rebuilds it)",
                    pyramid_sidecar_path(&a.file).display()
                )
            };
            println!(
                "{}: already has a pyramid of {levels} {place}",
                a.file.display()
            );
        }
        return Ok(());
    }
    drop(volume);
    // The sidecar can be written (a read-only folder is said before any work;
    // a stale sidecar is replaced). Its name is not the user's to choose.
    let sidecar = pyramid_sidecar_path(&a.file);
    if sidecar.is_dir() {
        anyhow::bail!(
            "{}: is a directory, where the pyramid of {} goes: move it away",
            sidecar.display(),
            a.file.display()
        );
    }
    crate::output::check_output(&sidecar, true)?;
    let bar = voxel_bar(pyramid_voxels(dims), "pyramid", a.quiet);
    let on_progress = |n| bar.inc(n);
    let job = Job::silent()
        .with_progress(&on_progress)
        .with_cancel(&CANCEL);
    let start = Instant::now();
    let levels = raycaster::volume::write_pyramid_sidecar(&a.file, &WriteOptions::default(), &job)?;
    bar.finish_and_clear();
    if !a.quiet {
        let sidecar = pyramid_sidecar_path(&a.file);
        let bytes = std::fs::metadata(&sidecar).map(|m| m.len()).unwrap_or(0);
        println!(
            "wrote {}: {}, {bytes} bytes in {:.2} s",
            sidecar.display(),
            counted(levels as u64, "level"),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
