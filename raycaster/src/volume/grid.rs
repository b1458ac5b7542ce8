//! Geometry of a grid of cubic bricks that overlap their neighbours by one voxel.
//!
//! A brick of side `B` spans `B - 1` cells: brick `b` holds voxels
//! `b·(B-1) ..= b·(B-1) + B-1` on each axis, so trilinear sampling anywhere inside
//! its cells never needs a second brick. This is the thesis's bricked layout; linear
//! volumes use the same grid for logical bricks and value-range blocks.

/// A grid of overlapping cubic bricks covering a volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BlockGrid {
    dims: [u32; 3],
    side: u32,
    counts: [u32; 3],
}

impl BlockGrid {
    /// The grid of bricks of `side` voxels (at least 2) over a volume of `dims`.
    ///
    /// Bricks per axis: `ceil((dim - 1) / (side - 1))`, at least one.
    pub fn new(dims: [u32; 3], side: u32) -> Self {
        let side = side.max(2);
        let step = side - 1;
        let counts = dims.map(|d| d.saturating_sub(1).div_ceil(step).max(1));
        BlockGrid { dims, side, counts }
    }

    /// Volume size in voxels.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// Brick side in voxels (stored extent of a whole brick).
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Cells per brick on each axis: the distance between brick origins.
    pub fn step(&self) -> u32 {
        self.side - 1
    }

    /// Bricks per axis.
    pub fn counts(&self) -> [u32; 3] {
        self.counts
    }

    /// Total number of bricks.
    pub fn block_count(&self) -> u64 {
        self.counts.iter().map(|&c| u64::from(c)).product()
    }

    /// First voxel of brick `b`.
    pub fn origin(&self, b: [u32; 3]) -> [u32; 3] {
        b.map(|c| c * self.step())
    }

    /// Voxels of brick `b` that lie inside the volume, per axis (overlap included,
    /// padding of edge bricks excluded).
    pub fn extent(&self, b: [u32; 3]) -> [u32; 3] {
        let o = self.origin(b);
        [0, 1, 2].map(|a| self.side.min(self.dims[a] - o[a]))
    }

    /// Position of brick `b` in file order (bz fastest, then by, then bx).
    pub fn index(&self, b: [u32; 3]) -> u64 {
        let [_, ny, nz] = self.counts.map(u64::from);
        (u64::from(b[0]) * ny + u64::from(b[1])) * nz + u64::from(b[2])
    }

    /// Brick coordinates of the brick at file position `index`.
    pub fn coords(&self, index: u64) -> [u32; 3] {
        let [_, ny, nz] = self.counts.map(u64::from);
        [
            (index / (ny * nz)) as u32,
            ((index / nz) % ny) as u32,
            (index % nz) as u32,
        ]
    }

    /// All brick coordinates in file order (counted up, not divided out of
    /// indices).
    pub fn iter(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        (0..self.counts[0]).flat_map(move |x| self.slab(x))
    }

    /// The coordinates of the bricks whose first coordinate is `x`, in file
    /// order: one slab of [`Self::iter`], for walking the grid in parallel.
    pub fn slab(&self, x: u32) -> impl Iterator<Item = [u32; 3]> + use<> {
        let [_, ny, nz] = self.counts;
        (0..ny).flat_map(move |y| (0..nz).map(move |z| [x, y, z]))
    }

    /// The brick that owns voxel `v`: on a shared face the lower brick.
    pub fn brick_of_voxel(&self, v: [u32; 3]) -> [u32; 3] {
        [0, 1, 2].map(|a| (v[a] / self.step()).min(self.counts[a] - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_brick_counts() {
        // 256³ with B = 16 → 17³ bricks (seed digest).
        assert_eq!(BlockGrid::new([256; 3], 16).counts(), [17; 3]);
        assert_eq!(BlockGrid::new([800; 3], 16).counts(), [54; 3]);
    }

    #[test]
    fn edge_bricks_are_partial() {
        let g = BlockGrid::new([20, 16, 2], 8);
        assert_eq!(g.counts(), [3, 3, 1]);
        assert_eq!(g.extent([2, 2, 0]), [6, 2, 2]);
        assert_eq!(g.extent([0, 0, 0]), [8, 8, 2]);
    }

    #[test]
    fn index_and_coords_are_inverse() {
        let g = BlockGrid::new([40, 30, 20], 6);
        for (i, b) in g.iter().enumerate() {
            assert_eq!(g.index(b), i as u64);
            assert_eq!(g.coords(i as u64), b);
        }
        assert_eq!(g.iter().count() as u64, g.block_count());
    }

    #[test]
    fn every_voxel_lies_in_its_owner_brick() {
        let g = BlockGrid::new([23, 9, 17], 5);
        for x in 0..23 {
            let b = g.brick_of_voxel([x, 0, 16]);
            let o = g.origin(b);
            let e = g.extent(b);
            assert!(x >= o[0] && x < o[0] + e[0]);
            assert!(16 >= o[2] && 16 < o[2] + e[2]);
        }
    }
}
