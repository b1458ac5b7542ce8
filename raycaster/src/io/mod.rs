//! Streaming volume I/O in bounded memory.
//!
//! Everything is moved in *slabs*: runs of whole x-planes (all y and z), which is the
//! unit both layouts can be written from. [`Input`] reads a slab from a raw file or a
//! `.vol` file with positioned reads (never mapping or reading the whole input);
//! [`write_volume`] asks for slabs in order and writes a `.vol` file atomically.

mod bytes_read;
mod decode;
mod input;
mod staging;
mod writer;

pub use bytes_read::process_bytes_read;
pub use decode::{Endian, RawType};
pub use input::{Input, InputType, RawData, RawOrder, RawSpec, ValueRange};
pub(crate) use staging::XRegions;
pub(crate) use writer::{CellSink, physical_memory, stream_samples};
pub use writer::{WriteOptions, WriteSummary, write_volume};
