//! `raycaster render`: a volume file (or a built-in scene) to a PNG.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use raycaster::render::{
    Camera, ClipPlane, ClipRegion, CropBox, DepthBand, LevelBand, LevelChoice, Light,
    LookAtProblem, MAX_CLIP_PLANES, Mat3, Membership, Mode, ModeParameters, Orbit, ParallelOptions,
    PixelProgress, Projection, RenderSettings, RenderVolume, Renderer, SabellaDepth,
    SabellaMapping, SabellaOutput, SegmentScene, Shading, SimdLevel, TileSink, TransferFunction,
    Vec3, closest_preset, patient_axes, render_sequential_noting,
};
use raycaster::session::{Session, SessionCamera};
use raycaster::source::{self, VolumeSource};
use raycaster::synth::{SceneKind, synthesize, synthesize_labels};
use raycaster::volume::{Access, Content, OpenOptions, SampleType, Volume};

use crate::args::{
    ClipArg, Coord, IsoArg, WindowArg, parse_clip, parse_color, parse_crop, parse_direction,
    parse_elevation, parse_finite, parse_fov, parse_iso, parse_positive, parse_size,
    parse_threshold, parse_vec3, parse_window,
};
use crate::stats;

/// Render a volume to a PNG image, without a window.
///
/// With no FILE, renders a built-in generated scene (`--scene`), so one command
/// shows a picture. The camera frames the whole volume from `--azimuth` and
/// `--elevation` unless `--position` is given. With `--session S.toml` (saved by
/// the viewer), renders exactly what the session describes: the flags that
/// describe the picture are refused with it. The output (PNG only) is checked
/// before rendering: its folder must exist and an existing file is only replaced
/// with `--force` (written to a temporary file and renamed, never left half-written).
#[derive(Args, Debug)]
#[command(after_help = AFTER_HELP, allow_negative_numbers = true)]
pub struct RenderArgs {
    /// The volume to render (default: a built-in generated scene): a .vol file, or a
    /// NRRD (.nrrd/.nhdr), NIfTI-1 (.nii/.nii.gz) or MetaImage (.mha/.mhd) file or a
    /// DICOM series folder,
    /// converted in memory when its samples take at most 1 GiB (larger ones:
    /// convert with `volgen convert` first).
    file: Option<PathBuf>,

    /// Render a session (TOML, saved by the viewer's "Save session"): its volume,
    /// image size, camera, transfer function, mode and settings, crop box and
    /// clipping planes, level and two-level scene, pixel for pixel as the viewer
    /// showed it. Flags that describe the picture are refused with it; `--size`
    /// overrides the session's image size (the same view at another resolution);
    /// output, renderer and statistics flags apply as usual.
    #[arg(long, value_name = "S.toml", conflicts_with_all = SESSION_CONFLICTS)]
    session: Option<PathBuf>,

    /// Output PNG (the name must end in .png).
    #[arg(short, long, default_value = "render.png", value_name = "PNG")]
    pub(crate) output: PathBuf,

    /// Replace the output image if it exists.
    #[arg(long)]
    pub(crate) force: bool,

    /// Image size, WxH (or N for a square) [default: 512x512; with --session,
    /// the session's size].
    #[arg(long, value_parser = parse_size, value_name = "WxH")]
    size: Option<[u32; 2]>,

    /// Built-in scene rendered when no FILE is given.
    #[arg(long, value_enum, default_value_t = SceneArg::Shapes, conflicts_with = "file")]
    scene: SceneArg,

    /// Size of the built-in scene in voxels per axis.
    #[arg(long, default_value_t = raycaster::synth::DEFAULT_SCENE_SIZE, value_parser = clap::value_parser!(u32).range(2..=1024), value_name = "N", conflicts_with = "file")]
    scene_size: u32,

    /// Seed of the built-in scene.
    #[arg(long, default_value_t = 1, conflicts_with = "file", value_parser = crate::args::parse_seed)]
    seed: u64,

    /// Transfer function: a preset name or a transfer-function file. Default:
    /// the preset that suits the built-in scene; for a file, what fits its data
    /// — `shapes` for u8 data, `ct-bone` for CT, `ct-skin` for other 16-bit data
    /// and for u8 scans placed in the patient (a converted MR).
    #[arg(long, value_name = "PRESET|FILE")]
    tf: Option<String>,

    /// Values the transfer function spans, LO,HI (or LO:HI) in the file's units
    /// (Hounsfield units for CT: `--domain -1000,2000`), or a named CT window:
    /// ct, bone, soft-tissue, lung, brain. Default: what fits the data — the
    /// whole range of u8 data, −1000..2000 HU for CT, the 0.5th to 99.5th
    /// percentile of other 16-bit data and of u8 scans placed in the patient. Files converted before value units were
    /// kept take stored sample values. A domain outside the data's values gets a
    /// warning.
    #[arg(long, value_parser = parse_window, allow_hyphen_values = true, value_name = "LO,HI|NAME")]
    domain: Option<WindowArg>,

    /// Compositing mode.
    #[arg(long, value_enum, default_value_t = ModeArg::Dvr)]
    mode: ModeArg,

    /// Iso-value of first-hit mode: a value in the file's units (HU for CT:
    /// `--iso 300` for bone) or a percentage of the transfer function's domain
    /// (`--iso 45%`). Refused with other modes, which do not use it.
    #[arg(long, default_value = "50%", value_parser = parse_iso, allow_hyphen_values = true, value_name = "V|P%")]
    iso: IsoArg,

    /// Sabella mode: which depth sets the saturation — `peak` (where the ray
    /// meets its largest value) or `centroid` (the value-weighted mean depth).
    /// Hue comes from the peak value (blue low, red high), value from the
    /// intensity accumulated with the transfer function's opacities. Refused
    /// with other modes.
    #[arg(long, value_enum, default_value_t = SabellaDepthArg::Peak, value_name = "DEPTH")]
    sabella_depth: SabellaDepthArg,

    /// Crop box: show only X0..X1 × Y0..Y1 × Z0..Z1. Each coordinate is in voxels
    /// (voxel centres at whole numbers, 0 to size − 1) or, with a `%` suffix, a
    /// percentage of the volume along its axis: `--crop 0%,0%,0%,100%,100%,50%`
    /// keeps the lower half in z. Samples keep their places along each ray.
    #[arg(long, value_parser = parse_crop, allow_hyphen_values = true, value_name = "X0,Y0,Z0,X1,Y1,Z1")]
    crop: Option<[Coord; 6]>,

    /// Clipping plane through the point PX,PY,PZ (voxels, or percentages with
    /// `%`) keeping the side its normal NX,NY,NZ points into:
    /// `--clip 50%,50%,50%,0,0,-1` keeps the lower half in z. Repeatable, at
    /// most 6 planes; with --crop, the part inside the box and every plane shows.
    #[arg(long, value_parser = parse_clip, allow_hyphen_values = true, value_name = "PX,PY,PZ,NX,NY,NZ")]
    clip: Vec<ClipArg>,

    /// Gain of xray mode: opacity 1 − exp(−gain·Σ normalised value × step).
    /// Default: 8 ÷ the volume's diagonal in voxels (0.036 for 128³), so that
    /// the densest rays reach about 86 % at every volume size. Refused with
    /// other modes.
    #[arg(long, value_parser = parse_positive, value_name = "G")]
    xray_gain: Option<f32>,

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

    /// Pre-integrated transfer tables (DVR, plain and two-level DVR objects; 1D
    /// transfer functions): each step composites the segment between two samples,
    /// halved where the field bends, so coarse steps (1 voxel) look like fine
    /// ones. Runs on the scalar kernel: a step of 1 takes about twice the time
    /// of a plain step of 0.25 with `--simd avx2` (docs/benchmarks.md §6).
    #[arg(long)]
    preintegrate: bool,

    /// Per-pixel ray-start jitter (deterministic noise of up to a step): fine
    /// noise instead of stripe and ring moiré at coarse steps.
    #[arg(long)]
    jitter: bool,

    /// Disable Blinn-Phong shading.
    #[arg(long)]
    no_shading: bool,

    /// Light direction x,y,z (world; the light shines along it). Default: a headlight.
    #[arg(long, value_parser = parse_direction, allow_hyphen_values = true, value_name = "X,Y,Z")]
    light: Option<[f32; 3]>,

    /// Background colour: #rrggbb, r,g,b, black, white or grey.
    #[arg(long, default_value = "black", value_parser = parse_color, value_name = "COLOUR")]
    background: [f32; 3],

    /// Camera azimuth about the vertical, degrees: the volume's z axis, or for a file
    /// placed in the patient (an orientation from NIfTI, NRRD, MetaImage or DICOM)
    /// the patient's superior direction, with 0 looking from the patient's left and
    /// −90 from the front (see --volume-axes).
    #[arg(long, default_value_t = -60.0, allow_negative_numbers = true, value_parser = parse_finite, value_name = "DEG")]
    azimuth: f32,

    /// Camera elevation above the volume's middle, degrees, −90 (from below)
    /// to 90 (from above).
    #[arg(
        long,
        default_value_t = 25.0,
        allow_negative_numbers = true,
        value_parser = parse_elevation,
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
    #[arg(long, default_value_t = 40.0, value_parser = parse_fov, value_name = "DEG")]
    fov: f32,

    /// Orthographic instead of perspective projection.
    #[arg(long)]
    orthographic: bool,

    /// Camera position x,y,z in world units (overrides azimuth/elevation/distance).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    position: Option<[f32; 3]>,

    /// Point the camera looks at (default: the volume's centre).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    target: Option<[f32; 3]>,

    /// Camera up vector (world; with --position or instead of the vertical).
    #[arg(long, default_value = "0,0,1", value_parser = parse_direction, allow_hyphen_values = true, value_name = "X,Y,Z")]
    up: [f32; 3],

    /// Measure --azimuth and --elevation about the file's voxel axes with +z up,
    /// even when the file says where the volume lies in the patient (by default
    /// such a file is shown in patient directions: superior up, mirrored where its
    /// axes are a mirror image of the patient's).
    #[arg(long)]
    volume_axes: bool,

    /// Render threads of the object-parallel renderer (default: one per core);
    /// `--sequential` uses the single-threaded reference renderer instead.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=raycaster::render::MAX_THREADS as i64), value_name = "N")]
    threads: Option<u32>,

    /// Compositing threads of the parallel renderer.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64), value_name = "N")]
    compositors: u32,

    /// Tile side of the parallel renderer, pixels.
    #[arg(long, default_value_t = raycaster::render::DEFAULT_TILE_SIZE, value_parser = clap::value_parser!(u32).range(1..=4096), value_name = "PX")]
    tile: u32,

    /// Render with the sequential reference renderer (one thread, image order;
    /// with `--simd scalar` the oracle every faster path is compared with).
    #[arg(long, conflicts_with_all = ["threads", "compositors", "tile"])]
    sequential: bool,

    /// Marching kernel: `scalar` (one sample at a time: the reference), or
    /// several samples of a ray at a time in SIMD lanes, compiled for
    /// `sse4.1`, `avx2`, `avx512` (x86-64) or `neon` (aarch64), which composite
    /// the same image. They serve DVR with a 1D, not pre-integrated transfer
    /// function (with hardware gathers on `avx2` and `avx512`), and on `avx2`
    /// and `avx512` DVR with a 2D function, the `mip`, `average`, `xray`,
    /// `first-hit`, `sabella`, `importance`, `context` and `silhouette` modes
    /// and two-level scenes (`--segments`); other frames (pre-integrated
    /// DVR) use the scalar kernel. `auto`:
    /// `avx2` where the CPU has it (DVR unshaded 1.6–2.3×, shaded 1.2–1.6× the
    /// scalar kernel's speed; docs/benchmarks.md), else `scalar`; with
    /// `--sequential`, `auto` is `scalar` (a packet of one ray per brick visit
    /// is slower there) and a named level is used.
    #[arg(long, default_value = "auto", value_parser = parse_simd, value_name = "LEVEL")]
    simd: SimdChoice,

    /// Brick side: logical bricks of linear volumes (default 16; 31 above about
    /// 800³ voxels, where fewer bricks render faster), or sub-bricks of a bricked
    /// file whose step divides the file's (default: the file's bricks).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=1024), value_name = "N")]
    brick: Option<u32>,

    /// Read the file into RAM instead of mapping it.
    #[arg(long)]
    ram: bool,

    /// Resolution level of the file's pyramid to sample: `auto` (the coarsest
    /// whose voxels project to at most a pixel along every axis; a deep perspective view samples
    /// each band of depths at its own level, finer near the camera) or a level
    /// number (0 = full resolution, 1 = half on every axis, ...). Files without
    /// a pyramid (`volgen pyramid FILE` adds one) always render level 0.
    #[arg(long, default_value = "auto", value_parser = |s: &str| s.parse::<LevelChoice>(), value_name = "auto|N")]
    level: LevelChoice,

    /// Shifts the automatic level choice by this many levels (1: one coarser,
    /// -1: one finer).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_parser = parse_finite,
        value_name = "LEVELS"
    )]
    lod_bias: f32,

    /// Two-level rendering of a segmented volume: a scene description (TOML) of
    /// value layers or a label volume, with each object's transfer function and
    /// local mode (see volumes/scenes/). The scene sets the modes and transfer
    /// functions: --mode, --tf, --iso, --xray-gain and --sabella-depth are
    /// refused with it; --domain sets the values its layers span.
    #[arg(long, value_name = "SCENE.toml")]
    segments: Option<PathBuf>,

    /// Label volume for a label scene (overrides the scene's `labels`).
    #[arg(long, value_name = "FILE", requires = "segments")]
    labels: Option<PathBuf>,

    /// Render as one rank of an MPI job: `mpirun -np N raycaster render FILE
    /// --distributed -o out.png`. Each rank renders one part of the volume and
    /// hands unfinished pixels to the rank behind it; rank 0 writes the image
    /// (docs/distributed.md). Needs a raycaster built with `--features mpi`.
    #[arg(long, conflicts_with = "sequential")]
    pub(crate) distributed: bool,

    /// Bands of tile rows a distributed frame is pipelined in (default: four
    /// per rank).
    #[arg(long, requires = "distributed", value_parser = clap::value_parser!(u32).range(1..=65536), value_name = "N")]
    pub(crate) bands: Option<u32>,

    /// How a distributed frame's parts become one image: `relay` (pixel states
    /// handed on front to back: exact for every mode, early ray termination
    /// global) or `direct-send` (partial images composited with "over" by strip
    /// owners: plain DVR without pre-integration only, one level per frame,
    /// early ray termination per part; for comparison).
    #[arg(long, value_enum, default_value_t = CompositingArg::Relay, requires = "distributed")]
    pub(crate) compositing: CompositingArg,

    /// Print the frame's counters (with --distributed: per rank too).
    #[arg(long)]
    pub(crate) stats: bool,

    /// Print the frame's counters as one JSON object on stdout.
    #[arg(long)]
    pub(crate) stats_json: bool,

    /// No message on success.
    #[arg(short, long)]
    pub(crate) quiet: bool,

    /// Show progress (reading a scan, rendering the frame) on stderr from the start,
    /// even when it is not a terminal (on a terminal, steps longer than a second
    /// show it anyway, unless --quiet).
    #[arg(long)]
    progress: bool,
}

/// The flags that describe the picture, which a session describes instead.
const SESSION_CONFLICTS: [&str; 35] = [
    "file",
    "scene",
    "scene_size",
    "seed",
    "tf",
    "domain",
    "mode",
    "iso",
    "sabella_depth",
    "crop",
    "clip",
    "xray_gain",
    "step",
    "no_ert",
    "ert_threshold",
    "no_ess",
    "preintegrate",
    "jitter",
    "no_shading",
    "light",
    "background",
    "azimuth",
    "elevation",
    "distance",
    "zoom",
    "fov",
    "orthographic",
    "position",
    "target",
    "up",
    "volume_axes",
    "level",
    "lod_bias",
    "segments",
    "labels",
];

/// The image size without `--size`.
const DEFAULT_SIZE: [u32; 2] = [512, 512];

const AFTER_HELP: &str = "Transfer-function presets: shapes, ct-bone, ct-skin, shells, cloud, opaque, grayscale, rainbow.
A transfer-function file holds lines `point VALUE R G B ALPHA` (all 0..1), optional
`domain LO HI` (raw values) and `gradient G0 G1` (2D: opacity × smoothstep of |∇f|).

Examples:
  raycaster render -o shapes.png
  raycaster render lung1.vol --tf ct-bone --domain -1000,2000 --size 800x800 --stats
  raycaster render lung1.vol --mode mip --azimuth 0 --elevation 0 -o mip.png --force
  raycaster render ch2.nii.gz --tf ct-skin -o head.png   # NRRD, NIfTI, MetaImage open directly
  raycaster render lung1.vol --crop 0%,0%,0%,100%,50%,100% -o half.png   # y up to the middle
  raycaster render lung1.vol --clip 50%,50%,50%,1,1,0 --clip 0,0,40%,0,0,1 -o cut.png
  raycaster render shapes.vol --mode sabella --sabella-depth centroid -o sabella.png
  raycaster render --session view.toml -o view.png   # what the viewer showed (Save session)
  raycaster render --session view.toml --size 2048x1536 -o poster.png

With --session, the session file describes the picture: FILE, --scene, --tf, --mode,
the camera, crop and clip, step and shading flags are refused with it; --size,
-o/--force, --threads, --tile, --sequential, --simd, --brick, --ram, --stats and
--progress apply.";

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

/// `--compositing`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum CompositingArg {
    /// Pixel states handed on front to back.
    Relay,
    /// Partial images composited by strip owners.
    DirectSend,
}

impl From<CompositingArg> for raycaster::render::Compositing {
    fn from(c: CompositingArg) -> Self {
        match c {
            CompositingArg::Relay => raycaster::render::Compositing::Relay,
            CompositingArg::DirectSend => raycaster::render::Compositing::DirectSend,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(crate) enum ModeArg {
    /// Direct volume rendering (emission-absorption, front to back).
    Dvr,
    /// Maximum intensity projection.
    Mip,
    /// Average intensity projection: the mean value along the ray, classified.
    /// The means of a mostly empty volume are low, and so the image dark: a
    /// transfer function or domain over the means' range brightens it;
    /// render warns of a dark average picture and names the domain that spans
    /// the means.
    Average,
    /// First hit of the iso-value, refined between samples, shaded.
    FirstHit,
    /// X-ray: the sum of values along the ray, scaled by a gain (render's
    /// `--xray-gain`).
    Xray,
    /// Importance-aware compositing. On its own its importance is constant and
    /// the image is DVR's; it differs in two-level scenes (`--segments`), whose
    /// objects give their importance sources.
    Importance,
    /// Context-preserving rendering (κt 1.5, κs 0.4).
    Context,
    /// Tone shading and silhouette darkening.
    Silhouette,
    /// Sabella's colouring (1988): hue from the peak value along the ray,
    /// saturation from its depth (render's `--sabella-depth`), value from
    /// the accumulated intensity.
    Sabella,
}

/// `--sabella-depth`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum SabellaDepthArg {
    /// The depth of the peak value.
    Peak,
    /// The value-weighted mean depth.
    Centroid,
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
            ModeArg::Sabella => Mode::Sabella,
        }
    }
}

/// The files the command reads (the image must be none of them): FILE's
/// ([`raycaster::import::volume_files`]: a foreign header's data file too)
/// and those the other flags name (a `--tf` that is a file, not a preset).
pub(crate) fn input_paths(args: &RenderArgs) -> Vec<PathBuf> {
    let volume = args
        .file
        .iter()
        .flat_map(|f| raycaster::import::volume_files(f));
    let named = [&args.session, &args.segments, &args.labels]
        .into_iter()
        .flatten()
        .cloned();
    let tf = args.tf.as_ref().map(PathBuf::from).filter(|p| p.is_file());
    volume.chain(named).chain(tf).collect()
}

/// Runs the render command.
pub fn run(args: RenderArgs) -> Result<()> {
    if args.distributed {
        return crate::distributed::run(args);
    }
    crate::output::check_output_of(&args.output, args.force, input_paths(&args))?;
    // A built-in scene is made in parallel: the pool first. Otherwise after
    // the memory checks, which its threads' address space would tighten.
    if args.file.is_none() && args.session.is_none() {
        crate::threads::start_worker_pool()?;
    }
    let setup = Setup::new(&args)?;
    crate::memory::check_frame(setup.camera.width(), setup.camera.height())?;
    crate::threads::start_worker_pool()?;
    let prepared = setup.prepared_bands(&args)?;
    let passes: Vec<(&RenderVolume<'_>, Option<DepthBand>)> = prepared
        .iter()
        .zip(&setup.bands)
        .map(|(volume, band)| (volume, band.depth))
        .collect();
    let frame = if args.sequential {
        let progress = PixelProgress::new();
        with_progress_line(
            "rendering",
            progress_after(&args),
            || progress.fraction(),
            || render_sequential_noting(&passes, &setup.camera, &setup.settings, &progress),
        )?
    } else {
        let options = parallel_options(&args, 1);
        // The frame's threads and the read-ahead's.
        crate::threads::check_threads(options.render_threads + options.compositing_threads + 1)?;
        render_with_progress(
            &passes,
            &setup.camera,
            &setup.settings,
            &options,
            progress_after(&args),
        )?
    };
    // Planes (and a crop box) that together keep nothing, where no single
    // plane does (that one is said before rendering). (A frame without rays
    // may also be one whose transfer function shows nothing: no brick is
    // marched, and no ray made.)
    let clip = &setup.settings.clip;
    let sampled = setup.volume.sampled_box();
    if frame.stats.counters.rays == 0
        && !clip.is_empty()
        && clip.plane_keeping_nothing(sampled).is_none()
        && clip.keeps_nothing_of(sampled)
        && !args.quiet
    {
        eprintln!(
            "warning: the crop box and clipping planes together keep nothing of {}: the picture is background (each plane keeps the side its normal points into)",
            setup.volume.path().display()
        );
    }
    let image = frame.to_image();
    warn_of_dark_average(&args, &setup, &image)?;
    finish(&args, &setup, &frame, &image, serde_json::Map::new())
}

/// The warning for `--preintegrate` with a mode that ignores it (`render` and
/// `bench` alike), or `None`.
pub(crate) fn preintegrate_ignored(preintegrate: bool, mode: ModeArg) -> Option<String> {
    (preintegrate && mode != ModeArg::Dvr).then(|| {
        format!(
            "warning: --preintegrate applies to --mode dvr only; {} frames ignore it",
            Mode::from(mode).name()
        )
    })
}

/// The parallel renderer's options from the flags; without `--threads`, the
/// cores shared by `processes` processes on this machine.
pub(crate) fn parallel_options(args: &RenderArgs, processes: usize) -> ParallelOptions {
    let mut options = ParallelOptions {
        compositing_threads: args.compositors as usize,
        tile_size: args.tile,
        ..ParallelOptions::default()
    };
    options.render_threads = match args.threads {
        Some(n) => n as usize,
        None => (options.render_threads / processes.max(1)).max(1),
    };
    options
}

/// Everything a frame needs besides the renderer: the opened volume (and label
/// volume), the settings, the camera and the pyramid level.
pub(crate) struct Setup {
    pub volume: Volume,
    pub labels: Option<Volume>,
    pub settings: RenderSettings,
    pub camera: Camera,
    /// The level a frame of one level samples (the nearest band's).
    pub level: usize,
    /// The levels the frame samples, nearest first, each in its band of depths
    /// (one for a fixed level, an orthographic view, a two-level scene).
    pub bands: Vec<LevelBand>,
    /// Bytes this process had read before opening anything.
    read_before: u64,
}

impl Setup {
    /// Opens the volume and labels and resolves the settings, camera and level:
    /// from `--session`, or from the flags (which become a session first, so both
    /// make a frame the same way).
    pub(crate) fn new(args: &RenderArgs) -> Result<Setup> {
        let read_before = raycaster::io::process_bytes_read();
        let (volume, session) = match &args.session {
            Some(path) => {
                let mut session = Session::load(path)?;
                if let Some(size) = args.size {
                    session.size = size;
                }
                if let Some(problem) = session.image_size_problem() {
                    bail!(
                        "{}: {problem} (--size WxH renders the session at another size)",
                        path.display()
                    );
                }
                // The kernel does not change the picture: a session leaves it to the flag.
                session.settings.simd = args.simd.0;
                let volume = open_volume(&session.source, args)
                    .with_context(|| format!("{}: the session's `volume`", path.display()))?;
                if let Err(e) = session.check_cuts(volume.sampled_box()) {
                    bail!("{}: {e}", path.display());
                }
                if let Some(warning) = session.settings.transfer.domain.and_then(|[a, b]| {
                    let said = format!("{}: `[transfer] domain = [{a}, {b}]`", path.display());
                    stored_domain_warning(&said, [a, b], &volume, None)
                }) && !args.quiet
                {
                    eprintln!("{warning}");
                }
                if let (Some(warning), LevelChoice::Fixed(k)) =
                    (level_warning(session.level, &volume), session.level)
                    && !args.quiet
                {
                    eprintln!("warning: {}: `level = {k}`: {warning}", path.display());
                }
                if let Some(warning) = raycaster::render::step_past_volume(
                    session.settings.step,
                    volume.diagonal_voxels(),
                ) && !args.quiet
                {
                    eprintln!("warning: {}: `step`: {warning}", path.display());
                }
                (volume, session)
            }
            None => {
                let source = flags_source(args);
                let volume = open_volume(&source, args)?;
                let session = flags_session(args, source, &volume)?;
                (volume, session)
            }
        };
        // A scene file's object cut away whole is refused at full resolution,
        // as a session's is (at a coarse level its margin let some pass).
        if args.session.is_none()
            && let Some(scene) = &session.settings.segments
            && let Err(e) = scene.check_cuts(volume.sampled_box(), 1.0)
        {
            match &args.segments {
                Some(file) => bail!("{}: {e}", file.display()),
                None => bail!("{e}"),
            }
        }
        if let Some(plane) = session
            .settings
            .clip
            .plane_keeping_nothing(volume.sampled_box())
            && !args.quiet
        {
            eprintln!(
                "warning: the clipping plane through {} with normal {} keeps nothing of {}: the picture is background (a plane keeps the side its normal points into)",
                plane.point,
                plane.normal,
                volume.path().display()
            );
        }
        // How the user names another label volume: a flag, or the session's field.
        let advice = if args.session.is_some() {
            LabelsAdvice {
                other: "a session's `volume.labels` names another",
                use_it: "name the data volume in the session's `volume.file` and this one in `volume.labels` (with a `[scene]`)",
            }
        } else {
            LabelsAdvice {
                other: "--labels FILE names another",
                use_it: "render the data volume and give this file with --labels (and a --segments SCENE.toml)",
            }
        };
        if let Some(warning) = raycaster::render::flat_volume(volume.dims(), &session.settings)
            && !args.quiet
        {
            eprintln!("warning: {}: {warning}", volume.path().display());
        }
        let setup = Setup::from_session(volume, session, read_before, &advice)?;
        if let Some(scene) = &setup.settings.segments
            && !args.quiet
        {
            for warning in scene.warnings(setup.labels.as_ref()) {
                eprintln!("warning: {warning}");
            }
        }
        Ok(setup)
    }

    /// The frame a session describes, its volume opened; `advice` says how to
    /// name label volumes (where the scene's does not open, or one is given as
    /// the data).
    fn from_session(
        volume: Volume,
        session: Session,
        read_before: u64,
        advice: &LabelsAdvice,
    ) -> Result<Setup> {
        if volume.content() == Content::Labels {
            // (From a session it named flags a session cannot take.)
            bail!(
                "{}: is a label volume (object ids, not values); {}",
                volume.path().display(),
                advice.use_it
            );
        }
        if let (Some(path), Some(problem)) = (&session.labels, session.labels_problem()) {
            bail!("{}: {problem}", path.display());
        }
        let labels = match (&session.settings.segments, &session.labels) {
            (Some(_), Some(path)) => Some(open_labels(path)?),
            (Some(scene), None) => match (&scene.membership, &session.source) {
                // A built-in scene brings its own segmentation, when it has one.
                (Membership::Labels(_), VolumeSource::BuiltIn { kind, size, seed }) => {
                    Some(built_in_labels(*kind, *size, *seed)?)
                }
                (Membership::Labels(path), VolumeSource::File { .. }) => {
                    Some(open_labels(path).with_context(|| {
                        format!(
                            "the scene's label volume (its `labels =`, read beside the scene file; {})", advice.other
                        )
                    })?)
                }
                (Membership::Layers(_), _) => None,
            },
            (None, _) => None,
        };
        // (Said here in the files' own sizes; the renderer compares the
        // pyramid levels it samples.)
        if let Some(labels) = &labels
            && labels.dims() != volume.dims()
        {
            let [x, y, z] = labels.dims();
            let [vx, vy, vz] = volume.dims();
            bail!(
                "{}: the labels are {x}x{y}x{z} voxels and the volume {vx}x{vy}x{vz}: a label volume labels the voxels of its volume, one for one",
                labels.path().display()
            );
        }
        let camera = session.camera().context("invalid camera")?;
        // Two-level scenes sample one level, and with labels the labels of the
        // same level, when they have it.
        let levels = labels.as_ref().map_or(volume.level_count(), |l| {
            volume.level_count().min(l.level_count())
        });
        let bands = session
            .level
            .frame_bands(&volume, &camera, &session.settings, levels);
        Ok(Setup {
            volume,
            labels,
            settings: session.settings,
            camera,
            level: bands[0].level,
            bands,
            read_before,
        })
    }

    /// The volume's levels of [`Self::bands`], nearest first, prepared for
    /// rendering with `--brick` (preparing reads nothing).
    pub(crate) fn prepared_bands(&self, args: &RenderArgs) -> Result<Vec<RenderVolume<'_>>> {
        let mut levels = vec![self.prepared(args)?];
        for band in &self.bands[1..] {
            levels.push(RenderVolume::new(
                self.volume.level(band.level),
                args.brick,
            )?);
        }
        Ok(levels)
    }

    /// The volume's level prepared for rendering with `--brick`, labels attached.
    pub(crate) fn prepared(&self, args: &RenderArgs) -> Result<RenderVolume<'_>> {
        let mut prepared = RenderVolume::new(self.volume.level(self.level), args.brick)?;
        if let Some(labels) = &self.labels {
            prepared = prepared.with_labels(labels.level(self.level))?;
        }
        Ok(prepared)
    }
}

/// Writes `image` (the frame's) and prints the statistics and the closing
/// line; `extra` fields join the `--stats-json` object.
pub(crate) fn finish(
    args: &RenderArgs,
    setup: &Setup,
    frame: &raycaster::render::Frame,
    image: &raycaster::render::RgbImage,
    extra: serde_json::Map<String, serde_json::Value>,
) -> Result<()> {
    image.save_png(&args.output)?;
    let bytes_read = raycaster::io::process_bytes_read().saturating_sub(setup.read_before);
    if args.stats {
        eprint!("{}", stats::table(&frame.stats));
        eprint!(
            "{}",
            stats::level_table(&setup.volume, &setup.bands, bytes_read)
        );
    }
    if args.stats_json {
        let mut json = stats::json(
            &frame.stats,
            &setup.volume,
            &setup.settings,
            &setup.bands,
            bytes_read,
        );
        if let Some(object) = json.as_object_mut() {
            object.extend(extra);
        }
        println!("{json}");
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

/// Warns of a dark average frame `image` on the default domain, saying which
/// domain shows it (a transfer-function file's own domain, `--domain` or a
/// session's was the user's choice); `render` and `render --distributed` alike.
pub(crate) fn warn_of_dark_average(
    args: &RenderArgs,
    setup: &Setup,
    image: &raycaster::render::RgbImage,
) -> Result<()> {
    let own_domain = args
        .tf
        .as_ref()
        .is_some_and(|tf| TransferFunction::names_a_file(tf, Path::new("")));
    if setup.settings.mode == Mode::Average
        && args.domain.is_none()
        && !own_domain
        && args.session.is_none()
        && !args.quiet
        && let Some(dark) =
            raycaster::render::dark_average(&setup.volume, &setup.settings, &setup.camera, image)?
    {
        eprintln!("{}", dark_average_warning(&setup.volume, &dark));
    }
    Ok(())
}

/// The warning for a dark average frame: where its rays' means lie, and the
/// `--domain` that spans them.
fn dark_average_warning(volume: &Volume, dark: &raycaster::render::DarkAverage) -> String {
    let units = volume.value_units();
    let [lo, hi] = dark.domain.map(|v| units.format(v));
    // As --domain takes them: numbers without the unit.
    let [a, b] = dark.spanning.map(raycaster::volume::number_text);
    format!(
        "warning: --mode average: the picture is dark: the means along the rays lie in the lowest {:.0} % of the transfer function's domain, {lo} to {hi}; --domain {a},{b} spans them",
        dark.share * 100.0
    )
}

/// Opens a label volume, checking that it holds labels.
fn open_labels(path: &Path) -> Result<Volume> {
    Ok(raycaster::source::open_labels(path)?)
}

/// Where the flags say the volume comes from.
fn flags_source(args: &RenderArgs) -> VolumeSource {
    match &args.file {
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
    }
}

impl RenderArgs {
    /// Flags that do not go together in a way clap cannot see (they depend on
    /// a value): a command-line error (exit status 2), as a session refuses
    /// the same.
    ///
    /// `given` are the render command's matches: a flag given on the command
    /// line that the frame would not use is refused, not ignored (a mode's
    /// parameter with another mode; what a two-level scene's file sets).
    pub(crate) fn conflict(&self, given: &clap::ArgMatches) -> Option<String> {
        if let LevelChoice::Fixed(k) = self.level
            && self.lod_bias != 0.0
        {
            return Some(format!(
                "--lod-bias shifts the automatic level only; it takes --level auto, not --level {k}"
            ));
        }
        let on_line =
            |id: &str| given.value_source(id) == Some(clap::parser::ValueSource::CommandLine);
        if self.segments.is_some() {
            let set_by_scene = [
                ("mode", "--mode", "its global and local modes"),
                ("tf", "--tf", "each object's transfer function"),
                ("iso", "--iso", "each first-hit object's iso-value"),
                ("xray_gain", "--xray-gain", "each x-ray object's gain"),
                ("sabella_depth", "--sabella-depth", "its modes"),
            ];
            if let Some((_, flag, what)) = set_by_scene.iter().find(|(id, ..)| on_line(id)) {
                return Some(format!(
                    "{flag} is not used with --segments: the scene file sets {what} (--domain \
                     sets the values its layers and objects without a domain span)"
                ));
            }
            return None;
        }
        let mode = Mode::from(self.mode).name();
        let parameters = [
            ("iso", "--iso", ModeArg::FirstHit, "first-hit"),
            ("xray_gain", "--xray-gain", ModeArg::Xray, "xray"),
            (
                "sabella_depth",
                "--sabella-depth",
                ModeArg::Sabella,
                "sabella",
            ),
        ];
        parameters
            .iter()
            .find(|(id, _, of, _)| on_line(id) && self.mode != *of)
            .map(|(_, flag, _, of)| {
                format!("{flag} is a parameter of --mode {of}; a {mode} frame does not use it")
            })
    }
}

/// What to say of a fixed `level` past `volume`'s coarsest (it renders the
/// coarsest).
fn level_warning(level: LevelChoice, volume: &Volume) -> Option<String> {
    level.past_coarsest(volume).map(|coarsest| {
        format!("the volume's coarsest level is {coarsest}; rendering level {coarsest}")
    })
}

/// What an error about label volumes advises, in the words of where the
/// volumes were named (flags or a session).
struct LabelsAdvice {
    /// How another label volume is named.
    other: &'static str,
    /// How a label volume given as the data is used instead.
    use_it: &'static str,
}

/// The session the flags describe, for the opened `volume` (its type chooses
/// the default transfer function, its size resolves percentages, its box the
/// framing).
fn flags_session(args: &RenderArgs, source: VolumeSource, volume: &Volume) -> Result<Session> {
    let size = args.size.unwrap_or(DEFAULT_SIZE);
    let level = match args.level {
        LevelChoice::Auto { .. } => LevelChoice::Auto {
            bias: args.lod_bias,
        },
        LevelChoice::Fixed(k) => {
            if let Some(warning) = level_warning(args.level, volume).filter(|_| !args.quiet) {
                eprintln!("warning: --level {k}: {warning}");
            }
            LevelChoice::Fixed(k)
        }
    };
    // (Counted at the level rendered: a fixed one, or level 0 when there is
    // no other; an automatic level of a pyramid is chosen per frame, mostly
    // coarser, and not checked.)
    let checked_dims = match args.level {
        LevelChoice::Fixed(k) => Some(
            volume
                .level(k.min(volume.level_count() as u32 - 1) as usize)
                .dims(),
        ),
        LevelChoice::Auto { .. } => (volume.level_count() == 1).then(|| volume.dims()),
    };
    if let (Some(side), Some(dims)) = (args.brick, checked_dims) {
        let count = raycaster::volume::BlockGrid::new(dims, side).block_count();
        crate::memory::check_bricks("--brick", count, side)?;
    }
    if let Some(warning) = args
        .brick
        .and_then(|side| brick_count_warning(volume.dims(), side))
        .filter(|_| !args.quiet)
    {
        eprintln!("{warning}");
    }
    if let Some(warning) = raycaster::render::step_past_volume(args.step, volume.diagonal_voxels())
        .filter(|_| !args.quiet)
    {
        eprintln!("warning: --step: {warning}");
    }
    // (In a two-level scene it applies to the objects rendered by DVR.)
    if let Some(warning) = preintegrate_ignored(args.preintegrate, args.mode)
        .filter(|_| args.segments.is_none() && !args.quiet)
    {
        eprintln!("{warning}");
    }
    Ok(Session {
        source,
        labels: args.labels.clone(),
        size,
        camera: camera(
            args,
            source::world_box(volume),
            if args.volume_axes {
                Mat3::IDENTITY
            } else {
                patient_axes(volume.orientation())
            },
        )?,
        settings: settings(args, volume)?,
        level,
        slices: None,
    })
}

fn open_volume(source: &VolumeSource, args: &RenderArgs) -> Result<Volume> {
    if let VolumeSource::File { path, .. } = source {
        raycaster::files::guard_mapped_file(path);
    }
    match source {
        VolumeSource::File { path, .. } if raycaster::import::detect(path).is_some() => {
            // Decompressing a large scan takes seconds: progress as for frames.
            let limit = raycaster::import::DEFAULT_IN_MEMORY_LIMIT;
            let imported = raycaster::import::open(path)?;
            let done = AtomicU64::new(0);
            let on_progress = |n| {
                done.fetch_add(n, Ordering::Relaxed);
            };
            let job = raycaster::job::Job::silent().with_progress(&on_progress);
            let label = format!("reading {}", path.display());
            let total = imported.sample_bytes();
            let share = || share_done(&done, total);
            let volume = with_progress_line(&label, progress_after(args), share, || {
                imported.to_volume_noting(limit, &job)
            })?;
            let (volume, warning) = volume;
            if let Some(warning) = warning.filter(|_| !args.quiet) {
                eprintln!("warning: {warning}");
            }
            Ok(volume)
        }
        VolumeSource::File { path, .. } => {
            let access = if args.ram {
                if let Ok(meta) = std::fs::metadata(path) {
                    crate::memory::check_ram(path.display(), meta.len())?;
                }
                Access::Ram
            } else {
                Access::Mapped
            };
            let options = OpenOptions {
                access,
                ..OpenOptions::default()
            };
            let volume = Volume::open_with(path, options).map_err(|e| {
                // A session or scene given as the volume: say which flag takes it.
                if raycaster::files::is_toml_name(path) && path.is_file() {
                    anyhow::anyhow!(
                        "{}: is a TOML file, not a volume: --session FILE renders a saved session, --segments FILE a two-level scene",
                        path.display()
                    )
                } else {
                    e.into()
                }
            })?;
            if !args.quiet {
                for warning in volume.open_warnings() {
                    eprintln!("{warning}");
                }
            }
            Ok(volume)
        }
        VolumeSource::BuiltIn { kind, size, seed } => {
            let n = *size;
            let scene = kind.build([n; 3], *seed);
            let name = format!("built-in {} scene {n}³", kind.name());
            Ok(synthesize(
                scene.as_ref(),
                &name,
                [n; 3],
                [1.0; 3],
                SampleType::U8,
            )?)
        }
    }
}

/// The label volume of the built-in scene, for label scenes rendered without a file.
fn built_in_labels(kind: SceneKind, n: u32, seed: u64) -> Result<Volume> {
    let scene = kind.build([n; 3], seed);
    let name = format!("built-in {} labels {n}³", kind.name());
    synthesize_labels(scene.as_ref(), &name, [n; 3], [1.0; 3])?.with_context(|| {
        format!(
            "the built-in `{}` scene has no label volume: name one (--labels FILE, or a session's `volume.labels`) or use a scene of value layers",
            kind.name()
        )
    })
}

fn settings(args: &RenderArgs, volume: &Volume) -> Result<RenderSettings> {
    // The preset and domain that fit the data (the viewer's defaults too).
    let fit = raycaster::windows::fit(volume);
    let tf_name = match (&args.tf, &args.file) {
        (Some(tf), _) => tf.clone(),
        (None, None) => source::scene_preset(args.scene.kind()).to_string(),
        (None, Some(_)) => fit.preset.to_string(),
    };
    let tf_path = Path::new(&tf_name);
    let names_a_file = TransferFunction::names_a_file(&tf_name, Path::new(""));
    let mut transfer = if names_a_file && tf_path.exists() {
        // A file (or something else there, which load refuses with a reason).
        TransferFunction::load(tf_path)?
    } else if names_a_file {
        bail!(
            "--tf {tf_name}: no such transfer-function file{}",
            // `tfs/ct-bonee` or `ct-bon.tf`: the name may be a near-miss preset.
            tf_path
                .file_stem()
                .and_then(|stem| closest_preset(&stem.to_string_lossy()))
                .map(|p| format!(" (did you mean the preset {p}?)"))
                .unwrap_or_default()
        );
    } else {
        TransferFunction::preset(&tf_name).context("--tf")?
    };
    let units = volume.value_units();
    // A file's own `domain` is in stored values: say so where it misses the
    // data (a CT user writing HU in it gets an empty picture).
    if names_a_file
        && args.domain.is_none()
        && !args.quiet
        && let Some(warning) = transfer
            .domain
            .and_then(|d| file_domain_warning(&tf_name, d, volume))
    {
        eprintln!("{warning}");
    }
    if let Some(domain) = args.domain {
        let name = volume.path().display().to_string();
        let named = domain.named_on_plain_data("--domain", volume, &name);
        let warning = domain_warning(domain, volume).or(named);
        if let Some(warning) = warning.filter(|_| !args.quiet) {
            eprintln!("{warning}");
        }
        transfer.domain = Some(units.stored_range(domain.values()));
    } else if transfer.domain.is_none() {
        transfer.domain = fit.domain;
    }
    let iso_value = match args.iso {
        IsoArg::Fraction(f) => f,
        IsoArg::Value(v) => {
            let [lo, hi] = transfer
                .domain
                .unwrap_or([0.0, f32::from(volume.sample_type().max_value())]);
            let stored = units.stored(f64::from(v)) as f32;
            if !(lo..=hi).contains(&stored) {
                let [a, b] = [lo, hi].map(|s| units.format(units.value(f64::from(s))));
                bail!("--iso {v} lies outside the transfer function's domain {a} to {b}");
            }
            (stored - lo) / (hi - lo)
        }
    };
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
            sabella: SabellaOutput::Colours(SabellaMapping {
                depth: match args.sabella_depth {
                    SabellaDepthArg::Peak => SabellaDepth::Peak,
                    SabellaDepthArg::Centroid => SabellaDepth::Centroid,
                },
                ..SabellaMapping::default()
            }),
            ..ModeParameters::default()
        },
        step: args.step,
        early_termination: (!args.no_ert).then_some(args.ert_threshold),
        empty_space_skipping: !args.no_ess,
        shading,
        iso_value,
        background: args.background,
        transfer,
        segments: match &args.segments {
            Some(path) => Some(SegmentScene::load(path)?),
            None => None,
        },
        simd: args.simd.0,
        preintegrated: args.preintegrate,
        jitter: args.jitter,
        clip: clip_region(args, volume.dims())?,
    })
}

/// The crop box and clipping planes of `--crop` and `--clip` in voxels of a
/// volume of `dims`, refused with the flag's name when they make no sense.
fn clip_region(args: &RenderArgs, dims: [u32; 3]) -> Result<ClipRegion> {
    let last = dims.map(|d| d - 1);
    let crop = match args.crop {
        None => None,
        Some(c) => {
            let lo = [0, 1, 2].map(|a| c[a].voxels(last[a]));
            let hi = [0, 1, 2].map(|a| c[a + 3].voxels(last[a]));
            for (a, name) in ["x", "y", "z"].iter().enumerate() {
                if lo[a] >= hi[a] {
                    bail!(
                        "--crop: the box is empty or inverted along {name} ({name}0 = {} is not below {name}1 = {})",
                        lo[a],
                        hi[a]
                    );
                }
                if hi[a] < 0.0 || lo[a] > last[a] as f32 {
                    bail!(
                        "--crop: the box {}..{} along {name} lies outside the volume (0..{} voxels)",
                        lo[a],
                        hi[a],
                        last[a]
                    );
                }
            }
            Some(CropBox {
                lo: Vec3::from(lo),
                hi: Vec3::from(hi),
            })
        }
    };
    if args.clip.len() > MAX_CLIP_PLANES {
        bail!(
            "--clip given {} times: at most {MAX_CLIP_PLANES} clipping planes",
            args.clip.len()
        );
    }
    let mut planes = Vec::with_capacity(args.clip.len());
    for plane in &args.clip {
        if plane.normal == [0.0; 3] {
            bail!(
                "--clip: the plane's normal is zero; give the direction of the part kept, e.g. 0,0,1"
            );
        }
        planes.push(ClipPlane {
            point: Vec3::from([0, 1, 2].map(|a| plane.point[a].voxels(last[a]))),
            normal: Vec3::from(plane.normal),
        });
    }
    let region = ClipRegion { crop, planes };
    region.validate()?;
    Ok(region)
}

/// `--simd`: `auto` (`None`) or a kernel level.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SimdChoice(pub(crate) Option<SimdLevel>);

/// Parses `--simd`.
pub(crate) fn parse_simd(text: &str) -> Result<SimdChoice, String> {
    if text == "auto" {
        return Ok(SimdChoice(None));
    }
    SimdLevel::parse(text)
        .map(|l| SimdChoice(Some(l)))
        .ok_or_else(|| {
            let names: Vec<&str> = SimdLevel::ALL.iter().map(|l| l.name()).collect();
            format!("unknown kernel {text:?}: auto, {}", names.join(", "))
        })
}

/// Bricks past which a frame's per-brick work (planning, sorting, one task per
/// brick and tile) can outweigh its samples, when the bricks are small too:
/// [`brick_count_warning`].
const MANY_BRICKS: u64 = 1 << 20;

/// A warning when `--brick side` cuts a volume of `dims` into more than
/// [`MANY_BRICKS`] bricks of fewer than 8³ voxels each on average (`--brick 2`
/// on 256³: 16.6 M, minutes per frame; on 128³ 60× the time of `--brick 16`).
fn brick_count_warning(dims: [u32; 3], side: u32) -> Option<String> {
    let count = raycaster::volume::BlockGrid::new(dims, side).block_count();
    let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
    (count > MANY_BRICKS.max(voxels / 512)).then(|| {
        format!(
            "warning: --brick {side} cuts the volume into {:.1} M bricks; each frame plans every one, which takes far longer than its samples (sides of 16 to 32 render fastest)",
            count as f64 / 1e6
        )
    })
}

/// A warning when `--domain` misses the data's values entirely (the image would
/// be empty or flat); values and the data's range in the file's units, with a
/// hint when a CT scan's file has no units (converted before they were kept).
fn domain_warning(domain: WindowArg, volume: &Volume) -> Option<String> {
    let units = volume.value_units();
    let [a, b] = domain.values();
    let [lo, hi] = volume
        .ranges()
        .overall()
        .map(|s| units.value(f64::from(s)) as f32);
    if b >= lo && a <= hi {
        return None;
    }
    let hint = if units.is_identity() && volume.sample_type() == SampleType::U16 && a < 0.0 {
        " (this file keeps no value units: a CT scan converted by an older volgen stores HU + 32768; convert it again to give HU)"
    } else {
        ""
    };
    let [a, b, lo, hi] = [a, b, lo, hi].map(|v| units.format(f64::from(v)));
    Some(format!(
        "warning: --domain {a} to {b} lies outside the data's values {lo} to {hi}; the image will be empty or flat{hint}"
    ))
}

/// The warning for a transfer-function file `name` whose `domain` (stored
/// values) lies outside the data's stored values.
fn file_domain_warning(name: &str, [a, b]: [f32; 2], volume: &Volume) -> Option<String> {
    let said = format!("{name}: `domain {a} {b}`");
    stored_domain_warning(&said, [a, b], volume, Some("--domain LO,HI takes those"))
}

/// The warning for a domain in stored values, `said` as its file writes it,
/// that lies outside the data's stored values; for data with units, says the
/// data's range in them, `and` added.
fn stored_domain_warning(
    said: &str,
    [a, b]: [f32; 2],
    volume: &Volume,
    and: Option<&str>,
) -> Option<String> {
    let [lo, hi] = volume.ranges().overall().map(f32::from);
    if b >= lo && a <= hi {
        return None;
    }
    let units = volume.value_units();
    let hint = if units.is_identity() {
        String::new()
    } else {
        let [ulo, uhi] = [lo, hi].map(|v| units.format(units.value(f64::from(v))));
        let and = and.map(|a| format!(": {a}")).unwrap_or_default();
        format!(" (in the file's units the data span {ulo} to {uhi}{and})")
    };
    Some(format!(
        "warning: {said} is in stored sample values and lies outside the data's, {lo} to {hi}; the image will be empty or flat{hint}"
    ))
}

fn glam_vec(v: [f32; 3]) -> raycaster::render::Vec3 {
    raycaster::render::Vec3::from(v)
}

/// The camera the flags describe (checked for an image of the flags' size).
fn camera(
    args: &RenderArgs,
    (lo, hi): (raycaster::render::Vec3, raycaster::render::Vec3),
    axes: Mat3,
) -> Result<SessionCamera> {
    let [w, h] = args.size.unwrap_or(DEFAULT_SIZE);
    let spec = camera_spec(args, (lo, hi), axes);
    if let Err(e) = spec.camera(w, h) {
        match camera_flags_problem(args, &spec) {
            Some(problem) => bail!("{problem}"),
            None => return Err(anyhow::Error::new(e).context("invalid camera")),
        }
    }
    if let SessionCamera::LookAt {
        position,
        target,
        up,
        ..
    } = spec
        && !args.quiet
    {
        // Within a degree of the view, the picture's roll follows the small
        // difference (the camera's up is the part of --up across the view).
        let angle = (target - position).angle_between(up).to_degrees();
        let off_view = angle.min(180.0 - angle);
        if off_view < 1.0 {
            let flag = |v: Vec3| v.to_array().map(|c| c.to_string()).join(",");
            eprintln!(
                "warning: --up {} lies {off_view:.2}° from the view direction (from {} to {}): the \
                 picture's roll follows that small difference; give an --up across the view",
                flag(up),
                flag(position),
                flag(target)
            );
        }
    }
    Ok(spec)
}

/// Which camera flags make the view impossible, said with their names and a
/// way out, when the camera the flags build has no view.
fn camera_flags_problem(args: &RenderArgs, spec: &SessionCamera) -> Option<String> {
    let (position, target, up) = match spec {
        SessionCamera::LookAt {
            position,
            target,
            up,
            ..
        } => (*position, *target, *up),
        SessionCamera::Orbit(orbit) => (orbit.position(), orbit.target, orbit.axes.z_axis),
    };
    // As the flags write them: `x,y,z`.
    let flag = |v: raycaster::render::Vec3| v.to_array().map(|c| c.to_string()).join(",");
    let view = target - position;
    if !view.length_squared().is_finite() {
        return Some(match args.distance {
            Some(d) => format!(
                "--distance {}: the camera is too far away for its view to be computed; give a distance nearer the volume's size",
                raycaster::volume::number_text(d)
            ),
            None => format!(
                "the camera at {} is too far from its target {} for its view to be computed",
                flag(position),
                flag(target)
            ),
        });
    }
    Some(
        match raycaster::render::look_at_problem(position, target, up)? {
            LookAtProblem::SamePoint => format!(
                "--position {} and --target {} are the same point: the camera looks nowhere",
                flag(position),
                flag(target)
            ),
            LookAtProblem::UpNotADirection => format!("--up {}: not a direction", flag(up)),
            LookAtProblem::UpAlongView => {
                let other = if up.normalize().dot(raycaster::render::Vec3::Y).abs() > 0.9 {
                    "0,0,1"
                } else {
                    "0,1,0"
                };
                format!(
                    "the camera looks along its up direction --up {} (from {} to {}): give another --up, e.g. --up {other}",
                    flag(up),
                    flag(position),
                    flag(target)
                )
            }
        },
    )
}

fn camera_spec(
    args: &RenderArgs,
    (lo, hi): (raycaster::render::Vec3, raycaster::render::Vec3),
    axes: Mat3,
) -> SessionCamera {
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
        return SessionCamera::LookAt {
            position: glam_vec(position),
            target,
            up,
            projection,
        };
    }
    let vfov = (!args.orthographic).then_some(args.fov);
    let mut orbit = Orbit::framing(
        lo,
        hi,
        args.azimuth.to_radians(),
        args.elevation.to_radians(),
        vfov,
    )
    .with_axes(axes);
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
        return SessionCamera::LookAt {
            position,
            target,
            up,
            projection,
        };
    }
    SessionCamera::Orbit(orbit)
}

/// When progress shows: from the start with --progress, after
/// [`PROGRESS_AFTER`] on a terminal, never with --quiet or when piped.
fn progress_after(args: &RenderArgs) -> Option<Duration> {
    if args.progress {
        Some(Duration::ZERO)
    } else {
        (!args.quiet && std::io::stderr().is_terminal()).then_some(PROGRESS_AFTER)
    }
}

/// Frames longer than this show progress on a terminal.
const PROGRESS_AFTER: Duration = Duration::from_secs(1);

/// The frame being filled tile by tile, and the share of it done (as the
/// renderer counts it: scheduled tasks, level by level).
struct ProgressSink {
    frame: Mutex<raycaster::render::Frame>,
    /// The share, as `f64` bits.
    share: AtomicU64,
}

impl TileSink for ProgressSink {
    fn tile_finished(&self, rect: raycaster::render::PixelRect, rgba: &[[f32; 4]], depth: &[f32]) {
        let mut frame = self.frame.lock().unwrap_or_else(|e| e.into_inner());
        let w = (rect.x1 - rect.x0) as usize;
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            let start = frame.index(rect.x0, y);
            frame.rgba[start..start + w].copy_from_slice(&rgba[row * w..(row + 1) * w]);
            frame.depth[start..start + w].copy_from_slice(&depth[row * w..(row + 1) * w]);
        }
    }

    fn progress(&self, share: f64) {
        // (Compositing threads report in any order: keep the largest.)
        self.share.fetch_max(share.to_bits(), Ordering::Relaxed);
    }
}

/// Renders with the parallel renderer; with `show_after`, a frame that takes longer
/// than that shows the share of its pixels done on stderr.
fn render_with_progress(
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
    options: &ParallelOptions,
    show_after: Option<Duration>,
) -> Result<raycaster::render::Frame> {
    let sink = ProgressSink {
        frame: Mutex::new(raycaster::render::Frame::empty(
            camera.width(),
            camera.height(),
            settings.background,
        )),
        share: AtomicU64::new(0f64.to_bits()),
    };
    let share = || f64::from_bits(sink.share.load(Ordering::Relaxed));
    let stats = with_progress_line("rendering", show_after, share, || {
        Renderer::per_frame()
            .render_levels_into(passes, camera, settings, options, &sink, &|| false)
    })?
    .expect("a frame that cannot be cancelled completes");
    let mut frame = sink.frame.into_inner().unwrap_or_else(|e| e.into_inner());
    frame.stats = stats;
    Ok(frame)
}

/// The share of `total` the counter `done` has reached, in `[0, 1]`.
fn share_done(done: &AtomicU64, total: u64) -> f64 {
    done.load(Ordering::Relaxed).min(total) as f64 / total.max(1) as f64
}

/// A progress line is on stderr, unfinished: a message printed now (an
/// interruption) goes on a line of its own.
pub(crate) static PROGRESS_LINE_OPEN: AtomicBool = AtomicBool::new(false);

/// Runs `work`; with `show_after`, once it has run that long, shows on stderr the
/// share of it `share` says is finished (`rendering 42 % (3.1 s, about 4 s
/// left)`), cleared at the end on a terminal.
fn with_progress_line<R: Send>(
    label: &str,
    show_after: Option<Duration>,
    share: impl Fn() -> f64 + Sync,
    work: impl FnOnce() -> R + Send,
) -> R {
    let Some(after) = show_after else {
        return work();
    };
    let finished = AtomicBool::new(false);
    let start = Instant::now();
    let line = |share: f64, eta: &str| {
        eprint!(
            "\r{label} {:>3.0} % ({:.1} s{eta})   ",
            100.0 * share.clamp(0.0, 1.0),
            start.elapsed().as_secs_f64()
        );
        PROGRESS_LINE_OPEN.store(true, Ordering::Relaxed);
    };
    // Asked for from the start: say so before any work, however short.
    let shown_at_start = after.is_zero();
    if shown_at_start {
        line(0.0, "");
    }
    std::thread::scope(|scope| {
        let (finished_ref, share, line) = (&finished, &share, &line);
        // (Without a thread for it — the system refused one — the work runs
        // without a progress line.)
        let reporter = std::thread::Builder::new().spawn_scoped(scope, move || {
            let mut shown = shown_at_start;
            while !finished_ref.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(100));
                let elapsed = start.elapsed().as_secs_f64();
                if elapsed < after.as_secs_f64() || finished_ref.load(Ordering::Relaxed) {
                    continue;
                }
                let share = share().clamp(0.0, 1.0);
                let eta = if share > 0.01 {
                    match elapsed * (1.0 - share) / share {
                        left if left < 1.0 => ", under a second left".to_string(),
                        left => format!(", about {left:.0} s left"),
                    }
                } else {
                    String::new()
                };
                line(share, &eta);
                shown = true;
            }
            if shown && std::io::stderr().is_terminal() {
                // Clear the progress line.
                eprint!("\r{:70}\r", "");
            } else if shown {
                // A log keeps the last state, on a line of its own.
                line(share(), "");
                eprintln!();
            }
            PROGRESS_LINE_OPEN.store(false, Ordering::Relaxed);
        });
        if reporter.is_err() && shown_at_start {
            eprintln!();
            PROGRESS_LINE_OPEN.store(false, Ordering::Relaxed);
        }
        let result = work();
        finished.store(true, Ordering::Relaxed);
        result
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_brick_side_that_makes_millions_of_bricks_is_warned_of() {
        let warning = brick_count_warning([256; 3], 2).unwrap();
        assert!(
            warning.starts_with("warning: --brick 2 cuts the volume into 16.6 M bricks"),
            "{warning}"
        );
        // 103³ bricks of side 2: just over the limit; side 3 makes 51³.
        assert!(brick_count_warning([104; 3], 2).is_some());
        assert!(brick_count_warning([104; 3], 3).is_none());
        // The thesis's volume: 2.4 M bricks of side 16 are large enough.
        assert!(brick_count_warning([2000; 3], 16).is_none());
        assert!(brick_count_warning([2000; 3], 8).is_some());
    }
}
