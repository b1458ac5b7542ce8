//! A tile: a rectangle of pixels with their rays and compositing state. Tiles move
//! by value between the compositing and render threads (never shared).

use super::camera::{Camera, PixelRect};
use super::counters::Counters;
use super::geometry::VolumeGeometry;
use super::ownership_lanes::{BrickOwnership, RayLanes};
use super::pixel::{PixelRay, PixelState};
use super::prepared::FramePlan;

/// A tile and everything its pixels have accumulated.
#[derive(Clone, Debug)]
pub(crate) struct Tile<S> {
    /// Index in the frame's tile list.
    pub index: u32,
    /// The compositing thread that owns it.
    pub compositor: u32,
    /// Its pixels.
    pub rect: PixelRect,
    /// Position of the next brick in the tile's queue.
    pub next: usize,
    /// Per pixel, row by row: the ray (`None` when it misses the volume), filled
    /// on the tile's first task.
    pub rays: Vec<Option<PixelRay>>,
    /// The rays as ownership reads them in lanes, filled with `rays` where
    /// the frame's SIMD level asks in lanes ([`BrickOwnership::in_lanes`]).
    pub ray_lanes: RayLanes,
    /// Per pixel: the compositing state.
    pub states: Vec<PixelState<S>>,
    /// Work done on this tile.
    pub counters: Counters,
}

impl<S: Copy> Tile<S> {
    /// A fresh tile with no rays yet.
    /// Every pixel starts from the compositor's `start` state.
    pub fn new(index: u32, compositor: u32, rect: PixelRect, start: S) -> Tile<S> {
        Tile {
            index,
            compositor,
            rect,
            next: 0,
            rays: Vec::new(),
            ray_lanes: RayLanes::default(),
            states: vec![PixelState::new(start); rect.area() as usize],
            counters: Counters::default(),
        }
    }

    /// Index of pixel `(x, y)` (image coordinates) in this tile.
    #[inline]
    pub fn local(&self, x: u32, y: u32) -> usize {
        ((y - self.rect.y0) * (self.rect.x1 - self.rect.x0) + (x - self.rect.x0)) as usize
    }

    /// Computes the pixels' rays (once, [`FramePlan::pixel_ray`]); pixels outside
    /// `volume_rect` get none.
    pub fn prepare_rays(
        &mut self,
        camera: &Camera,
        geometry: &VolumeGeometry,
        plan: &FramePlan,
        volume_rect: &PixelRect,
    ) {
        if !self.rays.is_empty() {
            return;
        }
        let r = self.rect;
        self.rays.reserve(r.area() as usize);
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let inside = x >= volume_rect.x0
                    && x < volume_rect.x1
                    && y >= volume_rect.y0
                    && y < volume_rect.y1;
                let ray = inside
                    .then(|| plan.pixel_ray(camera, geometry, x, y))
                    .flatten();
                self.counters.rays += u64::from(ray.is_some());
                self.rays.push(ray);
            }
        }
        if BrickOwnership::in_lanes(plan.simd) {
            self.ray_lanes = RayLanes::new(&self.rays);
        }
        for (state, ray) in self.states.iter_mut().zip(&self.rays) {
            match ray {
                Some(ray) => state.next_sample = state.next_sample.max(ray.first),
                None => state.done = true,
            }
        }
    }

    /// Whether every pixel of the tile is finished (needs rays prepared).
    pub fn all_finished(&self) -> bool {
        !self.rays.is_empty() && self.states.iter().all(|s| s.done)
    }

    /// Whether every pixel of `rect ∩ tile` is finished (needs rays prepared).
    pub fn finished_within(&self, rect: &PixelRect) -> bool {
        if self.rays.is_empty() {
            return false;
        }
        let Some(r) = self.rect.intersect(rect) else {
            return true;
        };
        (r.y0..r.y1).all(|y| (r.x0..r.x1).all(|x| self.states[self.local(x, y)].done))
    }
}
