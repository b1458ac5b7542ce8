//! `raycaster bench`: frame time and samples/s/core over a grid of render threads ×
//! tile size × brick size (× optimisations), as a table, CSV and a PNG or SVG plot.
//!
//! Every grid point is a [`BenchCase`] of the benchmark crate, the type the
//! criterion benches are built from, so a sweep row and a criterion id describe a
//! frame the same way.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Args;
use raycaster::render::{PRESETS, RenderVolume, SimdLevel};
use raycaster::volume::{Access, Layout, SampleType};
use raycaster_benches::{
    BenchCase, Optimisations, SceneSpec, View, VolumeSource, VolumeSpec, parse_layout,
    parse_sample_type,
};

use crate::args::{parse_positive, parse_size};
use crate::plot;
use crate::render::ModeArg;

/// Benchmark the renderers over a parameter grid.
///
/// Renders a view of a volume (FILE, or a generated `shapes` volume of
/// `--volume-size` voxels, written once to `--cache-dir` and reused) for every
/// combination of `--threads`, `--tiles`, `--bricks` and `--optimisations`, each
/// `--frames` times (after `--warm-up` untimed frames), and reports the fastest
/// frame, the median and the spread (slowest − fastest). Frames sample the
/// volume's full resolution (`raycaster render --level 0`) with the transfer
/// function render fits to the data unless `--tf` names one, so `raycaster
/// render FILE --level 0` with the same settings marches the same samples.
/// Bricks are logical bricks over linear storage (any size, no conversion); a
/// bricked volume is rendered by its own bricks or sub-bricks that divide them.
#[derive(Args, Debug)]
#[command(
    allow_negative_numbers = true,
    after_help = "\
Examples:
  raycaster bench --quick --plot sweep.png
  raycaster bench --volume-size 512 --sequential --csv sweep.csv --plot sweep.png
  raycaster bench --volume-size 800 --threads 1 --sequential --optimisations none,ert,ess,both
  raycaster bench volumes/data/lung1.vol --ram --tiles 16 --bricks 16 --image 700x700 --step 0.2"
)]
pub struct BenchArgs {
    /// Volume to render, a .vol file (default: a generated `shapes` volume;
    /// other formats: convert them first, `volgen convert FILE -o FILE.vol`).
    file: Option<PathBuf>,

    /// Size of the generated volume (voxels per axis) [default: 256; 96 with
    /// --quick].
    // (The generated volume's flags conflict with a FILE: they were ignored
    // without a word.)
    #[arg(long, visible_alias = "scene-size", value_name = "N", conflicts_with = "file",
          value_parser = clap::value_parser!(u32).range(2..=i64::from(raycaster::volume::MAX_AXIS)))]
    volume_size: Option<u32>,

    /// Sample type of the generated volume: u8, u16.
    #[arg(long, default_value = "u8", value_parser = parse_sample_type, value_name = "TYPE", conflicts_with = "file")]
    sample_type: SampleType,

    /// Storage of the generated volume: linear, bricked (side 16), bricked:N.
    #[arg(long, default_value = "linear", value_parser = parse_layout, value_name = "LAYOUT", conflicts_with = "file")]
    layout: Layout,

    /// Read the volume into RAM instead of mapping it.
    #[arg(long)]
    ram: bool,

    /// Where generated volumes are kept between runs [default:
    /// $XDG_CACHE_HOME/raycaster/bench-volumes, else ~/.cache/raycaster/bench-volumes,
    /// else raycaster-UID/bench-volumes in the temporary folder, UID the user's id].
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<PathBuf>,

    /// Image size [default: 512x512; 128x128 with --quick].
    #[arg(long, visible_alias = "size", value_parser = parse_size, value_name = "WxH")]
    image: Option<[u32; 2]>,

    /// Render-thread counts to try [default: 1, the powers of two below the
    /// core count, and the core count: 1,2 on two cores].
    #[arg(long, value_delimiter = ',', default_values_t = default_threads(), hide_default_value = true, value_parser = parse_threads, value_name = "N,..")]
    threads: Vec<usize>,

    /// Tile sizes to try (pixels) [default: 8,16,32].
    #[arg(long, visible_alias = "tile", value_delimiter = ',', default_values_t = [8, 16, 32], hide_default_value = true, value_parser = clap::value_parser!(u32).range(1..=4096), value_name = "PX,..")]
    tiles: Vec<u32>,

    /// Brick sides to try [default: 8,16,32; on a bricked volume those of them
    /// that tile its bricks (side−1 divides the volume's side−1), else its own
    /// side].
    #[arg(long, visible_alias = "brick", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(2..=1024), value_name = "N,..")]
    bricks: Vec<u32>,

    /// Optimisation settings to try: none, ert, ess, both.
    #[arg(long, value_delimiter = ',', default_values_t = [Optimisations::Both], value_name = "SET,..")]
    optimisations: Vec<Optimisations>,

    /// Camera preset: default, front (face-on from +x), close (twice as near).
    #[arg(long, default_value = "default", value_parser = parse_view, value_name = "VIEW")]
    view: View,

    /// Compositing mode.
    #[arg(long, value_enum, default_value_t = ModeArg::Dvr)]
    mode: ModeArg,

    /// Transfer-function preset. Default: the built-in volume's `shapes`; for a
    /// FILE, the preset and domain `raycaster render` fits to its data (`shapes`
    /// for u8, ct-bone over -1000..2000 HU for CT), so that both time the same
    /// frame.
    #[arg(long = "tf", value_parser = parse_preset, value_name = "PRESET")]
    transfer: Option<&'static str>,

    /// Timed frames per configuration (the fastest is reported; at most
    /// 10000) [default: 3; 1 with --quick].
    #[arg(long, value_parser = parse_frames, value_name = "N")]
    frames: Option<u32>,

    /// Untimed frames before the timed ones (page cache, allocations; at
    /// most 10000).
    #[arg(long, default_value_t = 1, value_parser = parse_warm_up, value_name = "N")]
    warm_up: u32,

    /// Sample step in voxels.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive, value_name = "VOXELS")]
    step: f32,

    /// Pre-integrated transfer tables, as `raycaster render --preintegrate`
    /// (DVR with a 1D transfer function; it runs on the scalar kernel).
    #[arg(long)]
    preintegrate: bool,

    /// Also time the sequential reference renderer per brick size and optimisation.
    #[arg(long)]
    sequential: bool,

    /// Marching kernel of both renderers (as `raycaster render --simd`):
    /// auto, scalar, sse4.1, avx2, avx512, neon.
    #[arg(long, default_value = "auto", value_parser = crate::render::parse_simd, value_name = "LEVEL")]
    simd: crate::render::SimdChoice,

    /// Small and fast (for CI): a 96³ volume, a 128×128 image and one frame
    /// unless --volume-size, --image or --frames say otherwise.
    #[arg(long)]
    quick: bool,

    /// Write the results as CSV.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,

    /// Plot frame time and samples/s per render thread against threads, tile and brick:
    /// PNG, or SVG when FILE ends in `.svg`.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,

    /// Replace existing `--csv` and `--plot` files.
    #[arg(long)]
    force: bool,
}

impl BenchArgs {
    /// The generated volume's side: `--volume-size`, else 256 (96 quick).
    fn volume_size(&self) -> u32 {
        self.volume_size
            .unwrap_or(if self.quick { 96 } else { 256 })
    }

    /// The image size: `--image`, else 512×512 (128×128 quick).
    fn image(&self) -> [u32; 2] {
        self.image
            .unwrap_or(if self.quick { [128, 128] } else { [512, 512] })
    }

    /// Timed frames per configuration: `--frames`, else 3 (1 quick).
    fn frames(&self) -> u32 {
        self.frames.unwrap_or(if self.quick { 1 } else { 3 })
    }
}

/// Drops the repeats of a list, keeping its first order.
fn dedup<T: PartialEq + Copy>(list: &mut Vec<T>) {
    let mut seen = Vec::with_capacity(list.len());
    list.retain(|v| {
        let new = !seen.contains(v);
        if new {
            seen.push(*v);
        }
        new
    });
}

/// The most render threads a case may ask for (as `raycaster render --threads`).
const MAX_THREADS: usize = raycaster::render::MAX_THREADS;

/// A `--threads` count: 1 to [`MAX_THREADS`].
fn parse_threads(s: &str) -> Result<usize, String> {
    crate::args::parse_bounded(s, 1, MAX_THREADS as u32).map(|n| n as usize)
}

/// The most frames a case may time or warm up with: ten thousand frames of a
/// small image already take minutes; more is a typo, whose frame times
/// would not fit in memory either (they are kept for the median).
const MAX_FRAMES: u32 = 10_000;

/// A `--frames` count: 1 to [`MAX_FRAMES`].
fn parse_frames(s: &str) -> Result<u32, String> {
    crate::args::parse_bounded(s, 1, MAX_FRAMES)
}

/// A `--warm-up` count: 0 to [`MAX_FRAMES`].
fn parse_warm_up(s: &str) -> Result<u32, String> {
    crate::args::parse_bounded(s, 0, MAX_FRAMES)
}

fn default_threads() -> Vec<usize> {
    let cores = raycaster_benches::cores();
    let mut t = vec![1];
    let mut n = 2;
    while n < cores {
        t.push(n);
        n *= 2;
    }
    if cores > 1 {
        t.push(cores);
    }
    t
}

fn parse_view(s: &str) -> Result<View, String> {
    [View::Default, View::Front, View::Close]
        .into_iter()
        .find(|v| v.name() == s)
        .ok_or_else(|| format!("unknown view {s:?} (default, front, close)"))
}

fn parse_preset(s: &str) -> Result<&'static str, String> {
    PRESETS
        .iter()
        .map(|(name, _)| *name)
        .find(|name| *name == s)
        .ok_or_else(|| format!("unknown transfer-function preset {s:?}"))
}

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct Record {
    /// What was rendered.
    pub case: BenchCase,
    /// Fastest frame.
    pub frame: Duration,
    /// Median frame.
    pub median: Duration,
    /// Slowest minus fastest frame.
    pub spread: Duration,
    /// Frames timed.
    pub frames: u32,
    /// Samples taken per frame.
    pub samples: u64,
}

impl Record {
    /// The record's fields as text, in CSV column order ([`HEADER`]).
    fn fields(&self) -> [String; COLUMNS] {
        let c = &self.case;
        [
            c.renderer().to_string(),
            c.render_threads().to_string(),
            if c.threads.is_some() { c.tile } else { 0 }.to_string(),
            c.brick.map_or(0, |b| b).to_string(),
            c.optimisations.to_string(),
            format!("{:.3}", self.frame.as_secs_f64() * 1e3),
            self.samples.to_string(),
            format!("{:.0}", self.samples_per_second_per_thread()),
            c.volume.name(),
            format!("{}x{}", c.image[0], c.image[1]),
            c.step.to_string(),
            c.view.name().to_string(),
            format!("{:.3}", self.median.as_secs_f64() * 1e3),
            format!("{:.3}", self.spread.as_secs_f64() * 1e3),
            // Whether the frames used it (DVR only).
            c.settings().is_ok_and(|s| s.preintegrates()).to_string(),
            c.mode.name().to_string(),
            c.transfer.unwrap_or("fitted").to_string(),
            self.kernel().to_string(),
        ]
    }

    /// The marching kernel the frames ran: `--simd`, else each renderer's
    /// automatic choice (the parallel renderer's widest, the sequential
    /// renderer's scalar loop).
    pub fn kernel(&self) -> SimdLevel {
        let auto = if self.case.threads.is_some() {
            SimdLevel::automatic()
        } else {
            SimdLevel::Scalar
        };
        self.case.simd.unwrap_or(auto)
    }

    /// Samples per second per render thread.
    pub fn samples_per_second_per_thread(&self) -> f64 {
        self.samples as f64 / self.frame.as_secs_f64().max(1e-9) / self.case.render_threads() as f64
    }

    /// Frame time in milliseconds.
    pub fn frame_ms(&self) -> f64 {
        self.frame.as_secs_f64() * 1e3
    }
}

/// The brick sides swept when `--bricks` is not given, for a linear volume.
const DEFAULT_BRICKS: [u32; 3] = [8, 16, 32];

/// The default brick sides for a volume stored in `layout`: [`DEFAULT_BRICKS`],
/// on a bricked volume those of them that tile its bricks, else its side.
fn bricks_for(layout: Layout) -> Vec<u32> {
    match layout {
        Layout::Linear => DEFAULT_BRICKS.to_vec(),
        Layout::Bricked { side } => {
            let side = u32::from(side);
            let tiling: Vec<u32> = DEFAULT_BRICKS
                .into_iter()
                .filter(|b| (side - 1).is_multiple_of(b - 1))
                .collect();
            if tiling.is_empty() {
                vec![side]
            } else {
                tiling
            }
        }
    }
}

/// The grid of cases of the arguments, brick by brick (bricks outermost, so a
/// prepared volume serves every case of its brick side).
fn cases(args: &BenchArgs) -> Vec<BenchCase> {
    let access = if args.ram {
        Access::Ram
    } else {
        Access::Mapped
    };
    let volume = match &args.file {
        Some(p) => VolumeSpec::file(p, access),
        None => VolumeSpec {
            source: VolumeSource::Scene(SceneSpec {
                scene: raycaster::synth::SceneKind::Shapes,
                dims: [args.volume_size(); 3],
                sample_type: args.sample_type,
                layout: args.layout,
                seed: 1,
            }),
            access,
        },
    };
    let base = BenchCase {
        volume,
        view: args.view,
        step: args.step,
        mode: args.mode.into(),
        // The built-in volume's preset, or what render fits to a file.
        transfer: args.transfer.or(args.file.is_none().then_some("shapes")),
        image: args.image(),
        simd: args.simd.0,
        preintegrated: args.preintegrate,
        ..BenchCase::default()
    };
    let mut out = Vec::new();
    for &brick in &args.bricks {
        for &optimisations in &args.optimisations {
            let case = BenchCase {
                brick: Some(brick),
                optimisations,
                ..base.clone()
            };
            if args.sequential {
                out.push(BenchCase {
                    threads: None,
                    ..case.clone()
                });
            }
            for &threads in &args.threads {
                for &tile in &args.tiles {
                    out.push(BenchCase {
                        threads: Some(threads),
                        tile,
                        ..case.clone()
                    });
                }
            }
        }
    }
    out
}

/// Runs the bench command.
pub fn run(mut args: BenchArgs) -> Result<()> {
    // A value given twice in a list is measured once.
    dedup(&mut args.threads);
    dedup(&mut args.tiles);
    dedup(&mut args.bricks);
    dedup(&mut args.optimisations);
    // The outputs are checked before the sweep, not after it.
    if let Some(csv) = &args.csv {
        if csv.as_os_str() == "-" {
            bail!("--csv -: the table goes to standard output already; name a file for the CSV");
        }
        crate::output::check_not_an_input(csv, &args.file, "the CSV")?;
        crate::output::check_file(csv, args.force)?;
    }
    if let Some(path) = &args.plot {
        crate::output::check_not_an_input(path, &args.file, "the plot")?;
        if let Some(csv) = &args.csv
            && raycaster::files::same_target(csv, path)
        {
            bail!(
                "--csv and --plot both name {}: the plot would replace the CSV; name two files",
                path.display()
            );
        }
        if plot::is_svg(path) {
            crate::output::check_file(path, args.force)?;
        } else {
            crate::output::check_output(path, args.force)?;
        }
    }
    let [w, h] = args.image();
    crate::memory::check_frame(w, h)?;
    if let Some(warning) = crate::render::preintegrate_ignored(args.preintegrate, args.mode) {
        eprintln!("{warning}");
    }
    if let Some(level) = args.simd.0.filter(|l| !l.is_available()) {
        bail!("--simd {level}: this machine does not have it");
    }
    let default_bricks = args.bricks.is_empty();
    if default_bricks {
        // Until the volume is open: a placeholder that opens it.
        args.bricks = DEFAULT_BRICKS.to_vec();
    }
    if let Some(file) = &args.file
        && let Some(problem) = raycaster::import::vol_only_problem(file)
    {
        bail!("{}: {problem}", file.display());
    }
    // What aborted the process (an allocation past the limit) is refused
    // first, with the numbers, as render does.
    if args.ram {
        match &args.file {
            Some(file) => {
                if let Ok(meta) = std::fs::metadata(file) {
                    crate::memory::check_ram(file.display(), meta.len())?;
                }
            }
            None => {
                let voxels = u64::from(args.volume_size()).pow(3);
                let bytes = voxels.saturating_mul(args.sample_type.size());
                crate::memory::check_ram("the generated volume", bytes)?;
            }
        }
    }
    // The most threads a case starts: its render threads, a compositing
    // thread and the read-ahead.
    if let Some(most) = args.threads.iter().max() {
        crate::threads::check_threads(*most + 2)?;
    }
    let cases_then = cases(&args);
    let Some(first) = cases_then.first() else {
        bail!(
            "nothing to measure: give at least one thread count, tile, brick and optimisation set"
        );
    };
    let cache_dir = match &args.cache_dir {
        Some(dir) => dir.clone(),
        None => default_cache_dir(
            std::env::var_os("XDG_CACHE_HOME").map(PathBuf::from),
            std::env::var_os("HOME").map(PathBuf::from),
        ),
    };
    if cache_dir.exists() && !cache_dir.is_dir() {
        bail!(
            "--cache-dir {}: is not a folder (it names the folder generated volumes are kept in)",
            cache_dir.display()
        );
    }
    std::fs::create_dir_all(&cache_dir)
        .with_context(|| format!("cannot create the cache folder {}", cache_dir.display()))?;
    // The default folder in the shared temporary folder must be this user's:
    // another user could have made it, and put files there to be measured.
    if args.cache_dir.is_none() && cache_dir.starts_with(std::env::temp_dir()) {
        for dir in [cache_dir.parent().unwrap_or(&cache_dir), &cache_dir] {
            if let Some(owner) = foreign_owner(dir) {
                bail!(
                    "{}: belongs to another user (uid {owner}), and bench would measure its files; name a folder of your own with --cache-dir",
                    dir.display()
                );
            }
        }
    }
    // (After the memory checks: its threads take address space.)
    crate::threads::start_worker_pool()?;
    let volume = first.open_volume(&cache_dir)?;
    raycaster::files::guard_mapped_file(volume.path());
    // (As render refuses it: it was measured, with no sample taken.)
    if volume.content() == raycaster::volume::Content::Labels {
        bail!(
            "{}: is a label volume (object ids, not values); bench renders the data volume",
            volume.path().display()
        );
    }
    // The generated volume is an input too (a named FILE was checked above).
    for (output, what) in [(&args.csv, "--csv"), (&args.plot, "--plot")] {
        if let Some(output) = output
            && raycaster::files::same_target(output, volume.path())
        {
            bail!(
                "{what} {}: is the volume this benchmark reads; name another file",
                output.display()
            );
        }
    }
    // A table piped to `head` must not cost the files written at the end: a
    // closed standard output skips the rest of the table
    // (`raycaster::console`) instead of ending the process.
    if args.csv.is_some() || args.plot.is_some() {
        crate::ignore_sigpipe();
    }
    if default_bricks {
        args.bricks = bricks_for(volume.layout());
    }
    let cases = cases(&args);
    // Every brick side is checked before the sweep prints anything, and the
    // frame's samples (the step, image and view are every case's).
    let mut geometry = None;
    for &side in &args.bricks {
        let count = raycaster::volume::BlockGrid::new(volume.dims(), side).block_count();
        crate::memory::check_bricks("--bricks", count, side)?;
        let prepared =
            RenderVolume::new(&volume, Some(side)).with_context(|| format!("--bricks {side}"))?;
        geometry.get_or_insert(*prepared.geometry());
    }
    if let Some(geometry) = &geometry {
        let camera = first.view.camera(&volume, args.image())?;
        raycaster::render::check_sample_budget(geometry, args.step, &camera)?;
    }
    eprintln!(
        "bench: {} ({}×{}×{}, {}), image {w}×{h}, step {}{}, {} frame(s) per configuration, {} kernel",
        volume.path().display(),
        volume.dims()[0],
        volume.dims()[1],
        volume.dims()[2],
        first.volume.name(),
        args.step,
        // (Only where the mode uses it: the warning above says it is ignored.)
        if args.preintegrate && crate::render::preintegrate_ignored(true, args.mode).is_none() {
            " pre-integrated"
        } else {
            ""
        },
        args.frames(),
        args.simd.0.map_or("auto".to_string(), |l| l.to_string())
    );
    if let Some(warning) = load_warning(load_average(), available_cores()) {
        eprintln!("{warning}");
    }
    let mut records: Vec<Record> = Vec::new();
    println!("{}", table_row(&HEADER.map(String::from)));
    let mut prepared: Option<(Option<u32>, RenderVolume<'_>)> = None;
    for case in cases {
        if prepared.as_ref().is_none_or(|(b, _)| *b != case.brick) {
            let p = RenderVolume::new(&volume, case.brick)
                .with_context(|| format!("brick side {}", brick_text(case.brick)))?;
            prepared = Some((case.brick, p));
        }
        let (_, shared) = prepared.take().expect("prepared above");
        let ready = case.prepare_with(shared)?;
        let record = measure(&case, &ready, args.warm_up, args.frames())?;
        prepared = Some((case.brick, ready.volume));
        println!("{}", table_row(&record.fields()));
        records.push(record);
    }
    summarise(&records, args.quick);
    // Written once the sweep is complete: an interrupted sweep leaves no CSV
    // of part of the grid (its rows are in the table on standard output).
    if let Some(csv) = &args.csv {
        write_atomically(csv, csv_text(&records).as_bytes())?;
        eprintln!("wrote {}", csv.display());
    }
    if let Some(path) = &args.plot {
        plot::write(path, &records)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// The folder bench volumes are cached in: under `$XDG_CACHE_HOME` (an absolute
/// path, as the XDG spec requires), else `~/.cache`, else the temporary folder; never
/// the working directory.
fn default_cache_dir(xdg_cache: Option<PathBuf>, home: Option<PathBuf>) -> PathBuf {
    let own = xdg_cache
        .filter(|p| p.is_absolute())
        .or_else(|| home.filter(|p| p.is_absolute()).map(|h| h.join(".cache")));
    match own {
        Some(base) => base.join("raycaster").join("bench-volumes"),
        // The shared temporary folder: a folder of this user's own (one for
        // all users let another user's files be measured).
        None => {
            let user = own_uid().map_or_else(
                || std::env::var("USER").unwrap_or_else(|_| "user".into()),
                |uid| uid.to_string(),
            );
            std::env::temp_dir()
                .join(format!("raycaster-{user}"))
                .join("bench-volumes")
        }
    }
}

/// This process's user id: the owner of its `/proc` entry (`None` where
/// there is no `/proc`).
fn own_uid() -> Option<u32> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self").ok().map(|m| m.uid())
}

/// The owner of `dir` (a link itself, not what it points to) where it is
/// another user than this process's.
fn foreign_owner(dir: &Path) -> Option<u32> {
    use std::os::unix::fs::MetadataExt;
    let owner = std::fs::symlink_metadata(dir).ok()?.uid();
    (owner != own_uid()?).then_some(owner)
}

/// `warm_up` untimed frames, then `frames` timed ones: the fastest, the median and
/// the spread.
fn measure(
    case: &BenchCase,
    ready: &raycaster_benches::PreparedCase<'_>,
    warm_up: u32,
    frames: u32,
) -> Result<Record> {
    for _ in 0..warm_up {
        ready.frame()?;
    }
    let mut times = Vec::with_capacity(frames as usize);
    let mut samples = 0;
    for _ in 0..frames {
        let start = Instant::now();
        samples = ready.samples()?;
        times.push(start.elapsed());
    }
    times.sort();
    let best = times.first().copied().unwrap_or_default();
    let worst = times.last().copied().unwrap_or_default();
    Ok(Record {
        case: case.clone(),
        frame: best,
        median: times.get(times.len() / 2).copied().unwrap_or_default(),
        spread: worst - best,
        frames,
        samples,
    })
}

/// The one-minute load average (`/proc/loadavg`), if known.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
}

/// A warning when other work loads the machine (load average above half its cores):
/// timings then measure the neighbours too.
fn load_warning(load: Option<f64>, cores: usize) -> Option<String> {
    let load = load?;
    (load > 0.5 * cores as f64).then(|| {
        format!(
            "warning: the machine is loaded (load average {load:.1} on {cores} cores): frame times include other work; rerun on an idle machine"
        )
    })
}

/// A brick side for people: `16`, or `default` when the renderer chooses.
fn brick_text(brick: Option<u32>) -> String {
    brick.map_or_else(|| "default".to_string(), |b| b.to_string())
}

/// Speedups and the best configuration, on stderr (without the one-frame
/// warning for `--quick`, a smoke run by definition).
fn summarise(records: &[Record], quick: bool) {
    if !quick && records.iter().any(|r| r.frames == 1) && records.len() > 1 {
        eprintln!(
            "warning: each configuration was timed on one frame; speedups resting on one frame are noisy (use --frames 5 or more)"
        );
    }
    let parallel: Vec<&Record> = records
        .iter()
        .filter(|r| r.case.threads.is_some())
        .collect();
    if let Some(best) = parallel.iter().min_by_key(|r| r.frame) {
        let threads = best.case.render_threads();
        eprintln!(
            "fastest: {}, tile {}, brick {}, {}: {:.2} ms",
            raycaster::text::counted(threads as u64, "thread"),
            best.case.tile,
            brick_text(best.case.brick),
            best.case.optimisations,
            best.frame_ms()
        );
    }
    let same =
        |a: &BenchCase, b: &BenchCase| a.brick == b.brick && a.optimisations == b.optimisations;
    for r in &parallel {
        let one = parallel.iter().find(|o| {
            o.case.threads == Some(1) && o.case.tile == r.case.tile && same(&o.case, &r.case)
        });
        if let Some(one) = one.filter(|_| r.case.render_threads() > 1) {
            eprintln!(
                "speedup {} threads over 1 (tile {}, brick {}, {}): {:.2}×",
                r.case.render_threads(),
                r.case.tile,
                brick_text(r.case.brick),
                r.case.optimisations,
                one.frame.as_secs_f64() / r.frame.as_secs_f64()
            );
        }
    }
    for s in records.iter().filter(|r| r.case.threads.is_none()) {
        for p in parallel
            .iter()
            .filter(|p| p.case.threads == Some(1) && same(&p.case, &s.case))
        {
            eprintln!(
                "parallel renderer on 1 thread ({} kernel) against the sequential one ({} kernel) (tile {}, brick {}, {}): {:.2}× its speed, {} samples",
                p.kernel(),
                s.kernel(),
                p.case.tile,
                brick_text(p.case.brick),
                p.case.optimisations,
                s.frame.as_secs_f64() / p.frame.as_secs_f64(),
                if p.samples == s.samples {
                    "the same"
                } else {
                    "NOT the same"
                }
            );
        }
    }
}

/// Columns of the CSV and the table.
const COLUMNS: usize = 18;

/// Column names (CSV header and table heading).
const HEADER: [&str; COLUMNS] = [
    "renderer",
    "threads",
    "tile",
    "brick",
    "optimisations",
    "frame_ms",
    "samples",
    "samples_per_s_per_thread",
    "volume",
    "image",
    "step",
    "view",
    "median_ms",
    "spread_ms",
    "preintegrated",
    "mode",
    "transfer",
    "kernel",
];

/// One aligned table row: the CSV columns with median and spread beside the
/// fastest frame (a tile of 0, the CSV's "no tiles", shown as `-`).
fn table_row(fields: &[String; COLUMNS]) -> String {
    const ORDER: [usize; COLUMNS] = [0, 1, 2, 3, 4, 5, 12, 13, 6, 7, 8, 9, 10, 11, 14, 15, 16, 17];
    const WIDTHS: [usize; COLUMNS] = [10, 7, 5, 5, 13, 10, 10, 10, 12, 22, 0, 0, 0, 0, 0, 0, 0, 0];
    ORDER
        .iter()
        .zip(WIDTHS)
        .enumerate()
        .map(|(i, (&column, w))| {
            let f = match fields[column].as_str() {
                "0" if column == 2 => "-",
                f => f,
            };
            if i == 0 || w == 0 {
                format!("{f:<w$}")
            } else {
                format!("{f:>w$}")
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn csv_text(records: &[Record]) -> String {
    let mut out = HEADER.join(",") + "\n";
    for r in records {
        out += &r.fields().join(",");
        out.push('\n');
    }
    out
}

/// Writes `bytes` to `path` atomically (the library's writer: a temporary file
/// beside it, renamed into place).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    raycaster::volume::write_file_atomically(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_bricks_tile_a_bricked_volume() {
        assert_eq!(bricks_for(Layout::Linear), [8, 16, 32]);
        // Side 16: step 15, which 7 and 31 do not divide.
        assert_eq!(bricks_for(Layout::Bricked { side: 16 }), [16]);
        assert_eq!(bricks_for(Layout::Bricked { side: 32 }), [32]);
        assert_eq!(bricks_for(Layout::Bricked { side: 29 }), [8]);
        assert_eq!(bricks_for(Layout::Bricked { side: 64 }), [8]);
        assert_eq!(bricks_for(Layout::Bricked { side: 11 }), [11]);
    }

    #[test]
    fn bench_volumes_are_cached_under_the_xdg_cache_not_the_working_directory() {
        let p = |s: &str| Some(PathBuf::from(s));
        assert_eq!(
            default_cache_dir(p("/c"), p("/home/u")),
            Path::new("/c/raycaster/bench-volumes")
        );
        assert_eq!(
            default_cache_dir(None, p("/home/u")),
            Path::new("/home/u/.cache/raycaster/bench-volumes")
        );
        // A relative XDG_CACHE_HOME is ignored (XDG spec).
        assert_eq!(
            default_cache_dir(p("rel"), p("/home/u")),
            Path::new("/home/u/.cache/raycaster/bench-volumes")
        );
        let shared = default_cache_dir(None, None);
        assert!(shared.is_absolute());
        // (One folder of this user's own in the shared temporary folder.)
        assert!(
            shared.to_string_lossy().contains("/raycaster-"),
            "{}",
            shared.display()
        );
    }

    #[test]
    fn a_loaded_machine_is_warned_about() {
        assert!(
            load_warning(Some(3.0), 2)
                .unwrap()
                .contains("load average 3.0 on 2")
        );
        assert!(load_warning(Some(0.2), 2).is_none());
        assert!(load_warning(None, 2).is_none());
    }
}
