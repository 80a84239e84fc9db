//! The pixel formats the device offers: the PFNC Mono formats and LUCID's polarized names for
//! the same bytes (their vendor codes), with the ADC depth each implies.
//!
//! | name | code | bytes as | ADC bits |
//! |---|---|---|---|
//! | Mono8 | 0x01080001 | Mono8 | 8 |
//! | Mono12p | 0x010C0047 | Mono12p | 12 |
//! | Mono12Packed | 0x010C0006 | Mono12Packed | 12 |
//! | Mono16 | 0x01100007 | Mono16 (12 bits, LSB-aligned) | 12 |
//! | PolarizeMono8 | 0x81080001 | Mono8 | 8 |
//! | PolarizeMono12p | 0x810C0047 | Mono12p | 12 |
//! | PolarizeMono12Packed | 0x810C0006 | Mono12Packed | 12 |
//! | PolarizeMono16 | 0x81100007 | Mono16 | 12 |
//!
//! ```
//! use psns::gige::pixel::GevPixelFormat;
//! use psns::sensor::packing::PixelFormat;
//! let f = GevPixelFormat::from_code(0x8108_0001).unwrap();
//! assert_eq!(f.name(), "PolarizeMono8");
//! assert_eq!((f.packing(), f.adc_bits()), (PixelFormat::Mono8, 8));
//! ```

use crate::sensor::packing::PixelFormat;

/// Bits of the real camera's ADC (the IMX250MZR's 12).
const ADC_BITS: u8 = 12;

/// A pixel format of the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GevPixelFormat {
    /// PFNC Mono8.
    Mono8,
    /// PFNC Mono12p.
    Mono12p,
    /// GigE Vision Mono12Packed.
    Mono12Packed,
    /// PFNC Mono16.
    Mono16,
    /// LUCID PolarizeMono8 (Mono8's bytes).
    PolarizeMono8,
    /// LUCID PolarizeMono12p (Mono12p's bytes).
    PolarizeMono12p,
    /// LUCID PolarizeMono12Packed (Mono12Packed's bytes).
    PolarizeMono12Packed,
    /// LUCID PolarizeMono16 (Mono16's bytes).
    PolarizeMono16,
}

// the GenICam enumeration's entries, in its order
crate::names::name_table!(GevPixelFormat {
    Mono8 => "Mono8",
    Mono12p => "Mono12p",
    Mono12Packed => "Mono12Packed",
    Mono16 => "Mono16",
    PolarizeMono8 => "PolarizeMono8",
    PolarizeMono12p => "PolarizeMono12p",
    PolarizeMono12Packed => "PolarizeMono12Packed",
    PolarizeMono16 => "PolarizeMono16",
});

impl GevPixelFormat {
    /// The format's row of the table: the packing of its bytes (the Mono twin), and whether it
    /// is one of LUCID's polarized (vendor) names.
    const fn twin(self) -> (PixelFormat, bool) {
        use GevPixelFormat::*;
        match self {
            Mono8 => (PixelFormat::Mono8, false),
            Mono12p => (PixelFormat::Mono12p, false),
            Mono12Packed => (PixelFormat::Mono12Packed, false),
            Mono16 => (PixelFormat::Mono16, false),
            PolarizeMono8 => (PixelFormat::Mono8, true),
            PolarizeMono12p => (PixelFormat::Mono12p, true),
            PolarizeMono12Packed => (PixelFormat::Mono12Packed, true),
            PolarizeMono16 => (PixelFormat::Mono16, true),
        }
    }

    /// The packing of the bytes (the Mono twin).
    pub fn packing(self) -> PixelFormat {
        self.twin().0
    }

    /// Whether this is one of the polarized (vendor) names.
    pub fn polarized(self) -> bool {
        self.twin().1
    }

    /// The code in the PixelFormat register and the stream leader: PFNC for the Mono names,
    /// LUCID's vendor code (PFNC's with the top bit set) for the polarized ones.
    pub fn code(self) -> u32 {
        let vendor = if self.polarized() { 0x8000_0000 } else { 0 };
        self.packing().pfnc_code() | vendor
    }

    /// The format with this register code.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.code() == code)
    }

    /// ADC depth in bits on the real camera: its ADC's 12 bits, or fewer when the format holds
    /// fewer (8 for the 8-bit formats).
    pub fn adc_bits(self) -> u8 {
        self.packing().container_bits().min(ADC_BITS)
    }

    /// Payload bytes of a `width` x `height` image (`None` on overflow).
    pub fn image_bytes(self, width: usize, height: usize) -> Option<usize> {
        crate::sensor::packing::payload_size_checked(self.packing(), width, height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lucid_codes() {
        let c: Vec<u32> = GevPixelFormat::ALL.iter().map(|f| f.code()).collect();
        assert_eq!(
            c,
            [
                0x0108_0001,
                0x010C_0047,
                0x010C_0006,
                0x0110_0007,
                0x8108_0001,
                0x810C_0047,
                0x810C_0006,
                0x8110_0007
            ]
        );
        for f in GevPixelFormat::ALL {
            assert_eq!(GevPixelFormat::from_code(f.code()), Some(f));
            assert_eq!(f.polarized(), f.name().starts_with("Polarize"));
        }
        assert_eq!(
            GevPixelFormat::Mono12Packed.image_bytes(2448, 2048),
            Some(7_520_256)
        );
    }

    /// The device offers every stream pixel format, under its PFNC name and LUCID's polarized
    /// one, with the PFNC code.
    #[test]
    fn every_pixel_format_has_its_two_names() {
        for p in PixelFormat::ALL {
            let twins: Vec<GevPixelFormat> = GevPixelFormat::ALL
                .into_iter()
                .filter(|g| g.packing() == p)
                .collect();
            let names: Vec<&str> = twins.iter().map(|g| g.name()).collect();
            let polarized = format!("Polarize{}", p.pfnc_name());
            assert_eq!(names, [p.pfnc_name(), polarized.as_str()], "{p}");
            assert_eq!(twins[0].code(), p.pfnc_code(), "{p}");
        }
    }
}
