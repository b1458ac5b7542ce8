//! Parsers for the value syntaxes the commands share (sizes, spacing, windows).

use clap::ValueEnum;
use raycaster::io::{Endian, RawOrder, RawType};
use raycaster::volume::{Format, MAX_AXIS, MAX_SPACING, MIN_SPACING, SampleType};

/// Flags that do not go together (`--brick` with `--layout linear`): a wrong
/// command line, exit status 2 like clap's own errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CommandLineError(pub String);

/// Returns a [`CommandLineError`] saying `message`.
macro_rules! wrong_command_line {
    ($($arg:tt)*) => {
        return Err($crate::args::CommandLineError(format!($($arg)*)).into())
    };
}
pub(crate) use wrong_command_line;

/// `N` (a cube) or `XxYxZ`.
pub fn parse_dims(s: &str) -> Result<[u32; 3], String> {
    // (Sizes written like spacings, `512,512,128`: said with the form sizes take.)
    if s.contains(',') {
        return Err(format!(
            "`{s}`: sizes are written N or XxYxZ, e.g. 256 or 512x512x128"
        ));
    }
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let nums = parts
        .iter()
        .map(|p| {
            let p = p.trim();
            p.parse::<u32>().map_err(|e| match e.kind() {
                // (Beyond u32: out of range, as any size above the limit.)
                std::num::IntErrorKind::PosOverflow => {
                    format!("size {p} is out of range 1..={MAX_AXIS}")
                }
                _ => format!("`{p}` is not a whole number"),
            })
        })
        .collect::<Result<Vec<u32>, String>>()?;
    let dims = match nums[..] {
        [n] => [n; 3],
        [x, y, z] => [x, y, z],
        _ => return Err("expected N or XxYxZ, e.g. 256 or 512x512x128".into()),
    };
    if let Some(d) = dims.iter().find(|&&d| d == 0 || d > MAX_AXIS) {
        return Err(format!("size {d} is out of range 1..={MAX_AXIS}"));
    }
    Ok(dims)
}

/// `S` (the same on every axis) or `X,Y,Z`, each a number in
/// [`MIN_SPACING`]..=[`MAX_SPACING`], the spacings a header is read with.
pub fn parse_spacing(s: &str) -> Result<[f32; 3], String> {
    let nums = s
        .split(',')
        .map(|p| {
            let p = p.trim();
            let v = p
                .parse::<f32>()
                .map_err(|_| format!("`{p}` is not a number"))?;
            if !(MIN_SPACING..=MAX_SPACING).contains(&v) {
                return Err(format!(
                    "spacing `{p}` is out of range: a spacing is a number from {MIN_SPACING:e} to {MAX_SPACING:e}"
                ));
            }
            Ok(v)
        })
        .collect::<Result<Vec<f32>, String>>()?;
    let spacing = match nums[..] {
        [v] => [v; 3],
        [x, y, z] => [x, y, z],
        _ => return Err("expected S or X,Y,Z, e.g. 1 or 0.5,0.5,2".into()),
    };
    // The limit foreign files are read under: the renderer steps by the
    // smallest spacing, and would refuse the file's rays as too long.
    if let Some(ratio) = raycaster::import::lopsided_spacing(spacing) {
        return Err(format!(
            "the largest spacing is {ratio:.3e} times the smallest; at most {:.0e} renders (rays step by the smallest spacing, and would take too many samples)",
            raycaster::import::MAX_SPACING_RATIO
        ));
    }
    Ok(spacing)
}

/// `LO:HI` (or `LO,HI`, as `raycaster` writes it) with LO < HI, or the name of
/// a CT window (`lung`: its Hounsfield units).
pub fn parse_window(s: &str) -> Result<WindowArg, String> {
    if let Some(named) = raycaster::windows::named_window(s.trim()) {
        let [lo, hi] = named.range();
        return Ok(WindowArg {
            range: (lo, hi),
            name: Some(named.name),
        });
    }
    let separator = if s.contains(':') { ':' } else { ',' };
    let (lo, hi) = s.split_once(separator).ok_or_else(|| {
        format!(
            "expected LO:HI (e.g. -1000:2000) or a named window ({})",
            raycaster::windows::named_window_list()
        )
    })?;
    let num = |p: &str| {
        p.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or(format!("`{p}` is not a finite number"))
    };
    let (lo, hi) = (num(lo)?, num(hi)?);
    if lo >= hi {
        return Err(format!("window low {lo} must be below high {hi}"));
    }
    Ok(WindowArg {
        range: (lo, hi),
        name: None,
    })
}

/// A `--window`: input values `lo..hi`, and the name of a CT window given by
/// name (in Hounsfield units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowArg {
    /// The values, in the input's units.
    pub range: (f32, f32),
    /// The CT window's name, when one was named.
    pub name: Option<&'static str>,
}

/// A brick side that fits the header byte and is at least 2.
pub fn parse_brick(s: &str) -> Result<u8, String> {
    match s.parse::<u32>() {
        Ok(v @ 2..=255) => Ok(v as u8),
        Ok(v) => Err(format!("brick side {v} is out of range 2..=255")),
        Err(e) if *e.kind() == std::num::IntErrorKind::PosOverflow => {
            Err(format!("brick side {s} is out of range 2..=255"))
        }
        Err(_) => Err(format!("`{s}` is not a whole number")),
    }
}

/// Sample order on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LayoutArg {
    /// One array, z fastest (thesis order 1).
    Linear,
    /// Overlapping cubic bricks (thesis order 2).
    Bricked,
}

/// Stored sample type on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SampleArg {
    /// 8-bit samples.
    U8,
    /// 16-bit samples (extended format).
    U16,
}

impl From<SampleArg> for SampleType {
    fn from(s: SampleArg) -> Self {
        match s {
            SampleArg::U8 => SampleType::U8,
            SampleArg::U16 => SampleType::U16,
        }
    }
}

/// Header format on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// The extended header (64 bytes, 128 or 256 with value units and an
    /// orientation): sample type, labels, the embedded brick-range table and the
    /// resolution pyramid.
    Extended,
    /// The thesis's 26-byte header, u8 only (brick ranges go to FILE.ranges).
    Thesis,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Extended => Format::Extended,
            FormatArg::Thesis => Format::Thesis,
        }
    }
}

/// Raw sample types on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RawTypeArg {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit float.
    F32,
}

impl From<RawTypeArg> for RawType {
    fn from(t: RawTypeArg) -> Self {
        match t {
            RawTypeArg::U8 => RawType::U8,
            RawTypeArg::U16 => RawType::U16,
            RawTypeArg::I16 => RawType::I16,
            RawTypeArg::F32 => RawType::F32,
        }
    }
}

/// Byte order on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EndianArg {
    /// Least significant byte first.
    Little,
    /// Most significant byte first.
    Big,
}

impl From<EndianArg> for Endian {
    fn from(e: EndianArg) -> Self {
        match e {
            EndianArg::Little => Endian::Little,
            EndianArg::Big => Endian::Big,
        }
    }
}

/// Raw axis order on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RawOrderArg {
    /// x changes fastest (C order [z][y][x]; most raw dumps).
    X,
    /// z changes fastest (the .vol linear order).
    Z,
}

impl From<RawOrderArg> for RawOrder {
    fn from(o: RawOrderArg) -> Self {
        match o {
            RawOrderArg::X => RawOrder::XFastest,
            RawOrderArg::Z => RawOrder::ZFastest,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dims_accept_cube_and_triple_and_reject_nonsense() {
        assert_eq!(parse_dims("64"), Ok([64; 3]));
        assert_eq!(parse_dims("3x4X5"), Ok([3, 4, 5]));
        assert!(parse_dims("0").is_err());
        assert!(parse_dims("2x2").is_err());
        assert_eq!(
            parse_dims("20,20,1"),
            Err("`20,20,1`: sizes are written N or XxYxZ, e.g. 256 or 512x512x128".into())
        );
        assert!(parse_dims("99999999").is_err());
        // Beyond u32 it is out of range too, not "not a whole number".
        assert_eq!(
            parse_dims("4294967296x1x1"),
            Err(format!("size 4294967296 is out of range 1..={MAX_AXIS}"))
        );
        assert_eq!(
            parse_dims("1x-2x3"),
            Err("`-2` is not a whole number".into())
        );
        assert_eq!(
            parse_brick("99999999999"),
            Err("brick side 99999999999 is out of range 2..=255".into())
        );
    }

    #[test]
    fn spacing_and_window_reject_bad_numbers() {
        assert_eq!(parse_spacing("0.5,1,2"), Ok([0.5, 1.0, 2.0]));
        assert!(parse_spacing("-1").is_err());
        assert!(parse_spacing("nan").is_err());
        // Out of the header's range, named as typed (1e39 is `inf` as an f32).
        let too_large = parse_spacing("1,1,1e39").unwrap_err();
        assert!(too_large.contains("`1e39` is out of range"), "{too_large}");
        assert!(parse_spacing("1e-20").is_err());
        assert_eq!(parse_spacing("1e15"), Ok([1e15; 3]));
        // Beyond the spacing ratio the renderer reads (before: generated, and
        // `raycaster render` refused the file).
        let lopsided = parse_spacing("1,1,100000").unwrap_err();
        assert!(
            lopsided
                .contains("the largest spacing is 1.000e5 times the smallest; at most 1e4 renders"),
            "{lopsided}"
        );
        assert_eq!(parse_spacing("1,1,10000"), Ok([1.0, 1.0, 1e4]));
        assert_eq!(parse_window("-1000:3000").unwrap().range, (-1000.0, 3000.0));
        assert!(parse_window("5:5").is_err());
        // raycaster's spelling and the named CT windows too.
        assert_eq!(parse_window("-1000,2000").unwrap().range, (-1000.0, 2000.0));
        let lung = raycaster::windows::named_window("lung").unwrap().range();
        assert_eq!(parse_window("lung").unwrap().range, (lung[0], lung[1]));
        assert_eq!(parse_window("lung").unwrap().name, Some("lung"));
        assert!(parse_window("lungs").unwrap_err().contains("named window"));
        assert_eq!(parse_brick("16"), Ok(16));
        assert!(parse_brick("1").is_err());
        assert!(parse_brick("256").is_err());
    }
}
