//! Division-of-focal-plane mosaic layouts.
//!
//! A layout names the polarizer transmission axis of each pixel of the repeating 2 x 2 superpixel,
//! in degrees from +x (columns) toward +y (rows, down), see [`crate::angle::SensorAngle`].
//! The IMX250MZR reads `90,45/135,0`: (row 0, col 0) = 90°, (0, 1) = 45°, (1, 0) = 135°, (1, 1) = 0°.

use crate::error::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// The four nominal polarizer angles, indexed by channel: 0 → 0°, 1 → 45°, 2 → 90°, 3 → 135°.
pub const CHANNEL_ANGLES_DEG: [f64; 4] = [0.0, 45.0, 90.0, 135.0];

/// A 2 x 2 polarizer layout: which channel (0°, 45°, 90°, 135°) sits at each superpixel position.
///
/// ```
/// use psns::sensor::mosaic::MosaicLayout;
/// let l = MosaicLayout::IMX250MZR;
/// assert_eq!(l.to_string(), "90,45/135,0");
/// assert_eq!(l.angle_deg(0, 0), 90.0);
/// assert_eq!(l.angle_deg(0, 1), 45.0);
/// assert_eq!(l.angle_deg(1, 0), 135.0);
/// assert_eq!(l.angle_deg(1, 1), 0.0);
/// assert_eq!(l.angle_deg(2047, 2447), 0.0); // odd row, odd column
/// assert_eq!(l.angle_deg(2047, 2446), 135.0); // odd row, even column
/// assert_eq!("90,45/135,0".parse::<MosaicLayout>().unwrap(), l);
/// // where does the 0° channel sit?
/// assert_eq!(l.position_of(0), (1, 1));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MosaicLayout {
    /// channel index (0 = 0°, 1 = 45°, 2 = 90°, 3 = 135°) at positions (0,0), (0,1), (1,0), (1,1).
    channels: [u8; 4],
}

impl MosaicLayout {
    /// Sony IMX250MZR / IMX253MZR: `90,45/135,0`.
    pub const IMX250MZR: MosaicLayout = MosaicLayout {
        channels: [2, 1, 3, 0],
    };

    /// Builds a layout from the channel at (0,0), (0,1), (1,0), (1,1); must be a permutation of 0..4.
    pub fn from_channels(channels: [u8; 4]) -> Result<Self> {
        let mut seen = [false; 4];
        for &c in &channels {
            if c > 3 || seen[c as usize] {
                return Err(Error::Invalid(format!(
                    "mosaic layout channels {channels:?} are not a permutation of 0, 1, 2, 3"
                )));
            }
            seen[c as usize] = true;
        }
        Ok(MosaicLayout { channels })
    }

    /// All 24 permutations (the 8 rotations/reflections of the IMX250MZR pattern among them).
    pub fn all() -> Vec<MosaicLayout> {
        let mut out = Vec::with_capacity(24);
        for a in 0..4u8 {
            for b in 0..4u8 {
                for c in 0..4u8 {
                    for d in 0..4u8 {
                        if let Ok(l) = Self::from_channels([a, b, c, d]) {
                            out.push(l);
                        }
                    }
                }
            }
        }
        out
    }

    /// Channel index (0 = 0°, 1 = 45°, 2 = 90°, 3 = 135°) of the pixel at (row, col).
    #[inline]
    pub fn channel(&self, row: usize, col: usize) -> usize {
        self.channels[((row & 1) << 1) | (col & 1)] as usize
    }

    /// Nominal transmission-axis angle (degrees, from +x toward +y) of the pixel at (row, col).
    #[inline]
    pub fn angle_deg(&self, row: usize, col: usize) -> f64 {
        CHANNEL_ANGLES_DEG[self.channel(row, col)]
    }

    /// Channel at (0,0), (0,1), (1,0), (1,1).
    pub fn channels(&self) -> [u8; 4] {
        self.channels
    }

    /// (row, col) within the superpixel of a channel.
    pub fn position_of(&self, channel: usize) -> (usize, usize) {
        let i = self
            .channels
            .iter()
            .position(|&c| c as usize == channel)
            .expect("layout is a permutation");
        (i >> 1, i & 1)
    }

    /// Angles in degrees at (0,0), (0,1), (1,0), (1,1) (as the stream header stores them).
    pub fn angles_deg(&self) -> [f64; 4] {
        self.channels.map(|c| CHANNEL_ANGLES_DEG[c as usize])
    }
}

impl Default for MosaicLayout {
    fn default() -> Self {
        Self::IMX250MZR
    }
}

impl fmt::Display for MosaicLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.angles_deg();
        write!(f, "{},{}/{},{}", a[0], a[1], a[2], a[3])
    }
}

/// Serialized as its string form, e.g. `"90,45/135,0"`.
impl serde::Serialize for MosaicLayout {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> serde::Deserialize<'de> for MosaicLayout {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let s = <String as serde::Deserialize>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl FromStr for MosaicLayout {
    type Err = Error;
    /// Parses `"90,45/135,0"` (row 0 / row 1, angles 0, 45, 90, 135 each once).
    fn from_str(s: &str) -> Result<Self> {
        let bad = || {
            Error::Invalid(format!(
                "mosaic layout '{s}' is not of the form 'a,b/c,d' with a permutation of 0,45,90,135"
            ))
        };
        let mut ch = [0u8; 4];
        let mut n = 0;
        for row in s.trim().split('/') {
            for v in row.split(',') {
                if n >= 4 {
                    return Err(bad());
                }
                let deg: f64 = v.trim().parse().map_err(|_| bad())?;
                ch[n] = CHANNEL_ANGLES_DEG
                    .iter()
                    .position(|&a| a == deg)
                    .ok_or_else(bad)? as u8;
                n += 1;
            }
        }
        if n != 4 {
            return Err(bad());
        }
        Self::from_channels(ch).map_err(|_| bad())
    }
}
