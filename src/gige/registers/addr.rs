//! Register addresses.

/// GigE Vision version (major << 16 | minor).
pub const VERSION: u32 = 0x0000;
/// Device mode: big-endian registers, UTF-8 strings.
pub const DEVICE_MODE: u32 = 0x0004;
/// MAC address, high 16 bits.
pub const MAC_HIGH: u32 = 0x0008;
/// MAC address, low 32 bits.
pub const MAC_LOW: u32 = 0x000C;
/// Supported IP configuration.
pub const SUPPORTED_IP_CONFIG: u32 = 0x0010;
/// Current IP configuration.
pub const CURRENT_IP_CONFIG: u32 = 0x0014;
/// Current IPv4 address.
pub const CURRENT_IP: u32 = 0x0024;
/// Current subnet mask.
pub const SUBNET_MASK: u32 = 0x0034;
/// Current default gateway.
pub const GATEWAY: u32 = 0x0044;
/// Manufacturer name, 32 bytes.
pub const MANUFACTURER: u32 = 0x0048;
/// Model name, 32 bytes.
pub const MODEL: u32 = 0x0068;
/// Device version, 32 bytes.
pub const DEVICE_VERSION: u32 = 0x0088;
/// Manufacturer information, 48 bytes.
pub const MANUFACTURER_INFO: u32 = 0x00A8;
/// Serial number, 16 bytes.
pub const SERIAL: u32 = 0x00D8;
/// User-defined name (DeviceUserID), 16 bytes, writable.
pub const USER_NAME: u32 = 0x00E8;
/// First URL of the GenICam XML, 512 bytes.
pub const XML_URL_0: u32 = 0x0200;
/// Second URL of the GenICam XML, 512 bytes (empty).
pub const XML_URL_1: u32 = 0x0400;
/// Number of network interfaces.
pub const NET_INTERFACES: u32 = 0x0600;
/// Persistent IP address (not used: 0).
pub const PERSISTENT_IP: u32 = 0x064C;
/// Persistent subnet mask (0).
pub const PERSISTENT_MASK: u32 = 0x065C;
/// Persistent gateway (0).
pub const PERSISTENT_GATEWAY: u32 = 0x066C;
/// Number of message channels (0).
pub const MESSAGE_CHANNELS: u32 = 0x0900;
/// Number of stream channels (1).
pub const STREAM_CHANNELS: u32 = 0x0904;
/// GVCP capability flags.
pub const GVCP_CAPABILITY: u32 = 0x0934;
/// Heartbeat timeout, ms.
pub const HEARTBEAT_TIMEOUT: u32 = 0x0938;
/// Timestamp tick frequency, high 32 bits.
pub const TICK_FREQUENCY_HIGH: u32 = 0x093C;
/// Timestamp tick frequency, low 32 bits.
pub const TICK_FREQUENCY_LOW: u32 = 0x0940;
/// Timestamp control: bit 0 reset, bit 1 latch (write only).
pub const TIMESTAMP_CONTROL: u32 = 0x0944;
/// Latched timestamp, high 32 bits.
pub const TIMESTAMP_LATCH_HIGH: u32 = 0x0948;
/// Latched timestamp, low 32 bits.
pub const TIMESTAMP_LATCH_LOW: u32 = 0x094C;
/// GVCP configuration (stored, no effect).
pub const GVCP_CONFIG: u32 = 0x0954;
/// Control channel privilege: bit 1 control, bit 0 exclusive.
pub const CCP: u32 = 0x0A00;
/// Stream channel 0: host port (low 16 bits).
pub const SCP: u32 = 0x0D00;
/// Stream channel 0: packet size (bits 0..15), bit 30 do not fragment, bit 31 fire a test
/// packet.
pub const SCPS: u32 = 0x0D04;
/// Stream channel 0: delay between packets, timestamp ticks.
pub const SCPD: u32 = 0x0D08;
/// Stream channel 0: destination IPv4 address.
pub const SCDA: u32 = 0x0D18;
/// Stream channel 0: source UDP port (read only).
pub const SCSP: u32 = 0x0D1C;
/// Stream channel 0: capability (0).
pub const SCC: u32 = 0x0D20;
/// Stream channel 0: configuration (0).
pub const SCCFG: u32 = 0x0D24;

/// First feature register.
pub const FEATURES: u32 = 0x0010_0000;
/// SensorWidth (RO).
pub const SENSOR_WIDTH: u32 = FEATURES;
/// SensorHeight (RO).
pub const SENSOR_HEIGHT: u32 = FEATURES + 0x04;
/// Width.
pub const WIDTH: u32 = FEATURES + 0x08;
/// Height.
pub const HEIGHT: u32 = FEATURES + 0x0C;
/// OffsetX.
pub const OFFSET_X: u32 = FEATURES + 0x10;
/// OffsetY.
pub const OFFSET_Y: u32 = FEATURES + 0x14;
/// PixelFormat (the format's code).
pub const PIXEL_FORMAT: u32 = FEATURES + 0x18;
/// PayloadSize (RO).
pub const PAYLOAD_SIZE: u32 = FEATURES + 0x1C;
/// AcquisitionMode: 0 Continuous, 1 SingleFrame, 2 MultiFrame.
pub const ACQUISITION_MODE: u32 = FEATURES + 0x20;
/// AcquisitionFrameCount (MultiFrame).
pub const ACQUISITION_FRAME_COUNT: u32 = FEATURES + 0x24;
/// AcquisitionStart (command, WO).
pub const ACQUISITION_START: u32 = FEATURES + 0x28;
/// AcquisitionStop (command, WO).
pub const ACQUISITION_STOP: u32 = FEATURES + 0x2C;
/// AcquisitionFrameRateEnable.
pub const FRAME_RATE_ENABLE: u32 = FEATURES + 0x30;
/// TriggerSelector: 0 FrameStart.
pub const TRIGGER_SELECTOR: u32 = FEATURES + 0x34;
/// TriggerMode: 0 Off, 1 On.
pub const TRIGGER_MODE: u32 = FEATURES + 0x38;
/// TriggerSource: 0 Software.
pub const TRIGGER_SOURCE: u32 = FEATURES + 0x3C;
/// TriggerSoftware (command, WO).
pub const TRIGGER_SOFTWARE: u32 = FEATURES + 0x40;
/// ExposureAuto: 0 Off, 2 Continuous.
pub const EXPOSURE_AUTO: u32 = FEATURES + 0x44;
/// GainAuto: 0 Off.
pub const GAIN_AUTO: u32 = FEATURES + 0x48;
/// DeviceLinkThroughputLimitMode: 0 Off, 1 On.
pub const THROUGHPUT_LIMIT_MODE: u32 = FEATURES + 0x4C;
/// ChunkModeActive.
pub const CHUNK_MODE_ACTIVE: u32 = FEATURES + 0x50;
/// ChunkSelector (index into [`super::ChunkKind::ALL`]).
pub const CHUNK_SELECTOR: u32 = FEATURES + 0x54;
/// TLParamsLocked.
pub const TL_PARAMS_LOCKED: u32 = FEATURES + 0x58;
/// ExposureTime, µs (f64).
pub const EXPOSURE_TIME: u32 = FEATURES + 0x80;
/// Gain, dB (f64).
pub const GAIN: u32 = FEATURES + 0x88;
/// BlackLevel, DN at 12 bits (f64).
pub const BLACK_LEVEL: u32 = FEATURES + 0x90;
/// AcquisitionFrameRate, Hz (f64).
pub const FRAME_RATE: u32 = FEATURES + 0x98;
/// AcquisitionResultingFrameRate, Hz (f64, RO).
pub const RESULTING_FRAME_RATE: u32 = FEATURES + 0xA0;
/// DeviceLinkThroughputLimit, bytes per second (u64).
pub const THROUGHPUT_LIMIT: u32 = FEATURES + 0xA8;
/// DeviceTemperature, °C (f64, RO).
pub const DEVICE_TEMPERATURE: u32 = FEATURES + 0xB0;
/// ChunkEnable of chunk k at `CHUNK_ENABLE + 4 k`.
pub const CHUNK_ENABLE: u32 = FEATURES + 0x100;
/// The GenICam XML.
pub const XML: u32 = 0x0020_0000;
