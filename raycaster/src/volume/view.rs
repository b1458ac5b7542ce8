//! Typed, layout-aware views of sample data: the whole volume and single bricks.
//!
//! A [`BrickView`] addresses its voxels locally through three strides, so a brick
//! of a bricked file and a logical brick carved out of a linear file look the same
//! to the renderer, and no per-sample global brick index is ever computed.

use super::grid::BlockGrid;
use super::header::Layout;
use super::sample::Sample;

/// A volume's samples of one type with their layout.
#[derive(Clone, Copy, Debug)]
pub struct TypedVolume<'a, T: Sample> {
    samples: &'a [T],
    dims: [u32; 3],
    layout: Layout,
}

impl<'a, T: Sample> TypedVolume<'a, T> {
    /// Wraps `samples` stored in `layout` for a volume of `dims`.
    ///
    /// # Panics
    /// If `samples` is shorter than the layout needs (the caller checked the header).
    pub fn new(samples: &'a [T], dims: [u32; 3], layout: Layout) -> Self {
        let needed = match layout {
            Layout::Linear => dims.iter().map(|&d| d as usize).product::<usize>(),
            Layout::Bricked { side } => {
                let grid = BlockGrid::new(dims, u32::from(side));
                grid.block_count() as usize * (side as usize).pow(3)
            }
        };
        assert!(
            samples.len() >= needed,
            "sample slice shorter than its layout"
        );
        TypedVolume {
            samples: &samples[..needed],
            dims,
            layout,
        }
    }

    /// Volume size in voxels.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// Sample order in storage.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// The stored samples in file order.
    pub fn samples(&self) -> &'a [T] {
        self.samples
    }

    /// The grid of stored bricks (bricked) or of logical bricks of side
    /// `linear_side` (linear).
    pub fn natural_grid(&self, linear_side: u32) -> BlockGrid {
        match self.layout {
            Layout::Linear => BlockGrid::new(self.dims, linear_side),
            Layout::Bricked { side } => BlockGrid::new(self.dims, u32::from(side)),
        }
    }

    /// Brick `b` of `grid`. For bricked storage `grid` must be the stored grid
    /// ([`Self::natural_grid`]); linear storage accepts any grid over its dims.
    ///
    /// # Panics
    /// If `grid` does not fit this volume's storage.
    pub fn brick(&self, grid: &BlockGrid, b: [u32; 3]) -> BrickView<'a, T> {
        assert_eq!(grid.dims(), self.dims, "grid of another volume");
        let origin = grid.origin(b);
        let extent = grid.extent(b);
        match self.layout {
            Layout::Linear => {
                let [_, dy, dz] = self.dims.map(|d| d as usize);
                let strides = [dy * dz, dz, 1];
                let start = linear_index(strides, origin);
                let end = linear_index(strides, [0, 1, 2].map(|a| origin[a] + extent[a] - 1)) + 1;
                BrickView {
                    samples: &self.samples[start..end],
                    strides,
                    origin,
                    extent,
                }
            }
            Layout::Bricked { side } => {
                assert_eq!(
                    grid.side(),
                    u32::from(side),
                    "bricked storage has side {side}"
                );
                let s = side as usize;
                let start = grid.index(b) as usize * s * s * s;
                BrickView {
                    samples: &self.samples[start..start + s * s * s],
                    strides: [s * s, s, 1],
                    origin,
                    extent,
                }
            }
        }
    }

    /// The sample at voxel `v` (slow path: finds the brick first).
    ///
    /// # Panics
    /// If `v` is outside the volume.
    pub fn voxel(&self, v: [u32; 3]) -> T {
        assert!(
            (0..3).all(|a| v[a] < self.dims[a]),
            "voxel outside the volume"
        );
        match self.layout {
            Layout::Linear => {
                let [_, dy, dz] = self.dims.map(|d| d as usize);
                self.samples[linear_index([dy * dz, dz, 1], v)]
            }
            Layout::Bricked { side } => {
                let grid = BlockGrid::new(self.dims, u32::from(side));
                let b = grid.brick_of_voxel(v);
                let o = grid.origin(b);
                self.brick(&grid, b)
                    .get([v[0] - o[0], v[1] - o[1], v[2] - o[2]])
            }
        }
    }
}

impl<T: Sample> TypedVolume<'_, T> {
    /// Copies the z-run of voxels `(x, y, 0..dims[2])` into `out` (the first
    /// `dims[2]` elements), from whichever bricks hold it.
    ///
    /// # Panics
    /// If `(x, y)` is outside the volume or `out` is too short.
    pub fn row_into(&self, x: u32, y: u32, out: &mut [T]) {
        let dz = self.dims[2] as usize;
        match self.layout {
            Layout::Linear => {
                let [_, dy, _] = self.dims.map(|d| d as usize);
                let start = linear_index([dy * dz, dz, 1], [x, y, 0]);
                out[..dz].copy_from_slice(&self.samples[start..start + dz]);
            }
            Layout::Bricked { side } => {
                let grid = BlockGrid::new(self.dims, u32::from(side));
                let b = grid.brick_of_voxel([x, y, 0]);
                let o = grid.origin(b);
                let step = grid.step() as usize;
                for bz in 0..grid.counts()[2] {
                    let view = self.brick(&grid, [b[0], b[1], bz]);
                    let row = view.row(x - o[0], y - o[1]);
                    let z0 = bz as usize * step;
                    let n = row.len().min(dz - z0);
                    out[z0..z0 + n].copy_from_slice(&row[..n]);
                }
            }
        }
    }
}

fn linear_index(strides: [usize; 3], v: [u32; 3]) -> usize {
    v[0] as usize * strides[0] + v[1] as usize * strides[1] + v[2] as usize * strides[2]
}

/// One brick's samples with local addressing: `get([0,0,0])` is the brick's origin.
#[derive(Clone, Copy, Debug)]
pub struct BrickView<'a, T: Sample> {
    samples: &'a [T],
    strides: [usize; 3],
    origin: [u32; 3],
    extent: [u32; 3],
}

impl<'a, T: Sample> BrickView<'a, T> {
    /// A view of a dense x-slowest, z-fastest block (e.g. a slab being written).
    ///
    /// # Panics
    /// If `samples` is shorter than `extent`.
    pub fn dense(samples: &'a [T], origin: [u32; 3], extent: [u32; 3]) -> Self {
        let [ex, ey, ez] = extent.map(|e| e as usize);
        assert!(
            samples.len() >= ex * ey * ez,
            "dense block shorter than its extent"
        );
        BrickView {
            samples,
            strides: [ey * ez, ez, 1],
            origin,
            extent,
        }
    }

    /// A stored brick of `side³` samples (local z fastest) with volume origin
    /// `origin`, of which `extent` voxels per axis lie in the volume.
    ///
    /// # Panics
    /// If `samples` is shorter than `side³` or `extent` exceeds `side`.
    pub fn stored(samples: &'a [T], side: usize, origin: [u32; 3], extent: [u32; 3]) -> Self {
        assert!(samples.len() >= side * side * side && extent.iter().all(|&e| e as usize <= side));
        BrickView {
            samples,
            strides: [side * side, side, 1],
            origin,
            extent,
        }
    }

    /// First voxel of the brick in volume coordinates.
    pub fn origin(&self) -> [u32; 3] {
        self.origin
    }

    /// Voxels inside the volume on each axis (padding excluded).
    pub fn extent(&self) -> [u32; 3] {
        self.extent
    }

    /// Distance in samples between neighbours along x, y, z.
    pub fn strides(&self) -> [usize; 3] {
        self.strides
    }

    /// The sample at local voxel `l` (each coordinate below `extent`).
    #[inline]
    pub fn get(&self, l: [u32; 3]) -> T {
        self.samples[linear_index(self.strides, l)]
    }

    /// The brick's samples from storage offset `offset` (a local index built from
    /// [`Self::strides`]) to the end of the view: the base of a trilinear cell.
    #[inline]
    pub fn samples_from(&self, offset: usize) -> &'a [T] {
        &self.samples[offset..]
    }

    /// The samples as one dense x-slowest, z-fastest block of exactly `extent`
    /// (no gaps between rows or planes), if they are stored so.
    pub fn contiguous(&self) -> Option<&'a [T]> {
        let [ex, ey, ez] = self.extent.map(|e| e as usize);
        (self.strides == [ey * ez, ez, 1]).then(|| &self.samples[..ex * ey * ez])
    }

    /// The z-run of samples at local `(x, y)`: `extent[2]` samples.
    #[inline]
    pub fn row(&self, x: u32, y: u32) -> &'a [T] {
        let start = linear_index(self.strides, [x, y, 0]);
        &self.samples[start..start + self.extent[2] as usize]
    }

    /// Smallest and largest sample inside the volume part of the brick.
    pub fn value_range(&self) -> (T, T) {
        let mut lo = self.get([0, 0, 0]);
        let mut hi = lo;
        for x in 0..self.extent[0] {
            for y in 0..self.extent[1] {
                for &v in self.row(x, y) {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
        (lo, hi)
    }
}

impl<'a, T: Sample> BrickView<'a, T> {
    /// The part of this view starting at local `offset` with `extent` voxels, with
    /// volume origin `origin + offset`.
    ///
    /// # Panics
    /// If the part reaches past this view.
    pub fn sub(&self, offset: [u32; 3], extent: [u32; 3]) -> BrickView<'a, T> {
        assert!(
            (0..3).all(|a| offset[a] + extent[a] <= self.extent[a] && extent[a] > 0),
            "sub-view outside its view"
        );
        let start = linear_index(self.strides, offset);
        let end = linear_index(self.strides, [0, 1, 2].map(|a| offset[a] + extent[a] - 1)) + 1;
        BrickView {
            samples: &self.samples[start..end],
            strides: self.strides,
            origin: [0, 1, 2].map(|a| self.origin[a] + offset[a]),
            extent,
        }
    }
}
