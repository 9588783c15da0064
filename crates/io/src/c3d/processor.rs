//! Number encodings of the three C3D processor types.
//!
//! The C3D manual (chapter "The parameter section", processor type byte) defines:
//! - 84 = Intel: little-endian integers, IEEE-754 floats;
//! - 85 = DEC (VAX): little-endian integers, VAX F-floating floats;
//! - 86 = MIPS (SGI): big-endian integers, big-endian IEEE-754 floats.
//!
//! locap reads all three and always writes Intel, the only type every reader supports
//! (ezc3d, for one, cannot read MIPS files).

/// The processor type of a C3D file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Processor {
    /// Intel (little-endian, IEEE floats). Type byte 84.
    Intel,
    /// DEC / VAX (little-endian integers, VAX F-float). Type byte 85.
    Dec,
    /// MIPS / SGI (big-endian). Type byte 86.
    Mips,
}

impl Processor {
    /// Decodes the parameter-section type byte.
    pub fn from_byte(byte: u8) -> Option<Processor> {
        match byte {
            84 => Some(Processor::Intel),
            85 => Some(Processor::Dec),
            86 => Some(Processor::Mips),
            _ => None,
        }
    }

    /// The parameter-section type byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Processor::Intel => 84,
            Processor::Dec => 85,
            Processor::Mips => 86,
        }
    }

    /// Human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            Processor::Intel => "Intel",
            Processor::Dec => "DEC",
            Processor::Mips => "MIPS/SGI",
        }
    }

    /// Decodes a 16-bit integer.
    pub fn i16(self, b: [u8; 2]) -> i16 {
        match self {
            Processor::Mips => i16::from_be_bytes(b),
            _ => i16::from_le_bytes(b),
        }
    }

    /// Decodes a 16-bit unsigned integer.
    pub fn u16(self, b: [u8; 2]) -> u16 {
        self.i16(b) as u16
    }

    /// Decodes a 32-bit float.
    pub fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Processor::Intel => f32::from_le_bytes(b),
            Processor::Mips => f32::from_be_bytes(b),
            Processor::Dec => dec_to_ieee(b),
        }
    }
}

/// Converts a VAX F-floating number to IEEE-754.
///
/// A VAX F-float is stored as two little-endian 16-bit words with the *high* word first; its
/// exponent bias is 128 (IEEE: 127) and its mantissa is `0.1f` (IEEE: `1.f`), so swapping the
/// words and dividing by 4 gives the IEEE value. A zero exponent means zero in VAX.
fn dec_to_ieee(b: [u8; 4]) -> f32 {
    let swapped = [b[2], b[3], b[0], b[1]];
    let bits = u32::from_le_bytes(swapped);
    if bits & 0x7f80_0000 == 0 {
        return 0.0;
    }
    f32::from_bits(bits) / 4.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dec_float_known_values() {
        // VAX F-float 1.0 is stored as bytes 80 40 00 00.
        assert_eq!(Processor::Dec.f32([0x80, 0x40, 0x00, 0x00]), 1.0);
        // -2.5: IEEE 0xC0200000 -> VAX words (0xC120, 0x0000) stored LE: 20 C1 00 00.
        assert_eq!(Processor::Dec.f32([0x20, 0xC1, 0x00, 0x00]), -2.5);
        assert_eq!(Processor::Dec.f32([0, 0, 0, 0]), 0.0);
        assert_eq!(Processor::Mips.i16([0x01, 0x02]), 0x0102);
        assert_eq!(Processor::Intel.i16([0x01, 0x02]), 0x0201);
    }
}
