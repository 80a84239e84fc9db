//! ROS 2 messages of psns frames, for rosbag2 bags in MCAP storage (`docs/ros2.md`).
//!
//! Pure codecs, no files: the CDR encoding of the few messages a psns bag holds ([`cdr`],
//! [`msg`]), their `ros2msg` schema texts, the `metadata.yaml` of a bag ([`metadata`]), and how a
//! psns frame becomes those messages (this module): the topics, the frames and the conventions
//! as types. The MCAP file and the bag directory are written by the front-end.
//!
//! Conventions: the camera optical frame is ROS's and psns's camera frame (x right along the
//! columns, y down along the rows, z forward along the optical axis); the world frame is ENU
//! (x east, y north, z up); the principal point is 0-based with pixel centres at whole numbers,
//! which is ROS's `CameraInfo` convention as it is psns's.

pub mod cdr;
pub mod metadata;
pub mod msg;

use crate::camera::{Intrinsics, Projection};
use crate::error::{Error, Result};
use crate::sensor::packing::{CodeWord, PixelFormat};
use crate::stream::FrameMeta;
use msg::{
    CameraInfo, DistortionModel, Float64MultiArray, Header, PoseStamped, RegionOfInterest,
    TfMessage, TransformStamped, Vector3Stamped,
};

/// The raw mosaic, `sensor_msgs/msg/Image`.
pub const TOPIC_IMAGE: &str = "/psns/image_raw";
/// The intrinsics, `sensor_msgs/msg/CameraInfo`.
pub const TOPIC_CAMERA_INFO: &str = "/psns/camera_info";
/// The camera's attitude in ENU, `geometry_msgs/msg/PoseStamped`.
pub const TOPIC_POSE: &str = "/psns/pose";
/// The unit sun vector in ENU, `geometry_msgs/msg/Vector3Stamped`.
pub const TOPIC_SUN: &str = "/psns/sun";
/// The camera optical frame in ENU for 3D viewers (tf2), `tf2_msgs/msg/TFMessage`:
/// `enu -> psns_camera_optical`, the pose of [`TOPIC_POSE`].
pub const TOPIC_TF: &str = "/tf";
/// The ground-truth degree of linear polarization, `32FC1` images.
pub const TOPIC_TRUTH_DOLP: &str = "/psns/truth/dolp";
/// The ground-truth angle of linear polarization (degrees, sensor convention), `32FC1` images.
pub const TOPIC_TRUTH_AOLP: &str = "/psns/truth/aolp";
/// The fraction of the image in each class, for frames with a world around the camera.
pub const TOPIC_TRUTH_CLASSES: &str = "/psns/truth/classes";

/// The coordinate frames psns messages are in (`header.frame_id`).
///
/// ```
/// use psns::ros2::FrameId;
/// assert_eq!(FrameId::CameraOptical.as_str(), "psns_camera_optical");
/// assert_eq!(FrameId::Enu.as_str(), "enu");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameId {
    /// The camera optical frame: x right (columns), y down (rows), z forward (optical axis);
    /// of the image, the camera info and the truth images.
    CameraOptical,
    /// East-North-Up at the camera: of the pose and the sun.
    Enu,
}

impl FrameId {
    /// The `frame_id` string.
    pub fn as_str(self) -> &'static str {
        match self {
            FrameId::CameraOptical => "psns_camera_optical",
            FrameId::Enu => "enu",
        }
    }
}

/// Pixel encodings of `sensor_msgs/msg/Image` that psns writes (`encoding`), always
/// little-endian.
///
/// ```
/// use psns::ros2::ImageEncoding;
/// use psns::sensor::packing::PixelFormat;
/// assert_eq!(ImageEncoding::of_pixel_format(PixelFormat::Mono8), ImageEncoding::Mono8);
/// // packed 12-bit is unpacked: the codes as 16-bit words, as --pixel-format mono16 has them
/// assert_eq!(ImageEncoding::of_pixel_format(PixelFormat::Mono12p), ImageEncoding::Mono16);
/// assert_eq!(ImageEncoding::Mono16.as_str(), "mono16");
/// assert_eq!(ImageEncoding::Float32.as_str(), "32FC1");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ImageEncoding {
    /// `mono8`: one byte per pixel.
    Mono8,
    /// `mono16`: one u16 per pixel, the raw codes LSB-aligned.
    Mono16,
    /// `32FC1`: one f32 per pixel.
    Float32,
}

impl ImageEncoding {
    /// The `encoding` string.
    pub fn as_str(self) -> &'static str {
        match self {
            ImageEncoding::Mono8 => "mono8",
            ImageEncoding::Mono16 => "mono16",
            ImageEncoding::Float32 => "32FC1",
        }
    }

    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> u32 {
        match self {
            ImageEncoding::Mono8 => 1,
            ImageEncoding::Mono16 => 2,
            ImageEncoding::Float32 => 4,
        }
    }

    /// The raw image's encoding for a stream pixel format: `mono8` for Mono8, `mono16` (the
    /// codes, as in a Mono16 stream) for the 12- and 16-bit formats.
    pub fn of_pixel_format(f: PixelFormat) -> Self {
        match f.info().word {
            CodeWord::U8 => ImageEncoding::Mono8,
            CodeWord::U16 => ImageEncoding::Mono16,
        }
    }

    /// The stream pixel format whose payload is this encoding's pixel bytes (`None` for
    /// `32FC1`).
    pub fn pixel_format(self) -> Option<PixelFormat> {
        match self {
            ImageEncoding::Mono8 => Some(PixelFormat::Mono8),
            ImageEncoding::Mono16 => Some(PixelFormat::Mono16),
            ImageEncoding::Float32 => None,
        }
    }
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since 1970-01-01 UTC.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0..999 999 999.
    pub nanosec: u32,
}

/// The latest time a bag can hold, ns since 1970: 2038-01-19T03:14:07.999999999Z (the last
/// second of ROS's int32 `sec`).
pub const MAX_TIME_NS: i64 = i32::MAX as i64 * 1_000_000_000 + 999_999_999;

impl Time {
    /// A stamp from ns since 1970-01-01 UTC. A bag's times are MCAP log times (unsigned) and
    /// ROS times (int32 seconds): 0..=[`MAX_TIME_NS`].
    ///
    /// ```
    /// use psns::ros2::Time;
    /// let t = Time::from_unix_ns(1_750_500_000_250_000_000).unwrap();
    /// assert_eq!((t.sec, t.nanosec), (1_750_500_000, 250_000_000));
    /// assert_eq!(t.unix_ns(), 1_750_500_000_250_000_000);
    /// assert!(Time::from_unix_ns(-1).is_err());
    /// assert!(Time::from_unix_ns(psns::ros2::MAX_TIME_NS + 1).is_err());
    /// ```
    pub fn from_unix_ns(ns: i64) -> Result<Time> {
        if !(0..=MAX_TIME_NS).contains(&ns) {
            return Err(Error::OutOfRange {
                name: "time (ns since 1970 UTC)".into(),
                value: ns.to_string(),
                allowed: format!(
                    "0..{MAX_TIME_NS}, 1970-01-01..2038-01-19T03:14:07Z: a ROS 2 time has int32 \
                     seconds and an MCAP log time is unsigned"
                ),
            });
        }
        Ok(Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        })
    }

    /// Nanoseconds since 1970 (the MCAP log time).
    pub fn unix_ns(self) -> u64 {
        self.sec as u64 * 1_000_000_000 + self.nanosec as u64
    }
}

/// The `geometry_msgs/msg/PoseStamped` of a frame: the camera optical frame in ENU, at the
/// origin, turned by the stream's attitude (camera → ENU), stamped with the exposure start.
///
/// ```
/// use psns::stream::FrameMeta;
/// let m = FrameMeta { exposure_start_ns: 5, attitude_wxyz: [0.5, 0.5, -0.5, 0.5], ..Default::default() };
/// let p = psns::ros2::pose(&m).unwrap();
/// assert_eq!(p.orientation_xyzw, [0.5, -0.5, 0.5, 0.5]);
/// assert_eq!(p.header.frame_id.as_str(), "enu");
/// ```
pub fn pose(meta: &FrameMeta) -> Result<PoseStamped> {
    let [w, x, y, z] = meta.attitude_wxyz;
    Ok(PoseStamped {
        header: Header {
            stamp: Time::from_unix_ns(meta.exposure_start_ns)?,
            frame_id: FrameId::Enu,
        },
        position: [0.0; 3],
        orientation_xyzw: [x, y, z, w],
    })
}

/// The `tf2_msgs/msg/TFMessage` of a frame: one transform from ENU (`enu`, the parent) to the
/// camera optical frame (`psns_camera_optical`, the child), the rotation of [`pose`] and no
/// translation, stamped with the exposure start.
///
/// ```
/// use psns::stream::FrameMeta;
/// let m = FrameMeta { exposure_start_ns: 5, attitude_wxyz: [0.5, 0.5, -0.5, 0.5], ..Default::default() };
/// let tf = psns::ros2::transform(&m).unwrap();
/// let t = tf.transforms[0];
/// assert_eq!((t.header.frame_id.as_str(), t.child_frame_id.as_str()), ("enu", "psns_camera_optical"));
/// assert_eq!(t.rotation_xyzw, psns::ros2::pose(&m).unwrap().orientation_xyzw);
/// assert_eq!(t.translation, [0.0; 3]);
/// ```
pub fn transform(meta: &FrameMeta) -> Result<TfMessage> {
    let p = pose(meta)?;
    Ok(TfMessage {
        transforms: vec![TransformStamped {
            header: p.header,
            child_frame_id: FrameId::CameraOptical,
            translation: p.position,
            rotation_xyzw: p.orientation_xyzw,
        }],
    })
}

/// The `geometry_msgs/msg/Vector3Stamped` of a frame: the unit sun vector in ENU from the frame
/// header's sun azimuth and elevation (at mid-exposure), stamped with the exposure start.
///
/// ```
/// use psns::stream::FrameMeta;
/// let m = FrameMeta { sun_azimuth_deg: 90.0, sun_elevation_deg: 0.0, ..Default::default() };
/// let v = psns::ros2::sun(&m).unwrap().vector;
/// assert!((v[0] - 1.0).abs() < 1e-15 && v[1].abs() < 1e-15 && v[2].abs() < 1e-15); // east
/// ```
pub fn sun(meta: &FrameMeta) -> Result<Vector3Stamped> {
    let v = crate::angle::direction(90.0 - meta.sun_elevation_deg, meta.sun_azimuth_deg);
    Ok(Vector3Stamped {
        header: Header {
            stamp: Time::from_unix_ns(meta.exposure_start_ns)?,
            frame_id: FrameId::Enu,
        },
        vector: v.to_array(),
    })
}

/// The `std_msgs/msg/Float64MultiArray` of a frame's class fractions when it has them
/// ([`crate::stream::FLAG_CLASSES`]): one dimension labelled with the class names in order.
///
/// ```
/// use psns::stream::{FrameMeta, FLAG_CLASSES};
/// let mut m = FrameMeta { class_fractions: [0.0, 0.5, 0.0, 0.5, 0.0, 0.0], ..Default::default() };
/// assert!(psns::ros2::classes(&m).is_none());
/// m.flags |= FLAG_CLASSES;
/// let a = psns::ros2::classes(&m).unwrap();
/// assert_eq!(a.label, "outside,sky,cloud,obstruction,ground,sun");
/// assert_eq!(a.data, [0.0, 0.5, 0.0, 0.5, 0.0, 0.0]);
/// ```
pub fn classes(meta: &FrameMeta) -> Option<Float64MultiArray> {
    if meta.flags & crate::stream::FLAG_CLASSES == 0 {
        return None;
    }
    let names: Vec<&str> = crate::world::Class::ALL.iter().map(|c| c.name()).collect();
    Some(Float64MultiArray {
        label: names.join(","),
        data: meta.class_fractions.iter().map(|&f| f as f64).collect(),
    })
}

/// The `sensor_msgs/msg/CameraInfo` of the intrinsics, in the camera optical frame: K from the
/// focal length in pixels (focal length / pixel pitch) and the 0-based principal point, R the
/// identity, P = [K | 0], no binning, the full image; the lens model of [`distortion`].
///
/// ```
/// use psns::camera::Intrinsics;
/// use psns::ros2::msg::Header;
/// use psns::ros2::{FrameId, Time};
/// let h = Header { stamp: Time::default(), frame_id: FrameId::CameraOptical };
/// let ci = psns::ros2::camera_info(h, &Intrinsics::default()).unwrap();
/// let f = 4.0 * 1000.0 / 3.45;
/// assert_eq!(ci.k, [f, 0.0, 1223.5, 0.0, f, 1023.5, 0.0, 0.0, 1.0]);
/// assert_eq!((ci.distortion_model.as_str(), ci.d.as_slice()), ("plumb_bob", &[0.0; 5][..]));
/// ```
pub fn camera_info(header: Header, intr: &Intrinsics) -> Result<CameraInfo> {
    let size = |name: &str, v: usize| {
        u32::try_from(v).map_err(|_| Error::range(name, v as f64, "1..4294967295"))
    };
    let f = intr.focal_px();
    let (cx, cy) = intr.principal();
    let (distortion_model, d) = distortion(intr.projection);
    Ok(CameraInfo {
        header,
        height: size("height", intr.height)?,
        width: size("width", intr.width)?,
        distortion_model,
        d,
        k: [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        binning_x: 0,
        binning_y: 0,
        roi: RegionOfInterest::default(),
    })
}

/// The `CameraInfo` lens model of a projection. Rectilinear: `plumb_bob` with five zeros (a
/// distortion-free pinhole). The fisheyes: `equidistant` (Kannala–Brandt, radius
/// f·θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)); exact for the equidistant projection (k = 0), and for
/// equisolid, stereographic and orthographic the least-squares fit of [`kannala_brandt_fit`]
/// over 0..90°, since ROS has no model of their own.
pub fn distortion(p: Projection) -> (DistortionModel, Vec<f64>) {
    match p {
        Projection::Rectilinear => (DistortionModel::PlumbBob, vec![0.0; 5]),
        Projection::Equidistant => (DistortionModel::Equidistant, vec![0.0; 4]),
        Projection::Equisolid | Projection::Stereographic | Projection::Orthographic => {
            (DistortionModel::Equidistant, kannala_brandt_fit(p).to_vec())
        }
    }
}

/// Samples of the field angle in the fit of [`kannala_brandt_fit`].
const FIT_SAMPLES: usize = 4096;

/// The Kannala–Brandt coefficients k1..k4 that bring f·θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)
/// closest to the projection's radius f·ρ(θ) over the image circle, θ in 0..90°: linear least
/// squares on 4096 evenly spaced angles (a QR factorisation by modified Gram–Schmidt). Pure
/// and deterministic: the same numbers on every run.
///
/// ```
/// use psns::camera::Projection;
/// // equisolid: 2 sin(θ/2) = θ(1 − θ²/24 + θ⁴/1920 − ...)
/// let k = psns::ros2::kannala_brandt_fit(Projection::Equisolid);
/// assert!((k[0] + 1.0 / 24.0).abs() < 1e-6 && (k[1] - 1.0 / 1920.0).abs() < 1e-6);
/// ```
pub fn kannala_brandt_fit(p: Projection) -> [f64; 4] {
    let half_pi = std::f64::consts::FRAC_PI_2;
    let thetas: Vec<f64> = (0..FIT_SAMPLES)
        .map(|i| (i as f64 + 0.5) / FIT_SAMPLES as f64 * half_pi)
        .collect();
    // columns θ³, θ⁵, θ⁷, θ⁹; target ρ(θ) − θ
    let mut a: Vec<Vec<f64>> = (0..4)
        .map(|j| thetas.iter().map(|t| t.powi(2 * j + 3)).collect())
        .collect();
    let y: Vec<f64> = thetas
        .iter()
        .map(|&t| p.radius(t).unwrap_or(t) - t)
        .collect();
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
    let mut r = [[0.0f64; 4]; 4];
    for j in 0..4 {
        for i in 0..j {
            let rij = dot(&a[i], &a[j]);
            r[i][j] = rij;
            let (qi, qj) = {
                let (lo, hi) = a.split_at_mut(j);
                (&lo[i], &mut hi[0])
            };
            for (x, q) in qj.iter_mut().zip(qi) {
                *x -= rij * q;
            }
        }
        let n = dot(&a[j], &a[j]).sqrt();
        r[j][j] = n;
        for x in a[j].iter_mut() {
            *x /= n;
        }
    }
    let qty: Vec<f64> = (0..4).map(|j| dot(&a[j], &y)).collect();
    let mut k = [0.0; 4];
    for i in (0..4).rev() {
        let s: f64 = (i + 1..4).map(|j| r[i][j] * k[j]).sum();
        k[i] = (qty[i] - s) / r[i][i];
    }
    k
}

/// The largest |θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸) − ρ(θ)| over θ in 0..90° (sampled every
/// 0.01°), in focal lengths: multiply by the focal length in pixels for the error in pixels.
pub fn kannala_brandt_error(p: Projection, k: &[f64; 4]) -> f64 {
    (0..=9000)
        .map(|i| (i as f64 * 0.01).to_radians())
        .map(|t| {
            let t2 = t * t;
            let kb = t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
            (kb - p.radius(t).unwrap_or(f64::INFINITY)).abs()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_are_close_to_the_projections_taylor_series() {
        // orthographic: sin θ = θ(1 − θ²/6 + θ⁴/120 − θ⁶/5040 + θ⁸/362880)
        let k = kannala_brandt_fit(Projection::Orthographic);
        assert!((k[0] + 1.0 / 6.0).abs() < 1e-5, "{k:?}");
        assert!((k[1] - 1.0 / 120.0).abs() < 1e-5, "{k:?}");
        // stereographic: 2 tan(θ/2) = θ(1 + θ²/12 + θ⁴/120 + ...)
        let k = kannala_brandt_fit(Projection::Stereographic);
        assert!((k[0] - 1.0 / 12.0).abs() < 2e-3, "{k:?}");
        // equidistant is exact with zeros (the fit agrees)
        let k = kannala_brandt_fit(Projection::Equidistant);
        assert!(k.iter().all(|c| c.abs() < 1e-12), "{k:?}");
    }

    #[test]
    fn fit_errors_are_a_small_fraction_of_a_pixel() {
        // a 1.8 mm fisheye on 3.45 um pixels has f = 521.7 px
        let f = 1.8e3 / 3.45;
        for p in [
            Projection::Equisolid,
            Projection::Stereographic,
            Projection::Orthographic,
        ] {
            let (_, d) = distortion(p);
            let e = kannala_brandt_error(p, &d.clone().try_into().unwrap()) * f;
            assert!(e < 0.05, "{p}: {e} px");
        }
        assert_eq!(
            kannala_brandt_error(Projection::Equidistant, &[0.0; 4]),
            0.0
        );
    }

    #[test]
    fn stamps_split_into_seconds_and_nanoseconds() {
        let t = Time::from_unix_ns(MAX_TIME_NS).unwrap();
        assert_eq!((t.sec, t.nanosec), (i32::MAX, 999_999_999));
        assert_eq!(t.unix_ns(), MAX_TIME_NS as u64);
        let e = Time::from_unix_ns(MAX_TIME_NS + 1).unwrap_err();
        assert!(e.is_usage() && e.to_string().contains("2038-01-19"), "{e}");
    }

    #[test]
    fn sun_vector_is_east_north_up() {
        let m = FrameMeta {
            sun_azimuth_deg: 180.0,
            sun_elevation_deg: 30.0,
            ..Default::default()
        };
        let v = sun(&m).unwrap().vector;
        let (s, c) = 30f64.to_radians().sin_cos();
        assert!((v[0]).abs() < 1e-15 && (v[1] + c).abs() < 1e-15 && (v[2] - s).abs() < 1e-15);
    }
}
