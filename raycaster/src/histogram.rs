//! Value histograms of volumes, computed in one streaming pass.

use crate::io::Input;
use crate::job::Job;
use crate::volume::{ValueUnits, VolumeError};

/// Exact counts of every sample value (one bin per value, up to 65536).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Histogram {
    counts: Vec<u64>,
    total: u64,
}

impl Histogram {
    /// Counts the values of a `.vol` input, slab by slab (bounded memory). Values of
    /// raw inputs of other types are saturated to u16.
    pub fn of_input(input: &Input, job: &Job) -> Result<Histogram, VolumeError> {
        let mut counts = vec![0u64; 1 << 16];
        input.for_each_value(8 << 20, &|v| v as u16, job, |slab| {
            for &v in slab {
                counts[v as usize] += 1;
            }
        })?;
        let last = counts.iter().rposition(|&c| c > 0).map_or(1, |i| i + 1);
        counts.truncate(last.max(256));
        Ok(Histogram {
            total: counts.iter().sum(),
            counts,
        })
    }

    /// Builds a histogram from per-value counts.
    pub fn from_counts(counts: Vec<u64>) -> Histogram {
        Histogram {
            total: counts.iter().sum(),
            counts,
        }
    }

    /// Count of each value (index = value).
    pub fn counts(&self) -> &[u64] {
        &self.counts
    }

    /// Number of samples counted.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Mean value.
    pub fn mean(&self) -> f64 {
        let sum: f64 = self
            .counts
            .iter()
            .enumerate()
            .map(|(v, &c)| v as f64 * c as f64)
            .sum();
        sum / self.total.max(1) as f64
    }

    /// The smallest value with at least `p` (0..=1) of the samples at or below it.
    pub fn percentile(&self, p: f64) -> u16 {
        let target = (p.clamp(0.0, 1.0) * self.total as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (v, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= target {
                return v as u16;
            }
        }
        self.counts.len().saturating_sub(1) as u16
    }

    /// Counts merged into `bins` equal-width bins over `0..=max_value`.
    pub fn coarse(&self, bins: usize, max_value: u16) -> Vec<u64> {
        let mut out = vec![0u64; bins.max(1)];
        let width = (usize::from(max_value) + 1).div_ceil(out.len());
        let last = out.len() - 1;
        for (v, &c) in self.counts.iter().enumerate() {
            out[(v / width).min(last)] += c;
        }
        out
    }

    /// The smallest and largest value counted (`[0, 0]` when empty).
    pub fn value_range(&self) -> [u16; 2] {
        let first = self.counts.iter().position(|&c| c > 0).unwrap_or(0);
        let last = self.counts.iter().rposition(|&c| c > 0).unwrap_or(0);
        [first as u16, last as u16]
    }

    /// Counts merged into at most `bins` equal-width bins over the values
    /// present ([`Self::value_range`]): each bin's first value and count.
    pub fn over_data(&self, bins: usize) -> Vec<(u16, u64)> {
        let [lo, hi] = self.value_range();
        let span = usize::from(hi - lo) + 1;
        let width = span.div_ceil(bins.max(1));
        let mut out: Vec<(u16, u64)> = (0..span.div_ceil(width))
            .map(|i| (lo + (i * width) as u16, 0))
            .collect();
        for (v, &c) in self.counts[usize::from(lo)..=usize::from(hi)]
            .iter()
            .enumerate()
        {
            out[v / width].1 += c;
        }
        out
    }

    /// A few lines for a terminal: summary figures and a bar chart of 16 bins
    /// over the values present (a CT scan's few thousand values of 65536 fill
    /// the chart instead of one bar), values in `units` (the file's: HU for CT);
    /// `max_value` is the type's largest sample.
    pub fn summary(&self, max_value: u16, units: &ValueUnits) -> String {
        let value = |s: f64| units.format(units.value(s));
        let stored = |s: u16| value(f64::from(s));
        let zero = self.counts.first().copied().unwrap_or(0);
        // A negative scale (a NIfTI slope of −1) turns the stored order
        // around: percentiles, ranges and bars are said in the values' order.
        let flip = units.scale < 0.0;
        let order = |a: u16, b: u16| if flip { [b, a] } else { [a, b] };
        // (The values' 1st percentile is the stored samples' 99th, flipped.)
        let [p1, p99] = order(self.percentile(0.01), self.percentile(0.99));
        let mut s = format!(
            "histogram   mean {}, p1 {}, median {}, p99 {}, {} {:.1} %\n",
            units.format((units.value(self.mean()) * 100.0).round() / 100.0),
            stored(p1),
            stored(self.percentile(0.5)),
            stored(p99),
            if units.is_identity() {
                "zero".to_string()
            } else {
                format!("at {}", stored(0))
            },
            100.0 * zero as f64 / self.total.max(1) as f64
        );
        let bins = self.over_data(16);
        let [lo, hi] = self.value_range();
        let [first, last] = order(lo, hi);
        let [type_first, type_last] = order(0, max_value);
        s += &format!(
            "            {} over the values present, {} to {} (of {} to {}), bars on a log scale\n",
            crate::text::counted(bins.len() as u64, "bin"),
            stored(first),
            stored(last),
            stored(type_first),
            stored(type_last)
        );
        let peak = bins.iter().map(|b| b.1).max().unwrap_or(1).max(1) as f64;
        let plain = ValueUnits {
            unit: String::new(),
            ..units.clone()
        };
        // Labels that tell neighbouring bins apart, however narrow the values.
        let width = bins.get(1).map_or(1, |b| b.0 - bins[0].0);
        let resolution = f64::from(width) * units.scale.abs();
        let label = |v: u16| plain.format_resolved(plain.value(f64::from(v)), resolution);
        let mut lines: Vec<String> = bins
            .iter()
            .enumerate()
            .map(|(i, &(first, c))| {
                let last = bins.get(i + 1).map_or(hi, |next| next.0 - 1);
                let [from, to] = order(first, last);
                // Log scale: a few voxels of a rare value still show.
                let bar = ((c as f64).ln_1p() / peak.ln_1p() * 40.0).round() as usize;
                format!(
                    "  {:>7}..{:<7} {c:>12} {}\n",
                    label(from),
                    label(to),
                    "#".repeat(bar)
                )
            })
            .collect();
        if flip {
            lines.reverse();
        }
        s.extend(lines);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_and_mean_of_a_known_histogram() {
        let mut counts = vec![0u64; 256];
        counts[0] = 50;
        counts[10] = 49;
        counts[200] = 1;
        let h = Histogram::from_counts(counts);
        assert_eq!(h.percentile(0.5), 0);
        assert_eq!(h.percentile(0.51), 10);
        assert_eq!(h.percentile(0.995), 200);
        assert!((h.mean() - (490.0 + 200.0) / 100.0).abs() < 1e-9);
        assert_eq!(h.coarse(2, 255), vec![99, 1]);
        assert_eq!(h.value_range(), [0, 200]);
        assert_eq!(h.over_data(2), vec![(0, 99), (101, 1)]);
    }

    #[test]
    fn a_negative_scale_is_said_in_the_values_order() {
        // value = 10 − stored (a NIfTI slope of −1): stored 0..=99 are 10..=−89.
        let counts: Vec<u64> = (0..=99u64).map(|v| 1 + v % 3).collect();
        let h = Histogram::from_counts(counts);
        let units = ValueUnits {
            scale: -1.0,
            offset: 10.0,
            unit: String::new(),
        };
        let text = h.summary(255, &units);
        assert!(text.contains(", -89 to 10 (of -245 to 10)"), "{text}");
        let p1 = text.split("p1 ").nth(1).unwrap().split(',').next().unwrap();
        let p99 = text
            .split("p99 ")
            .nth(1)
            .unwrap()
            .split(',')
            .next()
            .unwrap();
        assert!(
            p1.parse::<f64>().unwrap() < p99.parse::<f64>().unwrap(),
            "{text}"
        );
        // Bars from the smallest value up.
        let bars: Vec<&str> = text.lines().skip(2).collect();
        assert!(bars[0].trim_start().starts_with("-89.."), "{text}");
        assert!(bars.last().unwrap().contains("..10 "), "{text}");
    }

    #[test]
    fn the_terminal_chart_spans_the_values_present() {
        // A CT-like histogram: values 31000..=35000 of u16.
        let counts: Vec<u64> = (0..=35000u64)
            .map(|v| if v >= 31000 { 1 + v % 7 } else { 0 })
            .collect();
        let h = Histogram::from_counts(counts);
        let bins = h.over_data(16);
        assert_eq!(bins.len(), 16);
        assert_eq!(bins[0].0, 31000);
        assert!(bins.iter().all(|b| b.1 > 0), "{bins:?}");
        assert_eq!(bins.iter().map(|b| b.1).sum::<u64>(), h.total());
        let text = h.summary(u16::MAX, &ValueUnits::IDENTITY);
        assert!(text.contains("31000 to 35000 (of 0 to 65535)"), "{text}");
        assert!(text.contains("    31000..31250"), "{text}");
        assert!(text.contains(", zero "), "{text}");
        assert!(text.trim_end().ends_with('#'), "{text}");
        // In Hounsfield units (i16 stored as HU + 32768).
        let hu = ValueUnits::new(1.0, -32768.0, "HU").unwrap();
        let text = h.summary(u16::MAX, &hu);
        assert!(
            text.contains("-1768 HU to 2232 HU (of -32768 HU to 32767 HU)"),
            "{text}"
        );
        assert!(text.contains("    -1768..-1518"), "{text}");
        assert!(text.contains("at -32768 HU 0.0 %"), "{text}");
    }

    #[test]
    fn narrow_bins_get_labels_that_tell_them_apart() {
        // Float data of 3..3.0001 mapped onto u16: bins 6.25e-6 wide.
        let counts: Vec<u64> = (0..=u16::MAX as u64).map(|v| v % 3).collect();
        let h = Histogram::from_counts(counts);
        let units = ValueUnits::new(1e-4 / 65535.0, 3.0, "").unwrap();
        let text = h.summary(u16::MAX, &units);
        let labels: Vec<&str> = text
            .lines()
            .skip(2)
            .map(|l| l.split_whitespace().next().unwrap())
            .collect();
        assert_eq!(labels.len(), 16, "{text}");
        let mut distinct = labels.clone();
        distinct.dedup();
        assert_eq!(distinct, labels, "{text}");
        assert!(labels[1].starts_with("3.000006"), "{text}");
        // One value: one bin, said in the singular.
        let mut counts = vec![0u64; 256];
        counts[3] = 64;
        let text = Histogram::from_counts(counts).summary(255, &ValueUnits::IDENTITY);
        assert!(
            text.contains("1 bin over the values present, 3 to 3"),
            "{text}"
        );
    }
}
