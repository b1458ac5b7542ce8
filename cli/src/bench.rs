//! `raycaster bench`: frame time and samples/s/core over a grid of render threads ×
//! tile size × brick size (× optimisations), as a table, CSV and an SVG plot.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Args;
use raycaster::generate::generate;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::render::{
    Orbit, ParallelOptions, RenderSettings, RenderVolume, TransferFunction, Vec3, render_parallel,
    render_sequential,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Content, Format, Header, Layout, OpenOptions, SampleType, Volume};

use crate::args::parse_size;
use crate::plot;

/// Benchmark the renderers over a parameter grid.
///
/// Renders the default view of a volume (FILE, or a generated `shapes` volume of
/// `--volume-size` voxels, written once to `--cache-dir` and reused) for every
/// combination of `--threads`, `--tiles`, `--bricks` and `--optimisations`, each
/// `--frames` times (after one warm-up frame), and reports the fastest frame.
/// Bricks are logical bricks over linear storage (any size, no conversion); a
/// bricked FILE is rendered by its own bricks or sub-bricks that divide them.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Volume to render (default: a generated `shapes` volume).
    file: Option<PathBuf>,

    /// Size of the generated volume (voxels per axis).
    #[arg(long, default_value_t = 256, value_name = "N")]
    volume_size: u32,

    /// Where generated volumes are kept between runs.
    #[arg(long, default_value = "target/bench-volumes", value_name = "DIR")]
    cache_dir: PathBuf,

    /// Image size.
    #[arg(long, default_value = "512x512", value_parser = parse_size, value_name = "WxH")]
    image: [u32; 2],

    /// Render-thread counts to try.
    #[arg(long, value_delimiter = ',', default_values_t = default_threads(), value_name = "N,..")]
    threads: Vec<usize>,

    /// Tile sizes to try (pixels).
    #[arg(long, value_delimiter = ',', default_values_t = [8, 16, 32], value_name = "PX,..")]
    tiles: Vec<u32>,

    /// Brick sides to try.
    #[arg(long, value_delimiter = ',', default_values_t = [8, 16, 32], value_name = "N,..")]
    bricks: Vec<u32>,

    /// Optimisation settings to try: none, ert, ess, both.
    #[arg(long, value_delimiter = ',', default_values_t = ["both".to_string()], value_name = "SET,..")]
    optimisations: Vec<String>,

    /// Timed frames per configuration (the fastest is reported).
    #[arg(long, default_value_t = 3, value_name = "N")]
    frames: u32,

    /// Sample step in voxels.
    #[arg(long, default_value_t = 0.5)]
    step: f32,

    /// Also time the sequential reference renderer per brick size and optimisation.
    #[arg(long)]
    sequential: bool,

    /// Small and fast: a 96³ volume, 128×128 image, one frame (for CI).
    #[arg(long)]
    quick: bool,

    /// Write the results as CSV.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,

    /// Write a plot of frame time and samples/s per core (SVG).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
}

fn default_threads() -> Vec<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
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

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct Record {
    /// "parallel" or "sequential".
    pub renderer: &'static str,
    /// Render threads.
    pub threads: usize,
    /// Tile side (0 for the sequential renderer).
    pub tile: u32,
    /// Brick side.
    pub brick: u32,
    /// none / ert / ess / both.
    pub optimisations: String,
    /// Fastest frame.
    pub frame: Duration,
    /// Samples taken per frame.
    pub samples: u64,
}

impl Record {
    /// The record's fields as text, in CSV column order.
    fn fields(&self) -> [String; 8] {
        [
            self.renderer.to_string(),
            self.threads.to_string(),
            self.tile.to_string(),
            self.brick.to_string(),
            self.optimisations.clone(),
            format!("{:.3}", self.frame.as_secs_f64() * 1e3),
            self.samples.to_string(),
            format!("{:.0}", self.samples_per_second_per_core()),
        ]
    }

    /// Samples per second per render thread.
    pub fn samples_per_second_per_core(&self) -> f64 {
        self.samples as f64 / self.frame.as_secs_f64().max(1e-9) / self.threads as f64
    }
}

/// Runs the bench command.
pub fn run(mut args: BenchArgs) -> Result<()> {
    if args.quick {
        args.volume_size = args.volume_size.min(96);
        args.image = [128, 128];
        args.frames = 1;
    }
    if args.frames == 0 || args.threads.contains(&0) || args.tiles.contains(&0) {
        bail!("--frames, --threads and --tiles must be at least 1");
    }
    if args.bricks.iter().any(|&b| b < 2) {
        bail!("--bricks must be at least 2");
    }
    if !(args.step > 0.0 && args.step.is_finite()) {
        bail!("--step must be a positive number");
    }
    let opts: Vec<(String, bool, bool)> = args
        .optimisations
        .iter()
        .map(|o| match o.as_str() {
            "none" => Ok((o.clone(), false, false)),
            "ert" => Ok((o.clone(), true, false)),
            "ess" => Ok((o.clone(), false, true)),
            "both" => Ok((o.clone(), true, true)),
            other => bail!("unknown optimisation set {other:?} (none, ert, ess, both)"),
        })
        .collect::<Result<_>>()?;
    let path = match &args.file {
        Some(p) => p.clone(),
        None => generated_volume(&args.cache_dir, args.volume_size)?,
    };
    let volume = Volume::open_with(
        &path,
        OpenOptions {
            access: Access::Mapped,
            ..OpenOptions::default()
        },
    )?;
    let [w, h] = args.image;
    let hi = Vec3::from(volume.dims().map(|d| (d - 1) as f32)) * Vec3::from(volume.spacing());
    let camera = Orbit::default_view(Vec3::ZERO, hi).camera(w, h)?;
    eprintln!(
        "bench: {} ({}×{}×{}), image {w}×{h}, step {}, {} frame(s) per configuration",
        path.display(),
        volume.dims()[0],
        volume.dims()[1],
        volume.dims()[2],
        args.step,
        args.frames
    );
    let mut records = Vec::new();
    println!("{}", table_row(&HEADER.map(String::from)));
    for &brick in &args.bricks {
        let prepared = RenderVolume::new(&volume, Some(brick))
            .with_context(|| format!("brick side {brick}"))?;
        for (name, ert, ess) in &opts {
            let settings = RenderSettings {
                step: args.step,
                early_termination: ert.then_some(raycaster::render::DEFAULT_ERT_THRESHOLD),
                empty_space_skipping: *ess,
                transfer: TransferFunction::preset("shapes")?,
                ..RenderSettings::default()
            };
            let mut measure =
                |renderer, threads, tile, f: &dyn Fn() -> Result<u64>| -> Result<()> {
                    f()?; // warm-up
                    let mut best = Duration::MAX;
                    let mut samples = 0;
                    for _ in 0..args.frames {
                        let start = std::time::Instant::now();
                        samples = f()?;
                        best = best.min(start.elapsed());
                    }
                    let r = Record {
                        renderer,
                        threads,
                        tile,
                        brick,
                        optimisations: name.clone(),
                        frame: best,
                        samples,
                    };
                    println!("{}", table_row(&r.fields()));
                    records.push(r);
                    Ok(())
                };
            if args.sequential {
                measure("sequential", 1, 0, &|| {
                    Ok(render_sequential(&prepared, &camera, &settings)?
                        .stats
                        .counters
                        .samples)
                })?;
            }
            for &threads in &args.threads {
                for &tile in &args.tiles {
                    let options = ParallelOptions {
                        render_threads: threads,
                        compositing_threads: 1,
                        tile_size: tile,
                    };
                    measure("parallel", threads, tile, &|| {
                        Ok(render_parallel(&prepared, &camera, &settings, &options)?
                            .stats
                            .counters
                            .samples)
                    })?;
                }
            }
        }
    }
    summarise(&records);
    if let Some(csv) = &args.csv {
        write_atomically(csv, csv_text(&records).as_bytes())?;
        eprintln!("wrote {}", csv.display());
    }
    if let Some(svg) = &args.plot {
        write_atomically(svg, plot::svg(&records).as_bytes())?;
        eprintln!("wrote {}", svg.display());
    }
    Ok(())
}

/// The cached `shapes` volume of `n³` voxels (linear, so any brick size applies).
fn generated_volume(dir: &Path, n: u32) -> Result<PathBuf> {
    let path = dir.join(format!("shapes-{n}-linear.vol"));
    if path.is_file() {
        return Ok(path);
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    eprintln!("bench: generating {} (once)", path.display());
    let header = Header::new(
        [n; 3],
        [1.0; 3],
        Layout::Linear,
        SampleType::U8,
        Content::Scalar,
        Format::Extended,
    );
    let scene = SceneKind::Shapes.build([n; 3], 1);
    generate(
        scene.as_ref(),
        &header,
        &path,
        &WriteOptions::default(),
        &Job::silent(),
    )?;
    Ok(path)
}

/// Speedups and the best configuration, on stderr.
fn summarise(records: &[Record]) {
    let parallel: Vec<&Record> = records
        .iter()
        .filter(|r| r.renderer == "parallel")
        .collect();
    if let Some(best) = parallel.iter().min_by_key(|r| r.frame) {
        eprintln!(
            "fastest: {} threads, tile {}, brick {}, {}: {:.2} ms",
            best.threads,
            best.tile,
            best.brick,
            best.optimisations,
            best.frame.as_secs_f64() * 1e3
        );
    }
    for r in &parallel {
        let one = parallel.iter().find(|o| {
            o.threads == 1
                && o.tile == r.tile
                && o.brick == r.brick
                && o.optimisations == r.optimisations
        });
        if let Some(one) = one.filter(|_| r.threads > 1) {
            eprintln!(
                "speedup {} threads over 1 (tile {}, brick {}, {}): {:.2}×",
                r.threads,
                r.tile,
                r.brick,
                r.optimisations,
                one.frame.as_secs_f64() / r.frame.as_secs_f64()
            );
        }
    }
    for s in records.iter().filter(|r| r.renderer == "sequential") {
        for p in parallel
            .iter()
            .filter(|p| p.threads == 1 && p.brick == s.brick && p.optimisations == s.optimisations)
        {
            eprintln!(
                "1-thread parallel / sequential (tile {}, brick {}, {}): {:.2} (same samples: {})",
                p.tile,
                p.brick,
                p.optimisations,
                p.frame.as_secs_f64() / s.frame.as_secs_f64(),
                p.samples == s.samples
            );
        }
    }
}

/// Column names (CSV header and table heading).
const HEADER: [&str; 8] = [
    "renderer",
    "threads",
    "tile",
    "brick",
    "optimisations",
    "frame_ms",
    "samples",
    "samples_per_s_per_core",
];

/// One aligned table row.
fn table_row(fields: &[String; 8]) -> String {
    let widths = [10, 7, 5, 5, 13, 10, 12, 22];
    fields
        .iter()
        .zip(widths)
        .enumerate()
        .map(|(i, (f, w))| {
            if i == 0 {
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

fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let tmp = dir.join(format!(
        ".{}.partial",
        path.file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
