//! The marching kernels side by side: one render thread, shaded DVR at step 0.2,
//! the scalar reference and every SIMD level this machine runs (`--simd`); then
//! maximum and average intensity on the scalar kernel and the widest level (the
//! value kernel). Samples per second are the throughput; every kernel takes the
//! same samples.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raycaster_benches::{Volumes, default_cache_dir, kernel_cases, quick_mode};

fn kernels(c: &mut Criterion) {
    let mut volumes = Volumes::new(default_cache_dir());
    let mut group = c.benchmark_group("kernels");
    group.sample_size(10);
    if quick_mode() {
        group.warm_up_time(Duration::from_millis(200));
        group.measurement_time(Duration::from_secs(1));
    }
    for case in kernel_cases(quick_mode()) {
        let volume = volumes.get(&case.volume).expect("benchmark volume");
        let prepared = case.prepare(volume).expect("valid benchmark case");
        group.throughput(Throughput::Elements(prepared.samples().expect("renders")));
        group.bench_function(case.name(), |b| {
            b.iter(|| black_box(prepared.frame().expect("renders")))
        });
    }
    group.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
