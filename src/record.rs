//! The frame record: everything known about one rendered frame, made by the pipeline
//! ([`crate::pipeline::RawPipeline::render`]) and read by every output. The stream's frame
//! header ([`crate::stream::FrameMeta::of_record`]), the GigE chunks
//! ([`crate::gige::chunk::ChunkValues::of_record`]), the ROS 2 messages (from the frame header),
//! `psns gige --truth-csv`, Python's metadata dicts and `psns render`'s `scene.json` all derive
//! from it. A new per-frame value is a field here plus one line in each format that carries it.
//!
//! ```
//! use psns::record::FrameRecord;
//! let r = FrameRecord { frame_index: 3, exposure_us: 1000.0, ..Default::default() };
//! let v = serde_json::to_value(r).unwrap();
//! assert_eq!(v["frame_index"], 3);
//! assert_eq!(v["class_fractions"], serde_json::Value::Null); // no world
//! ```

use serde::Serialize;

/// Everything known about one rendered frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameRecord {
    /// Frame index (the sensor's temporal noise is drawn from it).
    pub frame_index: u64,
    /// Scene time of the frame's pose, s (drifting clouds move with it).
    pub t_s: f64,
    /// Exposure start, ns since 1970-01-01 UTC (no leap seconds); 0 for a frame without a clock.
    pub exposure_start_ns: i64,
    /// Exposure end, same clock.
    pub exposure_end_ns: i64,
    /// Exposure, µs.
    pub exposure_us: f64,
    /// The exposure was chosen by auto-exposure.
    pub auto_exposed: bool,
    /// Auto-exposure wanted more or less than the sensor's range.
    pub exposure_clipped: bool,
    /// Analog gain, dB.
    pub gain_db: f64,
    /// ADC bits of the codes.
    pub bit_depth: u8,
    /// Black level, DN at `bit_depth`.
    pub black_level_dn: f64,
    /// Conversion gain, DN per electron at `bit_depth`.
    pub dn_per_electron: f64,
    /// Sensor temperature, °C.
    pub temperature_c: f64,
    /// Pixels at the maximum code at mosaic positions (0,0), (0,1), (1,0), (1,1).
    pub saturated: [u32; 4],
    /// A sky scene whose sun is up (false: the frame is dark, or a flat field).
    pub sky_valid: bool,
    /// Sun azimuth at mid-exposure, compass degrees (0 for a flat field).
    pub sun_azimuth_deg: f64,
    /// Sun zenith angle at mid-exposure, degrees (0 for a flat field).
    pub sun_zenith_deg: f64,
    /// Sun unit vector in the camera frame (x right, y down, z optical axis).
    pub sun_camera: [f64; 3],
    /// Attitude quaternion w, x, y, z rotating camera-frame vectors into ENU.
    pub attitude_wxyz: [f64; 4],
    /// The sun's centre projects inside the image and the sun is up.
    pub sun_in_view: bool,
    /// Some pixel looks below the horizon.
    pub ground_in_view: bool,
    /// Pixels touched by the solar disc.
    pub sun_disc_pixels: usize,
    /// Pixels looking at the ground (an open sky's horizon).
    pub ground_pixels: usize,
    /// Latitude, degrees (WGS-84); 0 without a place.
    pub lat_deg: f64,
    /// Longitude, degrees; 0 without a place.
    pub lon_deg: f64,
    /// Ellipsoidal height, m; 0 without a place.
    pub height_m: f64,
    /// Sky turbidity.
    pub turbidity: f32,
    /// Ground albedo.
    pub albedo: f32,
    /// With a world around the camera: the fraction of the image in each class, in
    /// [`crate::world::Class::ALL`]'s order (outside, sky, cloud, obstruction, ground, sun).
    pub class_fractions: Option<[f64; 6]>,
}

impl FrameRecord {
    /// The sun's geometric elevation, degrees.
    pub fn sun_elevation_deg(&self) -> f64 {
        90.0 - self.sun_zenith_deg
    }

    /// The black level in DN of a payload of `bits_valid` bits (Mono8 keeps the top 8 of
    /// `bit_depth` bits).
    pub fn black_level_in(&self, bits_valid: u8) -> f64 {
        self.black_level_dn * 2f64.powi(bits_valid as i32 - self.bit_depth as i32)
    }
}
