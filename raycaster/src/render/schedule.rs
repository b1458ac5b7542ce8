//! The per-frame schedule of the object-parallel renderer: which bricks to render,
//! in which order, into which tiles.
//!
//! Bricks the transfer function makes empty are dropped; the rest are sorted front
//! to back by the distance of their (uncut) box centre from the eye (depth along
//! the view for orthographic cameras) and appended to the queue of every tile
//! their projected rectangle touches. For a grid of equal boxes this order is a
//! visibility order along every ray: a ray leaving a brick through a face enters
//! the neighbour whose centre is farther from the eye, so each ray meets its bricks
//! in queue order and its samples are composited in sequence.

use glam::Vec3;
use rayon::prelude::*;

use super::camera::{Camera, PixelRect, Projection};
use super::geometry::VolumeGeometry;
use super::partition::BrickBox;
use super::prepared::{FramePlan, RenderVolume};

/// A brick in the frame's order with its screen rectangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScheduledBrick {
    /// Grid coordinates.
    pub coords: [u32; 3],
    /// Pixels whose rays may meet it.
    pub rect: PixelRect,
    /// Its sort key: the distance of its centre from the eye (or its depth
    /// along the view).
    pub depth: f32,
}

/// One tile: its pixels and its bricks, front to back.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TileQueue {
    /// The tile's pixels.
    pub rect: PixelRect,
    /// Indices into [`FrameSchedule::bricks`], front to back.
    pub bricks: Vec<u32>,
}

/// Bricks in visibility order and the tiles' queues.
#[derive(Clone, Debug)]
pub(crate) struct FrameSchedule {
    /// Visible, non-empty bricks, front to back.
    pub bricks: Vec<ScheduledBrick>,
    /// Every tile of the image, row by row.
    pub tiles: Vec<TileQueue>,
    /// Pixels whose rays may hit the volume at all.
    pub volume_rect: Option<PixelRect>,
    /// The grid's bricks no sample of can change a pixel
    /// ([`FramePlan::transparent_bricks`]), counted in the schedule's pass
    /// over the grid; `None` where it made none over the whole grid (a part
    /// of it, or a volume off the image).
    pub transparent: Option<u64>,
}

impl FrameSchedule {
    /// The schedule of `volume` seen by `camera`, with square tiles of `tile_size`;
    /// with `part`, only that part's bricks (distributed rendering).
    pub fn new(
        volume: &RenderVolume<'_>,
        plan: &FramePlan,
        camera: &Camera,
        tile_size: u32,
        part: Option<&BrickBox>,
    ) -> Self {
        let tile_size = tile_size.max(1);
        let geometry = volume.geometry();
        let grid = geometry.grid();
        let (lo, hi) = geometry.world_bounds();
        let volume_rect = camera.project_box(lo, hi);
        let spacing = geometry.spacing();
        let step = grid.step() as f32;
        let eye = sorting_eye(camera, geometry);
        // One record per scheduled brick, sorted in place: no second list and
        // no merge-sort buffer (equal keys keep grid order, as a stable sort
        // would). Both in parallel: the schedule comes before the frame's
        // threads start (about 7 ms of the pass and 2 ms of the sort in a
        // frame of the thesis's 2000³ case, on one thread). The same pass
        // counts the transparent bricks.
        let scheduled = |b: [u32; 3], transparent: bool| {
            if plan.droppable_if(transparent, volume, b) || part.is_some_and(|p| !p.contains(b)) {
                return None;
            }
            let (blo, bhi) = geometry.brick_world_box(b);
            let rect = camera.project_box(blo, bhi)?;
            let centre =
                geometry.origin() + (Vec3::from(b.map(|c| c as f32)) + 0.5) * step * spacing;
            Some(ScheduledBrick {
                coords: b,
                rect,
                depth: match camera.projection() {
                    Projection::Perspective { .. } => (centre - eye).length(),
                    Projection::Orthographic { .. } => camera.depth_key(centre),
                },
            })
        };
        let (mut bricks, transparent) = if volume_rect.is_some() {
            // By slabs of bricks of one x, walked by coordinates: a brick's
            // coordinates from its index take three 64-bit divisions, which
            // were half the pass.
            let (bricks, transparent) = (0..grid.counts()[0])
                .into_par_iter()
                .fold(
                    || (Vec::new(), 0u64),
                    |(mut kept, mut transparent), x| {
                        for b in grid.slab(x) {
                            let clear = plan.brick_transparent(volume, b);
                            transparent += u64::from(clear);
                            kept.extend(scheduled(b, clear));
                        }
                        (kept, transparent)
                    },
                )
                .reduce(
                    || (Vec::new(), 0),
                    |(mut a, na), (b, nb)| {
                        a.extend(b);
                        (a, na + nb)
                    },
                );
            (bricks, part.is_none().then_some(transparent))
        } else {
            (Vec::new(), None)
        };
        bricks.par_sort_unstable_by(|a, b| {
            a.depth
                .total_cmp(&b.depth)
                .then_with(|| grid.index(a.coords).cmp(&grid.index(b.coords)))
        });
        let (w, h) = (camera.width(), camera.height());
        let (nx, ny) = (w.div_ceil(tile_size), h.div_ceil(tile_size));
        let mut tiles: Vec<TileQueue> = (0..ny)
            .flat_map(|ty| (0..nx).map(move |tx| (tx, ty)))
            .map(|(tx, ty)| TileQueue {
                rect: PixelRect {
                    x0: tx * tile_size,
                    y0: ty * tile_size,
                    x1: ((tx + 1) * tile_size).min(w),
                    y1: ((ty + 1) * tile_size).min(h),
                },
                bricks: Vec::new(),
            })
            .collect();
        for (i, brick) in bricks.iter().enumerate() {
            let r = brick.rect;
            for ty in r.y0 / tile_size..r.y1.div_ceil(tile_size) {
                for tx in r.x0 / tile_size..r.x1.div_ceil(tile_size) {
                    tiles[(ty * nx + tx) as usize].bricks.push(i as u32);
                }
            }
        }
        FrameSchedule {
            bricks,
            tiles,
            volume_rect,
            transparent,
        }
    }
}

/// The point a perspective frame sorts its bricks by their distance from: the
/// eye, or for an eye inside the volume the eye moved a quarter of a brick step
/// off the faces of the brick that owns it ([`VolumeGeometry::owner`]), into
/// that brick.
///
/// Between two bricks that share a face, the nearer centre is the one on the
/// eye's side of the face's plane, so any point on the same side of every
/// brick plane sorts them as the eye does. An eye on a plane (a camera placed
/// on a brick boundary) is on neither side, and the two centres tie: a ray
/// leaving the eye takes its first sample, on the plane, in the brick that owns
/// the plane, and its next ones in the brick on the side it goes, so that
/// brick must not come first. Moved into its owner, the eye sorts the owner
/// first; moved by less than half a step, it stays inside the owner and so on
/// the same side of every other plane.
fn sorting_eye(camera: &Camera, geometry: &VolumeGeometry) -> Vec3 {
    let eye = camera.position();
    let voxel = (eye - geometry.origin()) * geometry.spacing().recip();
    if !(voxel.cmpge(Vec3::ZERO).all() && voxel.cmple(geometry.last_voxel()).all()) {
        return eye;
    }
    let (lo, hi) = geometry.brick_voxel_box(geometry.owner(voxel));
    let margin = (hi - lo) * 0.25;
    geometry.origin() + voxel.clamp(lo + margin, hi - margin) * geometry.spacing()
}
