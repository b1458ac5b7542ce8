//! The object-parallel renderer: frame time over render threads × tile size ×
//! brick size on a 256³ `shapes` volume (shaded DVR, ERT + ESS), with the
//! sequential renderer on the same view for reference. Throughput is in samples.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use raycaster::render::{ParallelOptions, RenderVolume, render_parallel, render_sequential};
use raycaster_benches::{default_camera, shaded_dvr, shapes_volume};

fn parallel(c: &mut Criterion) {
    let volume = shapes_volume(256);
    let camera = default_camera(&volume, 256);
    let settings = shaded_dvr(true, true);
    let mut group = c.benchmark_group("parallel-256");
    group.sample_size(10);
    for brick in [8, 16, 32] {
        let prepared = RenderVolume::new(&volume, Some(brick)).expect("valid brick side");
        let samples = render_sequential(&prepared, &camera, &settings)
            .expect("renders")
            .stats
            .counters
            .samples;
        group.throughput(Throughput::Elements(samples));
        group.bench_function(
            BenchmarkId::new("sequential", format!("brick{brick}")),
            |b| {
                b.iter(|| {
                    black_box(render_sequential(&prepared, &camera, &settings).expect("renders"))
                })
            },
        );
        for threads in [1, 2] {
            for tile in [8, 16, 32] {
                let options = ParallelOptions {
                    render_threads: threads,
                    compositing_threads: 1,
                    tile_size: tile,
                };
                let id = BenchmarkId::new(
                    format!("threads{threads}"),
                    format!("tile{tile}-brick{brick}"),
                );
                group.bench_function(id, |b| {
                    b.iter(|| {
                        black_box(
                            render_parallel(&prepared, &camera, &settings, &options)
                                .expect("renders"),
                        )
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, parallel);
criterion_main!(benches);
