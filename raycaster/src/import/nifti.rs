//! NIfTI-1 (`.nii`, `.nii.gz`, and `.hdr` + `.img` pairs): a fixed 348-byte binary
//! header.
//!
//! Read by hand rather than with the `nifti` crate: that crate loads whole volumes
//! into `ndarray`s, while conversion here must stream in bounded memory, which needs
//! only the few fields below. Supported: either byte order (detected from
//! `sizeof_hdr`), magic `n+1` (single file, data at `vox_offset`) and `ni1` (pair),
//! `dim[0]` 3 (or 4..7 with every extra dimension 1), datatypes 2 (u8), 4 (i16),
//! 512 (u16) and 16 (f32), spacing from `pixdim[1..=3]`. `scl_slope`/`scl_inter` are
//! kept as the values' units. The orientation is the sform where `sform_code > 0`,
//! else the qform where `qform_code > 0` (as nibabel's `affine`), converted from RAS
//! to LPS; the spacing is then the length of each axis step. NIfTI-2 files are
//! refused with a clear message.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::gzip::gzip_magic_at;
use super::{
    Encoding, ImportError, ImportErrorKind, ImportFormat, Imported, check_dims, check_spacing,
    header_error, unsupported,
};
use crate::io::{Endian, RawType};
use crate::volume::{MAX_AXIS, Orientation, PatientSpace};

const F: ImportFormat = ImportFormat::Nifti;

/// Length of the NIfTI-1 header.
pub const HEADER_LEN: usize = 348;

/// The fields of a NIfTI-1 header this reader uses.
#[derive(Clone, Debug, PartialEq)]
pub struct NiftiHeader {
    /// `dim[1..=3]`.
    pub dims: [u32; 3],
    /// `|pixdim[1..=3]|`.
    pub spacing: [f32; 3],
    /// From `datatype`.
    pub sample: RawType,
    /// Byte order of the header and the data.
    pub endian: Endian,
    /// `vox_offset`: where the data starts (in the `.nii`, or in the `.img` of a pair).
    pub vox_offset: u64,
    /// Whether this is a single file (`n+1`) rather than a pair (`ni1`).
    pub single_file: bool,
    /// `(scl_slope, scl_inter)` when the slope is set and not the identity.
    pub scaling: Option<(f32, f32)>,
    /// From the sform or qform, when either has a code above 0.
    pub orientation: Option<Orientation>,
}

/// Parses a NIfTI-1 header from the first bytes of a (decompressed) file.
/// A pure function of the bytes: it never panics, whatever they hold.
pub fn parse_header(bytes: &[u8]) -> Result<NiftiHeader, ImportErrorKind> {
    if bytes.len() < HEADER_LEN {
        return Err(header_error(
            F,
            format!(
                "the header needs {HEADER_LEN} bytes but the file has {}",
                bytes.len()
            ),
        ));
    }
    let b = |o: usize, n: usize| &bytes[o..o + n];
    let le = i32::from_le_bytes(b(0, 4).try_into().unwrap_or_default());
    let be = i32::from_be_bytes(b(0, 4).try_into().unwrap_or_default());
    let endian = match (le, be) {
        (348, _) => Endian::Little,
        (_, 348) => Endian::Big,
        (540, _) | (_, 540) => {
            return Err(unsupported(
                F,
                "NIfTI-2 (540-byte header); only NIfTI-1 is read",
            ));
        }
        _ => {
            return Err(header_error(
                F,
                format!("sizeof_hdr is {le}, not 348: not a NIfTI-1 file"),
            ));
        }
    };
    let big = endian == Endian::Big;
    let i16_at = |o: usize| {
        let a = [bytes[o], bytes[o + 1]];
        if big {
            i16::from_be_bytes(a)
        } else {
            i16::from_le_bytes(a)
        }
    };
    let f32_at = |o: usize| {
        let a = [bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]];
        if big {
            f32::from_be_bytes(a)
        } else {
            f32::from_le_bytes(a)
        }
    };
    let single_file = match b(344, 4) {
        b"n+1\0" => true,
        b"ni1\0" => false,
        m => {
            return Err(header_error(
                F,
                format!(
                    "magic {:?} is neither \"n+1\" nor \"ni1\" (ANALYZE 7.5 files are not read)",
                    String::from_utf8_lossy(m)
                ),
            ));
        }
    };
    let dim: Vec<i16> = (0..8).map(|i| i16_at(40 + 2 * i)).collect();
    let ndim = dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(header_error(F, format!("dim[0] = {ndim} is outside 1..=7")));
    }
    if ndim < 3 {
        return Err(unsupported(
            F,
            format!("{ndim}-dimensional images (3D volumes are read)"),
        ));
    }
    if let Some(extra) = dim[4..=ndim as usize].iter().find(|&&d| d != 1) {
        return Err(unsupported(
            F,
            format!(
                "a {ndim}-dimensional image with {extra} entries beyond the third dimension (one 3D volume is read)"
            ),
        ));
    }
    if let Some(axis) = (1..=3).find(|&i| dim[i] < 0) {
        return Err(header_error(
            F,
            format!(
                "dim[{axis}] = {} is negative (a size is 1..={MAX_AXIS})",
                dim[axis]
            ),
        ));
    }
    let sizes: Vec<u64> = dim[1..=3].iter().map(|&d| d as u64).collect();
    let dims = check_dims(F, &sizes)?;
    let datatype = i16_at(70);
    let sample = match datatype {
        2 => RawType::U8,
        4 => RawType::I16,
        512 => RawType::U16,
        16 => RawType::F32,
        other => {
            let name = match other {
                1 => "binary",
                8 => "int32",
                32 => "complex64",
                64 => "float64",
                128 => "rgb24",
                256 => "int8",
                768 => "uint32",
                1024 => "int64",
                1280 => "uint64",
                2304 => "rgba32",
                _ => "unknown",
            };
            return Err(unsupported(
                F,
                format!(
                    "datatype {other} ({name}); supported: 2 (uint8), 4 (int16), 512 (uint16), 16 (float32)"
                ),
            ));
        }
    };
    let mut spacing = [1f32; 3];
    for (axis, s) in spacing.iter_mut().enumerate() {
        let v = f32_at(76 + 4 * (axis + 1));
        // Writers leave 0 where they have no spacing; treat it as 1.
        *s = if v == 0.0 {
            1.0
        } else {
            check_spacing(F, axis, f64::from(v))?
        };
    }
    let vox_offset = f32_at(108);
    if !(vox_offset.is_finite()
        && vox_offset >= 0.0
        && vox_offset.fract() == 0.0
        && vox_offset < 1e12)
    {
        return Err(header_error(
            F,
            format!("vox_offset {vox_offset} is not a byte offset"),
        ));
    }
    let vox_offset = vox_offset as u64;
    if single_file && vox_offset < HEADER_LEN as u64 {
        return Err(header_error(
            F,
            format!("vox_offset {vox_offset} lies inside the 348-byte header"),
        ));
    }
    let orientation = orientation(&i16_at, &f32_at, &mut spacing)?;
    let (slope, inter) = (f32_at(112), f32_at(116));
    let scaling = (slope.is_finite() && slope != 0.0 && (slope != 1.0 || inter != 0.0))
        .then_some((slope, inter));
    Ok(NiftiHeader {
        dims,
        spacing,
        sample,
        endian,
        vox_offset,
        single_file,
        scaling,
        orientation,
    })
}

/// The voxel-to-patient map of the header: the sform (`sform_code > 0`), else the
/// qform (`qform_code > 0`), else none; a form that makes no volume (zero or
/// coplanar axes, NaN) is passed over, as files with a broken form still open as
/// before. Where there is one, `spacing` becomes the length of its axis steps, so
/// voxels land where the affine puts them.
fn orientation(
    i16_at: &dyn Fn(usize) -> i16,
    f32_at: &dyn Fn(usize) -> f32,
    spacing: &mut [f32; 3],
) -> Result<Option<Orientation>, ImportErrorKind> {
    let f = |o: usize| f64::from(f32_at(o));
    let sform = || {
        let row = |o: usize| [f(o), f(o + 4), f(o + 8), f(o + 12)];
        let rows = [row(280), row(296), row(312)];
        let steps: [[f64; 3]; 3] = std::array::from_fn(|c| std::array::from_fn(|r| rows[r][c]));
        (steps, [rows[0][3], rows[1][3], rows[2][3]])
    };
    let qform = || {
        let (mut b, mut c, mut d) = (f(256), f(260), f(264));
        // A unit quaternion's b² + c² + d² is at most 1. Past it by a rounding
        // error (a half turn, a = 0): (b, c, d) normalised, as nifti1_io does.
        // Past it by more the form is broken (a rotation that also scales):
        // NaN, which no volume's axes are, so the form is passed over.
        let norm = b * b + c * c + d * d;
        let a = if norm <= 1.0 {
            (1.0 - norm).sqrt()
        } else if norm <= 1.0 + 1e-3 {
            let s = norm.sqrt().recip();
            (b, c, d) = (b * s, c * s, d * s);
            0.0
        } else {
            f64::NAN
        };
        let rotation = [
            [
                a * a + b * b - c * c - d * d,
                2.0 * (b * c - a * d),
                2.0 * (b * d + a * c),
            ],
            [
                2.0 * (b * c + a * d),
                a * a + c * c - b * b - d * d,
                2.0 * (c * d - a * b),
            ],
            [
                2.0 * (b * d - a * c),
                2.0 * (c * d + a * b),
                a * a + d * d - c * c - b * b,
            ],
        ];
        let qfac = if f(76) < 0.0 { -1.0 } else { 1.0 };
        let pixdim = [f(80), f(84), f(88) * qfac];
        let steps =
            std::array::from_fn(|col| std::array::from_fn(|row| rotation[row][col] * pixdim[col]));
        (steps, [f(268), f(272), f(276)])
    };
    let forms = [(i16_at(254) > 0, sform()), (i16_at(252) > 0, qform())];
    let Some((orientation, lengths)) =
        forms
            .into_iter()
            .filter(|(set, _)| *set)
            .find_map(|(_, (steps, origin))| {
                Orientation::from_steps(PatientSpace::Ras, steps, origin).ok()
            })
    else {
        return Ok(None);
    };
    for (axis, (s, len)) in spacing.iter_mut().zip(lengths).enumerate() {
        *s = check_spacing(F, axis, len)?;
    }
    Ok(Some(orientation))
}

/// Decompressed bytes read past a `.nii.gz` header that does not parse, to see
/// whether the stream is corrupt.
const CORRUPTION_LOOKAHEAD: u64 = 16 << 20;

/// Parses the NIfTI-1 file at `path` (`.nii`, `.nii.gz`, or the `.hdr` of a pair).
pub fn open(path: &Path) -> Result<Imported, ImportError> {
    let at = |e: ImportErrorKind| ImportError::new(path, e);
    let gz = gzip_magic_at(path, 0).map_err(|e| at(e.into()))?;
    let file = crate::files::open_regular(path).map_err(|e| at(e.into()))?;
    let mut head = Vec::with_capacity(HEADER_LEN);
    let h = if gz {
        let mut stream = super::gzip::GzipMembers::new(std::io::BufReader::new(file));
        (&mut stream)
            .take(HEADER_LEN as u64)
            .read_to_end(&mut head)
            .map_err(|e| at(ImportErrorKind::Compressed(e)))?;
        parse_header(&head).map_err(|e| {
            // A header of nonsense from a stream corrupt near its start (the
            // decoder finds out a little later): said as the corruption it
            // is, where reading on finds it.
            let mut ahead = (&mut stream).take(CORRUPTION_LOOKAHEAD);
            match std::io::copy(&mut ahead, &mut std::io::sink()) {
                Err(corrupt) => at(ImportErrorKind::Compressed(corrupt)),
                Ok(_) => at(e),
            }
        })?
    } else {
        file.take(HEADER_LEN as u64)
            .read_to_end(&mut head)
            .map_err(|e| at(e.into()))?;
        parse_header(&head).map_err(at)?
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let pair_header = name.ends_with(".hdr") || name.ends_with(".hdr.gz");
    if !h.single_file && !pair_header {
        return Err(at(header_error(
            F,
            "magic \"ni1\" says the image is in a separate .img file, but this is no .hdr file (a .nii file's magic is \"n+1\")",
        )));
    }
    let data_path = if h.single_file {
        path.to_path_buf()
    } else {
        image_path(path)
    };
    let encoding = if !h.single_file {
        // (A missing .img is said as the header's data file, as NRRD's and
        // MetaImage's are.)
        if gzip_magic_at(&data_path, 0).map_err(|e| super::data_file_error(path, &data_path, e))? {
            Encoding::Gzip
        } else {
            Encoding::Raw
        }
    } else if gz {
        Encoding::Gzip
    } else {
        Encoding::Raw
    };
    let (data_offset, skip_after_decode) = match encoding {
        Encoding::Raw => (h.vox_offset, 0),
        _ => (0, h.vox_offset),
    };
    Ok(Imported {
        path: path.to_path_buf(),
        format: F,
        dims: h.dims,
        spacing: h.spacing,
        sample: h.sample,
        endian: h.endian,
        data_path,
        data_offset,
        skip_after_decode,
        compressed_size: None,
        encoding,
        scaling: h.scaling,
        unit: String::new(),
        orientation: h.orientation,
        slices: Vec::new(),
    })
}

/// The `.img` beside a `.hdr` (`.img.gz` when only that exists).
fn image_path(hdr: &Path) -> PathBuf {
    let name = hdr
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let stem = name
        .strip_suffix(".gz")
        .unwrap_or(&name)
        .trim_end_matches(".hdr")
        .trim_end_matches(".HDR")
        .to_string();
    let img = hdr.with_file_name(format!("{stem}.img"));
    let img_gz = hdr.with_file_name(format!("{stem}.img.gz"));
    if !img.exists() && img_gz.exists() {
        img_gz
    } else {
        img
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn header(datatype: i16, dims: [i16; 3], pixdim: [f32; 3]) -> Vec<u8> {
        let mut h = vec![0u8; 352];
        h[0..4].copy_from_slice(&348i32.to_le_bytes());
        let dim = [3, dims[0], dims[1], dims[2], 1, 1, 1, 1];
        for (i, d) in dim.iter().enumerate() {
            h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
        }
        h[70..72].copy_from_slice(&datatype.to_le_bytes());
        for (i, p) in [1.0, pixdim[0], pixdim[1], pixdim[2]].iter().enumerate() {
            h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
        }
        h[108..112].copy_from_slice(&352f32.to_le_bytes());
        h[344..348].copy_from_slice(b"n+1\0");
        h
    }

    #[test]
    fn a_gzip_stream_corrupt_near_its_start_is_said_as_corrupt_not_as_a_bad_header() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("corrupt.nii.gz");
        let mut data = header(2, [16, 16, 16], [1.0; 3]);
        data.extend((0..16 * 16 * 16u32).map(|i| (i * 7 % 256) as u8));
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        gz.write_all(&data).unwrap();
        let good = gz.finish().unwrap();
        std::fs::write(&path, &good).unwrap();
        assert_eq!(open(&path).unwrap().dims, [16; 3]);
        // Every byte of the deflate stream flipped (before: some said as
        // "invalid NIfTI-1 header: magic \"\0\0\0\0\" is neither …", the
        // header decoded from a corrupt stream before its decoder noticed).
        for at in 10..good.len() - 8 {
            let mut bad = good.clone();
            bad[at] ^= 0xff;
            std::fs::write(&path, &bad).unwrap();
            // (A header that decoded whole: the samples' read finds it.)
            let e = match open(&path) {
                Ok(_) => crate::import::open_volume_any(&path, 1 << 30)
                    .map(|_| ())
                    .unwrap_err()
                    .to_string(),
                Err(e) => e.to_string(),
            };
            assert!(
                e.contains("the compressed data is truncated or corrupt"),
                "byte {at}: {e}"
            );
        }
    }

    #[test]
    fn a_value_scaling_beyond_f32_is_refused_and_one_within_it_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scaled.nii");
        let write = |slope: f32, inter: f32| {
            let mut h = header(4, [2, 2, 2], [1.0; 3]);
            h[112..116].copy_from_slice(&slope.to_le_bytes());
            h[116..120].copy_from_slice(&inter.to_le_bytes());
            h.extend_from_slice(&[1; 16]);
            std::fs::write(&path, &h).unwrap();
        };
        // (Before: accepted, its values ±∞ and "max 7.68e40" in the file.)
        write(3e38, 3e38);
        let e = crate::import::open(&path).unwrap_err().to_string();
        assert!(
            e.contains("the value scaling (slope 3e38, intercept 3e38) takes stored i16 value")
                && e.contains("beyond the ±3.4e38 values are read in"),
            "{e}"
        );
        write(1.1e34, -5.0);
        let e = crate::import::open(&path).unwrap_err().to_string();
        assert!(e.contains("stored i16 value -32768 to -3.6"), "{e}");
        write(2.0, -1024.0);
        let imported = crate::import::open(&path).unwrap();
        assert_eq!(imported.scaling, Some((2.0, -1024.0)));
    }

    #[test]
    fn a_pair_magic_in_a_single_file_is_named_as_such() {
        let dir = tempfile::tempdir().unwrap();
        let mut h = header(2, [2, 2, 2], [1.0; 3]);
        h[344..348].copy_from_slice(b"ni1\0");
        h.extend_from_slice(&[0; 8]);
        let nii = dir.path().join("pair.nii");
        std::fs::write(&nii, &h).unwrap();
        let e = open(&nii).unwrap_err().to_string();
        assert!(
            e.contains(
                "magic \"ni1\" says the image is in a separate .img file, but this is no .hdr file"
            ),
            "{e}"
        );
        // As a .hdr beside its .img it opens.
        let hdr = dir.path().join("pair.hdr");
        std::fs::write(&hdr, &h[..348]).unwrap();
        std::fs::write(dir.path().join("pair.img"), [0u8; 8]).unwrap();
        h.truncate(348);
        h[108..112].copy_from_slice(&0f32.to_le_bytes());
        std::fs::write(&hdr, &h).unwrap();
        assert_eq!(open(&hdr).unwrap().dims, [2, 2, 2]);
    }

    #[test]
    fn a_quaternion_past_unit_length_is_normalised_or_passed_over() {
        let with_qform = |bcd: [f32; 3]| {
            let mut h = header(2, [3, 4, 5], [1.0, 2.0, 3.0]);
            h[252..254].copy_from_slice(&1i16.to_le_bytes());
            for (i, q) in bcd.iter().enumerate() {
                h[256 + 4 * i..260 + 4 * i].copy_from_slice(&q.to_le_bytes());
            }
            parse_header(&h).unwrap()
        };
        // b = c = d = 1: no rotation (it would scale the axes threefold).
        let broken = with_qform([1.0, 1.0, 1.0]);
        assert!(broken.orientation.is_none());
        assert_eq!(broken.spacing, [1.0, 2.0, 3.0]);
        // A half turn about z written with a rounding error: a rotation, the
        // spacing kept.
        let half_turn = with_qform([0.0, 0.0, 1.000_1]);
        assert!(half_turn.orientation.is_some());
        for (s, want) in half_turn.spacing.iter().zip([1.0, 2.0, 3.0]) {
            assert!((s - want).abs() < 1e-4, "{:?}", half_turn.spacing);
        }
    }

    #[test]
    fn parses_either_byte_order() {
        let h = parse_header(&header(4, [3, 4, 5], [0.5, 1.0, 2.0])).unwrap();
        assert_eq!(h.dims, [3, 4, 5]);
        assert_eq!(h.spacing, [0.5, 1.0, 2.0]);
        assert_eq!(h.sample, RawType::I16);
        assert_eq!(h.vox_offset, 352);
        assert!(h.single_file);
        // The same header big-endian: swap every field we read.
        let mut be = header(4, [3, 4, 5], [0.5, 1.0, 2.0]);
        for (o, n) in [(0, 4), (70, 2), (108, 4)]
            .into_iter()
            .chain((0..8).map(|i| (40 + 2 * i, 2)))
            .chain((0..8).map(|i| (76 + 4 * i, 4)))
        {
            be[o..o + n].reverse();
        }
        let hb = parse_header(&be).unwrap();
        assert_eq!(hb.endian, Endian::Big);
        assert_eq!(
            (hb.dims, hb.spacing, hb.sample),
            (h.dims, h.spacing, h.sample)
        );
    }

    #[test]
    fn rejects_what_it_cannot_read_with_a_reason() {
        let good = header(2, [3, 4, 5], [1.0; 3]);
        let mut cases: Vec<(Vec<u8>, &str)> = vec![
            (header(64, [3, 4, 5], [1.0; 3]), "float64"),
            (header(2, [3, 0, 5], [1.0; 3]), "size 0"),
            (header(2, [3, -4, 5], [1.0; 3]), "dim[2] = -4 is negative"),
            (header(2, [3, 4, 5], [1.0, f32::NAN, 1.0]), "spacing NaN"),
            (good[..200].to_vec(), "348 bytes"),
        ];
        let mut m = good.clone();
        m[344..348].copy_from_slice(b"abcd");
        cases.push((m, "magic"));
        let mut v2 = good.clone();
        v2[0..4].copy_from_slice(&540i32.to_le_bytes());
        cases.push((v2, "NIfTI-2"));
        let mut d4 = good.clone();
        d4[40..42].copy_from_slice(&4i16.to_le_bytes());
        d4[48..50].copy_from_slice(&7i16.to_le_bytes());
        cases.push((d4, "beyond the third"));
        let mut off = good.clone();
        off[108..112].copy_from_slice(&100f32.to_le_bytes());
        cases.push((off, "inside the 348-byte header"));
        for (bytes, needle) in cases {
            let err = parse_header(&bytes).unwrap_err().to_string();
            assert!(err.contains(needle), "{needle}: {err}");
        }
    }
}
