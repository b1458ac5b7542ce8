//! The one runner of every criterion group: a list of [`BenchCase`]s, each timed
//! per frame with its sample count as throughput (criterion's "elements/s" reads
//! as samples/s).

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput};
use raycaster::render::SegmentScene;
use raycaster_benches::{BenchCase, Volumes, default_cache_dir, quick_mode};

/// Times every case of `cases` in the criterion group `name`, by its name.
#[allow(dead_code)] // not every bench target uses both runners
pub fn run_group(c: &mut Criterion, name: &str, cases: &[BenchCase]) {
    run_cases(c, name, cases.iter().map(|case| (case.name(), case, None)));
}

/// Times `(id, case, segments)` triples in the criterion group `name`; `segments`
/// renders the case with two-level compositing.
pub fn run_cases<'a>(
    c: &mut Criterion,
    name: &str,
    cases: impl IntoIterator<Item = (String, &'a BenchCase, Option<SegmentScene>)>,
) {
    let mut volumes = Volumes::new(default_cache_dir());
    let mut group = c.benchmark_group(name);
    group.sample_size(10);
    if quick_mode() {
        group.warm_up_time(Duration::from_millis(200));
        group.measurement_time(Duration::from_secs(1));
    }
    for (id, case, segments) in cases {
        let volume = volumes.get(&case.volume).expect("benchmark volume");
        let mut prepared = case.prepare(volume).expect("valid benchmark case");
        prepared.settings.segments = segments;
        let samples = prepared.samples().expect("renders");
        group.throughput(Throughput::Elements(samples));
        group.bench_function(id, |b| {
            b.iter(|| black_box(prepared.frame().expect("renders")))
        });
    }
    group.finish();
}
