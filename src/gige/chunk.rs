//! Chunk data: per-frame values appended to the image when ChunkModeActive is on (payload type
//! "image extended chunk", [`crate::gige::gvsp::PAYLOAD_IMAGE_CHUNK`]).
//!
//! The block is a sequence of chunks, each its data followed by an 8-byte trailer: chunk id and
//! data length (both u32 big-endian), so a client walks it from the end. The image is the first
//! chunk ([`IMAGE_CHUNK_ID`]); the enabled chunks follow in [`ChunkKind::ALL`]'s order. Values are
//! big-endian: IEEE doubles and unsigned integers of 8 or 4 bytes.
//!
//! Every chunk is its ChunkSelector name in the name table of [`ChunkKind`] and one row of the
//! table in [`ChunkKind::chunk`]: its GenICam features, each a field of the data with its type,
//! unit and description. The encoding ([`append`]), the data lengths, the GenICam XML's chunk
//! features and the table in `docs/gige.md` all come from them.
//!
//! ```
//! use psns::gige::chunk::{append, chunks, ChunkKind, ChunkValues, IMAGE_CHUNK_ID};
//! let image = [7u8; 6];
//! let mut tail = Vec::new();
//! let v = ChunkValues { gain_db: 6.0, ..Default::default() };
//! append(&mut tail, image.len(), 1 << ChunkKind::Gain as u32, &v);
//! let block = [&image[..], &tail].concat();
//! let found = chunks(&block).unwrap();
//! assert_eq!(found[0], (ChunkKind::Gain.id(), &6.0f64.to_be_bytes()[..]));
//! assert_eq!(found[1], (IMAGE_CHUNK_ID, &image[..]));
//! ```

/// Chunk id of the image.
pub const IMAGE_CHUNK_ID: u32 = 0x5053_4E00;
/// Length of a chunk's trailer (id and length).
pub const TRAILER_LEN: usize = 8;

/// The chunks the device can add.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum ChunkKind {
    /// Exposure time of the frame, µs.
    ExposureTime = 0,
    /// Analog gain, dB.
    Gain = 1,
    /// Device timestamp of the frame (the leader's), ticks.
    Timestamp = 2,
    /// psns's frame index (block id k carries frame index k − 1).
    FrameIndex = 3,
    /// Attitude quaternion, camera to ENU, w x y z.
    Attitude = 4,
    /// Sun azimuth and elevation at mid-exposure, degrees.
    SunPosition = 5,
    /// First column of the region.
    OffsetX = 6,
    /// First row of the region.
    OffsetY = 7,
    /// Width of the region.
    Width = 8,
    /// Height of the region.
    Height = 9,
    /// Pixel format code.
    PixelFormat = 10,
}

/// A field of a chunk's data: its type, and where [`ChunkValues`] keeps its value. Every field
/// is big-endian.
#[derive(Clone, Copy, Debug)]
pub enum ChunkField {
    /// An IEEE double (a GenICam FloatReg).
    F64(fn(&ChunkValues) -> f64),
    /// An 8-byte unsigned integer (an IntReg).
    U64(fn(&ChunkValues) -> u64),
    /// A 4-byte unsigned integer (an IntReg).
    U32(fn(&ChunkValues) -> u32),
    /// A pixel format code, 4 bytes (an Enumeration of the device's pixel formats).
    PixelFormat(fn(&ChunkValues) -> u32),
}

impl ChunkField {
    /// Bytes of the field.
    pub const fn bytes(self) -> usize {
        match self {
            ChunkField::F64(_) | ChunkField::U64(_) => 8,
            ChunkField::U32(_) | ChunkField::PixelFormat(_) => 4,
        }
    }

    /// The type as `docs/gige.md` names it: `f64`, `u64` or `u32`.
    pub const fn type_name(self) -> &'static str {
        match self {
            ChunkField::F64(_) => "f64",
            ChunkField::U64(_) => "u64",
            ChunkField::U32(_) | ChunkField::PixelFormat(_) => "u32",
        }
    }

    /// Appends the field's value in `v`, big-endian.
    fn write(self, v: &ChunkValues, out: &mut Vec<u8>) {
        match self {
            ChunkField::F64(f) => out.extend(f(v).to_be_bytes()),
            ChunkField::U64(f) => out.extend(f(v).to_be_bytes()),
            ChunkField::U32(f) | ChunkField::PixelFormat(f) => out.extend(f(v).to_be_bytes()),
        }
    }
}

/// A GenICam feature of a chunk: one field of its data, in the data's order.
#[derive(Clone, Copy, Debug)]
pub struct ChunkFeature {
    /// The feature's name, e.g. `ChunkAttitudeW`.
    pub name: &'static str,
    /// Its type and value.
    pub field: ChunkField,
    /// Its unit, if it has one.
    pub unit: Option<&'static str>,
    /// What it is, without the unit.
    pub what: &'static str,
}

impl ChunkFeature {
    /// The feature's tooltip in the GenICam XML: what it is, then its unit.
    pub fn tip(&self) -> String {
        match self.unit {
            Some(u) => format!("{}, {u}.", self.what),
            None => format!("{}.", self.what),
        }
    }
}

/// The descriptor of a chunk: its features (its ChunkSelector name is [`ChunkKind::name`]).
#[derive(Clone, Copy, Debug)]
pub struct Chunk {
    /// Whether the features are SFNC's (GenICam namespace Standard) or psns's own (Custom).
    pub sfnc: bool,
    /// The features, one per field of the data, in the data's order.
    pub features: &'static [ChunkFeature],
}

impl Chunk {
    /// Data bytes of the chunk: the sum of its fields.
    pub fn data_len(&self) -> usize {
        self.features.iter().map(|f| f.field.bytes()).sum()
    }

    /// Each feature with its byte offset in the chunk's data.
    pub fn layout(&self) -> impl Iterator<Item = (usize, &'static ChunkFeature)> {
        let features: &'static [ChunkFeature] = self.features;
        features.iter().scan(0, |at, f| {
            let here = *at;
            *at += f.field.bytes();
            Some((here, f))
        })
    }
}

/// A [`ChunkFeature`] literal, `feature!(name, field, unit, what)` (a literal, not a call, so
/// that the table is a constant).
macro_rules! feature {
    ($name:literal, $field:expr, $unit:expr, $what:expr $(,)?) => {
        ChunkFeature {
            name: $name,
            field: $field,
            unit: $unit,
            what: $what,
        }
    };
}

const ATTITUDE: &str = "Attitude quaternion of the camera, camera to ENU (w, x, y, z)";
const REGION: &str = "Region of the frame";

// the ChunkSelector entries, in selector (and block) order: `ALL` and `name()`
crate::names::name_table!(ChunkKind {
    ExposureTime => "ExposureTime",
    Gain => "Gain",
    Timestamp => "Timestamp",
    FrameIndex => "FrameIndex",
    Attitude => "Attitude",
    SunPosition => "SunPosition",
    OffsetX => "OffsetX",
    OffsetY => "OffsetY",
    Width => "Width",
    Height => "Height",
    PixelFormat => "PixelFormat",
});

impl ChunkKind {
    /// The chunk's descriptor: the one table of the chunks.
    pub const fn chunk(self) -> &'static Chunk {
        use ChunkField as F;
        match self {
            ChunkKind::ExposureTime => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkExposureTime",
                    F::F64(|v| v.exposure_us),
                    Some("us"),
                    "Exposure time of the frame",
                )],
            },
            ChunkKind::Gain => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkGain",
                    F::F64(|v| v.gain_db),
                    Some("dB"),
                    "Gain of the frame",
                )],
            },
            ChunkKind::Timestamp => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkTimestamp",
                    F::U64(|v| v.timestamp),
                    Some("ticks"),
                    "Timestamp of the frame (the leader's)"
                )],
            },
            ChunkKind::FrameIndex => &Chunk {
                sfnc: false,
                features: &[feature!(
                    "ChunkFrameIndex",
                    F::U64(|v| v.frame_index),
                    None,
                    "psns's frame index (block id k carries frame k - 1)",
                )],
            },
            ChunkKind::Attitude => &Chunk {
                sfnc: false,
                features: &[
                    feature!(
                        "ChunkAttitudeW",
                        F::F64(|v| v.attitude_wxyz[0]),
                        None,
                        ATTITUDE
                    ),
                    feature!(
                        "ChunkAttitudeX",
                        F::F64(|v| v.attitude_wxyz[1]),
                        None,
                        ATTITUDE
                    ),
                    feature!(
                        "ChunkAttitudeY",
                        F::F64(|v| v.attitude_wxyz[2]),
                        None,
                        ATTITUDE
                    ),
                    feature!(
                        "ChunkAttitudeZ",
                        F::F64(|v| v.attitude_wxyz[3]),
                        None,
                        ATTITUDE
                    ),
                ],
            },
            ChunkKind::SunPosition => &Chunk {
                sfnc: false,
                features: &[
                    feature!(
                        "ChunkSunAzimuth",
                        F::F64(|v| v.sun_azimuth_deg),
                        Some("degrees from north"),
                        "Sun azimuth at mid-exposure",
                    ),
                    feature!(
                        "ChunkSunElevation",
                        F::F64(|v| v.sun_elevation_deg),
                        Some("degrees"),
                        "Sun elevation at mid-exposure",
                    ),
                ],
            },
            ChunkKind::OffsetX => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkOffsetX",
                    F::U32(|v| v.region[0]),
                    None,
                    REGION
                )],
            },
            ChunkKind::OffsetY => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkOffsetY",
                    F::U32(|v| v.region[1]),
                    None,
                    REGION
                )],
            },
            ChunkKind::Width => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkWidth",
                    F::U32(|v| v.region[2]),
                    None,
                    REGION
                )],
            },
            ChunkKind::Height => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkHeight",
                    F::U32(|v| v.region[3]),
                    None,
                    REGION
                )],
            },
            ChunkKind::PixelFormat => &Chunk {
                sfnc: true,
                features: &[feature!(
                    "ChunkPixelFormat",
                    F::PixelFormat(|v| v.pixel_format),
                    None,
                    "Pixel format of the frame",
                )],
            },
        }
    }

    /// The chunk id.
    pub fn id(self) -> u32 {
        IMAGE_CHUNK_ID + 1 + self as u32
    }

    /// Data bytes of the chunk.
    pub fn data_len(self) -> usize {
        self.chunk().data_len()
    }
}

// `ALL` lists the chunks in the order of their selector values (and mask bits), each once
const _: () = {
    let mut i = 0;
    while i < ChunkKind::ALL.len() {
        assert!(ChunkKind::ALL[i] as usize == i);
        i += 1;
    }
};

/// Mask of every chunk kind.
pub const ALL_MASK: u32 = (1 << ChunkKind::ALL.len()) - 1;

/// A frame's chunk values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ChunkValues {
    /// Exposure, µs.
    pub exposure_us: f64,
    /// Gain, dB.
    pub gain_db: f64,
    /// Device timestamp, ticks.
    pub timestamp: u64,
    /// psns frame index.
    pub frame_index: u64,
    /// Camera-to-ENU quaternion w, x, y, z.
    pub attitude_wxyz: [f64; 4],
    /// Sun azimuth, degrees from north.
    pub sun_azimuth_deg: f64,
    /// Sun elevation, degrees.
    pub sun_elevation_deg: f64,
    /// Region: offset x, offset y, width, height.
    pub region: [u32; 4],
    /// Pixel format code.
    pub pixel_format: u32,
}

/// Bytes the chunks of `mask` add after an image: the image's trailer and each enabled chunk's
/// data and trailer.
pub fn tail_len(mask: u32) -> usize {
    TRAILER_LEN
        + ChunkKind::ALL
            .iter()
            .filter(|k| mask & (1 << **k as u32) != 0)
            .map(|k| k.data_len() + TRAILER_LEN)
            .sum::<usize>()
}

fn trailer(out: &mut Vec<u8>, id: u32, len: usize) {
    out.extend(id.to_be_bytes());
    out.extend((len as u32).to_be_bytes());
}

/// Appends what follows an `image_len`-byte image in a chunk block: the image chunk's trailer,
/// then the chunks of `mask` ([`tail_len`] bytes).
pub fn append(out: &mut Vec<u8>, image_len: usize, mask: u32, v: &ChunkValues) {
    trailer(out, IMAGE_CHUNK_ID, image_len);
    for k in ChunkKind::ALL {
        if mask & (1 << k as u32) == 0 {
            continue;
        }
        for f in k.chunk().features {
            f.field.write(v, out);
        }
        trailer(out, k.id(), k.data_len());
    }
}

/// The chunks of a block, walked from its end as a client does: (id, data), last chunk first.
/// `None` when a trailer's length runs past the start of the block. Never panics.
pub fn chunks(block: &[u8]) -> Option<Vec<(u32, &[u8])>> {
    let mut out = Vec::new();
    let mut end = block.len();
    while end > 0 {
        if end < TRAILER_LEN {
            return None;
        }
        let t = &block[end - TRAILER_LEN..end];
        let id = u32::from_be_bytes([t[0], t[1], t[2], t[3]]);
        let len = u32::from_be_bytes([t[4], t[5], t[6], t[7]]) as usize;
        let start = (end - TRAILER_LEN).checked_sub(len)?;
        out.push((id, &block[start..end - TRAILER_LEN]));
        end = start;
    }
    Some(out)
}

impl ChunkValues {
    /// The chunk values of the frame `rec`, sent at device time `timestamp` from the region
    /// `region` (offset x, offset y, width, height) in the pixel format `pixel_format` (its code).
    pub fn of_record(
        rec: &crate::record::FrameRecord,
        timestamp: u64,
        region: [u32; 4],
        pixel_format: u32,
    ) -> Self {
        ChunkValues {
            exposure_us: rec.exposure_us,
            gain_db: rec.gain_db,
            timestamp,
            frame_index: rec.frame_index,
            attitude_wxyz: rec.attitude_wxyz,
            sun_azimuth_deg: rec.sun_azimuth_deg,
            sun_elevation_deg: rec.sun_elevation_deg(),
            region,
            pixel_format,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chunk_round_trips() {
        let v = ChunkValues {
            exposure_us: 1234.5,
            gain_db: 3.0,
            timestamp: 0x0102_0304_0506_0708,
            frame_index: 41,
            attitude_wxyz: [0.5, -0.5, 0.5, -0.5],
            sun_azimuth_deg: 200.0,
            sun_elevation_deg: 40.0,
            region: [2, 4, 640, 480],
            pixel_format: 0x0108_0001,
        };
        let image = [1u8; 10];
        let mut tail = Vec::new();
        append(&mut tail, image.len(), ALL_MASK, &v);
        assert_eq!(tail.len(), tail_len(ALL_MASK));
        let block = [&image[..], &tail].concat();
        let c = chunks(&block).unwrap();
        assert_eq!(c.len(), ChunkKind::ALL.len() + 1);
        assert_eq!(c[11], (IMAGE_CHUNK_ID, &image[..]));
        assert_eq!(
            c[0],
            (
                ChunkKind::PixelFormat.id(),
                &0x0108_0001u32.to_be_bytes()[..]
            )
        );
        assert_eq!(c[1].1, 480u32.to_be_bytes());
        assert_eq!(c[4].1, 2u32.to_be_bytes());
        let c = &c[5..];
        let f = |i: usize, at: usize| f64::from_be_bytes(c[i].1[at..at + 8].try_into().unwrap());
        assert_eq!(c[0].0, ChunkKind::SunPosition.id());
        assert_eq!((f(0, 0), f(0, 8)), (200.0, 40.0));
        assert_eq!((f(1, 0), f(1, 24)), (0.5, -0.5));
        assert_eq!(c[2].1, 41u64.to_be_bytes());
        assert_eq!(c[3].1, 0x0102_0304_0506_0708u64.to_be_bytes());
        assert_eq!((f(4, 0), f(5, 0)), (3.0, 1234.5));
        assert_eq!(tail_len(0), 8);
    }

    #[test]
    fn damaged_blocks_do_not_panic() {
        assert_eq!(chunks(&[1, 2, 3]), None);
        assert_eq!(chunks(&[0, 0, 0, 1, 0xFF, 0xFF, 0xFF, 0xFF]), None);
        assert_eq!(chunks(&[]), Some(vec![]));
    }
}
