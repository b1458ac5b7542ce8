//! What stored samples mean: the linear map from a sample to the value the
//! file's source measured (Hounsfield units for CT), kept in the extended
//! header's value block (extension version 3, `docs/format.md`).

use super::header::HeaderError;

/// Length of the value block that follows the 64-byte extended header.
pub const UNITS_BLOCK_LEN: u64 = 64;
/// Magic bytes that open the value block.
const UNITS_MAGIC: [u8; 4] = *b"RCVU";
/// The longest unit text, in UTF-8 bytes.
pub const MAX_UNIT_LEN: usize = 16;
/// The unit of CT scans: Hounsfield units.
pub const HOUNSFIELD: &str = "HU";

/// How a stored sample relates to the value it stands for:
/// `value = stored × scale + offset`, in `unit` ("HU" for CT; empty when unknown).
///
/// An i16 CT scan stored as `HU + 32768` in u16 samples has scale 1, offset
/// −32768 and unit "HU"; a float volume windowed onto u16 has the window's step
/// as scale and its low end as offset. Files without a value block store values
/// as they are (scale 1, offset 0, no unit).
#[derive(Clone, Debug, PartialEq)]
pub struct ValueUnits {
    /// Value per stored step (finite, not zero).
    pub scale: f64,
    /// Value of stored sample 0 (finite).
    pub offset: f64,
    /// The unit's name, at most [`MAX_UNIT_LEN`] UTF-8 bytes, no control characters ("" =
    /// unknown).
    pub unit: String,
}

impl Default for ValueUnits {
    fn default() -> Self {
        ValueUnits::IDENTITY
    }
}

/// `v` as people read it: in scientific notation when far from 1, so that a
/// lying header's spacing of 1e30 prints as that and not as 31 digits
/// (import summaries and errors).
pub fn number_text<T>(v: T) -> String
where
    T: Into<f64> + Copy + std::fmt::Display + std::fmt::LowerExp,
{
    let x: f64 = v.into();
    if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl ValueUnits {
    /// Values are the stored samples themselves.
    pub const IDENTITY: ValueUnits = ValueUnits {
        scale: 1.0,
        offset: 0.0,
        unit: String::new(),
    };

    /// The map `value = stored × scale + offset` in `unit`, checked.
    pub fn new(scale: f64, offset: f64, unit: &str) -> Result<ValueUnits, HeaderError> {
        let units = ValueUnits {
            scale,
            offset,
            unit: unit.to_string(),
        };
        units.validate()?;
        Ok(units)
    }

    /// Checks that the map is invertible and the unit fits the header.
    pub fn validate(&self) -> Result<(), HeaderError> {
        if !(self.scale.is_finite() && self.scale != 0.0 && self.offset.is_finite()) {
            return Err(HeaderError::BadUnits(format!(
                "scale {} and offset {} must be finite and the scale not zero",
                self.scale, self.offset
            )));
        }
        // (No control characters: a unit is printed to terminals, where an
        // escape sequence in a file would act.)
        if self.unit.len() > MAX_UNIT_LEN || self.unit.chars().any(char::is_control) {
            return Err(HeaderError::BadUnits(format!(
                "unit {:?} must be at most {MAX_UNIT_LEN} bytes of printable text",
                self.unit
            )));
        }
        Ok(())
    }

    /// Whether values are the stored samples (nothing to say about units).
    pub fn is_identity(&self) -> bool {
        self.scale == 1.0 && self.offset == 0.0 && self.unit.is_empty()
    }

    /// Whether the values are Hounsfield units (a CT scan).
    pub fn is_hounsfield(&self) -> bool {
        self.unit == HOUNSFIELD
    }

    /// The value a stored sample stands for.
    pub fn value(&self, stored: f64) -> f64 {
        stored * self.scale + self.offset
    }

    /// The stored sample (fractional) that stands for `value`.
    pub fn stored(&self, value: f64) -> f64 {
        (value - self.offset) / self.scale
    }

    /// `lo..hi` in values converted to stored samples, kept in increasing order
    /// (a negative scale reverses it).
    pub fn stored_range(&self, [lo, hi]: [f32; 2]) -> [f32; 2] {
        let (a, b) = (
            self.stored(f64::from(lo)) as f32,
            self.stored(f64::from(hi)) as f32,
        );
        if a <= b { [a, b] } else { [b, a] }
    }

    /// `value` with its unit, as people read it: `-1000 HU`, `0.25`.
    pub fn format(&self, value: f64) -> String {
        self.format_resolved(value, 1.0)
    }

    /// [`Self::format`] with enough decimals that values `resolution` apart
    /// read differently (at least its four): the edges of histogram bins a
    /// ten-thousandth wide, `3.000006..3.000012`, not `3..3`.
    pub fn format_resolved(&self, value: f64, resolution: f64) -> String {
        // Whole values print without decimals; others with up to 4 significant
        // decimals, or as many as `resolution` asks (half of it shows, so two
        // values that far apart never round to one text).
        let decimals = if resolution.is_finite() && resolution > 0.0 {
            ((-(resolution / 2.0).log10()).ceil().max(0.0) as usize).clamp(4, 15)
        } else {
            4
        };
        let number = if value.is_finite() && value.abs() >= 1e15 {
            // Scientific past what digits show readably (f32 data of ±2e38).
            let text = format!("{value:.4e}");
            let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
            let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
            format!("{mantissa}e{exponent}")
        } else if value.fract() == 0.0 {
            format!("{value:.0}")
        } else {
            let text = format!("{value:.decimals$}");
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        };
        if self.unit.is_empty() {
            number
        } else {
            format!("{number} {}", self.unit)
        }
    }

    /// The map as people read it: `value = stored − 32768 (HU)`,
    /// `value = stored × 16 − 1000`.
    pub fn describe(&self) -> String {
        // A number read from an f32 field (a NIfTI slope) as written there:
        // the shortest f32 text when the f64 is that f32's widening.
        let short = |v: f64| {
            let f = v as f32;
            if f64::from(f) == v {
                format!("{f}")
            } else {
                format!("{v}")
            }
        };
        let mut text = "value = stored".to_string();
        if self.scale != 1.0 {
            text += &format!(" × {}", short(self.scale));
        }
        if self.offset != 0.0 {
            let sign = if self.offset < 0.0 { '−' } else { '+' };
            text += &format!(" {sign} {}", short(self.offset.abs()));
        }
        if !self.unit.is_empty() {
            text += &format!(" ({})", self.unit);
        }
        text
    }

    /// The value block's bytes (see `docs/format.md`).
    pub(crate) fn encode(&self) -> [u8; UNITS_BLOCK_LEN as usize] {
        let mut out = [0u8; UNITS_BLOCK_LEN as usize];
        out[0..4].copy_from_slice(&UNITS_MAGIC);
        out[8..16].copy_from_slice(&self.scale.to_le_bytes());
        out[16..24].copy_from_slice(&self.offset.to_le_bytes());
        out[24..24 + self.unit.len()].copy_from_slice(self.unit.as_bytes());
        out
    }

    /// Parses a value block.
    pub(crate) fn decode(block: &[u8]) -> Result<ValueUnits, HeaderError> {
        let bad = |what: &str| HeaderError::BadUnits(what.to_string());
        if block.len() < UNITS_BLOCK_LEN as usize {
            return Err(bad("the value block is cut short"));
        }
        if block[0..4] != UNITS_MAGIC {
            return Err(bad("the value block does not start with \"RCVU\""));
        }
        let f64_at = |o: usize| f64::from_le_bytes(block[o..o + 8].try_into().unwrap());
        let text = &block[24..24 + MAX_UNIT_LEN];
        let end = text.iter().position(|&b| b == 0).unwrap_or(MAX_UNIT_LEN);
        if text[end..].iter().any(|&b| b != 0) {
            return Err(bad("the unit text has bytes after its end"));
        }
        let unit = std::str::from_utf8(&text[..end])
            .map_err(|_| bad("the unit text is not UTF-8"))?
            .to_string();
        let units = ValueUnits {
            scale: f64_at(8),
            offset: f64_at(16),
            unit,
        };
        units.validate()?;
        Ok(units)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_round_trips_and_maps_both_ways() {
        let ct = ValueUnits::new(1.0, -32768.0, HOUNSFIELD).unwrap();
        assert_eq!(ValueUnits::decode(&ct.encode()).unwrap(), ct);
        assert_eq!(ct.value(31768.0), -1000.0);
        assert_eq!(ct.stored(2000.0), 34768.0);
        assert_eq!(ct.stored_range([-1000.0, 2000.0]), [31768.0, 34768.0]);
        assert_eq!(ct.format(-1000.0), "-1000 HU");
        assert!(ct.is_hounsfield() && !ct.is_identity());
        let reversed = ValueUnits::new(-0.5, 10.0, "").unwrap();
        assert_eq!(reversed.stored_range([0.0, 10.0]), [0.0, 20.0]);
        assert_eq!(reversed.format(0.25), "0.25");
        // Huge values in scientific notation, not 39 digits.
        let identity = ValueUnits::IDENTITY;
        assert_eq!(identity.format(-1.9999999e38), "-2e38");
        assert_eq!(identity.format(1.2345678e20), "1.2346e20");
        assert_eq!(identity.format(123456789.0), "123456789");
        assert_eq!(identity.format(f64::INFINITY), "inf");
        assert_eq!(number_text(1e30f32), "1e30");
        assert_eq!(number_text(0.5f32), "0.5");
        assert_eq!(number_text(1e-50f64), "1e-50");
        assert_eq!(number_text(0.0f64), "0");
        assert_eq!(number_text(f64::NAN), "NaN");
        assert!(ValueUnits::IDENTITY.is_identity());
        assert_eq!(ct.describe(), "value = stored − 32768 (HU)");
        assert_eq!(
            ValueUnits::new(16.0, 1000.0, "").unwrap().describe(),
            "value = stored × 16 + 1000"
        );
    }

    #[test]
    fn nonsense_is_refused() {
        for (scale, offset, unit) in [
            (0.0, 0.0, ""),
            (f64::NAN, 0.0, ""),
            (1.0, f64::INFINITY, ""),
            (1.0, 0.0, "a unit name far too long"),
            (1.0, 0.0, "a\0b"),
            // An escape sequence (clears a terminal that prints it).
            (1.0, 0.0, "\u{1b}[2J"),
            (1.0, 0.0, "HU\n"),
        ] {
            assert!(ValueUnits::new(scale, offset, unit).is_err(), "{unit:?}");
        }
        let good = ValueUnits::new(2.0, 1.0, "mm").unwrap().encode();
        let mut bad_magic = good;
        bad_magic[0] = b'X';
        let mut trailing = good;
        trailing[24 + 5] = b'x';
        let mut not_utf8 = good;
        not_utf8[24] = 0xff;
        let mut zero_scale = good;
        zero_scale[8..16].copy_from_slice(&0.0f64.to_le_bytes());
        let mut escape = good;
        escape[24] = 0x1b;
        for block in [bad_magic, trailing, not_utf8, zero_scale, escape] {
            assert!(ValueUnits::decode(&block).is_err());
        }
        assert!(ValueUnits::decode(&good[..40]).is_err());
    }
}
