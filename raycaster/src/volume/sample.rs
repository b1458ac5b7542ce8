//! The sample types a volume can store, behind one trait.

use super::header::SampleType;

/// A stored sample type (u8 or u16): plain old data, read straight from the file.
pub trait Sample: bytemuck::Pod + Copy + Ord + Send + Sync + std::fmt::Debug + 'static {
    /// The header's name for this type.
    const TYPE: SampleType;
    /// Widens to u16 without changing the value.
    fn to_u16(self) -> u16;
    /// Narrows from u16, saturating at the type's maximum.
    fn from_u16_saturating(v: u16) -> Self;
    /// Quantises a value in `[0, 1]` (clamped) to the full range of the type.
    fn from_unit(v: f32) -> Self;
}

impl Sample for u8 {
    const TYPE: SampleType = SampleType::U8;
    fn to_u16(self) -> u16 {
        u16::from(self)
    }
    fn from_u16_saturating(v: u16) -> Self {
        v.min(u16::from(u8::MAX)) as u8
    }
    #[inline]
    #[allow(clippy::manual_clamp)] // max/min, not clamp: NaN must become 0, not NaN
    fn from_unit(v: f32) -> Self {
        // max/min instead of clamp: NaN becomes 0 and the loop vectorises.
        (v * 255.0 + 0.5).max(0.0).min(255.0) as u8
    }
}

impl Sample for u16 {
    const TYPE: SampleType = SampleType::U16;
    fn to_u16(self) -> u16 {
        self
    }
    fn from_u16_saturating(v: u16) -> Self {
        v
    }
    #[inline]
    #[allow(clippy::manual_clamp)] // as for u8: NaN must become 0
    fn from_unit(v: f32) -> Self {
        (v * 65535.0 + 0.5).max(0.0).min(65535.0) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_quantisation_hits_both_ends() {
        assert_eq!(u8::from_unit(0.0), 0);
        assert_eq!(u8::from_unit(1.0), 255);
        assert_eq!(u8::from_unit(0.5), 128);
        assert_eq!(u16::from_unit(2.0), 65535);
        assert_eq!(u8::from_unit(f32::NAN), 0);
        assert_eq!(u8::from_unit(-3.0), 0);
        assert_eq!(u16::from_unit(0.5), 32768);
        assert_eq!(u8::from_u16_saturating(300), 255);
    }
}
