//! Decoding raw sample bytes of the types users bring (u8, u16, i16, f32).

/// The sample type of a raw input file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawType {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit (CT Hounsfield units, for example).
    I16,
    /// 32-bit IEEE float.
    F32,
}

impl std::fmt::Display for RawType {
    /// `u8`, `u16`, `i16`, `f32`: as the tools' flags and messages write types.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RawType::U8 => "u8",
            RawType::U16 => "u16",
            RawType::I16 => "i16",
            RawType::F32 => "f32",
        })
    }
}

impl RawType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            RawType::U8 => 1,
            RawType::U16 | RawType::I16 => 2,
            RawType::F32 => 4,
        }
    }
}

/// Byte order of multi-byte raw samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Endian {
    /// Least significant byte first.
    #[default]
    Little,
    /// Most significant byte first.
    Big,
}

/// Decodes every sample in `bytes` and stores `map(value)` into `out`, in order.
///
/// `bytes.len()` must be `out.len() * ty.size()`.
pub(crate) fn decode_into<O>(
    bytes: &[u8],
    ty: RawType,
    endian: Endian,
    map: &impl Fn(f32) -> O,
    out: &mut [O],
) {
    debug_assert_eq!(bytes.len(), out.len() * ty.size());
    let big = endian == Endian::Big;
    match ty {
        RawType::U8 => {
            for (o, &b) in out.iter_mut().zip(bytes) {
                *o = map(f32::from(b));
            }
        }
        RawType::U16 => {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(2)) {
                let b = [c[0], c[1]];
                let v = if big {
                    u16::from_be_bytes(b)
                } else {
                    u16::from_le_bytes(b)
                };
                *o = map(f32::from(v));
            }
        }
        RawType::I16 => {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(2)) {
                let b = [c[0], c[1]];
                let v = if big {
                    i16::from_be_bytes(b)
                } else {
                    i16::from_le_bytes(b)
                };
                *o = map(f32::from(v));
            }
        }
        RawType::F32 => {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(4)) {
                let b = [c[0], c[1], c[2], c[3]];
                let v = if big {
                    f32::from_be_bytes(b)
                } else {
                    f32::from_le_bytes(b)
                };
                *o = map(v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decodes_each_type_and_byte_order() {
        let mut out = [0f32; 2];
        decode_into(
            &[0x01, 0x02, 0xff, 0xff],
            RawType::I16,
            Endian::Little,
            &|v| v,
            &mut out,
        );
        assert_eq!(out, [513.0, -1.0]);
        decode_into(
            &[0x01, 0x02, 0x00, 0x10],
            RawType::U16,
            Endian::Big,
            &|v| v,
            &mut out,
        );
        assert_eq!(out, [258.0, 16.0]);
        let mut one = [0f32; 1];
        decode_into(
            &1.5f32.to_be_bytes(),
            RawType::F32,
            Endian::Big,
            &|v| v,
            &mut one,
        );
        assert_eq!(one, [1.5]);
    }
}
