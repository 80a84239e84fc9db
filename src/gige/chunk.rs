//! Chunk data: per-frame values appended to the image when ChunkModeActive is on (payload type
//! "image extended chunk", [`crate::gige::gvsp::PAYLOAD_IMAGE_CHUNK`]).
//!
//! The block is a sequence of chunks, each its data followed by an 8-byte trailer: chunk id and
//! data length (both u32 big-endian), so a client walks it from the end. The image is the first
//! chunk ([`IMAGE_CHUNK_ID`]); the enabled chunks follow in [`ChunkKind::ALL`]'s order. Values are
//! big-endian: IEEE doubles, and u64 for the timestamp and the frame index.
//!
//! | ChunkSelector | id | data | features (GenICam) |
//! |---|---|---|---|
//! | ExposureTime | 0x50534E01 | f64, µs | ChunkExposureTime |
//! | Gain | 0x50534E02 | f64, dB | ChunkGain |
//! | Timestamp | 0x50534E03 | u64, ticks (ns) | ChunkTimestamp |
//! | FrameIndex | 0x50534E04 | u64 | ChunkFrameIndex (psns's frame index) |
//! | Attitude | 0x50534E05 | 4 × f64: w, x, y, z | ChunkAttitudeW/X/Y/Z (camera → ENU) |
//! | SunPosition | 0x50534E06 | 2 × f64: azimuth, elevation, ° | ChunkSunAzimuth, ChunkSunElevation |
//! | OffsetX | 0x50534E07 | u32 | ChunkOffsetX |
//! | OffsetY | 0x50534E08 | u32 | ChunkOffsetY |
//! | Width | 0x50534E09 | u32 | ChunkWidth |
//! | Height | 0x50534E0A | u32 | ChunkHeight |
//! | PixelFormat | 0x50534E0B | u32, the format's code | ChunkPixelFormat |
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

impl ChunkKind {
    /// Every chunk, in selector (and block) order.
    pub const ALL: [ChunkKind; 11] = [
        ChunkKind::ExposureTime,
        ChunkKind::Gain,
        ChunkKind::Timestamp,
        ChunkKind::FrameIndex,
        ChunkKind::Attitude,
        ChunkKind::SunPosition,
        ChunkKind::OffsetX,
        ChunkKind::OffsetY,
        ChunkKind::Width,
        ChunkKind::Height,
        ChunkKind::PixelFormat,
    ];

    /// The ChunkSelector entry's name.
    pub fn name(self) -> &'static str {
        match self {
            ChunkKind::ExposureTime => "ExposureTime",
            ChunkKind::Gain => "Gain",
            ChunkKind::Timestamp => "Timestamp",
            ChunkKind::FrameIndex => "FrameIndex",
            ChunkKind::Attitude => "Attitude",
            ChunkKind::SunPosition => "SunPosition",
            ChunkKind::OffsetX => "OffsetX",
            ChunkKind::OffsetY => "OffsetY",
            ChunkKind::Width => "Width",
            ChunkKind::Height => "Height",
            ChunkKind::PixelFormat => "PixelFormat",
        }
    }

    /// The chunk id.
    pub fn id(self) -> u32 {
        IMAGE_CHUNK_ID + 1 + self as u32
    }

    /// Data bytes of the chunk.
    pub fn data_len(self) -> usize {
        match self {
            ChunkKind::Attitude => 32,
            ChunkKind::SunPosition => 16,
            ChunkKind::OffsetX
            | ChunkKind::OffsetY
            | ChunkKind::Width
            | ChunkKind::Height
            | ChunkKind::PixelFormat => 4,
            _ => 8,
        }
    }
}

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
        match k {
            ChunkKind::ExposureTime => out.extend(v.exposure_us.to_be_bytes()),
            ChunkKind::Gain => out.extend(v.gain_db.to_be_bytes()),
            ChunkKind::Timestamp => out.extend(v.timestamp.to_be_bytes()),
            ChunkKind::FrameIndex => out.extend(v.frame_index.to_be_bytes()),
            ChunkKind::Attitude => v
                .attitude_wxyz
                .iter()
                .for_each(|q| out.extend(q.to_be_bytes())),
            ChunkKind::SunPosition => {
                out.extend(v.sun_azimuth_deg.to_be_bytes());
                out.extend(v.sun_elevation_deg.to_be_bytes());
            }
            ChunkKind::OffsetX => out.extend(v.region[0].to_be_bytes()),
            ChunkKind::OffsetY => out.extend(v.region[1].to_be_bytes()),
            ChunkKind::Width => out.extend(v.region[2].to_be_bytes()),
            ChunkKind::Height => out.extend(v.region[3].to_be_bytes()),
            ChunkKind::PixelFormat => out.extend(v.pixel_format.to_be_bytes()),
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
        assert_eq!(c.len(), 12);
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
