//! Writing a `.vol` file from slabs, atomically and in bounded memory.

use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::Path;

use rayon::prelude::*;

use crate::job::Job;
use crate::volume::{
    AtPath, BlockGrid, BrickRanges, BrickView, Format, Header, LINEAR_RANGE_SIDE, Layout, Sample,
    VolumeError, VolumeErrorKind, ranges_sidecar_path,
};

/// How [`write_volume`] writes.
#[derive(Clone, Copy, Debug)]
pub struct WriteOptions {
    /// Replace an existing file (atomically, at the end). Without it an existing
    /// output is an error before any work is done.
    pub overwrite: bool,
    /// Upper bound on the slab buffer, in bytes (at least one brick row is used).
    pub slab_bytes: usize,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            overwrite: false,
            slab_bytes: 64 << 20,
        }
    }
}

/// What [`write_volume`] wrote.
#[derive(Clone, Debug)]
pub struct WriteSummary {
    /// Size of the file in bytes.
    pub file_bytes: u64,
    /// The per-brick value ranges stored with it.
    pub ranges: BrickRanges,
}

/// Writes the volume described by `header` to `path`.
///
/// `fill(x0, x1, slab)` must fill `slab` with the samples of planes `x0..x1` (x slowest,
/// z fastest). Slabs arrive in increasing x, aligned to the value-range grid, and
/// consecutive slabs share one plane. The file is written to a temporary file beside
/// `path` and renamed at the end; on any error or cancellation nothing is left behind.
/// Per-brick ranges are computed on the way and embedded (extended format) or put in
/// a sidecar (thesis format). Edge bricks are padded by repeating the last voxel.
pub fn write_volume<T: Sample>(
    path: &Path,
    header: &Header,
    options: &WriteOptions,
    job: &Job,
    mut fill: impl FnMut(u32, u32, &mut [T]) -> Result<(), VolumeError>,
) -> Result<WriteSummary, VolumeError> {
    assert_eq!(
        header.sample_type,
        T::TYPE,
        "header and sample type disagree"
    );
    let mut header = header.clone();
    header.ranges_offset = None;
    let head_bytes = header.encode().at(path)?;
    if !options.overwrite && path.exists() {
        return Err(VolumeError::new(path, VolumeErrorKind::Exists));
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        let msg = format!("directory {} does not exist", dir.display());
        let e = std::io::Error::new(std::io::ErrorKind::NotFound, msg);
        return Err(VolumeError::new(path, e));
    }
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(".partial")
        .tempfile_in(dir)
        .at(path)?;
    let mut out = BufWriter::with_capacity(8 << 20, tmp);
    out.write_all(&head_bytes).at(path)?;

    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    let [dx, dy, dz] = header.dims;
    let plane = dy as usize * dz as usize;
    let step = grid.step();
    let [nx, ny, nz] = grid.counts();
    let per_block_x = step as usize * plane * size_of::<T>();
    let blocks_per_slab = (options.slab_bytes / per_block_x.max(1)).clamp(1, nx as usize) as u32;
    let mut ranges = Vec::with_capacity(grid.block_count() as usize);
    let mut slab: Vec<T> = Vec::new();
    let mut bricks: Vec<T> = Vec::new();
    let mut k0 = 0;
    while k0 < nx {
        let k1 = (k0 + blocks_per_slab).min(nx);
        let x0 = k0 * step;
        let x1 = (k1 * step).min(dx - 1) + 1;
        slab.clear();
        slab.resize((x1 - x0) as usize * plane, T::from_u16_saturating(0));
        fill(x0, x1, &mut slab)?;
        if job.is_cancelled() {
            return Err(VolumeError::new(path, VolumeErrorKind::Cancelled));
        }
        let view = BrickView::dense(&slab, [x0, 0, 0], [x1 - x0, dy, dz]);
        let slab_ranges: Vec<[u16; 2]> = (u64::from(k0) * u64::from(ny * nz)
            ..u64::from(k1) * u64::from(ny * nz))
            .into_par_iter()
            .map(|i| {
                let b = grid.coords(i);
                let o = grid.origin(b);
                let (lo, hi) = view
                    .sub([o[0] - x0, o[1], o[2]], grid.extent(b))
                    .value_range();
                [lo.to_u16(), hi.to_u16()]
            })
            .collect();
        ranges.extend(slab_ranges);
        // Planes this slab adds to the file; the last plane is shared with the next slab.
        let new_planes = if k1 == nx { x1 - x0 } else { x1 - 1 - x0 };
        match header.layout {
            Layout::Linear => {
                let bytes = bytemuck::cast_slice(&slab[..new_planes as usize * plane]);
                out.write_all(bytes).at(path)?;
            }
            Layout::Bricked { side } => {
                for bx in k0..k1 {
                    gather_bricks(&view, &grid, bx, usize::from(side), &mut bricks);
                    out.write_all(bytemuck::cast_slice(&bricks)).at(path)?;
                }
            }
        }
        job.advance(u64::from(new_planes) * plane as u64);
        k0 = k1;
    }

    let ranges = BrickRanges::from_parts(grid, ranges);
    let data_end = header.data_end().at(path)?;
    if header.format == Format::Extended {
        out.write_all(&ranges.encode()).at(path)?;
        header.ranges_offset = Some(data_end);
        out.seek(SeekFrom::Start(0)).at(path)?;
        out.write_all(&header.encode().at(path)?).at(path)?;
    }
    let tmp = out
        .into_inner()
        .map_err(|e| VolumeError::new(path, e.into_error()))?;
    tmp.as_file().sync_all().at(path)?;
    let file_bytes = tmp.as_file().metadata().at(path)?.len();
    debug_assert!(file_bytes >= data_end);
    if options.overwrite {
        tmp.persist(path)
            .map_err(|e| VolumeError::new(path, e.error))?;
    } else {
        tmp.persist_noclobber(path)
            .map_err(|e| VolumeError::new(path, e.error))?;
    }
    if header.format == Format::Thesis {
        let meta = std::fs::metadata(path).at(path)?;
        let sidecar = ranges.encode_sidecar(meta.len(), meta.modified().at(path)?);
        let sidecar_path = ranges_sidecar_path(path);
        crate::volume::write_file_atomically(&sidecar_path, &sidecar).at(&sidecar_path)?;
    }
    Ok(WriteSummary { file_bytes, ranges })
}

/// Copies every brick with x index `bx` out of `slab` into `out`, in file order,
/// each brick whole (`side³` samples) with edge padding repeating the last voxel.
fn gather_bricks<T: Sample>(
    slab: &BrickView<'_, T>,
    grid: &BlockGrid,
    bx: u32,
    side: usize,
    out: &mut Vec<T>,
) {
    let [_, ny, nz] = grid.counts();
    let per_brick = side * side * side;
    out.clear();
    out.resize(
        ny as usize * nz as usize * per_brick,
        T::from_u16_saturating(0),
    );
    let slab_end = [0, 1, 2].map(|a| slab.origin()[a] + slab.extent()[a] - 1);
    out.par_chunks_mut(per_brick)
        .enumerate()
        .for_each(|(i, brick)| {
            let (by, bz) = ((i / nz as usize) as u32, (i % nz as usize) as u32);
            let o = grid.origin([bx, by, bz]);
            for lx in 0..side as u32 {
                let x = (o[0] + lx).min(slab_end[0]) - slab.origin()[0];
                for ly in 0..side as u32 {
                    let y = (o[1] + ly).min(slab_end[1]);
                    let dst = &mut brick[(lx as usize * side + ly as usize) * side..][..side];
                    let src = slab.row(x, y);
                    let z0 = o[2] as usize;
                    let valid = (src.len() - z0).min(side);
                    dst[..valid].copy_from_slice(&src[z0..z0 + valid]);
                    let last = src[src.len().min(z0 + side) - 1];
                    dst[valid..].fill(last);
                }
            }
        });
}
