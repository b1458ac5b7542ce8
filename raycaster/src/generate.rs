//! Generating `.vol` files from synthetic scenes, in parallel batches.

use std::path::Path;

use rayon::prelude::*;

use crate::io::{WriteOptions, WriteSummary, write_volume};
use crate::job::Job;
use crate::synth::Scene;
use crate::volume::{AtPath, Content, Header, Sample, SampleType, VolumeError};

/// Samples `scene` into a file described by `header` (its sample type and content
/// choose values or labels) and writes it atomically to `path`.
pub fn generate(
    scene: &dyn Scene,
    header: &Header,
    path: &Path,
    options: &WriteOptions,
    job: &Job,
) -> Result<WriteSummary, VolumeError> {
    // An invalid header (u16 labels, say) is a typed error, before any dispatch.
    header.validate().at(path)?;
    match (header.content, header.sample_type) {
        (Content::Labels, _) => {
            write_rows::<u8>(header, path, options, job, |x, y, row: &mut [u8], _| {
                scene.fill_label_row(x, y, row)
            })
        }
        (Content::Scalar, SampleType::U8) => write_values::<u8>(scene, header, path, options, job),
        (Content::Scalar, SampleType::U16) => {
            write_values::<u16>(scene, header, path, options, job)
        }
    }
}

fn write_values<T: Sample>(
    scene: &dyn Scene,
    header: &Header,
    path: &Path,
    options: &WriteOptions,
    job: &Job,
) -> Result<WriteSummary, VolumeError> {
    write_rows::<T>(
        header,
        path,
        options,
        job,
        |x, y, row: &mut [T], scratch| {
            scene.fill_row(x, y, scratch);
            for (o, &v) in row.iter_mut().zip(scratch.iter()) {
                *o = T::from_unit(v);
            }
        },
    )
}

/// Fills every slab row by row in parallel with `fill_row(x, y, row, scratch)`.
fn write_rows<T: Sample>(
    header: &Header,
    path: &Path,
    options: &WriteOptions,
    job: &Job,
    fill_row: impl Fn(u32, u32, &mut [T], &mut [f32]) + Sync,
) -> Result<WriteSummary, VolumeError> {
    let [_, dy, dz] = header.dims;
    write_volume::<T>(path, header, options, job, |x0, _x1, slab| {
        slab.par_chunks_mut(dz as usize).enumerate().for_each_init(
            || vec![0f32; dz as usize],
            |scratch, (i, row)| {
                let (x, y) = (x0 + (i / dy as usize) as u32, (i % dy as usize) as u32);
                fill_row(x, y, row, scratch);
            },
        );
        Ok(())
    })
}
