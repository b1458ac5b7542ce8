//! Two-level compositing with 10 value layers, all DVR with the plain transfer
//! function, against plain DVR of the same view (the target: ≤ 1.3×).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster::render::{
    GlobalMode, LocalMode, Membership, ObjectStyle, ParallelOptions, RenderSettings, RenderVolume,
    SegmentScene, render_parallel,
};
use raycaster_benches::{default_camera, shaded_dvr, shapes_volume};

fn ten_layers(plain: &RenderSettings) -> RenderSettings {
    let layers: Vec<[f32; 2]> = (0..10)
        .map(|i| [i as f32 / 10.0, (i + 1) as f32 / 10.0])
        .collect();
    let objects = (0..10)
        .map(|i| ObjectStyle {
            name: format!("layer {i}"),
            id: i + 1,
            visible: true,
            transfer: plain.transfer.clone(),
            mode: LocalMode::Dvr,
        })
        .collect();
    RenderSettings {
        segments: Some(SegmentScene {
            membership: Membership::Layers(layers),
            objects,
            global: GlobalMode::Dvr,
        }),
        ..plain.clone()
    }
}

fn two_level(c: &mut Criterion) {
    let volume = shapes_volume(256);
    let prepared = RenderVolume::new(&volume, None).expect("valid volume");
    let camera = default_camera(&volume, 256);
    let options = ParallelOptions::default();
    let plain = shaded_dvr(true, true);
    let layered = ten_layers(&plain);
    let mut group = c.benchmark_group("two-level-256");
    group.sample_size(10);
    for (name, settings) in [("plain-dvr", &plain), ("10-layers-dvr", &layered)] {
        group.bench_function(name, |b| {
            b.iter(|| {
                black_box(render_parallel(&prepared, &camera, settings, &options).expect("renders"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, two_level);
criterion_main!(benches);
