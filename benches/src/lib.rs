//! Shared setup of the raycaster benchmarks: the volumes and views they render.
//!
//! Run with `cargo bench -p raycaster-benches`; `cargo test -p raycaster-benches
//! --benches` runs every benchmark once (quick mode, as CI does).

use raycaster::render::{Camera, Orbit, RenderSettings, TransferFunction, Vec3};
use raycaster::synth::{SceneKind, synthesize};
use raycaster::volume::{SampleType, Volume};

/// The `shapes` scene of `n³` u8 voxels in RAM (seed 1, as `volgen generate`).
pub fn shapes_volume(n: u32) -> Volume {
    let scene = SceneKind::Shapes.build([n; 3], 1);
    synthesize(scene.as_ref(), "shapes", [n; 3], [1.0; 3], SampleType::U8)
        .expect("valid built-in scene")
}

/// The default view of a volume (as `raycaster render`), `size` pixels square.
pub fn default_camera(volume: &Volume, size: u32) -> Camera {
    let hi = Vec3::from(volume.dims().map(|d| (d - 1) as f32)) * Vec3::from(volume.spacing());
    Orbit::default_view(Vec3::ZERO, hi)
        .camera(size, size)
        .expect("valid camera")
}

/// Shaded DVR with the `shapes` preset and the given optimisations.
pub fn shaded_dvr(ert: bool, ess: bool) -> RenderSettings {
    RenderSettings {
        early_termination: ert.then_some(raycaster::render::DEFAULT_ERT_THRESHOLD),
        empty_space_skipping: ess,
        transfer: TransferFunction::preset("shapes").expect("built-in preset"),
        ..RenderSettings::default()
    }
}
