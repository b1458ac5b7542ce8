//! Writing a `.vol` file from slabs, atomically and in bounded memory.

use std::os::unix::fs::FileExt;
use std::path::Path;
use std::sync::mpsc;

use rayon::prelude::*;

use crate::job::Job;
use crate::volume::pyramid::{
    PlaneFeed, PlaneTap, PyramidLayout, level_dims, map_region, write_levels,
};
use crate::volume::{
    AtPath, BlockGrid, BrickRanges, BrickView, CellShape, Content, Format, Header,
    LINEAR_RANGE_SIDE, Layout, Sample, TypedVolume, VolumeError, VolumeErrorKind,
    ranges_sidecar_path,
};

/// Where [`stream_samples`] writes the cell-range table of the level it writes,
/// computed from the slabs on the way.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CellSink<'f> {
    /// The cells (of the level's default grid).
    pub shape: CellShape,
    /// The output file.
    pub file: &'f std::fs::File,
    /// Byte offset of the table in it.
    pub offset: u64,
}

/// Bytes the writer thread writes between two flushes to disk.
const SYNC_EVERY_BYTES: usize = 32 << 20;

/// How [`write_volume`] writes.
#[derive(Clone, Copy, Debug)]
pub struct WriteOptions {
    /// Replace an existing file (atomically, at the end). Without it an existing
    /// output is an error before any work is done.
    pub overwrite: bool,
    /// Upper bound on the slab buffer, in bytes (at least one brick row is used).
    pub slab_bytes: usize,
    /// Also write the resolution pyramid: embedded in extended files, in a
    /// `FILE.pyramid` sidecar for thesis files (volumes larger than
    /// [`crate::volume::COARSEST_EDGE`] on some axis only).
    pub pyramid: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            overwrite: false,
            slab_bytes: 16 << 20,
            pyramid: true,
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
    /// Levels of the resolution pyramid written with it (0: none).
    pub pyramid_levels: usize,
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
    header.pyramid_offset = None;
    let head_bytes = header.encode().at(path)?;
    if !options.overwrite && path.exists() {
        return Err(VolumeError::new(path, VolumeErrorKind::Exists));
    }
    check_resources::<T>(path, &header, options.pyramid)?;
    let tmp = crate::volume::temp_file_beside(path).at(path)?;
    let file = tmp.as_file();
    file.write_all_at(&head_bytes, 0).at(path)?;
    let data_end = header.data_end().at(path)?;
    let wants_pyramid = options.pyramid && !level_dims(header.dims).is_empty();
    // Extended files embed the pyramid after the range table; its level 1 is built
    // from level 0's slabs while they are written, the rest from level 1.
    let embedded = (wants_pyramid && header.format == Format::Extended)
        .then(|| PyramidLayout::plan(&header, true))
        .transpose()
        .at(path)?;
    let table_len = 28 + 4 * header.block_grid(LINEAR_RANGE_SIDE).block_count();
    let block_start = (data_end + table_len).div_ceil(64) * 64;
    let level0_start = head_bytes.len() as u64;
    // Where a level's cell table goes (a layout with cell tables places them).
    let sink = |header: &Header, cells: Option<(u64, u64)>| {
        cells.map(|(offset, _)| CellSink {
            shape: CellShape::default_for(header),
            file,
            offset: block_start + offset,
        })
    };
    let ranges = match &embedded {
        None => stream_samples(
            file,
            level0_start,
            &header,
            options,
            job,
            path,
            None,
            &mut fill,
        )?,
        Some(layout) => {
            file.write_all_at(&layout.encode(), block_start).at(path)?;
            let level1 = &layout.levels[0];
            let level1_header = layout.level_header(&header, 1);
            let labels = header.content == Content::Labels;
            let (to_level1, from_level0) = mpsc::sync_channel(4);
            // (A writer thread the system refuses is an error: it panicked.)
            let (ranges, level1_ranges) = std::thread::scope(|scope| {
                let spawned = std::thread::Builder::new().spawn_scoped(scope, || {
                    let mut feed = PlaneFeed::new(from_level0);
                    stream_samples(
                        file,
                        block_start + level1.data_offset,
                        &level1_header,
                        options,
                        job,
                        path,
                        sink(&level1_header, level1.cells).as_ref(),
                        &mut |x0, x1, slab: &mut [T]| feed.fill(x0, x1, slab, path),
                    )
                });
                let writer = spawned.at(path)?;
                let mut tap = PlaneTap::new(to_level1, header.dims, labels);
                let level0 = stream_samples(
                    file,
                    level0_start,
                    &header,
                    options,
                    job,
                    path,
                    sink(&header, layout.level0_cells).as_ref(),
                    &mut |x0, x1, slab: &mut [T]| {
                        fill(x0, x1, slab)?;
                        tap.push(x0, x1, slab);
                        Ok(())
                    },
                );
                // Level 1 ends when level 0 does (its feed sees the channel close).
                drop(tap);
                let level1 = writer.join().expect("the level-1 writer does not panic");
                Ok::<_, VolumeError>((level0, level1))
            })?;
            // Level 0's error explains a level 1 that stopped for want of planes.
            let (ranges, level1_ranges) = (ranges?, level1_ranges?);
            file.write_all_at(&level1_ranges.encode(), block_start + level1.ranges_offset)
                .at(path)?;
            ranges
        }
    };
    let mut pyramid_levels = 0;
    if header.format == Format::Extended {
        file.write_all_at(&ranges.encode(), data_end).at(path)?;
        header.ranges_offset = Some(data_end);
        if let Some(layout) = &embedded {
            file.sync_data().at(path)?;
            let level1 = &layout.levels[0];
            let map =
                map_region(file, block_start + level1.data_offset, level1.data_len).at(path)?;
            let samples: &[T] = bytemuck::try_cast_slice(&map[..])
                .map_err(|_| VolumeError::new(path, VolumeErrorKind::Misaligned))?;
            let level1_view = TypedVolume::new(samples, level1.dims, header.layout);
            write_levels(
                file,
                block_start,
                &header,
                layout,
                2,
                level1_view,
                None,
                options,
                job,
                path,
            )?;
            pyramid_levels = layout.levels.len();
            header.pyramid_offset = Some(block_start);
            header.pyramid_cells = layout.has_cells();
        }
        file.write_all_at(&header.encode().at(path)?, 0).at(path)?;
    }
    tmp.as_file().sync_all().at(path)?;
    let file_bytes = tmp.as_file().metadata().at(path)?.len();
    debug_assert!(file_bytes >= data_end);
    if options.overwrite {
        tmp.persist(path)
            .map_err(|e| VolumeError::new(path, e.error))?;
    } else {
        // (Another run may have written it since the check before the work.)
        tmp.persist_noclobber(path)
            .map_err(|e| match e.error.kind() {
                std::io::ErrorKind::AlreadyExists => {
                    VolumeError::new(path, VolumeErrorKind::Exists)
                }
                _ => VolumeError::new(path, e.error),
            })?;
    }
    if header.format == Format::Thesis {
        let meta = std::fs::metadata(path).at(path)?;
        let sidecar = ranges.encode_sidecar(meta.len(), meta.modified().at(path)?);
        let sidecar_path = ranges_sidecar_path(path);
        crate::volume::write_file_atomically(&sidecar_path, &sidecar).at(&sidecar_path)?;
        if wants_pyramid {
            pyramid_levels = crate::volume::write_pyramid_sidecar(path, options, job)?;
        }
    }
    Ok(WriteSummary {
        file_bytes,
        ranges,
        pyramid_levels,
    })
}

/// Writes the samples `fill` gives (see [`write_volume`]) in `header`'s layout into
/// `file` from byte `start`, computing on this thread (and rayon) while a writer
/// thread drains finished buffers. Returns the brick value ranges; writes the cell
/// ranges into `cells` when given.
#[allow(clippy::too_many_arguments)]
pub(crate) fn stream_samples<T: Sample>(
    file: &std::fs::File,
    start: u64,
    header: &Header,
    options: &WriteOptions,
    job: &Job,
    path: &Path,
    cells: Option<&CellSink<'_>>,
    fill: &mut impl FnMut(u32, u32, &mut [T]) -> Result<(), VolumeError>,
) -> Result<BrickRanges, VolumeError> {
    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    // Compute on this thread (and rayon) while a writer thread drains finished
    // buffers, so generation runs at the speed of the slower of the two.
    let (full_tx, full_rx) = mpsc::sync_channel::<(Vec<T>, usize)>(1);
    let (empty_tx, empty_rx) = mpsc::channel::<Vec<T>>();
    let recycle = empty_tx.clone();
    let ranges = std::thread::scope(|scope| {
        // (A writer thread the system refuses is an error: it panicked.)
        let writer = std::thread::Builder::new()
            .spawn_scoped(scope, move || -> std::io::Result<()> {
                let mut offset = start;
                let mut unsynced = 0;
                for (buf, len) in full_rx {
                    let bytes: &[u8] = bytemuck::cast_slice(&buf[..len]);
                    file.write_all_at(bytes, offset)?;
                    offset += bytes.len() as u64;
                    unsynced += bytes.len();
                    // Flush as we go, on this thread: the disk works while the producer
                    // computes, instead of all at the final sync.
                    if unsynced >= SYNC_EVERY_BYTES {
                        file.sync_data()?;
                        unsynced = 0;
                    }
                    // The producer may have finished already; then the buffer is dropped.
                    let _ = empty_tx.send(buf);
                }
                Ok(())
            })
            .at(path)?;
        let mut take_buffer = || empty_rx.try_recv().unwrap_or_default();
        let mut send = |buf: Vec<T>, len: usize| full_tx.send((buf, len)).is_ok();
        let produced = produce_slabs(
            header,
            &grid,
            cells,
            options,
            job,
            path,
            fill,
            &mut take_buffer,
            &mut send,
            &recycle,
        );
        drop(full_tx);
        // A write error (disk full) explains a stopped producer: report it first.
        writer
            .join()
            .expect("the writer thread does not panic")
            .at(path)?;
        produced
    })?;
    Ok(BrickRanges::from_parts(grid, ranges))
}

/// Refuses, before anything is written, a volume whose file (with its pyramid, when
/// one is written) does not fit in the free disk space or whose smallest slab (one brick's depth of whole x-planes) does not
/// fit in half the machine's memory: such a job could only fail later, or abort on
/// a failed allocation.
fn check_resources<T: Sample>(
    path: &Path,
    header: &Header,
    pyramid: bool,
) -> Result<(), VolumeError> {
    let data_end = header.data_end().at(path)?;
    let grid = header.block_grid(LINEAR_RANGE_SIDE);
    let table = grid.block_count().saturating_mul(4).saturating_add(64);
    let levels = if pyramid && !level_dims(header.dims).is_empty() {
        PyramidLayout::plan(header, true).at(path)?.block_len() + 64
    } else {
        0
    };
    let needed = data_end.saturating_add(table).saturating_add(levels);
    crate::files::check_free_space(path, needed).at(path)?;
    let [_, dy, dz] = header.dims;
    let slab = (u64::from(grid.step()) + 1)
        .saturating_mul(u64::from(dy) * u64::from(dz))
        .saturating_mul(size_of::<T>() as u64);
    let memory = physical_memory();
    if memory > 0 && slab > memory / 2 {
        let msg = format!(
            "writing it needs {} of memory for one slab of x-planes but the machine has {}",
            crate::files::human_bytes(slab),
            crate::files::human_bytes(memory)
        );
        return Err(VolumeError::new(
            path,
            std::io::Error::new(std::io::ErrorKind::OutOfMemory, msg),
        ));
    }
    Ok(())
}

/// The machine's physical memory in bytes (0 when unknown).
#[allow(unsafe_code)] // sysconf has no safe wrapper in std
pub(crate) fn physical_memory() -> u64 {
    // SAFETY: sysconf only reads system configuration.
    let (pages, page) = unsafe {
        (
            libc::sysconf(libc::_SC_PHYS_PAGES),
            libc::sysconf(libc::_SC_PAGESIZE),
        )
    };
    if pages > 0 && page > 0 {
        (pages as u64).saturating_mul(page as u64)
    } else {
        0
    }
}

/// The slab loop of [`write_volume`]: fills each slab, computes its brick ranges
/// (and the cell ranges of the bricks of `cells` it holds, written there) and
/// hands the file's bytes to `send` in order. Returns the ranges in brick order.
#[allow(clippy::too_many_arguments)]
fn produce_slabs<T: Sample>(
    header: &Header,
    grid: &BlockGrid,
    cells: Option<&CellSink<'_>>,
    options: &WriteOptions,
    job: &Job,
    path: &Path,
    fill: &mut impl FnMut(u32, u32, &mut [T]) -> Result<(), VolumeError>,
    take_buffer: &mut impl FnMut() -> Vec<T>,
    send: &mut impl FnMut(Vec<T>, usize) -> bool,
    recycle: &mpsc::Sender<Vec<T>>,
) -> Result<Vec<[u16; 2]>, VolumeError> {
    let [dx, dy, dz] = header.dims;
    let plane = dy as usize * dz as usize;
    let step = grid.step();
    let [nx, ny, nz] = grid.counts();
    let per_block_x = step as usize * plane * size_of::<T>();
    // Slabs hold whole bricks of the cells' grid too: a cell brick spans `ratio`
    // range bricks along x (1, or 2 for the side-31 bricks of large linear files).
    let ratio = cells.map_or(1, |c| (c.shape.grid().step() / step).max(1));
    debug_assert!(cells.is_none_or(|c| c.shape.grid().step() % step == 0));
    let blocks_per_slab = (options.slab_bytes / per_block_x.max(1))
        .clamp(1, nx as usize)
        .next_multiple_of(ratio as usize) as u32;
    if let Some(sink) = cells {
        sink.file
            .write_all_at(&sink.shape.encode_head(T::TYPE), sink.offset)
            .at(path)?;
    }
    let writer_stopped = || {
        let e = std::io::Error::other("the writer stopped");
        VolumeError::new(path, e)
    };
    let mut ranges = Vec::with_capacity(grid.block_count() as usize);
    let mut k0 = 0;
    while k0 < nx {
        let k1 = (k0 + blocks_per_slab).min(nx);
        let x0 = k0 * step;
        let x1 = (k1 * step).min(dx - 1) + 1;
        let mut slab = take_buffer();
        slab.clear();
        slab.resize((x1 - x0) as usize * plane, T::from_u16_saturating(0));
        fill(x0, x1, &mut slab)?;
        if job.is_cancelled() {
            return Err(VolumeError::new(path, VolumeErrorKind::Cancelled));
        }
        let view = BrickView::dense(&slab, [x0, 0, 0], [x1 - x0, dy, dz]);
        if let (Some(sink), Layout::Linear) = (cells, header.layout) {
            write_slab_cells(sink, &view, k0 / ratio, k1 == nx).at(path)?;
        }
        // Planes this slab adds to the file; the last plane is shared with the next slab.
        let new_planes = if k1 == nx { x1 - x0 } else { x1 - 1 - x0 };
        match header.layout {
            Layout::Linear => {
                let bricks_before = u64::from(k0) * u64::from(ny * nz);
                let bricks_after = u64::from(k1) * u64::from(ny * nz);
                let slab_ranges: Vec<[u16; 2]> = (bricks_before..bricks_after)
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
                if !send(slab, new_planes as usize * plane) {
                    return Err(writer_stopped());
                }
            }
            Layout::Bricked { side } => {
                for bx in k0..k1 {
                    for by in 0..ny {
                        let mut bricks = take_buffer();
                        let side = usize::from(side);
                        let shape = cells.map(|c| &c.shape);
                        let row_cells = gather_bricks(
                            &view,
                            grid,
                            [bx, by],
                            side,
                            &mut bricks,
                            &mut ranges,
                            shape,
                        );
                        if let Some(sink) = cells {
                            // The cells' grid is the file's: its bricks are these.
                            debug_assert_eq!(sink.shape.grid(), grid);
                            let first = grid.index([bx, by, 0]);
                            sink.shape
                                .write_cells::<T>(sink.file, sink.offset, first, &row_cells)
                                .at(path)?;
                        }
                        let len = bricks.len();
                        if !send(bricks, len) {
                            return Err(writer_stopped());
                        }
                    }
                }
                let _ = recycle.send(slab);
            }
        }
        job.advance(u64::from(new_planes) * plane as u64);
        k0 = k1;
    }
    Ok(ranges)
}

/// Writes the cell ranges of the bricks of `sink`'s grid whose x index runs from
/// `first` to those ending at `slab`'s last plane (to the grid's end for the
/// `last` slab), read from `slab`.
fn write_slab_cells<T: Sample>(
    sink: &CellSink<'_>,
    slab: &BrickView<'_, T>,
    first: u32,
    last: bool,
) -> std::io::Result<()> {
    let grid = sink.shape.grid();
    let x0 = slab.origin()[0];
    let end = if last {
        grid.counts()[0]
    } else {
        (x0 + slab.extent()[0] - 1) / grid.step()
    };
    sink.shape
        .write_columns(sink.file, sink.offset, first..end, |b| {
            let o = grid.origin(b);
            slab.sub([o[0] - x0, o[1], o[2]], grid.extent(b))
        })
}

/// Copies the row of bricks `(bx, by, 0..n_z)` out of `slab` into `out`, in file order,
/// each brick whole (`side³` samples) with edge padding repeating the last voxel,
/// and appends each brick's value range to `ranges`. Padding only repeats voxels of
/// the volume, so the range of the whole stored brick is the range inside the volume.
/// Returns the bricks' cell ranges in `cells`' shape (none without it), computed from
/// the gathered bricks while they are in cache.
fn gather_bricks<T: Sample>(
    slab: &BrickView<'_, T>,
    grid: &BlockGrid,
    [bx, by]: [u32; 2],
    side: usize,
    out: &mut Vec<T>,
    ranges: &mut Vec<[u16; 2]>,
    cells: Option<&CellShape>,
) -> Vec<[u16; 2]> {
    let nz = grid.counts()[2];
    let per_brick = side * side * side;
    out.clear();
    out.resize(nz as usize * per_brick, T::from_u16_saturating(0));
    let slab_end = [0, 1, 2].map(|a| slab.origin()[a] + slab.extent()[a] - 1);
    // Without cells, one unused entry per brick keeps the zip below brick by brick.
    let per_brick_cells = cells.map_or(1, CellShape::per_brick);
    let mut row_cells = vec![[0u16; 2]; nz as usize * per_brick_cells];
    let brick_ranges: Vec<[u16; 2]> = out
        .par_chunks_mut(per_brick)
        .zip(row_cells.par_chunks_mut(per_brick_cells))
        .enumerate()
        .map(|(bz, (brick, brick_cells))| {
            let b = [bx, by, bz as u32];
            let o = grid.origin(b);
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
            let lo = brick.iter().copied().min().expect("bricks are not empty");
            let hi = brick.iter().copied().max().expect("bricks are not empty");
            if let Some(shape) = cells {
                if lo == hi {
                    // What a scan gives a brick of one value, without the scan.
                    brick_cells.fill([lo.to_u16(), hi.to_u16()]);
                } else {
                    let view = BrickView::stored(brick, side, o, grid.extent(b));
                    shape.scan_brick(&view, brick_cells);
                }
            }
            [lo.to_u16(), hi.to_u16()]
        })
        .collect();
    ranges.extend(brick_ranges);
    if cells.is_none() {
        row_cells.clear();
    }
    row_cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{CellTable, SampleType};

    /// Large linear files are rendered (and their cells stored) by bricks of side
    /// 31 over a range grid of side 16: slabs must hold whole bricks of both.
    #[test]
    fn slabs_hold_whole_cell_bricks_of_a_coarser_grid() {
        let dims = [97, 40, 33];
        let values: Vec<u16> = (0..dims.iter().product::<u32>())
            .map(|i| ((i * 7919) % 65521) as u16 / 3)
            .collect();
        let header = Header::new(
            dims,
            [1.0; 3],
            Layout::Linear,
            SampleType::U16,
            Content::Scalar,
            Format::Extended,
        );
        let shape = CellShape::of_grid(&BlockGrid::new(dims, 31));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cells");
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .unwrap();
        let table_at = header.data_len().unwrap() + 64;
        let sink = CellSink {
            shape,
            file: &file,
            offset: table_at,
        };
        let plane = (dims[1] * dims[2]) as usize;
        // One range brick (15 planes) per slab asked for: rounded up to two.
        let options = WriteOptions {
            slab_bytes: 15 * plane * 2,
            ..WriteOptions::default()
        };
        stream_samples(
            &file,
            0,
            &header,
            &options,
            &Job::silent(),
            &path,
            Some(&sink),
            &mut |x0, x1, slab: &mut [u16]| {
                slab.copy_from_slice(&values[x0 as usize * plane..x1 as usize * plane]);
                Ok(())
            },
        )
        .unwrap();
        let len = shape.table_len(SampleType::U16).unwrap();
        let table = CellTable::read_from(
            &file,
            table_at,
            len,
            &shape,
            SampleType::U16,
            crate::volume::Access::Mapped,
        )
        .unwrap()
        .expect("a table of the shape");
        let volume = TypedVolume::new(&values, dims, Layout::Linear);
        let scan = shape.scan_bricks(0..shape.grid().block_count(), |b| {
            volume.brick(shape.grid(), b)
        });
        assert_eq!(table.to_vec(), scan);
    }
}
