//! The ROS 2 messages of a psns bag, their CDR encoding ([`super::cdr`]) and their `ros2msg`
//! schema texts.
//!
//! A schema is the message definition followed by the definitions it uses, each after a line of
//! 80 `=` and a `MSG: pkg/Type` line, as rosbag2 writes them into an MCAP schema record (field
//! lines only, no comments or default values).

use super::cdr::CdrWriter;
use super::{FrameId, ImageEncoding, Time};
use crate::error::{Error, Result};

/// One message type: its name, its schema and its encoding.
pub trait Message {
    /// The type name as rosbag2 records it, e.g. `sensor_msgs/msg/Image`.
    const TYPE: &'static str;
    /// The `ros2msg` schema text (the definition and its dependencies).
    const SCHEMA: &'static str;
    /// Appends the fields in CDR.
    fn encode(&self, w: &mut CdrWriter) -> Result<()>;

    /// The whole CDR message (encapsulation header first) in `buf`'s allocation.
    fn to_cdr_in(&self, buf: Vec<u8>) -> Result<Vec<u8>> {
        let mut w = CdrWriter::with_buffer(buf);
        self.encode(&mut w)?;
        Ok(w.into_bytes())
    }

    /// The whole CDR message (encapsulation header first).
    fn to_cdr(&self) -> Result<Vec<u8>> {
        self.to_cdr_in(Vec::new())
    }
}

/// The separator rosbag2 puts before each dependency of a schema.
macro_rules! dep {
    ($name:literal, $body:literal) => {
        concat!(
            "================================================================================\n",
            "MSG: ",
            $name,
            "\n",
            $body
        )
    };
}

const TIME_DEF: &str = "int32 sec\nuint32 nanosec\n";

/// `builtin_interfaces/msg/Time`.
impl Message for Time {
    const TYPE: &'static str = "builtin_interfaces/msg/Time";
    const SCHEMA: &'static str = TIME_DEF;
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        w.i32(self.sec);
        w.u32(self.nanosec);
        Ok(())
    }
}

/// `std_msgs/msg/Header`: a stamp and the frame the data is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// Acquisition time.
    pub stamp: Time,
    /// Coordinate frame of the data.
    pub frame_id: FrameId,
}

impl Message for Header {
    const TYPE: &'static str = "std_msgs/msg/Header";
    const SCHEMA: &'static str = concat!(
        "builtin_interfaces/Time stamp\nstring frame_id\n",
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        self.stamp.encode(w)?;
        w.string(self.frame_id.as_str())
    }
}

/// `sensor_msgs/msg/Image` over borrowed pixel bytes, little-endian (`is_bigendian` 0), rows
/// without padding (`step` = width × bytes per pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Image<'a> {
    /// Stamp and frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding.
    pub encoding: ImageEncoding,
    /// Row-major pixels, `height × step` bytes.
    pub data: &'a [u8],
}

impl<'a> Image<'a> {
    /// An image of `width × height` pixels; `data` must hold exactly that many pixels of
    /// `encoding`.
    ///
    /// ```
    /// use psns::ros2::msg::{Header, Image};
    /// use psns::ros2::{FrameId, ImageEncoding, Time};
    /// let h = Header { stamp: Time::from_unix_ns(1_500_000_000).unwrap(), frame_id: FrameId::CameraOptical };
    /// let px = [1u8, 0, 2, 0, 3, 0];
    /// let im = Image::new(h, 3, 1, ImageEncoding::Mono16, &px).unwrap();
    /// assert_eq!(im.step(), 6);
    /// assert!(Image::new(h, 4, 1, ImageEncoding::Mono16, &px).is_err());
    /// ```
    pub fn new(
        header: Header,
        width: u32,
        height: u32,
        encoding: ImageEncoding,
        data: &'a [u8],
    ) -> Result<Self> {
        let need = width as u64 * height as u64 * encoding.bytes_per_pixel() as u64;
        if data.len() as u64 != need {
            return Err(Error::Invalid(format!(
                "a {width} x {height} {} image needs {need} bytes, got {}",
                encoding.as_str(),
                data.len()
            )));
        }
        if width as u64 * encoding.bytes_per_pixel() as u64 > u32::MAX as u64 {
            return Err(Error::range(
                "image width",
                width as f64,
                "a row of at most 4294967295 bytes",
            ));
        }
        Ok(Image {
            header,
            height,
            width,
            encoding,
            data,
        })
    }

    /// Bytes per row.
    pub fn step(&self) -> u32 {
        self.width * self.encoding.bytes_per_pixel()
    }

    /// The CDR bytes of a `width × height` image message in front of its pixels: the
    /// encapsulation header, the fields and the pixel byte count. The message is these bytes
    /// followed by the pixels, the same bytes as [`Message::to_cdr`] of the whole image, so
    /// pixels made in place behind room for them need no copy. Its length depends on the
    /// frame id and the encoding name only (a multiple of 4), not on the stamp or the size.
    ///
    /// ```
    /// use psns::ros2::msg::{Header, Image, Message};
    /// use psns::ros2::{FrameId, ImageEncoding, Time};
    /// let h = Header { stamp: Time::from_unix_ns(1_500_000_000).unwrap(), frame_id: FrameId::CameraOptical };
    /// let px = [1u8, 0, 2, 0, 3, 0];
    /// let pre = Image::cdr_prefix(h, 3, 1, ImageEncoding::Mono16).unwrap();
    /// let whole = Image::new(h, 3, 1, ImageEncoding::Mono16, &px).unwrap().to_cdr().unwrap();
    /// assert_eq!([&pre[..], &px[..]].concat(), whole);
    /// assert_eq!(pre.len() % 4, 0);
    /// ```
    pub fn cdr_prefix(
        header: Header,
        width: u32,
        height: u32,
        encoding: ImageEncoding,
    ) -> Result<Vec<u8>> {
        let mut w = CdrWriter::new();
        let step = Self::encode_fields(&mut w, header, width, height, encoding)?;
        let len = usize::try_from(step as u64 * height as u64).map_err(|_| {
            Error::Invalid(format!("a {width} x {height} image does not fit in memory"))
        })?;
        w.byte_seq_len(len)?;
        Ok(w.into_bytes())
    }

    /// The fields in front of `data`; returns `step`.
    fn encode_fields(
        w: &mut CdrWriter,
        header: Header,
        width: u32,
        height: u32,
        encoding: ImageEncoding,
    ) -> Result<u32> {
        let bpp = encoding.bytes_per_pixel() as u64;
        let step = u32::try_from(width as u64 * bpp).map_err(|_| {
            Error::range(
                "image width",
                width as f64,
                "a row of at most 4294967295 bytes",
            )
        })?;
        header.encode(w)?;
        w.u32(height);
        w.u32(width);
        w.string(encoding.as_str())?;
        w.u8(0); // little-endian pixels
        w.u32(step);
        Ok(step)
    }
}

impl Message for Image<'_> {
    const TYPE: &'static str = "sensor_msgs/msg/Image";
    const SCHEMA: &'static str = concat!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n",
        "uint8 is_bigendian\nuint32 step\nuint8[] data\n",
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        w.reserve(self.data.len() + 96);
        Self::encode_fields(w, self.header, self.width, self.height, self.encoding)?;
        w.byte_seq(self.data)
    }
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RegionOfInterest {
    /// Leftmost column.
    pub x_offset: u32,
    /// Topmost row.
    pub y_offset: u32,
    /// Rows (0: the full image).
    pub height: u32,
    /// Columns (0: the full image).
    pub width: u32,
    /// Whether a rectified region is wanted.
    pub do_rectify: bool,
}

impl Message for RegionOfInterest {
    const TYPE: &'static str = "sensor_msgs/msg/RegionOfInterest";
    const SCHEMA: &'static str =
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n";
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        w.u32(self.x_offset);
        w.u32(self.y_offset);
        w.u32(self.height);
        w.u32(self.width);
        w.bool(self.do_rectify);
        Ok(())
    }
}

/// The lens models of `sensor_msgs/msg/CameraInfo` psns uses (`distortion_model`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DistortionModel {
    /// `plumb_bob`: Brown–Conrady k1, k2, t1, t2, k3 (all 0 for psns's rectilinear lens).
    PlumbBob,
    /// `equidistant`: the fisheye model of OpenCV and ROS's `image_geometry` (Kannala–Brandt),
    /// image radius f·θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸) at field angle θ.
    Equidistant,
}

impl DistortionModel {
    /// The name in `distortion_model`.
    pub fn as_str(self) -> &'static str {
        match self {
            DistortionModel::PlumbBob => "plumb_bob",
            DistortionModel::Equidistant => "equidistant",
        }
    }
}

/// `sensor_msgs/msg/CameraInfo`.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfo {
    /// Stamp and frame (the optical frame of the image it describes).
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Lens model of `d`.
    pub distortion_model: DistortionModel,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major: fx 0 cx / 0 fy cy / 0 0 1.
    pub k: [f64; 9],
    /// Rectification rotation, row-major (identity for a monocular camera).
    pub r: [f64; 9],
    /// Projection matrix of the rectified image, row-major 3 × 4.
    pub p: [f64; 12],
    /// Horizontal binning (0 = none).
    pub binning_x: u32,
    /// Vertical binning (0 = none).
    pub binning_y: u32,
    /// Region of interest (all 0: the full image).
    pub roi: RegionOfInterest,
}

impl Message for CameraInfo {
    const TYPE: &'static str = "sensor_msgs/msg/CameraInfo";
    const SCHEMA: &'static str = concat!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n",
        "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n",
        "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        dep!(
            "sensor_msgs/RegionOfInterest",
            "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
        ),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        self.header.encode(w)?;
        w.u32(self.height);
        w.u32(self.width);
        w.string(self.distortion_model.as_str())?;
        w.f64_seq(&self.d)?;
        w.f64_array(&self.k);
        w.f64_array(&self.r);
        w.f64_array(&self.p);
        w.u32(self.binning_x);
        w.u32(self.binning_y);
        self.roi.encode(w)
    }
}

/// `geometry_msgs/msg/PoseStamped`: where a frame is and how it is turned, in `header.frame_id`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseStamped {
    /// Stamp and the parent frame.
    pub header: Header,
    /// Position x, y, z, metres.
    pub position: [f64; 3],
    /// Orientation as a unit quaternion x, y, z, w (ROS order), rotating vectors of the posed
    /// frame into the parent frame.
    pub orientation_xyzw: [f64; 4],
}

impl Message for PoseStamped {
    const TYPE: &'static str = "geometry_msgs/msg/PoseStamped";
    const SCHEMA: &'static str = concat!(
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        dep!(
            "geometry_msgs/Pose",
            "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
        ),
        dep!("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
        dep!(
            "geometry_msgs/Quaternion",
            "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
        ),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        self.header.encode(w)?;
        w.f64_array(&self.position);
        w.f64_array(&self.orientation_xyzw);
        Ok(())
    }
}

/// `geometry_msgs/msg/Vector3Stamped`: a direction or vector in `header.frame_id`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vector3Stamped {
    /// Stamp and frame.
    pub header: Header,
    /// x, y, z.
    pub vector: [f64; 3],
}

impl Message for Vector3Stamped {
    const TYPE: &'static str = "geometry_msgs/msg/Vector3Stamped";
    const SCHEMA: &'static str = concat!(
        "std_msgs/Header header\ngeometry_msgs/Vector3 vector\n",
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        dep!("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        self.header.encode(w)?;
        w.f64_array(&self.vector);
        Ok(())
    }
}

/// `geometry_msgs/msg/TransformStamped`: where `child_frame_id` is in `header.frame_id`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransformStamped {
    /// Stamp and the parent frame.
    pub header: Header,
    /// The frame this transform places.
    pub child_frame_id: FrameId,
    /// The child's origin in the parent frame, metres.
    pub translation: [f64; 3],
    /// Unit quaternion x, y, z, w (ROS order), rotating vectors of the child frame into the
    /// parent frame.
    pub rotation_xyzw: [f64; 4],
}

impl Message for TransformStamped {
    const TYPE: &'static str = "geometry_msgs/msg/TransformStamped";
    const SCHEMA: &'static str = concat!(
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        dep!(
            "geometry_msgs/Transform",
            "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
        ),
        dep!("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
        dep!(
            "geometry_msgs/Quaternion",
            "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
        ),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        self.header.encode(w)?;
        w.string(self.child_frame_id.as_str())?;
        w.f64_array(&self.translation);
        w.f64_array(&self.rotation_xyzw);
        Ok(())
    }
}

/// `tf2_msgs/msg/TFMessage`: the transforms of one moment, as `/tf` carries them.
#[derive(Clone, Debug, PartialEq)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl Message for TfMessage {
    const TYPE: &'static str = "tf2_msgs/msg/TFMessage";
    const SCHEMA: &'static str = concat!(
        "geometry_msgs/TransformStamped[] transforms\n",
        dep!(
            "geometry_msgs/TransformStamped",
            "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"
        ),
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        dep!(
            "geometry_msgs/Transform",
            "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
        ),
        dep!("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
        dep!(
            "geometry_msgs/Quaternion",
            "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
        ),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        w.seq_len(self.transforms.len())?;
        for t in &self.transforms {
            t.encode(w)?;
        }
        Ok(())
    }
}

/// `std_msgs/msg/Float64MultiArray` of one dimension: `data` with the dimension's `label`.
#[derive(Clone, Debug, PartialEq)]
pub struct Float64MultiArray {
    /// What the elements are.
    pub label: String,
    /// The values.
    pub data: Vec<f64>,
}

impl Message for Float64MultiArray {
    const TYPE: &'static str = "std_msgs/msg/Float64MultiArray";
    const SCHEMA: &'static str = concat!(
        "std_msgs/MultiArrayLayout layout\nfloat64[] data\n",
        dep!(
            "std_msgs/MultiArrayLayout",
            "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n"
        ),
        dep!(
            "std_msgs/MultiArrayDimension",
            "string label\nuint32 size\nuint32 stride\n"
        ),
    );
    fn encode(&self, w: &mut CdrWriter) -> Result<()> {
        let n = u32::try_from(self.data.len())
            .map_err(|_| Error::Invalid(format!("{} values in one array", self.data.len())))?;
        w.seq_len(1)?;
        w.string(&self.label)?;
        w.u32(n); // size
        w.u32(n); // stride
        w.u32(0); // data_offset
        w.f64_seq(&self.data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER_DEPS: &str = concat!(
        dep!(
            "std_msgs/Header",
            "builtin_interfaces/Time stamp\nstring frame_id\n"
        ),
        dep!("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    );

    fn header() -> Header {
        Header {
            stamp: Time {
                sec: 1_750_500_000,
                nanosec: 50_000_000,
            },
            frame_id: FrameId::Enu,
        }
    }

    #[test]
    fn header_bytes_by_hand() {
        let b = header().to_cdr().unwrap();
        let mut want = vec![0, 1, 0, 0];
        want.extend(1_750_500_000i32.to_le_bytes());
        want.extend(50_000_000u32.to_le_bytes());
        want.extend(4u32.to_le_bytes());
        want.extend(b"enu\0");
        assert_eq!(b, want);
    }

    #[test]
    fn vector3_stamped_pads_to_eight_after_the_frame_id() {
        let v = Vector3Stamped {
            header: header(),
            vector: [1.0, 2.0, 3.0],
        };
        let b = v.to_cdr().unwrap();
        // header ends at payload offset 16 ("enu\0" at 12..16): the doubles start at 16
        assert_eq!(b.len(), 4 + 16 + 24);
        assert_eq!(&b[20..28], &1.0f64.to_le_bytes());
        // with the 20-byte optical frame id the header ends at 32: no padding either
        let v = Vector3Stamped {
            header: Header {
                frame_id: FrameId::CameraOptical,
                ..header()
            },
            ..v
        };
        let b = v.to_cdr().unwrap();
        assert_eq!(b.len(), 4 + 32 + 24);
    }

    #[test]
    fn image_prefix_and_pixels_are_the_whole_message() {
        for frame_id in [FrameId::CameraOptical, FrameId::Enu] {
            let enc = [
                ImageEncoding::Mono8,
                ImageEncoding::Mono16,
                ImageEncoding::Float32,
            ];
            for (e, (w, h)) in enc.into_iter().zip([(3, 5), (7, 1), (2, 2)]) {
                let px: Vec<u8> = (0..w * h * e.bytes_per_pixel()).map(|i| i as u8).collect();
                for ns in [0, 1_750_500_000_123_456_789] {
                    let hd = Header {
                        stamp: Time::from_unix_ns(ns).unwrap(),
                        frame_id,
                    };
                    let pre = Image::cdr_prefix(hd, w, h, e).unwrap();
                    let whole = Image::new(hd, w, h, e, &px).unwrap().to_cdr().unwrap();
                    assert_eq!([&pre[..], &px[..]].concat(), whole, "{e:?} {frame_id:?}");
                    // the length does not depend on the stamp or the size
                    let other = Image::cdr_prefix(hd, 2448, 2048, e).unwrap();
                    assert_eq!(other.len(), pre.len());
                    assert_eq!(pre.len() % 4, 0);
                }
            }
        }
        assert!(Image::cdr_prefix(header(), u32::MAX, 1, ImageEncoding::Mono16).is_err());
    }

    #[test]
    fn schemas_end_with_their_dependencies() {
        assert!(Header::SCHEMA.ends_with(TIME_DEF));
        assert!(Image::SCHEMA.ends_with(HEADER_DEPS));
        assert!(CameraInfo::SCHEMA.contains(HEADER_DEPS));
        assert!(PoseStamped::SCHEMA.contains(HEADER_DEPS));
        assert!(Vector3Stamped::SCHEMA.contains(HEADER_DEPS));
        assert!(TransformStamped::SCHEMA.contains(HEADER_DEPS));
        assert!(TfMessage::SCHEMA.contains(HEADER_DEPS));
        for s in [
            Image::SCHEMA,
            CameraInfo::SCHEMA,
            PoseStamped::SCHEMA,
            Vector3Stamped::SCHEMA,
            TransformStamped::SCHEMA,
            TfMessage::SCHEMA,
        ] {
            for block in s.split("================================================================================\n").skip(1) {
                assert!(block.starts_with("MSG: "), "{block}");
            }
        }
    }
}
