//! Parsers for command-line values: image sizes, vectors, colours.

/// `WxH` (or a single `N` for a square), each between 1 and
/// [`raycaster::render::MAX_IMAGE_SIDE`] (16384).
pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let parts: Vec<&str> = s.split(['x', 'X', '×']).collect();
    let nums = parts
        .iter()
        .map(|p| {
            p.trim()
                .parse::<u32>()
                .ok()
                .filter(|&v| (1..=raycaster::render::MAX_IMAGE_SIDE).contains(&v))
        })
        .collect::<Option<Vec<u32>>>()
        .ok_or_else(|| {
            format!(
                "{s:?} is not an image size; expected WxH with 1..{} pixels each",
                raycaster::render::MAX_IMAGE_SIDE
            )
        })?;
    match nums[..] {
        [n] => Ok([n, n]),
        [w, h] => Ok([w, h]),
        _ => Err(format!(
            "{s:?} is not an image size; expected WxH, e.g. 800x600"
        )),
    }
}

/// `x,y,z` of finite numbers.
pub fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    list_in_range(s)?;
    let nums = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<Vec<f32>>>()
        .ok_or_else(|| format!("{s:?} is not a vector; expected x,y,z"))?;
    <[f32; 3]>::try_from(nums).map_err(|_| format!("{s:?} is not a vector; expected x,y,z"))
}

/// A direction `x,y,z`: [`parse_vec3`], not all zero.
pub fn parse_direction(s: &str) -> Result<[f32; 3], String> {
    let v = parse_vec3(s)?;
    if v == [0.0; 3] {
        return Err(format!("{s:?} is no direction: x, y and z are all zero"));
    }
    // (A vector whose squared length underflows normalises to nothing: it
    // lit nothing without a word.)
    if raycaster::render::Vec3::from(v).try_normalize().is_none() {
        return Err(format!(
            "{s:?} is too short to give a direction; scale it up (only its direction counts)"
        ));
    }
    Ok(v)
}

/// `lo,hi` with lo < hi.
pub fn parse_domain(s: &str) -> Result<[f32; 2], String> {
    // `lo:hi` too, as `volgen convert --window` writes it.
    let separator = if s.contains(',') { ',' } else { ':' };
    let nums = s
        .split(separator)
        // (A number past f32's range is said as too large, not as lo ≥ hi.)
        .map(|p| parse_in_range(p).map(|v| v.filter(|v| v.is_finite())))
        .collect::<Result<Option<Vec<f32>>, String>>()?;
    match nums.as_deref() {
        Some(&[lo, hi]) if lo < hi => Ok([lo, hi]),
        Some(&[lo, hi]) if lo == hi && typed_increasing(s, separator) => Err(format!(
            "{s:?}: lo and hi are one value at the renderer's precision (about 7 significant digits); give a wider range"
        )),
        _ => Err(format!(
            "{s:?} is not a value domain; expected lo,hi with lo < hi"
        )),
    }
}

/// Whether `s` names two numbers, the first smaller, as typed (in f64).
fn typed_increasing(s: &str, separator: char) -> bool {
    let values: Vec<f64> = s
        .split(separator)
        .filter_map(|p| p.trim().parse().ok())
        .collect();
    matches!(values.as_slice(), &[lo, hi] if lo < hi)
}

/// A value window given on the command line: two values or a named CT window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WindowArg {
    /// `lo,hi` in the file's units.
    Values([f32; 2]),
    /// A named window in Hounsfield units (`lung`, `bone`, ...).
    Named(&'static raycaster::windows::NamedWindow),
}

impl WindowArg {
    /// The window in the file's units (a named window's HU).
    pub fn values(self) -> [f32; 2] {
        match self {
            WindowArg::Values(v) => v,
            WindowArg::Named(w) => w.range(),
        }
    }

    /// A warning for a named (HU) window given as `flag` on `volume`, named
    /// `name`, whose values are stored samples without value units (not a CT
    /// scan): it windows numbers that mean something else.
    pub fn named_on_plain_data(
        self,
        flag: &str,
        volume: &raycaster::volume::Volume,
        name: &str,
    ) -> Option<String> {
        let WindowArg::Named(named) = self else {
            return None;
        };
        raycaster::windows::ct_window_misreads(volume).then(|| {
            format!(
                "warning: {flag} {}: a CT window in Hounsfield units, and {name} {}; {flag} LO,HI gives a range in its own values",
                named.name,
                raycaster::windows::not_ct_values(volume)
            )
        })
    }
}

/// `lo,hi` or `lo:hi` (values in the file's units), or the name of a CT
/// window.
pub fn parse_window(s: &str) -> Result<WindowArg, String> {
    if let Some(named) = raycaster::windows::named_window(s.trim()) {
        return Ok(WindowArg::Named(named));
    }
    if s.contains(',') || s.contains(':') {
        return parse_domain(s).map(WindowArg::Values);
    }
    Err(format!(
        "{s:?} is neither lo,hi (or lo:hi) nor a named window ({})",
        raycaster::windows::named_window_list()
    ))
}

/// An iso-value: a value in the file's units, or `P%` of the transfer
/// function's domain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IsoArg {
    /// A value in the file's units.
    Value(f32),
    /// A fraction 0..=1 of the domain (given as a percentage).
    Fraction(f32),
}

/// `V` (finite) or `P%` with P in 0..=100.
pub fn parse_iso(s: &str) -> Result<IsoArg, String> {
    let s = s.trim();
    if let Some(percent) = s.strip_suffix('%') {
        return match percent.trim().parse::<f32>() {
            Ok(p) if (0.0..=100.0).contains(&p) => Ok(IsoArg::Fraction(p / 100.0)),
            _ => Err(format!(
                "{s:?}: a percentage of the domain lies in 0%..100%"
            )),
        };
    }
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(IsoArg::Value(v)),
        _ => Err(format!(
            "{s:?} is not an iso-value; give a value in the file's units or a percentage of the domain (40%)"
        )),
    }
}

/// A colour: `#rrggbb`, `r,g,b` in 0..255, or black/white/grey.
pub fn parse_color(s: &str) -> Result<[f32; 3], String> {
    let bad =
        || format!("{s:?} is not a colour; expected #rrggbb, r,g,b (0-255), black, white or grey");
    let bytes: [u8; 3] = match s.trim() {
        "black" => [0; 3],
        "white" => [255; 3],
        "grey" | "gray" => [128; 3],
        hex if hex.starts_with('#') && hex.len() == 7 => {
            let channel = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
            [channel(1)?, channel(3)?, channel(5)?]
        }
        triple => {
            let v = triple
                .split(',')
                .map(|p| p.trim().parse::<u8>().ok())
                .collect::<Option<Vec<u8>>>()
                .ok_or_else(bad)?;
            <[u8; 3]>::try_from(v).map_err(|_| bad())?
        }
    };
    Ok(bytes.map(|b| f32::from(b) / 255.0))
}

/// A probability-like number in (0, 1].
pub fn parse_threshold(s: &str) -> Result<f32, String> {
    s.parse::<f32>()
        .ok()
        .filter(|&v| v > 0.0 && v <= 1.0)
        .ok_or_else(|| format!("{s:?} must be a number in (0, 1]"))
}

/// `s` as an `f32`, or the error for a number written beyond `f32`'s range
/// (which parses as infinite): too large, not "inf".
fn parse_in_range(s: &str) -> Result<Option<f32>, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_infinite() && !s.to_ascii_lowercase().contains("inf") => Err(format!(
            "{s:?} is too large: numbers here lie within ±{:e}",
            f32::MAX
        )),
        parsed => Ok(parsed.ok()),
    }
}

/// The error for the first of the comma-separated numbers of `s` (each
/// perhaps a percentage) written beyond `f32`'s range ([`parse_in_range`]), so
/// that a list says it rather than "not a vector".
fn list_in_range(s: &str) -> Result<(), String> {
    s.split(',')
        .try_for_each(|p| parse_in_range(p.trim().trim_end_matches('%')).map(|_| ()))
}

/// A finite number; one beyond `f32`'s range is refused as too large, not
/// taken as infinite.
pub fn parse_finite(s: &str) -> Result<f32, String> {
    parse_in_range(s)?
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{s:?} must be a finite number"))
}

/// A whole number `min` or more, said in words when it is not (clap's own
/// message for `-1` reads "-1 is not in 0..=4294967295").
fn parse_whole<T: std::str::FromStr + Into<u64> + Copy>(s: &str, min: u64) -> Result<T, String> {
    let text = s.trim();
    match text.parse::<T>() {
        Ok(v) if v.into() >= min => Ok(v),
        // A whole number of the bound or more that the type cannot hold.
        Err(_) if text.parse::<i128>().is_ok_and(|v| v >= i128::from(min)) => {
            Err(format!("{s:?} is too large for a whole number here"))
        }
        _ => Err(format!("{s:?} must be a whole number, {min} or more")),
    }
}

/// A whole number 0 or more that fits 32 bits (an index).
pub fn parse_index(s: &str) -> Result<u32, String> {
    parse_whole(s, 0)
}

/// A whole number in `min..=max` (a count with a ceiling).
pub fn parse_bounded(s: &str, min: u32, max: u32) -> Result<u32, String> {
    match parse_whole::<u32>(s, u64::from(min))? {
        n if n <= max => Ok(n),
        n => Err(format!("{n} is not in {min}..={max}")),
    }
}

/// A whole number 0 or more that fits 64 bits (a seed).
pub fn parse_seed(s: &str) -> Result<u64, String> {
    parse_whole(s, 0)
}

/// A camera elevation in degrees, −90 to 90 (beyond, the orbit would stop at
/// the pole without a word).
pub fn parse_elevation(s: &str) -> Result<f32, String> {
    parse_in_range(s)?
        .filter(|v| (-90.0..=90.0).contains(v))
        .ok_or_else(|| {
            format!("{s:?} must lie between -90 (from below) and 90 (from above) degrees")
        })
}

/// A vertical field of view in degrees: strictly between 0 and 180.
pub fn parse_fov(s: &str) -> Result<f32, String> {
    parse_in_range(s)?
        .filter(|&v| v > 0.0 && v < 180.0)
        .ok_or_else(|| format!("{s:?} must lie strictly between 0 and 180 degrees"))
}

/// A positive finite number.
pub fn parse_positive(s: &str) -> Result<f32, String> {
    parse_in_range(s)?
        .filter(|&v| v > 0.0 && v.is_finite())
        .ok_or_else(|| format!("{s:?} must be a positive number"))
}

/// A coordinate along one axis of the volume: voxels, or a percentage of the
/// volume's extent along that axis (`50%`: the middle; 0% the first voxel,
/// 100% the last).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coord {
    /// Voxel coordinates (voxel centres at whole numbers).
    Voxels(f32),
    /// Percent of `dims − 1`.
    Percent(f32),
}

impl Coord {
    /// The coordinate in voxels along an axis whose last voxel is `last`.
    pub fn voxels(self, last: u32) -> f32 {
        match self {
            Coord::Voxels(v) => v,
            Coord::Percent(p) => p / 100.0 * last as f32,
        }
    }
}

/// One coordinate: a finite number, optionally followed by `%`.
fn parse_coord(s: &str) -> Option<Coord> {
    let s = s.trim();
    let (number, percent) = match s.strip_suffix('%') {
        Some(n) => (n.trim(), true),
        None => (s, false),
    };
    let v = number.parse::<f32>().ok().filter(|v| v.is_finite())?;
    Some(if percent {
        Coord::Percent(v)
    } else {
        Coord::Voxels(v)
    })
}

/// `--crop X0,Y0,Z0,X1,Y1,Z1`: six coordinates, voxels or percentages.
pub fn parse_crop(s: &str) -> Result<[Coord; 6], String> {
    list_in_range(s)?;
    s.split(',')
        .map(parse_coord)
        .collect::<Option<Vec<Coord>>>()
        .and_then(|v| <[Coord; 6]>::try_from(v).ok())
        .ok_or_else(|| {
            format!(
                "{s:?} is not a crop box; expected X0,Y0,Z0,X1,Y1,Z1 in voxels or percentages of the volume (e.g. 0,0,0,127,127,64 or 0%,0%,0%,100%,100%,50%)"
            )
        })
}

/// A clipping plane on the command line: a point (voxels or percentages) and a
/// normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipArg {
    /// A point on the plane.
    pub point: [Coord; 3],
    /// The normal, pointing into the kept half-space (not checked for zero here).
    pub normal: [f32; 3],
}

/// `--clip PX,PY,PZ,NX,NY,NZ`.
pub fn parse_clip(s: &str) -> Result<ClipArg, String> {
    let bad = || {
        format!(
            "{s:?} is not a clipping plane; expected PX,PY,PZ,NX,NY,NZ: a point (voxels or percentages) and a normal pointing into the part kept (e.g. 50%,50%,50%,0,0,1)"
        )
    };
    list_in_range(s)?;
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 6 {
        return Err(bad());
    }
    let point = parts[..3]
        .iter()
        .map(|p| parse_coord(p))
        .collect::<Option<Vec<Coord>>>()
        .ok_or_else(bad)?;
    let normal = parts[3..]
        .iter()
        .map(|p| p.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<Vec<f32>>>()
        .ok_or_else(bad)?;
    Ok(ClipArg {
        point: [point[0], point[1], point[2]],
        normal: [normal[0], normal[1], normal[2]],
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn numbers_beyond_f32_in_lists_are_said_too_large() {
        use super::{parse_clip, parse_crop, parse_vec3};
        for e in [
            parse_clip("0,0,0,1e300,1e300,1").unwrap_err(),
            parse_crop("0,0,0,1e40%,9,9").unwrap_err(),
            parse_vec3("1,-1e39,0").unwrap_err(),
        ] {
            assert!(e.contains("is too large"), "{e}");
        }
        assert!(parse_clip("0,0,0,1e30,1e30,1").is_ok());
        assert!(
            parse_clip("0,0,0,inf,0,1")
                .unwrap_err()
                .contains("not a clipping plane")
        );
    }

    #[test]
    fn whole_numbers_are_refused_in_words() {
        use super::{parse_bounded, parse_index, parse_seed};
        let parse_count = |s| parse_bounded(s, 1, u32::MAX);
        assert_eq!(parse_index("0"), Ok(0));
        assert_eq!(parse_count(" 7 "), Ok(7));
        assert_eq!(parse_seed("18446744073709551615"), Ok(u64::MAX));
        assert_eq!(
            parse_index("-1"),
            Err("\"-1\" must be a whole number, 0 or more".into())
        );
        assert_eq!(
            parse_count("0"),
            Err("\"0\" must be a whole number, 1 or more".into())
        );
        assert_eq!(
            parse_seed("-1"),
            Err("\"-1\" must be a whole number, 0 or more".into())
        );
        assert_eq!(
            parse_index("5000000000"),
            Err("\"5000000000\" is too large for a whole number here".into())
        );
        assert_eq!(
            parse_count("two"),
            Err("\"two\" must be a whole number, 1 or more".into())
        );
        assert_eq!(
            parse_bounded("11", 1, 10),
            Err("11 is not in 1..=10".into())
        );
        assert_eq!(parse_bounded("10", 0, 10), Ok(10));
    }

    use super::*;

    #[test]
    fn crop_boxes_and_planes() {
        assert_eq!(
            parse_crop("0, 1.5,2,10%,100%,3"),
            Ok([
                Coord::Voxels(0.0),
                Coord::Voxels(1.5),
                Coord::Voxels(2.0),
                Coord::Percent(10.0),
                Coord::Percent(100.0),
                Coord::Voxels(3.0)
            ])
        );
        assert_eq!(Coord::Percent(50.0).voxels(30), 15.0);
        assert!(parse_crop("1,2,3,4,5").is_err());
        assert!(parse_crop("1,2,3,4,5,nan").is_err());
        assert!(parse_crop("1,2,3,4,5,6%%").is_err());
        let plane = parse_clip("50%,1,2,0,0,-1").unwrap();
        assert_eq!(plane.point[0], Coord::Percent(50.0));
        assert_eq!(plane.normal, [0.0, 0.0, -1.0]);
        assert!(parse_clip("1,2,3,0,0,1%").is_err());
        assert!(parse_clip("1,2,3,0,0").is_err());
        assert!(parse_clip("1,2,3,0,inf,1").is_err());
    }

    #[test]
    fn sizes_vectors_and_colours() {
        assert_eq!(parse_size("800x600"), Ok([800, 600]));
        assert_eq!(parse_size("64"), Ok([64, 64]));
        assert!(parse_size("0x5").is_err());
        assert!(parse_size("1x2x3").is_err());
        assert!(parse_size("99999x2").is_err());
        assert_eq!(parse_vec3("1, 2,3"), Ok([1.0, 2.0, 3.0]));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,nan,2").is_err());
        assert_eq!(parse_direction("0,-1,0.5"), Ok([0.0, -1.0, 0.5]));
        let zero = parse_direction("0,0,-0").unwrap_err();
        assert!(zero.contains("all zero"), "{zero}");
        // Its length squared underflows: no direction (it lit nothing).
        let tiny = parse_direction("1e-30,0,0").unwrap_err();
        assert!(tiny.contains("too short to give a direction"), "{tiny}");
        assert!(parse_direction("1e-20,0,0").is_ok());
        assert_eq!(parse_color("#ff0080"), Ok([1.0, 0.0, 128.0 / 255.0]));
        assert_eq!(parse_color("255,255,255"), Ok([1.0; 3]));
        assert!(parse_color("#12345").is_err());
        assert!(parse_color("300,0,0").is_err());
        assert_eq!(parse_domain("0,4095"), Ok([0.0, 4095.0]));
        assert_eq!(
            parse_window("-1000,2000").map(WindowArg::values),
            Ok([-1000.0, 2000.0])
        );
        assert_eq!(
            parse_window("lung").map(WindowArg::values),
            Ok([-1350.0, 150.0])
        );
        assert!(parse_window("lungs").unwrap_err().contains("soft-tissue"));
        assert_eq!(parse_iso("40%"), Ok(IsoArg::Fraction(0.4)));
        assert_eq!(parse_iso("-500"), Ok(IsoArg::Value(-500.0)));
        for bad in ["101%", "-1%", "nan", "x", "inf"] {
            assert!(parse_iso(bad).is_err(), "{bad}");
        }
        assert!(parse_domain("5,5").is_err());
        // Increasing as typed, one value in f32: said so (it blamed the order).
        let e = parse_domain("100,100.0000001").unwrap_err();
        assert!(e.contains("one value at the renderer's precision"), "{e}");
        // volgen's spelling too.
        assert_eq!(parse_domain("-1000:2000"), Ok([-1000.0, 2000.0]));
        // Past f32: said as too large (not as lo ≥ hi, both taken as infinite).
        assert!(
            parse_domain("1e300,1e301")
                .unwrap_err()
                .contains("\"1e300\" is too large")
        );
        assert_eq!(
            parse_window("-1000:2000").map(WindowArg::values),
            Ok([-1000.0, 2000.0])
        );
        assert!(parse_threshold("0").is_err());
        assert!(parse_positive("-1").is_err());
    }

    #[test]
    fn finite_numbers_refuse_nan_infinity_and_overflow_by_name() {
        assert_eq!(parse_finite("-60"), Ok(-60.0));
        assert_eq!(parse_finite(" 1e30 "), Ok(1e30));
        for bad in ["nan", "NaN", "inf", "-inf", "infinity", "x"] {
            assert!(parse_finite(bad).unwrap_err().contains("finite"), "{bad}");
        }
        // Beyond f32: too large, not "inf" (and not "must be finite").
        let e = parse_finite("1e39").unwrap_err();
        assert!(e.contains("\"1e39\" is too large"), "{e}");
        assert!(parse_positive("-1e39").unwrap_err().contains("too large"));
        assert!(parse_positive("1e39").unwrap_err().contains("too large"));
        assert!(parse_positive("0").unwrap_err().contains("positive"));
        assert!(parse_positive("nan").unwrap_err().contains("positive"));
    }
}
