//! NRRD (`.nrrd`, detached `.nhdr`): a text header of `field: value` lines.
//!
//! Supported: `NRRD0001`..`NRRD0005` magic, `dimension: 3` (or more, the other
//! axes of one sample each: a 4D file of one volume), types u8, i16, u16 and
//! f32 under any of their NRRD spellings, `raw` and `gzip` encodings, `endian`,
//! `sizes`, `spacings` or `space directions` (spacing = length of each direction
//! vector), `byte skip` (including `-1` for raw data at the end of the file),
//! `line skip`, and `data file` naming one detached file (relative to the header's
//! directory). Key/value pairs (`key:=value`) and comments are skipped. With an
//! anatomical `space` (RAS, LAS, LPS), `space directions` and `space origin` give
//! the volume's orientation in the patient.

use std::path::Path;

use super::{
    Encoding, ImportError, ImportErrorKind, ImportFormat, Imported, check_dims, check_spacing,
    data_at_end, header_error, read_text_header, unsupported,
};
use crate::io::{Endian, RawType};
use crate::volume::{Orientation, PatientSpace};

const F: ImportFormat = ImportFormat::Nrrd;

/// The largest header read (a NRRD header is a few hundred bytes).
pub const MAX_HEADER_BYTES: usize = 1 << 20;

/// Where a NRRD header says the samples are.
#[derive(Clone, Debug, PartialEq)]
pub enum DataFile {
    /// After the blank line that ends the header, in the same file.
    Attached,
    /// In another file (a path relative to the header's directory, or absolute).
    Detached(String),
}

/// The fields of a NRRD header this reader uses.
#[derive(Clone, Debug, PartialEq)]
pub struct NrrdHeader {
    /// Sizes, fastest axis first.
    pub dims: [u32; 3],
    /// Spacing per axis (1 when the header gives none).
    pub spacing: [f32; 3],
    /// Sample type.
    pub sample: RawType,
    /// Byte order (little when the type has one byte).
    pub endian: Endian,
    /// Raw or gzip.
    pub encoding: Encoding,
    /// Where the samples are.
    pub data_file: DataFile,
    /// `byte skip`: bytes before the samples (after decompression for gzip);
    /// `None` for `-1` (raw data at the end of the file).
    pub byte_skip: Option<u64>,
    /// `line skip`: lines before the samples in a detached file.
    pub line_skip: u64,
    /// Length of the header in bytes, including the blank line that ends it (the
    /// offset of attached data).
    pub header_len: usize,
    /// Where the volume lies in the patient: from an anatomical `space`, `space
    /// directions` on every axis and `space origin`.
    pub orientation: Option<Orientation>,
}

fn parse_type(s: &str) -> Result<RawType, ImportErrorKind> {
    match s {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => Ok(RawType::U8),
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            Ok(RawType::I16)
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            Ok(RawType::U16)
        }
        "float" => Ok(RawType::F32),
        other => Err(unsupported(
            F,
            format!("sample type `{other}` (supported: uchar, short, ushort, float)"),
        )),
    }
}

/// Parses a vector `(a,b,c)` of `space directions`; `none` gives `None`.
fn parse_vector(s: &str) -> Result<Option<Vec<f64>>, ImportErrorKind> {
    if s == "none" {
        return Ok(None);
    }
    let inner = s
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| header_error(F, format!("space direction `{s}` is not (x,y,z)")))?;
    inner
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| header_error(F, format!("`{p}` in space direction is not a number")))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// A `space directions` vector in the patient's three axes: three
/// components, or four of a space with time (`…-time`) whose time
/// component is 0 (a spatial axis; a time axis has no place in the patient).
fn in_space(v: &[f64]) -> Option<[f64; 3]> {
    match v {
        [x, y, z] | [x, y, z, 0.0] => Some([*x, *y, *z]),
        _ => None,
    }
}

/// Splits `space directions: (1,0,0) (0,1,0) none` into its vectors.
fn split_vectors(s: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        let end = if rest.starts_with('(') {
            rest.find(')').map_or(rest.len(), |i| i + 1)
        } else {
            rest.find(char::is_whitespace).unwrap_or(rest.len())
        };
        out.push(rest[..end].trim());
        rest = rest[end..].trim_start();
    }
    out
}

/// The three axes of a NRRD of `sizes` (one per dimension) that make the
/// volume. An axis whose `kinds` entry is not a space kind (`domain`,
/// `space`, or unknown), or, without kinds, whose `space directions` entry is
/// `none`, is no space axis: it must hold one sample (a channel, vector or
/// time axis of more is refused, naming it). A file of more than three
/// dimensions leaves out such axes, then axes of one sample when exactly
/// enough of those are left (a 4D file of one volume, as some tools write);
/// which to leave out must be clear.
fn spatial_axes(
    sizes: &[u64],
    directions: Option<&str>,
    kinds: Option<&str>,
) -> Result<[usize; 3], ImportErrorKind> {
    let dimension = sizes.len();
    let directions = directions.map(split_vectors);
    let kinds: Option<Vec<&str>> = kinds.map(|k| k.split_whitespace().collect());
    if let Some(kinds) = kinds.as_ref().filter(|k| k.len() != dimension) {
        return Err(header_error(
            F,
            format!(
                "`kinds` has {} entries for dimension {dimension}",
                kinds.len()
            ),
        ));
    }
    // Why an axis is no space axis, if it is none.
    let not_space = |axis: usize| -> Option<String> {
        if let Some(kinds) = &kinds {
            let kind = kinds.get(axis)?;
            let spatial = ["domain", "space", "???", "none"]
                .iter()
                .any(|s| kind.eq_ignore_ascii_case(s));
            return (!spatial).then(|| format!("of kind `{kind}`"));
        }
        let direction = directions.as_ref()?.get(axis)?;
        direction
            .eq_ignore_ascii_case("none")
            .then(|| "without a space direction (`none`)".to_string())
    };
    // Kinds and directions that disagree: a space axis without a direction.
    if let (Some(kinds), Some(directions)) = (&kinds, &directions)
        && let Some(axis) = (0..dimension).find(|&a| {
            sizes[a] > 1
                && not_space(a).is_none()
                && directions
                    .get(a)
                    .is_some_and(|d| d.eq_ignore_ascii_case("none"))
        })
    {
        return Err(header_error(
            F,
            format!(
                "axis {axis} is a space axis by its kind `{}` but has no space direction \
                 (`none`)",
                kinds[axis]
            ),
        ));
    }
    if let Some((axis, why)) = (0..dimension)
        .filter(|&a| sizes[a] > 1)
        .find_map(|a| not_space(a).map(|why| (a, why)))
    {
        return Err(unsupported(
            F,
            format!(
                "axis {axis} {why} holds {} samples (channels, vectors or a series of \
                 volumes); only one volume of single values is read",
                sizes[axis]
            ),
        ));
    }
    let marked: Vec<usize> = (0..dimension).filter(|&a| not_space(a).is_some()).collect();
    let single: Vec<usize> = (0..dimension)
        .filter(|&a| sizes[a] == 1 && !marked.contains(&a))
        .collect();
    let extra = dimension - 3;
    let left_out: Vec<usize> = if marked.len() > extra {
        return Err(unsupported(
            F,
            format!(
                "of its {dimension} axes only {} are space axes (axes {marked:?} are not): \
                 not a 3D volume",
                dimension - marked.len()
            ),
        ));
    } else if marked.len() == extra {
        marked
    } else if marked.len() + single.len() == extra {
        marked.into_iter().chain(single).collect()
    } else {
        let unclear = if single.len() > 1 {
            format!(
                "axes {single:?} hold one sample each and {} of them could be left out: mark \
                 the axes that are no space axes (`kinds: list` or `time`, or `none` in \
                 `space directions`)",
                extra - marked.len()
            )
        } else {
            format!("its sizes are {sizes:?}")
        };
        return Err(unsupported(
            F,
            format!(
                "dimension {dimension}: {unclear}; only 3D volumes are read, or files of more \
                 dimensions whose other axes hold one sample each"
            ),
        ));
    };
    let kept: Vec<usize> = (0..dimension).filter(|a| !left_out.contains(a)).collect();
    Ok([kept[0], kept[1], kept[2]])
}

/// A per-axis field's `items`: one per axis of the file (`dimension`), else
/// an error naming the field.
fn per_axis<'a>(
    field: &str,
    items: Vec<&'a str>,
    what: &str,
    dimension: usize,
) -> Result<Vec<&'a str>, ImportErrorKind> {
    if items.len() == dimension {
        Ok(items)
    } else {
        Err(header_error(
            F,
            format!(
                "`{field}` has {} {what} for dimension {dimension}",
                items.len()
            ),
        ))
    }
}

/// Parses a NRRD header from the start of `bytes` (which may go on into the data).
///
/// A pure function of the bytes: it never panics, whatever they hold.
pub fn parse_header(bytes: &[u8]) -> Result<NrrdHeader, ImportErrorKind> {
    if !bytes.starts_with(b"NRRD000") {
        return Err(header_error(
            F,
            "the file does not start with the magic NRRD000X",
        ));
    }
    let mut pos = 0;
    let mut lines = Vec::new();
    let mut header_len = None;
    while pos < bytes.len().min(MAX_HEADER_BYTES) {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let line = &bytes[pos..end];
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        pos = (end + 1).min(bytes.len());
        if line.is_empty() {
            header_len = Some(pos);
            break;
        }
        match std::str::from_utf8(line) {
            // A control character would be invisible in messages naming the value.
            Ok(text)
                if !line.starts_with(b"#") && text.chars().any(|c| c.is_control() && c != '\t') =>
            {
                let n = lines.len() + 1;
                let c = text
                    .chars()
                    .find(|c| c.is_control() && *c != '\t')
                    .unwrap_or('\0');
                return Err(header_error(
                    F,
                    format!("header line {n} holds a control character ({c:?})"),
                ));
            }
            Ok(line) => lines.push(line),
            // Comments and key/value pairs, skipped below, may hold any bytes
            // (a name in Latin-1), as teem reads them: kept as an empty
            // comment, so that lines keep their numbers.
            Err(_) if line.starts_with(b"#") || line.windows(2).any(|w| w == b":=") => {
                lines.push("#");
            }
            Err(_) => {
                let n = lines.len() + 1;
                return Err(header_error(F, format!("header line {n} is not text")));
            }
        }
        if end >= bytes.len() {
            break;
        }
    }
    if header_len.is_none() && pos >= MAX_HEADER_BYTES {
        return Err(header_error(
            F,
            format!(
                "no blank line ends the header within its first {} (a NRRD header is text of \
                 a few hundred bytes)",
                crate::text::counted(MAX_HEADER_BYTES as u64, "byte")
            ),
        ));
    }
    let magic = lines.first().copied().unwrap_or_default();
    match magic
        .strip_prefix("NRRD000")
        .and_then(|v| v.parse::<u8>().ok())
    {
        Some(1..=5) => {}
        _ => {
            return Err(unsupported(
                F,
                format!("magic `{magic}` (NRRD0001..NRRD0005 are read)"),
            ));
        }
    }
    let mut fields = std::collections::HashMap::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        if line.starts_with('#') || line.contains(":=") {
            continue;
        }
        let (key, value) = line.split_once(": ").ok_or_else(|| {
            header_error(F, format!("line {} `{line}` is not `field: value`", i + 1))
        })?;
        let key = key.trim().to_ascii_lowercase();
        let value = value.trim().to_string();
        // `data file: LIST`: the lines after it are file names, not fields
        // (refused below as a list of files).
        let list = (key == "data file" || key == "datafile") && value.starts_with("LIST");
        if fields.contains_key(&key) {
            // Which would count? Readers differ (teem refuses it): said, not guessed.
            return Err(header_error(F, format!("the field `{key}` is given twice")));
        }
        fields.insert(key, value);
        if list {
            break;
        }
    }
    let get = |k: &str| fields.get(k).map(String::as_str);
    let need = |k: &str| {
        get(k).ok_or_else(|| header_error(F, format!("the required field `{k}` is missing")))
    };

    let dimension = need("dimension")?;
    let dimension = match dimension.parse::<usize>() {
        Ok(d) if (3..=16).contains(&d) => d,
        _ => {
            return Err(unsupported(
                F,
                format!("dimension {dimension} (only 3D volumes are read)"),
            ));
        }
    };
    let sample = parse_type(need("type")?)?;
    let all_sizes = need("sizes")?
        .split_whitespace()
        .map(|s| {
            s.parse::<u64>()
                .map_err(|_| header_error(F, format!("size `{s}` is not a whole number")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if all_sizes.len() != dimension {
        return Err(header_error(
            F,
            format!(
                "`sizes` has {} values for dimension {dimension}",
                all_sizes.len()
            ),
        ));
    }
    // The three axes of the volume; the others hold one sample each.
    let axes = spatial_axes(&all_sizes, get("space directions"), get("kinds"))?;
    let sizes = axes.map(|a| all_sizes[a]);
    let dims = check_dims(F, &sizes)?;
    let encoding = match need("encoding")? {
        "raw" => Encoding::Raw,
        "gzip" | "gz" => Encoding::Gzip,
        other => {
            return Err(unsupported(
                F,
                format!("encoding `{other}` (raw and gzip are read)"),
            ));
        }
    };
    let endian = match (get("endian"), sample.size()) {
        (_, 1) => Endian::Little,
        (Some("little"), _) => Endian::Little,
        (Some("big"), _) => Endian::Big,
        (Some(other), _) => {
            return Err(header_error(
                F,
                format!("endian `{other}` is neither little nor big"),
            ));
        }
        (None, _) => return Err(header_error(F, "multi-byte samples need an `endian` field")),
    };
    let mut spacing = [1f32; 3];
    let mut orientation = None;
    // `space directions` place the axes (and give their spacing); `spacings`
    // give the spacing of axes without a direction. NRRD wants `nan` spacings
    // on axes with directions: they are not read (a number there lost the
    // orientation, a `nan` refused the file).
    let spacings = get("spacings")
        .map(|s| {
            per_axis(
                "spacings",
                s.split_whitespace().collect(),
                "values",
                dimension,
            )
        })
        .transpose()?;
    let directions = get("space directions")
        .map(|s| per_axis("space directions", split_vectors(s), "entries", dimension))
        .transpose()?;
    let mut steps = Vec::with_capacity(3);
    // (Axes are named as the file numbers them.)
    for (i, axis) in axes.into_iter().enumerate() {
        let direction = match &directions {
            Some(vectors) => parse_vector(vectors[axis])?,
            None => None,
        };
        if let Some(v) = direction {
            let len = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            spacing[i] = check_spacing(F, axis, len)?;
            steps.extend(in_space(&v));
        } else if let Some(values) = &spacings {
            let v = values[axis];
            if v.eq_ignore_ascii_case("nan") {
                // NRRD's "no spacing on this axis": a volume renders with its spacing,
                // so guessing 1 would silently distort it.
                return Err(header_error(
                    F,
                    format!(
                        "spacing on axis {axis} is NaN (unknown); write the spacing, or drop `spacings` for 1 on every axis"
                    ),
                ));
            }
            let v = v
                .parse::<f64>()
                .map_err(|_| header_error(F, format!("spacing `{v}` is not a number")))?;
            spacing[i] = check_spacing(F, axis, v)?;
        }
    }
    // An anatomical space and a direction on every axis place the volume in
    // the patient; `space origin` defaults to 0.
    let space = get("space").and_then(PatientSpace::from_nrrd);
    if let (Some(space), Ok(steps)) = (space, <[[f64; 3]; 3]>::try_from(steps)) {
        let origin = match get("space origin") {
            Some(o) => parse_vector(o)?
                .and_then(|o| in_space(&o).or_else(|| o.get(..3)?.try_into().ok()))
                .ok_or_else(|| header_error(F, format!("space origin `{o}` is not (x,y,z)")))?,
            None => [0.0; 3],
        };
        // Directions that make no volume (coplanar) are passed over: the file
        // opens as it did before orientations were read.
        orientation = Orientation::from_steps(space, steps, origin)
            .ok()
            .map(|(placed, _)| placed);
    }
    let data_file = match get("data file").or(get("datafile")) {
        None => DataFile::Attached,
        Some(f) if f.starts_with("LIST") || f.split_whitespace().count() > 1 => {
            return Err(unsupported(
                F,
                format!("data file `{f}` (one detached file is read, not lists or patterns)"),
            ));
        }
        Some(f) => DataFile::Detached(f.to_string()),
    };
    let byte_skip = match get("byte skip").or(get("byteskip")) {
        None => Some(0),
        Some("-1") => None,
        Some(s) => Some(s.parse::<u64>().map_err(|_| {
            header_error(F, format!("byte skip `{s}` is not -1 or a whole number"))
        })?),
    };
    if byte_skip.is_none() && encoding != Encoding::Raw {
        return Err(header_error(
            F,
            "byte skip -1 is only valid for raw encoding",
        ));
    }
    let line_skip = match get("line skip").or(get("lineskip")) {
        None => 0,
        Some(s) => s
            .parse::<u64>()
            .map_err(|_| header_error(F, format!("line skip `{s}` is not a whole number")))?,
    };
    let header_len = match (header_len, &data_file) {
        (Some(n), _) => n,
        (None, DataFile::Detached(_)) => pos,
        (None, DataFile::Attached) => {
            return Err(header_error(
                F,
                "the header does not end with a blank line before the data",
            ));
        }
    };
    Ok(NrrdHeader {
        orientation,
        dims,
        spacing,
        sample,
        endian,
        encoding,
        data_file,
        byte_skip,
        line_skip,
        header_len,
    })
}

/// Parses the NRRD file at `path` (a `.nrrd` or `.nhdr` header).
pub fn open(path: &Path) -> Result<Imported, ImportError> {
    let bytes = read_text_header(path, MAX_HEADER_BYTES)?;
    let h = parse_header(&bytes).map_err(|e| ImportError::new(path, e))?;
    let (data_path, mut offset) = match &h.data_file {
        DataFile::Attached => (path.to_path_buf(), h.header_len as u64),
        DataFile::Detached(name) => {
            let dir = path.parent().unwrap_or(Path::new("."));
            (dir.join(name), 0)
        }
    };
    if h.line_skip > 0 {
        crate::files::check_regular(&data_path)
            .map_err(|source| super::data_file_error(path, &data_path, source))?;
        offset += skip_lines(&data_path, offset, h.line_skip)
            .map_err(|e| ImportError::new(&data_path, e))?;
    }
    let sample_bytes =
        h.dims.iter().map(|&d| u64::from(d)).product::<u64>() * h.sample.size() as u64;
    let (data_offset, skip_after_decode) = match (h.encoding, h.byte_skip) {
        (Encoding::Raw, Some(skip)) => {
            // A skip near 2^64 must not wrap around onto the header text.
            let start = offset.checked_add(skip).ok_or_else(|| {
                ImportError::new(
                    path,
                    header_error(F, format!("byte skip {skip} runs past any file's end")),
                )
            })?;
            (start, 0)
        }
        (Encoding::Raw, None) => (data_at_end(path, &data_path, sample_bytes, offset)?, 0),
        (_, skip) => (offset, skip.unwrap_or(0)),
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
        encoding: h.encoding,
        scaling: None,
        unit: String::new(),
        orientation: h.orientation,
        slices: Vec::new(),
    })
}

/// Bytes taken by the first `lines` lines of `path` after `offset`.
fn skip_lines(path: &Path, offset: u64, lines: u64) -> std::io::Result<u64> {
    use std::io::{BufRead, Seek, SeekFrom};
    let mut f = crate::files::open_regular(path)?;
    f.seek(SeekFrom::Start(offset))?;
    let mut r = std::io::BufReader::new(f);
    let mut total = 0;
    let mut line = Vec::new();
    for _ in 0..lines {
        line.clear();
        let n = r.read_until(b'\n', &mut line)?;
        if n == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the data file ends within its `line skip` lines",
            ));
        }
        total += n as u64;
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_of_data_files_is_refused_as_one() {
        for head in [
            "data file: LIST\na.raw\nb.raw\n",
            "datafile: LIST 2\na.raw\nb.raw\n",
            "data file: slice%03d.raw 1 40 1\n",
        ] {
            let text =
                format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n{head}");
            let e = parse_header(text.as_bytes())
                .map(|_| ())
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("one detached file is read, not lists or patterns"),
                "{head}: {e}"
            );
        }
    }

    #[test]
    fn a_space_with_time_places_the_volume_as_its_three_patient_axes_do() {
        let header = |space: &str, dims: &str, sizes: &str, dirs: &str, origin: &str| {
            format!(
                "NRRD0005\ntype: uchar\ndimension: {dims}\nspace: {space}\nsizes: {sizes}\n\
                 space directions: {dirs}\nencoding: raw\nspace origin: {origin}\n\n"
            )
        };
        let three = parse_header(
            header(
                "right-anterior-superior",
                "3",
                "4 5 6",
                "(0.5,0,0) (0,0.5,0) (0,0,2)",
                "(10,20,30)",
            )
            .as_bytes(),
        )
        .unwrap();
        assert!(three.orientation.is_some());
        // (It was read without one: `-time` spaces were not known, and their
        // vectors have four components.)
        for (space, dims, sizes, dirs) in [
            (
                "right-anterior-superior-time",
                "3",
                "4 5 6",
                "(0.5,0,0,0) (0,0.5,0,0) (0,0,2,0)",
            ),
            (
                "RAST",
                "4",
                "4 5 6 1",
                "(0.5,0,0,0) (0,0.5,0,0) (0,0,2,0) (0,0,0,1)",
            ),
        ] {
            let h =
                parse_header(header(space, dims, sizes, dirs, "(10,20,30,0)").as_bytes()).unwrap();
            assert_eq!(h.orientation, three.orientation, "{space}");
            assert_eq!(h.spacing, three.spacing, "{space}");
        }
    }

    /// `space directions` give the spacing and place the volume even beside
    /// `spacings` (whose `nan`, as NRRD wants on such axes, refused the file;
    /// a number there lost the orientation); `spacings` still give the axes
    /// without a direction.
    #[test]
    fn space_directions_win_over_spacings_which_fill_axes_without_one() {
        let header = |extra: &str, dirs: &str| {
            format!(
                "NRRD0005\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\n\
                 sizes: 4 5 6\nspace directions: {dirs}\n{extra}encoding: raw\n\n"
            )
        };
        let dirs = "(0.5,0,0) (0,0.5,0) (0,0,2.5)";
        let plain = parse_header(header("", dirs).as_bytes()).unwrap();
        assert_eq!(plain.spacing, [0.5, 0.5, 2.5]);
        assert!(plain.orientation.is_some());
        for spacings in ["spacings: nan nan nan\n", "spacings: 1 1 1\n"] {
            let h = parse_header(header(spacings, dirs).as_bytes()).unwrap();
            assert_eq!(h.spacing, plain.spacing, "{spacings}");
            assert_eq!(h.orientation, plain.orientation, "{spacings}");
        }
        // An axis without a direction takes its spacing from `spacings`.
        let h =
            parse_header(header("spacings: nan 0.7 nan\n", "(0.5,0,0) none (0,0,2.5)").as_bytes());
        // (A `none` among three spatial axes: whether the file opens is the
        // axis rules' business; where it does, the spacing is the given one.)
        if let Ok(h) = h {
            assert_eq!(h.spacing[1], 0.7);
        }
    }

    #[test]
    fn parses_a_typical_header() {
        let h = parse_header(
            b"NRRD0004\n# comment\ntype: short\ndimension: 3\nspace: left-posterior-superior\n\
              sizes: 4 5 6\nspace directions: (0.5,0,0) (0,0.5,0) (0,0,2.5)\nkinds: domain domain domain\n\
              endian: little\nencoding: gzip\nspace origin: (1,2,3)\nfoo:=bar\n\nDATA",
        )
        .unwrap();
        assert_eq!(h.dims, [4, 5, 6]);
        assert_eq!(h.spacing, [0.5, 0.5, 2.5]);
        assert_eq!(h.sample, RawType::I16);
        assert_eq!(h.encoding, Encoding::Gzip);
        assert_eq!(h.data_file, DataFile::Attached);
        assert_eq!(h.header_len, b"NRRD0004\n# comment\ntype: short\ndimension: 3\nspace: left-posterior-superior\n\
              sizes: 4 5 6\nspace directions: (0.5,0,0) (0,0.5,0) (0,0,2.5)\nkinds: domain domain domain\n\
              endian: little\nencoding: gzip\nspace origin: (1,2,3)\nfoo:=bar\n\n".len());
    }

    #[test]
    fn rejects_what_it_cannot_read_with_a_reason() {
        let base = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n";
        assert!(parse_header(base.as_bytes()).is_ok());
        for (bad, needle) in [
            (base.replace("uchar", "double"), "double"),
            (base.replace("dimension: 3", "dimension: 4"), "dimension 4"),
            (base.replace("encoding: raw", "encoding: bzip2"), "bzip2"),
            (base.replace("sizes: 2 2 2", "sizes: 2 0 2"), "size 0"),
            (base.replace("sizes: 2 2 2", "sizes: 2 2"), "2 values"),
            (base.replace("NRRD0004", "NRRD0009"), "NRRD0009"),
            (base.replace("uchar", "short"), "endian"),
            (base.replace("type: uchar\n", ""), "`type`"),
            (base.replace("\n\n", "\n"), "blank line"),
            (
                base.replace("sizes: 2 2 2", "sizes: 2 2 2\nspacings: 1 nan0 1"),
                "nan0",
            ),
            (
                base.replace("sizes: 2 2 2", "sizes: 2 2 2\nspacings: 1 0 1"),
                "spacing 0",
            ),
            (
                base.replace("sizes: 2 2 2", "sizes: 2 2 2\nspacings: 1 NaN 1"),
                "NaN",
            ),
            ("PNG".to_string(), "magic"),
            (
                base.replace("dimension: 3\nsizes: 2 2 2", "dimension: 4\nsizes: 5 2 2 2"),
                "dimension 4: its sizes are [5, 2, 2, 2]",
            ),
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 3 2 2 2\nkinds: RGB-color domain domain domain",
                ),
                "axis 0 of kind `RGB-color` holds 3 samples",
            ),
            // One slice over time: the time axis stays refused, not read as z.
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 6 5 1 4\nkinds: domain domain domain time",
                ),
                "axis 3 of kind `time` holds 4 samples",
            ),
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 3 8 6 1\n\
                     space directions: none (0.5,0,0) (0,0.5,0) (0,0,1)",
                ),
                "axis 0 without a space direction (`none`) holds 3 samples",
            ),
            // A 2D colour image in three dimensions.
            (
                base.replace(
                    "sizes: 2 2 2",
                    "sizes: 3 8 6\nkinds: RGB-color domain domain",
                ),
                "axis 0 of kind `RGB-color` holds 3 samples",
            ),
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 1 6 5 1\nkinds: list domain domain time",
                ),
                "only 2 are space axes (axes [0, 3] are not)",
            ),
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 1 6 5 4\nkinds: list domain domain domain\n\
                     spacings: nan 0.5 0 2",
                ),
                "spacing 0 on axis 2",
            ),
            (
                base.replace("dimension: 3\nsizes: 2 2 2", "dimension: 4\nsizes: 1 2 1 2"),
                "axes [0, 2] hold one sample each and 1 of them could be left out",
            ),
            (base.replace("dimension: 3", "dimension: 2"), "dimension 2"),
            (
                base.replace(
                    "dimension: 3\nsizes: 2 2 2",
                    "dimension: 4\nsizes: 3 6 5 4\nkinds: list domain domain domain\n\
                     space directions: (1,0,0) none (0,1,0) (0,0,1)",
                ),
                "axis 1 is a space axis by its kind `domain` but has no space direction",
            ),
            (
                base.replace("type: uchar", "type: uchar\0"),
                "header line 2 holds a control character ('\\0')",
            ),
            (
                format!(
                    "{}\n{}",
                    base.trim_end(),
                    "# x\n".repeat(MAX_HEADER_BYTES / 4 + 1)
                ),
                "no blank line ends the header within its first 1048576 bytes",
            ),
            (
                base.replace(
                    "sizes: 2 2 2",
                    "sizes: 2 2 2\nspacings: 1 1 1\nspacings: 2 2 2",
                ),
                "the field `spacings` is given twice",
            ),
            (
                base.replace("sizes: 2 2 2", "sizes: 2 2 2\nkinds: domain domain"),
                "`kinds` has 2 entries for dimension 3",
            ),
        ] {
            let err = parse_header(bad.as_bytes()).unwrap_err().to_string();
            assert!(err.contains(needle), "{bad:?}: {err}");
        }
    }

    #[test]
    fn comments_and_key_value_pairs_may_hold_any_bytes() {
        let text = b"NRRD0004\n# patient: M\xfcller\nname:=M\xfcller\ntype: uchar\ndimension: 3\n\
                     sizes: 2 2 2\nencoding: raw\n\n";
        assert_eq!(parse_header(text).unwrap().dims, [2, 2, 2]);
        let after = b"NRRD0004\n# M\xfcller\ntype: uchar\nbad line\n\n";
        let err = parse_header(after).unwrap_err().to_string();
        assert!(err.contains("line 4 `bad line`"), "{err}");
        let field = b"NRRD0004\ntype: uchar\ncontent: M\xfcller\n\n";
        let err = parse_header(field).unwrap_err().to_string();
        assert!(err.contains("header line 3 is not text"), "{err}");
    }

    #[test]
    fn a_four_dimensional_file_of_one_volume_reads_as_its_three_axes() {
        let base = "NRRD0004\ntype: short\nendian: little\nencoding: raw\nspace: left-posterior-superior\n";
        let three = parse_header(
            format!(
                "{base}dimension: 3\nsizes: 4 5 6\n\
                 space directions: (0.5,0,0) (0,0.7,0) (0,0,2.5)\nspace origin: (1,2,3)\n\n"
            )
            .as_bytes(),
        )
        .unwrap();
        for fields in [
            // A leading list axis (as 3D Slicer writes), spacings and kinds too.
            "dimension: 4\nsizes: 1 4 5 6\nkinds: list domain domain domain\n\
             space directions: none (0.5,0,0) (0,0.7,0) (0,0,2.5)\nspace origin: (1,2,3)\n",
            // A trailing time axis of one frame.
            "dimension: 4\nsizes: 4 5 6 1\n\
             space directions: (0.5,0,0) (0,0.7,0) (0,0,2.5) none\nspace origin: (1,2,3)\n",
            // A flat volume: of the two axes of one sample, the one that is no space axis goes.
            "dimension: 4\nsizes: 4 1 6 1\nkinds: domain domain domain time\n\
             space directions: (0.5,0,0) (0,0.7,0) (0,0,2.5) none\nspace origin: (1,2,3)\n",
        ] {
            let h = parse_header(format!("{base}{fields}\n").as_bytes()).unwrap();
            if fields.contains("4 1 6 1") {
                assert_eq!(h.dims, [4, 1, 6], "{fields}");
                continue;
            }
            assert_eq!(h.dims, three.dims, "{fields}");
            assert_eq!(h.spacing, three.spacing, "{fields}");
            assert_eq!(h.orientation, three.orientation, "{fields}");
        }
        let spacings = parse_header(
            format!("{base}dimension: 4\nsizes: 1 4 5 6\nspacings: nan 0.5 0.7 2.5\n\n").as_bytes(),
        )
        .unwrap();
        assert_eq!(
            (spacings.dims, spacings.spacing),
            ([4, 5, 6], [0.5, 0.7, 2.5])
        );
    }
}
