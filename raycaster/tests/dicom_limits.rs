//! DICOM series read in bounded memory and under a low open-file limit: only each
//! slice's pixel data is read, and slices are opened one at a time.
//!
//! Alone in its test binary: it lowers the process's open-file limit.

#![allow(unsafe_code)] // libc without a safe wrapper: FIFOs, signals, resource limits

use std::path::Path;

use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use raycaster::import;

const SIDE: u16 = 4;

/// Writes slice `z` of an explicit-VR little-endian u8 series: value `z` everywhere.
fn write_slice(path: &Path, z: u16) {
    let mut obj = InMemDicomObject::new_empty();
    let us = |tag, v: u16| DataElement::new(tag, VR::US, PrimitiveValue::from(v));
    obj.put(DataElement::new(
        tags::SERIES_INSTANCE_UID,
        VR::UI,
        PrimitiveValue::from("1.2.3"),
    ));
    obj.put(DataElement::new(
        tags::INSTANCE_NUMBER,
        VR::IS,
        PrimitiveValue::from(format!("{}", z + 1)),
    ));
    obj.put(us(tags::SAMPLES_PER_PIXEL, 1));
    obj.put(us(tags::ROWS, SIDE));
    obj.put(us(tags::COLUMNS, SIDE));
    obj.put(us(tags::BITS_ALLOCATED, 8));
    obj.put(us(tags::BITS_STORED, 8));
    obj.put(us(tags::PIXEL_REPRESENTATION, 0));
    let pixels = vec![(z % 256) as u8; usize::from(SIDE * SIDE)];
    obj.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        PrimitiveValue::from(pixels),
    ));
    let file = obj
        .with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax("1.2.840.10008.1.2.1")
                .media_storage_sop_class_uid("1.2.840.10008.5.1.4.1.1.2")
                .media_storage_sop_instance_uid(format!("1.2.3.{z}")),
        )
        .unwrap();
    file.write_to_file(path).unwrap();
}

/// Peak resident memory of this process, in bytes.
fn peak_rss() -> u64 {
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    assert_eq!(unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) }, 0);
    usage.ru_maxrss as u64 * 1024
}

#[test]
fn a_long_series_under_a_low_file_limit_and_a_huge_sparse_slice_read_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let slices = 300u16;
    for z in 0..slices {
        write_slice(&dir.path().join(format!("s{z:04}.dcm")), z);
    }
    // One slice with 8 GiB of (sparse) trailing bytes after its pixel data.
    let fat = dir.path().join("s0007.dcm");
    let f = std::fs::OpenOptions::new().write(true).open(&fat).unwrap();
    f.set_len(f.metadata().unwrap().len() + (8 << 30)).unwrap();
    drop(f);
    // Fewer open files allowed than the series has slices.
    let limit = libc::rlimit {
        rlim_cur: 64,
        rlim_max: 64,
    };
    assert_eq!(unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &limit) }, 0);

    let volume = import::open_volume_any(dir.path(), 1 << 30).unwrap();
    assert_eq!(volume.dims(), [4, 4, u32::from(slices)]);
    for z in [0, 7, 150, 299] {
        assert_eq!(volume.voxel([1, 2, z]), z as u16 % 256, "slice {z}");
    }
    let peak = peak_rss();
    assert!(
        peak < 1 << 30,
        "reading the series peaked at {peak} bytes of memory"
    );
}
