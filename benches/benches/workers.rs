//! Worker threads that live across frames: small frames (160×160, default
//! threads) rendered on threads started for each frame (`render_parallel`) and on
//! a [`Renderer`] whose threads wait between frames. The difference is the cost of
//! starting and joining the frame's threads.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raycaster::render::Renderer;
use raycaster_benches::{Volumes, default_cache_dir, quick_mode, small_frame_case};

fn workers(c: &mut Criterion) {
    let case = small_frame_case(quick_mode());
    let mut volumes = Volumes::new(default_cache_dir());
    let volume = volumes.get(&case.volume).expect("benchmark volume");
    let prepared = case.prepare(volume).expect("valid benchmark case");
    let mut group = c.benchmark_group("workers");
    group.sample_size(30);
    if quick_mode() {
        group.warm_up_time(Duration::from_millis(200));
        group.measurement_time(Duration::from_secs(1));
    }
    group.throughput(Throughput::Elements(prepared.samples().expect("renders")));
    group.bench_function(format!("threads-per-frame/{}", case.name()), |b| {
        b.iter(|| black_box(prepared.frame().expect("renders")))
    });
    let mut renderer = Renderer::new();
    group.bench_function(format!("kept-workers/{}", case.name()), |b| {
        b.iter(|| black_box(prepared.frame_on(&mut renderer).expect("renders")))
    });
    group.finish();
}

criterion_group!(benches, workers);
criterion_main!(benches);
