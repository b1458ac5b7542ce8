//! Where a volume's bytes live: a read-only memory map or a buffer in RAM.
//!
//! Both hand out one `&[u8]`; nothing above this module knows which it is.

use crate::files::human_bytes;
use std::fs::File;
use std::os::unix::fs::FileExt;

use memmap2::Mmap;

/// How to hold an opened volume.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Access {
    /// Map the file read-only (volumes larger than RAM work).
    #[default]
    Mapped,
    /// Read the whole file into memory.
    Ram,
}

/// The bytes of a whole volume file.
#[derive(Debug)]
pub(crate) enum Storage {
    /// A read-only mapping of the file (or of a region of it).
    Mapped {
        map: Mmap,
        /// The mapped file, to see whether it still holds the mapping's bytes.
        file: File,
        /// The file's length when it was mapped: a shorter file lost bytes the
        /// volume may read (the mapping's, or its tables', mapped apart).
        end: u64,
    },
    /// The file read into an 8-byte aligned buffer (so u16 samples can be viewed in place).
    Ram { words: Vec<u64>, len: usize },
}

/// A map of `len` bytes refused for want of address space (ENOMEM: an
/// address-space limit, `ulimit -v`, below the file's size), said so.
fn without_address_space(e: std::io::Error, len: usize) -> std::io::Error {
    if e.raw_os_error() != Some(libc::ENOMEM) {
        return e;
    }
    std::io::Error::new(
        std::io::ErrorKind::OutOfMemory,
        format!(
            "mapping it needs {} of address space, more than this process may take (an address-space limit, ulimit -v?)",
            human_bytes(len as u64)
        ),
    )
}

impl Storage {
    /// Maps `file` or reads it whole, as `access` says.
    pub(crate) fn open(file: &File, len: u64, access: Access) -> std::io::Result<Storage> {
        let len = usize::try_from(len).map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::OutOfMemory,
                "file does not fit in this machine's address space",
            )
        })?;
        match access {
            Access::Mapped => {
                // SAFETY: the map is read-only and we never hand out a mutable view.
                // Another process truncating or rewriting the file while it is mapped
                // would change or remove the bytes under us (SIGBUS on truncation);
                // that is the documented contract of opening a volume mapped, the
                // reason the design uses mmap at all (volumes larger than RAM), and
                // no Rust invariant beyond the bytes' values depends on the content.
                #[allow(unsafe_code)] // memmap2: mapping a file is unsafe by contract
                let map = unsafe { Mmap::map(file) }.map_err(|e| without_address_space(e, len))?;
                if map.len() < len {
                    return Err(std::io::Error::new(
                        std::io::ErrorKind::UnexpectedEof,
                        "file shrank while it was being opened",
                    ));
                }
                Ok(Storage::Mapped {
                    map,
                    file: file.try_clone()?,
                    end: len as u64,
                })
            }
            // Positioned: the header was already read through this handle.
            Access::Ram => Storage::read_into_ram(file, 0, len),
        }
    }

    /// `len` bytes of `file` at `offset` (a pyramid level), mapped or read.
    pub(crate) fn open_region(
        file: &File,
        offset: u64,
        len: u64,
        access: Access,
    ) -> std::io::Result<Storage> {
        match access {
            // (The whole file counts: its tables lie beyond the region.)
            Access::Mapped => Ok(Storage::Mapped {
                map: super::pyramid::map_region(file, offset, len)
                    .map_err(|e| without_address_space(e, len as usize))?,
                file: file.try_clone()?,
                end: file.metadata()?.len().max(offset.saturating_add(len)),
            }),
            Access::Ram => {
                let len = usize::try_from(len).map_err(|_| {
                    std::io::Error::new(std::io::ErrorKind::OutOfMemory, "level too large")
                })?;
                Storage::read_into_ram(file, offset, len)
            }
        }
    }

    /// Tells the OS that pages are used in no particular order (bricked files: a
    /// page fault reads that page, not its neighbours, which belong to other
    /// bricks); the renderer asks for the bricks it needs itself
    /// ([`Self::will_need`]). Best effort.
    pub(crate) fn advise_random(&self) {
        if let Storage::Mapped { map, .. } = self {
            let _ = map.advise(memmap2::Advice::Random);
        }
    }

    /// `len` bytes of `file` at `offset` read into an 8-byte aligned buffer.
    fn read_into_ram(file: &File, offset: u64, len: usize) -> std::io::Result<Storage> {
        // Refused when the memory is not there (an address-space limit, more
        // than the machine has): the allocation aborted the process.
        let mut words: Vec<u64> = Vec::new();
        words.try_reserve_exact(len.div_ceil(8)).map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::OutOfMemory,
                format!(
                    "reading it into memory needs {}, more than this process can allocate; mapped (the default), it needs no such memory",
                    human_bytes(len as u64)
                ),
            )
        })?;
        words.resize(len.div_ceil(8), 0);
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        file.read_exact_at(&mut bytes[..len], offset)
            .map_err(|e| match e.kind() {
                // Another program cut the file while it was read.
                std::io::ErrorKind::UnexpectedEof => {
                    let now = file.metadata().map_or(0, |m| m.len());
                    let needed = offset.saturating_add(len as u64);
                    std::io::Error::new(
                        e.kind(),
                        format!(
                            "shrank to {now} bytes while it was read into memory (it needs {needed}): another program truncated it"
                        ),
                    )
                }
                _ => e,
            })?;
        Ok(Storage::Ram { words, len })
    }

    /// Asks the OS to read `len` bytes at `offset` ahead of use (mapped storage
    /// only; best effort: errors are ignored).
    pub(crate) fn will_need(&self, offset: u64, len: u64) {
        if let Storage::Mapped { map, .. } = self {
            let start = (offset as usize).min(map.len());
            let len = (len as usize).min(map.len() - start);
            if len > 0 {
                let _ = map.advise_range(memmap2::Advice::WillNeed, start, len);
            }
        }
    }

    /// A RAM copy of `bytes` (a whole file image built in memory).
    pub(crate) fn from_bytes(bytes: &[u8]) -> Storage {
        let mut words = vec![0u64; bytes.len().div_ceil(8)];
        bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
        Storage::Ram {
            words,
            len: bytes.len(),
        }
    }

    /// All bytes of the file.
    pub(crate) fn bytes(&self) -> &[u8] {
        match self {
            Storage::Mapped { map, .. } => map,
            Storage::Ram { words, len } => &bytemuck::cast_slice(words)[..*len],
        }
    }

    /// The mapped file's length now and the length the mapping needs, when the
    /// file has become shorter than that (another program truncated it: a read
    /// of the missing bytes would fault); `None` for a whole file or RAM.
    pub(crate) fn shrunk(&self) -> Option<(u64, u64)> {
        match self {
            Storage::Mapped { file, end, .. } => {
                let now = file.metadata().ok()?.len();
                (now < *end).then_some((now, *end))
            }
            Storage::Ram { .. } => None,
        }
    }

    /// Which kind of storage this is.
    pub(crate) fn access(&self) -> Access {
        match self {
            Storage::Mapped { .. } => Access::Mapped,
            Storage::Ram { .. } => Access::Ram,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_shorter_than_opened_is_said_so() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v");
        std::fs::write(&path, [7u8; 1000]).unwrap();
        let file = File::open(&path).unwrap();
        // Read into RAM expecting more than is there (cut after the header
        // was read): the sizes, not "failed to fill whole buffer".
        let e = Storage::open(&file, 4000, Access::Ram).unwrap_err();
        assert_eq!(
            e.to_string(),
            "shrank to 1000 bytes while it was read into memory (it needs 4000): another program truncated it"
        );
        // Mapped: whole until the file shrinks below its length when mapped.
        let mapped = Storage::open(&file, 1000, Access::Mapped).unwrap();
        assert_eq!(mapped.shrunk(), None);
        let region = Storage::open_region(&file, 100, 200, Access::Mapped).unwrap();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(600)
            .unwrap();
        assert_eq!(mapped.shrunk(), Some((600, 1000)));
        // (A region counts the whole file: its tables lie beyond it.)
        assert_eq!(region.shrunk(), Some((600, 1000)));
        let ram = Storage::open(&file, 600, Access::Ram).unwrap();
        assert_eq!(ram.shrunk(), None);
    }
}
