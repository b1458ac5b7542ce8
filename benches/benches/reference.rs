//! The sequential reference renderer on one core: samples per second of shaded
//! DVR on a 256³ `shapes` volume, and of the unshaded loop for comparison.
//!
//! Throughput is reported in samples (criterion's "elements"), so the output reads
//! directly as samples/s on one core.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raycaster::render::{RenderSettings, RenderVolume, render_sequential};
use raycaster_benches::{default_camera, shaded_dvr, shapes_volume};

fn reference(c: &mut Criterion) {
    let volume = shapes_volume(256);
    let prepared = RenderVolume::new(&volume, None).expect("valid volume");
    let camera = default_camera(&volume, 256);
    let mut group = c.benchmark_group("reference-256");
    group.sample_size(10);
    let cases = [
        ("dvr-shaded-none", shaded_dvr(false, false)),
        ("dvr-shaded-ert-ess", shaded_dvr(true, true)),
        (
            "dvr-unshaded-none",
            RenderSettings {
                shading: None,
                ..shaded_dvr(false, false)
            },
        ),
    ];
    for (name, settings) in cases {
        let samples = render_sequential(&prepared, &camera, &settings)
            .expect("renders")
            .stats
            .counters
            .samples;
        group.throughput(Throughput::Elements(samples));
        group.bench_function(name, |b| {
            b.iter(|| black_box(render_sequential(&prepared, &camera, &settings).expect("renders")))
        });
    }
    group.finish();
}

criterion_group!(benches, reference);
criterion_main!(benches);
