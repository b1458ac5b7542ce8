//! `raycaster slice`: one axis-aligned slice of a volume as a greyscale PNG.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};
use raycaster::slice::{Axis, PlaneLayout, Slice};
use raycaster::volume::{Access, OpenOptions, Volume};

use crate::args::{WindowArg, parse_index, parse_window};

/// Write one slice of a volume as a greyscale PNG.
///
/// The slice is read through the volume's samples (a mapped .vol file reads only
/// the pages of that plane), linear or bricked, u8 or u16; NRRD, NIfTI-1,
/// MetaImage files and DICOM series are converted in memory first. A volume
/// placed in the patient (a medical file's orientation) is shown as
/// radiologists read it: axial slices seen from the feet (the patient's right
/// on the left, anterior at the top), coronal ones from the front, sagittal
/// ones from the patient's left (anterior on the left), superior at the top.
/// Other volumes, and `--volume-axes`, keep voxel order: columns along x
/// (along y for x slices), rows along y for z slices and along z otherwise,
/// the highest coordinate at the top. Pixels are square: where the
/// voxel spacing differs between the two axes (CT slices farther apart than
/// their pixels), the coarser axis is stretched, interpolating between its
/// voxels; `--voxels` writes one pixel per voxel. The output is checked before
/// reading (a .png name, an existing folder; an existing file only with
/// `--force`) and written atomically.
#[derive(Args, Debug)]
#[command(after_help = SLICE_HELP, allow_negative_numbers = true)]
pub struct SliceArgs {
    /// The volume: a .vol file, or a file or folder `raycaster render` opens.
    file: PathBuf,

    /// The axis the slice is perpendicular to.
    #[arg(long, value_enum)]
    axis: AxisArg,

    /// The slice's index along the axis, 0 to size − 1.
    #[arg(long, value_name = "N", value_parser = parse_index)]
    index: u32,

    /// Output PNG (the name must end in .png).
    #[arg(short, long, value_name = "PNG")]
    output: PathBuf,

    /// Replace the output image if it exists.
    #[arg(long)]
    force: bool,

    /// Values shown black and white, LO,HI (or LO:HI) in the file's units
    /// (Hounsfield units for CT: `--window -160,240`), or a named CT window: ct, bone,
    /// soft-tissue, lung, brain. Default: the slice's own value range (a slice of one value: the volume's). Files
    /// converted before value units were kept take stored sample values.
    #[arg(long, value_parser = parse_window, allow_hyphen_values = true, value_name = "LO,HI|NAME")]
    window: Option<WindowArg>,

    /// One pixel per voxel, whatever the spacing (by default the axis with the
    /// larger spacing is stretched to square pixels).
    #[arg(long)]
    voxels: bool,

    /// Keep voxel order on a volume placed in the patient, instead of showing
    /// the slice as radiologists read it (axial from the feet, coronal from the
    /// front, sagittal from the patient's left).
    #[arg(long)]
    volume_axes: bool,

    /// Print nothing on success.
    #[arg(short, long)]
    quiet: bool,
}

const SLICE_HELP: &str = "Examples:
  raycaster slice lung1.vol --axis z --index 24 -o axial.png
  raycaster slice lung1.vol --axis y --index 256 --window -1000,2000 -o coronal.png --force
  raycaster slice lung1.vol --axis z --index 24 --window lung -o lung.png
  raycaster slice lung1.vol --axis y --index 256 --voxels -o coronal-voxels.png";

#[derive(Clone, Copy, Debug, ValueEnum)]
enum AxisArg {
    X,
    Y,
    Z,
}

/// Runs the slice command.
pub fn run(args: SliceArgs) -> Result<()> {
    let inputs = raycaster::import::volume_files(&args.file);
    crate::output::check_output_of(&args.output, args.force, inputs)?;
    raycaster::files::guard_mapped_file(&args.file);
    let volume = if raycaster::import::detect(&args.file).is_some() {
        let (volume, warning) = raycaster::import::open(&args.file)?.to_volume_noting(
            raycaster::import::DEFAULT_IN_MEMORY_LIMIT,
            &raycaster::job::Job::silent(),
        )?;
        if let Some(warning) = warning.filter(|_| !args.quiet) {
            eprintln!("warning: {warning}");
        }
        volume
    } else {
        let options = OpenOptions {
            access: Access::Mapped,
            ..OpenOptions::default()
        };
        let volume = Volume::open_with(&args.file, options)?;
        if !args.quiet {
            for warning in volume.open_warnings() {
                eprintln!("{warning}");
            }
        }
        volume
    };
    let axis = match args.axis {
        AxisArg::X => Axis::X,
        AxisArg::Y => Axis::Y,
        AxisArg::Z => Axis::Z,
    };
    let (layout, plane) = if args.volume_axes {
        (PlaneLayout::voxel_order(axis), None)
    } else {
        PlaneLayout::patient(axis, volume.orientation())
    };
    if plane.is_none() && !args.volume_axes && !args.quiet && volume.orientation().is_some() {
        // Two of the voxel axes are nearest the same patient axis (an oblique
        // volume at about 45°): there is no reading to show it in.
        eprintln!(
            "note: {}'s voxel axes lie about 45° from the patient's, so this slice has no \
             anatomical reading: it keeps voxel order, as with --volume-axes",
            args.file.display()
        );
    }
    let slice = Slice::extract_laid_out(&volume, axis, args.index, layout)
        .map_err(|e| anyhow::anyhow!("--index {}: {e}", args.index))?;
    let units = volume.value_units();
    if let Some(warning) = args
        .window
        .and_then(|w| w.named_on_plain_data("--window", &volume, &args.file.display().to_string()))
        .filter(|_| !args.quiet)
    {
        eprintln!("{warning}");
    }
    let asked = args.window.map(|w| {
        let [lo, hi] = units.stored_range(w.values());
        // A window narrower than f32 holds at the stored values (0 to 0.001 HU
        // is 32768 to 32768 stored): a threshold there, as typed (lo < hi).
        [lo, if hi > lo { hi } else { lo.next_up() }]
    });
    // Without one, the slice's own range; a slice of one value (empty space)
    // is shown as in the volume's range (black for its lowest value), not as
    // a flat mid-grey.
    let [slice_lo, slice_hi] = slice.range();
    let volume_range = volume.ranges().overall();
    let flat = asked.is_none() && slice_lo == slice_hi && volume_range[0] < volume_range[1];
    let window = asked.or(flat.then(|| volume_range.map(f32::from)));
    // A window beside all of the slice's values shows one grey: say so.
    if let (Some(arg), Some([lo, hi])) = (args.window, asked)
        && !args.quiet
    {
        let [min, max] = slice.range().map(f32::from);
        if hi < min || lo > max {
            let [a, b] = arg.values().map(|v| units.format(f64::from(v)));
            let [c, d] = [min, max].map(|v| units.format(units.value(f64::from(v))));
            let shade = if hi < min { "white" } else { "black" };
            eprintln!(
                "warning: --window {a} to {b} lies outside this slice's values, {c} to {d}: \
                 the slice is all {shade}"
            );
        }
    }
    let spacing = volume.spacing();
    let (u, v) = (layout.columns, layout.rows);
    let image = if args.voxels {
        slice.to_image(window)
    } else {
        slice.to_square_image(window, [spacing[u], spacing[v]])
    }
    .map_err(|e| anyhow::anyhow!("--window: {e}"))?;
    image.save_png(&args.output)?;
    if !args.quiet {
        let [lo, hi] = slice
            .range()
            .map(|v| units.format(units.value(f64::from(v))));
        // Say how the voxels became pixels where they are not one to one, and
        // where the pixels are not square (--voxels, or the stretch's limit).
        let (w, h) = (image.width(), image.height());
        let pixel = |side: u32, voxels: u32, axis: usize| {
            f64::from(spacing[axis]) * f64::from(voxels) / f64::from(side)
        };
        let aspect = pixel(w, slice.width, u) / pixel(h, slice.height, v);
        // Stretched pixels are square but for rounding to whole pixels, unless
        // the stretch stopped at its limit.
        let capped = w.max(h) >= raycaster::slice::MAX_SQUARE_SIDE;
        let square = (aspect - 1.0).abs() <= 0.01 || !(args.voxels || capped);
        let shape = if aspect > 1.0 {
            format!("pixels {aspect:.3}× as wide as high")
        } else {
            format!("pixels {:.3}× as high as wide", 1.0 / aspect)
        };
        let unstretched = (w, h) == (slice.width, slice.height);
        let stretched = match (unstretched, square, args.voxels) {
            (true, true, _) => String::new(),
            (true, false, true) => format!(", {shape}"),
            (true, false, false) => format!(
                ", {shape}: the stretch stops at {} pixels a side",
                raycaster::slice::MAX_SQUARE_SIDE
            ),
            (false, true, _) => format!(
                " from {}×{} voxels, stretched to square pixels",
                slice.width, slice.height
            ),
            (false, false, _) => format!(
                " from {}×{} voxels, stretched to {} pixels a side: {shape}",
                slice.width,
                slice.height,
                raycaster::slice::MAX_SQUARE_SIDE
            ),
        };
        // The anatomical plane, and where the patient lies in the picture, for
        // a volume placed in the patient.
        let (plane, seen) = match (plane, volume.orientation()) {
            (Some(plane), Some(orientation)) => {
                let [left, top] = layout.left_and_top(orientation);
                (
                    format!("{} ", plane.name()),
                    format!(", {left} on the left, {top} at the top"),
                )
            }
            _ => (String::new(), String::new()),
        };
        // The values shown black and white: the window asked for, else the
        // slice's own range.
        let shown = match args.window {
            Some(window) => {
                let [black, white] = window.values().map(|v| units.format(f64::from(v)));
                format!("black at {black}, white at {white}; the slice's values {lo} to {hi}")
            }
            None if flat => {
                let [black, white] = volume_range.map(|v| units.format(units.value(f64::from(v))));
                format!(
                    "every value {lo}, shown as in the volume's values {black} (black) to {white} (white)"
                )
            }
            None if slice_lo == slice_hi => {
                format!("every value {lo}, as in the whole volume: grey")
            }
            None => format!("values {lo} (black) to {hi} (white)"),
        };
        eprintln!(
            "wrote {} ({w}×{h}{stretched}, {plane}slice {} = {} of {}{seen}, {shown})",
            args.output.display(),
            axis,
            args.index,
            args.file.display()
        );
    }
    Ok(())
}
