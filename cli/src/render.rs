//! `raycaster render`: a volume file (or a built-in scene) to a PNG.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use raycaster::render::{
    Camera, LevelChoice, Light, Membership, Mode, ModeParameters, Orbit, ParallelOptions,
    Projection, RenderSettings, RenderVolume, SegmentScene, Shading, render_parallel,
    render_sequential,
};
use raycaster::source::{self, OpenedVolume, VolumeSource};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Volume};

use crate::args::{
    parse_color, parse_domain, parse_positive, parse_size, parse_threshold, parse_vec3,
};
use crate::stats;

/// Render a volume to a PNG image, without a window.
///
/// With no FILE, renders a built-in generated scene (`--scene`), so one command
/// shows a picture. The camera frames the whole volume from `--azimuth` and
/// `--elevation` unless `--position` is given. The output file is replaced if it
/// exists (written to a temporary file and renamed, never left half-written).
#[derive(Args, Debug)]
#[command(after_help = AFTER_HELP)]
pub struct RenderArgs {
    /// The volume to render (default: a built-in generated scene): a .vol file, or a
    /// NRRD (.nrrd/.nhdr), NIfTI-1 (.nii/.nii.gz) or MetaImage (.mha/.mhd) file or a
    /// DICOM series folder,
    /// converted in memory when its samples take at most 1 GiB (larger ones:
    /// convert with `volgen convert` first).
    file: Option<PathBuf>,

    /// Output PNG.
    #[arg(short, long, default_value = "render.png", value_name = "PNG")]
    output: PathBuf,

    /// Image size, WxH (or N for a square).
    #[arg(long, default_value = "512x512", value_parser = parse_size, value_name = "WxH")]
    size: [u32; 2],

    /// Built-in scene rendered when no FILE is given.
    #[arg(long, value_enum, default_value_t = SceneArg::Shapes)]
    scene: SceneArg,

    /// Size of the built-in scene in voxels per axis.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(2..=1024), value_name = "N")]
    scene_size: u32,

    /// Seed of the built-in scene.
    #[arg(long, default_value_t = 1)]
    seed: u64,

    /// Transfer function: a preset name or a transfer-function file
    /// (default: the preset that suits the built-in scene, `shapes` for files).
    #[arg(long, value_name = "PRESET|FILE")]
    tf: Option<String>,

    /// Raw sample values the transfer function spans, lo,hi (default: the whole
    /// u8 range; the data's range for u16 volumes).
    #[arg(long, value_parser = parse_domain, value_name = "LO,HI")]
    domain: Option<[f32; 2]>,

    /// Compositing mode.
    #[arg(long, value_enum, default_value_t = ModeArg::Dvr)]
    mode: ModeArg,

    /// Iso-value for first-hit mode, 0..1 over the transfer function's domain.
    #[arg(long, default_value_t = 0.5, value_name = "V")]
    iso: f32,

    /// Gain of xray mode: opacity 1 − exp(−gain·Σ normalised value × step).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive, value_name = "G")]
    xray_gain: f32,

    /// Sample distance along rays, in voxels.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive, value_name = "VOXELS")]
    step: f32,

    /// Disable early ray termination.
    #[arg(long)]
    no_ert: bool,

    /// Opacity at which early ray termination stops a ray.
    #[arg(long, default_value_t = 0.99, value_parser = parse_threshold, value_name = "ALPHA")]
    ert_threshold: f32,

    /// Disable empty-space skipping.
    #[arg(long)]
    no_ess: bool,

    /// Disable Blinn-Phong shading.
    #[arg(long)]
    no_shading: bool,

    /// Light direction x,y,z (world; the light shines along it). Default: a headlight.
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z")]
    light: Option<[f32; 3]>,

    /// Background colour: #rrggbb, r,g,b, black, white or grey.
    #[arg(long, default_value = "black", value_parser = parse_color, value_name = "COLOUR")]
    background: [f32; 3],

    /// Camera azimuth about the volume's vertical (z) axis, degrees.
    #[arg(long, default_value_t = -60.0, allow_negative_numbers = true, value_name = "DEG")]
    azimuth: f32,

    /// Camera elevation above the volume's middle, degrees.
    #[arg(
        long,
        default_value_t = 25.0,
        allow_negative_numbers = true,
        value_name = "DEG"
    )]
    elevation: f32,

    /// Distance from the target in world units (default: frame the whole volume).
    #[arg(long, value_parser = parse_positive, value_name = "D")]
    distance: Option<f32>,

    /// Zoom factor on the framed view (2 = twice as close).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    zoom: f32,

    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 40.0, value_name = "DEG")]
    fov: f32,

    /// Orthographic instead of perspective projection.
    #[arg(long)]
    orthographic: bool,

    /// Camera position x,y,z in world units (overrides azimuth/elevation/distance).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true, value_name = "X,Y,Z")]
    position: Option<[f32; 3]>,

    /// Point the camera looks at (default: the volume's centre).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true, value_name = "X,Y,Z")]
    target: Option<[f32; 3]>,

    /// Camera up vector.
    #[arg(long, default_value = "0,0,1", value_parser = parse_vec3, allow_negative_numbers = true, value_name = "X,Y,Z")]
    up: [f32; 3],

    /// Render threads of the object-parallel renderer (default: one per core);
    /// `--sequential` uses the single-threaded reference renderer instead.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024), value_name = "N")]
    threads: Option<u32>,

    /// Compositing threads of the parallel renderer.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64), value_name = "N")]
    compositors: u32,

    /// Tile side of the parallel renderer, pixels.
    #[arg(long, default_value_t = raycaster::render::DEFAULT_TILE_SIZE, value_parser = clap::value_parser!(u32).range(1..=4096), value_name = "PX")]
    tile: u32,

    /// Render with the sequential reference renderer (one thread, image order).
    #[arg(long, conflicts_with_all = ["threads", "compositors", "tile"])]
    sequential: bool,

    /// Brick side: logical bricks of linear volumes (default 16; 31 above about
    /// 800³ voxels, where fewer bricks render faster), or sub-bricks of a bricked
    /// file whose step divides the file's (default: the file's bricks).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=1024), value_name = "N")]
    brick: Option<u32>,

    /// Read the file into RAM instead of mapping it.
    #[arg(long)]
    ram: bool,

    /// Resolution level of the file's pyramid to sample: `auto` (the coarsest
    /// whose voxels project to at most a pixel) or a level number (0 = full
    /// resolution, 1 = half on every axis, ...). Files without a pyramid
    /// (`volgen pyramid FILE` adds one) always render level 0.
    #[arg(long, default_value = "auto", value_parser = |s: &str| s.parse::<LevelChoice>(), value_name = "auto|N")]
    level: LevelChoice,

    /// Shifts the automatic level choice by this many levels (1: one coarser,
    /// -1: one finer).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_name = "LEVELS"
    )]
    lod_bias: f32,

    /// Two-level rendering of a segmented volume: a scene description (TOML) of
    /// value layers or a label volume, with each object's transfer function and
    /// local mode (see volumes/scenes/).
    #[arg(long, value_name = "SCENE.toml")]
    segments: Option<PathBuf>,

    /// Label volume for a label scene (overrides the scene's `labels`).
    #[arg(long, value_name = "FILE", requires = "segments")]
    labels: Option<PathBuf>,

    /// Print the frame's counters.
    #[arg(long)]
    stats: bool,

    /// Print the frame's counters as one JSON object on stdout.
    #[arg(long)]
    stats_json: bool,

    /// No message on success.
    #[arg(short, long)]
    quiet: bool,
}

const AFTER_HELP: &str = "Transfer-function presets: shapes, ct-bone, ct-skin, shells, cloud, opaque, grayscale, rainbow.
A transfer-function file holds lines `point VALUE R G B ALPHA` (all 0..1), optional
`domain LO HI` (raw values) and `gradient G0 G1` (2D: opacity × smoothstep of |∇f|).

Examples:
  raycaster render -o shapes.png
  raycaster render head.vol --tf ct-bone --size 800x800 --stats
  raycaster render head.vol --mode mip --azimuth 0 --elevation 0 -o mip.png
  raycaster render ch2.nii.gz --tf ct-skin -o head.png   # NRRD, NIfTI, MetaImage open directly";

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SceneArg {
    Shapes,
    Shells,
    Noise,
    Gradient,
}

impl SceneArg {
    fn kind(self) -> SceneKind {
        match self {
            SceneArg::Shapes => SceneKind::Shapes,
            SceneArg::Shells => SceneKind::Shells,
            SceneArg::Noise => SceneKind::Noise,
            SceneArg::Gradient => SceneKind::Gradient,
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum ModeArg {
    /// Direct volume rendering (emission-absorption, front to back).
    Dvr,
    /// Maximum intensity projection.
    Mip,
    /// Average intensity projection.
    Average,
    /// First hit of the iso-value, refined between samples, shaded.
    FirstHit,
    /// X-ray: the sum of values along the ray (`--xray-gain`).
    Xray,
    /// Importance-aware compositing (constant importance).
    Importance,
    /// Context-preserving rendering (κt 1.5, κs 0.4).
    Context,
    /// Tone shading and silhouette darkening.
    Silhouette,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Dvr => Mode::Dvr,
            ModeArg::Mip => Mode::Mip,
            ModeArg::Average => Mode::Average,
            ModeArg::FirstHit => Mode::FirstHit,
            ModeArg::Xray => Mode::XRay,
            ModeArg::Importance => Mode::Importance,
            ModeArg::Context => Mode::ContextPreserving,
            ModeArg::Silhouette => Mode::Silhouette,
        }
    }
}

/// Runs the render command.
pub fn run(args: RenderArgs) -> Result<()> {
    if !(args.fov > 0.0 && args.fov < 180.0) {
        bail!(
            "--fov {} must lie strictly between 0 and 180 degrees",
            args.fov
        );
    }
    if !(0.0..=1.0).contains(&args.iso) {
        bail!("--iso {} must lie in [0, 1]", args.iso);
    }
    let read_before = stats::bytes_read();
    let opened = open_volume(&args)?;
    let settings = settings(&args, &opened)?;
    let OpenedVolume { volume, labels, .. } = opened;
    let label_volume = match (&settings.segments, &args.labels) {
        (Some(_), Some(path)) => Some(Volume::open(path)?),
        (Some(scene), None) => match &scene.membership {
            // A built-in scene brings its own segmentation, when it has one.
            Membership::Labels(_) if args.file.is_none() => Some(labels.with_context(|| {
                format!(
                    "the built-in `{}` scene has no label volume; give --labels FILE or a layer scene",
                    args.scene.kind().name()
                )
            })?),
            Membership::Labels(path) => Some(Volume::open(path)?),
            Membership::Layers(_) => None,
        },
        (None, _) => None,
    };
    let choice = match args.level {
        LevelChoice::Auto { .. } => LevelChoice::Auto {
            bias: args.lod_bias,
        },
        fixed => fixed,
    };
    let camera = camera(&args, source::world_box(&volume))?;
    // Two-level scenes with labels sample labels of the same level, when they have it.
    let level = match &label_volume {
        Some(labels) => choice
            .resolve(&volume, &camera)
            .min(labels.level_count() - 1),
        None => choice.resolve(&volume, &camera),
    };
    let mut prepared = RenderVolume::new(volume.level(level), args.brick)?;
    if let Some(labels) = &label_volume {
        prepared = prepared.with_labels(labels.level(level))?;
    }
    let frame = if args.sequential {
        render_sequential(&prepared, &camera, &settings)?
    } else {
        let mut options = ParallelOptions {
            compositing_threads: args.compositors as usize,
            tile_size: args.tile,
            ..ParallelOptions::default()
        };
        if let Some(n) = args.threads {
            options.render_threads = n as usize;
        }
        render_parallel(&prepared, &camera, &settings, &options)?
    };
    frame
        .to_image()
        .save_png(&args.output)
        .context("cannot write the image")?;
    let bytes_read = stats::bytes_read().saturating_sub(read_before);
    if args.stats {
        eprint!("{}", stats::table(&frame.stats));
        eprint!("{}", stats::level_table(&volume, level, bytes_read));
    }
    if args.stats_json {
        println!(
            "{}",
            stats::json(&frame.stats, &volume, &settings, level, bytes_read)
        );
    }
    if !args.quiet {
        eprintln!(
            "wrote {} ({}×{}, {:.3} s, {:.1} M samples)",
            args.output.display(),
            frame.width,
            frame.height,
            frame.stats.time.as_secs_f64(),
            frame.stats.counters.samples as f64 / 1e6
        );
    }
    Ok(())
}

fn open_volume(args: &RenderArgs) -> Result<OpenedVolume> {
    let source = match &args.file {
        Some(path) => VolumeSource::File {
            path: path.clone(),
            access: if args.ram {
                Access::Ram
            } else {
                Access::Mapped
            },
        },
        None => VolumeSource::BuiltIn {
            kind: args.scene.kind(),
            size: args.scene_size,
            seed: args.seed,
        },
    };
    Ok(source::open(&source)?)
}

fn settings(args: &RenderArgs, opened: &OpenedVolume) -> Result<RenderSettings> {
    let tf_name = args.tf.as_deref().unwrap_or(opened.preset);
    let mut transfer = opened
        .transfer(tf_name)
        .with_context(|| format!("--tf {tf_name:?} is neither a preset nor a file"))?;
    if let Some(domain) = args.domain {
        transfer.domain = Some(domain);
    }
    let shading = (!args.no_shading).then(|| Shading {
        light: match args.light {
            Some(d) => Light::Fixed(glam_vec(d)),
            None => Light::Headlight,
        },
        ..Shading::default()
    });
    Ok(RenderSettings {
        mode: args.mode.into(),
        mode_parameters: ModeParameters {
            xray_gain: args.xray_gain,
            ..ModeParameters::default()
        },
        step: args.step,
        early_termination: (!args.no_ert).then_some(args.ert_threshold),
        empty_space_skipping: !args.no_ess,
        shading,
        iso_value: args.iso,
        background: args.background,
        transfer,
        segments: match &args.segments {
            Some(path) => Some(SegmentScene::load(path)?),
            None => None,
        },
    })
}

fn glam_vec(v: [f32; 3]) -> raycaster::render::Vec3 {
    raycaster::render::Vec3::from(v)
}

fn camera(
    args: &RenderArgs,
    (lo, hi): (raycaster::render::Vec3, raycaster::render::Vec3),
) -> Result<Camera> {
    let [w, h] = args.size;
    let target = args.target.map(glam_vec).unwrap_or((lo + hi) / 2.0);
    let up = glam_vec(args.up);
    if let Some(position) = args.position {
        let projection = if args.orthographic {
            Projection::Orthographic {
                height: (hi - lo).length() * 1.08 / args.zoom,
            }
        } else {
            Projection::Perspective { vfov_deg: args.fov }
        };
        return Camera::look_at(glam_vec(position), target, up, projection, w, h)
            .context("invalid camera");
    }
    let vfov = (!args.orthographic).then_some(args.fov);
    let mut orbit = Orbit::framing(
        lo,
        hi,
        args.azimuth.to_radians(),
        args.elevation.to_radians(),
        vfov,
    );
    orbit.target = target;
    if let Some(d) = args.distance {
        orbit.distance = d;
    }
    orbit.zoom(1.0 / args.zoom);
    if up != raycaster::render::Vec3::Z {
        let position = orbit.position();
        let projection = match vfov {
            Some(vfov_deg) => Projection::Perspective { vfov_deg },
            None => Projection::Orthographic {
                height: orbit.ortho_height,
            },
        };
        return Camera::look_at(position, target, up, projection, w, h).context("invalid camera");
    }
    orbit.camera(w, h).context("invalid camera")
}
