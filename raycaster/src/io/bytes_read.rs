//! How many bytes this process has made the OS read from storage.

/// Bytes this process has caused to be read from storage so far: Linux's
/// `/proc/self/io` `read_bytes`, which counts page-cache misses, page faults on
/// mapped files included (the cache's hits cost nothing and are not counted); 0
/// where that is not available.
pub fn process_bytes_read() -> u64 {
    std::fs::read_to_string("/proc/self/io")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|l| l.strip_prefix("read_bytes:"))
                .and_then(|v| v.trim().parse().ok())
        })
        .unwrap_or(0)
}
