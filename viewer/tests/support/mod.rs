//! What the headless viewer tests share: the testing platform, waiting for
//! frames, finding elements, a private configuration folder and volume files.

use std::path::Path;
use std::time::{Duration, Instant};

use i_slint_backend_testing::{ElementHandle, TestingBackend, TestingBackendOptions};
use raycaster::synth::SceneKind;
use slint::ComponentHandle;
use viewer::{Source, Viewer};

/// Installs Slint's testing platform: software renderer, mocked time, no
/// threads. Call it once, first, in the test process.
pub fn headless_platform() {
    slint::platform::set_platform(Box::new(TestingBackend::new(TestingBackendOptions {
        mock_time: true,
        threading: false,
        renderer_name: Some("software".into()),
    })))
    .expect("the first platform of this process");
}

/// Writes the built-in `kind` scene of `size³` voxels as a bricked u8 `.vol` file
/// (with its resolution pyramid, when it is large enough for one).
// Not every test file writes volumes.
#[allow(dead_code)]
pub fn generate_file(path: &Path, kind: SceneKind, size: u32) {
    generate_content(path, kind, size, raycaster::volume::Content::Scalar);
}

/// [`generate_file`] of the scene's labels (a label volume), as `volgen
/// generate` writes them beside the data.
#[allow(dead_code)]
pub fn generate_labels(path: &Path, kind: SceneKind, size: u32) {
    generate_content(path, kind, size, raycaster::volume::Content::Labels);
}

fn generate_content(path: &Path, kind: SceneKind, size: u32, content: raycaster::volume::Content) {
    let header = raycaster::volume::Header::new(
        [size; 3],
        [1.0; 3],
        raycaster::volume::Layout::Bricked { side: 16 },
        raycaster::volume::SampleType::U8,
        content,
        raycaster::volume::Format::Extended,
    );
    raycaster::generate::generate(
        kind.build([size; 3], 1).as_ref(),
        &header,
        path,
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap();
}

/// A viewer on `source` in a shown window of `width × height` logical pixels,
/// its canvas laid out (the first frame is requested, not waited for).
#[allow(dead_code)]
pub fn shown_viewer(source: Source, width: f32, height: f32) -> Viewer {
    let v = Viewer::new(source, None).unwrap();
    v.ui()
        .window()
        .set_size(slint::LogicalSize::new(width, height));
    v.ui().show().unwrap();
    v.pump();
    v.ui().invoke_canvas_resized();
    v
}

/// Pumps until the newest frame is on screen.
pub fn wait_for_frame(v: &Viewer) {
    let start = Instant::now();
    loop {
        v.pump();
        if v.idle() {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no frame arrived; status: {:?}, message: {:?}",
            v.ui().get_status(),
            v.ui().get_message()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Lets the view rest (the settle timer fires) and waits for the full-quality
/// frame, checking that it is one.
#[allow(dead_code)]
pub fn settle(v: &Viewer) {
    wait_for_frame(v);
    i_slint_backend_testing::mock_elapsed_time(Duration::from_millis(300));
    slint::platform::update_timers_and_animations();
    wait_for_frame(v);
    assert_eq!(
        v.last_stats().map(|(_, moving)| moving),
        Some(false),
        "a settled, full-quality frame"
    );
}

/// The mode box's index of `mode`.
#[allow(dead_code)]
pub fn mode_index(mode: raycaster::render::Mode) -> i32 {
    raycaster::render::Mode::ALL
        .iter()
        .position(|&m| m == mode)
        .expect("every mode is in the box") as i32
}

/// The UI element with the id `id` (`App::canvas`).
pub fn element(v: &Viewer, id: &str) -> ElementHandle {
    ElementHandle::find_by_element_id(v.ui(), id)
        .next()
        .unwrap_or_else(|| panic!("no element {id}"))
}

/// Points `XDG_CONFIG_HOME` at `dir`, so that the recent files the viewer
/// remembers go there and not into the user's configuration. Call it first,
/// before the viewer (or any thread of the test) starts.
pub fn private_config(dir: &Path) {
    // SAFETY: called before any other thread of the test process starts.
    #[allow(unsafe_code)]
    unsafe {
        std::env::set_var("XDG_CONFIG_HOME", dir);
    }
}
