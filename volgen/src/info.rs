//! `volgen info`: what a `.vol` file holds.

use std::path::PathBuf;

use clap::Args;
use raycaster::io::Input;
use raycaster::job::Job;
use raycaster::volume::{Format, Layout, OpenOptions, ValueUnits, Volume};

use crate::generate::{describe_layout, describe_size};
use crate::progress::{CANCEL, voxel_bar};
use raycaster::text::counted;

/// Show a volume file's header, layout, value histogram and brick statistics.
///
/// Reads .vol files and every importable format (NRRD, NIfTI-1, MetaImage, a DICOM
/// series folder); values are shown in the file's own units (Hounsfield units for
/// CT) over their data range. The histogram needs a
/// streaming pass over the samples (bounded memory); --no-histogram skips it for a
/// quick look at a huge file. Example:
///
///   volgen info shapes.vol
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct InfoArgs {
    /// The .vol file, or a NRRD, NIfTI-1, MetaImage file or DICOM series folder.
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Skip the value histogram (no pass over the samples).
    #[arg(long)]
    no_histogram: bool,
    /// Print nothing but the report (no progress bar).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: InfoArgs) -> anyhow::Result<()> {
    if raycaster::import::detect(&a.file).is_some() {
        return run_foreign(&a);
    }
    raycaster::files::guard_mapped_file(&a.file);
    let volume = Volume::open_with(&a.file, OpenOptions::default())?;
    let h = volume.header();
    let file_bytes = std::fs::metadata(&a.file)?.len();
    let voxels: u64 = h.dims.iter().map(|&d| u64::from(d)).product();
    println!("file        {}", a.file.display());
    println!(
        "size        {} ({})",
        describe_size(h.dims),
        counted(voxels, "voxel")
    );
    println!("spacing     {}", describe_spacing(h.spacing));
    println!("samples     {}", describe_layout(h));
    match h.format {
        Format::Thesis => println!("header      26 bytes (reference thesis format)"),
        Format::Extended => println!(
            "header      {} bytes (extension version {})",
            h.data_offset,
            h.extension_version()
        ),
    }
    if let Some(orientation) = &h.orientation {
        println!("orientation {}", orientation.describe());
    }
    let units = h.value_units();
    // Two stored samples' values, smaller first.
    let ordered = |a: u16, b: u16| {
        let (x, y) = (units.value(f64::from(a)), units.value(f64::from(b)));
        [x.min(y), x.max(y)].map(|v| units.format(v))
    };
    if !units.is_identity() {
        println!("units       {}", units.describe());
    }
    println!(
        "file bytes  {file_bytes} ({} of samples, {:.3}x the voxel count)",
        h.data_len()?,
        h.stored_samples()? as f64 / voxels as f64
    );
    if let Some((start, count)) = volume.unused_tail() {
        println!(
            "unused      {} after the file's last block, from byte {start}: not part of the volume (a damaged copy, or two files joined?)",
            raycaster::text::counted(count, "byte")
        );
    }
    let ranges = volume.ranges();
    let grid = ranges.grid();
    let [nx, ny, nz] = grid.counts();
    let count = grid.block_count();
    let bricks = counted(count, "brick");
    let side = grid.side();
    // Stored bricks repeat their neighbours' boundary voxels (the file's size
    // beyond the voxel count); a linear file's are logical.
    match h.layout {
        Layout::Linear => println!(
            "bricks      {nx}x{ny}x{nz} = {bricks} of side {side}, logical, for empty-space skipping"
        ),
        Layout::Bricked { .. } => println!(
            "bricks      {nx}x{ny}x{nz} = {bricks} of side {side}, neighbours sharing one voxel layer"
        ),
    }
    let all = ranges.as_slice();
    let [lo, hi] = ranges.overall();
    let zero = all.iter().filter(|r| r[1] == 0).count();
    let constant = all.iter().filter(|r| r[0] == r[1]).count();
    let mean_width =
        all.iter().map(|r| f64::from(r[1] - r[0])).sum::<f64>() / all.len().max(1) as f64;
    // (In the values' order: a negative scale turns the stored order around.)
    let [min, max] = ordered(lo, hi);
    println!("values      min {min}, max {max}");
    println!(
        "brick stats {zero} all-zero ({:.1} %), {constant} constant ({:.1} %), mean value range {mean_width:.1}",
        100.0 * zero as f64 / all.len() as f64,
        100.0 * constant as f64 / all.len() as f64
    );
    if volume.level_count() > 1 {
        let place = match h.pyramid_offset {
            Some(_) => "in the file".to_string(),
            None => format!(
                "in {}",
                raycaster::volume::pyramid_sidecar_path(&a.file).display()
            ),
        };
        let levels = counted(volume.level_count() as u64 - 1, "level");
        println!("pyramid     {levels} beyond full resolution, {place}");
        for k in 1..volume.level_count() {
            let level = volume.level(k);
            let [lo, hi] = level.ranges().overall();
            let [min, max] = ordered(lo, hi);
            println!(
                "  level {k}   {} spacing {}, {} bytes, values {min} to {max}",
                describe_size(level.dims()),
                describe_spacing(level.spacing()),
                level.data_bytes(),
            );
        }
    } else if !raycaster::volume::level_dims(h.dims).is_empty() {
        let sidecar = raycaster::volume::pyramid_sidecar_path(&a.file);
        // A sidecar that is there but not read: stale (the file changed after
        // it was built; a damaged one is warned of when the file opens).
        if sidecar.is_file() && volume.ignored_pyramid().is_none() {
            println!(
                "pyramid     none: {} is stale, built before the file last changed (`volgen pyramid {}` builds it again)",
                sidecar.display(),
                a.file.display()
            );
        } else {
            println!(
                "pyramid     none (`volgen pyramid {}` adds one)",
                a.file.display()
            );
        }
    }
    match volume.stored_cells() {
        Some(cells) => {
            let shape = cells.shape();
            println!(
                "cell ranges stored for every level: {}³ cells of {} voxels per brick of side {}",
                shape.per_axis(),
                shape.cell_step(),
                shape.grid().side()
            );
        }
        None => {
            let how = if raycaster::volume::level_dims(h.dims).is_empty() {
                "a volume this small has no pyramid block to hold them"
            } else if volume.level_count() == 1 {
                "`volgen pyramid` stores them with the pyramid"
            } else if h.pyramid_offset.is_some() {
                "the file predates them; `volgen convert` rewrites it with them"
            } else {
                "the sidecar predates them; `volgen pyramid --force` rebuilds it"
            };
            println!("cell ranges not stored: computed while rendering ({how})");
        }
    }
    if !a.no_histogram {
        let input = Input::open_vol(&a.file)?;
        let bar = voxel_bar(voxels, "histogram", a.quiet);
        let on_progress = |n| bar.inc(n);
        let job = Job::silent()
            .with_progress(&on_progress)
            .with_cancel(&CANCEL);
        let hist = raycaster::histogram::Histogram::of_input(&input, &job)?;
        bar.finish_and_clear();
        print!("{}", hist.summary(h.sample_type.max_value(), &units));
    }
    Ok(())
}

/// `volgen info` on a foreign file: its header as read, and its values in the file's
/// own units (min, max and a histogram over that range, two streaming passes).
fn run_foreign(a: &InfoArgs) -> anyhow::Result<()> {
    use raycaster::import;
    let imported = import::open(&a.file)?;
    println!("file        {}", a.file.display());
    println!("format      {}", imported.format.name());
    println!(
        "size        {} ({})",
        describe_size(imported.dims),
        counted(imported.voxels(), "voxel")
    );
    println!("spacing     {}", describe_spacing(imported.spacing));
    // What convert and render refuse (a spacing or extent beyond what is
    // read) is said, with the flag that overrides it.
    let header = raycaster::volume::Header::new(
        imported.dims,
        imported.spacing,
        raycaster::volume::Layout::Linear,
        raycaster::volume::SampleType::U16,
        raycaster::volume::Content::Scalar,
        raycaster::volume::Format::Extended,
    );
    if let Err(e) = header.validate() {
        eprintln!(
            "warning: `volgen convert` refuses this file's spacing ({e}); give one with `volgen convert --spacing X,Y,Z`"
        );
    }
    println!(
        "samples     {}, {} endian, {} data",
        imported.sample,
        match imported.endian {
            raycaster::io::Endian::Little => "little",
            raycaster::io::Endian::Big => "big",
        },
        crate::convert::encoding_name(imported.encoding)
    );
    if let Some(orientation) = &imported.orientation {
        println!("orientation {}", orientation.describe());
    }
    if let Some((slope, inter)) = imported.scaling {
        println!(
            "scaling     {} (the values below are scaled)",
            raycaster::text::scaling_text(slope, inter)
        );
    }
    if a.no_histogram {
        return Ok(());
    }
    let scratch = std::env::temp_dir();
    let input = imported.input(Some(&scratch), import::DECOMPRESS_IN_MEMORY_MAX)?;
    let voxels = imported.voxels();
    let bar = voxel_bar(2 * voxels, "histogram", a.quiet);
    let on_progress = |n| bar.inc(n);
    let job = Job::silent()
        .with_progress(&on_progress)
        .with_cancel(&CANCEL);
    let units = imported.units();
    let to_value = |v: f32| units.value(f64::from(v)) as f32;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut non_finite = 0u64;
    input.for_each_value(8 << 20, &to_value, &job, |slab| {
        for &v in slab {
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            } else {
                non_finite += 1;
            }
        }
    })?;
    if lo > hi {
        bar.finish_and_clear();
        println!("values      no finite values");
        return Ok(());
    }
    const BINS: usize = 16;
    let mut counts = [0u64; BINS];
    // Whole-number values (every type but f32, unscaled) get whole-number bins.
    let whole = imported.sample != raycaster::io::RawType::F32 && imported.scaling.is_none();
    // (In f64: the span of f32 values can pass f32's range.)
    let span = f64::from(hi) - f64::from(lo);
    let width = if whole {
        ((span + 1.0) / BINS as f64).ceil()
    } else {
        span / BINS as f64
    };
    input.for_each_value(8 << 20, &to_value, &job, |slab| {
        for &v in slab {
            if v.is_finite() {
                let i = if width > 0.0 {
                    (((f64::from(v) - f64::from(lo)) / width) as usize).min(BINS - 1)
                } else {
                    0
                };
                counts[i] += 1;
            }
        }
    })?;
    bar.finish_and_clear();
    println!(
        "values      min {}, max {} (the file's units)",
        units.format(f64::from(lo)),
        units.format(f64::from(hi))
    );
    if non_finite > 0 {
        // (What convert, render and the viewer store them as.)
        println!(
            "            {} (left out of the histogram; stored as the window's ends)",
            raycaster::convert::non_finite_count(non_finite, voxels)
        );
    }
    let used = if whole {
        // (Bins past the largest value stay out.)
        ((span / width) as usize + 1).min(BINS)
    } else if width > 0.0 {
        BINS
    } else {
        // One value: one bin (not sixteen with the same label).
        1
    };
    println!(
        "histogram   {} over min..max, bars on a log scale",
        counted(used as u64, "bin")
    );
    let peak = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    // Six decimals, or more where bins are narrower (labels that differ).
    let resolution = if width > 0.0 { width.min(2e-6) } else { 2e-6 };
    let number = |v: f64| ValueUnits::IDENTITY.format_resolved(v, resolution);
    for (i, &c) in counts.iter().take(used).enumerate() {
        let from = f64::from(lo) + width * i as f64;
        let label = if whole {
            let to = (from + width - 1.0).min(f64::from(hi));
            format!("{}..{}", number(from), number(to))
        } else {
            number(from)
        };
        let bar = ((c as f64).ln_1p() / peak.ln_1p() * 40.0).round() as usize;
        println!("  {label:>12} {c:>12} {}", "#".repeat(bar));
    }
    Ok(())
}

/// `0.5 x 0.5 x 2`; absurd sizes in exponent form (`1e-40`, not forty digits).
fn describe_spacing(spacing: [f32; 3]) -> String {
    spacing.map(raycaster::volume::number_text).join(" x ")
}
