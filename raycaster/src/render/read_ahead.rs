//! Reading a frame's bricks ahead: asking the OS (`madvise(WILLNEED)` on the
//! mapping) for the stored samples of the bricks a frame will march, in the order
//! it visits them, so render threads find them in the page cache instead of
//! stalling on page faults.
//!
//! Bricked files store each brick as one contiguous run: one request per brick
//! (the mapping is advised for random access, so nothing else is read). A brick of
//! a linear file is not contiguous: it covers, in every x-slab of the volume (z is
//! fastest in the file, x slowest), the rows `y0 ..= y1` from its first to its last
//! z, i.e. one byte range per slab. [`LinearRanges`] turns the bricks' slab ranges
//! into few requests: ranges closer than [`MERGE_GAP`] are joined (reading a small
//! gap costs less than another request), and consecutive bricks' ranges are
//! joined too, up to [`MAX_REQUEST`] per request so the first bricks' bytes are
//! asked for without waiting for the later ones. The page cache is the OS's:
//! nothing is copied into this process's memory. Where the file stores the bricks'
//! cell ranges, their entries are asked for too.
//!
//! A brick is asked for once, not every frame ([`ReadAheadLog`]): asking again
//! for pages already in the page cache makes the kernel look each one up, work
//! that took 6.6 % of the CPU time of the thesis's 2000³ case on 2 cores. The
//! log forgets everything once the bricks asked for since it last did add up to
//! half the machine's memory, since by then earlier ones may have been evicted.

use std::ops::Range;

use super::prepared::RenderVolume;
use crate::io::physical_memory;
use crate::volume::{BlockGrid, Layout, Volume};

/// Page size the requests are rounded to (bytes).
pub(crate) const PAGE: u64 = 4096;

/// Ranges of a linear file separated by at most this many bytes are requested
/// together.
pub(crate) const MERGE_GAP: u64 = 64 << 10;

/// A request grows by joining the next bricks' ranges up to this many bytes.
pub(crate) const MAX_REQUEST: u64 = 4 << 20;

/// Asks the OS to read the samples (and labels) of `bricks`, grid coordinates of
/// `volume`'s rendering grid in the order a frame visits them; returns early when
/// `interrupted` holds (asked every few bricks).
pub(crate) fn read_ahead(
    volume: &RenderVolume<'_>,
    bricks: impl IntoIterator<Item = [u32; 3]>,
    interrupted: impl Fn() -> bool,
) {
    // Another frame of this volume is reading ahead: it asks for what both need.
    let Some(mut log) = volume.read_ahead_log().try_lock() else {
        return;
    };
    let grid = *volume.geometry().grid();
    let mut data = Stream::new(volume.volume(), &grid);
    let mut labels = volume.labels().map(|l| Stream::new(l, &grid));
    let sample_bytes = volume.volume().sample_type().size();
    let cell_bytes = volume.cells().per_brick() as u64 * 2 * sample_bytes;
    let cells_per_page = (PAGE / cell_bytes).max(1);
    let mut last_cells_page = u64::MAX;
    for (i, b) in bricks.into_iter().enumerate() {
        if i % 16 == 0 && interrupted() {
            return;
        }
        let index = grid.index(b);
        let bytes = grid
            .extent(b)
            .iter()
            .map(|&e| u64::from(e))
            .product::<u64>()
            * sample_bytes;
        if !log.first_request(index, bytes) {
            continue;
        }
        data.brick(&grid, b);
        // Consecutive bricks' cells share a page: ask for each page once in a row.
        if index / cells_per_page != last_cells_page {
            last_cells_page = index / cells_per_page;
            volume.cells().prefetch(index);
        }
        if let Some(labels) = &mut labels {
            labels.brick(&grid, b);
        }
    }
    data.finish();
    if let Some(labels) = labels {
        labels.finish();
    }
}

/// Which bricks of a rendering grid were asked for ([`read_ahead`]) since the
/// log last forgot them, and how many bytes that was.
#[derive(Debug)]
pub(crate) struct ReadAheadLog {
    /// Bricks in the grid.
    bricks: u64,
    /// One bit per brick (grid index), allocated on the first request (a
    /// volume is opened without work per brick).
    requested: Vec<u64>,
    /// Bytes of the bricks asked for since the bits were last cleared.
    bytes: u64,
    /// The bits are cleared when `bytes` passes this; 0: never skip a brick.
    budget: u64,
}

impl ReadAheadLog {
    /// A log of `bricks` bricks that forgets them after half the machine's
    /// memory was asked for (never skips a brick where that is unknown).
    pub(crate) fn new(bricks: u64) -> Self {
        Self::with_budget(bricks, physical_memory() / 2)
    }

    /// A log of `bricks` bricks that forgets them after `budget` bytes.
    pub(crate) fn with_budget(bricks: u64, budget: u64) -> Self {
        ReadAheadLog {
            bricks,
            requested: Vec::new(),
            bytes: 0,
            budget,
        }
    }

    /// Whether brick `index` (of `bytes` bytes) is to be asked for: not asked
    /// for since the log last forgot. Notes it as asked for.
    pub(crate) fn first_request(&mut self, index: u64, bytes: u64) -> bool {
        if self.budget == 0 || index >= self.bricks {
            return true;
        }
        if self.requested.is_empty() {
            self.requested = vec![0; self.bricks.div_ceil(64) as usize];
        }
        let (word, bit) = ((index / 64) as usize, 1u64 << (index % 64));
        if self.requested[word] & bit != 0 {
            return false;
        }
        self.bytes = self.bytes.saturating_add(bytes);
        if self.bytes > self.budget {
            // What was asked for before may have been evicted since.
            self.requested.fill(0);
            self.bytes = bytes;
        }
        self.requested[word] |= bit;
        true
    }
}

/// The requests for one stored volume (data or labels).
struct Stream<'v> {
    volume: &'v Volume,
    /// Set for linear files.
    linear: Option<LinearRanges>,
}

impl<'v> Stream<'v> {
    /// The requests for `volume`, rendered by bricks of `grid`.
    fn new(volume: &'v Volume, grid: &BlockGrid) -> Self {
        let linear = match volume.layout() {
            Layout::Linear => Some(LinearRanges::new(grid, volume.sample_type().size())),
            Layout::Bricked { .. } => None,
        };
        Stream { volume, linear }
    }

    /// Requests what brick `b` of `grid` (a rendering grid over this volume's
    /// dims) needs.
    fn brick(&mut self, grid: &BlockGrid, b: [u32; 3]) {
        let volume = self.volume;
        match (&mut self.linear, volume.layout()) {
            (Some(linear), _) => linear.push(grid.origin(b), grid.extent(b), &mut |r| {
                volume.prefetch(r.start, r.end - r.start)
            }),
            (None, Layout::Bricked { side }) => {
                // The file brick holding the rendering brick's first voxel holds it
                // all (sub-bricks divide the stored bricks).
                let file_grid = BlockGrid::new(volume.dims(), u32::from(side));
                let fb = file_grid.brick_of_voxel(grid.origin(b));
                let bytes = u64::from(side).pow(3) * volume.sample_type().size();
                volume.prefetch(file_grid.index(fb) * bytes, bytes);
            }
            (None, Layout::Linear) => unreachable!("linear volumes have a planner"),
        }
    }

    fn finish(self) {
        if let Some(linear) = self.linear {
            linear.finish(&mut |r| self.volume.prefetch(r.start, r.end - r.start));
        }
    }
}

/// Turns bricks of a linear volume into few byte ranges of its samples (offsets
/// from the first sample), in the order the bricks come.
///
/// Rows (runs along z) shorter than about [`MERGE_GAP`] are not worth cutting: a
/// brick then needs its rows whole, and so does every brick stacked on it along z
/// (they share those rows' pages), so the first brick of such a column asks for
/// the column's rows in each x-slab once, and the column is marked done (one bit
/// per x-slab and brick row: `dims.x × ⌈dims.y / step⌉` bits, 18 KiB for 2048³).
/// Longer rows are asked for brick by brick, each row's z-run.
#[derive(Clone, Debug)]
pub(crate) struct LinearRanges {
    dims: [u64; 3],
    sample_bytes: u64,
    /// The rendering bricks' step (voxels between brick origins).
    step: u64,
    /// The request being built.
    pending: Option<Range<u64>>,
    /// With short rows: per x-slab and brick row, whether its rows were asked for
    /// (bit `x · rows + y0 / step`); empty with long rows.
    columns_done: Vec<u64>,
}

impl LinearRanges {
    /// The planner for bricks of `grid` over a linear volume with samples of
    /// `sample_bytes`.
    pub(crate) fn new(grid: &BlockGrid, sample_bytes: u64) -> Self {
        let dims = grid.dims().map(u64::from);
        let step = u64::from(grid.step());
        let short_rows = dims[2].saturating_sub(step + 1) * sample_bytes <= MERGE_GAP;
        let columns = if short_rows {
            dims[0] * u64::from(grid.counts()[1])
        } else {
            0
        };
        LinearRanges {
            dims,
            sample_bytes,
            step,
            pending: None,
            columns_done: vec![0; columns.div_ceil(64) as usize],
        }
    }

    /// Bytes of samples in the volume.
    fn len(&self) -> u64 {
        self.dims.iter().product::<u64>() * self.sample_bytes
    }

    /// Adds the brick of voxels `origin .. origin + extent` (a brick of the grid
    /// given to [`Self::new`]): the rows it needs, rounded out to pages; hands
    /// `emit` every request completed.
    pub(crate) fn push(
        &mut self,
        origin: [u32; 3],
        extent: [u32; 3],
        emit: &mut impl FnMut(Range<u64>),
    ) {
        let [_, dy, dz] = self.dims;
        let [x0, y0, z0] = origin.map(u64::from);
        let [ex, ey, ez] = extent.map(u64::from);
        let bytes = self.sample_bytes;
        let len = self.len();
        let pages = |first: u64, end: u64| {
            (first * bytes / PAGE * PAGE)..((end * bytes).div_ceil(PAGE) * PAGE).min(len)
        };
        let row = |x: u64, y: u64| (x * dy + y) * dz;
        if self.columns_done.is_empty() {
            for x in x0..x0 + ex {
                for y in y0..y0 + ey {
                    self.add(pages(row(x, y) + z0, row(x, y) + z0 + ez), emit);
                }
            }
            return;
        }
        let rows = dy.saturating_sub(1).div_ceil(self.step).max(1);
        for x in x0..x0 + ex {
            let bit = x * rows + y0 / self.step;
            let (word, mask) = ((bit / 64) as usize, 1u64 << (bit % 64));
            if self.columns_done[word] & mask == 0 {
                self.columns_done[word] |= mask;
                self.add(pages(row(x, y0), row(x, y0 + ey - 1) + dz), emit);
            }
        }
    }

    /// Joins `r` to the pending request when they are at most [`MERGE_GAP`] apart
    /// (and the request stays under [`MAX_REQUEST`]); otherwise emits the pending
    /// request and starts a new one with `r`.
    fn add(&mut self, r: Range<u64>, emit: &mut impl FnMut(Range<u64>)) {
        match &mut self.pending {
            Some(p)
                if r.start <= p.end + MERGE_GAP
                    && p.start <= r.end + MERGE_GAP
                    && r.end.max(p.end) - r.start.min(p.start)
                        <= MAX_REQUEST.max(p.end - p.start) =>
            {
                *p = r.start.min(p.start)..r.end.max(p.end);
            }
            _ => {
                if let Some(p) = self.pending.replace(r) {
                    emit(p);
                }
            }
        }
    }

    /// Emits the last request.
    pub(crate) fn finish(mut self, emit: &mut impl FnMut(Range<u64>)) {
        if let Some(p) = self.pending.take() {
            emit(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_asks_for_each_brick_once_until_its_budget_is_spent() {
        let mut log = ReadAheadLog::with_budget(100, 1000);
        assert!(log.first_request(3, 300));
        assert!(log.first_request(64, 300));
        assert!(!log.first_request(3, 300), "asked for already");
        assert!(!log.first_request(64, 300));
        assert!(log.first_request(99, 300));
        // 1200 bytes: over the budget, so every brick is asked for again.
        assert!(log.first_request(5, 300));
        assert!(log.first_request(3, 300));
        assert!(!log.first_request(5, 300));
        // Without a budget (memory unknown) nothing is skipped.
        let mut always = ReadAheadLog::with_budget(10, 0);
        assert!(always.first_request(1, 1) && always.first_request(1, 1));
        // Nothing per brick until a brick is asked for (a grid of 2^40 bricks
        // would take 128 GiB of bits).
        assert!(
            ReadAheadLog::with_budget(1 << 40, 1000)
                .requested
                .is_empty()
        );
        assert!(ReadAheadLog::new(1 << 40).requested.is_empty());
    }

    /// Byte offset of voxel `v` in a linear volume of `dims` (z fastest).
    fn offset(dims: [u32; 3], v: [u32; 3], bytes: u64) -> u64 {
        let [_, dy, dz] = dims.map(u64::from);
        let [x, y, z] = v.map(u64::from);
        ((x * dy + y) * dz + z) * bytes
    }

    /// The requests for `bricks` of `grid`, each with the number of bricks pushed
    /// when it was emitted.
    fn plan(grid: &BlockGrid, bytes: u64, bricks: &[[u32; 3]]) -> Vec<(Range<u64>, usize)> {
        let mut out = Vec::new();
        let mut ranges = LinearRanges::new(grid, bytes);
        for (k, &b) in bricks.iter().enumerate() {
            ranges.push(grid.origin(b), grid.extent(b), &mut |r| out.push((r, k)));
        }
        ranges.finish(&mut |r| out.push((r, bricks.len())));
        out
    }

    /// Every voxel of every brick lies in a request; requests are page aligned,
    /// inside the samples and much fewer than the bricks' rows; and they come in
    /// the bricks' order: the first brick a request serves (whose bytes it is the
    /// first to cover) is never before the first brick an earlier request served
    /// (a request may serve none: pages a neighbour's request already covered).
    fn check(dims: [u32; 3], side: u32, bytes: u64, order: impl Fn(&BlockGrid) -> Vec<[u32; 3]>) {
        check_rows(dims, side, bytes, order, true);
    }

    /// [`check`], the count of requests checked only when `rows_merge` (rows
    /// shorter than [`MERGE_GAP`]; long rows take a request each).
    fn check_rows(
        dims: [u32; 3],
        side: u32,
        bytes: u64,
        order: impl Fn(&BlockGrid) -> Vec<[u32; 3]>,
        rows_merge: bool,
    ) {
        let grid = BlockGrid::new(dims, side);
        let bricks = order(&grid);
        let requests = plan(&grid, bytes, &bricks);
        let total = dims.iter().map(|&d| u64::from(d)).product::<u64>() * bytes;
        // Per byte: the first brick (in order) holding it.
        let mut first_need = vec![usize::MAX; total as usize];
        let mut rows = 0u64;
        for (k, &b) in bricks.iter().enumerate() {
            let (o, e) = (grid.origin(b), grid.extent(b));
            rows += u64::from(e[0] * e[1]);
            for x in o[0]..o[0] + e[0] {
                for y in o[1]..o[1] + e[1] {
                    for z in o[2]..o[2] + e[2] {
                        let at = offset(dims, [x, y, z], bytes);
                        for byte in at..at + bytes {
                            let need = &mut first_need[byte as usize];
                            *need = (*need).min(k);
                        }
                    }
                }
            }
        }
        let mut requested = vec![false; total as usize];
        let mut served = 0;
        for (i, (r, _)) in requests.iter().enumerate() {
            assert!(r.start < r.end && r.end <= total, "{r:?} of {total}");
            assert_eq!(r.start % PAGE, 0);
            assert!(r.end % PAGE == 0 || r.end == total);
            let first = (r.start..r.end)
                .filter(|&byte| !requested[byte as usize])
                .map(|byte| first_need[byte as usize])
                .min();
            if let Some(first) = first.filter(|&f| f != usize::MAX) {
                assert!(
                    first >= served,
                    "request {i} {r:?} serves brick {first} after {served}"
                );
                served = first;
            }
            requested[r.start as usize..r.end as usize].fill(true);
        }
        for (byte, need) in first_need.iter().enumerate() {
            assert!(
                *need == usize::MAX || requested[byte],
                "byte {byte} of brick {need} never requested"
            );
        }
        assert!(
            !rows_merge || (requests.len() as u64) * 4 <= rows,
            "{} requests for {rows} brick rows",
            requests.len()
        );
    }

    /// Bricks sorted by distance from a point outside the volume (a frame's
    /// visibility order).
    fn by_distance(eye: [f32; 3]) -> impl Fn(&BlockGrid) -> Vec<[u32; 3]> {
        move |grid: &BlockGrid| {
            let mut bricks: Vec<[u32; 3]> = grid.iter().collect();
            let step = grid.step() as f32;
            let key = |b: &[u32; 3]| {
                (0..3)
                    .map(|a| ((b[a] as f32 + 0.5) * step - eye[a]).powi(2))
                    .sum::<f32>()
            };
            bricks.sort_by(|a, b| key(a).total_cmp(&key(b)));
            bricks
        }
    }

    #[test]
    fn requests_cover_every_voxel_of_each_brick_in_visibility_order() {
        check([40, 33, 70], 9, 1, by_distance([-30.0, 10.0, 90.0]));
        check([64, 64, 64], 16, 2, by_distance([200.0, -50.0, 20.0]));
        check([20, 300, 300], 31, 1, by_distance([5.0, 400.0, -100.0]));
        check([17, 5, 3], 4, 2, |g: &BlockGrid| g.iter().collect());
    }

    #[test]
    fn slabs_closer_than_the_gap_are_one_request() {
        // 64×64 u8 slabs of 4 KiB: a brick's 16 slabs are one request.
        let grid = BlockGrid::new([64, 64, 64], 16);
        let requests = plan(&grid, 1, &[[1, 1, 1]]);
        assert_eq!(requests.len(), 1);
        assert_eq!(requests[0].0, 15 * 4096..31 * 4096);
        // 1024² u8 slabs of 1 MiB: one request per slab the brick covers.
        let grid = BlockGrid::new([64, 1024, 1024], 16);
        let requests = plan(&grid, 1, &[[0, 0, 0]]);
        assert_eq!(requests.len(), 16);
        for (x, (r, _)) in requests.iter().enumerate() {
            assert_eq!(r.start, (x as u64) << 20);
            // Rows 0..=15 of the slab, 15 KiB and 16 bytes, rounded up to a page.
            assert_eq!(r.end, ((x as u64) << 20) + 16384);
        }
    }

    #[test]
    fn long_rows_are_requested_row_by_row() {
        // u16 rows of 80 and 128 KiB: a brick needs one page of each of its rows.
        let order = |_: &BlockGrid| vec![[0, 0, 0], [0, 0, 2000], [1, 0, 1], [0, 0, 1]];
        check_rows([31, 4, 40000], 16, 2, order, false);
        let grid = BlockGrid::new([4, 16, 65536], 16);
        let requests = plan(&grid, 2, &[[0, 0, 0]]);
        assert_eq!(requests.len(), 4 * 16);
        assert!(requests.iter().all(|(r, _)| r.end - r.start == PAGE));
    }

    #[test]
    fn a_brick_asked_for_again_is_not_requested_again() {
        let grid = BlockGrid::new([2, 1024, 1024], 16);
        assert_eq!(plan(&grid, 1, &[[0, 0, 0]]).len(), 2);
        assert_eq!(plan(&grid, 1, &[[0, 0, 0], [0, 0, 0]]).len(), 2);
    }

    #[test]
    fn requests_stop_growing_at_the_maximum() {
        let grid = BlockGrid::new([64, 256, 256], 16);
        // A row of bricks along z: each slab range touches the previous brick's.
        let bricks: Vec<[u32; 3]> = (0..grid.counts()[2]).map(|z| [0, 0, z]).collect();
        let all: Vec<[u32; 3]> = grid.iter().collect();
        for order in [&bricks, &all] {
            for (r, _) in plan(&grid, 1, order) {
                assert!(r.end - r.start <= MAX_REQUEST + 2 * MERGE_GAP, "{r:?}");
            }
        }
    }
}
