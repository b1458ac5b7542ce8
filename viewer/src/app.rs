//! The viewer's controller: owns the render front and the view state, turns UI
//! callbacks into frame requests and shows frames as they fill in.
//!
//! The UI thread never renders and never waits for a frame: requests go to the
//! library's [`RenderFront`] (a newer request supersedes the frame in progress),
//! and the front wakes the UI thread (coalesced) whenever tiles land. Volumes
//! are opened on a background thread; a failure leaves the current volume.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::rc::{Rc, Weak};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context, Result};
use crossbeam_channel::{Receiver, Sender};
use raycaster::render::{Camera, ClipRegion};
use raycaster::render::{
    DEFAULT_ERT_THRESHOLD, FrameEvent, FrameRequest, FrameStats, GlobalMode, LevelChoice,
    Membership, Mode, Notify, ObjectStyle, PRESETS, ParallelOptions, RenderFront, RenderSettings,
    SegmentScene, TransferFunction,
};
use raycaster::session::{Session, SessionCamera, SliceViews, SliceWindow};
use raycaster::slice::Axis;
use raycaster::source::VolumeSource;
use raycaster::synth::SceneKind;
use raycaster::text::counted;
use raycaster::volume::{VolumeError, VolumeErrorKind, write_file_atomically};
use slint::{
    ComponentHandle, Image, ModelRc, Rgba8Pixel, SharedPixelBuffer, SharedString, VecModel,
};

use crate::cut::CutValues;
use crate::loader::{self, LoadedVolume};
use crate::navigation::{AxisView, DragKind, Navigator};
use crate::quality::{QualityPolicy, StepPreset};
use crate::segments_panel::{self, LOCAL_MODES, ObjectRowData};
use crate::shortcuts::Shortcut;
use crate::slices::{Crosshair, WheelSteps};
use crate::ui::{App, ObjectRow};

/// Quiet time after the last camera change before the full-quality frame.
const SETTLE: Duration = Duration::from_millis(200);
/// Canvas size assumed before the window is laid out.
const FALLBACK_CANVAS: (u32, u32) = (640, 480);
/// Frames whose cameras are remembered (requests in flight at once).
const REMEMBERED_CAMERAS: usize = 8;
/// Tile sizes of the settings panel.
const TILE_SIZES: [u32; 4] = [8, 16, 32, 64];

/// What to open.
#[derive(Clone, Debug)]
pub enum Source {
    /// A generated scene (seed 1).
    BuiltIn(SceneKind, u32),
    /// A volume file.
    File(PathBuf),
    /// A saved session: its volume, camera, transfer function and settings.
    Session(PathBuf),
}

/// The step presets' still steps, in the panel's order (fine, coarse, adaptive).
const STEP_PRESETS: [StepPreset; 3] = [StepPreset::Fine, StepPreset::Coarse, StepPreset::Adaptive];

/// A volume with its renderer.
struct Loaded {
    volume: LoadedVolume,
    front: RenderFront,
}

/// The outcome of background work that replaces the renderer.
struct Install {
    loaded: Loaded,
    /// A new volume (reset view, transfer function) or the same one with labels.
    new_volume: bool,
    /// Where a new volume came from.
    source: Option<VolumeSource>,
    /// A label volume given by the session, not by its scene.
    labels_path: Option<PathBuf>,
    /// A scene to switch to.
    scene: Option<SegmentScene>,
    /// A session to restore once the volume is in place.
    session: Option<Box<Session>>,
    /// The file or session the user opened, for the recent files.
    recent: Option<PathBuf>,
    message: String,
}

/// The running viewer: its window and controller.
pub struct Viewer {
    ui: App,
    controller: Rc<Controller>,
}

/// What a background open sends back: a volume to install or an error message.
type InstallResult = Result<Install, String>;
type InstallSender = Sender<InstallResult>;

struct Controller {
    ui: slint::Weak<App>,
    state: RefCell<State>,
    /// Set while a pump is posted to the event loop (wake-ups coalesce).
    scheduled: Arc<AtomicBool>,
    wake: Notify,
    installs: (InstallSender, Receiver<InstallResult>),
    settle: slint::Timer,
    /// Repaints the whole window again a moment after a new volume
    /// ([`Controller::repaint_window`]).
    repaint: slint::Timer,
}

struct State {
    current: Option<Loaded>,
    nav: Navigator,
    quality: QualityPolicy,
    editor: crate::tf_editor::TfEditor,
    scene: Option<SegmentScene>,
    /// The newest request: id and whether it was an interactive (coarse) frame.
    latest: Option<(u64, bool)>,
    /// How the newest request samples its rays.
    latest_sampling: Sampling,
    /// The newest average-mode request's id and settings, until its
    /// full-quality frame has been looked at for darkness
    /// ([`Controller::note_dark_average`]).
    average_to_check: Option<(u64, RenderSettings)>,
    /// Frame id and tiles of the image on screen.
    shown: (u64, u64),
    last_stats: Option<(FrameStats, bool)>,
    /// How the frame of `last_stats` sampled its rays.
    last_sampling: Sampling,
    /// The id of the newest request that ended (done or failed).
    ended: Option<u64>,
    /// The camera moved while a moving frame was in flight: the newest view is
    /// requested when that frame ends (moving frames are never dropped
    /// unfinished, so a picture keeps up with a drag).
    pending_move: bool,
    /// A full-quality frame was asked for while a moving frame was in flight:
    /// it is requested once the moving frames have caught up with the camera,
    /// so its tiles fill in over a picture of its own view (over the older
    /// view of a superseded moving frame they showed torn edges for as long as
    /// the frame took).
    pending_still: bool,
    /// Frames superseded before they finished.
    superseded: u64,
    busy: bool,
    /// No frame of the newly opened volume is done yet: frames sample the coarsest
    /// pyramid level, so a picture shows at once, and refine when the view rests.
    first_frame: bool,
    /// Where the volume on screen came from (for sessions).
    source: VolumeSource,
    /// A label volume a session named (saved back into sessions).
    labels_path: Option<PathBuf>,
    /// The settings no panel edits (mode parameters, iso-value, crop and clip,
    /// light, background, ...): the defaults, or what a session restored.
    fixed: RenderSettings,
    /// The level choice of still frames (a session may fix one).
    level: LevelChoice,
    /// A still step a session restored that no step preset has, with the
    /// preset index it applies to (until another preset is picked).
    step_override: Option<(i32, f32)>,
    /// The cut a session restored, with the panel values that show it: used as
    /// given (bit for bit) until a Cut control changes.
    cut_restored: Option<(CutValues, ClipRegion)>,
    /// The slice views' crosshair (full-resolution voxels).
    crosshair: Crosshair,
    /// The pyramid level the slice views read.
    slice_level: usize,
    /// Per slice view (x, y, z): its wheel deltas short of a step.
    slice_wheel: [WheelSteps; 3],
    /// The recent files, newest first.
    recent: Vec<PathBuf>,
    /// Per slice view (x, y, z): the shown part of the slice, first column
    /// and row, width and height (level pixels).
    slice_frames: [[u32; 4]; 3],
    /// The canvas size (physical pixels) of the newest frame request.
    canvas: (u32, u32),
    /// A recent-files error was shown (shown once, not on every open).
    recent_error_shown: bool,
    /// The job in the background was started from the command line (a
    /// scene's label volume): its error goes to the terminal too.
    started_at_launch: bool,
    /// What the red message on screen says went wrong, where it is a state the
    /// viewer leaves again (a frame or the slices that could not be drawn):
    /// the message goes when that part draws again. `None` for any other
    /// message, which stays until the next one.
    shown_failure: Option<Failure>,
    /// A screenshot asked for while the frame was still rendering: saved when
    /// the full-quality frame of the view is complete (not half old, half new).
    pending_screenshot: Option<PathBuf>,
    /// An existing file a save button was pressed on once: a second press on
    /// the same path replaces it.
    overwrite_armed: Option<PathBuf>,
    /// The newest request that failed, and its error: no screenshot of it.
    failed: Option<(u64, String)>,
    /// The file browser's folder and the entries it lists.
    browser: Option<(PathBuf, Vec<crate::browser::Entry>)>,
    /// The newest requests' ids, cameras and orbit targets: the annotations of
    /// the frame on screen follow its own camera.
    cameras: VecDeque<(u64, Camera, glam::Vec3)>,
    /// The slice views' window (stored values) on screen, the one a right-drag
    /// started from, and the free window such drags set.
    slice_window: [f32; 2],
    window_drag_base: [f32; 2],
    custom_window: Option<[f32; 2]>,
}

impl State {
    /// The volume on screen's voxels per axis and spacing (one voxel of unit
    /// spacing before a volume is there): what the Cut panel's values mean.
    fn volume_shape(&self) -> ([u32; 3], [f32; 3]) {
        self.current.as_ref().map_or(([1; 3], [1.0; 3]), |c| {
            (c.volume.volume.dims(), c.volume.volume.spacing())
        })
    }
}

/// A part of the view that could not be drawn, said on the message line until
/// it draws again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Failure {
    /// A frame of the 3D view (its camera or its render).
    Frame,
    /// The slice views.
    Slices,
    /// Not a failure: an average-mode picture said to be dark, until a frame
    /// of another mode is asked for or an average one is not dark.
    DarkAverage,
    /// Not a failure: every object of the two-level scene hidden, until one
    /// shows again.
    AllObjectsHidden,
}

thread_local! {
    /// The controller the event-loop wake-ups pump (one viewer per UI thread).
    static ACTIVE: RefCell<Weak<Controller>> = const { RefCell::new(Weak::new()) };
}

impl Viewer {
    /// Builds the window and opens `source` (a bad file shows its error over the
    /// built-in scene); `scene` is a two-level scene description to load.
    pub fn new(source: Source, scene: Option<PathBuf>) -> Result<Viewer> {
        let ui = App::new().context("cannot create the viewer window")?;
        init_models(&ui);
        let scheduled = Arc::new(AtomicBool::new(false));
        let wake = wake_up(scheduled.clone());
        let installs = crossbeam_channel::unbounded();
        let fallback = || -> Result<(LoadedVolume, VolumeSource)> {
            let source = VolumeSource::BuiltIn {
                kind: SceneKind::Shapes,
                size: loader::BUILT_IN_SIZE,
                seed: 1,
            };
            Ok((loader::open_source(&source)?, source))
        };
        let mut session = None;
        let mut labels_path = None;
        let ((mut first, mut first_source), mut error) = match &source {
            Source::BuiltIn(kind, size) => {
                let source = VolumeSource::BuiltIn {
                    kind: *kind,
                    size: *size,
                    seed: 1,
                };
                ((loader::open_source(&source)?, source), None)
            }
            Source::File(path) => match loader::open_file(path) {
                Ok(v) => ((v, loader::file_source(path)), None),
                Err(e) => (fallback()?, Some(over_built_in_scene(e.as_ref()))),
            },
            Source::Session(path) => match open_session_volume(path, None) {
                Ok((s, v, labels)) => {
                    let source = s.source.clone();
                    session = Some(Box::new(s));
                    labels_path = labels;
                    ((v, source), None)
                }
                Err(e) => (fallback()?, Some(over_built_in_scene(e.as_ref()))),
            },
        };
        let prepare = |v: &LoadedVolume| {
            RenderFront::with_labels(v.volume.clone(), v.labels.clone(), None, Some(wake.clone()))
                .context("cannot prepare the volume for rendering")
        };
        let front = match prepare(&first) {
            Ok(front) => front,
            // A session whose parts do not fit together (labels of another size):
            // its error over the built-in scene, as for a session that cannot be read.
            Err(e) if matches!(source, Source::Session(_)) && error.is_none() => {
                error = Some(over_built_in_scene(e.as_ref()));
                session = None;
                labels_path = None;
                (first, first_source) = fallback()?;
                prepare(&first)?
            }
            Err(e) => return Err(e),
        };
        let nav = navigator_for(&first);
        let editor =
            crate::tf_editor::TfEditor::new(&preset_for(&first, first.preset), &first.histogram);
        let controller = Rc::new(Controller {
            ui: ui.as_weak(),
            state: RefCell::new(State {
                current: None,
                nav,
                quality: QualityPolicy::default(),
                editor,
                scene: None,
                latest: None,
                latest_sampling: Sampling::default(),
                average_to_check: None,
                last_sampling: Sampling::default(),
                shown: (0, 0),
                last_stats: None,
                ended: None,
                pending_move: false,
                pending_still: false,
                superseded: 0,
                busy: false,
                first_frame: false,
                source: first_source.clone(),
                labels_path: None,
                fixed: RenderSettings::default(),
                level: LevelChoice::default(),
                step_override: None,
                cut_restored: None,
                crosshair: Crosshair::centre(first.volume.dims()),
                slice_level: 0,
                slice_wheel: Default::default(),
                recent: crate::recent::recent_file()
                    .map(|f| crate::recent::load(&f))
                    .unwrap_or_default(),
                recent_error_shown: false,
                started_at_launch: false,
                shown_failure: None,
                pending_screenshot: None,
                overwrite_armed: None,
                failed: None,
                browser: None,
                canvas: (0, 0),
                slice_frames: [[0; 4]; 3],
                cameras: VecDeque::new(),
                slice_window: [0.0, 1.0],
                window_drag_base: [0.0, 1.0],
                custom_window: None,
            }),
            scheduled,
            wake: wake.clone(),
            installs,
            settle: slint::Timer::default(),
            repaint: slint::Timer::default(),
        });
        ACTIVE.with(|a| *a.borrow_mut() = Rc::downgrade(&controller));
        // (As *Open session* says it: the session, not its volume.)
        let message = match &source {
            Source::Session(path) if session.is_some() => {
                first.opened_message(&format!("session {}", path.display()))
            }
            _ => first.opened_message(&first.description),
        };
        let recent = match &source {
            Source::File(p) | Source::Session(p) if error.is_none() => Some(p.clone()),
            _ => None,
        };
        controller.install(Ok(Install {
            loaded: Loaded {
                volume: first,
                front,
            },
            new_volume: true,
            source: Some(first_source),
            labels_path,
            scene: None,
            session,
            recent,
            message,
        }));
        if let Some(error) = &error {
            controller.show_message(error, true);
            // Said on the terminal the viewer was started from too (once; the
            // window keeps it in sight).
            eprintln!("viewer: {error}");
        }
        match &source {
            Source::File(path) => ui.set_file_path(path.display().to_string().into()),
            Source::Session(path) => ui.set_session_path(path.display().to_string().into()),
            Source::BuiltIn(..) => {}
        }
        connect(&ui, &controller);
        controller.show_recent();
        if let Some(path) = scene {
            ui.set_scene_path(path.display().to_string().into());
            // (A label volume opens in the background: its error comes later.)
            controller.state.borrow_mut().started_at_launch = true;
            controller.load_scene(&path);
            let busy = controller.state.borrow().busy;
            controller.state.borrow_mut().started_at_launch = busy;
            // A scene refused at start is said on the terminal too, as a
            // volume's or session's error is.
            if ui.get_message_is_error() {
                eprintln!("viewer: {}", ui.get_message());
            }
            // The file's error stays in sight, the scene's message after it.
            if let Some(error) = &error {
                let scene_message = ui.get_message().to_string();
                controller.show_message(&format!("{error} — {scene_message}"), true);
            }
        }
        Ok(Viewer { ui, controller })
    }

    /// The window.
    pub fn ui(&self) -> &App {
        &self.ui
    }

    /// Shows the window and runs the event loop until it closes.
    pub fn run(&self) -> Result<()> {
        self.ui.run().context("the viewer's event loop failed")
    }

    /// Takes in what the renderer and loaders produced (the event loop does this
    /// on every wake-up; tests call it directly).
    pub fn pump(&self) {
        self.controller.pump();
    }

    /// Whether the newest frame request has ended and is on screen, and no volume
    /// is loading.
    pub fn idle(&self) -> bool {
        let st = self.controller.state.borrow();
        !st.busy
            && !st.pending_move
            && !st.pending_still
            && st
                .latest
                .is_some_and(|(id, _)| st.ended == Some(id) && st.shown.0 == id)
    }

    /// The camera's orbit.
    pub fn orbit(&self) -> raycaster::render::Orbit {
        *self.controller.state.borrow().nav.orbit()
    }

    /// Path of the volume on screen (built-in scenes have a descriptive name).
    pub fn volume_name(&self) -> String {
        let st = self.controller.state.borrow();
        st.current
            .as_ref()
            .map(|c| c.volume.volume.path().display().to_string())
            .unwrap_or_default()
    }

    /// The statistics of the last finished frame and whether it was interactive.
    pub fn last_stats(&self) -> Option<(FrameStats, bool)> {
        self.controller.state.borrow().last_stats
    }

    /// How many frame requests were superseded before they finished (a still
    /// frame cut short by a new move; never a moving frame by a newer move).
    pub fn frames_superseded(&self) -> u64 {
        self.controller.state.borrow().superseded
    }

    /// The view on screen as a session: what "Save session" writes (the
    /// full-quality frame the view settles on).
    pub fn session(&self) -> Option<Session> {
        self.controller.session()
    }

    /// The slice views' crosshair: a voxel of the full-resolution volume.
    pub fn crosshair(&self) -> [u32; 3] {
        self.controller.state.borrow().crosshair.voxel
    }

    /// The recent files the menu lists, newest first.
    pub fn recent_files(&self) -> Vec<PathBuf> {
        self.controller.state.borrow().recent.clone()
    }
}

/// Reads a session and opens what it needs: its volume (`current` when it is
/// the same source) and the label volume it or its scene names, unless the
/// volume brings labels. Refuses a camera the viewer cannot drive. Returns the
/// session, the volume and the label path the session itself gave.
fn open_session_volume(
    path: &Path,
    current: Option<(VolumeSource, LoadedVolume)>,
) -> Result<(Session, LoadedVolume, Option<PathBuf>)> {
    let session = Session::load(path)?;
    if let SessionCamera::LookAt { .. } = session.camera {
        anyhow::bail!(
            "{}: the camera is a look-at camera (`position`); the viewer orbits about a target with +z up (render it with `raycaster render --session`)",
            path.display()
        );
    }
    let mut volume = match current {
        Some((source, volume)) if source == session.source => volume,
        _ => loader::open_source(&session.source)?,
    };
    // A cut that keeps nothing of the volume is refused, the view kept (as
    // `raycaster render --session` refuses it).
    if let Err(e) = session.check_cuts(volume.volume.sampled_box()) {
        anyhow::bail!("{}: {e}", path.display());
    }
    let scene_labels = session
        .settings
        .segments
        .as_ref()
        .and_then(|s| match &s.membership {
            Membership::Labels(p) => Some(p.clone()),
            Membership::Layers(_) => None,
        });
    let wanted = match (&session.labels, scene_labels) {
        (Some(p), _) => Some(p.clone()),
        // Built-in scenes bring their labels.
        (None, Some(p)) if volume.labels.is_none() => Some(p),
        _ => None,
    };
    if let Some(labels) = wanted {
        let label_volume = raycaster::source::open_labels(&labels).map_err(|e| {
            with_labels_context(e, || format!("cannot open labels {}", labels.display()))
        })?;
        volume.labels = Some(Arc::new(label_volume));
    }
    let labels_path = session.labels.clone();
    Ok((session, volume, labels_path))
}

/// A label volume's error with `context` (what the file was for), unless the
/// file is no label volume: that refusal names the file and what to do.
fn with_labels_context(e: VolumeError, context: impl FnOnce() -> String) -> anyhow::Error {
    match e.kind {
        VolumeErrorKind::ForeignLabels { .. } | VolumeErrorKind::ValuesNotLabels => e.into(),
        _ => anyhow::Error::new(e).context(context()),
    }
}

/// `message` and a scene's `warnings`, one status line.
fn with_warnings(message: String, warnings: Vec<String>) -> String {
    warnings
        .into_iter()
        .fold(message, |m, w| format!("{m}; warning: {w}"))
}

fn init_models(ui: &App) {
    let strings = |items: Vec<&str>| -> ModelRc<SharedString> {
        ModelRc::new(VecModel::from(
            items
                .into_iter()
                .map(SharedString::from)
                .collect::<Vec<_>>(),
        ))
    };
    ui.set_tf_presets(strings(
        PRESETS
            .iter()
            .map(|(n, _)| *n)
            .chain([CUSTOM_PRESET])
            .collect(),
    ));
    ui.set_modes(strings(Mode::ALL.iter().map(|m| m.name()).collect()));
    ui.set_local_modes(strings(LOCAL_MODES.to_vec()));
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    ui.set_max_threads((cores * 2).max(4) as i32);
    ui.set_threads(cores as i32);
    ui.set_tile_index(1);
    ui.set_help(crate::shortcuts::HELP.into());
    ui.set_slice_windows(strings(
        crate::slices::window_names()
            .iter()
            .map(String::as_str)
            .collect(),
    ));
    ui.set_slice_labels(strings(crate::slices::VIEW_NAMES.to_vec()));
}

/// A wake-up the renderer threads may call: posts one pump to the event loop.
fn wake_up(scheduled: Arc<AtomicBool>) -> Notify {
    Arc::new(move || {
        if !scheduled.swap(true, Ordering::SeqCst) {
            let posted = slint::invoke_from_event_loop(|| {
                if let Some(c) = ACTIVE.with(|a| a.borrow().upgrade()) {
                    c.pump();
                }
            });
            if posted.is_err() {
                // No event loop (yet): the next pump picks everything up.
                scheduled.store(false, Ordering::SeqCst);
            }
        }
    })
}

/// The canvas in physical pixels (a fallback size before the window is laid out).
fn canvas_size(ui: &App) -> (u32, u32) {
    laid_out_canvas(ui).unwrap_or(FALLBACK_CANVAS)
}

/// The canvas in physical pixels, once the window is laid out.
fn laid_out_canvas(ui: &App) -> Option<(u32, u32)> {
    let scale = ui.window().scale_factor();
    let canvas = (
        (ui.get_canvas_width() * scale).round() as u32,
        (ui.get_canvas_height() * scale).round() as u32,
    );
    (canvas.0 >= 8 && canvas.1 >= 8).then_some(canvas)
}

/// The navigator framing `v` from the default view, in the patient's directions
/// when the file gives them (as `raycaster render` frames it).
fn navigator_for(v: &LoadedVolume) -> Navigator {
    let (lo, hi) = raycaster::source::world_box(&v.volume);
    let axes = raycaster::render::patient_axes(v.volume.orientation());
    Navigator::from_home(raycaster::render::Orbit::default_view(lo, hi).with_axes(axes))
}

/// The slice views' fitted window (stored values): the volume's fitted domain,
/// else its sample type's whole range.
fn fitted_window(v: &LoadedVolume) -> [f32; 2] {
    v.domain
        .unwrap_or([0.0, f32::from(v.volume.sample_type().max_value())])
}

fn preset_for(v: &LoadedVolume, name: &str) -> TransferFunction {
    let mut tf = TransferFunction::preset(name)
        .unwrap_or_else(|_| TransferFunction::preset("grayscale").expect("built-in preset"));
    tf.domain = v.domain;
    tf
}

fn connect(ui: &App, c: &Rc<Controller>) {
    let weak = Rc::downgrade(c);
    let with = move |f: &dyn Fn(&Controller)| {
        if let Some(c) = weak.upgrade() {
            f(&c);
        }
    };
    macro_rules! on {
        ($setter:ident, |$c:ident $(, $arg:ident)*| $body:expr) => {{
            let with = with.clone();
            ui.$setter(move |$($arg),*| with(&|$c: &Controller| $body));
        }};
    }
    on!(on_drag_started, |c, x, y, pan| {
        let kind = if pan { DragKind::Pan } else { DragKind::Orbit };
        c.state.borrow_mut().nav.begin_drag(kind, x, y);
    });
    on!(on_dragged, |c, x, y| {
        let height = c.ui.upgrade().map_or(1.0, |ui| ui.get_canvas_height());
        let moved = c.state.borrow_mut().nav.drag_to(x, y, height);
        if moved {
            c.request_frame(true);
        }
    });
    on!(on_drag_ended, |c| {
        c.state.borrow_mut().nav.end_drag();
        c.request_frame(false);
    });
    on!(on_zoomed, |c, delta| {
        if c.state.borrow_mut().nav.wheel(delta) {
            c.request_frame(true);
        }
    });
    on!(on_reset_view, |c| {
        c.state.borrow_mut().nav.reset();
        c.request_frame(false);
    });
    on!(on_axis_view, |c, label| {
        if let Some(view) = AxisView::parse(&label) {
            c.state.borrow_mut().nav.axis_view(view);
            c.request_frame(false);
        }
    });
    on!(on_open_file, |c, path| c
        .open(Source::File(typed_path(&path))));
    on!(on_browse, |c| c.toggle_browser());
    on!(on_browser_picked, |c, index| c.browser_pick(index));
    on!(on_browser_up, |c| c.browser_up());
    on!(on_browser_open_folder, |c| c.browser_open_folder());
    on!(on_save_screenshot, |c, path| c
        .save_png_pressed(Path::new(path.as_str())));
    on!(on_open_session, |c, path| c
        .open(Source::Session(typed_path(&path))));
    on!(on_save_session, |c, path| c
        .save_session(Path::new(path.as_str())));
    on!(on_preset_selected, |c, index| c.select_preset(index));
    on!(on_tf_pressed, |c, x, y, right| {
        let (w, h) = c.tf_size();
        let changed = c.state.borrow_mut().editor.press(x, y, w, h, right);
        c.redraw_tf();
        if changed {
            c.show_custom_preset();
            c.request_frame(true);
        }
    });
    on!(on_tf_moved, |c, x, y| {
        let (w, h) = c.tf_size();
        if c.state.borrow_mut().editor.drag_to(x, y, w, h) {
            c.show_custom_preset();
            c.redraw_tf();
            c.request_frame(true);
        }
    });
    on!(on_tf_released, |c| {
        c.state.borrow_mut().editor.release();
        c.request_frame(false);
    });
    on!(on_tf_color, |c, color| {
        let rgb = [color.red(), color.green(), color.blue()].map(|v| f32::from(v) / 255.0);
        if c.state.borrow_mut().editor.set_color(rgb) {
            c.show_custom_preset();
            c.redraw_tf();
            c.request_frame(false);
        }
    });
    on!(on_settings_changed, |c| c.request_frame(false));
    // A drop-down's pick: the keys go to the canvas now, and again once the
    // box's popup has closed (closing it gives the box the focus back, and a
    // focused box takes the wheel: the first wheel step over it after a pick
    // changed its value).
    {
        let weak = ui.as_weak();
        ui.on_picked(move || {
            if let Some(ui) = weak.upgrade() {
                ui.invoke_focus_canvas();
            }
            let weak = weak.clone();
            slint::Timer::single_shot(std::time::Duration::ZERO, move || {
                if let Some(ui) = weak.upgrade() {
                    ui.invoke_focus_canvas();
                }
            });
        });
    }
    on!(on_load_scene, |c, path| c
        .load_scene(Path::new(path.as_str())));
    on!(on_save_scene, |c, path| c
        .save_scene(Path::new(path.as_str())));
    on!(on_clear_scene, |c| {
        let had_scene = c.state.borrow_mut().scene.take().is_some();
        // (The scene's "loaded scene …" line outlived it.)
        if had_scene {
            c.show_message("plain rendering: the scene was dropped", false);
        }
        c.show_objects();
        c.request_frame(false);
        // (It outlived the scene.)
        c.part_drawn(Failure::AllObjectsHidden);
    });
    on!(on_object_changed, |c, index, row| c
        .edit_object(index, &row));
    on!(on_object_gain_automatic, |c, index| c
        .automatic_object_gain(index));
    on!(on_canvas_resized, |c| {
        // Layout jitter below a pixel (366.99997 for 367) asks for no frame.
        let size = c.ui().map(|ui| canvas_size(&ui));
        if size != Some(c.state.borrow().canvas) {
            c.request_frame(true);
        }
    });
    on!(on_cut_changed, |c, moving| {
        c.show_cut();
        c.request_frame(moving);
    });
    on!(on_cut_reset, |c| {
        if let Some(ui) = c.ui() {
            set_cut_values(&ui, &CutValues::default());
        }
        c.show_cut();
        c.request_frame(false);
    });
    on!(on_slice_clicked, |c, axis, x, y, w, h| c
        .click_slice(axis, x, y, w, h));
    on!(on_slice_scrolled, |c, axis, delta| c
        .scroll_slice(axis, delta));
    on!(on_slice_window_selected, |c, index| c
        .window_selected(index));
    on!(on_slice_zoom_changed, |c| c.update_slices());
    on!(on_slice_window_dragged, |c, _axis, dx, dy, start| c
        .drag_slice_window(dx, dy, start));
    on!(on_show_planes_toggled, |c| c.redraw_frame());
    on!(on_recent_selected, |c, index| c.open_recent(index));
    let weak = Rc::downgrade(c);
    ui.on_shortcut(move |text, control| {
        let Some(c) = weak.upgrade() else {
            return false;
        };
        let Some(shortcut) = crate::shortcuts::shortcut(&text, control) else {
            return false;
        };
        match shortcut {
            Shortcut::Reset => {
                c.state.borrow_mut().nav.reset();
                c.request_frame(false);
            }
            Shortcut::Axis(view) => {
                c.state.borrow_mut().nav.axis_view(view);
                c.request_frame(false);
            }
            Shortcut::Screenshot => c.quick_screenshot(),
            Shortcut::Undo => c.undo_tf(false),
            Shortcut::Redo => c.undo_tf(true),
        }
        true
    });
}

/// The path a user typed or pasted in a path field: without surrounding
/// whitespace or one pair of matching quotes (a file manager's copy), and `~`
/// at its start as the home folder (a shell's spelling); the field's text as
/// it is otherwise.
pub(crate) fn typed_path(text: &str) -> PathBuf {
    let text = text.trim();
    let text = ['\'', '"']
        .iter()
        .find_map(|&q| text.strip_prefix(q).and_then(|t| t.strip_suffix(q)))
        .unwrap_or(text);
    let home = std::env::var_os("HOME").filter(|h| !h.is_empty());
    match (text.strip_prefix('~'), home) {
        (Some(""), Some(home)) => PathBuf::from(home),
        (Some(rest), Some(home)) if rest.starts_with('/') => {
            PathBuf::from(home).join(rest.trim_start_matches('/'))
        }
        _ => PathBuf::from(text),
    }
}

/// The Cut panel's values.
fn cut_values(ui: &App) -> CutValues {
    CutValues {
        lo: [ui.get_crop_x0(), ui.get_crop_y0(), ui.get_crop_z0()],
        hi: [ui.get_crop_x1(), ui.get_crop_y1(), ui.get_crop_z1()],
        plane: ui.get_plane_enabled(),
        offset: ui.get_plane_offset(),
        azimuth: ui.get_plane_azimuth(),
        elevation: ui.get_plane_elevation(),
    }
}

/// Shows `v` in the Cut panel.
fn set_cut_values(ui: &App, v: &CutValues) {
    ui.set_crop_x0(v.lo[0]);
    ui.set_crop_y0(v.lo[1]);
    ui.set_crop_z0(v.lo[2]);
    ui.set_crop_x1(v.hi[0]);
    ui.set_crop_y1(v.hi[1]);
    ui.set_crop_z1(v.hi[2]);
    ui.set_plane_enabled(v.plane);
    ui.set_plane_offset(v.offset);
    ui.set_plane_azimuth(v.azimuth);
    ui.set_plane_elevation(v.elevation);
}

/// The transfer-function picker's entry after the presets: a curve that is none
/// of them (edited, or from a session).
const CUSTOM_PRESET: &str = "custom";

/// What to say of a session saved at `saved` pixels shown on `canvas`: nothing
/// where they agree, or before layout (`None`, as at start under a window
/// system, whose fallback size is no size to compare with, and the session was
/// often saved from a window of the same size).
fn size_note(saved: [u32; 2], canvas: Option<(u32, u32)>) -> String {
    match canvas {
        Some((w, h)) if [w, h] != saved => format!(
            " (saved at {}×{}; the canvas is {w}×{h})",
            saved[0], saved[1]
        ),
        _ => String::new(),
    }
}

/// The message of a volume or session that did not open at start, shown over
/// the built-in scene.
fn over_built_in_scene(e: &(dyn std::error::Error + 'static)) -> String {
    format!(
        "{} (showing the built-in scene)",
        raycaster::errors::error_text(e)
    )
}

/// The id of the newest frame asked for when it is a moving frame that has not
/// ended (its tiles are not shown until it has).
fn moving_frame_in_flight(st: &State) -> Option<u64> {
    st.latest
        .filter(|&(id, moving)| moving && st.ended != Some(id))
        .map(|(id, _)| id)
}

/// Whether the newest frame asked for is a full-quality one and has ended: the
/// frame buffer then holds it whole.
fn frame_complete(st: &State) -> bool {
    st.latest
        .is_some_and(|(id, moving)| !moving && st.ended == Some(id))
}

/// The first free `STEM-N.png` beside `path` (`screenshot.png` →
/// `screenshot-1.png`; `shot.jpg` → `shot-1.png`: the data are PNG).
fn numbered_path(path: &Path) -> PathBuf {
    // A folder (or a path ending in `/`): numbered screenshots inside it.
    let inside;
    let path = if path.is_dir() || path.as_os_str().to_string_lossy().ends_with('/') {
        inside = path.join("screenshot.png");
        inside.as_path()
    } else {
        path
    };
    let stem = path
        .file_stem()
        .map_or("screenshot".into(), |s| s.to_string_lossy().into_owned());
    // (PNG data: named .png whatever the field's extension.)
    let dir = path.parent().unwrap_or(Path::new(""));
    (1u32..)
        .map(|n| dir.join(format!("{stem}-{n}.png")))
        .find(|p| raycaster::files::existing_output(p).is_none())
        .unwrap_or_else(|| path.to_path_buf())
}

impl Controller {
    fn ui(&self) -> Option<App> {
        self.ui.upgrade()
    }

    fn show_message(&self, text: &str, error: bool) {
        self.state.borrow_mut().shown_failure = None;
        if let Some(ui) = self.ui() {
            // One line: a parser's snippet lines would push its reason out of sight.
            ui.set_message(raycaster::errors::one_line(text).into());
            ui.set_message_is_error(error);
        }
        self.repaint_window();
    }

    /// Says that `part` could not be drawn, until it draws again
    /// ([`Self::part_drawn`]).
    fn show_failure(&self, part: Failure, text: &str) {
        self.show_message(text, true);
        self.state.borrow_mut().shown_failure = Some(part);
    }

    /// `part` drew: the message that said it could not goes (any other
    /// message stays).
    fn part_drawn(&self, part: Failure) {
        let cleared = {
            let mut st = self.state.borrow_mut();
            let cleared = st.shown_failure == Some(part);
            if cleared {
                st.shown_failure = None;
            }
            cleared
        };
        if let (true, Some(ui)) = (cleared, self.ui()) {
            ui.set_message("".into());
            ui.set_message_is_error(false);
        }
    }

    /// Shows the file browser at the folder of the typed path (else the working
    /// folder), or hides it.
    fn toggle_browser(&self) {
        let Some(ui) = self.ui() else { return };
        if ui.get_browser_shown() {
            ui.set_browser_shown(false);
            return;
        }
        let folder = crate::browser::start_folder(ui.get_file_path().as_str());
        ui.set_browser_shown(true);
        self.browse_to(folder);
    }

    /// Lists `folder` in the browser; a folder that cannot be read is said on
    /// the message line and the listing stays.
    fn browse_to(&self, folder: PathBuf) {
        let Some(ui) = self.ui() else { return };
        match crate::browser::list(&folder) {
            Ok(entries) => {
                let labels: Vec<SharedString> = entries.iter().map(|e| e.label().into()).collect();
                ui.set_browser_folder(folder.display().to_string().into());
                ui.set_browser_entries(ModelRc::new(VecModel::from(labels)));
                self.state.borrow_mut().browser = Some((folder, entries));
            }
            Err(e) => self.show_message(&format!("cannot list {}: {e}", folder.display()), true),
        }
    }

    /// A browser entry picked: a folder is shown, a volume opened, a session
    /// restored, a scene loaded.
    fn browser_pick(&self, index: i32) {
        let picked = {
            let st = self.state.borrow();
            st.browser.as_ref().and_then(|(folder, entries)| {
                let entry = entries.get(usize::try_from(index).ok()?)?;
                Some((folder.join(&entry.name), entry.kind))
            })
        };
        let (Some(ui), Some((path, kind))) = (self.ui(), picked) else {
            return;
        };
        let text: SharedString = path.display().to_string().into();
        match kind {
            crate::browser::EntryKind::Folder => self.browse_to(path),
            crate::browser::EntryKind::Volume => {
                ui.set_file_path(text);
                ui.set_browser_shown(false);
                self.open(Source::File(path));
            }
            crate::browser::EntryKind::Session => {
                ui.set_session_path(text);
                ui.set_browser_shown(false);
                self.open(Source::Session(path));
            }
            crate::browser::EntryKind::Scene => {
                ui.set_scene_path(text);
                ui.set_browser_shown(false);
                self.load_scene(&path);
            }
        }
    }

    /// The browser shows the folder above.
    fn browser_up(&self) {
        let parent = {
            let st = self.state.borrow();
            st.browser
                .as_ref()
                .and_then(|(folder, _)| folder.parent().map(Path::to_path_buf))
        };
        if let Some(parent) = parent {
            self.browse_to(parent);
        }
    }

    /// Opens the browser's folder itself (a DICOM series).
    fn browser_open_folder(&self) {
        let folder = {
            let st = self.state.borrow();
            st.browser.as_ref().map(|(folder, _)| folder.clone())
        };
        let (Some(ui), Some(folder)) = (self.ui(), folder) else {
            return;
        };
        ui.set_file_path(folder.display().to_string().into());
        ui.set_browser_shown(false);
        self.open(Source::File(folder));
    }

    /// Opens a volume on a background thread; the current one stays until it is
    /// ready (and stays for good if opening fails).
    fn open(&self, source: Source) {
        let what = match &source {
            Source::File(p) => p.display().to_string(),
            Source::BuiltIn(kind, _) => format!("the built-in {} scene", kind.name()),
            Source::Session(p) => format!("session {}", p.display()),
        };
        // A session of the volume on screen reuses it.
        let current = {
            let st = self.state.borrow();
            st.current
                .as_ref()
                .map(|c| (st.source.clone(), c.volume.clone()))
        };
        let recent = match &source {
            Source::File(p) | Source::Session(p) => Some(p.clone()),
            Source::BuiltIn(..) => None,
        };
        self.in_background(
            format!("opening {what} …"),
            "the previous volume stays",
            move |wake| {
                let mut session = None;
                let mut labels_path = None;
                let (volume, volume_source) = match &source {
                    Source::BuiltIn(kind, size) => {
                        let s = VolumeSource::BuiltIn {
                            kind: *kind,
                            size: *size,
                            seed: 1,
                        };
                        (loader::open_source(&s)?, s)
                    }
                    Source::File(path) => (loader::open_file(path)?, loader::file_source(path)),
                    Source::Session(path) => {
                        let (s, volume, labels) = open_session_volume(path, current)?;
                        let volume_source = s.source.clone();
                        session = Some(Box::new(s));
                        labels_path = labels;
                        (volume, volume_source)
                    }
                };
                let front = RenderFront::with_labels(
                    volume.volume.clone(),
                    volume.labels.clone(),
                    None,
                    Some(wake),
                )
                .context("cannot prepare the volume for rendering")?;
                let message = match &source {
                    Source::Session(path) => {
                        volume.opened_message(&format!("session {}", path.display()))
                    }
                    _ => volume.opened_message(&volume.description),
                };
                Ok(Install {
                    message,
                    loaded: Loaded { volume, front },
                    new_volume: true,
                    source: Some(volume_source),
                    labels_path,
                    scene: None,
                    session,
                    recent,
                })
            },
        );
    }

    /// Shows `message` and runs `job` on a worker thread (the viewer is busy until
    /// it ends); its volume, or its error, is installed by the next pump.
    /// `kept` says what stays when the job fails (after its error).
    fn in_background(
        &self,
        message: String,
        kept: &'static str,
        job: impl FnOnce(Notify) -> Result<Install> + Send + 'static,
    ) {
        self.state.borrow_mut().busy = true;
        self.show_message(&message, false);
        let wake = self.wake.clone();
        let tx = self.installs.0.clone();
        let started = std::thread::Builder::new().spawn(move || {
            let result = job(wake.clone());
            let _ = tx
                .send(result.map_err(|e| {
                    format!("{} ({kept})", raycaster::errors::error_text(e.as_ref()))
                }));
            wake();
        });
        if let Err(e) = started {
            // The system refused the thread (a process or address-space limit).
            let _ = self
                .installs
                .0
                .send(Err(format!("cannot start a thread for it: {e} ({kept})")));
            (self.wake)();
        }
    }

    fn install(&self, result: Result<Install, String>) {
        let install = match result {
            Ok(install) => install,
            Err(e) => {
                let at_launch = {
                    let mut st = self.state.borrow_mut();
                    st.busy = false;
                    std::mem::take(&mut st.started_at_launch)
                };
                // Said on the terminal too, as errors at launch are.
                if at_launch {
                    eprintln!("viewer: {e}");
                }
                self.show_message(&e, true);
                return;
            }
        };
        self.state.borrow_mut().started_at_launch = false;
        // Bytes after the file's last block, a damaged pyramid sidecar: said as
        // `raycaster render` says them.
        let open_warnings = if install.new_volume {
            install.loaded.volume.volume.open_warnings()
        } else {
            Vec::new()
        };
        let dropped_screenshot;
        // A two-level scene of the old volume that the new one does not keep.
        let mut dropped_scene = false;
        {
            let mut st = self.state.borrow_mut();
            st.busy = false;
            if install.new_volume {
                dropped_scene =
                    st.scene.is_some() && install.scene.is_none() && install.session.is_none();
                let v = &install.loaded.volume;
                if let Some(source) = install.source {
                    st.source = source;
                }
                // A fault on its mapping ends the viewer naming the file.
                if let VolumeSource::File { path, .. } = &st.source {
                    raycaster::files::guard_mapped_file(path);
                }
                st.labels_path = install.labels_path;
                st.fixed = RenderSettings::default();
                st.cut_restored = None;
                st.crosshair = Crosshair::centre(v.volume.dims());
                st.slice_level = crate::slices::slice_level(&v.volume);
                st.level = LevelChoice::default();
                st.step_override = None;
                st.nav = navigator_for(v);
                let tf = preset_for(v, v.preset);
                st.editor.set_transfer(&tf);
                st.editor.set_histogram(&v.histogram);
                st.scene = None;
                if let Some(ui) = self.ui() {
                    let [x, y, z] = v.volume.dims();
                    ui.set_dim_x(x as i32);
                    ui.set_dim_y(y as i32);
                    ui.set_dim_z(z as i32);
                    set_cut_values(&ui, &CutValues::default());
                    // The path field names the volume on screen (a session's,
                    // a recent entry's), so *Open* opens what is shown.
                    ui.set_file_path(match &st.source {
                        VolumeSource::File { path, .. } => path.display().to_string().into(),
                        VolumeSource::BuiltIn { .. } => SharedString::new(),
                    });
                    // A new volume's slices start whole (a session sets its zoom).
                    ui.set_slice_zoom(1.0);
                    ui.set_volume_info(v.description.clone().into());
                    ui.set_preset_index(
                        PRESETS
                            .iter()
                            .position(|(n, _)| *n == v.preset)
                            .map_or(PRESETS.len() as i32, |i| i as i32),
                    );
                }
            }
            if let Some(scene) = install.scene {
                st.scene = Some(scene);
            }
            // The old front (if any) is dropped here: its frame is cancelled and its
            // threads joined.
            st.current = Some(install.loaded);
            // Request ids start again with the new front: forget the old front's.
            st.latest = None;
            st.ended = None;
            (st.pending_move, st.pending_still) = (false, false);
            st.shown = (0, 0);
            st.cameras.clear();
            // A dragged window belonged to the old volume: the picker goes
            // back to the fitted one. A named window stays where it reads the
            // new volume (in HU), else it goes too (it carried over unsaid
            // and showed a u16 file's slices white).
            st.custom_window = None;
            if let Some(ui) = self.ui() {
                let index = ui.get_slice_window_index().max(0) as usize;
                let dragged = index + 1 == crate::slices::window_names().len();
                let misread = st.current.as_ref().is_some_and(|current| {
                    crate::slices::named_window_note(index, &current.volume.volume).is_some()
                });
                if dragged || misread {
                    ui.set_slice_window_index(0);
                }
            }
            st.last_stats = None;
            st.first_frame = true;
            // A screenshot of the old view waits for no frame of the new volume.
            dropped_screenshot = st.pending_screenshot.take();
            st.failed = None;
        }
        let mut message = install.message;
        if let Some(path) = dropped_screenshot {
            message += &format!(
                " — {} was not saved: the volume changed before its frame was complete",
                path.display()
            );
        }
        for warning in open_warnings {
            message = format!("{message} — {warning}");
        }
        if dropped_scene {
            message += " — the two-level scene was cleared: it described the previous volume (Segments, Load reads it again)";
        }
        if let Some(session) = install.session {
            message += &self.restore(*session);
        }
        if let Some(path) = install.recent
            && let Some(note) = self.remember(&path)
        {
            message += &note;
        }
        self.show_message(&message, false);
        self.show_objects();
        self.show_cut();
        self.update_slices();
        self.redraw_tf();
        self.request_frame(false);
        self.repaint_window();
    }

    /// Makes the whole window dirty now and again a moment later (`repaints`
    /// in app.slint): after a new volume, the software renderer's partial
    /// repaint sometimes left the text of the volume before on screen (status
    /// and message lines, crop rows; about one open in twenty under Xvfb,
    /// slint 1.18.1), while the window's state was right. Once it kept the
    /// status and message lines of a save (every later message and status
    /// unseen until a volume was opened), so each message and each
    /// full-quality frame's status line repaint the window too.
    fn repaint_window(&self) {
        let toggle = |ui: &App| ui.set_repaints(ui.get_repaints().wrapping_add(1));
        if let Some(ui) = self.ui() {
            toggle(&ui);
        }
        let weak = self.ui.clone();
        self.repaint.start(
            slint::TimerMode::SingleShot,
            std::time::Duration::from_millis(600),
            move || {
                if let Some(ui) = weak.upgrade() {
                    toggle(&ui);
                }
            },
        );
    }

    /// Puts `path` first in the recent files; returns a note for the message
    /// line the first time the list cannot be written.
    fn remember(&self, path: &Path) -> Option<String> {
        let file = crate::recent::recent_file()?;
        let result = crate::recent::add(&file, path);
        let note = {
            let mut st = self.state.borrow_mut();
            match result {
                Ok(list) => {
                    st.recent = list;
                    None
                }
                Err(e) if !st.recent_error_shown => {
                    st.recent_error_shown = true;
                    Some(format!(
                        " (cannot update the recent files {}: {e})",
                        file.display()
                    ))
                }
                Err(_) => None,
            }
        };
        self.show_recent();
        note
    }

    /// Fills the recent-files menu.
    fn show_recent(&self) {
        let Some(ui) = self.ui() else { return };
        let st = self.state.borrow();
        let items: Vec<SharedString> =
            std::iter::once(format!("recent files ({})", st.recent.len()).into())
                .chain(st.recent.iter().map(|p| p.display().to_string().into()))
                .collect();
        ui.set_recent_files(ModelRc::new(VecModel::from(items)));
        ui.set_recent_index(0);
    }

    /// Reopens entry `index` of the recent-files menu (0 is its title): a
    /// `.toml` file as a session, anything else as a volume.
    fn open_recent(&self, index: i32) {
        let Some(ui) = self.ui() else { return };
        ui.set_recent_index(0);
        let path = {
            let st = self.state.borrow();
            let Some(path) = usize::try_from(index - 1)
                .ok()
                .and_then(|i| st.recent.get(i))
            else {
                return;
            };
            path.clone()
        };
        if path.extension().is_some_and(|e| e == "toml") {
            ui.set_session_path(path.display().to_string().into());
            self.open(Source::Session(path));
        } else {
            ui.set_file_path(path.display().to_string().into());
            self.open(Source::File(path));
        }
    }

    /// The cut the view renders: the region a session restored while the
    /// panel still shows it, else the panel's (with a session's planes beyond
    /// the first, which the panel does not show).
    fn clip(ui: &App, st: &State) -> ClipRegion {
        let values = cut_values(ui);
        if let Some((restored, region)) = &st.cut_restored
            && *restored == values
        {
            return region.clone();
        }
        let (dims, spacing) = st.volume_shape();
        let mut region = match &st.cut_restored {
            // The controls that did not move keep the session's values.
            Some((before, restored)) => values.region_after(before, restored, dims, spacing),
            None => values.region(dims, spacing),
        };
        region
            .planes
            .extend(st.fixed.clip.planes.iter().skip(1).copied());
        region
    }

    /// Says what the cut keeps: the voxels along each axis over its crop
    /// sliders, the clipping plane under its own.
    fn show_cut(&self) {
        let Some(ui) = self.ui() else { return };
        let st = self.state.borrow();
        let region = Self::clip(&ui, &st);
        let kept: Vec<SharedString> = crate::cut::kept_voxels(&region, st.volume_shape().0)
            .into_iter()
            .map(SharedString::from)
            .collect();
        ui.set_crop_kept(ModelRc::new(VecModel::from(kept)));
        let keeps_nothing = st.current.as_ref().is_some_and(|c| {
            region
                .plane_keeping_nothing(c.volume.volume.sampled_box())
                .is_some()
        });
        drop(st);
        // Rounded as shown, without a sign on zero ("-0.00").
        let shown = |v: f32, digits: i32| {
            let scale = 10f32.powi(digits);
            (v * scale).round() / scale + 0.0
        };
        let text = match region.planes.first() {
            Some(p) => format!(
                "plane through ({:.0}, {:.0}, {:.0}), normal ({:.2}, {:.2}, {:.2}) (voxels){}",
                shown(p.point.x, 0),
                shown(p.point.y, 0),
                shown(p.point.z, 0),
                shown(p.normal.x, 2),
                shown(p.normal.y, 2),
                shown(p.normal.z, 2),
                if keeps_nothing {
                    ": it keeps nothing of the volume (it keeps the side its normal points into)"
                } else {
                    ""
                }
            ),
            None => "no clipping plane".into(),
        };
        ui.set_plane_info(text.into());
    }

    /// Redraws the three slice views through the crosshair.
    fn update_slices(&self) {
        let Some(ui) = self.ui() else { return };
        let st = self.state.borrow();
        let Some(current) = &st.current else { return };
        let volume = &current.volume.volume;
        // A file truncated under its mapping is not read (a read of a missing
        // byte would end the viewer); the slices shown stay.
        if let Err(e) = volume.check_whole() {
            drop(st);
            let text = raycaster::errors::error_text(&e);
            self.show_failure(Failure::Slices, &format!("slices: {text}"));
            return;
        }
        let units = volume.value_units();
        let fitted = fitted_window(&current.volume);
        let index = ui.get_slice_window_index().max(0) as usize;
        let window = match st.custom_window {
            Some(custom) if index + 1 == crate::slices::window_names().len() => custom,
            _ => crate::slices::window(index, fitted, &units),
        };
        let zoom = ui.get_slice_zoom();
        let spacing = volume.spacing();
        let orientation = volume.orientation();
        let mut edges = Vec::with_capacity(12);
        let mut aspects = [1.0f32; 3];
        let mut frames = [[0u32; 4]; 3];
        let mut error = None;
        for axis in Axis::ALL {
            let image = crate::slices::slice_image(
                volume,
                st.slice_level,
                axis,
                &st.crosshair,
                window,
                zoom,
            );
            let layout = crate::slices::slice_layout(volume, axis);
            let labels = crate::annotations::slice_labels(&layout, orientation);
            edges.extend([labels.left, labels.right, labels.top, labels.bottom]);
            let image = match image {
                Ok((image, at)) => {
                    frames[axis.index()] = [at[0], at[1], image.width(), image.height()];
                    let (u, v) = (layout.columns, layout.rows);
                    aspects[axis.index()] =
                        (image.width() as f32 * spacing[u]) / (image.height() as f32 * spacing[v]);
                    image
                }
                Err(e) => {
                    error = Some(format!("slice {axis}: {e}"));
                    continue;
                }
            };
            let rgba: Vec<u8> = image
                .data()
                .chunks(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect();
            let buffer = SharedPixelBuffer::<Rgba8Pixel>::clone_from_slice(
                &rgba,
                image.width(),
                image.height(),
            );
            let image = Image::from_rgba8(buffer);
            match axis {
                Axis::X => ui.set_slice_x(image),
                Axis::Y => ui.set_slice_y(image),
                Axis::Z => ui.set_slice_z(image),
            }
        }
        let [x, y, z] = st.crosshair.voxel;
        ui.set_cross_x(x as i32);
        ui.set_cross_y(y as i32);
        ui.set_cross_z(z as i32);
        let mut info = format!("window {}", crate::slices::describe_window(window, &units));
        if st.slice_level > 0 {
            info += &format!(" · slices read from pyramid level {}", st.slice_level);
        }
        ui.set_slice_window_info(info.into());
        let edges: Vec<SharedString> = edges.into_iter().map(Into::into).collect();
        ui.set_slice_edges(ModelRc::new(VecModel::from(edges)));
        ui.set_slice_aspects(ModelRc::new(VecModel::from(aspects.to_vec())));
        let names = crate::slices::view_names(volume);
        let shown = ui.get_slice_labels();
        if !slint::Model::iter(&shown).eq(names.iter().map(SharedString::from)) {
            ui.set_slice_labels(ModelRc::new(VecModel::from(
                names.map(SharedString::from).to_vec(),
            )));
        }
        drop(st);
        let mut st = self.state.borrow_mut();
        st.slice_frames = frames;
        st.slice_window = window;
        drop(st);
        match error {
            Some(error) => self.show_failure(Failure::Slices, &error),
            None => self.part_drawn(Failure::Slices),
        }
        if ui.get_show_planes() {
            self.redraw_frame();
        }
    }

    /// Moves the crosshair to a click at `(x, y)` in the `axis` slice's area
    /// of `w × h` (the image is fitted inside it, centred, at its aspect).
    fn click_slice(&self, axis: i32, x: f32, y: f32, w: f32, h: f32) {
        let Some(axis) = usize::try_from(axis).ok().and_then(|a| Axis::ALL.get(a)) else {
            return;
        };
        {
            let mut guard = self.state.borrow_mut();
            let st = &mut *guard;
            let Some(current) = &st.current else { return };
            let level = current.volume.volume.level(st.slice_level);
            let dims = level.dims();
            let layout = crate::slices::slice_layout(&current.volume.volume, *axis);
            let (u, v) = (layout.columns, layout.rows);
            // The part of the slice shown (zoomed about the crosshair).
            let [x0, y0, fw, fh] = st.slice_frames[axis.index()];
            let (iw, ih) = (fw as f32, fh as f32);
            let spacing = current.volume.volume.spacing();
            let aspect = (iw * spacing[u]) / (ih * spacing[v]);
            // The image's size on screen, as app.slint lays it out.
            let shown_w = w.min(h * aspect);
            let shown_h = shown_w / aspect;
            if fw == 0 || fh == 0 || !(shown_w > 0.0 && shown_h > 0.0) {
                return;
            }
            let col = (x - (w - shown_w) / 2.0) / shown_w * iw;
            let row = (y - (h - shown_h) / 2.0) / shown_h * ih;
            if !(0.0..iw).contains(&col) || !(0.0..ih).contains(&row) {
                return;
            }
            st.crosshair.click(
                &layout,
                [col + x0 as f32, row + y0 as f32],
                [dims[u], dims[v]],
                1 << st.slice_level,
            );
        }
        self.update_slices();
    }

    /// Free window/level: a right-drag on a slice started (`start`) or moved by
    /// `dx`, `dy` (fractions of the view) from where it started.
    fn drag_slice_window(&self, dx: f32, dy: f32, start: bool) {
        let Some(ui) = self.ui() else { return };
        {
            let mut st = self.state.borrow_mut();
            if start {
                st.window_drag_base = st.slice_window;
                return;
            }
            let Some(current) = &st.current else { return };
            let [lo, hi] = fitted_window(&current.volume);
            st.custom_window = Some(crate::slices::dragged_window(
                st.window_drag_base,
                dx,
                dy,
                hi - lo,
            ));
        }
        ui.set_slice_window_index(crate::slices::window_names().len() as i32 - 1);
        self.update_slices();
    }

    /// Steps the `axis` slice by one (level) voxel per wheel notch
    /// ([`WheelSteps`]): a wheel turned away from the user (a positive delta,
    /// as the canvas zooms in) moves the slice away from the viewer, into the
    /// screen, in every view ([`PlaneLayout::index_grows_toward_viewer`]);
    /// it went by voxel index, into the screen in some views and out of it in
    /// others.
    ///
    /// [`PlaneLayout::index_grows_toward_viewer`]: raycaster::slice::PlaneLayout::index_grows_toward_viewer
    fn scroll_slice(&self, axis: i32, delta: f32) {
        let Some(axis) = usize::try_from(axis).ok().and_then(|a| Axis::ALL.get(a)) else {
            return;
        };
        {
            let mut st = self.state.borrow_mut();
            let Some(current) = &st.current else { return };
            let volume = &current.volume.volume;
            let toward = crate::slices::slice_layout(volume, *axis)
                .index_grows_toward_viewer(*axis, volume.orientation());
            let steps = st.slice_wheel[axis.index()].steps(delta);
            if steps == 0 {
                return;
            }
            let step = 1i64 << st.slice_level;
            let away = if toward { -1 } else { 1 };
            st.crosshair.step(*axis, away * steps * step);
        }
        self.update_slices();
    }

    /// Saves the frame on screen as the first free `NAME-N.png` for the *Save
    /// PNG* path `NAME.png` ([`numbered_path`]; the S key).
    fn quick_screenshot(&self) {
        let Some(ui) = self.ui() else { return };
        self.numbered_screenshot(Path::new(ui.get_screenshot_path().as_str()));
    }

    /// Saves the frame on screen as the first free `NAME-N.png` for `base`
    /// ([`numbered_path`]).
    fn numbered_screenshot(&self, base: &Path) {
        let path = numbered_path(base);
        let path = std::path::absolute(&path).unwrap_or(path);
        self.save_screenshot(&path);
    }

    /// Sets the panels, camera, transfer function, scene and the settings no
    /// panel shows from `session` (its volume is in place); returns a note for
    /// the message line when the canvas differs from the session's image size,
    /// its fixed level is past the volume's coarsest or its step past the
    /// volume.
    fn restore(&self, session: Session) -> String {
        let Some(ui) = self.ui() else {
            return String::new();
        };
        let settings = session.settings;
        let mut notes = String::new();
        {
            let mut st = self.state.borrow_mut();
            if let SessionCamera::Orbit(orbit) = session.camera {
                st.nav.set_orbit(orbit);
            }
            st.editor.set_transfer(&settings.transfer);
            st.scene = settings.segments.clone();
            // A scene the session brings has no file of its own: the Segments
            // path field no longer names the scene shown (its *Save* offered
            // to replace another scene's file).
            if st.scene.is_some() {
                ui.set_scene_path("".into());
            }
            st.level = session.level;
            // What `raycaster render --session` warns of: a fixed level past
            // the coarsest (which renders the coarsest), a step past the volume.
            if let Some(volume) = st.current.as_ref().map(|c| &c.volume.volume) {
                if let (LevelChoice::Fixed(k), Some(coarsest)) =
                    (session.level, session.level.past_coarsest(volume))
                {
                    notes = format!(
                        " (its level {k} is past the volume's coarsest, {coarsest}: showing level {coarsest})"
                    );
                }
                if let Some(note) =
                    raycaster::render::step_past_volume(settings.step, volume.diagonal_voxels())
                {
                    notes += &format!(" ({note})");
                }
            }
            let preset = STEP_PRESETS.iter().position(|&p| {
                let mut q = QualityPolicy::default();
                q.preset = p;
                q.still().step == settings.step
            });
            match preset {
                Some(i) => {
                    ui.set_step_index(i as i32);
                    st.step_override = None;
                }
                None => st.step_override = Some((ui.get_step_index(), settings.step)),
            }
            st.fixed = settings.clone();
            let (dims, spacing) = st.volume_shape();
            let values = CutValues::from_region(&settings.clip, dims, spacing);
            set_cut_values(&ui, &values);
            st.cut_restored = Some((values, settings.clip.clone()));
            if let Some(slices) = &session.slices {
                st.crosshair = Crosshair::at(slices.crosshair, dims);
                if let SliceWindow::Values(values) = slices.window {
                    st.custom_window = Some(values);
                }
                ui.set_slice_window_index(crate::slices::window_index(&slices.window) as i32);
                ui.set_slice_zoom(slices.zoom);
            }
        }
        ui.set_mode_index(
            Mode::ALL
                .iter()
                .position(|&m| m == settings.mode)
                .map_or(0, |i| i as i32),
        );
        ui.set_ert(settings.early_termination.is_some());
        ui.set_ess(settings.empty_space_skipping);
        ui.set_shading(settings.shading.is_some());
        ui.set_preintegrate(settings.preintegrated);
        ui.set_jitter(settings.jitter);
        let preset = crate::tf_editor::preset_of(&settings.transfer);
        ui.set_preset_index(preset.map_or(PRESETS.len() as i32, |i| i as i32));
        size_note(session.size, laid_out_canvas(&ui)) + &notes
    }

    /// The render settings of the view: the panels over the fixed settings,
    /// with sampling step `step`.
    fn view_settings(ui: &App, st: &State, step: f32) -> RenderSettings {
        let fixed = &st.fixed;
        RenderSettings {
            mode: Mode::ALL
                .get(ui.get_mode_index().max(0) as usize)
                .copied()
                .unwrap_or(Mode::Dvr),
            step,
            early_termination: ui
                .get_ert()
                .then_some(fixed.early_termination.unwrap_or(DEFAULT_ERT_THRESHOLD)),
            empty_space_skipping: ui.get_ess(),
            shading: ui.get_shading().then(|| fixed.shading.unwrap_or_default()),
            preintegrated: ui.get_preintegrate(),
            jitter: ui.get_jitter(),
            transfer: st.editor.transfer(),
            segments: st.scene.clone(),
            clip: Self::clip(ui, st),
            ..fixed.clone()
        }
    }

    /// The step of still frames: the preset's, or the one a session restored.
    fn still_step(ui: &App, st: &State) -> f32 {
        match st.step_override {
            Some((index, step)) if index == ui.get_step_index() => step,
            _ => st.quality.still().step,
        }
    }

    /// The view as a session: the full-quality frame it settles on.
    fn session(&self) -> Option<Session> {
        let ui = self.ui()?;
        let mut st = self.state.borrow_mut();
        st.quality.preset = StepPreset::from_index(ui.get_step_index());
        let (w, h) = canvas_size(&ui);
        let step = Self::still_step(&ui, &st);
        let mut session = Session {
            source: st.source.clone(),
            labels: st.labels_path.clone(),
            size: [w, h],
            camera: SessionCamera::Orbit(*st.nav.orbit()),
            settings: Self::view_settings(&ui, &st, step),
            level: st.level,
            slices: Some(Self::slice_views(&ui, &st)),
        };
        // The label volume a session brought stays with a label scene only
        // (the scene cleared or replaced by layers: a session that reads).
        if session.labels_problem().is_some() {
            session.labels = None;
        }
        Some(session)
    }

    /// A choice in the slice window picker: the slices again, and a note when a
    /// CT window meets values without units ([`crate::slices::named_window_note`]).
    fn window_selected(&self, index: i32) {
        self.update_slices();
        let note = {
            let st = self.state.borrow();
            st.current.as_ref().and_then(|current| {
                crate::slices::named_window_note(index.max(0) as usize, &current.volume.volume)
            })
        };
        if let Some(note) = note {
            self.show_message(&note, false);
        }
    }

    /// The slice views as a session holds them.
    fn slice_views(ui: &App, st: &State) -> SliceViews {
        let index = ui.get_slice_window_index().max(0) as usize;
        SliceViews {
            crosshair: st.crosshair.voxel,
            window: crate::slices::session_window(
                index,
                st.custom_window.unwrap_or(st.slice_window),
            ),
            zoom: ui.get_slice_zoom(),
        }
    }

    /// Whether `path` names a file a save button can write: not blank (it was
    /// said as "cannot write session : No such file", and a name of spaces
    /// wrote a file named so) and not a folder; else says so.
    fn names_a_file(&self, path: &Path, what: &str, button: &str) -> bool {
        if path.to_string_lossy().trim().is_empty() {
            self.show_message(
                &format!("type a file name for the {what} next to {button}"),
                true,
            );
            return false;
        }
        if path.is_dir() {
            self.show_message(
                &format!("{}: is a folder; name a .toml file in it", path.display()),
                true,
            );
            return false;
        }
        true
    }

    fn save_session(&self, path: &Path) {
        if !self.names_a_file(path, "session", "Save session")
            || self.refuse_input_as_output(path)
            || !self.replace_confirmed(path, "Save session")
        {
            return;
        }
        let Some(session) = self.session() else {
            return;
        };
        match session.save(path) {
            Ok(()) => self.show_message(&format!("saved session {}", path.display()), false),
            Err(e) => self.show_message(&raycaster::errors::error_text(&e), true),
        }
    }

    /// Requests a frame of the current view: interactive (coarser, followed by a
    /// full-quality frame once the view rests) or full quality.
    fn request_frame(&self, moving: bool) {
        let Some(ui) = self.ui() else { return };
        let mut st = self.state.borrow_mut();
        // Pacing: a moving frame in flight finishes; the newest view follows it.
        let moving_in_flight = moving_frame_in_flight(&st).is_some();
        if moving && moving_in_flight {
            st.pending_move = true;
            st.pending_still = false;
            drop(st);
            self.settle_later();
            return;
        }
        if !moving && moving_in_flight {
            st.pending_still = true;
            return;
        }
        st.pending_move = false;
        st.pending_still = false;
        // Until a new volume's first frame is done: its coarsest level at
        // interactive quality, refined like any moving frame once the view rests.
        let first_levels = st
            .first_frame
            .then(|| {
                st.current
                    .as_ref()
                    .map_or(1, |c| c.volume.volume.level_count())
            })
            .filter(|&n| n > 1);
        let moving = moving || first_levels.is_some();
        let level = match first_levels {
            Some(n) => LevelChoice::Fixed(n as u32 - 1),
            None if moving => LevelChoice::Auto {
                bias: st.quality.moving_level_bias(),
            },
            None => st.level,
        };
        st.quality.preset = StepPreset::from_index(ui.get_step_index());
        st.quality.full_quality_only = ui.get_full_quality_only();
        let quality = if moving {
            st.quality.moving()
        } else {
            st.quality.still()
        };
        let canvas = canvas_size(&ui);
        st.canvas = canvas;
        let (w, h) = QualityPolicy::frame_size(quality, canvas.0, canvas.1);
        let camera = match st.nav.orbit().camera(w, h) {
            Ok(camera) => camera,
            Err(e) => {
                drop(st);
                self.show_failure(Failure::Frame, &format!("camera: {e}"));
                return;
            }
        };
        // Still frames are what a saved session holds (one function makes both).
        let step = if quality == st.quality.still() {
            Self::still_step(&ui, &st)
        } else {
            quality.step
        };
        let Some(skipping_below) = st
            .current
            .as_ref()
            .map(|c| c.front.preintegrated_skipping_below())
        else {
            return;
        };
        let mut settings = Self::view_settings(&ui, &st, step);
        // Moving frames at coarse steps pre-integrate (no rings or stripes)
        // where that keeps empty-space skipping (else it would cost several
        // times the frame); modes other than DVR and two-level scenes ignore it.
        if quality.preintegrated && settings.step < skipping_below {
            settings.preintegrated = true;
        }
        st.latest_sampling = Sampling {
            step: settings.step,
            preintegrated: settings.preintegrates(),
        };
        let options = ParallelOptions {
            render_threads: ui.get_threads().max(1) as usize,
            tile_size: TILE_SIZES
                .get(ui.get_tile_index().max(0) as usize)
                .copied()
                .unwrap_or(16),
            ..ParallelOptions::default()
        };
        let Some(current) = &st.current else { return };
        let average_mode = settings.mode == Mode::Average;
        let average = (average_mode && !moving).then(|| settings.clone());
        let id = current.front.request(FrameRequest {
            camera,
            settings,
            options,
            level,
        });
        st.latest = Some((id, moving));
        st.average_to_check = average.map(|settings| (id, settings));
        if st.cameras.len() == REMEMBERED_CAMERAS {
            st.cameras.pop_front();
        }
        let target = st.nav.orbit().target;
        st.cameras.push_back((id, camera, target));
        drop(st);
        if !average_mode {
            self.part_drawn(Failure::DarkAverage);
        }
        if moving {
            self.settle_later();
        } else {
            self.settle.stop();
        }
    }

    /// (Re)starts the timer of the full-quality frame once the view rests.
    fn settle_later(&self) {
        let weak = ACTIVE.with(|a| a.borrow().clone());
        self.settle
            .start(slint::TimerMode::SingleShot, SETTLE, move || {
                if let Some(c) = weak.upgrade() {
                    c.request_frame(false);
                }
            });
    }

    fn pump(&self) {
        self.scheduled.store(false, Ordering::SeqCst);
        while let Ok(result) = self.installs.1.try_recv() {
            self.install(result);
        }
        self.take_events();
        self.show_frame();
        self.save_pending_screenshot();
        self.note_dark_average();
        // The moving frame in flight ended: render the view the camera moved
        // to, then the full-quality frame asked for meanwhile.
        let (follow, still) = {
            let st = self.state.borrow();
            let ended = st.latest.is_some_and(|(id, _)| st.ended == Some(id));
            (st.pending_move && ended, st.pending_still && ended)
        };
        if follow {
            self.request_frame(true);
            // (Still asked for: after this frame.)
            self.state.borrow_mut().pending_still = still;
        } else if still {
            self.request_frame(false);
        }
    }

    fn take_events(&self) {
        let mut failures = Vec::new();
        let mut latest_done = false;
        // The first frame of a new volume ended (its status line follows).
        let mut first_done = false;
        {
            let mut guard = self.state.borrow_mut();
            let st = &mut *guard;
            let Some(current) = &st.current else { return };
            let latest = st.latest;
            for event in current.front.events().try_iter() {
                match event {
                    FrameEvent::Done { id, stats } => {
                        let moving = latest.is_some_and(|(l, m)| l == id && m);
                        if moving {
                            let coarsest = st.current.as_ref().is_none_or(|c| {
                                stats.level + 1 >= c.volume.volume.level_count() as u32
                            });
                            st.quality.moving_frame_took(stats.time, coarsest);
                        }
                        if latest.is_some_and(|(l, _)| l == id) {
                            latest_done = true;
                            first_done |= st.first_frame;
                            st.last_stats = Some((stats, moving));
                            st.last_sampling = st.latest_sampling;
                            st.ended = Some(id);
                            st.first_frame = false;
                        }
                    }
                    FrameEvent::Failed { id, error } => {
                        if latest.is_some_and(|(l, _)| l == id) {
                            st.ended = Some(id);
                            st.failed = Some((id, error.clone()));
                        }
                        failures.push(error);
                    }
                    FrameEvent::Superseded { .. } => st.superseded += 1,
                }
            }
        }
        if let Some(e) = failures.last() {
            self.show_failure(Failure::Frame, &format!("cannot render: {e}"));
        } else if latest_done {
            self.part_drawn(Failure::Frame);
        }
        let status = {
            let st = self.state.borrow();
            st.last_stats.as_ref().map(|(s, m)| {
                status_line(s, *m, st.last_sampling, raycaster::io::process_bytes_read())
            })
        };
        if let (Some(ui), Some(status)) = (self.ui(), status) {
            ui.set_status(status.into());
        }
        // (A full-quality frame's status line: the one that stays.)
        let still_done = latest_done && !self.state.borrow().latest.is_some_and(|(_, m)| m);
        if first_done || still_done {
            self.repaint_window();
        }
    }

    /// Copies the frame buffer to the canvas when tiles landed since last time,
    /// with the annotations of its camera (edge labels, scale bar and, when
    /// asked, the crosshair's slice planes).
    fn show_frame(&self) {
        let Some(ui) = self.ui() else { return };
        let mut st = self.state.borrow_mut();
        let Some(current) = &st.current else { return };
        let unfinished_moving = moving_frame_in_flight(&st);
        let (id, tiles, mut pixels) = {
            let fb = current.front.framebuffer().lock();
            // A moving frame shows whole, once it has ended: its tiles land
            // over the last picture, of an older view, which they would tear
            // (the new view's tiles beside the old one's, in the order they
            // finish). Full-quality frames fill in over a picture of their own
            // view (`pending_still`).
            if (fb.frame_id, fb.tiles_written) == st.shown
                || fb.width == 0
                || Some(fb.frame_id) == unfinished_moving
            {
                return;
            }
            let pixels = SharedPixelBuffer::<Rgba8Pixel>::clone_from_slice(
                fb.pixels.as_flattened(),
                fb.width,
                fb.height,
            );
            (fb.frame_id, fb.tiles_written, pixels)
        };
        let volume = &current.volume.volume;
        let camera =
            st.cameras
                .iter()
                .rfind(|(c, _, _)| *c == id)
                .and_then(|(_, camera, target)| {
                    let camera = camera.with_size(pixels.width(), pixels.height()).ok()?;
                    Some((camera, *target))
                });
        if let Some((camera, target)) = camera {
            let orientation = volume.orientation();
            let labels = crate::annotations::view_labels(&camera, orientation);
            ui.set_label_left(labels.left.into());
            ui.set_label_right(labels.right.into());
            ui.set_label_top(labels.top.into());
            ui.set_label_bottom(labels.bottom.into());
            let unit = crate::annotations::length_unit(volume);
            let bar = crate::annotations::view_scale_bar(&camera, target, unit);
            ui.set_scale_fraction(bar.as_ref().map_or(0.0, |b| b.fraction));
            ui.set_scale_label(bar.map(|b| b.label).unwrap_or_default().into());
            if ui.get_show_planes() {
                let outlines = crate::annotations::plane_outlines(
                    volume.dims(),
                    volume.spacing(),
                    st.crosshair.voxel,
                );
                crate::annotations::draw_plane_outlines(
                    pixels.make_mut_bytes(),
                    &camera,
                    &outlines,
                );
            }
        }
        st.shown = (id, tiles);
        drop(st);
        ui.set_frame(Image::from_rgba8(pixels));
    }

    /// Draws the frame on screen again (its annotations changed).
    fn redraw_frame(&self) {
        self.state.borrow_mut().shown = (u64::MAX, u64::MAX);
        self.show_frame();
    }

    fn tf_size(&self) -> (f32, f32) {
        self.ui()
            .map_or((1.0, 1.0), |ui| (ui.get_tf_width(), ui.get_tf_height()))
    }

    fn redraw_tf(&self) {
        let Some(ui) = self.ui() else { return };
        let scale = ui.window().scale_factor();
        let (w, h) = self.tf_size();
        let (w, h) = (
            ((w * scale) as u32).clamp(64, 2048),
            ((h * scale) as u32).clamp(32, 1024),
        );
        let pixels = self.state.borrow().editor.draw(w, h);
        let buffer = SharedPixelBuffer::<Rgba8Pixel>::clone_from_slice(pixels.as_flattened(), w, h);
        ui.set_tf_image(Image::from_rgba8(buffer));
    }

    fn select_preset(&self, index: i32) {
        // (`custom`, past the presets, keeps the curve.)
        let Some((name, _)) = PRESETS.get(index.max(0) as usize) else {
            return;
        };
        {
            let mut st = self.state.borrow_mut();
            let Some(current) = &st.current else { return };
            let tf = preset_for(&current.volume, name);
            st.editor.pick_transfer(&tf);
        }
        self.redraw_tf();
        self.request_frame(false);
    }

    /// Takes back the last transfer-function edit (`redo`: makes the last one
    /// undone again), unless a two-level scene is loaded (the function is not
    /// used there, and its editor is off).
    fn undo_tf(&self, redo: bool) {
        let changed = {
            let mut st = self.state.borrow_mut();
            if st.scene.is_some() {
                return;
            }
            if redo {
                st.editor.redo()
            } else {
                st.editor.undo()
            }
        };
        if !changed {
            return;
        }
        // The picker names the preset the curve is now, else `custom`.
        let preset = crate::tf_editor::preset_of(&self.state.borrow().editor.transfer());
        if let Some(ui) = self.ui() {
            ui.set_preset_index(preset.unwrap_or(PRESETS.len()) as i32);
        }
        self.redraw_tf();
        self.request_frame(false);
    }

    /// Shows `custom` in the transfer-function picker: the curve was edited.
    fn show_custom_preset(&self) {
        if let Some(ui) = self.ui() {
            ui.set_preset_index(PRESETS.len() as i32);
        }
    }

    /// Saves the frame on screen to `path`, or, while a frame is still
    /// rendering (tiles of the new view over the old, or the coarse moving
    /// frame), once the full-quality frame is complete.
    fn save_screenshot(&self, path: &Path) {
        {
            let mut st = self.state.borrow_mut();
            if st.latest.is_some() && !frame_complete(&st) {
                let replaced = st
                    .pending_screenshot
                    .replace(path.to_path_buf())
                    .filter(|p| p != path);
                drop(st);
                let note = replaced.map_or(String::new(), |p| {
                    format!(" (in place of {}, which was waiting too)", p.display())
                });
                return self.show_message(
                    &format!(
                        "saving {} when the frame is complete …{note}",
                        path.display()
                    ),
                    false,
                );
            }
            st.pending_screenshot = None;
        }
        self.write_screenshot(path);
    }

    /// The files the view is read from: the volume (a foreign header's data
    /// file too) and its labels. No save writes over one of them (as
    /// `raycaster render` refuses an image onto its inputs).
    fn input_files(&self) -> Vec<PathBuf> {
        let st = self.state.borrow();
        let mut files = match &st.source {
            VolumeSource::File { path, .. } => raycaster::import::volume_files(path),
            VolumeSource::BuiltIn { .. } => Vec::new(),
        };
        files.extend(st.labels_path.clone());
        files
    }

    /// Says so and returns `true` when `path` is one of [`Self::input_files`].
    fn refuse_input_as_output(&self, path: &Path) -> bool {
        let Some(input) = self
            .input_files()
            .into_iter()
            .find(|i| raycaster::files::same_file(i, path))
        else {
            return false;
        };
        // (The input's own name only where the typed one is another way to
        // write it, or another file of the volume: a header's data file.)
        let which = if input == path {
            String::new()
        } else {
            format!(" ({})", input.display())
        };
        self.show_message(
            &format!(
                "{}: the view is read from it{which}; name another file",
                path.display(),
            ),
            true,
        );
        true
    }

    /// The *Save PNG* button: the typed path, which must be named (a folder
    /// takes numbered screenshots, as the S key); an existing file is
    /// replaced only when the button is pressed on it a second time.
    fn save_png_pressed(&self, path: &Path) {
        if path.as_os_str().is_empty() {
            return self.show_message("type a file name for the PNG next to Save PNG", true);
        }
        // A folder: numbered screenshots in it, as the S key saves them (it
        // was refused as a name without .png).
        if path.is_dir() {
            return self.numbered_screenshot(path);
        }
        if let Some(problem) = raycaster::files::png_name_problem(path) {
            return self.show_message(&format!("{}: {problem}", path.display()), true);
        }
        if self.refuse_input_as_output(path) {
            return;
        }
        if self.replace_confirmed(path, "Save PNG") {
            self.save_screenshot(path);
        }
    }

    /// Whether a save by `button` may write `path`: it does not exist, or the
    /// button was pressed on it a second time; else says so and arms the
    /// second press. Every save button asks (*Save session* and the scene's
    /// *Save* replaced a file without a word).
    fn replace_confirmed(&self, path: &Path, button: &str) -> bool {
        let confirmed = {
            let mut st = self.state.borrow_mut();
            let again = st.overwrite_armed.take().is_some_and(|p| p == path);
            // (A link to a missing file counts: the save would replace it.)
            if raycaster::files::existing_output(path).is_some() && !again {
                st.overwrite_armed = Some(path.to_path_buf());
                false
            } else {
                true
            }
        };
        if !confirmed {
            self.show_message(
                &format!(
                    "{} exists: press {button} again to replace it",
                    path.display()
                ),
                true,
            );
        }
        confirmed
    }

    /// Once an average-mode frame is complete: when it is dark because its
    /// rays' means lie low in the transfer function's domain, says where they
    /// lie (`raycaster render` warns of the same, naming a `--domain`).
    fn note_dark_average(&self) {
        let found = {
            let mut st = self.state.borrow_mut();
            if !frame_complete(&st) {
                return;
            }
            let Some((id, settings)) = st.average_to_check.take() else {
                return;
            };
            let Some(current) = &st.current else { return };
            let Some((_, camera, _)) = st.cameras.iter().rfind(|(c, _, _)| *c == id) else {
                return;
            };
            let image = current.front.framebuffer().lock().to_image();
            let volume = &current.volume.volume;
            raycaster::render::dark_average(volume, &settings, camera, &image)
                .ok()
                .flatten()
                .map(|dark| (dark, volume.value_units()))
        };
        let Some((dark, units)) = found else {
            return self.part_drawn(Failure::DarkAverage);
        };
        let [lo, hi] = dark.domain.map(|v| units.format(v));
        let [a, b] = dark.spanning.map(|v| units.format(v));
        self.show_message(
            &format!(
                "average: the picture is dark — the rays' means lie in {a} .. {b}, the lowest {:.0} % of the transfer function's range {lo} .. {hi}: move its points into that part to see them",
                dark.share * 100.0
            ),
            false,
        );
        self.state.borrow_mut().shown_failure = Some(Failure::DarkAverage);
    }

    /// Saves a screenshot asked for while the frame rendered, once it is complete.
    fn save_pending_screenshot(&self) {
        let due = {
            let mut st = self.state.borrow_mut();
            if frame_complete(&st) {
                st.pending_screenshot.take()
            } else {
                None
            }
        };
        if let Some(path) = due {
            self.write_screenshot(&path);
        }
    }

    fn write_screenshot(&self, path: &Path) {
        let failure = {
            let st = self.state.borrow();
            st.failed
                .as_ref()
                .filter(|(id, _)| st.latest.is_some_and(|(l, _)| l == *id))
                .map(|(_, e)| e.clone())
        };
        if let Some(e) = failure {
            return self.show_message(
                &format!(
                    "cannot save {}: the view's frame did not render: {e}",
                    path.display()
                ),
                true,
            );
        }
        let image = {
            let st = self.state.borrow();
            let Some(current) = &st.current else { return };
            current.front.framebuffer().lock().to_image()
        };
        match image.save_png(path) {
            Ok(()) => self.show_message(
                &format!(
                    "saved {} ({}×{})",
                    path.display(),
                    image.width(),
                    image.height()
                ),
                false,
            ),
            Err(e) => self.show_message(&format!("cannot save the screenshot: {e}"), true),
        }
    }

    fn load_scene(&self, path: &Path) {
        let scene = match SegmentScene::load(path) {
            Ok(scene) => scene,
            Err(e) => return self.show_message(&format!("{e}"), true),
        };
        // An object cut away whole is refused here, the view kept (as
        // `raycaster render --segments` refuses it).
        let sampled = {
            let st = self.state.borrow();
            st.current.as_ref().map(|c| c.volume.volume.sampled_box())
        };
        if let Some(sampled) = sampled
            && let Err(e) = scene.check_cuts(sampled, 1.0)
        {
            return self.show_message(&format!("{}: {e}", path.display()), true);
        }
        let labels_path = match &scene.membership {
            Membership::Labels(p) => Some(p.clone()),
            Membership::Layers(_) => None,
        };
        let has_labels = {
            let st = self.state.borrow();
            st.current
                .as_ref()
                .is_some_and(|c| c.volume.labels.is_some())
        };
        match labels_path {
            // Layers, or labels the volume brought along (built-in scenes).
            None => self.use_scene(scene, path),
            Some(_) if has_labels => self.use_scene(scene, path),
            Some(labels) => self.attach_labels(scene, labels),
        }
    }

    fn use_scene(&self, scene: SegmentScene, path: &Path) {
        // What keeps it from showing is said with it (as the CLI warns).
        let warnings = {
            let st = self.state.borrow();
            let labels = st.current.as_ref().and_then(|c| c.volume.labels.as_deref());
            scene.warnings(labels)
        };
        self.state.borrow_mut().scene = Some(scene);
        self.show_objects();
        let message = with_warnings(format!("loaded scene {}", path.display()), warnings);
        self.show_message(&message, false);
        self.request_frame(false);
    }

    /// Rebuilds the renderer with the scene's label volume, in the background.
    fn attach_labels(&self, scene: SegmentScene, labels: PathBuf) {
        let volume = {
            let st = self.state.borrow();
            let Some(current) = &st.current else { return };
            current.volume.clone()
        };
        // (It said "the previous volume stays": the volume was not what failed.)
        self.in_background(
            format!("opening labels {} …", labels.display()),
            "the scene was not loaded; the view stays",
            move |wake| {
                // (The volume's error names the file; a foreign file or a
                // volume of values is said as what it is.)
                let label_volume =
                    Arc::new(raycaster::source::open_labels(&labels).map_err(|e| {
                        with_labels_context(e, || {
                            "the scene's label volume (its `labels =`, read beside the scene file)"
                                .to_string()
                        })
                    })?);
                let warnings = scene.warnings(Some(&label_volume));
                let front = RenderFront::with_labels(
                    volume.volume.clone(),
                    Some(label_volume.clone()),
                    None,
                    Some(wake),
                )?;
                let mut volume = volume;
                volume.labels = Some(label_volume);
                let message =
                    with_warnings(format!("labels {} attached", labels.display()), warnings);
                Ok(Install {
                    message,
                    loaded: Loaded { volume, front },
                    new_volume: false,
                    source: None,
                    labels_path: None,
                    scene: Some(scene),
                    session: None,
                    recent: None,
                })
            },
        );
    }

    /// Writes the scene on screen; without one, the plain view as a one-layer
    /// scene (which renders the same image).
    fn save_scene(&self, path: &Path) {
        if !self.names_a_file(path, "scene", "Save (scene)")
            || self.refuse_input_as_output(path)
            || !self.replace_confirmed(path, "Save (scene)")
        {
            return;
        }
        let scene = {
            let st = self.state.borrow();
            st.scene.clone().unwrap_or_else(|| {
                let mode = self.ui().map_or(0, |ui| ui.get_mode_index());
                let mode = Mode::ALL
                    .get(mode.max(0) as usize)
                    .copied()
                    .unwrap_or(Mode::Dvr);
                SegmentScene {
                    membership: Membership::Layers(vec![[0.0, 1.0]]),
                    objects: vec![ObjectStyle {
                        name: "volume".into(),
                        id: 1,
                        visible: true,
                        transfer: st.editor.transfer(),
                        // Every mode has its local counterpart (Sabella included).
                        mode: mode.local(&st.fixed.mode_parameters, st.fixed.iso_value),
                        clip: Default::default(),
                    }],
                    global: GlobalMode::Dvr,
                }
            })
        };
        let dir = raycaster::files::parent_dir(path);
        match write_file_atomically(path, scene.with_paths_for(dir).to_toml().as_bytes()) {
            Ok(()) => self.show_message(&format!("saved scene {}", path.display()), false),
            Err(e) => self.show_message(&format!("cannot save {}: {e}", path.display()), true),
        }
    }

    fn show_objects(&self) {
        let Some(ui) = self.ui() else { return };
        let auto_gain = self.auto_xray_gain();
        let rows: Vec<ObjectRow> = self
            .state
            .borrow()
            .scene
            .iter()
            .flat_map(|s| s.objects.iter())
            .map(|o| to_ui_row(&segments_panel::row_of(o, auto_gain)))
            .collect();
        ui.set_objects(ModelRc::new(VecModel::from(rows)));
    }

    /// The X-ray gain of the open volume an object without one renders with.
    fn auto_xray_gain(&self) -> f32 {
        let diagonal = self
            .state
            .borrow()
            .current
            .as_ref()
            .map_or(1.0, |c| c.volume.volume.diagonal_voxels());
        raycaster::render::auto_xray_gain(diagonal)
    }

    fn edit_object(&self, index: i32, row: &ObjectRow) {
        let auto_gain = self.auto_xray_gain();
        self.change_object(index, |object| {
            segments_panel::apply(object, &from_ui_row(row), auto_gain)
        });
    }

    /// Object `index`'s X-ray gain back to the automatic one (its row's
    /// *auto* button).
    fn automatic_object_gain(&self, index: i32) {
        self.change_object(index, segments_panel::automatic_gain);
    }

    /// Changes object `index` of the scene with `change`, then shows the
    /// panel and renders (saying when every object is then hidden).
    fn change_object(&self, index: i32, change: impl FnOnce(&mut ObjectStyle)) {
        {
            let mut st = self.state.borrow_mut();
            let Some(object) = st
                .scene
                .as_mut()
                .and_then(|s| s.objects.get_mut(index.max(0) as usize))
            else {
                return;
            };
            change(object);
        }
        self.show_objects();
        self.request_frame(false);
        // (Said as `raycaster render` warns; the canvas went black unsaid.)
        let all_hidden = self
            .state
            .borrow()
            .scene
            .as_ref()
            .is_some_and(|s| !s.objects.is_empty() && s.objects.iter().all(|o| !o.visible));
        if all_hidden {
            self.show_message(
                "every object of the scene is hidden: nothing shows (tick one to see it)",
                false,
            );
            self.state.borrow_mut().shown_failure = Some(Failure::AllObjectsHidden);
        } else {
            self.part_drawn(Failure::AllObjectsHidden);
        }
    }
}

fn to_ui_row(r: &ObjectRowData) -> ObjectRow {
    ObjectRow {
        id: i32::from(r.id),
        name: r.name.clone().into(),
        visible: r.visible,
        mode_index: r.mode_index as i32,
        // A function that is no preset (a file's, an edited one): "custom".
        preset_index: r.preset_index.map_or(PRESETS.len() as i32, |i| i as i32),
        param: r.param,
        param_label: r.param_label.as_str().into(),
        param_min: r.param_min,
        param_max: r.param_max,
        param_log: r.param_log,
    }
}

fn from_ui_row(r: &ObjectRow) -> ObjectRowData {
    ObjectRowData {
        id: r.id.clamp(0, 255) as u8,
        name: r.name.to_string(),
        visible: r.visible,
        mode_index: r.mode_index.max(0) as usize,
        preset_index: usize::try_from(r.preset_index)
            .ok()
            .filter(|&i| i < PRESETS.len()),
        param: r.param,
        param_label: r.param_label.to_string(),
        param_min: r.param_min,
        param_max: r.param_max,
        param_log: r.param_log,
    }
}

/// How a frame samples its rays: what the status line says of it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sampling {
    /// The step, in voxels of the level sampled.
    pub step: f32,
    /// Whether the transfer function was pre-integrated.
    pub preintegrated: bool,
}

/// The status line of a finished frame.
pub fn status_line(
    s: &FrameStats,
    interactive: bool,
    sampling: Sampling,
    bytes_read: u64,
) -> String {
    let c = &s.counters;
    let ms = s.time.as_secs_f64() * 1e3;
    let rays = c.rays.max(1) as f64;
    format!(
        "{}{}×{} in {ms:.0} ms · {} · step {}{} · {:.1} MB read from disk by the viewer · {:.1} M samples/s · {:.2} M samples ({:.1}/ray, {:.0} % in SIMD lanes) · \
         {:.0} % skipped empty · {:.0} % rays ended early · {} (+{} skipped, pixels finished) · {} \
         ({} transparent) · {}",
        if interactive { "interactive " } else { "" },
        s.width,
        s.height,
        if s.coarsest_level > s.level {
            format!("levels {}–{} by depth", s.level, s.coarsest_level)
        } else {
            format!("level {}", s.level)
        },
        // Steps are rungs of 2^(1/4): two decimals tell them apart.
        // (Far from the rungs, as a session may give: no "step 0".)
        if !(0.01..1e4).contains(&sampling.step) {
            raycaster::volume::number_text(sampling.step)
        } else {
            format!("{:.2}", sampling.step)
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        },
        if sampling.preintegrated {
            " pre-integrated"
        } else {
            ""
        },
        bytes_read as f64 / 1e6,
        s.samples_per_second() / 1e6,
        c.samples as f64 / 1e6,
        c.samples as f64 / rays,
        100.0 * c.samples_in_lanes as f64 / c.samples.max(1) as f64,
        100.0 * c.samples_skipped_empty as f64
            / (c.samples + c.samples_skipped_empty).max(1) as f64,
        100.0 * c.rays_terminated as f64 / rays,
        counted(c.tasks, "task"),
        c.tasks_skipped_occluded,
        counted(s.bricks, "brick"),
        s.bricks_transparent,
        counted(s.threads as u64, "thread"),
    )
}

#[cfg(test)]
mod tests {
    use super::{Sampling, numbered_path, over_built_in_scene, size_note, status_line, typed_path};
    use std::path::PathBuf;

    /// Pasted paths open: surrounding spaces and one pair of quotes go, `~`
    /// is the home folder (they failed with "No such file or directory").
    #[test]
    fn typed_paths_lose_quotes_and_spaces_and_find_home() {
        assert_eq!(
            typed_path("  /a/my scan.vol \n"),
            PathBuf::from("/a/my scan.vol")
        );
        assert_eq!(
            typed_path("'/a/my scan.vol'"),
            PathBuf::from("/a/my scan.vol")
        );
        assert_eq!(typed_path(" \"/a/b.vol\" "), PathBuf::from("/a/b.vol"));
        assert_eq!(typed_path("'/a/b.vol"), PathBuf::from("'/a/b.vol"));
        assert_eq!(typed_path("a~b.vol"), PathBuf::from("a~b.vol"));
        if let Some(home) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
            let home = PathBuf::from(home);
            assert_eq!(typed_path("~/scans/a.vol"), home.join("scans/a.vol"));
            assert_eq!(typed_path("~"), home);
            assert_eq!(typed_path("~other/a.vol"), PathBuf::from("~other/a.vol"));
        }
    }

    #[test]
    fn the_status_line_names_steps_far_from_the_rungs() {
        let stats = raycaster::render::FrameStats::default();
        let line = |step| {
            status_line(
                &stats,
                false,
                Sampling {
                    step,
                    preintegrated: false,
                },
                0,
            )
        };
        assert!(line(0.71).contains(" step 0.71 "), "{}", line(0.71));
        assert!(line(1e-30).contains(" step 1e-30 "), "{}", line(1e-30));
        assert!(line(1e30).contains(" step 1e30 "), "{}", line(1e30));
    }

    #[test]
    fn numbered_screenshots_are_named_png() {
        let dir = tempfile::tempdir().unwrap();
        let base = dir.path().join("shot.jpg");
        assert_eq!(numbered_path(&base), dir.path().join("shot-1.png"));
        std::fs::write(dir.path().join("shot-1.png"), b"").unwrap();
        assert_eq!(numbered_path(&base), dir.path().join("shot-2.png"));
        // A folder: screenshots inside it.
        assert_eq!(
            numbered_path(dir.path()),
            dir.path().join("screenshot-1.png")
        );
    }

    #[test]
    fn the_status_line_says_how_many_samples_a_simd_kernel_took() {
        let mut stats = raycaster::render::FrameStats::default();
        stats.counters.rays = 10;
        stats.counters.samples = 400;
        stats.counters.samples_in_lanes = 300;
        let sampling = Sampling {
            step: 0.5,
            preintegrated: false,
        };
        let line = status_line(&stats, false, sampling, 0);
        assert!(
            line.contains("M samples (40.0/ray, 75 % in SIMD lanes)"),
            "{line}"
        );
        // A frame of no samples divides by nothing.
        let empty = status_line(
            &raycaster::render::FrameStats::default(),
            false,
            sampling,
            0,
        );
        assert!(empty.contains("(0.0/ray, 0 % in SIMD lanes)"), "{empty}");
        assert!(
            empty.contains("· 0 tasks (+0 skipped, pixels finished) · 0 bricks"),
            "{empty}"
        );
        // One of a kind is said in the singular.
        let mut one = raycaster::render::FrameStats::default();
        (one.bricks, one.threads, one.counters.tasks) = (1, 1, 1);
        let line = status_line(&one, false, sampling, 0);
        assert!(
            line.contains(
                "· 1 task (+0 skipped, pixels finished) · 1 brick (0 transparent) · 1 thread"
            ),
            "{line}"
        );
    }

    #[test]
    fn a_start_error_ending_in_a_newline_reads_as_one_line() {
        // TOML errors end with a newline: the note must not become a line
        // that the message area joins on with ": ".
        let e = std::io::Error::other("t.toml: missing field `transfer`\n");
        let message = raycaster::errors::one_line(&over_built_in_scene(&e));
        assert_eq!(
            message,
            "t.toml: missing field `transfer` (showing the built-in scene)"
        );
    }

    #[test]
    fn a_session_size_is_compared_with_a_laid_out_canvas_only() {
        assert_eq!(size_note([640, 480], Some((640, 480))), "");
        assert_eq!(
            size_note([800, 600], Some((442, 265))),
            " (saved at 800×600; the canvas is 442×265)"
        );
        // Before layout the fallback 640×480 is no canvas: nothing is said.
        assert_eq!(size_note([800, 600], None), "");
    }
}
