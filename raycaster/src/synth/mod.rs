//! Deterministic synthetic scenes: "virtual volumes" sampled one z-row at a time.
//!
//! Every scene is a pure function of the voxel coordinate, the volume size and the
//! seed, so the same arguments give byte-identical files whatever the thread count.

mod gradient;
mod noise;
mod rng;
mod shapes;
mod shells;

use rayon::prelude::*;

use crate::volume::{
    AtPath, Content, Format, Header, Layout, Sample, SampleType, Volume, VolumeError,
};

pub use gradient::Gradient;
pub use noise::Noise;
pub use shapes::Shapes;
pub use shells::Shells;

/// A volume defined by a formula, sampled row by row.
pub trait Scene: Sync {
    /// Fills `out[z]` with the value in `[0, 1]` of voxel `(x, y, z)` for
    /// `z in 0..out.len()`.
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]);

    /// Fills `out[z]` with the object id of voxel `(x, y, z)`, for scenes that come
    /// with a segmentation ([`Scene::has_labels`]); 0 is background.
    fn fill_label_row(&self, x: u32, y: u32, out: &mut [u8]) {
        let _ = (x, y);
        out.fill(0);
    }

    /// Whether the scene defines a matching label volume.
    fn has_labels(&self) -> bool {
        false
    }
}

/// The built-in scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneKind {
    /// Dozens of spheres and boxes, some nearly transparent, some opaque.
    Shapes,
    /// Nested spherical shells of distinct value ranges, with a label volume.
    Shells,
    /// Fractal value noise shaped into a cloud.
    Noise,
    /// A linear ramp along x, for exactness tests.
    Gradient,
}

/// Edge in voxels of a built-in scene rendered without a size: the same picture
/// from `raycaster render` and the viewer.
pub const DEFAULT_SCENE_SIZE: u32 = 128;

impl SceneKind {
    /// Every scene, in the order `--help` lists them.
    pub const ALL: [SceneKind; 4] = [
        SceneKind::Shapes,
        SceneKind::Shells,
        SceneKind::Noise,
        SceneKind::Gradient,
    ];

    /// The scene's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Shapes => "shapes",
            SceneKind::Shells => "shells",
            SceneKind::Noise => "noise",
            SceneKind::Gradient => "gradient",
        }
    }

    /// Builds the scene for a volume of `dims` from `seed`.
    pub fn build(self, dims: [u32; 3], seed: u64) -> Box<dyn Scene> {
        match self {
            SceneKind::Shapes => Box::new(Shapes::new(dims, seed)),
            SceneKind::Shells => Box::new(Shells::new(dims)),
            SceneKind::Noise => Box::new(Noise::new(dims, seed)),
            SceneKind::Gradient => Box::new(Gradient::new(dims)),
        }
    }
}

/// Samples `scene` into a linear volume held in RAM (no file): the built-in scene of
/// the render command and the test volumes. Rows are sampled in parallel.
pub fn synthesize(
    scene: &dyn Scene,
    name: &str,
    dims: [u32; 3],
    spacing: [f32; 3],
    sample_type: SampleType,
) -> Result<Volume, VolumeError> {
    let header = Header::new(
        dims,
        spacing,
        Layout::Linear,
        sample_type,
        Content::Scalar,
        Format::Extended,
    );
    header.validate().at(std::path::Path::new(name))?;
    // The samples, then their copy in the volume.
    let bytes = dims.iter().map(|&d| u64::from(d)).product::<u64>() * sample_type.size();
    check_memory(name, 2 * bytes)?;
    match sample_type {
        SampleType::U8 => Volume::from_samples(name, &header, &sample_rows::<u8>(scene, dims)),
        SampleType::U16 => Volume::from_samples(name, &header, &sample_rows::<u16>(scene, dims)),
    }
}

/// Builds the label volume of `scene` (u8 object ids, linear, in RAM), or `None`
/// when the scene has no segmentation.
pub fn synthesize_labels(
    scene: &dyn Scene,
    name: &str,
    dims: [u32; 3],
    spacing: [f32; 3],
) -> Result<Option<Volume>, VolumeError> {
    if !scene.has_labels() {
        return Ok(None);
    }
    let header = Header::new(
        dims,
        spacing,
        Layout::Linear,
        SampleType::U8,
        Content::Labels,
        Format::Extended,
    );
    header.validate().at(std::path::Path::new(name))?;
    check_memory(
        name,
        2 * dims.iter().map(|&d| u64::from(d)).product::<u64>(),
    )?;
    let [dx, dy, dz] = dims.map(|d| d as usize);
    let mut labels = vec![0u8; dx * dy * dz];
    labels
        .par_chunks_mut(dz)
        .enumerate()
        .for_each(|(i, row)| scene.fill_label_row((i / dy) as u32, (i % dy) as u32, row));
    Volume::from_samples(name, &header, &labels).map(Some)
}

/// That the system gives `bytes` of memory to a volume built in RAM (a
/// refusal is an error, not an abort later).
fn check_memory(name: &str, bytes: u64) -> Result<(), VolumeError> {
    if crate::alloc_check::system_gives(bytes) {
        return Ok(());
    }
    Err(VolumeError::new(
        std::path::Path::new(name),
        crate::volume::VolumeErrorKind::InMemory { bytes },
    ))
}

fn sample_rows<T: Sample>(scene: &dyn Scene, dims: [u32; 3]) -> Vec<T> {
    let [dx, dy, dz] = dims.map(|d| d as usize);
    let mut samples = vec![T::from_unit(0.0); dx * dy * dz];
    samples.par_chunks_mut(dz).enumerate().for_each_init(
        || vec![0f32; dz],
        |scratch, (i, row)| {
            scene.fill_row((i / dy) as u32, (i % dy) as u32, scratch);
            for (o, &v) in row.iter_mut().zip(scratch.iter()) {
                *o = T::from_unit(v);
            }
        },
    );
    samples
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume of a size the header accepts but no memory holds is an error
    /// naming what it takes (an abort in the allocator before).
    #[test]
    fn a_volume_too_large_for_memory_is_an_error_not_an_abort() {
        let scene = SceneKind::Shells.build([100_000; 3], 1);
        let e = synthesize(
            scene.as_ref(),
            "huge",
            [100_000; 3],
            [1.0; 3],
            SampleType::U8,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("2.0 PB") && e.contains("refused"), "{e}");
        let e = synthesize_labels(scene.as_ref(), "huge", [100_000; 3], [1.0; 3])
            .unwrap_err()
            .to_string();
        assert!(e.contains("refused"), "{e}");
        assert!(synthesize(scene.as_ref(), "small", [8; 3], [1.0; 3], SampleType::U16).is_ok());
    }
}
