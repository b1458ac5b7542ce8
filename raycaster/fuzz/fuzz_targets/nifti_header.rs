//! Fuzzes the nifti header parser: any bytes give a header or an error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(h) = raycaster::import::nifti::parse_header(data) {
        // A parsed header is internally consistent.
        assert!(h.dims.iter().all(|&d| d >= 1));
        assert!(h.spacing.iter().all(|s| s.is_finite() && *s > 0.0));
    }
});
