//! DICOM series: a folder of single-frame slices of one series (or one `.dcm` file
//! of it, meaning its folder).
//!
//! Each file's metadata is read with `dicom-object` (dicom-rs) up to the pixel data;
//! the pixel data itself is located in the file (the `(7FE0,0010)` element whose
//! length is exactly rows × columns × bytes per sample) and later read with positioned
//! reads, so a series streams like a raw file. Files without the `DICM` marker (a
//! `DICOMDIR`, notes) are skipped. Supported: uncompressed transfer syntaxes
//! (implicit/explicit VR little endian, explicit big endian), one sample per pixel,
//! 8 or 16 bits allocated (u8, u16, i16), one frame per file, one series per folder.
//!
//! Slices are sorted by their Image Position (Patient) projected on the slice normal
//! (from Image Orientation (Patient)), else by Instance Number, else by file name.
//! x runs along a row (columns, fastest), y down the rows, z through the slices;
//! spacing is Pixel Spacing (column spacing on x, row spacing on y) and the distance
//! between slice positions (else Spacing Between Slices, else Slice Thickness). The
//! orientation is not applied, and Rescale Slope/Intercept are reported, not applied
//! (see `docs/import.md`).

use std::path::{Path, PathBuf};

use dicom_dictionary_std::tags;
use dicom_object::OpenFileOptions;

use super::{
    Encoding, ImportError, ImportErrorKind, ImportFormat, Imported, check_dims, check_spacing,
    header_error, unsupported,
};
use crate::io::{Endian, RawType};
use crate::volume::{Orientation, PatientSpace};

const F: ImportFormat = ImportFormat::Dicom;

/// One slice of a series: its file, where its pixel data starts, and what orders it.
#[derive(Clone, Debug)]
struct Slice {
    path: PathBuf,
    pixel_offset: u64,
    rows: u32,
    columns: u32,
    sample: RawType,
    endian: Endian,
    series: String,
    position: Option<[f64; 3]>,
    orientation: Option<[f64; 6]>,
    instance: Option<i64>,
    pixel_spacing: Option<[f64; 2]>,
    between: Option<f64>,
    scaling: Option<(f32, f32)>,
    /// "HU" for a CT slice (Modality CT), else empty.
    unit: String,
}

fn has_dicm_marker(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 132];
    crate::files::open_regular(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|_| &head[128..132] == b"DICM")
}

/// The folder of the series `path` names (itself, or a `.dcm` file's folder).
pub fn series_dir(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.to_path_buf()
    } else {
        path.parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf()
    }
}

/// The byte order of transfer syntax `ts`, or why it is not read.
fn endian_of(ts: &str) -> Result<Endian, ImportErrorKind> {
    match ts.trim_end_matches('\0') {
        "1.2.840.10008.1.2" | "1.2.840.10008.1.2.1" => Ok(Endian::Little),
        "1.2.840.10008.1.2.2" => Ok(Endian::Big),
        deflated @ "1.2.840.10008.1.2.1.99" => Err(unsupported(
            F,
            format!(
                "transfer syntax {deflated} (a deflate-compressed data set; only uncompressed slices are read)"
            ),
        )),
        // JPEG, JPEG-LS, JPEG 2000, MPEG, HEVC (…1.2.4.*) and RLE (…1.2.5).
        compressed
            if compressed.starts_with("1.2.840.10008.1.2.4.")
                || compressed == "1.2.840.10008.1.2.5" =>
        {
            Err(unsupported(
                F,
                format!(
                    "transfer syntax {compressed} (compressed pixel data; only uncompressed slices are read)"
                ),
            ))
        }
        other => Err(unsupported(
            F,
            format!(
                "transfer syntax {other:?}, which is no known one (only the uncompressed 1.2.840.10008.1.2, 1.2.840.10008.1.2.1 and 1.2.840.10008.1.2.2 are read)"
            ),
        )),
    }
}

/// The transfer syntax in the file meta group of the DICOM file at `path`
/// (after its 128-byte preamble), read alone; `None` where it cannot be.
fn transfer_syntax_of(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut file = crate::files::open_regular(path).ok()?;
    let mut preamble = [0u8; 128];
    file.read_exact(&mut preamble).ok()?;
    let meta =
        dicom_object::meta::FileMetaTable::from_reader(std::io::BufReader::new(file)).ok()?;
    Some(meta.transfer_syntax().to_string())
}

/// Reads one slice's metadata and finds its pixel data.
fn read_slice(path: &Path) -> Result<Slice, ImportErrorKind> {
    let obj = OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
        .map_err(|e| {
            // A transfer syntax the parser cannot read (a deflated data set)
            // is said as the unsupported syntax it is, not as the parser's
            // advice to its own developers.
            match transfer_syntax_of(path).map(|ts| endian_of(&ts)) {
                Some(Err(e)) => e,
                _ => header_error(F, format!("cannot parse the DICOM file: {e}")),
            }
        })?;
    let endian = endian_of(obj.meta().transfer_syntax())?;
    let int = |tag, name: &str| -> Result<i64, ImportErrorKind> {
        obj.element(tag)
            .map_err(|_| header_error(F, format!("{name} is missing")))?
            .to_int::<i64>()
            .map_err(|_| header_error(F, format!("{name} is not a number")))
    };
    // A geometry field that is there must be numbers: one that is not would
    // silently become the default (a spacing of 1, slices out of order).
    let floats = |tag, name: &str| -> Result<Option<Vec<f64>>, ImportErrorKind> {
        let Ok(element) = obj.element(tag) else {
            return Ok(None);
        };
        let text = element
            .to_str()
            .map(|t| t.trim_matches(['\0', ' ']).to_string())
            .unwrap_or_default();
        match element.to_multi_float64() {
            Ok(values) => Ok(Some(values)),
            // (An empty value: a type-2 element left blank, as if absent.)
            Err(_) if text.is_empty() => Ok(None),
            Err(_) => Err(header_error(
                F,
                format!("{name} `{text}` is not a list of numbers"),
            )),
        }
    };
    let rows = int(tags::ROWS, "Rows")?;
    let columns = int(tags::COLUMNS, "Columns")?;
    let samples_per_pixel = int(tags::SAMPLES_PER_PIXEL, "Samples per Pixel").unwrap_or(1);
    if samples_per_pixel != 1 {
        return Err(unsupported(
            F,
            format!("{samples_per_pixel} samples per pixel (grey images are read)"),
        ));
    }
    if let Ok(frames) = int(tags::NUMBER_OF_FRAMES, "Number of Frames")
        && frames > 1
    {
        return Err(unsupported(
            F,
            format!("a multi-frame file ({frames} frames)"),
        ));
    }
    let bits = int(tags::BITS_ALLOCATED, "Bits Allocated")?;
    let signed = int(tags::PIXEL_REPRESENTATION, "Pixel Representation").unwrap_or(0) == 1;
    let sample = match (bits, signed) {
        (8, false) => RawType::U8,
        (16, false) => RawType::U16,
        (16, true) => RawType::I16,
        _ => {
            return Err(unsupported(
                F,
                format!(
                    "{bits} bits allocated, {} (u8, u16 and i16 are read)",
                    if signed { "signed" } else { "unsigned" }
                ),
            ));
        }
    };
    let dims = check_dims(F, &[columns.max(0) as u64, rows.max(0) as u64])?;
    let expected = u64::from(dims[0]) * u64::from(dims[1]) * sample.size() as u64;
    let pixel_offset = find_pixel_data(path, expected, endian).map_err(ImportErrorKind::Io)?.ok_or_else(|| {
        header_error(F, format!("no Pixel Data element of {expected} bytes ({columns}x{rows}, {bits} bits) was found"))
    })?;
    let slope = floats(tags::RESCALE_SLOPE, "Rescale Slope")?.and_then(|v| v.first().copied());
    let inter =
        floats(tags::RESCALE_INTERCEPT, "Rescale Intercept")?.and_then(|v| v.first().copied());
    // (Units hold f32: a slope or intercept beyond it would become ∞ or NaN.)
    for (name, v) in [("Rescale Slope", slope), ("Rescale Intercept", inter)] {
        if let Some(v) = v
            && !(v as f32).is_finite()
        {
            return Err(header_error(
                F,
                format!("{name} {v:e} is not a finite number of the ±3.4e38 the units hold"),
            ));
        }
    }
    if slope == Some(0.0) {
        return Err(header_error(
            F,
            "Rescale Slope 0 maps every stored value to the intercept: no image".to_string(),
        ));
    }
    let scaling = match (slope, inter) {
        (Some(s), i) if s != 1.0 || i.unwrap_or(0.0) != 0.0 => {
            Some((s as f32, i.unwrap_or(0.0) as f32))
        }
        (None, Some(i)) if i != 0.0 => Some((1.0, i as f32)),
        _ => None,
    };
    let series = obj
        .element(tags::SERIES_INSTANCE_UID)
        .ok()
        .and_then(|e| {
            e.to_str()
                .ok()
                .map(|s| s.trim_end_matches('\0').trim().to_string())
        })
        .unwrap_or_default();
    // Rescaled CT values are Hounsfield units.
    let modality = obj.element(tags::MODALITY).ok().and_then(|e| {
        e.to_str()
            .ok()
            .map(|s| s.trim_end_matches('\0').trim().to_string())
    });
    let unit = match modality.as_deref() {
        Some("CT") => crate::volume::HOUNSFIELD.to_string(),
        _ => String::new(),
    };
    let position: Option<[f64; 3]> =
        floats(tags::IMAGE_POSITION_PATIENT, "Image Position (Patient)")?
            .and_then(|v| v.try_into().ok());
    if let Some(p) = position
        && !p.iter().all(|v| v.is_finite())
    {
        return Err(header_error(
            F,
            format!("Image Position (Patient) {p:?} is not three finite numbers"),
        ));
    }
    let orientation: Option<[f64; 6]> = floats(
        tags::IMAGE_ORIENTATION_PATIENT,
        "Image Orientation (Patient)",
    )?
    .and_then(|v| v.try_into().ok());
    if let Some(o) = orientation {
        let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
        let length = |v: [f64; 3]| dot(v, v).sqrt();
        let normal = [
            r[1] * c[2] - r[2] * c[1],
            r[2] * c[0] - r[0] * c[2],
            r[0] * c[1] - r[1] * c[0],
        ];
        let kept = length(normal) > 1e-3 * length(r) * length(c);
        if !kept || !o.iter().all(|v| v.is_finite()) {
            return Err(header_error(
                F,
                format!(
                    "Image Orientation (Patient) {o:?}: its row and column directions are zero, not finite or parallel"
                ),
            ));
        }
    }
    Ok(Slice {
        path: path.to_path_buf(),
        pixel_offset,
        rows: dims[1],
        columns: dims[0],
        sample,
        endian,
        series,
        position,
        orientation,
        instance: int(tags::INSTANCE_NUMBER, "Instance Number").ok(),
        pixel_spacing: floats(tags::PIXEL_SPACING, "Pixel Spacing")?
            .and_then(|v| v.try_into().ok()),
        between: floats(tags::SPACING_BETWEEN_SLICES, "Spacing Between Slices")?
            .or(floats(tags::SLICE_THICKNESS, "Slice Thickness")?)
            .and_then(|v| v.first().copied()),
        scaling,
        unit,
    })
}

/// Bytes of a slice file scanned per read when looking for its pixel data.
const SCAN_CHUNK: usize = 1 << 20;

/// The byte offset of the value of the first top-level-looking Pixel Data element
/// whose length is `expected` (explicit VR `OB`/`OW` or implicit VR encoding).
///
/// The file is scanned in chunks and the scan stops at the element: only the bytes
/// before the pixel data are read, whatever follows it (memory stays bounded for a
/// slice with gigabytes of trailing bytes).
fn find_pixel_data(path: &Path, expected: u64, endian: Endian) -> std::io::Result<Option<u64>> {
    use std::os::unix::fs::FileExt;
    let (tag, len_bytes): ([u8; 4], [u8; 4]) = match endian {
        Endian::Little => ([0xe0, 0x7f, 0x10, 0x00], (expected as u32).to_le_bytes()),
        Endian::Big => ([0x7f, 0xe0, 0x00, 0x10], (expected as u32).to_be_bytes()),
    };
    if expected > u64::from(u32::MAX) {
        return Ok(None);
    }
    let file = crate::files::open_regular(path)?;
    let len = file.metadata()?.len();
    // A window of the file from `base`; consecutive windows overlap by the 12 bytes an
    // element header takes, so no header is split between two of them.
    const OVERLAP: u64 = 12;
    let mut buf = vec![0u8; SCAN_CHUNK];
    let mut base = 132.min(len);
    while base < len {
        let n = ((len - base) as usize).min(SCAN_CHUNK);
        file.read_exact_at(&mut buf[..n], base)?;
        let bytes = &buf[..n];
        let last_window = base + n as u64 >= len;
        let mut from = 0;
        while let Some(i) = bytes[from..].windows(4).position(|w| w == tag) {
            let at = from + i;
            let rest = &bytes[at + 4..];
            // Near the window's end the element header may continue in the next one.
            if rest.len() < 8 && !last_window {
                break;
            }
            let explicit = rest.len() >= 8
                && (rest[..2] == *b"OW" || rest[..2] == *b"OB")
                && rest[2..4] == [0, 0]
                && rest[4..8] == len_bytes;
            if explicit {
                return Ok(Some(base + at as u64 + 12));
            }
            if rest.len() >= 4 && rest[..4] == len_bytes {
                return Ok(Some(base + at as u64 + 8));
            }
            from = at + 1;
        }
        if last_window {
            break;
        }
        base += n as u64 - OVERLAP;
    }
    Ok(None)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Parses the series in the folder `path` (or the folder of the file `path`).
pub fn open(path: &Path) -> Result<Imported, ImportError> {
    // A file named is one of the series: it is said by name when it is
    // missing or no DICOM file (not as its folder holding none).
    if !path.is_dir() {
        crate::files::check_regular(path).map_err(|e| ImportError::new(path, e))?;
        if !has_dicm_marker(path) {
            return Err(ImportError::new(path, ImportErrorKind::NotDicom));
        }
    }
    let dir = series_dir(path);
    let at_dir = |k: ImportErrorKind| ImportError::new(&dir, k);
    let (plain, folders): (Vec<PathBuf>, Vec<PathBuf>) = std::fs::read_dir(&dir)
        .map_err(|e| at_dir(e.into()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() || p.is_dir())
        .partition(|p| p.is_file());
    let plain_count = plain.len();
    let mut files: Vec<PathBuf> = plain.into_iter().filter(|p| has_dicm_marker(p)).collect();
    files.sort();
    if files.is_empty() {
        return Err(at_dir(ImportErrorKind::NoDicomFiles {
            files: plain_count,
            folders: folders.len(),
        }));
    }
    let mut slices = Vec::with_capacity(files.len());
    for f in &files {
        slices.push(read_slice(f).map_err(|k| ImportError::new(f, k))?);
    }
    let first = slices[0].clone();
    for s in &slices[1..] {
        let mismatch = |what: String| ImportError::new(&s.path, header_error(F, what));
        if s.series != first.series {
            return Err(mismatch(format!(
                "belongs to series {} but {} belongs to {}: give a folder of one series",
                s.series,
                first.path.display(),
                first.series
            )));
        }
        if (s.rows, s.columns, s.sample, s.endian)
            != (first.rows, first.columns, first.sample, first.endian)
        {
            return Err(mismatch(format!(
                "is {}x{} {} but {} is {}x{} {}",
                s.columns,
                s.rows,
                s.sample,
                first.path.display(),
                first.columns,
                first.rows,
                first.sample
            )));
        }
    }
    // Sort: by position along the slice normal, else instance number, else name.
    let normal = first.orientation.map(|o| {
        let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
        [
            r[1] * c[2] - r[2] * c[1],
            r[2] * c[0] - r[0] * c[2],
            r[0] * c[1] - r[1] * c[0],
        ]
    });
    let along = |s: &Slice| normal.zip(s.position).map(|(n, p)| dot(n, p));
    if slices.iter().all(|s| along(s).is_some()) {
        slices.sort_by(|a, b| along(a).unwrap_or(0.0).total_cmp(&along(b).unwrap_or(0.0)));
    } else if slices.iter().all(|s| s.instance.is_some()) {
        slices.sort_by_key(|s| s.instance);
    }
    let mut dz = None;
    if slices.len() > 1 && slices.iter().all(|s| along(s).is_some()) {
        let pos: Vec<f64> = slices.iter().map(|s| along(s).unwrap_or(0.0)).collect();
        let gaps: Vec<f64> = pos.windows(2).map(|w| w[1] - w[0]).collect();
        let mean = (pos[pos.len() - 1] - pos[0]) / gaps.len() as f64;
        // Gaps are judged against the median, which a missing slice does not move.
        let mut sorted = gaps.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        if median.abs() <= 1e-6 {
            // (Else the z spacing would be 0, refused without saying why.)
            let first_repeat = gaps.iter().position(|g| g.abs() <= 1e-6).unwrap_or(0);
            return Err(ImportError::new(
                &slices[first_repeat + 1].path,
                header_error(
                    F,
                    format!(
                        "{} of the {} slices lie at the position of the slice before them along the slice normal: not a volume's slices (one slice repeated, or several series or echoes in one folder?)",
                        gaps.iter().filter(|g| g.abs() <= 1e-6).count(),
                        slices.len()
                    ),
                ),
            ));
        }
        if let Some((i, g)) = gaps
            .iter()
            .enumerate()
            .find(|(_, g)| (*g - median).abs() > 0.05 * median.abs().max(1e-6))
        {
            return Err(ImportError::new(
                &slices[i + 1].path,
                header_error(
                    F,
                    format!(
                        "slices are not evenly spaced: a gap of {g:.4} mm before this slice where the median gap is {median:.4} mm (a missing or duplicate slice?)"
                    ),
                ),
            ));
        }
        dz = Some(mean);
    }
    let sizes = [
        u64::from(first.columns),
        u64::from(first.rows),
        slices.len() as u64,
    ];
    let dims = check_dims(F, &sizes).map_err(at_dir)?;
    let [row_spacing, col_spacing] = first.pixel_spacing.unwrap_or([1.0, 1.0]);
    let spacing = [
        check_spacing(F, 0, col_spacing).map_err(at_dir)?,
        check_spacing(F, 1, row_spacing).map_err(at_dir)?,
        check_spacing(F, 2, dz.or(first.between).unwrap_or(1.0)).map_err(at_dir)?,
    ];
    // Patient placement: x along the rows (Image Orientation's first cosine), y down
    // the columns, z along the slice normal in sorted order; the origin is the
    // first sorted slice's Image Position.
    let placement = first
        .orientation
        .zip(normal)
        .zip(slices[0].position)
        .and_then(|((o, n), origin)| {
            let step = |v: [f64; 3], s: f32| v.map(|c| c * f64::from(s));
            let steps = [
                step([o[0], o[1], o[2]], spacing[0]),
                step([o[3], o[4], o[5]], spacing[1]),
                step(n, spacing[2]),
            ];
            Orientation::from_steps(PatientSpace::Lps, steps, origin).ok()
        })
        .map(|(placed, _)| placed);
    Ok(Imported {
        orientation: placement,
        path: dir.clone(),
        format: F,
        dims,
        spacing,
        sample: first.sample,
        endian: first.endian,
        data_path: dir,
        data_offset: 0,
        skip_after_decode: 0,
        compressed_size: None,
        encoding: Encoding::Slices,
        scaling: first.scaling,
        unit: first.unit.clone(),
        slices: slices
            .into_iter()
            .map(|s| (s.path, s.pixel_offset))
            .collect(),
    })
}
