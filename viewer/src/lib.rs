//! The raycaster viewer: an interactive Slint window on the library's
//! asynchronous render front.
//!
//! [`Viewer`] builds the window and its controller; the modules below hold the
//! pieces that need no window (navigation, quality policy, transfer-function
//! editor, loading, the segments panel, the cut panel, keyboard shortcuts, slice
//! views, recent files, picture annotations) so they are tested on their own.

pub(crate) mod annotations;
pub mod app;
pub(crate) mod browser;
pub(crate) mod cut;
pub mod loader;
pub mod navigation;
pub mod quality;
pub(crate) mod recent;
pub mod segments_panel;
pub(crate) mod shortcuts;
pub(crate) mod slices;
pub mod tf_editor;
#[allow(missing_docs, clippy::all)]
pub mod ui;

pub use app::{Source, Viewer};
