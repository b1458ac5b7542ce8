//! Raw inputs whose x is fastest (NRRD, NIfTI-1, MetaImage, raw dumps), staged
//! for reading by slabs of whole x-planes.
//!
//! A slab of x-planes `x0..x1` takes a piece of every row of such a file: read
//! from the file itself, each slab reads it whole, and a conversion of slabs
//! reads it as many times as it has slabs (a 1.2 GB NRRD: 80 GB). Staged, the
//! file is read once, in order, and its rows' pieces are written into a scratch
//! file of *regions* of whole x-planes (each region's bytes together, rows in
//! file order); a slab then reads the regions it spans. Each byte is read from
//! the input once, written once and read back about once: linear in the file's
//! size, in bounded memory.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;

use super::decode::decode_into;
use super::input::Input;
use crate::job::Job;
use crate::volume::{AtPath, VolumeError};

/// About how many bytes a region holds, and how many bytes of the input are
/// read at once while staging.
const REGION_BYTES: usize = 32 << 20;

/// Samples (bytes) from which an x-fastest input is staged.
const STAGED_FROM: u64 = 512 << 20;

/// An x-fastest raw input rearranged into regions of whole x-planes in a
/// scratch file (deleted when this is dropped: it has no name).
#[derive(Debug)]
pub(crate) struct XRegions {
    file: File,
    /// x-planes per region (the last may hold fewer).
    width: u32,
    dims: [u32; 3],
    /// Bytes per sample.
    size: usize,
}

impl XRegions {
    /// Whether slabs of `input` should be read from a staged copy: an
    /// x-fastest raw input of more than [`STAGED_FROM`] bytes (a smaller one
    /// is read whole once per slab from the page cache faster than it is
    /// copied: 256 MB converted in 2.25 s read per slab, 2.77 s staged; 600 MB
    /// in 7.1 and 6.4 s; 1.2 GB in 15.5 and 8.1 s).
    pub(crate) fn needed(input: &Input) -> bool {
        input.x_fastest_raw().is_some_and(|spec| {
            let bytes: u64 = spec.dims.iter().map(|&d| u64::from(d)).product::<u64>()
                * spec.sample.size() as u64;
            bytes > STAGED_FROM
        })
    }

    /// The voxels staging reads (for progress totals): all of them when
    /// [`Self::needed`], else none.
    pub(crate) fn staged_voxels(input: &Input) -> u64 {
        if Self::needed(input) {
            input.dims().iter().map(|&d| u64::from(d)).product()
        } else {
            0
        }
    }

    /// Stages `input` (x-fastest raw) into a scratch file in folder `dir`,
    /// reading it once in file order; progress and cancelling through `job`.
    pub(crate) fn stage(input: &Input, dir: &Path, job: &Job) -> Result<XRegions, VolumeError> {
        Self::stage_in(input, dir, REGION_BYTES, job)
    }

    /// [`Self::stage`] in regions (and reads) of about `region_bytes`.
    fn stage_in(
        input: &Input,
        dir: &Path,
        region_bytes: usize,
        job: &Job,
    ) -> Result<XRegions, VolumeError> {
        let spec = *input
            .x_fastest_raw()
            .expect("staging is for x-fastest raw inputs");
        let [dx, dy, dz] = spec.dims.map(|d| d as usize);
        let size = spec.sample.size();
        // Errors of the copy name the folder and what it is for, not the input.
        let bytes = (dx * dy * dz * size) as u64;
        let staging = |e: std::io::Error| {
            let why = format!(
                "staging the samples of {} here (a temporary copy of {}, so that the input is read once) failed: {e}",
                input.path().display(),
                crate::files::human_bytes(bytes)
            );
            VolumeError::new(dir, std::io::Error::new(e.kind(), why))
        };
        crate::files::check_free_space_in(dir, bytes).map_err(staging)?;
        let file = tempfile::tempfile_in(dir).map_err(staging)?;
        let width = (region_bytes / (dy * dz * size)).clamp(1, dx);
        let row = dx * size;
        // Rows (all x of one y and z) of the input at a time, in file order.
        let total_rows = dy * dz;
        let rows_per_chunk = (region_bytes / row).clamp(1, total_rows);
        let mut chunk = Vec::new();
        let mut pieces = Vec::new();
        let mut r0 = 0;
        while r0 < total_rows {
            let r1 = (r0 + rows_per_chunk).min(total_rows);
            chunk.resize((r1 - r0) * row, 0);
            input.read_at(&mut chunk, spec.skip + (r0 * row) as u64)?;
            for xa in (0..dx).step_by(width) {
                let xb = (xa + width).min(dx);
                let piece = (xb - xa) * size;
                pieces.clear();
                for r in chunk.chunks_exact(row) {
                    pieces.extend_from_slice(&r[xa * size..xb * size]);
                }
                // Region of planes xa..xb: its rows in file order, `piece`
                // bytes each.
                let at = xa * dy * dz * size + r0 * piece;
                file.write_all_at(&pieces, at as u64).map_err(staging)?;
            }
            input.advance(job, ((r1 - r0) * dx) as u64)?;
            r0 = r1;
        }
        Ok(XRegions {
            file,
            width: width as u32,
            dims: spec.dims,
            size,
        })
    }

    /// [`Input::read_slab`] from the staged regions: `map`ped values of planes
    /// `x0..x1` into `out`, x slowest and z fastest.
    pub(crate) fn read_slab<O: Copy>(
        &self,
        input: &Input,
        x0: u32,
        x1: u32,
        map: &impl Fn(f32) -> O,
        out: &mut [O],
    ) -> Result<(), VolumeError> {
        let [dx, dy, dz] = self.dims.map(|d| d as usize);
        let (x0, x1) = (x0 as usize, x1 as usize);
        assert!(x0 < x1 && x1 <= dx, "slab outside the volume");
        assert_eq!(out.len(), (x1 - x0) * dy * dz, "slab buffer size");
        let (ty, endian) = input.raw_type();
        let width = self.width as usize;
        let mut bytes = Vec::new();
        let mut values = Vec::new();
        for xa in (x0 / width * width..x1).step_by(width) {
            let xb = (xa + width).min(dx);
            let w = xb - xa;
            bytes.resize(w * dy * dz * self.size, 0);
            // (The copy's: errors name the input it stands for.)
            self.file
                .read_exact_at(&mut bytes, (xa * dy * dz * self.size) as u64)
                .at(input.path())?;
            values.resize(w * dy * dz, map(0.0));
            decode_into(&bytes, ty, endian, map, &mut values);
            // The region's rows (z, y) of `w` values; the slab's planes of it.
            let (from, to) = (xa.max(x0), xb.min(x1));
            for (r, row) in values.chunks_exact(w).enumerate() {
                let (z, y) = (r / dy, r % dy);
                for x in from..to {
                    out[((x - x0) * dy + y) * dz + z] = row[x - xa];
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{Endian, RawData, RawOrder, RawSpec, RawType};

    /// A staged input reads every slab as the input does: regions of one
    /// plane to all of them, input read a row or all at once, slabs that
    /// start and end inside regions, overlap and span several.
    #[test]
    fn staged_slabs_equal_the_inputs_slabs() {
        for (dims, sample) in [([37, 5, 3], RawType::U16), ([300, 7, 2], RawType::U8)] {
            let size = sample.size();
            let n = dims.iter().product::<u32>() as usize * size;
            let skip = 11;
            let bytes: Vec<u8> = (0..skip + n).map(|i| (i * 7 + i / 251) as u8).collect();
            let spec = RawSpec {
                dims,
                sample,
                endian: Endian::Big,
                skip: skip as u64,
                order: RawOrder::XFastest,
            };
            let input =
                Input::from_raw_data(Path::new("t.raw"), RawData::Memory(bytes), spec, None)
                    .unwrap();
            let dir = tempfile::tempdir().unwrap();
            // A copy that cannot be made names the folder and what it was
            // for (it blamed the input: "t.raw: No space left on device").
            let missing = dir.path().join("missing");
            let e = XRegions::stage(&input, &missing, &Job::silent()).unwrap_err();
            assert!(
                e.to_string().starts_with(&format!(
                    "{}: staging the samples of t.raw here (a temporary copy of",
                    missing.display()
                )),
                "{e}"
            );
            let plane = (dims[1] * dims[2]) as usize;
            for region_bytes in [1, plane * size * 4 + 1, plane * size * 16, n] {
                let staged =
                    XRegions::stage_in(&input, dir.path(), region_bytes, &Job::silent()).unwrap();
                for (x0, x1) in [(0, dims[0]), (0, 1), (3, 9), (8, 9), (dims[0] - 5, dims[0])] {
                    let mut want = vec![0.0f32; (x1 - x0) as usize * plane];
                    input.read_slab(x0, x1, &|v| v, &mut want).unwrap();
                    let mut got = vec![f32::NAN; want.len()];
                    staged.read_slab(&input, x0, x1, &|v| v, &mut got).unwrap();
                    assert_eq!(
                        got, want,
                        "{dims:?}, regions of {} planes, planes {x0}..{x1}",
                        staged.width
                    );
                }
            }
        }
    }
}
