//! `volgen convert`: raw, `.vol`, NRRD, NIfTI-1 or MetaImage in; `.vol` of another
//! layout / brick / type out.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use raycaster::convert::{ConvertOptions, ConvertSummary, ValueMap, convert};
use raycaster::import::{self, Imported};
use raycaster::io::{Input, InputType, RawSpec, WriteOptions};
use raycaster::job::Job;
use raycaster::volume::{Format, Layout, SampleType, ValueUnits, pyramid_voxels};

use crate::args::{
    EndianArg, FormatArg, LayoutArg, RawOrderArg, RawTypeArg, SampleArg, WindowArg, parse_brick,
    parse_dims, parse_spacing, parse_window, wrong_command_line,
};
use crate::generate::{describe_layout, describe_pyramid, describe_size};
use crate::output::{check_output, output_name_warning, padding_warning, ray_length_warning};
use crate::progress::{CANCEL, voxel_bar};

/// Convert a raw, .vol, NRRD, NIfTI-1, MetaImage file or DICOM series into a .vol file.
///
/// Inputs: .vol; NRRD (.nrrd, .nhdr; raw or gzip); NIfTI-1 (.nii, .nii.gz, .hdr/.img);
/// MetaImage (.mha, .mhd; raw or zlib); a folder (or .dcm file) of an uncompressed
/// DICOM series; headerless raw with --raw. Foreign files
/// keep their spacing and axis order (first axis fastest = x; the samples are never
/// resampled); their orientation in the patient and what stored values mean
/// (rescale slope and intercept, HU for CT) are kept in the output's header, and
/// the renderer and viewer use both (docs/import.md).
///
/// Streams in bounded memory (slabs of whole x-planes; about 64 MiB at most plus one
/// row of bricks), so inputs larger than RAM convert; compressed inputs larger than
/// 256 MiB are first decompressed into a temporary file beside the output. Values
/// are copied when the output type holds them all; i16 to u16 stores value + 32768
/// (exact); otherwise (u16/i16/f32 to u8, f32 to u16) they are mapped linearly from
/// --window (default: the input's own finite min..max) onto the output's full
/// range; values outside it, ±infinity included, clamp to its ends, and NaN is
/// stored as its low end (the default window's pass counts them and warns; an
/// input without one finite value is refused). Examples:
///
///   volgen convert volumes/data/brainsmall.den --raw 128x128x84 --skip 62 -o brainsmall.vol
///
///   volgen convert volumes/data/lung1_image.nrrd --type u8 --window -1000:2000 -o lung1-u8.vol
///
///   volgen convert volumes/data/lung1_image.nrrd -o lung1.vol
///
///   volgen convert volumes/data/ch2.nii.gz --layout linear -o ch2.vol
///
///   volgen convert shapes.vol --layout linear -o shapes-linear.vol
///
///   volgen convert segmentation.nrrd --labels -o scan.labels.vol
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ConvertArgs {
    /// Input: .vol, .nrrd/.nhdr, .nii/.nii.gz/.hdr, .mha/.mhd, a DICOM series folder
    /// (or .dcm file), or a headerless raw file when --raw is given.
    #[arg(value_name = "IN")]
    input: PathBuf,
    /// Output .vol file.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Read IN as headerless raw samples of this size (N or XxYxZ).
    #[arg(long, value_name = "N|XxYxZ", value_parser = parse_dims)]
    raw: Option<[u32; 3]>,
    /// Raw sample type.
    #[arg(long, value_enum, default_value_t = RawTypeArg::U8, requires = "raw")]
    raw_type: RawTypeArg,
    /// Raw byte order.
    #[arg(long, value_enum, default_value_t = EndianArg::Little, requires = "raw")]
    endian: EndianArg,
    /// Bytes to skip at the start of the raw file (a foreign header).
    #[arg(long, value_name = "BYTES", default_value_t = 0, requires = "raw")]
    skip: u64,
    /// Which coordinate changes fastest in the raw file.
    #[arg(long, value_enum, default_value_t = RawOrderArg::X, requires = "raw")]
    raw_order: RawOrderArg,
    /// Output sample order [default: the input's; bricked for raw input].
    #[arg(long, value_enum)]
    layout: Option<LayoutArg>,
    /// Output brick side [default: the input's, or 16].
    #[arg(long, value_name = "N", value_parser = parse_brick)]
    brick: Option<u8>,
    /// Output sample type [default: u8 for u8 input, otherwise u16].
    #[arg(long = "type", value_enum)]
    sample_type: Option<SampleArg>,
    /// Input values LO..HI, in the input file's own units (CT: Hounsfield units,
    /// e.g. -1000:2000; LO,HI works too), map onto the output's full range
    /// (clamped outside); or a named CT window: ct, bone, soft-tissue, lung,
    /// brain.
    #[arg(long, value_name = "LO:HI|NAME", allow_hyphen_values = true, value_parser = parse_window)]
    window: Option<WindowArg>,
    /// The input is a segmentation (object ids 0 to 255, e.g. from a
    /// segmentation tool's NRRD or NIfTI): write a label volume for
    /// `raycaster render --labels` and scene files' `labels = ...` (u8 ids,
    /// never interpolated). Fractions are cut to their whole part (toward
    /// zero); values whose whole part lies beyond 0..=255 are refused.
    #[arg(long, conflicts_with_all = ["window", "sample_type"])]
    labels: bool,
    /// Output voxel spacing: S or X,Y,Z [default: the input's, or 1].
    #[arg(long, value_name = "S|X,Y,Z", value_parser = parse_spacing, allow_hyphen_values = true)]
    spacing: Option<[f32; 3]>,
    /// Output header format.
    #[arg(long, value_enum, default_value_t = FormatArg::Extended)]
    format: FormatArg,
    /// Replace an existing output file.
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

pub fn run(a: ConvertArgs) -> anyhow::Result<()> {
    // Before the input is read.
    check_output(&a.output, a.force)?;
    if let Some(warning) = output_name_warning(&a.output).filter(|_| !a.quiet) {
        eprintln!("{warning}");
    }
    let input = match a.raw {
        Some(dims) => {
            let spec = RawSpec {
                dims,
                sample: a.raw_type.into(),
                endian: a.endian.into(),
                skip: a.skip,
                order: a.raw_order.into(),
            };
            // Said with volgen's flag (the library's error says "a skip of").
            let len = std::fs::metadata(&a.input).ok().filter(|m| m.is_file());
            if let Some(problem) = len.and_then(|m| spec.length_problem(m.len(), "--skip")) {
                anyhow::bail!("{}: {problem}", a.input.display());
            }
            Input::open_raw(&a.input, spec)?
        }
        None => match import::detect(&a.input) {
            Some(_) => {
                // A broken spacing is refused unless --spacing replaces it.
                let imported = match a.spacing {
                    Some(_) => import::open_unchecked(&a.input)?,
                    None => import::open(&a.input)?,
                };
                if !a.quiet {
                    eprintln!("{}", describe_import(&imported));
                }
                let scratch = a
                    .output
                    .parent()
                    .filter(|p| !p.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                // Decompression (or gathering slices) comes first: its own bar, and
                // Ctrl-C / SIGTERM stop it too.
                let bar = crate::progress::byte_bar(imported.sample_bytes(), "decompress", a.quiet);
                let on_progress = |n| bar.inc(n);
                let job = Job::silent()
                    .with_progress(&on_progress)
                    .with_cancel(&CANCEL);
                let input =
                    imported.input_with(Some(scratch), import::DECOMPRESS_IN_MEMORY_MAX, &job)?;
                bar.finish_and_clear();
                input
            }
            None => {
                raycaster::files::guard_mapped_file(&a.input);
                Input::open_vol(&a.input)?
            }
        },
    };
    if let Some(Err(why)) = input.embedded_ranges_intact()
        && !a.quiet
    {
        eprintln!(
            "warning: {}: {why}; the output's table is computed from the samples",
            a.input.display()
        );
    }
    if let Some(Err(why)) = input.embedded_pyramid_intact()
        && !a.quiet
    {
        let output = if a.no_pyramid {
            "the output has none (--no-pyramid)"
        } else {
            "the output's is built from the samples"
        };
        eprintln!("warning: {}: {why}; {output}", a.input.display());
    }
    if let Some(tail) = input.unused_tail()
        && !a.quiet
    {
        let warning = raycaster::volume::unused_tail_warning(&a.input, tail, "they are not copied");
        eprintln!("{warning}");
    }
    // A named window is in Hounsfield units: 8-bit data without value units
    // holds no HU (said as render's --domain and slice's --window say it).
    if let Some(WindowArg {
        name: Some(name), ..
    }) = a.window
        && input.units().is_identity()
        && input.value_type() == InputType::U8
        && !a.quiet
    {
        eprintln!(
            "warning: --window {name}: a CT window in Hounsfield units, and {} holds 8-bit samples without value units; --window LO:HI gives a range in its own values",
            a.input.display()
        );
    }
    let input_layout = input.header().map(|h| h.layout);
    let layout = match (a.layout, a.brick) {
        (Some(LayoutArg::Linear), Some(_)) => {
            wrong_command_line!("--brick applies to --layout bricked only")
        }
        (Some(LayoutArg::Linear), None) => Layout::Linear,
        (Some(LayoutArg::Bricked), side) | (None, side @ Some(_)) => Layout::Bricked {
            side: side
                .or(match input_layout {
                    Some(Layout::Bricked { side }) => Some(side),
                    _ => None,
                })
                .unwrap_or(16),
        },
        (None, None) => input_layout.unwrap_or(Layout::Bricked { side: 16 }),
    };
    // (As generate says it; an input whose own type is u16 is said by the
    // conversion, with the file's name.)
    if a.format == FormatArg::Thesis
        && a.sample_type
            .is_some_and(|t| SampleType::from(t) != SampleType::U8)
    {
        wrong_command_line!(
            "--format thesis holds u8 samples only; use --format extended for --type u16"
        );
    }
    let options = ConvertOptions {
        layout,
        sample_type: a.sample_type.map(SampleType::from),
        format: Format::from(a.format),
        spacing: a.spacing,
        window: a.window.map(|w| w.range),
        labels: a.labels,
    };
    if let Some(warning) = padding_warning(input.dims(), layout).filter(|_| !a.quiet) {
        eprintln!("{warning}");
    }
    let voxels: u64 = input.dims().iter().map(|&d| u64::from(d)).product();
    let extra = if a.no_pyramid {
        0
    } else {
        pyramid_voxels(input.dims())
    };
    // (The count includes the pyramid's voxels: say so.)
    let what = if extra > 0 {
        "convert + pyramid"
    } else {
        "convert"
    };
    // (An x-fastest input of more than 512 MiB is staged first: one more
    // pass over its voxels.)
    let staging = raycaster::convert::staging_voxels(&input);
    let bar = voxel_bar(voxels + extra + staging, what, a.quiet);
    let on_progress = |n| bar.inc(n);
    let job = Job::silent()
        .with_progress(&on_progress)
        .with_cancel(&CANCEL);
    let write = WriteOptions {
        overwrite: a.force,
        pyramid: !a.no_pyramid,
        ..WriteOptions::default()
    };
    let start = Instant::now();
    let done = convert(&input, &a.output, &options, &write, &job)?;
    bar.finish_and_clear();
    if done.non_finite > 0 && !a.quiet {
        let voxels: u64 = done.header.dims.iter().map(|&d| u64::from(d)).product();
        let warning = raycaster::convert::non_finite_warning(&a.input, done.non_finite, voxels);
        eprintln!("warning: {warning}");
    }
    if !a.quiet {
        if let Some(warning) = thesis_loss_warning(&a.input, &input, options.format) {
            eprintln!("{warning}");
        }
        if let Some(warning) = ray_length_warning(done.header.dims, done.header.spacing) {
            eprintln!("{warning}");
        }
        if let Some(window) = a.window
            && let Some(warning) = window_outside_warning(&input, window.range, &done)?
        {
            eprintln!("{warning}");
        }
    }
    if !a.quiet {
        let window = match done.values {
            // Said in the input's units, as --window takes them (a .vol file
            // of HU stores HU + 32768).
            ValueMap::Window(lo, hi) => {
                let [lo, hi] = values_in_units(input.units(), [lo, hi]);
                format!(", values {lo}..={hi} mapped to the full range")
            }
            ValueMap::Offset => ", i16 samples stored as sample + 32768".to_string(),
            ValueMap::Copy if a.labels => ", object ids copied (a label volume)".to_string(),
            ValueMap::Copy => ", values copied".to_string(),
        };
        let unit = match done.header.units.as_ref().map(|u| u.unit.as_str()) {
            Some(unit) if !unit.is_empty() => format!(" (values in {unit})"),
            _ => String::new(),
        };
        println!(
            "wrote {}: {} {}{}, {} bytes in {:.2} s{window}{unit}",
            a.output.display(),
            describe_size(done.header.dims),
            describe_layout(&done.header),
            describe_pyramid(done.written.pyramid_levels),
            done.written.file_bytes,
            start.elapsed().as_secs_f64(),
        );
    }
    Ok(())
}

/// `lo..hi` in stored input values said in `units` (the values --window takes),
/// lower first.
fn values_in_units(units: &ValueUnits, [lo, hi]: [f32; 2]) -> [f32; 2] {
    let [a, b] = [lo, hi].map(|v| units.value(f64::from(v)) as f32);
    if a <= b { [a, b] } else { [b, a] }
}

/// The warning for a thesis-format output of an input whose values have units
/// or which lies in the patient: the thesis header holds neither.
fn thesis_loss_warning(path: &Path, input: &Input, format: Format) -> Option<String> {
    if format != Format::Thesis {
        return None;
    }
    let units = input.units();
    let lost = match (!units.is_identity(), input.orientation().is_some()) {
        (true, true) => format!(
            "keeps neither what its values mean ({}) nor where it lies in the patient; the output stores plain samples (--format extended keeps both)",
            units.describe()
        ),
        (true, false) => format!(
            "cannot keep what its values mean ({}); the output stores plain samples (--format extended keeps it)",
            units.describe()
        ),
        (false, true) => {
            "cannot keep where it lies in the patient (--format extended keeps it)".into()
        }
        (false, false) => return None,
    };
    Some(format!(
        "warning: {}: the thesis format {lost}",
        path.display()
    ))
}

/// The warning when `--window` lies wholly outside the input's values, so that
/// the output is flat: said in the input's units, as `raycaster render
/// --domain` says it. The input's range is only measured when the output came
/// out flat.
fn window_outside_warning(
    input: &Input,
    (lo, hi): (f32, f32),
    done: &ConvertSummary,
) -> anyhow::Result<Option<String>> {
    let [out_lo, out_hi] = done.written.ranges.overall();
    if out_lo != out_hi {
        return Ok(None);
    }
    let job = Job::silent().with_cancel(&CANCEL);
    let Some((data_lo, data_hi)) = input.value_range(&job)?.finite else {
        return Ok(None);
    };
    let units = input.units();
    let [data_lo, data_hi] = values_in_units(units, [data_lo, data_hi]);
    if hi >= data_lo && lo <= data_hi {
        return Ok(None);
    }
    let [lo, hi, data_lo, data_hi] = [lo, hi, data_lo, data_hi].map(|v| units.format(f64::from(v)));
    Ok(Some(format!(
        "warning: --window {lo} to {hi} lies outside the data's values {data_lo} to {data_hi}; every voxel of the output holds one value"
    )))
}

/// One line on what a foreign file holds.
fn describe_import(i: &Imported) -> String {
    let ty = i.sample;
    let [sx, sy, sz] = i.spacing.map(raycaster::volume::number_text);
    let mut line = format!(
        "{}: {} {} {ty}, spacing {sx} x {sy} x {sz}, {} data",
        i.path.display(),
        i.format.name(),
        describe_size(i.dims),
        encoding_name(i.encoding),
    );
    if let Some((slope, inter)) = i.scaling {
        line += &format!(
            " (declares {}; stored values are kept)",
            raycaster::text::scaling_text(slope, inter)
        );
    }
    line
}

/// How a foreign file's samples are stored, for people.
pub fn encoding_name(e: raycaster::import::Encoding) -> &'static str {
    use raycaster::import::Encoding;
    match e {
        Encoding::Raw => "raw",
        Encoding::Gzip => "gzip",
        Encoding::Zlib => "zlib",
        Encoding::Slices => "one file per slice",
    }
}
