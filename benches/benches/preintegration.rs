//! Quality at speed: plain DVR at steps 0.25 and 1 against pre-integrated DVR at
//! steps 1 and 2 (`raycaster_benches::preintegration_cases`). On `shapes` a
//! pre-integrated step of 1 is closer to a fine reference than a plain 0.25
//! (docs/benchmarks.md §6); this group says what each costs.

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster_benches::{preintegration_cases, quick_mode};

fn preintegration(c: &mut Criterion) {
    common::run_group(c, "preintegration", &preintegration_cases(quick_mode()));
}

criterion_group!(benches, preintegration);
criterion_main!(benches);
