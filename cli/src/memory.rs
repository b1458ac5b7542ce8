//! Whether a frame fits the machine's memory: checked before rendering, so a
//! huge `--size` is an error rather than a process killed for memory.

use anyhow::{Result, bail};

/// Bytes a frame takes per pixel, measured: about 56 at 4096² (`raycaster
/// render --size 4096 --step 1000` peaks at 0.92 GB: the pixels' compositing
/// states, the frame's floats, the image and its PNG encoding) and 65 at
/// 16384² (17.5 GB), with a margin.
const FRAME_BYTES_PER_PIXEL: u64 = 72;

/// Refuses a `width × height` frame that would take more memory than the
/// machine has available (`MemAvailable` of `/proc/meminfo`; no check where
/// that is unknown).
pub fn check_frame(width: u32, height: u32) -> Result<()> {
    let Some(available) = available_bytes() else {
        return Ok(());
    };
    frame_fits(width, height, available)
}

/// [`check_frame`] against `available` bytes.
fn frame_fits(width: u32, height: u32, available: u64) -> Result<()> {
    let needed = u64::from(width) * u64::from(height) * FRAME_BYTES_PER_PIXEL;
    if needed > available {
        bail!(
            "a {width}×{height} frame needs about {:.1} GB of memory and {:.1} GB are available; render a smaller --size",
            needed as f64 / 1e9,
            available as f64 / 1e9
        );
    }
    Ok(())
}

/// The memory available to new allocations, by the kernel's estimate.
fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_beyond_the_available_memory_are_refused_with_the_numbers() {
        let gb = 1_000_000_000;
        assert!(frame_fits(512, 512, gb).is_ok());
        let e = frame_fits(16384, 16384, 11 * gb).unwrap_err().to_string();
        assert_eq!(
            e,
            "a 16384×16384 frame needs about 19.3 GB of memory and 11.0 GB are available; render a smaller --size"
        );
        assert!(frame_fits(16384, 16384, 20 * gb).is_ok());
        assert!(frame_fits(16384, 16384, 18 * gb).is_err());
        // This machine reports its memory.
        assert!(available_bytes().is_some_and(|b| b > 0));
    }
}
