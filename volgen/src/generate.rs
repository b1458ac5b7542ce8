//! `volgen generate`: sample a synthetic scene into a `.vol` file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::{Args, ValueEnum};
use raycaster::generate::generate;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::synth::SceneKind;
use raycaster::text::counted;
use raycaster::volume::{
    Content, Format, Header, Layout, SampleType, pyramid_sidecar_path, pyramid_voxels,
    ranges_sidecar_path,
};

use crate::args::{
    FormatArg, LayoutArg, SampleArg, parse_brick, parse_dims, parse_spacing, wrong_command_line,
};
use crate::output::{check_output, output_name_warning, padding_warning, ray_length_warning};
use crate::progress::{CANCEL, voxel_bar};

/// Synthetic scenes on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SceneArg {
    /// Dozens of spheres and boxes, some nearly transparent, some opaque (benchmark scene).
    Shapes,
    /// Nested shells of distinct value ranges with an open octant, plus a label volume.
    Shells,
    /// Fractal noise shaped into a cloud.
    Noise,
    /// A linear ramp along x, value x/(size_x-1) (exactness tests).
    Gradient,
}

impl From<SceneArg> for SceneKind {
    fn from(s: SceneArg) -> Self {
        match s {
            SceneArg::Shapes => SceneKind::Shapes,
            SceneArg::Shells => SceneKind::Shells,
            SceneArg::Noise => SceneKind::Noise,
            SceneArg::Gradient => SceneKind::Gradient,
        }
    }
}

/// Generate a synthetic test volume.
///
/// The same arguments and seed always give a byte-identical file, whatever the
/// thread count. Example:
///
///   volgen generate --scene shapes --size 256 --layout bricked --brick 16 -o shapes.vol
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct GenerateArgs {
    /// Output .vol file.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// What to generate.
    #[arg(long, value_enum, default_value_t = SceneArg::Shapes)]
    scene: SceneArg,
    /// Size in voxels: N for a cube or XxYxZ.
    #[arg(long, value_name = "N|XxYxZ", default_value = "256", value_parser = parse_dims)]
    size: [u32; 3],
    /// Voxel spacing: S or X,Y,Z.
    #[arg(long, value_name = "S|X,Y,Z", default_value = "1", value_parser = parse_spacing, allow_hyphen_values = true)]
    spacing: [f32; 3],
    /// Sample order in the file.
    #[arg(long, value_enum, default_value_t = LayoutArg::Bricked)]
    layout: LayoutArg,
    /// Brick side in voxels for --layout bricked (bricks overlap by one voxel)
    /// [default: 16].
    #[arg(long, value_name = "N", value_parser = parse_brick)]
    brick: Option<u8>,
    /// Sample type.
    #[arg(long = "type", value_enum, default_value_t = SampleArg::U8)]
    sample_type: SampleArg,
    /// Header format (thesis: readable by the reference thesis's tools; u8 only;
    /// a label volume takes the extended header, the only one that marks labels).
    #[arg(long, value_enum, default_value_t = FormatArg::Extended)]
    format: FormatArg,
    /// Seed for the random placement of scene objects.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where the label volume of a segmented scene (shells) goes
    /// [default: OUTPUT with .labels.vol].
    #[arg(long, value_name = "FILE")]
    labels: Option<PathBuf>,
    /// Do not write the label volume of a segmented scene.
    #[arg(long, conflicts_with = "labels")]
    no_labels: bool,
    /// Replace existing output files.
    /// A symbolic link is replaced by the new file; the file it points to is kept.
    #[arg(long)]
    force: bool,
    /// Do not write the resolution pyramid (levels of half resolution on every
    /// axis, about 1/7 of the file, that let the renderer show large volumes at
    /// once; `volgen pyramid FILE` adds it later).
    #[arg(long)]
    no_pyramid: bool,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
}

/// The label file beside `output`: `a/b.vol` → `a/b.labels.vol`.
fn default_labels_path(output: &Path) -> PathBuf {
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    output.with_file_name(format!("{stem}.labels.vol"))
}

pub fn run(a: GenerateArgs) -> anyhow::Result<()> {
    let kind = SceneKind::from(a.scene);
    let layout = match a.layout {
        // (As `volgen convert` says it.)
        LayoutArg::Linear if a.brick.is_some() => {
            wrong_command_line!("--brick applies to --layout bricked only")
        }
        LayoutArg::Linear => Layout::Linear,
        LayoutArg::Bricked => Layout::Bricked {
            side: a.brick.unwrap_or(16),
        },
    };
    let sample_type = SampleType::from(a.sample_type);
    let format = Format::from(a.format);
    if format == Format::Thesis && sample_type != SampleType::U8 {
        wrong_command_line!(
            "--format thesis holds u8 samples only; use --format extended for --type u16"
        );
    }
    let scene = kind.build(a.size, a.seed);
    let labels = (scene.has_labels() && !a.no_labels).then(|| {
        a.labels
            .clone()
            .unwrap_or_else(|| default_labels_path(&a.output))
    });
    if a.labels.is_some() && !scene.has_labels() {
        wrong_command_line!("scene `{}` has no label volume; drop --labels", kind.name());
    }
    if labels
        .as_deref()
        .is_some_and(|l| raycaster::files::same_target(l, &a.output))
    {
        wrong_command_line!("--labels must differ from --output");
    }
    let options = WriteOptions {
        overwrite: a.force,
        pyramid: !a.no_pyramid,
        ..WriteOptions::default()
    };
    // Refuse before doing any work when an output exists or cannot be
    // written (a missing or read-only folder, a device).
    for path in std::iter::once(&a.output).chain(labels.as_ref()) {
        check_output(path, a.force)?;
    }
    // (After the checks: a name that cannot be written is said alone.)
    if let Some(warning) = output_name_warning(&a.output).filter(|_| !a.quiet) {
        eprintln!("{warning}");
    }
    let header = Header::new(
        a.size,
        a.spacing,
        layout,
        sample_type,
        Content::Scalar,
        format,
    );
    header.validate().context("invalid volume description")?;
    if let Some(warning) = ray_length_warning(a.size, a.spacing).filter(|_| !a.quiet) {
        eprintln!("{warning}");
    }
    if let Some(warning) = padding_warning(a.size, layout).filter(|_| !a.quiet) {
        eprintln!("{warning}");
    }
    let voxels: u64 = a.size.iter().map(|&d| u64::from(d)).product();

    let mut outputs = vec![(a.output.clone(), header.clone())];
    if let Some(path) = labels {
        // The thesis header cannot mark labels (they would read as values):
        // the labels take the extended header, which `wrote` names.
        let h = Header::new(
            a.size,
            a.spacing,
            layout,
            SampleType::U8,
            Content::Labels,
            Format::Extended,
        );
        outputs.push((path, h));
    }
    // Every output is written under a hidden name beside its target and moved
    // into place only when all are complete: a failed, full or interrupted
    // run leaves the files that were there as they were (a new volume beside
    // the old labels, or none, is not what was asked for).
    let mut done = Vec::new();
    for (path, header) in outputs {
        let what = if header.content == Content::Labels {
            "labels"
        } else {
            kind.name()
        };
        let extra = if a.no_pyramid {
            0
        } else {
            pyramid_voxels(header.dims)
        };
        // (The count includes the pyramid's voxels: say so.)
        let what = if extra > 0 {
            format!("{what} + pyramid")
        } else {
            what.to_string()
        };
        let bar = voxel_bar(voxels + extra, &what, a.quiet);
        let on_progress = |n| bar.inc(n);
        let job = Job::silent()
            .with_progress(&on_progress)
            .with_cancel(&CANCEL);
        let start = Instant::now();
        let staged = Staged::beside(&path)?;
        let staged_options = WriteOptions {
            overwrite: true,
            ..options
        };
        let written = generate(
            scene.as_ref(),
            &header,
            staged.path(),
            &staged_options,
            &job,
        )
        .map_err(|mut e| {
            // (Errors name the file asked for, not its hidden name.)
            if e.path == staged.path() {
                e.path = path.clone();
            }
            anyhow::Error::from(e)
        })?;
        let secs = start.elapsed().as_secs_f64();
        bar.finish_and_clear();
        done.push((path, header, staged, written, secs));
    }
    for (path, _, staged, _, _) in &mut done {
        staged.move_to(path, a.force)?;
    }
    if !a.quiet {
        for (path, header, _, written, secs) in &done {
            let [lo, hi] = written.ranges.overall();
            println!(
                "wrote {}: {} {}{}, {} bytes in {:.2} s ({:.1} M voxels/s), values {lo}..={hi}",
                path.display(),
                describe_size(header.dims),
                describe_layout(header),
                describe_pyramid(written.pyramid_levels),
                written.file_bytes,
                secs,
                voxels as f64 / secs / 1e6,
            );
        }
    }
    Ok(())
}

/// An output written under a hidden name beside its target (the same
/// folder, so the move is a rename), with the sidecars the writer put beside
/// it; removed when dropped unless moved into place.
struct Staged {
    path: Option<tempfile::TempPath>,
}

impl Staged {
    /// A fresh hidden name beside `target` (a partial file of it, as the
    /// writer's own: removed by a later run if this one is killed).
    fn beside(target: &Path) -> anyhow::Result<Staged> {
        let path = raycaster::files::temp_file_beside(target)
            .with_context(|| format!("{}: cannot write beside it", target.display()))?
            .into_temp_path();
        Ok(Staged { path: Some(path) })
    }

    fn path(&self) -> &Path {
        self.path
            .as_deref()
            .expect("a staged output is in place until moved")
    }

    /// The file's sidecars (thesis files' brick ranges and pyramid).
    fn sidecars(path: &Path) -> [PathBuf; 2] {
        [ranges_sidecar_path(path), pyramid_sidecar_path(path)]
    }

    /// Moves the file and its sidecars to `target` (replacing what is there
    /// only with `force`); a sidecar of the old target that the new file has
    /// not is removed.
    fn move_to(&mut self, target: &Path, force: bool) -> anyhow::Result<()> {
        let path = self.path.take().expect("a staged output is moved once");
        let sidecars = Staged::sidecars(&path);
        let moved = if force {
            path.persist(target)
        } else {
            path.persist_noclobber(target)
        };
        moved.map_err(|e| {
            self.path = Some(e.path);
            // (Another run may have written it since the check before the work.)
            if e.error.kind() == std::io::ErrorKind::AlreadyExists {
                return anyhow::Error::from(raycaster::volume::VolumeError::new(
                    target,
                    raycaster::volume::VolumeErrorKind::Exists,
                ));
            }
            anyhow::Error::from(e.error).context(format!("{}: cannot write it", target.display()))
        })?;
        for (from, to) in sidecars.iter().zip(Staged::sidecars(target)) {
            if from.exists() {
                std::fs::rename(from, &to)
                    .with_context(|| format!("{}: cannot write it", to.display()))?;
            } else if to.exists() {
                std::fs::remove_file(&to)
                    .with_context(|| format!("{}: cannot remove the old file", to.display()))?;
            }
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(path) = &self.path {
            for sidecar in Staged::sidecars(path) {
                let _ = std::fs::remove_file(sidecar);
            }
        }
    }
}

/// `, pyramid of 3 levels` (or nothing).
pub fn describe_pyramid(levels: usize) -> String {
    match levels {
        0 => String::new(),
        n => format!(", pyramid of {}", counted(n as u64, "level")),
    }
}

/// `256x256x256`.
pub fn describe_size(d: [u32; 3]) -> String {
    format!("{}x{}x{}", d[0], d[1], d[2])
}

/// `u8 bricked (side 16), extended header`.
pub fn describe_layout(h: &Header) -> String {
    let ty = match (h.sample_type, h.content) {
        (_, Content::Labels) => "u8 labels",
        (SampleType::U8, _) => "u8",
        (SampleType::U16, _) => "u16",
    };
    let layout = h.layout;
    let format = match h.format {
        Format::Thesis => "thesis header",
        Format::Extended => "extended header",
    };
    format!("{ty} {layout}, {format}")
}
