//! A volume prepared for rendering (its brick grid and value ranges) and the
//! per-frame plan (sampled transfer function, empty bricks, kernel parameters).

use std::sync::Arc;

use glam::Vec3;
use parking_lot::Mutex;
use rayon::prelude::*;

use super::camera::Camera;
use super::cells::{BrickCells, CellRanges};
use super::clip::ClipRegion;
use super::compositor::FrameCompositor;
use super::error::RenderError;
use super::geometry::VolumeGeometry;
use super::level::DepthBand;
use super::local::LocalCompositor;
use super::pixel::{PixelRay, ray_jitter};
use super::read_ahead::ReadAheadLog;
use super::segments::Membership;
use super::settings::RenderSettings;
use super::simd::SimdLevel;
use super::transfer::TransferTable;
use super::two_level::TwoLevel;
use crate::volume::{
    BlockGrid, BrickRanges, BrickView, Layout, Sample, TypedVolume, Volume, VolumeData,
};

/// A volume with the brick grid the renderer walks and each brick's value range.
#[derive(Debug)]
pub struct RenderVolume<'a> {
    volume: &'a Volume,
    geometry: VolumeGeometry,
    /// The file's table (its own grid); the rendering grid's ranges are merged
    /// from it brick by brick ([`RenderVolume::brick_range`]).
    ranges: &'a BrickRanges,
    cells: CellRanges,
    labels: Option<&'a Volume>,
    /// The bricks read ahead so far ([`super::read_ahead`]).
    read_ahead: Mutex<ReadAheadLog>,
}

pub use crate::volume::{LARGE_LINEAR_BRICKS, default_linear_brick_side};

impl<'a> RenderVolume<'a> {
    /// Prepares `volume` for rendering by bricks of `brick_side` voxels. Linear files
    /// are cut into logical bricks of any side (default
    /// [`default_linear_brick_side`]); bricked files use their stored bricks
    /// (default) or logical sub-bricks whose step divides the stored one (side 16 →
    /// 4, 6, 16; side 32 → 2, 32). Nothing is read or allocated per brick here:
    /// brick ranges are merged from the file's table when a frame asks for them
    /// (exact when the grid is the table's or a multiple of it, else a superset:
    /// [`BrickRanges::covering_range`]), and the small cells' ranges are read
    /// from the file's cell table when it stores one for this grid
    /// ([`Volume::stored_cells`]), else computed the first time a frame visits
    /// their brick and kept for later frames ([`CellRanges`]); transfer-function
    /// changes never rescan.
    pub fn new(volume: &'a Volume, brick_side: Option<u32>) -> Result<Self, RenderError> {
        if let Some(side) = brick_side
            && side < 2
        {
            return Err(RenderError::BrickSide(side));
        }
        let grid = match volume.layout() {
            Layout::Bricked { side: file_side } => {
                let file_side = u32::from(file_side);
                let side = brick_side.unwrap_or(file_side);
                if side > file_side || (file_side - 1) % (side - 1) != 0 {
                    return Err(RenderError::SubBrick { side, file_side });
                }
                BlockGrid::new(volume.dims(), side)
            }
            Layout::Linear => {
                let side = brick_side.unwrap_or_else(|| default_linear_brick_side(volume.dims()));
                // A brick past the volume's largest side is the one brick of
                // that side (the same grid), not a grid of cells over empty
                // space.
                let largest = volume.dims().into_iter().max().unwrap_or(2).max(2);
                BlockGrid::new(volume.dims(), side.min(largest))
            }
        };
        Ok(RenderVolume {
            volume,
            geometry: VolumeGeometry::placed(grid, volume.spacing(), volume.origin())
                .sampling(volume.sampled_box()),
            ranges: volume.ranges(),
            cells: CellRanges::stored_or_lazy(&grid, volume.stored_cells()),
            labels: None,
            read_ahead: Mutex::new(ReadAheadLog::new(grid.block_count())),
        })
    }

    /// Brick `b` of the rendering grid over `data` (this volume's samples).
    pub fn brick_view<'d, T: Sample>(
        &self,
        data: &TypedVolume<'d, T>,
        b: [u32; 3],
    ) -> BrickView<'d, T> {
        let grid = self.geometry.grid();
        match data.layout() {
            Layout::Bricked { side } if u32::from(side) != grid.side() => {
                let file_grid = data.natural_grid(u32::from(side));
                let origin = grid.origin(b);
                let fb = file_grid.brick_of_voxel(origin);
                let file_origin = file_grid.origin(fb);
                let offset = [0, 1, 2].map(|a| origin[a] - file_origin[a]);
                data.brick(&file_grid, fb).sub(offset, grid.extent(b))
            }
            _ => data.brick(grid, b),
        }
    }

    /// Attaches a label volume (u8 object ids, same dimensions) for two-level
    /// rendering; its layout must fit the rendering grid like the data's.
    pub fn with_labels(mut self, labels: &'a Volume) -> Result<Self, RenderError> {
        let bad = |why: String| {
            Err(RenderError::Labels(format!(
                "{}: {why}",
                labels.path().display()
            )))
        };
        if labels.dims() != self.volume.dims() {
            return bad(format!(
                "dimensions {:?} differ from the data's {:?}",
                labels.dims(),
                self.volume.dims()
            ));
        }
        let VolumeData::U8(_) = labels.data() else {
            return bad("label volumes hold u8 ids".into());
        };
        // (A volume of values took every value for an id: a blank scene.)
        if labels.content() != crate::volume::Content::Labels {
            return bad(crate::volume::VolumeErrorKind::ValuesNotLabels.to_string());
        }
        if let Layout::Bricked { side } = labels.layout() {
            let (file_side, side) = (u32::from(side), self.geometry.grid().side());
            if side > file_side || (file_side - 1) % (side - 1) != 0 {
                return bad(format!(
                    "its bricks of side {file_side} do not fit the rendering bricks of side {side}; convert it to linear or to the data's bricks (volgen convert LABELS --layout linear -o NEW.vol)"
                ));
            }
        }
        self.labels = Some(labels);
        Ok(self)
    }

    /// The attached label volume, if any.
    pub fn labels(&self) -> Option<&'a Volume> {
        self.labels
    }

    /// The volume.
    pub fn volume(&self) -> &'a Volume {
        self.volume
    }

    /// Placement and brick grid.
    pub fn geometry(&self) -> &VolumeGeometry {
        &self.geometry
    }

    /// Value range of brick `b` of the rendering grid, merged from the file's
    /// table ([`BrickRanges::covering_range`]; the entry itself when the grids
    /// agree).
    pub fn brick_range(&self, b: [u32; 3]) -> [u16; 2] {
        self.ranges.covering_range(self.geometry.grid(), b)
    }

    /// Which bricks were read ahead so far.
    pub(crate) fn read_ahead_log(&self) -> &Mutex<ReadAheadLog> {
        &self.read_ahead
    }

    /// Value ranges of the small cells inside each brick (those computed so far).
    pub fn cells(&self) -> &CellRanges {
        &self.cells
    }

    /// The step (voxels) below which pre-integrated frames of this volume keep
    /// empty-space skipping: its bricks' step. From this step on, a ray can
    /// cross a brick between two samples without a sample in it, which no visit
    /// of that brick sees, and the frame plan turns skipping off (see
    /// `Dvr::range_empty`); below it the run walker checks the cells between
    /// samples (`SampleRuns`).
    pub fn preintegrated_skipping_below(&self) -> f32 {
        self.geometry.brick_step()
    }

    /// The smallest extent, in voxels, of a small cell of the bricks along an
    /// axis (a brick's last cell may be shorter than the others).
    pub(crate) fn min_cell_extent(&self) -> f32 {
        let brick = self.geometry.grid().step();
        let last = brick.saturating_sub((self.cells.per_axis() - 1) * self.cells.cell_step());
        let extent = if last == 0 {
            self.cells.cell_step()
        } else {
            last.min(self.cells.cell_step())
        };
        extent as f32
    }

    /// The small cells' ranges of brick `b`, computed from `data` (this volume's
    /// samples) on the first visit.
    pub fn cells_of<T: Sample>(&self, data: &TypedVolume<'_, T>, b: [u32; 3]) -> BrickCells {
        let index = self.geometry.grid().index(b);
        let known = self.brick_range(b);
        self.cells
            .of_brick(index, Some(known), || self.brick_view(data, b))
    }
}

/// Everything the marching loop needs for one frame, besides the bricks.
#[derive(Clone, Debug)]
pub(crate) struct FramePlan {
    /// How samples become pixels (plain mode or two-level).
    pub compositor: FrameCompositor,
    /// Opacity at which a ray stops (above 1 when early termination is off).
    pub ert_threshold: f32,
    /// Skip empty bricks.
    pub empty_space_skipping: bool,
    /// World distance between samples.
    pub dt: f32,
    /// Per axis: raw value per voxel → value normalised over the transfer
    /// function's domain per world unit of the smallest spacing.
    pub gradient_scale: Vec3,
    /// The parallel renderer's kernel (available on this machine).
    pub simd: SimdLevel,
    /// Per-pixel ray-start jitter ([`RenderSettings::jitter`]).
    pub jitter: bool,
    /// The part of the volume shown ([`RenderSettings::clip`]), in voxel
    /// coordinates of the level rendered.
    pub clip: ClipRegion,
    /// The depths this level samples in a frame of several levels; `None`: all.
    pub band: Option<DepthBand>,
}

impl FramePlan {
    /// The plan for rendering `volume` with `settings`.
    pub fn new(volume: &RenderVolume<'_>, settings: &RenderSettings) -> Result<Self, RenderError> {
        settings.check()?;
        let (sampled, scale) = (volume.volume().sampled_box(), volume.volume().level_scale());
        settings.clip.check_overlaps(sampled, scale)?;
        // A scene object's own cut is checked alike (one outside the volume
        // hid its object without a word).
        if let Some(scene) = &settings.segments {
            scene.check_cuts(sampled, scale)?;
        }
        let simd = match settings.simd {
            None => SimdLevel::automatic(),
            Some(level) if level.is_available() => level,
            Some(level) => return Err(RenderError::Simd(level)),
        };
        let type_max = volume.volume().sample_type().max_value();
        // Opacity is defined per level-0 voxel: a coarse level's samples stand for
        // `2^level` times the distance (the level's spacing).
        let step_ratio = settings.step * volume.volume().level_scale();
        let domain = settings
            .transfer
            .domain
            .unwrap_or([0.0, f32::from(type_max)]);
        let geometry = volume.geometry();
        // The fade of shading spans the data's quantisation at least.
        let shading = settings
            .shading
            .map(|s| s.covering_quantum(1.0 / (domain[1] - domain[0])));
        let compositor = match &settings.segments {
            Some(scene) => {
                if matches!(scene.membership, Membership::Labels(_)) && volume.labels().is_none() {
                    return Err(RenderError::Labels(
                        "the scene takes objects from a label volume but none is attached".into(),
                    ));
                }
                FrameCompositor::TwoLevel(TwoLevel::new(
                    scene,
                    type_max,
                    domain,
                    step_ratio,
                    settings.shading,
                    settings.preintegrated,
                    volume.volume().level_scale(),
                    settings.early_termination,
                    volume.volume().diagonal_voxels(),
                ))
            }
            None => {
                let mut table = TransferTable::new(&settings.transfer, type_max, step_ratio);
                if settings.preintegrates() {
                    table = table.with_preintegration(&settings.transfer, type_max);
                }
                FrameCompositor::Plain(
                    LocalCompositor::new(
                        settings
                            .mode
                            .local(&settings.mode_parameters, settings.iso_value),
                        Arc::new(table),
                        shading,
                        domain,
                        volume.volume().diagonal_voxels(),
                    )
                    .stopping_at(settings.early_termination),
                )
            }
        };
        let [d0, d1] = domain;
        let plan = FramePlan {
            compositor,
            ert_threshold: settings.early_termination.unwrap_or(f32::INFINITY),
            empty_space_skipping: settings.empty_space_skipping
                && !(settings.preintegrates()
                    && settings.step >= volume.preintegrated_skipping_below()),
            dt: settings.step * geometry.min_spacing(),
            jitter: settings.jitter,
            gradient_scale: Vec3::splat(geometry.min_spacing() / (d1 - d0)) / geometry.spacing(),
            simd,
            clip: settings.clip.at_level(volume.volume().level_scale()),
            band: None,
        };
        Ok(plan)
    }

    /// Whether no sample with a value in `lo..=hi` can change a pixel under this
    /// frame's compositor ([`Compositor::range_empty`](super::compositor::Compositor::range_empty)).
    /// An empty range (`lo > hi`, a cell owning no sample) is empty.
    pub fn range_empty(&self, lo: u16, hi: u16) -> bool {
        lo > hi || self.compositor.range_empty(lo, hi)
    }

    /// Whether no sample of brick `b` of `volume`'s grid can change a pixel
    /// under this frame's compositor, whatever came before.
    pub fn brick_transparent(&self, volume: &RenderVolume<'_>, b: [u32; 3]) -> bool {
        let [lo, hi] = volume.brick_range(b);
        self.range_empty(lo, hi)
    }

    /// The plan of one level of a frame of several: the level samples the depths
    /// of `band` only ([`LevelChoice::bands`](super::level::LevelChoice::bands)).
    pub fn in_band(mut self, band: Option<DepthBand>) -> Self {
        self.band = band;
        self
    }

    /// Pixel `(x, y)`'s ray through `geometry` (this plan's level), with its
    /// jitter, clip region and depth band.
    #[inline]
    pub fn pixel_ray(
        &self,
        camera: &Camera,
        geometry: &VolumeGeometry,
        x: u32,
        y: u32,
    ) -> Option<PixelRay> {
        let jitter = if self.jitter { ray_jitter(x, y) } else { 0.0 };
        let ray = camera.ray(x, y);
        match &self.band {
            None => PixelRay::new(&ray, geometry, self.dt, jitter, &self.clip),
            Some(band) => PixelRay::in_band(&ray, geometry, self.dt, jitter, &self.clip, band),
        }
    }

    /// Whether brick `b` of `volume`'s grid lies entirely outside the clip region,
    /// or outside this level's depth band.
    pub fn brick_cut_away(&self, volume: &RenderVolume<'_>, b: [u32; 3]) -> bool {
        if let Some(band) = &self.band {
            let (lo, hi) = volume.geometry().brick_world_box(b);
            if !band.may_hold(lo, hi, self.dt) {
                return true;
            }
        }
        if self.clip.is_empty() {
            return false;
        }
        let (lo, hi) = volume.geometry().brick_voxel_box(b);
        self.clip.cuts_away(lo, hi)
    }

    /// Whether brick `b` of `volume`'s grid can be left out of the frame: nothing
    /// in it can change a pixel, whatever came before, or it lies outside the clip
    /// region.
    pub fn brick_droppable(&self, volume: &RenderVolume<'_>, b: [u32; 3]) -> bool {
        // (Transparency asked only with empty-space skipping on.)
        self.droppable_if(
            self.empty_space_skipping && self.brick_transparent(volume, b),
            volume,
            b,
        )
    }

    /// [`Self::brick_droppable`] of a brick whose transparency the caller
    /// knows (`transparent`: [`Self::brick_transparent`]).
    pub(crate) fn droppable_if(
        &self,
        transparent: bool,
        volume: &RenderVolume<'_>,
        b: [u32; 3],
    ) -> bool {
        (self.empty_space_skipping && transparent) || self.brick_cut_away(volume, b)
    }

    /// Bricks of `volume`'s grid that no sample of can change a pixel (for the
    /// statistics): one pass over the grid, nothing per brick kept (a frame's
    /// schedule counts them in its own pass: `FrameSchedule::transparent`).
    pub fn transparent_bricks(&self, volume: &RenderVolume<'_>) -> u64 {
        let grid = volume.geometry().grid();
        (0..grid.counts()[0])
            .into_par_iter()
            .map(|x| {
                let slab = grid.slab(x);
                slab.filter(|&b| self.brick_transparent(volume, b)).count() as u64
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::LINEAR_RANGE_SIDE;

    #[test]
    fn large_linear_volumes_get_bricks_of_two_range_blocks() {
        assert_eq!(default_linear_brick_side([256; 3]), LINEAR_RANGE_SIDE);
        assert_eq!(
            default_linear_brick_side([800, 800, 800]),
            LINEAR_RANGE_SIDE
        );
        assert_eq!(default_linear_brick_side([1024; 3]), 31);
        assert_eq!(default_linear_brick_side([2000; 3]), 31);
        assert_eq!(default_linear_brick_side([1, 1, 1]), LINEAR_RANGE_SIDE);
    }
}
