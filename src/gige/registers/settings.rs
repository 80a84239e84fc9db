//! What the registers hold: the limits, the device's identity, the camera settings, the stream
//! channel, and what the device asks of the front-end.

use super::*;

/// Smallest stream packet size (SCPS), bytes with IP and UDP headers.
pub const PACKET_SIZE_MIN: u32 = 576;
/// Largest stream packet size: the largest IPv4 datagram, rounded down to 4 bytes.
pub const PACKET_SIZE_MAX: u32 = 65532;
/// Default stream packet size.
pub const PACKET_SIZE_DEFAULT: u32 = 1500;
/// Largest delay between stream packets, ticks (ns).
pub const PACKET_DELAY_MAX: u32 = 1_000_000;
/// Default heartbeat timeout, ms.
pub const HEARTBEAT_DEFAULT_MS: u32 = 3000;
/// Smallest heartbeat timeout, ms.
pub const HEARTBEAT_MIN_MS: u32 = 500;
/// Largest heartbeat timeout, ms (10 min).
pub const HEARTBEAT_MAX_MS: u32 = 600_000;
/// AcquisitionFrameRate range, Hz.
pub const FRAME_RATE_RANGE: (f64, f64) = (0.1, 1000.0);
/// Default AcquisitionFrameRate, Hz.
pub const FRAME_RATE_DEFAULT: f64 = 20.0;
/// ExposureTime range, µs (the sensor model's).
pub const EXPOSURE_RANGE: (f64, f64) = (20.0, 10_000_000.0);
/// Gain range, dB.
pub const GAIN_RANGE: (f64, f64) = (0.0, 48.0);
/// BlackLevel range, DN at 12 bits.
pub const BLACK_LEVEL_RANGE: (f64, f64) = (0.0, 200.0);
/// DeviceLinkThroughputLimit range, bytes/s.
pub const THROUGHPUT_RANGE: (u64, u64) = (1_000_000, 10_000_000_000);
/// Default DeviceLinkThroughputLimit: a 1 GigE link, 125 MB/s.
pub const THROUGHPUT_DEFAULT: u64 = 125_000_000;
/// Software triggers waiting for their frame, at most.
pub const MAX_PENDING_TRIGGERS: u32 = 64;
/// Timestamp tick frequency, Hz.
pub const TICK_FREQUENCY: u64 = 1_000_000_000;

pub(super) const CCP_CONTROL: u32 = 1 << 1;
pub(super) const CCP_EXCLUSIVE: u32 = 1 << 0;

/// What the device says about itself (bootstrap strings, sensor size, temperature).
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// Manufacturer name (at most 31 bytes).
    pub vendor: String,
    /// Model name (at most 31 bytes).
    pub model: String,
    /// Device version (at most 31 bytes).
    pub version: String,
    /// Manufacturer information (at most 47 bytes).
    pub manufacturer_info: String,
    /// Serial number (at most 15 bytes).
    pub serial: String,
    /// Initial user-defined name (at most 15 bytes).
    pub user_id: String,
    /// MAC address.
    pub mac: [u8; 6],
    /// Sensor width, pixels (even).
    pub sensor_width: u32,
    /// Sensor height, pixels (even).
    pub sensor_height: u32,
    /// Sensor temperature, °C.
    pub temperature_c: f64,
    /// The settings at power-up.
    pub defaults: Settings,
}

impl Default for DeviceInfo {
    fn default() -> Self {
        DeviceInfo {
            vendor: "psns".into(),
            model: "IMX250MZR-sky".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            manufacturer_info: "psns polarization camera emulator".into(),
            serial: "PSNS0001".into(),
            user_id: String::new(),
            mac: [0x02, 0x50, 0x53, 0x4E, 0x00, 0x01],
            sensor_width: 2448,
            sensor_height: 2048,
            temperature_c: 25.0,
            defaults: Settings::default(),
        }
    }
}

/// AcquisitionMode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcquisitionMode {
    /// Frames until AcquisitionStop.
    Continuous = 0,
    /// One frame.
    SingleFrame = 1,
    /// AcquisitionFrameCount frames.
    MultiFrame = 2,
}

/// The client's settings of the image and the acquisition. They persist across control
/// sessions until the device restarts.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Width of the region, pixels (even).
    pub width: u32,
    /// Height of the region, pixels (even).
    pub height: u32,
    /// First column of the region (even).
    pub offset_x: u32,
    /// First row of the region (even).
    pub offset_y: u32,
    /// Pixel format.
    pub pixel_format: GevPixelFormat,
    /// Fixed exposure, µs (the value in force when `exposure_auto` is off).
    pub exposure_us: f64,
    /// ExposureAuto = Continuous.
    pub exposure_auto: bool,
    /// Gain, dB.
    pub gain_db: f64,
    /// Black level, DN at 12 bits.
    pub black_level: f64,
    /// AcquisitionMode.
    pub acquisition_mode: AcquisitionMode,
    /// AcquisitionFrameCount.
    pub frame_count: u32,
    /// AcquisitionFrameRateEnable.
    pub frame_rate_enable: bool,
    /// AcquisitionFrameRate, Hz.
    pub frame_rate: f64,
    /// TriggerMode = On (the source is Software).
    pub trigger_mode: bool,
    /// DeviceLinkThroughputLimitMode = On.
    pub throughput_limit_on: bool,
    /// DeviceLinkThroughputLimit, bytes/s.
    pub throughput_limit: u64,
    /// ChunkModeActive.
    pub chunk_mode: bool,
    /// ChunkSelector.
    pub chunk_selector: u32,
    /// ChunkEnable per [`ChunkKind`] (bit k).
    pub chunk_mask: u32,
    /// TLParamsLocked.
    pub tl_locked: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            width: 2448,
            height: 2048,
            offset_x: 0,
            offset_y: 0,
            pixel_format: GevPixelFormat::Mono8,
            exposure_us: 1000.0,
            exposure_auto: false,
            gain_db: 0.0,
            black_level: 0.0,
            acquisition_mode: AcquisitionMode::Continuous,
            frame_count: 1,
            frame_rate_enable: false,
            frame_rate: FRAME_RATE_DEFAULT,
            trigger_mode: false,
            throughput_limit_on: false,
            throughput_limit: THROUGHPUT_DEFAULT,
            chunk_mode: false,
            chunk_selector: 0,
            chunk_mask: chunk::ALL_MASK,
            tl_locked: false,
        }
    }
}

impl Settings {
    /// Image bytes of one frame.
    pub fn image_bytes(&self) -> usize {
        self.pixel_format
            .image_bytes(self.width as usize, self.height as usize)
            .unwrap_or(usize::MAX)
    }

    /// The chunks in force (none when chunk mode is off).
    pub fn chunks(&self) -> u32 {
        if self.chunk_mode {
            self.chunk_mask & chunk::ALL_MASK
        } else {
            0
        }
    }

    /// Bytes of one block: the image and, in chunk mode, the chunk trailers and data.
    pub fn payload_size(&self) -> usize {
        self.image_bytes()
            + if self.chunk_mode {
                chunk::tail_len(self.chunks())
            } else {
                0
            }
    }

    /// The GVSP payload type of the blocks.
    pub fn payload_type(&self) -> u16 {
        if self.chunk_mode {
            gvsp::PAYLOAD_IMAGE_CHUNK
        } else {
            gvsp::PAYLOAD_IMAGE
        }
    }
}

/// Stream channel 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Channel {
    /// Host port (0: closed).
    pub host_port: u16,
    /// Destination address.
    pub dest: Ipv4Addr,
    /// Packet size, bytes with IP and UDP headers.
    pub packet_size: u32,
    /// Do-not-fragment bit.
    pub do_not_fragment: bool,
    /// Delay between packets, ticks (ns).
    pub packet_delay: u32,
    /// The device's source port (set by the front-end once its socket is bound).
    pub source_port: u16,
}

impl Channel {
    /// The destination, when the channel is open.
    pub fn destination(&self) -> Option<SocketAddrV4> {
        (self.host_port != 0 && !self.dest.is_unspecified())
            .then(|| SocketAddrV4::new(self.dest, self.host_port))
    }
}

/// A frame the device starts: what to render and where to send it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameOrder {
    /// Blocks started since the device started, this one included (1, 2, ...).
    pub k: u64,
    /// Its block id ([`gvsp::block_id_of`]`(k)`).
    pub block_id: u16,
    /// psns's frame index: k − 1.
    pub frame_index: u64,
    /// Device timestamp at the start of the frame, ticks.
    pub timestamp: u64,
    /// The settings of this frame.
    pub settings: Settings,
    /// The stream channel when the frame started.
    pub channel: Channel,
}

/// What [`Device::poll_frame`] says.
#[derive(Clone, Debug, PartialEq)]
pub enum Poll {
    /// Start this frame now.
    Frame(Box<FrameOrder>),
    /// The next frame is due at this device time (ns).
    At(u64),
    /// No frame until a command arrives (acquisition stopped, or waiting for a trigger).
    Idle,
}

/// Something the front-end does for a command besides answering it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Send stream packets `first..=last` of a block again.
    Resend {
        /// Block id.
        block_id: u64,
        /// First packet id.
        first: u32,
        /// Last packet id.
        last: u32,
    },
    /// Send one test datagram of `packet_size − 28` bytes to the stream destination.
    FireTestPacket {
        /// Where to.
        dest: SocketAddrV4,
        /// The packet size (IP and UDP headers included).
        packet_size: u32,
        /// Whether the test packet must not be fragmented.
        do_not_fragment: bool,
    },
}

/// What the device does with one datagram.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outcome {
    /// The acknowledge to send back to the sender.
    pub reply: Option<Vec<u8>>,
    /// Work for the front-end.
    pub actions: Vec<Action>,
}
