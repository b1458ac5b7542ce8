//! The raycaster viewer: an interactive Slint window on the library's
//! asynchronous render front.
//!
//! [`Viewer`] builds the window and its controller; the modules below hold the
//! pieces that need no window (navigation, quality policy, transfer-function
//! editor, loading, the segments panel) so they are tested on their own.

pub mod app;
pub mod loader;
pub mod navigation;
pub mod quality;
pub mod segments_panel;
pub mod tf_editor;
#[allow(missing_docs, clippy::all)]
pub mod ui;

pub use app::{Source, Viewer};
