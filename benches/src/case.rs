//! [`BenchCase`]: everything one benchmarked frame depends on, in one value.

use std::fmt;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{Context, Result, bail};
use raycaster::render::{
    Camera, DEFAULT_ERT_THRESHOLD, DEFAULT_TILE_SIZE, Frame, Mode, Orbit, ParallelOptions,
    RenderSettings, RenderVolume, Renderer, SimdLevel, TransferFunction, patient_axes,
    render_parallel, render_sequential,
};
use raycaster::volume::{Access, Layout, SampleType, Volume};

use crate::volumes::VolumeSpec;

/// Which of the two optimisations are on (the thesis's four columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Optimisations {
    /// Neither early ray termination nor empty-space skipping.
    None,
    /// Early ray termination only.
    Ert,
    /// Empty-space skipping only.
    Ess,
    /// Both.
    Both,
}

impl Optimisations {
    /// The four settings, in the thesis's order.
    pub const ALL: [Optimisations; 4] = [
        Optimisations::None,
        Optimisations::Ert,
        Optimisations::Ess,
        Optimisations::Both,
    ];

    /// The setting's name on the command line and in ids: none, ert, ess, both.
    pub fn name(self) -> &'static str {
        match self {
            Optimisations::None => "none",
            Optimisations::Ert => "ert",
            Optimisations::Ess => "ess",
            Optimisations::Both => "both",
        }
    }

    /// Whether early ray termination is on.
    pub fn ert(self) -> bool {
        matches!(self, Optimisations::Ert | Optimisations::Both)
    }

    /// Whether empty-space skipping is on.
    pub fn ess(self) -> bool {
        matches!(self, Optimisations::Ess | Optimisations::Both)
    }
}

impl fmt::Display for Optimisations {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Optimisations {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        match Optimisations::ALL.into_iter().find(|o| o.name() == s) {
            Some(o) => Ok(o),
            None => bail!("unknown optimisation set {s:?} (none, ert, ess, both)"),
        }
    }
}

/// A camera preset, framing the whole volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum View {
    /// `raycaster render`'s default: front-right, a little above, 40° field of view.
    Default,
    /// Face-on from +x (rays run along x), as the thesis's slab images.
    Front,
    /// The default angles, twice as close: the volume overfills the image.
    Close,
}

impl View {
    /// The preset's name in ids.
    pub fn name(self) -> &'static str {
        match self {
            View::Default => "default",
            View::Front => "front",
            View::Close => "close",
        }
    }

    /// The camera of this view of `volume` for an image of `image` pixels.
    pub fn camera(self, volume: &Volume, image: [u32; 2]) -> Result<Camera> {
        let (lo, hi) = raycaster::source::world_box(volume);
        let mut orbit = Orbit::default_view(lo, hi);
        match self {
            View::Default => {}
            View::Front => orbit = Orbit::framing(lo, hi, 0.0, 0.0, Some(40.0)),
            // (`zoom` scales the distance: a half is twice as near.)
            View::Close => orbit.zoom(0.5),
        }
        // In the patient's directions where the file gives them, as
        // `raycaster render` turns its views.
        let orbit = orbit.with_axes(patient_axes(volume.orientation()));
        Ok(orbit.camera(image[0], image[1])?)
    }
}

/// One benchmarked frame: the volume (and how it is stored and held), the
/// optimisations, the renderer and its parameters, the camera and the sampling.
///
/// Criterion groups and the `raycaster bench` sweep are lists of these; [`name`]
/// is the benchmark id and [`BenchCase::prepare`] renders frames of it.
///
/// [`name`]: BenchCase::name
#[derive(Clone, Debug, PartialEq)]
pub struct BenchCase {
    /// The volume (generated into the cache when missing) and its access.
    pub volume: VolumeSpec,
    /// Early ray termination and empty-space skipping.
    pub optimisations: Optimisations,
    /// Render threads of the parallel renderer; `None` is the sequential renderer.
    pub threads: Option<usize>,
    /// Tile side in pixels (parallel renderer).
    pub tile: u32,
    /// Brick side the renderer walks: logical bricks of a linear file, sub-bricks of
    /// a bricked one; `None` is the default (16, or the file's own bricks).
    pub brick: Option<u32>,
    /// Camera preset.
    pub view: View,
    /// Sample step in voxels.
    pub step: f32,
    /// Compositing mode.
    pub mode: Mode,
    /// Blinn-Phong shading on (DVR and first hit).
    pub shading: bool,
    /// Pre-integrated DVR segments (`--preintegrate`).
    pub preintegrated: bool,
    /// Transfer-function preset; `None`: the preset and domain `raycaster
    /// render` fits to the data by default ([`raycaster::windows::fit`]: `shapes`
    /// for u8 volumes, a CT window for CT), chosen by [`BenchCase::prepare`].
    pub transfer: Option<&'static str>,
    /// Image size in pixels.
    pub image: [u32; 2],
    /// The parallel renderer's kernel (`None`: the automatic choice).
    pub simd: Option<SimdLevel>,
}

impl Default for BenchCase {
    /// Shaded DVR of a 256³ u8 `shapes` volume (linear, in RAM) with ERT and ESS,
    /// the parallel renderer with one render thread per core, tiles of 16, bricks
    /// of 16, the default view at 256×256, step 0.5.
    fn default() -> Self {
        BenchCase {
            volume: VolumeSpec::shapes(256),
            optimisations: Optimisations::Both,
            threads: Some(cores()),
            tile: DEFAULT_TILE_SIZE,
            brick: None,
            view: View::Default,
            step: 0.5,
            mode: Mode::Dvr,
            shading: true,
            preintegrated: false,
            transfer: Some("shapes"),
            image: [256, 256],
            simd: None,
        }
    }
}

/// The machine's core count.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, NonZeroUsize::get)
}

impl BenchCase {
    /// A unique, readable id of every field (criterion ids, table rows), e.g.
    /// `shapes-256-u8-linear-ram/both/t2-tile16-brick16/default-step0.5-dvr-256x256`.
    pub fn name(&self) -> String {
        let renderer = match self.threads {
            None => format!("seq-{}", self.brick_name()),
            Some(t) => format!("t{t}-tile{}-{}", self.tile, self.brick_name()),
        };
        let renderer = match self.simd {
            Some(level) => format!("{renderer}-{level}"),
            None => renderer,
        };
        let shading = match (self.shading, self.preintegrated) {
            (true, false) => "",
            (false, false) => "-unshaded",
            (true, true) => "-preintegrated",
            (false, true) => "-unshaded-preintegrated",
        };
        let transfer = match self.transfer {
            Some("shapes") => String::new(),
            Some(preset) => format!("-tf-{preset}"),
            None => "-tf-fitted".to_string(),
        };
        format!(
            "{}/{}/{renderer}/{}-step{}-{}{shading}{transfer}-{}x{}",
            self.volume.name(),
            self.optimisations,
            self.view.name(),
            self.step,
            self.mode.name(),
            self.image[0],
            self.image[1]
        )
    }

    /// `brick16`, or `brick-default` for the default bricks.
    fn brick_name(&self) -> String {
        match self.brick {
            Some(b) => format!("brick{b}"),
            None => "brick-default".to_string(),
        }
    }

    /// `"sequential"` or `"parallel"`.
    pub fn renderer(&self) -> &'static str {
        if self.threads.is_some() {
            "parallel"
        } else {
            "sequential"
        }
    }

    /// Render threads (1 for the sequential renderer).
    pub fn render_threads(&self) -> usize {
        self.threads.unwrap_or(1)
    }

    /// The render settings of the case (with `transfer` `None`, the `shapes`
    /// preset: [`BenchCase::prepare`] fits it to the volume).
    pub fn settings(&self) -> Result<RenderSettings> {
        if !(self.step > 0.0 && self.step.is_finite()) {
            bail!("step must be a positive number, not {}", self.step);
        }
        let defaults = RenderSettings::default();
        Ok(RenderSettings {
            mode: self.mode,
            step: self.step,
            early_termination: self.optimisations.ert().then_some(DEFAULT_ERT_THRESHOLD),
            empty_space_skipping: self.optimisations.ess(),
            shading: if self.shading { defaults.shading } else { None },
            preintegrated: self.preintegrated,
            transfer: TransferFunction::preset(self.transfer.unwrap_or("shapes"))?,
            simd: self.simd,
            ..defaults
        })
    }

    /// The parallel renderer's options, or `None` for the sequential renderer.
    pub fn parallel_options(&self) -> Result<Option<ParallelOptions>> {
        let Some(threads) = self.threads else {
            return Ok(None);
        };
        if threads == 0 || self.tile == 0 {
            bail!("threads and tile must be at least 1");
        }
        Ok(Some(ParallelOptions {
            render_threads: threads,
            compositing_threads: 1,
            tile_size: self.tile,
        }))
    }

    /// Generates the case's volume into `cache_dir` when missing and opens it.
    pub fn open_volume(&self, cache_dir: &Path) -> Result<Volume> {
        self.volume.open(cache_dir)
    }

    /// Prepares `volume` (which must be the case's, see [`BenchCase::open_volume`])
    /// for rendering frames of this case.
    pub fn prepare<'v>(&self, volume: &'v Volume) -> Result<PreparedCase<'v>> {
        let prepared = RenderVolume::new(volume, self.brick).with_context(|| {
            let side = self
                .brick
                .map_or_else(|| "default".to_string(), |b| b.to_string());
            format!("brick side {side} of {}", self.name())
        })?;
        self.prepare_with(prepared)
    }

    /// As [`BenchCase::prepare`], with an already prepared volume (to share one
    /// between cases of the same brick side).
    pub fn prepare_with<'v>(&self, volume: RenderVolume<'v>) -> Result<PreparedCase<'v>> {
        // As render: the preset that fits the data unless one is named, over
        // the preset's own domain, else the one fitted to the data (a CT
        // window, a u16 file's percentiles).
        let mut settings = self.settings()?;
        let fit = raycaster::windows::fit(volume.volume());
        if self.transfer.is_none() {
            settings.transfer = TransferFunction::preset(fit.preset)?;
        }
        if settings.transfer.domain.is_none() {
            settings.transfer.domain = fit.domain;
        }
        Ok(PreparedCase {
            camera: self.view.camera(volume.volume(), self.image)?,
            settings,
            options: self.parallel_options()?,
            volume,
        })
    }
}

/// A case ready to render: the prepared volume, camera, settings and renderer.
#[derive(Debug)]
pub struct PreparedCase<'v> {
    /// The volume with the case's brick grid.
    pub volume: RenderVolume<'v>,
    /// The case's camera.
    pub camera: Camera,
    /// The case's settings.
    pub settings: RenderSettings,
    /// The parallel renderer's options; `None` renders sequentially.
    pub options: Option<ParallelOptions>,
}

impl PreparedCase<'_> {
    /// Renders one frame (its statistics count the samples).
    pub fn frame(&self) -> Result<Frame> {
        Ok(match &self.options {
            Some(o) => render_parallel(&self.volume, &self.camera, &self.settings, o)?,
            None => render_sequential(&self.volume, &self.camera, &self.settings)?,
        })
    }

    /// Renders one frame with `renderer`, whose worker threads live across frames
    /// (the sequential renderer when the case has no parallel options).
    pub fn frame_on(&self, renderer: &mut Renderer) -> Result<Frame> {
        Ok(match &self.options {
            Some(o) => renderer.render(&self.volume, &self.camera, &self.settings, o)?,
            None => render_sequential(&self.volume, &self.camera, &self.settings)?,
        })
    }

    /// Renders one frame and returns its sample count.
    pub fn samples(&self) -> Result<u64> {
        Ok(self.frame()?.stats.counters.samples)
    }
}

/// Where generated benchmark volumes are kept: `$RAYCASTER_BENCH_DIR`, or
/// `target/bench-volumes` of this workspace.
pub fn default_cache_dir() -> PathBuf {
    match std::env::var_os("RAYCASTER_BENCH_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench-volumes"),
    }
}

/// Quick mode (small volumes and images): under `cargo test --benches` (criterion's
/// test mode, without `--bench`) or with `RAYCASTER_BENCH_QUICK=1`.
pub fn quick_mode() -> bool {
    std::env::var("RAYCASTER_BENCH_QUICK").is_ok_and(|v| v != "0" && !v.is_empty())
        || !std::env::args().any(|a| a == "--bench")
}

/// Parses `ram` / `mapped`.
pub fn parse_access(s: &str) -> Result<Access> {
    match s {
        "ram" => Ok(Access::Ram),
        "mapped" | "mmap" => Ok(Access::Mapped),
        _ => bail!("unknown access {s:?} (ram, mapped)"),
    }
}

/// Parses `u8` / `u16`.
pub fn parse_sample_type(s: &str) -> Result<SampleType> {
    match s {
        "u8" => Ok(SampleType::U8),
        "u16" => Ok(SampleType::U16),
        _ => bail!("unknown sample type {s:?} (u8, u16)"),
    }
}

/// Parses `linear` / `bricked` (side 16) / `bricked:N`.
pub fn parse_layout(s: &str) -> Result<Layout> {
    match s {
        "linear" => Ok(Layout::Linear),
        "bricked" => Ok(Layout::Bricked { side: 16 }),
        _ => match s.strip_prefix("bricked:").map(str::parse::<u8>) {
            Some(Ok(side)) if side >= 2 => Ok(Layout::Bricked { side }),
            _ => bail!("unknown layout {s:?} (linear, bricked, bricked:N with N in 2..=255)"),
        },
    }
}
