//! Two-level compositing with 10 value layers, all DVR with the plain transfer
//! function, against plain DVR of the same view (issue 5's target: ≤ 1.3×).

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster::render::{
    GlobalMode, LocalMode, Membership, ObjectStyle, RenderSettings, SegmentScene,
};
use raycaster_benches::{quick_mode, two_level_case};

/// Ten value layers of equal width, each local DVR with the plain transfer function.
fn ten_layers(plain: &RenderSettings) -> SegmentScene {
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
            clip: Default::default(),
        })
        .collect();
    SegmentScene {
        membership: Membership::Layers(layers),
        objects,
        global: GlobalMode::Dvr,
    }
}

fn two_level(c: &mut Criterion) {
    let case = two_level_case(quick_mode());
    let settings = case.settings().expect("valid case");
    let cases = [
        ("plain-dvr".to_string(), &case, None),
        (
            "10-layers-dvr".to_string(),
            &case,
            Some(ten_layers(&settings)),
        ),
    ];
    common::run_cases(c, "two-level", cases);
}

criterion_group!(benches, two_level);
criterion_main!(benches);
