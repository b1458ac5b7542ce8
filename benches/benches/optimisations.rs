//! The thesis's single-thread table: the sequential renderer on a `shapes` volume
//! with no optimisation, ERT, ESS and both, and the unshaded loop without
//! optimisations (the kernel's raw samples/s on one core). 256³, 256×256, step 0.5
//! (quick mode: 48³, 64×64).

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster_benches::{optimisation_cases, quick_mode};

fn optimisations(c: &mut Criterion) {
    common::run_group(c, "optimisations", &optimisation_cases(quick_mode()));
}

criterion_group!(benches, optimisations);
criterion_main!(benches);
