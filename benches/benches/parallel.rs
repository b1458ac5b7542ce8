//! The object-parallel renderer: frame time over render threads × tile size ×
//! brick size on a `shapes` volume (shaded DVR, ERT + ESS), with the sequential
//! renderer per brick size for reference. Throughput is in samples.

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster_benches::{parallel_cases, quick_mode};

fn parallel(c: &mut Criterion) {
    common::run_group(c, "parallel", &parallel_cases(quick_mode()));
}

criterion_group!(benches, parallel);
criterion_main!(benches);
