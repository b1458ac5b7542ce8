//! Ray casting: cameras, transfer functions, shading, the compositors, the marching
//! loop and the renderers.
//!
//! The renderer sees volumes only through [`RenderVolume`] (brick grid + value
//! ranges) and the sampler, never whether they are mapped or in RAM. Every renderer
//! marches rays through bricks with one generic loop over one compositor
//! interface (internal: the crate's `march` and `compositor` modules); samples
//! are placed globally along each ray so that the way the volume is cut cannot
//! change the image.

mod camera;
mod cell_cache;
mod cell_lanes;
mod cells;
mod clip;
mod compositor;
mod counters;
mod dark_average;
mod direct_send;
mod error;
mod frame;
mod front;
mod gather;
mod gather_gradients;
mod gather_layers;
mod gather_values;
mod geometry;
mod image;
mod level;
mod local;
mod march;
mod optics;
mod orbit;
mod ownership;
mod ownership_lanes;
mod packet;
mod parallel;
mod partition;
mod pixel;
mod prepared;
mod progress;
mod ray;
mod read_ahead;
mod relay;
mod renderer;
mod runs;
mod sabella;
mod sampler;
mod schedule;
mod segments;
mod sequential;
mod settings;
mod settings_check;
mod shading;
mod simd;
mod state_buffer;
#[cfg(test)]
mod test_rng;
mod tile;
mod transfer;
mod truncate;
mod two_level;

pub use camera::{
    Camera, CameraError, LookAtProblem, MAX_CAMERA_DISTANCE, MAX_IMAGE_SIDE, PixelRect, Projection,
    look_at_problem,
};
pub use cells::{
    BrickCells, CELL_CACHE_BYTES, CellRanges, MAX_CELLS, TARGET_CELL_STEP, target_cell_step,
};
pub use clip::{ClipPlane, ClipRegion, CropBox, MAX_CLIP_PLANES};
pub use counters::{Counters, FrameStats};
pub use dark_average::{DarkAverage, dark_average};
pub use error::RenderError;
pub use frame::Frame;
pub use front::{FrameBuffer, FrameEvent, FrameRequest, Notify, RenderFront};
pub use geometry::{
    MAX_SAMPLES_PER_FRAME, MAX_SAMPLES_PER_RAY, VolumeGeometry, check_sample_budget, samples_over,
    world_diagonal,
};
pub use glam::{Mat3, Vec3};
pub use image::{ImageError, RgbImage};
pub use level::{DepthBand, LevelBand, LevelChoice};
pub use optics::corrected_alpha;
pub use orbit::{Orbit, patient_axes};
pub use parallel::{
    DEFAULT_TILE_SIZE, MAX_THREADS, ParallelOptions, TileSink, render_parallel,
    render_parallel_into,
};
pub use partition::{BrickBox, Partition};
pub use prepared::{LARGE_LINEAR_BRICKS, RenderVolume, default_linear_brick_side};
pub use progress::PixelProgress;
pub use ray::Ray;
pub use relay::{
    ChannelLink, Compositing, DistributedFrame, DistributedOptions, Link, LinkError, RankStats,
    channel_links, default_bands, render_distributed, render_distributed_levels,
};
pub use renderer::Renderer;
pub use sabella::{SabellaChannels, SabellaDepth, SabellaMapping, SabellaOutput, hsv_to_rgb};
pub use segments::{
    GlobalMode, ImportanceSource, LocalMode, Membership, ObjectStyle, SceneError, SegmentScene,
};
pub use sequential::{render_sequential, render_sequential_levels, render_sequential_noting};
pub use settings::{
    AUTO_XRAY_DEPTH, DEFAULT_ERT_THRESHOLD, Mode, ModeParameters, RenderSettings, auto_xray_gain,
    flat_volume, step_past_volume,
};
pub use settings_check::{MAX_LIGHT_FACTOR, check_light_factor, light_direction_problem};
pub use shading::{FADE_QUANTA, Light, Shading};
pub use simd::{SimdLevel, available as simd_levels};
pub use state_buffer::{StateBuffer, StateBufferError};
pub use transfer::{
    ControlPoint, PRESETS, TEXT_MAX, TransferError, TransferFunction, check_domain,
    check_gradient_ramp, closest_preset,
};
