//! raycaster: CPU ray casting of huge bricked, memory-mapped volumes.
//!
//! This crate is the library behind the `volgen` generator/converter and the
//! renderer front ends. Modules:
//! - [`volume`]: the `.vol` format, mapped/RAM volumes, bricks and value ranges;
//! - [`io`]: streaming readers (raw and `.vol`) and the atomic volume writer;
//! - [`synth`]: deterministic synthetic scenes;
//! - [`generate`] and [`convert`]: the generation and conversion jobs;
//! - [`import`]: readers for NRRD, NIfTI-1, MetaImage files and DICOM series;
//! - [`job`]: progress reporting and cancellation;
//! - [`files`]: opening user-named files (regular files only, never blocking);
//! - [`errors`]: error text for people, each cause said once;
//! - [`render`]: cameras, transfer functions and the ray casters;
//! - [`session`]: everything that makes one frame, as a readable TOML file
//!   (what the viewer saves and `raycaster render --session` renders);
//! - [`source`]: the front ends' façade: a built-in scene or a file, opened with
//!   its labels, default transfer function, domain and framing.

#[cfg(target_endian = "big")]
compile_error!(
    "raycaster views little-endian samples in place; big-endian hosts are not supported"
);

mod alloc_check;
pub mod console;
pub mod convert;
pub mod errors;
pub mod files;
pub mod generate;
pub mod histogram;
pub mod import;
pub mod io;
pub mod job;
pub mod render;
pub mod session;
pub mod slice;
pub mod source;
pub mod synth;
pub mod text;
pub mod volume;
pub mod windows;
