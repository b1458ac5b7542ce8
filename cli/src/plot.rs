//! A small SVG plot of benchmark records: frame time and samples/s per core for
//! every configuration, as two bar charts one above the other.

use std::fmt::Write as _;

use crate::bench::Record;

const WIDTH: f64 = 900.0;
const CHART: f64 = 260.0;
const LEFT: f64 = 70.0;
const TOP: f64 = 40.0;

/// A value plotted per record.
type Metric = fn(&Record) -> f64;

/// The SVG document.
pub fn svg(records: &[Record]) -> String {
    let n = records.len().max(1) as f64;
    let bar = ((WIDTH - LEFT - 20.0) / n).max(2.0);
    let height = TOP + 2.0 * (CHART + 90.0);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{height}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let charts: [(&str, Metric); 2] = [
        ("frame time (ms)", |r| r.frame.as_secs_f64() * 1e3),
        ("M samples/s per render thread", |r| {
            r.samples_per_second_per_core() / 1e6
        }),
    ];
    for (c, (title, value)) in charts.iter().enumerate() {
        let y0 = TOP + c as f64 * (CHART + 90.0);
        let max = records.iter().map(value).fold(0.0f64, f64::max).max(1e-9);
        let _ = writeln!(
            out,
            "<text x=\"{LEFT}\" y=\"{}\" font-size=\"14\">{title}</text>",
            y0 - 10.0
        );
        let _ = writeln!(
            out,
            "<line x1=\"{LEFT}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>",
            y0 + CHART,
            WIDTH - 10.0,
            y0 + CHART
        );
        for tick in 0..=4 {
            let v = max * tick as f64 / 4.0;
            let y = y0 + CHART - CHART * tick as f64 / 4.0;
            let _ = writeln!(
                out,
                "<text x=\"{}\" y=\"{y}\" text-anchor=\"end\">{v:.1}</text><line x1=\"{LEFT}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"#ddd\"/>",
                LEFT - 5.0,
                WIDTH - 10.0
            );
        }
        for (i, r) in records.iter().enumerate() {
            let h = CHART * value(r) / max;
            let x = LEFT + i as f64 * bar;
            let colour = match r.threads {
                1 if r.renderer == "sequential" => "#888888",
                1 => "#4e79a7",
                2 => "#f28e2b",
                3 | 4 => "#59a14f",
                _ => "#e15759",
            };
            let _ = writeln!(
                out,
                "<rect x=\"{x:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{h:.1}\" fill=\"{colour}\"><title>{} t{} tile{} brick{} {}: {:.2}</title></rect>",
                y0 + CHART - h,
                (bar - 1.0).max(1.0),
                r.renderer,
                r.threads,
                r.tile,
                r.brick,
                r.optimisations,
                value(r)
            );
            let label = if r.renderer == "sequential" {
                format!("seq b{}", r.brick)
            } else {
                format!("t{} {}px b{}", r.threads, r.tile, r.brick)
            };
            let (lx, ly) = (x + bar / 2.0, y0 + CHART + 8.0);
            let _ = writeln!(
                out,
                "<text x=\"{lx:.1}\" y=\"{ly:.1}\" transform=\"rotate(60 {lx:.1} {ly:.1})\" font-size=\"9\">{label} {}</text>",
                r.optimisations
            );
        }
    }
    out.push_str("</svg>\n");
    out
}
