//! MetaImage (`.mha` with attached data, `.mhd` + a detached data file): a text
//! header of `Key = Value` lines ending with `ElementDataFile`.
//!
//! Supported: `NDims = 3` (or more, the further dimensions of one sample each),
//! `DimSize`, `ElementType` `MET_UCHAR`, `MET_SHORT`,
//! `MET_USHORT`, `MET_FLOAT`, one channel, `ElementSpacing` (or `ElementSize`),
//! `BinaryDataByteOrderMSB`/`ElementByteOrderMSB`, `CompressedData` (zlib),
//! `HeaderSize` (bytes to skip in a detached file, `-1` = data at its end), and
//! `ElementDataFile = LOCAL` or one file name (relative to the header's directory).
//! `TransformMatrix` (or `Rotation`/`Orientation`: the directions of axes x, y, z one
//! after the other, as ITK writes them) and `Offset` (or `Position`/`Origin`) give
//! the orientation in ITK's patient space, LPS; `AnatomicalOrientation` is read
//! past, as ITK does.

use std::path::Path;

use super::{
    Encoding, ImportError, ImportErrorKind, ImportFormat, Imported, check_dims, check_spacing,
    data_at_end, header_error, read_text_header, unsupported,
};
use crate::io::{Endian, RawType};
use crate::volume::{Orientation, PatientSpace};

const F: ImportFormat = ImportFormat::MetaImage;

/// The largest header read.
pub const MAX_HEADER_BYTES: usize = 1 << 20;

/// Where a MetaImage header says the samples are.
#[derive(Clone, Debug, PartialEq)]
pub enum DataFile {
    /// `LOCAL`: right after the `ElementDataFile` line.
    Local,
    /// Another file, relative to the header's directory (or absolute).
    Detached(String),
}

/// The fields of a MetaImage header this reader uses.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaHeader {
    /// `DimSize`, fastest axis first.
    pub dims: [u32; 3],
    /// `ElementSpacing` (1 where absent).
    pub spacing: [f32; 3],
    /// `ElementType`.
    pub sample: RawType,
    /// Byte order.
    pub endian: Endian,
    /// Whether the data is a zlib stream.
    pub compressed: bool,
    /// `CompressedDataSize` of compressed data: the stream's length in bytes.
    pub compressed_size: Option<u64>,
    /// Where the samples are.
    pub data_file: DataFile,
    /// `HeaderSize` of a detached file: `Some(n)` bytes to skip, `None` for `-1`.
    pub header_size: Option<u64>,
    /// Bytes up to and including the `ElementDataFile` line (attached data offset).
    pub header_len: usize,
    /// "HU" for `Modality = MET_MOD_CT`, else empty.
    pub unit: String,
    /// Where the volume lies in the patient (LPS): from `TransformMatrix` and
    /// `Offset`, when the header has either.
    pub orientation: Option<Orientation>,
}

fn parse_bool(key: &str, v: &str) -> Result<bool, ImportErrorKind> {
    match v.to_ascii_lowercase().as_str() {
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        _ => Err(header_error(
            F,
            format!("{key} `{v}` is neither True nor False"),
        )),
    }
}

fn parse_numbers(key: &str, v: &str) -> Result<Vec<f64>, ImportErrorKind> {
    v.split_whitespace()
        .map(|p| {
            p.parse::<f64>()
                .map_err(|_| header_error(F, format!("{key} value `{p}` is not a number")))
        })
        .collect()
}

/// Parses a MetaImage header from the start of `bytes` (which may go on into the
/// data). A pure function of the bytes: it never panics, whatever they hold.
pub fn parse_header(bytes: &[u8]) -> Result<MetaHeader, ImportErrorKind> {
    let mut pos = 0;
    let mut fields: Vec<(String, String)> = Vec::new();
    let mut header_len = None;
    while pos < bytes.len().min(MAX_HEADER_BYTES) {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        let line = std::str::from_utf8(raw)
            .map_err(|_| header_error(F, format!("header line {} is not text", fields.len() + 1)))?
            .trim();
        if line.is_empty() {
            continue;
        }
        let (key, value) = line.split_once('=').ok_or_else(|| {
            header_error(
                F,
                format!("line {} `{line}` is not `Key = Value`", fields.len() + 1),
            )
        })?;
        let key = key.trim().to_string();
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(header_error(F, format!("`{key}` is not a MetaImage key")));
        }
        if fields.iter().any(|(k, _)| k.eq_ignore_ascii_case(&key)) {
            // Which would count? Readers differ: said, not guessed.
            return Err(header_error(F, format!("the key `{key}` is given twice")));
        }
        let done = key.eq_ignore_ascii_case("ElementDataFile");
        fields.push((key, value.trim().to_string()));
        if done {
            header_len = Some(pos);
            break;
        }
    }
    let get = |k: &str| {
        fields
            .iter()
            .find(|(key, _)| key.eq_ignore_ascii_case(k))
            .map(|(_, v)| v.as_str())
    };
    let need = |k: &str| {
        get(k).ok_or_else(|| header_error(F, format!("the required key `{k}` is missing")))
    };
    if let Some(t) = get("ObjectType")
        && !t.eq_ignore_ascii_case("Image")
    {
        return Err(unsupported(
            F,
            format!("ObjectType `{t}` (only Image is read)"),
        ));
    }
    let ndims = need("NDims")?;
    // More dimensions (ITK's 4D images) are read when the others hold one
    // sample each: a volume at one time.
    let n = match ndims.parse::<usize>() {
        Ok(n) if (3..=16).contains(&n) => n,
        _ => {
            return Err(unsupported(
                F,
                format!("NDims {ndims} (only 3D volumes are read)"),
            ));
        }
    };
    let sizes = parse_numbers("DimSize", need("DimSize")?)?;
    if sizes.len() != n || sizes.iter().any(|s| s.fract() != 0.0 || *s < 0.0) {
        return Err(header_error(
            F,
            format!("DimSize `{}` is not {n} whole numbers", need("DimSize")?),
        ));
    }
    if let Some((axis, size)) = sizes.iter().enumerate().skip(3).find(|(_, s)| **s != 1.0) {
        return Err(unsupported(
            F,
            format!(
                "NDims {n}: dimension {axis} holds {size} samples (a series of volumes); only \
                 3D volumes are read, or files whose further dimensions hold one sample each"
            ),
        ));
    }
    let dims = check_dims(F, &sizes[..3].iter().map(|&s| s as u64).collect::<Vec<_>>())?;
    let sample = match need("ElementType")? {
        "MET_UCHAR" => RawType::U8,
        "MET_SHORT" => RawType::I16,
        "MET_USHORT" => RawType::U16,
        "MET_FLOAT" => RawType::F32,
        other => {
            return Err(unsupported(
                F,
                format!(
                    "ElementType `{other}` (supported: MET_UCHAR, MET_SHORT, MET_USHORT, MET_FLOAT)"
                ),
            ));
        }
    };
    if let Some(c) = get("ElementNumberOfChannels")
        && c != "1"
    {
        return Err(unsupported(
            F,
            format!("{c} channels per voxel (one is read)"),
        ));
    }
    let mut spacing = [1f32; 3];
    if let Some(v) = get("ElementSpacing").or(get("ElementSize")) {
        let values = parse_numbers("ElementSpacing", v)?;
        if values.len() != n {
            return Err(header_error(
                F,
                format!(
                    "ElementSpacing has {} values for {n} dimensions",
                    values.len()
                ),
            ));
        }
        for (axis, &s) in values.iter().take(3).enumerate() {
            spacing[axis] = check_spacing(F, axis, s)?;
        }
    }
    let orientation = orientation(&get, spacing, n)?;
    let msb = match get("BinaryDataByteOrderMSB").or(get("ElementByteOrderMSB")) {
        Some(v) => parse_bool("BinaryDataByteOrderMSB", v)?,
        None => false,
    };
    if let Some(v) = get("BinaryData")
        && !parse_bool("BinaryData", v)?
    {
        return Err(unsupported(F, "ASCII data (BinaryData = False)"));
    }
    let compressed = match get("CompressedData") {
        Some(v) => parse_bool("CompressedData", v)?,
        None => false,
    };
    let compressed_size = match get("CompressedDataSize") {
        Some(v) if compressed => Some(v.parse::<u64>().map_err(|_| {
            header_error(
                F,
                format!("CompressedDataSize `{v}` is not a whole number of bytes"),
            )
        })?),
        _ => None,
    };
    let data_file = match need("ElementDataFile")? {
        "LOCAL" | "Local" | "local" => DataFile::Local,
        f if f.starts_with("LIST") || f.split_whitespace().count() > 1 || f.contains('%') => {
            return Err(unsupported(
                F,
                format!("ElementDataFile `{f}` (one file or LOCAL is read)"),
            ));
        }
        f => DataFile::Detached(f.to_string()),
    };
    let header_size = match get("HeaderSize") {
        None => Some(0),
        Some("-1") => None,
        Some(v) => Some(v.parse::<u64>().map_err(|_| {
            header_error(F, format!("HeaderSize `{v}` is not -1 or a whole number"))
        })?),
    };
    if header_size.is_none() && compressed {
        return Err(header_error(
            F,
            "HeaderSize -1 cannot be used with compressed data",
        ));
    }
    Ok(MetaHeader {
        dims,
        spacing,
        sample,
        endian: if msb { Endian::Big } else { Endian::Little },
        compressed,
        compressed_size,
        data_file,
        header_size,
        header_len: header_len.unwrap_or(bytes.len()),
        orientation,
        unit: match get("Modality") {
            Some("MET_MOD_CT") => crate::volume::HOUNSFIELD.to_string(),
            _ => String::new(),
        },
    })
}

/// Parses the MetaImage file at `path` (`.mha` or `.mhd`).
pub fn open(path: &Path) -> Result<Imported, ImportError> {
    let bytes = read_text_header(path, MAX_HEADER_BYTES)?;
    let h = parse_header(&bytes).map_err(|e| ImportError::new(path, e))?;
    let sample_bytes =
        h.dims.iter().map(|&d| u64::from(d)).product::<u64>() * h.sample.size() as u64;
    let (data_path, data_offset) = match &h.data_file {
        DataFile::Local => (path.to_path_buf(), h.header_len as u64),
        DataFile::Detached(name) => {
            let data_path = path.parent().unwrap_or(Path::new(".")).join(name);
            let offset = match h.header_size {
                Some(n) => n,
                None => data_at_end(path, &data_path, sample_bytes, 0)?,
            };
            (data_path, offset)
        }
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
        skip_after_decode: 0,
        compressed_size: h.compressed_size,
        encoding: if h.compressed {
            Encoding::Zlib
        } else {
            Encoding::Raw
        },
        scaling: None,
        unit: h.unit,
        orientation: h.orientation,
        slices: Vec::new(),
    })
}

/// The orientation from `TransformMatrix` (axis directions, one after the other)
/// and `Offset`, when the header gives either; a matrix that makes no volume is
/// passed over (the file opens as before).
fn orientation<'a>(
    get: &dyn Fn(&str) -> Option<&'a str>,
    spacing: [f32; 3],
    n: usize,
) -> Result<Option<Orientation>, ImportErrorKind> {
    let matrix = get("TransformMatrix")
        .or(get("Rotation"))
        .or(get("Orientation"));
    let offset = get("Offset").or(get("Position")).or(get("Origin"));
    if matrix.is_none() && offset.is_none() {
        return Ok(None);
    }
    let m = match matrix {
        Some(v) => parse_numbers("TransformMatrix", v)?,
        None => (0..n * n)
            .map(|i| f64::from(u8::from(i % (n + 1) == 0)))
            .collect(),
    };
    let o = match offset {
        Some(v) => parse_numbers("Offset", v)?,
        None => vec![0.0; n],
    };
    if m.len() != n * n || o.len() != n {
        return Err(header_error(
            F,
            format!(
                "TransformMatrix needs {} numbers and Offset {n} for {n} dimensions",
                n * n
            ),
        ));
    }
    // The space part: the first three axes' first three components.
    let m: [f64; 9] = std::array::from_fn(|i| m[n * (i / 3) + i % 3]);
    let o = [o[0], o[1], o[2]];
    let steps = std::array::from_fn(|axis| {
        std::array::from_fn(|c| m[3 * axis + c] * f64::from(spacing[axis]))
    });
    Ok(Orientation::from_steps(PatientSpace::Lps, steps, o)
        .ok()
        .map(|(placed, _)| placed))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: &str = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
        CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 0 0 0\n\
        ElementSpacing = 0.5 1 2\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\nDATA";

    #[test]
    fn parses_a_typical_header() {
        let h = parse_header(BASE.as_bytes()).unwrap();
        assert_eq!(h.dims, [4, 3, 2]);
        assert_eq!(h.spacing, [0.5, 1.0, 2.0]);
        assert_eq!(h.sample, RawType::I16);
        assert_eq!(h.data_file, DataFile::Local);
        assert_eq!(h.header_len, BASE.len() - 4);
    }

    #[test]
    fn a_four_dimensional_image_of_one_time_reads_as_its_volume() {
        let oriented = BASE
            .replace(
                "TransformMatrix = 1 0 0 0 1 0 0 0 1",
                "TransformMatrix = 0 1 0 -1 0 0 0 0 1",
            )
            .replace("Offset = 0 0 0", "Offset = 3 4 5");
        let three = parse_header(oriented.as_bytes()).unwrap();
        let four = oriented
            .replace("NDims = 3", "NDims = 4")
            .replace(
                "TransformMatrix = 0 1 0 -1 0 0 0 0 1",
                "TransformMatrix = 0 1 0 0 -1 0 0 0 0 0 1 0 0 0 0 1",
            )
            .replace("Offset = 3 4 5", "Offset = 3 4 5 0")
            .replace("ElementSpacing = 0.5 1 2", "ElementSpacing = 0.5 1 2 1")
            .replace("DimSize = 4 3 2", "DimSize = 4 3 2 1");
        let h = parse_header(four.as_bytes()).unwrap();
        assert!(three.orientation.is_some());
        assert_eq!(
            (h.dims, h.spacing, h.orientation),
            (three.dims, three.spacing, three.orientation)
        );
        assert_eq!(h.header_len, four.len() - 4);
    }

    #[test]
    fn rejects_what_it_cannot_read_with_a_reason() {
        for (bad, needle) in [
            (BASE.replace("MET_SHORT", "MET_DOUBLE"), "MET_DOUBLE"),
            (BASE.replace("NDims = 3", "NDims = 2"), "NDims 2"),
            (
                BASE.replace("NDims = 3", "NDims = 4")
                    .replace("DimSize = 4 3 2", "DimSize = 4 3 2 5")
                    .replace("ElementSpacing = 0.5 1 2", "ElementSpacing = 0.5 1 2 1"),
                "dimension 3 holds 5 samples",
            ),
            (BASE.replace("DimSize = 4 3 2", "DimSize = 4 3"), "DimSize"),
            (BASE.replace("DimSize = 4 3 2", "DimSize = 4 0 2"), "size 0"),
            (BASE.replace("0.5 1 2", "0.5 nan 2"), "spacing NaN"),
            (BASE.replace("LOCAL", "LIST"), "LIST"),
            (
                BASE.replace("ElementDataFile = LOCAL\nDATA", ""),
                "`ElementDataFile` is missing",
            ),
            (
                BASE.replace("CompressedData = False", "CompressedData = Maybe"),
                "Maybe",
            ),
            ("garbage".to_string(), "Key = Value"),
            (
                BASE.replace("NDims = 3", "NDims = 3\nelementspacing = 1 1 1"),
                "the key `ElementSpacing` is given twice",
            ),
        ] {
            let err = parse_header(bad.as_bytes()).unwrap_err().to_string();
            assert!(err.contains(needle), "{bad:?}: {err}");
        }
    }
}
