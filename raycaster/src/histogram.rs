//! Value histograms of volumes, computed in one streaming pass.

use crate::io::Input;
use crate::job::Job;
use crate::volume::VolumeError;

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
        input.for_each_slab(8 << 20, &|v| v as u16, job, |slab| {
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

    /// A few lines for a terminal: summary figures and a bar chart of 16 bins.
    pub fn summary(&self, max_value: u16) -> String {
        let zero = self.counts.first().copied().unwrap_or(0);
        let mut s = format!(
            "histogram   mean {:.2}, p1 {}, median {}, p99 {}, zero {:.1} %\n",
            self.mean(),
            self.percentile(0.01),
            self.percentile(0.5),
            self.percentile(0.99),
            100.0 * zero as f64 / self.total.max(1) as f64
        );
        let bins = self.coarse(16, max_value);
        let width = (usize::from(max_value) + 1).div_ceil(16);
        let peak = bins.iter().copied().max().unwrap_or(1).max(1) as f64;
        for (i, &c) in bins.iter().enumerate() {
            // Log scale: a few voxels of a rare value still show.
            let bar = ((c as f64).ln_1p() / peak.ln_1p() * 40.0).round() as usize;
            s += &format!(
                "  {:>5}..{:<5} {:>12} {}\n",
                i * width,
                ((i + 1) * width - 1).min(usize::from(max_value)),
                c,
                "#".repeat(bar)
            );
        }
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
    }
}
