//! Whether a frame fits the machine's memory: checked before rendering, so a
//! huge `--size` or a tiny `--brick` is an error rather than a process killed
//! for memory.

use anyhow::{Result, bail};
use raycaster::files::human_bytes;

/// Bytes a frame takes per pixel, measured: about 56 at 4096² (`raycaster
/// render --size 4096 --step 1000` peaks at 0.92 GB: the pixels' compositing
/// states, the frame's floats, the image and its PNG encoding) and 65 at
/// 16384² (17.5 GB), with a margin.
const FRAME_BYTES_PER_PIXEL: u64 = 72;

/// Refuses a `width × height` frame that would take more memory than this
/// process can have: the least of what the machine has available
/// (`MemAvailable` of `/proc/meminfo`), what the process's address-space limit
/// leaves (`ulimit -v`) and what its control group's limit leaves
/// (`memory.max`); no check where none is known.
pub fn check_frame(width: u32, height: u32) -> Result<()> {
    let Some((available, whose)) = least_available() else {
        return Ok(());
    };
    frame_fits(width, height, available, whose)
}

/// The least of the memory limits [`check_frame`] names, and which it is
/// (said after the number); `None` where none is known.
fn least_available() -> Option<(u64, &'static str)> {
    let limits = [
        available_bytes().map(|b| (b, "")),
        address_space_left().map(|b| (b, " under the process's address-space limit (ulimit -v)")),
        cgroup_left().map(|b| (b, " under the control group's memory limit")),
    ];
    limits.into_iter().flatten().min_by_key(|(b, _)| *b)
}

/// Bytes a frame's plan takes per brick at the least, measured with `--brick
/// 2` (bricks of step 1; the brick's ranges, cells and schedule, a tile queue
/// entry): peaks of 16.3 GB for 1200³ (1.72 G bricks: 9.5 bytes each),
/// 0.81 GB for 384³ (56 M: 14) and 0.42 GB for 256³ (16.6 M: 25). Below the
/// least of them: a refusal only where the bricks cannot fit.
const BRICK_BYTES: u64 = 8;

/// Refuses brick side `side` (given by `flag`: `--brick`, `--bricks`) when
/// its `count` bricks take more memory than this process can have (as
/// [`check_frame`]): the allocation aborted the process.
pub fn check_bricks(flag: &str, count: u64, side: u32) -> Result<()> {
    let Some((available, whose)) = least_available() else {
        return Ok(());
    };
    bricks_fit(flag, count, side, available, whose)
}

/// Refuses work that needs `bytes` of memory (`what` needs them: said first)
/// where the process cannot have them (as [`check_frame`]).
pub fn check_memory(what: impl std::fmt::Display, bytes: u64) -> Result<()> {
    let Some((available, whose)) = least_available() else {
        return Ok(());
    };
    if bytes > available {
        bail!(
            "{what} needs about {} of memory and {} are available{whose}",
            human_bytes(bytes),
            human_bytes(available)
        );
    }
    Ok(())
}

/// Refuses reading a `bytes`-long volume file, `what` (its path, said first),
/// into memory (`--ram`) when it does not fit the memory this process can
/// have (as [`check_frame`]), with a tenth more for the frame and the rest:
/// the allocation that failed aborted the process, or, refused by the
/// library, named one level only.
pub fn check_ram(what: impl std::fmt::Display, bytes: u64) -> Result<()> {
    let Some((available, whose)) = least_available() else {
        return Ok(());
    };
    let needed = bytes.saturating_add(bytes / 10);
    if needed > available {
        bail!(
            "{what}: reading it into memory (--ram) needs about {} and {} are available{whose}; mapped (without --ram), it needs no such memory",
            human_bytes(needed),
            human_bytes(available)
        );
    }
    Ok(())
}

/// [`check_bricks`] against `available` bytes.
fn bricks_fit(flag: &str, count: u64, side: u32, available: u64, whose: &str) -> Result<()> {
    let needed = count.saturating_mul(BRICK_BYTES);
    if needed > available {
        bail!(
            "{flag} {side} cuts the volume into {:.1} M bricks, whose tables need about {} of memory and {} are available{whose}; give a larger {flag} (16 to 32 render fastest)",
            count as f64 / 1e6,
            human_bytes(needed),
            human_bytes(available)
        );
    }
    Ok(())
}

/// [`check_frame`] against `available` bytes (`whose`: which limit leaves
/// them, said after the number).
fn frame_fits(width: u32, height: u32, available: u64, whose: &str) -> Result<()> {
    let needed = u64::from(width) * u64::from(height) * FRAME_BYTES_PER_PIXEL;
    if needed > available {
        bail!(
            "a {width}×{height} frame needs about {} of memory and {} are available{whose}; render a smaller --size",
            human_bytes(needed),
            human_bytes(available)
        );
    }
    Ok(())
}

/// What the soft address-space limit (`/proc/self/limits`) leaves beyond the
/// process's present size (`VmSize`); `None` when unlimited or unknown.
fn address_space_left() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft: u64 = line
        .trim_start_matches("Max address space")
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    Some(soft.saturating_sub(kib_field(&status, "VmSize:")?))
}

/// What the memory limit of the process's (version 2) control group leaves
/// beyond its present use; `None` when unlimited or unknown.
fn cgroup_left() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = groups.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    let max: u64 = read("memory.max")?.trim().parse().ok()?;
    let current: u64 = read("memory.current")?.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

/// The number of kibibytes (in bytes) on the line of `text` starting `key`.
fn kib_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib * 1024)
}

/// The memory available to new allocations, by the kernel's estimate.
fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&text, "MemAvailable:")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_beyond_the_available_memory_are_refused_with_the_numbers() {
        let gb = 1_000_000_000;
        assert!(frame_fits(512, 512, gb, "").is_ok());
        let e = frame_fits(16384, 16384, 11 * gb, "")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "a 16384×16384 frame needs about 19.3 GB of memory and 11.0 GB are available; render a smaller --size"
        );
        assert!(frame_fits(16384, 16384, 20 * gb, "").is_ok());
        assert!(frame_fits(16384, 16384, 18 * gb, "").is_err());
        assert_eq!(
            kib_field("VmPeak:\t  10 kB\nVmSize:\t 2048 kB\n", "VmSize:"),
            Some(2 << 20)
        );
        // This machine reports its memory.
        assert!(available_bytes().is_some_and(|b| b > 0));
    }

    #[test]
    fn bricks_beyond_the_available_memory_are_refused_with_the_numbers() {
        let gb = 1_000_000_000;
        // 1200³ at --brick 2 peaked at 16.3 GB on a machine of 24.
        let bricks = 1199u64.pow(3);
        assert!(bricks_fit("--brick", bricks, 2, 20 * gb, "").is_ok());
        let e = bricks_fit(
            "--brick",
            bricks,
            2,
            4 * gb,
            " under the process's address-space limit (ulimit -v)",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "--brick 2 cuts the volume into 1723.7 M bricks, whose tables need about 13.8 GB of memory and 4.0 GB are available under the process's address-space limit (ulimit -v); give a larger --brick (16 to 32 render fastest)"
        );
    }
}
