//! Fuzzes the `.vol` header parser with arbitrary bytes and file lengths.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 8 {
        return;
    }
    let len = u64::from_le_bytes(data[..8].try_into().unwrap());
    let _ = raycaster::volume::Header::parse(&data[8..], len);
});
