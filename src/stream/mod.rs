//! Raw frame stream, format v1 (`docs/stream-format.md`, `stream.md`).
//!
//! Layout: `[file header 4096 B] [frame 0: header 256 B | payload P | zero pad] [frame 1] …` with a
//! fixed stride `ceil((256 + P) / 4096) · 4096`, so a regular file memory-maps as one structured
//! array. Little-endian, every field naturally aligned. Both headers end in a CRC-32 (zlib's, via
//! `crc32fast`) of their preceding bytes; each frame header holds the CRC-32 of its payload.
//! The same bytes go to a regular file, a growing file, a FIFO or stdout: the writer never seeks,
//! except that [`FileStreamWriter::finish`] patches the frame count into the header of a regular
//! file. Nothing host-dependent (clock, path, host name) enters the bytes unless the producer sets
//! [`FrameMeta::host_time_ns`].

mod reader;
mod salvage;
mod writer;

pub use reader::{
    extract_frame, find_frame, find_frame_with, verify, verify_with, Damage, Event, Extracted,
    FindOptions, Frame, FrameLocation, RecoverHint, Recovery, StreamReader, VerifyReport,
    VerifyStatus, VerifyTally, HEADER_DAMAGED, REASON_NOT_RECORDED,
};
pub use salvage::Salvage;
pub use writer::{FileStreamWriter, StreamWriter};

use crate::error::{Error, Result};
use crate::record::FrameRecord;
use crate::sensor::mosaic::MosaicLayout;
use crate::sensor::packing::{payload_size_checked, PixelFormat};
use serde::{Deserialize, Serialize};

/// File-header magic `\x89PSNSRAW`.
pub const FILE_MAGIC: [u8; 8] = *b"\x89PSNSRAW";
/// Frame-header magic `\x89PSNSFRM`.
pub const FRAME_MAGIC: [u8; 8] = *b"\x89PSNSFRM";
/// End-record magic `\x89PSNSEND` ([`EndRecord`]).
pub const END_MAGIC: [u8; 8] = *b"\x89PSNSEND";
/// End-record size in bytes.
pub const END_RECORD_SIZE: usize = 256;
/// Longest reason an end record holds, in bytes (longer ones are cut at a character boundary).
pub const END_REASON_MAX: usize = END_RECORD_SIZE - 4 - 24;
/// End-record status: the producer stopped because of a failure.
pub const END_ABORTED: u32 = 1;
/// Format major version (readers reject another major).
pub const VERSION_MAJOR: u16 = 1;
/// Format minor version written (readers accept any minor).
pub const VERSION_MINOR: u16 = 0;
/// File header size in bytes.
pub const FILE_HEADER_SIZE: usize = 4096;
/// Frame header size in bytes.
pub const FRAME_HEADER_SIZE: usize = 256;
/// Offset of the JSON document inside the file header.
pub const JSON_OFFSET: usize = 232;
/// Longest JSON document that fits (up to the header CRC).
pub const JSON_MAX: usize = FILE_HEADER_SIZE - 4 - JSON_OFFSET;
/// Largest payload a reader accepts (guards against absurd sizes in crafted headers).
pub const MAX_PAYLOAD: u64 = 1 << 30;

/// Frame flag: frames were dropped before this one (index gap).
pub const FLAG_DROPPED: u32 = 1 << 0;
/// Frame flag: some pixels at the maximum code.
pub const FLAG_SATURATION: u32 = 1 << 1;
/// Frame flag: exposure clipped to its range or the frame period.
pub const FLAG_EXPOSURE_CLIPPED: u32 = 1 << 2;
/// Frame flag: sun below the horizon or sky-model domain left (scene rendered dark).
pub const FLAG_SKY_INVALID: u32 = 1 << 3;
/// Frame flag: sun disc in the field of view.
pub const FLAG_SUN_IN_VIEW: u32 = 1 << 4;
/// Frame flag: ground in the field of view.
pub const FLAG_GROUND_IN_VIEW: u32 = 1 << 5;
/// Frame flag: exposure chosen by auto-exposure.
pub const FLAG_AUTO_EXPOSURE: u32 = 1 << 6;
/// Frame flag: last frame of the stream.
pub const FLAG_LAST: u32 = 1 << 7;
/// Frame flag: bytes 200..224 hold the fraction of the image in each class (a world around the
/// camera; [`FrameMeta::class_fractions`]).
pub const FLAG_CLASSES: u32 = 1 << 8;

/// CRC-32 (IEEE, zlib's) of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    crc32fast::hash(data)
}

/// Frame stride of a payload of `p` bytes: `ceil((256 + p) / 4096) · 4096`.
pub fn stride_for(p: u64) -> u64 {
    (FRAME_HEADER_SIZE as u64 + p).div_ceil(FILE_HEADER_SIZE as u64) * FILE_HEADER_SIZE as u64
}

/// Camera constants stored in the file header (informative; readers do not need them).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraConstants {
    /// Pixel pitch, µm.
    pub pixel_pitch_um: f64,
    /// Focal length, mm.
    pub focal_length_mm: f64,
    /// f-number.
    pub f_number: f64,
    /// Filter centre wavelength, nm.
    pub wavelength_nm: f64,
    /// Filter bandwidth, nm.
    pub bandwidth_nm: f64,
    /// Full-well capacity, e⁻.
    pub full_well_e: f64,
    /// Conversion gain K₀ at 0 dB and 12 bit, DN/e⁻.
    pub k0_dn_per_e: f64,
    /// Read noise, e⁻.
    pub read_noise_e: f64,
    /// Principal point column, 0-based pixels.
    pub principal_col: f64,
    /// Principal point row, 0-based pixels.
    pub principal_row: f64,
}

impl Default for CameraConstants {
    fn default() -> Self {
        CameraConstants {
            pixel_pitch_um: 3.45,
            focal_length_mm: 4.0,
            f_number: 2.0,
            wavelength_nm: 450.0,
            bandwidth_nm: 40.0,
            full_well_e: 10_500.0,
            k0_dn_per_e: 4095.0 / 10_500.0,
            read_noise_e: 2.5,
            principal_col: 1223.5,
            principal_row: 1023.5,
        }
    }
}

impl CameraConstants {
    fn to_array(self) -> [f64; 10] {
        [
            self.pixel_pitch_um,
            self.focal_length_mm,
            self.f_number,
            self.wavelength_nm,
            self.bandwidth_nm,
            self.full_well_e,
            self.k0_dn_per_e,
            self.read_noise_e,
            self.principal_col,
            self.principal_row,
        ]
    }
    fn from_array(a: [f64; 10]) -> Self {
        CameraConstants {
            pixel_pitch_um: a[0],
            focal_length_mm: a[1],
            f_number: a[2],
            wavelength_nm: a[3],
            bandwidth_nm: a[4],
            full_well_e: a[5],
            k0_dn_per_e: a[6],
            read_noise_e: a[7],
            principal_col: a[8],
            principal_row: a[9],
        }
    }
}

/// The 4096-byte file header (sensor description).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FileHeader {
    /// Minor version (written as [`VERSION_MINOR`]; any value is accepted on read).
    pub version_minor: u16,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Payload pixel format.
    pub pixel_format: PixelFormat,
    /// Valid bits of each stored value (8 for Mono8; the sensor bit depth otherwise).
    pub bits_valid: u8,
    /// Mono16 only: values shifted left by 16 − `bits_valid`.
    pub msb_aligned: bool,
    /// Polarizer layout of the 2 x 2 superpixel.
    pub layout: MosaicLayout,
    /// Angle sense: +1 = from +x (columns) toward +y (rows, down); −1 the other way.
    pub angle_sense: i16,
    /// Frames in the file; 0 = unknown (stream, or the writer did not close).
    pub frame_count: u64,
    /// The producer stopped because of a failure (offset 46; set on close of a regular file
    /// whose run failed, with the frame count left 0). The reason is in the [`EndRecord`].
    #[serde(default)]
    pub aborted: bool,
    /// Camera seed.
    pub seed: u64,
    /// Camera constants.
    pub camera: CameraConstants,
    /// Producer and version, at most 31 bytes UTF-8.
    pub producer: String,
    /// Preset name, at most 31 bytes UTF-8.
    pub preset: String,
    /// Configuration JSON (at most [`JSON_MAX`] bytes), empty if none.
    pub json: String,
}

impl Default for FileHeader {
    fn default() -> Self {
        FileHeader {
            version_minor: VERSION_MINOR,
            width: 2448,
            height: 2048,
            pixel_format: PixelFormat::Mono16,
            bits_valid: 12,
            msb_aligned: false,
            layout: MosaicLayout::IMX250MZR,
            angle_sense: 1,
            frame_count: 0,
            aborted: false,
            seed: 0,
            camera: CameraConstants::default(),
            producer: format!("psns {}", env!("CARGO_PKG_VERSION")),
            preset: "camera".into(),
            json: String::new(),
        }
    }
}

fn put<const N: usize>(b: &mut [u8], off: usize, v: [u8; N]) {
    b[off..off + N].copy_from_slice(&v);
}
fn get<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    b[off..off + N].try_into().expect("fixed offset")
}
fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes(get(b, o))
}
fn i16_at(b: &[u8], o: usize) -> i16 {
    i16::from_le_bytes(get(b, o))
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(get(b, o))
}
fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(get(b, o))
}
fn i64_at(b: &[u8], o: usize) -> i64 {
    i64::from_le_bytes(get(b, o))
}
fn f64_at(b: &[u8], o: usize) -> f64 {
    f64::from_le_bytes(get(b, o))
}
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(get(b, o))
}

fn put_str(b: &mut [u8], off: usize, s: &str, what: &str) -> Result<()> {
    if s.len() > 31 || s.contains('\0') {
        return Err(Error::Invalid(format!(
            "stream header {what} '{s}' must be at most 31 bytes without NUL"
        )));
    }
    b[off..off + s.len()].copy_from_slice(s.as_bytes());
    Ok(())
}

fn get_str(b: &[u8], off: usize, what: &str) -> Result<String> {
    let f = &b[off..off + 32];
    let end = f.iter().position(|&c| c == 0).unwrap_or(32);
    if f[end..].iter().any(|&c| c != 0) {
        return Err(Error::Format(format!("{what} field is not NUL-padded")));
    }
    String::from_utf8(f[..end].to_vec())
        .map_err(|_| Error::Format(format!("{what} field is not UTF-8")))
}

impl FileHeader {
    /// Payload bytes per frame.
    pub fn payload_size(&self) -> u64 {
        payload_size_checked(self.pixel_format, self.width as usize, self.height as usize)
            .map(|p| p as u64)
            .unwrap_or(u64::MAX)
    }

    /// Frame stride in bytes.
    pub fn stride(&self) -> u64 {
        stride_for(self.payload_size())
    }

    /// Byte offset of frame `i` in a file written without gaps or damage.
    pub fn frame_offset(&self, i: u64) -> u64 {
        FILE_HEADER_SIZE as u64 + i * self.stride()
    }

    /// Checks the header's fields for consistency.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 || self.width > 65_535 || self.height > 65_535 {
            return Err(Error::Invalid(format!(
                "stream frame size {} x {} is out of range (allowed 1..65535 each)",
                self.width, self.height
            )));
        }
        if self.payload_size() > MAX_PAYLOAD {
            return Err(Error::Invalid(format!(
                "stream payload of {} bytes exceeds {MAX_PAYLOAD}",
                self.payload_size()
            )));
        }
        if !self.pixel_format.bits_valid_ok(self.bits_valid as u16) {
            return Err(Error::Invalid(format!(
                "{} with {} valid bits",
                self.pixel_format, self.bits_valid
            )));
        }
        if self.msb_aligned && !self.pixel_format.info().msb_alignable {
            return Err(Error::Invalid(
                "MSB alignment exists only for Mono16".into(),
            ));
        }
        if self.angle_sense != 1 && self.angle_sense != -1 {
            return Err(Error::Invalid(format!(
                "angle sense {} (must be +1 or -1)",
                self.angle_sense
            )));
        }
        if self.json.len() > JSON_MAX || self.json.contains('\0') {
            return Err(Error::Invalid(format!(
                "stream header JSON of {} bytes (at most {JSON_MAX}, no NUL)",
                self.json.len()
            )));
        }
        Ok(())
    }

    /// Encodes the 4096-byte header (with its CRC).
    pub fn encode(&self) -> Result<Vec<u8>> {
        self.validate()?;
        let mut b = vec![0u8; FILE_HEADER_SIZE];
        put(&mut b, 0, FILE_MAGIC);
        put(&mut b, 8, VERSION_MAJOR.to_le_bytes());
        put(&mut b, 10, self.version_minor.to_le_bytes());
        put(&mut b, 12, (FILE_HEADER_SIZE as u32).to_le_bytes());
        put(&mut b, 16, (FRAME_HEADER_SIZE as u32).to_le_bytes());
        put(&mut b, 20, self.width.to_le_bytes());
        put(&mut b, 24, self.height.to_le_bytes());
        put(&mut b, 28, self.pixel_format.pfnc_code().to_le_bytes());
        put(&mut b, 32, (self.bits_valid as u16).to_le_bytes());
        put(&mut b, 34, (self.msb_aligned as u16).to_le_bytes());
        for (k, a) in self.layout.angles_deg().iter().enumerate() {
            put(&mut b, 36 + 2 * k, (*a as i16).to_le_bytes());
        }
        put(&mut b, 44, self.angle_sense.to_le_bytes());
        put(&mut b, 46, (self.aborted as u16).to_le_bytes());
        put(&mut b, 48, self.payload_size().to_le_bytes());
        put(&mut b, 56, self.stride().to_le_bytes());
        put(&mut b, 64, self.frame_count.to_le_bytes());
        put(&mut b, 72, self.seed.to_le_bytes());
        for (k, v) in self.camera.to_array().iter().enumerate() {
            put(&mut b, 80 + 8 * k, v.to_le_bytes());
        }
        put_str(&mut b, 160, &self.producer, "producer")?;
        put_str(&mut b, 192, &self.preset, "preset")?;
        if !self.json.is_empty() {
            put(&mut b, 224, (JSON_OFFSET as u32).to_le_bytes());
            put(&mut b, 228, (self.json.len() as u32).to_le_bytes());
            b[JSON_OFFSET..JSON_OFFSET + self.json.len()].copy_from_slice(self.json.as_bytes());
        }
        let c = crc32(&b[..FILE_HEADER_SIZE - 4]);
        put(&mut b, FILE_HEADER_SIZE - 4, c.to_le_bytes());
        Ok(b)
    }

    /// Decodes and checks a 4096-byte header: magic, major version, sizes, CRC and fields.
    pub fn decode(b: &[u8]) -> Result<Self> {
        if b.len() < FILE_HEADER_SIZE {
            return Err(Error::Format(format!(
                "stream file header truncated: {} of {FILE_HEADER_SIZE} bytes",
                b.len()
            )));
        }
        let b = &b[..FILE_HEADER_SIZE];
        if b[..8] != FILE_MAGIC {
            return Err(Error::Format(
                "not a psns stream (file-header magic missing)".into(),
            ));
        }
        let crc = u32_at(b, FILE_HEADER_SIZE - 4);
        if crc32(&b[..FILE_HEADER_SIZE - 4]) != crc {
            return Err(Error::Format("stream file header CRC mismatch".into()));
        }
        let major = u16_at(b, 8);
        if major != VERSION_MAJOR {
            return Err(Error::Format(format!(
                "stream format major version {major} is not supported (this reader: {VERSION_MAJOR})"
            )));
        }
        if u32_at(b, 12) as usize != FILE_HEADER_SIZE || u32_at(b, 16) as usize != FRAME_HEADER_SIZE
        {
            return Err(Error::Format(format!(
                "stream header sizes {} / {} (expected {FILE_HEADER_SIZE} / {FRAME_HEADER_SIZE})",
                u32_at(b, 12),
                u32_at(b, 16)
            )));
        }
        let fmt = PixelFormat::from_pfnc(u32_at(b, 28))?;
        let align = u16_at(b, 34);
        if align > 1 {
            return Err(Error::Format(format!("alignment code {align} (0 or 1)")));
        }
        let bits = u16_at(b, 32);
        let end = u16_at(b, 46);
        if end > 1 {
            return Err(Error::Format(format!("end status {end} (0 or 1)")));
        }
        let mut ch = [0u8; 4];
        for (k, c) in ch.iter_mut().enumerate() {
            let a = i16_at(b, 36 + 2 * k);
            *c = match a {
                0 => 0,
                45 => 1,
                90 => 2,
                135 => 3,
                _ => return Err(Error::Format(format!("polarizer angle {a} in header"))),
            };
        }
        let layout = MosaicLayout::from_channels(ch).map_err(|e| Error::Format(e.to_string()))?;
        let mut cam = [0f64; 10];
        for (k, v) in cam.iter_mut().enumerate() {
            *v = f64_at(b, 80 + 8 * k);
        }
        let (jo, jl) = (u32_at(b, 224) as usize, u32_at(b, 228) as usize);
        let json = if jo == 0 && jl == 0 {
            String::new()
        } else {
            if jo < JSON_OFFSET || jo.checked_add(jl).is_none_or(|e| e > FILE_HEADER_SIZE - 4) {
                return Err(Error::Format(format!(
                    "JSON at {jo} + {jl} outside the header"
                )));
            }
            String::from_utf8(b[jo..jo + jl].to_vec())
                .map_err(|_| Error::Format("header JSON is not UTF-8".into()))?
        };
        let h = FileHeader {
            version_minor: u16_at(b, 10),
            width: u32_at(b, 20),
            height: u32_at(b, 24),
            pixel_format: fmt,
            bits_valid: bits.min(255) as u8,
            msb_aligned: align == 1,
            layout,
            angle_sense: i16_at(b, 44),
            frame_count: u64_at(b, 64),
            aborted: end == 1,
            seed: u64_at(b, 72),
            camera: CameraConstants::from_array(cam),
            producer: get_str(b, 160, "producer")?,
            preset: get_str(b, 192, "preset")?,
            json,
        };
        if bits > 16 {
            return Err(Error::Format(format!("{bits} valid bits")));
        }
        h.validate().map_err(|e| Error::Format(e.to_string()))?;
        if u64_at(b, 48) != h.payload_size() || u64_at(b, 56) != h.stride() {
            return Err(Error::Format(format!(
                "payload size / stride {} / {} disagree with {} x {} {} ({} / {})",
                u64_at(b, 48),
                u64_at(b, 56),
                h.width,
                h.height,
                h.pixel_format,
                h.payload_size(),
                h.stride()
            )));
        }
        Ok(h)
    }
}

/// Per-frame metadata: the frame's ground truth (256-byte frame header without magic and CRCs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameMeta {
    /// Frame index, 0-based, strictly increasing; a gap means dropped frames.
    pub index: u64,
    /// Flags (`FLAG_*`).
    pub flags: u32,
    /// Exposure start, scene time, ns since 1970-01-01 UTC (no leap seconds).
    pub exposure_start_ns: i64,
    /// Exposure end, same clock.
    pub exposure_end_ns: i64,
    /// Host CLOCK_MONOTONIC ns when written; 0 unless asked for.
    pub host_time_ns: i64,
    /// Exposure, µs.
    pub exposure_us: f64,
    /// Gain, dB.
    pub gain_db: f64,
    /// Black level, DN of the payload format.
    pub black_level: f64,
    /// Sensor temperature, °C.
    pub temperature_c: f64,
    /// Sun azimuth at mid-exposure, compass degrees.
    pub sun_azimuth_deg: f64,
    /// Sun geometric elevation at mid-exposure, degrees.
    pub sun_elevation_deg: f64,
    /// Sun unit vector in the camera frame (x right, y down, z optical axis).
    pub sun_camera: [f64; 3],
    /// Attitude quaternion w, x, y, z rotating camera-frame vectors into ENU.
    pub attitude_wxyz: [f64; 4],
    /// Latitude, degrees (WGS-84).
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Ellipsoidal height, m.
    pub height_m: f64,
    /// Pixels at the maximum code at mosaic positions (0,0), (0,1), (1,0), (1,1).
    pub saturated: [u32; 4],
    /// Sky turbidity.
    pub turbidity: f32,
    /// Ground albedo.
    pub albedo: f32,
    /// With [`FLAG_CLASSES`]: the fraction of the image in each class (outside, sky, cloud,
    /// obstruction, ground, sun); else 0.
    pub class_fractions: [f32; 6],
}

impl FrameMeta {
    /// The frame header of `rec` in a payload of `bits_valid` bits (the black level in its DN),
    /// without [`FLAG_DROPPED`] and [`FLAG_LAST`], which the writer knows.
    pub fn of_record(rec: &FrameRecord, bits_valid: u8) -> FrameMeta {
        let flag = |on: bool, f: u32| if on { f } else { 0 };
        let flags = flag(rec.saturated.iter().any(|&n| n > 0), FLAG_SATURATION)
            | flag(!rec.sky_valid, FLAG_SKY_INVALID)
            | flag(rec.sun_in_view, FLAG_SUN_IN_VIEW)
            | flag(rec.ground_in_view, FLAG_GROUND_IN_VIEW)
            | flag(rec.auto_exposed, FLAG_AUTO_EXPOSURE)
            | flag(rec.exposure_clipped, FLAG_EXPOSURE_CLIPPED)
            | flag(rec.class_fractions.is_some(), FLAG_CLASSES);
        FrameMeta {
            index: rec.frame_index,
            flags,
            exposure_start_ns: rec.exposure_start_ns,
            exposure_end_ns: rec.exposure_end_ns,
            host_time_ns: 0,
            exposure_us: rec.exposure_us,
            gain_db: rec.gain_db,
            black_level: rec.black_level_in(bits_valid),
            temperature_c: rec.temperature_c,
            sun_azimuth_deg: rec.sun_azimuth_deg,
            sun_elevation_deg: rec.sun_elevation_deg(),
            sun_camera: rec.sun_camera,
            attitude_wxyz: rec.attitude_wxyz,
            lat_deg: rec.lat_deg,
            lon_deg: rec.lon_deg,
            height_m: rec.height_m,
            saturated: rec.saturated,
            turbidity: rec.turbidity,
            albedo: rec.albedo,
            class_fractions: rec
                .class_fractions
                .map_or([0.0; 6], |f| f.map(|v| v as f32)),
        }
    }

    /// Encodes the 256-byte frame header with the payload CRC and the header CRC.
    pub fn encode(&self, payload_crc: u32) -> [u8; FRAME_HEADER_SIZE] {
        let mut b = [0u8; FRAME_HEADER_SIZE];
        put(&mut b, 0, FRAME_MAGIC);
        put(&mut b, 8, self.index.to_le_bytes());
        put(&mut b, 16, self.flags.to_le_bytes());
        put(&mut b, 20, payload_crc.to_le_bytes());
        put(&mut b, 24, self.exposure_start_ns.to_le_bytes());
        put(&mut b, 32, self.exposure_end_ns.to_le_bytes());
        put(&mut b, 40, self.host_time_ns.to_le_bytes());
        let f = self.f64_fields();
        for (k, v) in f.iter().enumerate() {
            put(&mut b, 48 + 8 * k, v.to_le_bytes());
        }
        for (k, v) in self.saturated.iter().enumerate() {
            put(&mut b, 176 + 4 * k, v.to_le_bytes());
        }
        put(&mut b, 192, self.turbidity.to_le_bytes());
        put(&mut b, 196, self.albedo.to_le_bytes());
        for (k, v) in self.class_fractions.iter().enumerate() {
            put(&mut b, 200 + 4 * k, v.to_le_bytes());
        }
        let c = crc32(&b[..FRAME_HEADER_SIZE - 4]);
        put(&mut b, FRAME_HEADER_SIZE - 4, c.to_le_bytes());
        b
    }

    /// The 16 f64 fields at offsets 48..176 in order.
    pub fn f64_fields(&self) -> [f64; 16] {
        let s = &self.sun_camera;
        let q = &self.attitude_wxyz;
        [
            self.exposure_us,
            self.gain_db,
            self.black_level,
            self.temperature_c,
            self.sun_azimuth_deg,
            self.sun_elevation_deg,
            s[0],
            s[1],
            s[2],
            q[0],
            q[1],
            q[2],
            q[3],
            self.lat_deg,
            self.lon_deg,
            self.height_m,
        ]
    }

    /// Decodes a frame header; returns the metadata and the payload CRC it states.
    /// Fails on a wrong magic or header CRC.
    pub fn decode(b: &[u8]) -> Result<(FrameMeta, u32)> {
        if b.len() < FRAME_HEADER_SIZE {
            return Err(Error::Format("frame header truncated".into()));
        }
        if b[..8] != FRAME_MAGIC {
            return Err(Error::Format("frame magic missing".into()));
        }
        if crc32(&b[..FRAME_HEADER_SIZE - 4]) != u32_at(b, FRAME_HEADER_SIZE - 4) {
            return Err(Error::Format("frame header CRC mismatch".into()));
        }
        let f = |k: usize| f64_at(b, 48 + 8 * k);
        let m = FrameMeta {
            index: u64_at(b, 8),
            flags: u32_at(b, 16),
            exposure_start_ns: i64_at(b, 24),
            exposure_end_ns: i64_at(b, 32),
            host_time_ns: i64_at(b, 40),
            exposure_us: f(0),
            gain_db: f(1),
            black_level: f(2),
            temperature_c: f(3),
            sun_azimuth_deg: f(4),
            sun_elevation_deg: f(5),
            sun_camera: [f(6), f(7), f(8)],
            attitude_wxyz: [f(9), f(10), f(11), f(12)],
            lat_deg: f(13),
            lon_deg: f(14),
            height_m: f(15),
            saturated: [
                u32_at(b, 176),
                u32_at(b, 180),
                u32_at(b, 184),
                u32_at(b, 188),
            ],
            turbidity: f32_at(b, 192),
            albedo: f32_at(b, 196),
            class_fractions: std::array::from_fn(|k| f32_at(b, 200 + 4 * k)),
        };
        Ok((m, u32_at(b, 20)))
    }
}

/// The end record (256 bytes, after the last whole frame record): written only when the producer
/// stops because of a failure (bad input, I/O error, signal), so every reader can tell an aborted
/// stream from a finished one. A stream that ends normally has none.
///
/// | off | type | field |
/// |---|---|---|
/// | 0 | u8[8] | magic `\x89PSNSEND` |
/// | 8 | u64 | frame records written before it |
/// | 16 | u32 | status: 1 = aborted |
/// | 20 | u32 | reason length in bytes (at most 228) |
/// | 24 | u8[228] | reason, UTF-8, zero-padded |
/// | 252 | u32 | CRC-32 of bytes 0..251 |
///
/// ```
/// use psns::stream::EndRecord;
/// let e = EndRecord::aborted(3, "trajectory line 4: 'NaN' is not a finite number");
/// let b = e.encode();
/// assert_eq!(&b[..8], b"\x89PSNSEND");
/// assert_eq!(EndRecord::decode(&b).unwrap(), e);
/// ```
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct EndRecord {
    /// Frame records the producer wrote before the end record.
    pub frames: u64,
    /// Why the producer stopped.
    pub reason: String,
}

impl EndRecord {
    /// An aborted stream's end record; the reason is cut to [`END_REASON_MAX`] bytes.
    pub fn aborted(frames: u64, reason: &str) -> Self {
        let mut n = reason.len().min(END_REASON_MAX);
        while !reason.is_char_boundary(n) {
            n -= 1;
        }
        EndRecord {
            frames,
            reason: reason[..n].to_string(),
        }
    }

    /// Encodes the 256-byte record with its CRC.
    pub fn encode(&self) -> [u8; END_RECORD_SIZE] {
        let mut b = [0u8; END_RECORD_SIZE];
        let r = &self.reason.as_bytes()[..self.reason.len().min(END_REASON_MAX)];
        put(&mut b, 0, END_MAGIC);
        put(&mut b, 8, self.frames.to_le_bytes());
        put(&mut b, 16, END_ABORTED.to_le_bytes());
        put(&mut b, 20, (r.len() as u32).to_le_bytes());
        b[24..24 + r.len()].copy_from_slice(r);
        let c = crc32(&b[..END_RECORD_SIZE - 4]);
        put(&mut b, END_RECORD_SIZE - 4, c.to_le_bytes());
        b
    }

    /// Decodes and checks an end record: magic, CRC, status, reason length and UTF-8.
    pub fn decode(b: &[u8]) -> Result<Self> {
        if b.len() < END_RECORD_SIZE {
            return Err(Error::Format("end record truncated".into()));
        }
        if b[..8] != END_MAGIC {
            return Err(Error::Format("end-record magic missing".into()));
        }
        if crc32(&b[..END_RECORD_SIZE - 4]) != u32_at(b, END_RECORD_SIZE - 4) {
            return Err(Error::Format("end record CRC mismatch".into()));
        }
        let status = u32_at(b, 16);
        if status != END_ABORTED {
            return Err(Error::Format(format!("end record status {status}")));
        }
        let n = u32_at(b, 20) as usize;
        if n > END_REASON_MAX {
            return Err(Error::Format(format!("end record reason of {n} bytes")));
        }
        let reason = String::from_utf8(b[24..24 + n].to_vec())
            .map_err(|_| Error::Format("end record reason is not UTF-8".into()))?;
        Ok(EndRecord {
            frames: u64_at(b, 8),
            reason,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn strides() {
        let mut h = FileHeader::default();
        for (f, p, s) in [
            (PixelFormat::Mono8, 5_013_504, 5_017_600),
            (PixelFormat::Mono12p, 7_520_256, 7_524_352),
            (PixelFormat::Mono12Packed, 7_520_256, 7_524_352),
            (PixelFormat::Mono16, 10_027_008, 10_031_104),
        ] {
            h.pixel_format = f;
            h.bits_valid = if f == PixelFormat::Mono8 { 8 } else { 12 };
            assert_eq!((h.payload_size(), h.stride()), (p, s), "{f}");
        }
    }

    #[test]
    fn header_round_trip_and_crc() {
        let h = FileHeader {
            json: r#"{"a":1}"#.into(),
            seed: 42,
            frame_count: 3,
            ..Default::default()
        };
        let b = h.encode().unwrap();
        assert_eq!(&b[..8], b"\x89PSNSRAW");
        assert_eq!(FileHeader::decode(&b).unwrap(), h);
        let mut bad = b.clone();
        bad[100] ^= 1;
        assert!(FileHeader::decode(&bad).is_err());
        let m = FrameMeta {
            index: 7,
            gain_db: 6.0,
            saturated: [1, 2, 3, 4],
            turbidity: 2.5,
            ..Default::default()
        };
        let fb = m.encode(0xDEAD_BEEF);
        assert_eq!(FrameMeta::decode(&fb).unwrap(), (m, 0xDEAD_BEEF));
        let mut bad = fb;
        bad[60] ^= 0x80;
        assert!(FrameMeta::decode(&bad).is_err());
    }
}
