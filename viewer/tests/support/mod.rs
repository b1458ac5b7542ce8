//! What the headless viewer tests share: waiting for frames, finding elements
//! and a private configuration folder.

use std::path::Path;
use std::time::{Duration, Instant};

use i_slint_backend_testing::ElementHandle;
use viewer::Viewer;

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
