//! The 512-byte C3D header and the processor-dependent number encodings.

use crate::FormatError;

/// Size of a C3D block in bytes: the header, parameter and data sections are counted in blocks.
pub const BLOCK: usize = 512;
/// Byte 1 of every C3D file: the parameter-section key.
pub const KEY: u8 = 0x50;

/// The machine a file was written on, from byte 3 of the parameter section (83 + type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Processor {
    /// 84: little-endian integers, IEEE floats.
    Intel,
    /// 85: little-endian integers, VAX F-floats.
    Dec,
    /// 86: big-endian integers and IEEE floats.
    Mips,
}

impl Processor {
    /// From the parameter section's processor byte.
    pub fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            84 => Some(Processor::Intel),
            85 => Some(Processor::Dec),
            86 => Some(Processor::Mips),
            _ => None,
        }
    }

    /// The processor byte written in the parameter section.
    pub fn byte(self) -> u8 {
        match self {
            Processor::Intel => 84,
            Processor::Dec => 85,
            Processor::Mips => 86,
        }
    }

    /// Lower-case name as stored in [`crate::CaptureInfo::processor`].
    pub fn name(self) -> &'static str {
        match self {
            Processor::Intel => "intel",
            Processor::Dec => "dec",
            Processor::Mips => "mips",
        }
    }

    /// A 16-bit word as signed.
    #[inline(always)]
    pub fn i16(self, b: [u8; 2]) -> i16 {
        match self {
            Processor::Mips => i16::from_be_bytes(b),
            _ => i16::from_le_bytes(b),
        }
    }

    /// A 16-bit word as unsigned (C3D counts such as DATA_START and USED are unsigned).
    #[inline(always)]
    pub fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Processor::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }

    /// A 32-bit float in this processor's layout.
    #[inline(always)]
    pub fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Processor::Intel => f32::from_le_bytes(b),
            Processor::Mips => f32::from_be_bytes(b),
            Processor::Dec => vax_f32(b),
        }
    }
}

/// Decodes a VAX F-float as stored on disk (two little-endian 16-bit words, high word first).
///
/// Layout after swapping the words: sign(1) exponent(8, bias 128) fraction(23) with the
/// hidden bit at 0.5, i.e. value = (1 + f/2^23) · 2^(e − 129); exponent 0 is zero.
/// Computed in f64 so the largest VAX values (exponent 255) stay finite.
#[inline(always)]
pub fn vax_f32(b: [u8; 4]) -> f32 {
    let bits = u32::from_le_bytes([b[2], b[3], b[0], b[1]]);
    let exponent = (bits >> 23) & 0xff;
    if exponent == 0 {
        return 0.0;
    }
    if exponent > 2 && exponent < 255 {
        // The common case: an IEEE float with the exponent lowered by 2 is exact.
        return f32::from_bits(bits - (2 << 23));
    }
    let fraction = f64::from(bits & 0x7f_ffff) / f64::from(1u32 << 23);
    let magnitude = (1.0 + fraction) * 2f64.powi(exponent as i32 - 129);
    let value = if bits >> 31 == 1 {
        -magnitude
    } else {
        magnitude
    };
    value as f32
}

/// Encodes a float as a VAX F-float (for tests of the DEC reader).
#[cfg(test)]
pub fn to_vax(v: f32) -> [u8; 4] {
    if v == 0.0 {
        return [0; 4];
    }
    let bits = v.to_bits() + (2 << 23);
    let le = bits.to_le_bytes();
    [le[2], le[3], le[0], le[1]]
}

/// Reads `N` bytes at `offset`, or `None` past the end.
#[inline(always)]
pub fn take<const N: usize>(bytes: &[u8], offset: usize) -> Option<[u8; N]> {
    let end = offset.checked_add(N)?;
    bytes.get(offset..end)?.try_into().ok()
}

/// The header fields we use (C3D spec, words 1–12 of block 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Word 1, byte 1: block number (1-based) of the first parameter block.
    pub parameter_block: u8,
    /// Word 2: number of points (markers) per frame.
    pub points: u16,
    /// Word 3: analog values per frame (channels × samples per frame).
    pub analog_values: u16,
    /// Word 4: number of the first frame (1-based).
    pub first_frame: u16,
    /// Word 5: number of the last frame (wraps past 65535; the parameters then hold it).
    pub last_frame: u16,
    /// Words 7–8: point scale; negative means float storage.
    pub scale: f32,
    /// Word 9: block number (1-based) where point data starts.
    pub data_start: u16,
    /// Word 10: analog samples per frame per channel.
    pub analog_per_frame: u16,
    /// Words 11–12: frame rate in Hz.
    pub frame_rate: f32,
}

impl Header {
    /// Reads the header once the processor (from the parameter section) is known.
    pub fn read(bytes: &[u8], p: Processor) -> Result<Self, FormatError> {
        let short = || {
            FormatError::new(
                format!("byte {} (header)", bytes.len()),
                format!(
                    "file is {} bytes; a C3D file starts with a {BLOCK}-byte header",
                    bytes.len()
                ),
            )
        };
        let word = |i: usize| take::<2>(bytes, 2 * i).map(|b| p.u16(b)).ok_or_else(short);
        let float = |i: usize| take::<4>(bytes, 2 * i).map(|b| p.f32(b)).ok_or_else(short);
        let [parameter_block, _key] = take::<2>(bytes, 0).ok_or_else(short)?;
        Ok(Header {
            parameter_block,
            points: word(1)?,
            analog_values: word(2)?,
            first_frame: word(3)?,
            last_frame: word(4)?,
            scale: float(6)?,
            data_start: word(8)?,
            analog_per_frame: word(9)?,
            frame_rate: float(10)?,
        })
    }

    /// Frame count the header implies (last − first + 1), 0 when last < first.
    pub fn frames(&self) -> u32 {
        (u32::from(self.last_frame) + 1).saturating_sub(u32::from(self.first_frame))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vax_round_trips_ordinary_values() {
        for v in [1.0f32, -2.5, 0.083_333_336, 1234.567, -0.000_123, 3.0e30] {
            assert_eq!(vax_f32(to_vax(v)), v, "{v}");
        }
        assert_eq!(vax_f32([0, 0, 0, 0]), 0.0);
    }

    #[test]
    fn vax_one_is_0x4080_high_word() {
        // VAX 1.0 is 0x40800000 as a longword, stored high word first, each word little-endian.
        assert_eq!(vax_f32([0x80, 0x40, 0x00, 0x00]), 1.0);
    }

    #[test]
    fn vax_extreme_exponents_stay_finite() {
        let big = vax_f32([0xff, 0x7f, 0xff, 0xff]);
        assert!(big.is_finite() && big > 1.0e38, "{big}");
        let tiny = vax_f32([0x80, 0x00, 0x00, 0x00]);
        assert!(tiny > 0.0 && tiny < 1.0e-38, "{tiny}");
    }
}
