//! The sweep's plot: frame time and samples/s per render thread against render threads,
//! tile size and brick size (2 × 3 panels), drawn with plotters as PNG or SVG.
//!
//! Each panel draws every record as a faint point and, per renderer and
//! optimisation set, a line through the best value at each parameter value (the
//! other parameters at their best). Text uses an embedded subset of DejaVu Sans, so
//! no system font is needed.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use raycaster::render::RgbImage;

use crate::bench::{Record, write_atomically};

/// Plot size in pixels.
const SIZE: (u32, u32) = (1500, 900);

/// DejaVu Sans, printable ASCII and a few symbols (see fonts/LICENSE-DejaVu.txt).
static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans-subset.ttf");

/// Whether a plot to `path` is written as SVG (it ends in `.svg`), else PNG.
pub fn is_svg(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// Writes the plot of `records` to `path`: SVG when it ends in `.svg`, else PNG.
pub fn write(path: &Path, records: &[Record]) -> Result<()> {
    register_font()?;
    if is_svg(path) {
        let mut text = String::new();
        draw(
            SVGBackend::with_string(&mut text, SIZE).into_drawing_area(),
            records,
        )?;
        write_atomically(path, text.as_bytes())
    } else {
        let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        draw(
            BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(),
            records,
        )?;
        // (The image's error names the file.)
        Ok(RgbImage::new(SIZE.0, SIZE.1, rgb).save_png(path)?)
    }
}

fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    ok.then_some(())
        .ok_or_else(|| anyhow!("the embedded plot font does not load"))
}

/// A parameter on the x axis.
struct Parameter {
    name: &'static str,
    value: fn(&Record) -> Option<f64>,
}

/// A value on the y axis, and whether smaller is better.
struct Metric {
    name: &'static str,
    value: fn(&Record) -> f64,
    lower_is_better: bool,
}

/// Series colours (distinct on white).
const COLOURS: [RGBColor; 6] = [
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
];

const PARAMETERS: [Parameter; 3] = [
    Parameter {
        name: "render threads",
        value: |r| r.case.threads.map(|t| t as f64),
    },
    Parameter {
        name: "tile side (px)",
        value: |r| r.case.threads.map(|_| f64::from(r.case.tile)),
    },
    Parameter {
        name: "brick side (voxels)",
        value: |r| r.case.brick.map(f64::from),
    },
];

const METRICS: [Metric; 2] = [
    Metric {
        name: "frame time (ms)",
        value: Record::frame_ms,
        lower_is_better: true,
    },
    Metric {
        name: "M samples/s per render thread",
        value: |r| r.samples_per_second_per_thread() / 1e6,
        lower_is_better: false,
    },
];

fn draw<B: DrawingBackend>(root: DrawingArea<B, Shift>, records: &[Record]) -> Result<()>
where
    B::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<B::ErrorType>| anyhow!("cannot draw the plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let title = records.first().map_or_else(String::new, |r| {
        format!(
            "raycaster bench: {}, {}x{}, step {}",
            r.case.volume.name(),
            r.case.image[0],
            r.case.image[1],
            r.case.step
        )
    });
    let root = root.titled(&title, ("sans-serif", 22)).map_err(err)?;
    let panels = root.split_evenly((METRICS.len(), PARAMETERS.len()));
    for (i, area) in panels.iter().enumerate() {
        let metric = &METRICS[i / PARAMETERS.len()];
        let parameter = &PARAMETERS[i % PARAMETERS.len()];
        panel(area, records, parameter, metric).map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Series key: renderer and optimisation set, e.g. "parallel both".
fn series_name(r: &Record) -> String {
    format!("{} {}", r.case.renderer(), r.case.optimisations)
}

fn panel<B: DrawingBackend>(
    area: &DrawingArea<B, Shift>,
    records: &[Record],
    parameter: &Parameter,
    metric: &Metric,
) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
    let points: Vec<(String, f64, f64)> = records
        .iter()
        .filter_map(|r| Some((series_name(r), (parameter.value)(r)?, (metric.value)(r))))
        .collect();
    // Parameter values are categories, evenly spaced (8, 16, 32 read as a log axis).
    let mut keys: Vec<f64> = points.iter().map(|p| p.1).collect();
    keys.sort_by(f64::total_cmp);
    keys.dedup();
    // Key k at x = k's index; an empty step either side keeps a lone value
    // off the axes (it sat on the y axis, half drawn, without its label).
    let at = |x: f64| keys.iter().position(|&k| k == x).unwrap_or(0) as i32;
    let y_hi = points.iter().map(|p| p.2).fold(0.0, f64::max).max(1e-6) * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{} by {}", metric.name, parameter.name),
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(60)
        .build_cartesian_2d(-1..keys.len() as i32, 0.0..y_hi)?;
    chart
        .configure_mesh()
        .light_line_style(TRANSPARENT)
        .x_desc(parameter.name)
        .x_labels(keys.len() + 2)
        .x_label_formatter(&|i| {
            usize::try_from(*i)
                .ok()
                .and_then(|i| keys.get(i))
                .map_or_else(String::new, |k| format!("{k}"))
        })
        .y_label_formatter(&|y| format!("{y:.1}"))
        .label_style(("sans-serif", 13))
        .draw()?;
    chart.draw_series(
        points
            .iter()
            .map(|&(_, x, y)| Circle::new((at(x), y), 3, BLACK.mix(0.25).filled())),
    )?;
    // Best value per series and parameter value.
    let mut best: BTreeMap<&str, BTreeMap<u64, f64>> = BTreeMap::new();
    for (name, x, y) in &points {
        let slot = best
            .entry(name.as_str())
            .or_default()
            .entry(x.to_bits())
            .or_insert(*y);
        let better = if metric.lower_is_better {
            *y < *slot
        } else {
            *y > *slot
        };
        if better {
            *slot = *y;
        }
    }
    for (i, (name, line)) in best.into_iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let mut line: Vec<(f64, f64)> = line
            .into_iter()
            .map(|(x, y)| (f64::from_bits(x), y))
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        let line: Vec<(i32, f64)> = line.into_iter().map(|(x, y)| (at(x), y)).collect();
        chart
            .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2))
            });
        chart.draw_series(
            line.into_iter()
                .map(move |(x, y)| Circle::new((x, y), 4, colour.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The embedded font loads, and a plot draws text (dark pixels in the title band).
    #[test]
    fn the_png_plot_has_text_and_lines() {
        let dir = tempfile::tempdir().unwrap();
        let case = raycaster_benches::BenchCase::default();
        let records: Vec<Record> = [(1, 8, 30.0), (2, 8, 16.0), (1, 16, 28.0), (2, 16, 15.0)]
            .into_iter()
            .map(|(t, tile, ms)| Record {
                case: raycaster_benches::BenchCase {
                    threads: Some(t),
                    tile,
                    brick: Some(16),
                    ..case.clone()
                },
                frame: std::time::Duration::from_secs_f64(ms / 1e3),
                median: std::time::Duration::from_secs_f64(ms / 1e3),
                spread: std::time::Duration::ZERO,
                frames: 1,
                samples: 1_000_000,
            })
            .collect();
        let path = dir.path().join("p.png");
        write(&path, &records).unwrap();
        let image = RgbImage::load_png(&path).unwrap();
        assert_eq!((image.width(), image.height()), SIZE);
        let dark = |y0: u32, y1: u32| {
            (y0..y1)
                .flat_map(|y| (0..SIZE.0).map(move |x| (x, y)))
                .filter(|&(x, y)| image.pixel(x, y).iter().all(|&c| c < 100))
                .count()
        };
        assert!(dark(0, 30) > 200, "the title is drawn");
        let coloured = image
            .data()
            .chunks(3)
            .filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() > 80)
            .count();
        assert!(coloured > 500, "series lines are drawn ({coloured} pixels)");
        let svg = dir.path().join("p.svg");
        write(&svg, &records).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.starts_with("<svg") && text.contains("render threads"));
    }
}
