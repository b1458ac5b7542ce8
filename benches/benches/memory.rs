//! Memory kinds on one thread: RAM vs mapped × u8 vs u16 × linear vs bricked
//! storage of the same `shapes` volume (ERT + ESS, sequential renderer). The thesis
//! found no measurable difference between mapped and RAM.

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster_benches::{memory_cases, quick_mode};

fn memory(c: &mut Criterion) {
    common::run_group(c, "memory", &memory_cases(quick_mode()));
}

criterion_group!(benches, memory);
criterion_main!(benches);
