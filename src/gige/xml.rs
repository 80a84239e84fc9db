//! The device's GenICam description (GenApi schema 1.1), served from device memory at
//! [`addr::XML`]: every feature mapped onto the registers of
//! [`super::registers`], with the SFNC names a client expects.
//!
//! ```
//! let xml = psns::gige::xml::genicam_xml();
//! assert!(xml.starts_with("<?xml"));
//! for f in ["DeviceVendorName", "Width", "PixelFormat", "PolarizeMono12p", "ExposureTime",
//!           "AcquisitionStart", "TriggerSoftware", "ChunkSunAzimuth", "GevSCPSPacketSize"] {
//!     assert!(xml.contains(&format!("Name=\"{f}\"")), "{f}");
//! }
//! ```

use super::chunk::ChunkKind;
use super::pixel::GevPixelFormat;
use super::registers::{self, addr};
use std::fmt::Write;

/// Access mode of a register.
#[derive(Clone, Copy)]
enum Access {
    Ro,
    Rw,
    Wo,
}

impl Access {
    fn as_str(self) -> &'static str {
        match self {
            Access::Ro => "RO",
            Access::Rw => "RW",
            Access::Wo => "WO",
        }
    }
}

/// A small writer of GenApi nodes (elements in the schema's order).
struct X {
    s: String,
}

fn esc(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

impl X {
    fn line(&mut self, indent: usize, text: &str) {
        for _ in 0..indent {
            self.s.push_str("  ");
        }
        self.s.push_str(text);
        self.s.push('\n');
    }

    fn el(&mut self, indent: usize, name: &str, value: &str) {
        self.line(indent, &format!("<{name}>{}</{name}>", esc(value)));
    }

    fn open(&mut self, kind: &str, name: &str, standard: bool) {
        let ns = if standard { "Standard" } else { "Custom" };
        self.line(1, &format!("<{kind} Name=\"{name}\" NameSpace=\"{ns}\">"));
    }

    fn close(&mut self, kind: &str) {
        self.line(1, &format!("</{kind}>"));
    }

    /// ToolTip/Description/Visibility, the first elements of every node.
    fn head(&mut self, tip: &str, expert: bool) {
        self.el(2, "ToolTip", tip);
        if expert {
            self.el(2, "Visibility", "Expert");
        }
    }

    fn category(&mut self, name: &str, tip: &str, features: &[&str]) {
        self.open("Category", name, true);
        self.head(tip, false);
        for f in features {
            self.el(2, "pFeature", f);
        }
        self.close("Category");
    }

    /// A register node (IntReg, FloatReg, StringReg, MaskedIntReg) on the device port.
    #[allow(clippy::too_many_arguments)]
    fn register(
        &mut self,
        kind: &str,
        name: &str,
        address: u32,
        len: u32,
        access: Access,
        port: &str,
        index: Option<&str>,
        tail: &[(&str, &str)],
    ) {
        self.open(kind, name, false);
        self.el(2, "Visibility", "Invisible");
        self.el(2, "Address", &format!("0x{address:X}"));
        if let Some(i) = index {
            self.line(2, &format!("<pIndex Offset=\"4\">{i}</pIndex>"));
        }
        self.el(2, "Length", &len.to_string());
        self.el(2, "AccessMode", access.as_str());
        self.el(2, "pPort", port);
        self.el(2, "Cachable", "NoCache");
        for (k, v) in tail {
            self.el(2, k, v);
        }
        self.close(kind);
    }

    fn int_reg(&mut self, name: &str, address: u32, len: u32, access: Access) {
        self.register(
            "IntReg",
            name,
            address,
            len,
            access,
            "Device",
            None,
            &[("Sign", "Unsigned"), ("Endianess", "BigEndian")],
        );
    }

    fn float_reg(&mut self, name: &str, address: u32, access: Access) {
        self.register(
            "FloatReg",
            name,
            address,
            8,
            access,
            "Device",
            None,
            &[("Endianess", "BigEndian")],
        );
    }

    fn masked(&mut self, name: &str, address: u32, access: Access, bits: &[(&str, &str)]) {
        let mut tail = bits.to_vec();
        tail.extend([("Sign", "Unsigned"), ("Endianess", "BigEndian")]);
        self.register(
            "MaskedIntReg",
            name,
            address,
            4,
            access,
            "Device",
            None,
            &tail,
        );
    }

    /// An Integer feature on a register, with bounds (`Min`/`Max`/`Inc` or `pMin`/`pMax`).
    #[allow(clippy::too_many_arguments)]
    fn integer(
        &mut self,
        name: &str,
        tip: &str,
        expert: bool,
        locked: bool,
        value: &str,
        bounds: &[(&str, String)],
        unit: Option<&str>,
        repr: Option<&str>,
    ) {
        self.open("Integer", name, true);
        self.head(tip, expert);
        if locked {
            self.el(2, "pIsLocked", "TLParamsLocked");
        }
        self.el(2, "pValue", value);
        for (k, v) in bounds {
            self.el(2, k, v);
        }
        if let Some(u) = unit {
            self.el(2, "Unit", u);
        }
        if let Some(r) = repr {
            self.el(2, "Representation", r);
        }
        self.close("Integer");
    }

    fn float(&mut self, name: &str, tip: &str, value: &str, range: Option<(f64, f64)>, unit: &str) {
        self.open("Float", name, true);
        self.head(tip, false);
        self.el(2, "pValue", value);
        if let Some((lo, hi)) = range {
            self.el(2, "Min", &lo.to_string());
            self.el(2, "Max", &hi.to_string());
        }
        self.el(2, "Unit", unit);
        self.close("Float");
    }

    fn boolean(&mut self, name: &str, tip: &str, expert: bool, locked: bool, value: &str) {
        self.open("Boolean", name, true);
        self.head(tip, expert);
        if locked {
            self.el(2, "pIsLocked", "TLParamsLocked");
        }
        self.el(2, "pValue", value);
        self.el(2, "OnValue", "1");
        self.el(2, "OffValue", "0");
        self.close("Boolean");
    }

    fn command(&mut self, name: &str, tip: &str, expert: bool, value: &str, command_value: u32) {
        self.open("Command", name, true);
        self.head(tip, expert);
        self.el(2, "pValue", value);
        self.el(2, "CommandValue", &command_value.to_string());
        self.close("Command");
    }

    fn enumeration(
        &mut self,
        name: &str,
        tip: &str,
        locked: bool,
        value: &str,
        entries: &[(&str, u32, &str)],
    ) {
        self.open("Enumeration", name, true);
        self.head(tip, false);
        if locked {
            self.el(2, "pIsLocked", "TLParamsLocked");
        }
        for (e, v, t) in entries {
            self.line(
                2,
                &format!("<EnumEntry Name=\"{e}\" NameSpace=\"Standard\">"),
            );
            self.el(3, "ToolTip", t);
            self.el(3, "Value", &format!("0x{v:X}"));
            self.line(2, "</EnumEntry>");
        }
        self.el(2, "pValue", value);
        self.close("Enumeration");
    }

    fn string_reg(&mut self, name: &str, tip: &str, address: u32, len: u32, access: Access) {
        self.open("StringReg", name, true);
        self.head(tip, false);
        self.el(2, "Address", &format!("0x{address:X}"));
        self.el(2, "Length", &len.to_string());
        self.el(2, "AccessMode", access.as_str());
        self.el(2, "pPort", "Device");
        self.el(2, "Cachable", "NoCache");
        self.close("StringReg");
    }

    fn swiss_knife(&mut self, name: &str, vars: &[(&str, &str)], formula: &str) {
        self.open("IntSwissKnife", name, false);
        self.el(2, "Visibility", "Invisible");
        for (v, node) in vars {
            self.line(2, &format!("<pVariable Name=\"{v}\">{node}</pVariable>"));
        }
        self.el(2, "Formula", formula);
        self.close("IntSwissKnife");
    }

    fn port(&mut self, name: &str, chunk_id: Option<u32>) {
        self.open("Port", name, chunk_id.is_none());
        self.el(2, "Visibility", "Invisible");
        if let Some(id) = chunk_id {
            self.el(2, "ChunkID", &format!("{id:08X}"));
        }
        self.close("Port");
    }
}

/// Product GUID of the description (fixed).
pub const PRODUCT_GUID: &str = "5053534e-4749-4745-8000-494d58323530";
/// Version GUID of the description (changes with the register map).
pub const VERSION_GUID: &str = "5053534e-4749-4745-8001-000000000001";

/// The GenICam XML of the device.
pub fn genicam_xml() -> String {
    let mut x = X { s: String::new() };
    x.s.push_str("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    let _ = writeln!(
        x.s,
        "<RegisterDescription ModelName=\"IMX250MZR_sky\" VendorName=\"psns\" \
         ToolTip=\"psns: the Sony IMX250MZR polarization camera looking at a clear sky\" \
         StandardNameSpace=\"GEV\" SchemaMajorVersion=\"1\" SchemaMinorVersion=\"1\" \
         SchemaSubMinorVersion=\"0\" MajorVersion=\"1\" MinorVersion=\"0\" SubMinorVersion=\"0\" \
         ProductGuid=\"{PRODUCT_GUID}\" VersionGuid=\"{VERSION_GUID}\" \
         xmlns=\"http://www.genicam.org/GenApi/Version_1_1\" \
         xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" \
         xsi:schemaLocation=\"http://www.genicam.org/GenApi/Version_1_1 \
         http://www.genicam.org/GenApi/GenApiSchema_Version_1_1.xsd\">"
    );
    categories(&mut x);
    device_control(&mut x);
    image_format(&mut x);
    acquisition(&mut x);
    analog(&mut x);
    chunks(&mut x);
    transport(&mut x);
    x.port("Device", None);
    x.s.push_str("</RegisterDescription>\n");
    x.s
}

fn categories(x: &mut X) {
    x.category(
        "Root",
        "The features of the device.",
        &[
            "DeviceControl",
            "ImageFormatControl",
            "AcquisitionControl",
            "AnalogControl",
            "ChunkDataControl",
            "TransportLayerControl",
        ],
    );
    x.category(
        "DeviceControl",
        "Device information and control.",
        &[
            "DeviceVendorName",
            "DeviceModelName",
            "DeviceManufacturerInfo",
            "DeviceVersion",
            "DeviceSerialNumber",
            "DeviceUserID",
            "DeviceTemperature",
            "DeviceLinkThroughputLimitMode",
            "DeviceLinkThroughputLimit",
            "TimestampLatch",
            "TimestampLatchValue",
        ],
    );
    x.category(
        "ImageFormatControl",
        "Region and pixel format.",
        &[
            "SensorWidth",
            "SensorHeight",
            "WidthMax",
            "HeightMax",
            "Width",
            "Height",
            "OffsetX",
            "OffsetY",
            "PixelFormat",
        ],
    );
    x.category(
        "AcquisitionControl",
        "Acquisition, triggers and exposure.",
        &[
            "AcquisitionMode",
            "AcquisitionStart",
            "AcquisitionStop",
            "AcquisitionFrameCount",
            "AcquisitionFrameRateEnable",
            "AcquisitionFrameRate",
            "AcquisitionResultingFrameRate",
            "TriggerSelector",
            "TriggerMode",
            "TriggerSource",
            "TriggerSoftware",
            "ExposureAuto",
            "ExposureTime",
        ],
    );
    x.category(
        "AnalogControl",
        "Gain and black level.",
        &["Gain", "GainAuto", "BlackLevel"],
    );
    let mut chunk_features = vec!["ChunkModeActive", "ChunkSelector", "ChunkEnable"];
    chunk_features.extend(CHUNK_FEATURES.iter().map(|c| c.0));
    chunk_features.push("ChunkPixelFormat");
    x.category(
        "ChunkDataControl",
        "Per-frame data appended to the image.",
        &chunk_features,
    );
    x.category(
        "TransportLayerControl",
        "GigE Vision transport.",
        &[
            "PayloadSize",
            "GevCurrentIPAddress",
            "GevMACAddress",
            "GevStreamChannelCount",
            "GevHeartbeatTimeout",
            "GevTimestampTickFrequency",
            "GevSCPSPacketSize",
            "GevSCPSFireTestPacket",
            "GevSCPSDoNotFragment",
            "GevSCPD",
            "GevSCDA",
            "GevSCPHostPort",
            "GevSCSP",
        ],
    );
}

fn device_control(x: &mut X) {
    x.string_reg(
        "DeviceVendorName",
        "Name of the manufacturer.",
        addr::MANUFACTURER,
        32,
        Access::Ro,
    );
    x.string_reg(
        "DeviceModelName",
        "Model of the device.",
        addr::MODEL,
        32,
        Access::Ro,
    );
    x.string_reg(
        "DeviceManufacturerInfo",
        "Information from the manufacturer.",
        addr::MANUFACTURER_INFO,
        48,
        Access::Ro,
    );
    x.string_reg(
        "DeviceVersion",
        "Version of the device (psns's).",
        addr::DEVICE_VERSION,
        32,
        Access::Ro,
    );
    x.string_reg(
        "DeviceSerialNumber",
        "Serial number.",
        addr::SERIAL,
        16,
        Access::Ro,
    );
    x.string_reg(
        "DeviceUserID",
        "User-defined name (kept until the device restarts).",
        addr::USER_NAME,
        16,
        Access::Rw,
    );
    x.float(
        "DeviceTemperature",
        "Sensor temperature (the model's).",
        "DeviceTemperatureReg",
        None,
        "C",
    );
    x.float_reg("DeviceTemperatureReg", addr::DEVICE_TEMPERATURE, Access::Ro);
    x.enumeration(
        "DeviceLinkThroughputLimitMode",
        "On: stream packets are paced as a link of DeviceLinkThroughputLimit bytes/s would pace them.",
        false,
        "ThroughputLimitModeReg",
        &[("Off", 0, "No pacing."), ("On", 1, "Pace the stream.")],
    );
    x.int_reg(
        "ThroughputLimitModeReg",
        addr::THROUGHPUT_LIMIT_MODE,
        4,
        Access::Rw,
    );
    x.integer(
        "DeviceLinkThroughputLimit",
        "Link rate the stream is paced to, bytes per second, counting each packet with its IP, UDP and Ethernet framing.",
        false,
        false,
        "ThroughputLimitReg",
        &[
            ("Min", registers::THROUGHPUT_RANGE.0.to_string()),
            ("Max", registers::THROUGHPUT_RANGE.1.to_string()),
        ],
        Some("Bps"),
        None,
    );
    x.int_reg("ThroughputLimitReg", addr::THROUGHPUT_LIMIT, 8, Access::Rw);
    x.command(
        "TimestampLatch",
        "Latches the timestamp counter into TimestampLatchValue.",
        false,
        "TimestampControlReg",
        2,
    );
    x.int_reg(
        "TimestampControlReg",
        addr::TIMESTAMP_CONTROL,
        4,
        Access::Wo,
    );
    x.integer(
        "TimestampLatchValue",
        "The latched timestamp, ticks (ns since the device started).",
        false,
        false,
        "TimestampLatchValueReg",
        &[],
        None,
        None,
    );
    x.int_reg(
        "TimestampLatchValueReg",
        addr::TIMESTAMP_LATCH_HIGH,
        8,
        Access::Ro,
    );
}

fn image_format(x: &mut X) {
    x.integer(
        "SensorWidth",
        "Columns of the sensor.",
        false,
        false,
        "SensorWidthReg",
        &[],
        Some("px"),
        None,
    );
    x.int_reg("SensorWidthReg", addr::SENSOR_WIDTH, 4, Access::Ro);
    x.integer(
        "SensorHeight",
        "Rows of the sensor.",
        false,
        false,
        "SensorHeightReg",
        &[],
        Some("px"),
        None,
    );
    x.int_reg("SensorHeightReg", addr::SENSOR_HEIGHT, 4, Access::Ro);
    x.integer(
        "WidthMax",
        "Largest width.",
        false,
        false,
        "SensorWidthReg",
        &[],
        Some("px"),
        None,
    );
    x.integer(
        "HeightMax",
        "Largest height.",
        false,
        false,
        "SensorHeightReg",
        &[],
        Some("px"),
        None,
    );
    let two = || ("Min", "2".to_string());
    let inc = || ("Inc", "2".to_string());
    x.integer(
        "Width",
        "Width of the region, in steps of 2 (whole 2 x 2 polarizer cells).",
        false,
        true,
        "WidthReg",
        &[two(), ("pMax", "WidthMaxNow".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("WidthReg", addr::WIDTH, 4, Access::Rw);
    x.swiss_knife(
        "WidthMaxNow",
        &[("S", "SensorWidthReg"), ("O", "OffsetXReg")],
        "S-O",
    );
    x.integer(
        "Height",
        "Height of the region, in steps of 2.",
        false,
        true,
        "HeightReg",
        &[two(), ("pMax", "HeightMaxNow".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("HeightReg", addr::HEIGHT, 4, Access::Rw);
    x.swiss_knife(
        "HeightMaxNow",
        &[("S", "SensorHeightReg"), ("O", "OffsetYReg")],
        "S-O",
    );
    x.integer(
        "OffsetX",
        "First column of the region, in steps of 2 (the polarizer cell stays aligned).",
        false,
        true,
        "OffsetXReg",
        &[("Min", "0".into()), ("pMax", "OffsetXMax".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("OffsetXReg", addr::OFFSET_X, 4, Access::Rw);
    x.swiss_knife(
        "OffsetXMax",
        &[("S", "SensorWidthReg"), ("W", "WidthReg")],
        "S-W",
    );
    x.integer(
        "OffsetY",
        "First row of the region, in steps of 2.",
        false,
        true,
        "OffsetYReg",
        &[("Min", "0".into()), ("pMax", "OffsetYMax".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("OffsetYReg", addr::OFFSET_Y, 4, Access::Rw);
    x.swiss_knife(
        "OffsetYMax",
        &[("S", "SensorHeightReg"), ("H", "HeightReg")],
        "S-H",
    );
    let entries: Vec<(&str, u32, String)> = GevPixelFormat::ALL
        .iter()
        .map(|f| {
            let bits = if f.adc_bits() == 8 {
                "8-bit ADC"
            } else {
                "12-bit ADC"
            };
            let t = if f.polarized() {
                format!(
                    "LUCID's name for {}'s bytes ({bits}).",
                    f.packing().pfnc_name()
                )
            } else {
                format!("{} ({bits}).", f.name())
            };
            (f.name(), f.code(), t)
        })
        .collect();
    let e: Vec<(&str, u32, &str)> = entries
        .iter()
        .map(|(n, c, t)| (*n, *c, t.as_str()))
        .collect();
    x.enumeration(
        "PixelFormat",
        "Format of the pixels; the polarized names carry the same bytes as their Mono twins.",
        true,
        "PixelFormatReg",
        &e,
    );
    x.int_reg("PixelFormatReg", addr::PIXEL_FORMAT, 4, Access::Rw);
}

fn acquisition(x: &mut X) {
    x.enumeration(
        "AcquisitionMode",
        "How many frames an AcquisitionStart gives.",
        true,
        "AcquisitionModeReg",
        &[
            ("Continuous", 0, "Frames until AcquisitionStop."),
            ("SingleFrame", 1, "One frame."),
            ("MultiFrame", 2, "AcquisitionFrameCount frames."),
        ],
    );
    x.int_reg("AcquisitionModeReg", addr::ACQUISITION_MODE, 4, Access::Rw);
    x.command(
        "AcquisitionStart",
        "Starts the acquisition.",
        false,
        "AcquisitionStartReg",
        1,
    );
    x.int_reg(
        "AcquisitionStartReg",
        addr::ACQUISITION_START,
        4,
        Access::Wo,
    );
    x.command(
        "AcquisitionStop",
        "Stops the acquisition after the frame in flight.",
        false,
        "AcquisitionStopReg",
        1,
    );
    x.int_reg("AcquisitionStopReg", addr::ACQUISITION_STOP, 4, Access::Wo);
    x.integer(
        "AcquisitionFrameCount",
        "Frames of a MultiFrame acquisition.",
        false,
        true,
        "AcquisitionFrameCountReg",
        &[("Min", "1".into()), ("Max", "65535".into())],
        None,
        None,
    );
    x.int_reg(
        "AcquisitionFrameCountReg",
        addr::ACQUISITION_FRAME_COUNT,
        4,
        Access::Rw,
    );
    x.boolean(
        "AcquisitionFrameRateEnable",
        "Paces frames at AcquisitionFrameRate (off: as fast as the device renders).",
        false,
        false,
        "FrameRateEnableReg",
    );
    x.int_reg("FrameRateEnableReg", addr::FRAME_RATE_ENABLE, 4, Access::Rw);
    x.float(
        "AcquisitionFrameRate",
        "Frame rate; reads as the rate delivered when the device cannot render as fast as asked.",
        "FrameRateReg",
        Some(registers::FRAME_RATE_RANGE),
        "Hz",
    );
    x.float_reg("FrameRateReg", addr::FRAME_RATE, Access::Rw);
    x.float(
        "AcquisitionResultingFrameRate",
        "Rate of the recent frames.",
        "ResultingFrameRateReg",
        None,
        "Hz",
    );
    x.float_reg(
        "ResultingFrameRateReg",
        addr::RESULTING_FRAME_RATE,
        Access::Ro,
    );
    x.enumeration(
        "TriggerSelector",
        "The trigger to configure.",
        false,
        "TriggerSelectorReg",
        &[("FrameStart", 0, "Starts one frame.")],
    );
    x.int_reg("TriggerSelectorReg", addr::TRIGGER_SELECTOR, 4, Access::Rw);
    x.enumeration(
        "TriggerMode",
        "On: each trigger starts one frame.",
        false,
        "TriggerModeReg",
        &[
            ("Off", 0, "Free running."),
            ("On", 1, "One frame per trigger."),
        ],
    );
    x.int_reg("TriggerModeReg", addr::TRIGGER_MODE, 4, Access::Rw);
    x.enumeration(
        "TriggerSource",
        "Where triggers come from.",
        false,
        "TriggerSourceReg",
        &[("Software", 0, "TriggerSoftware.")],
    );
    x.int_reg("TriggerSourceReg", addr::TRIGGER_SOURCE, 4, Access::Rw);
    x.command(
        "TriggerSoftware",
        "Triggers one frame.",
        false,
        "TriggerSoftwareReg",
        1,
    );
    x.int_reg("TriggerSoftwareReg", addr::TRIGGER_SOFTWARE, 4, Access::Wo);
    x.enumeration(
        "ExposureAuto",
        "Continuous: exposure from the sky (99th percentile at 70 % of full well).",
        false,
        "ExposureAutoReg",
        &[
            ("Off", 0, "ExposureTime."),
            ("Continuous", 2, "Every frame."),
        ],
    );
    x.int_reg("ExposureAutoReg", addr::EXPOSURE_AUTO, 4, Access::Rw);
    x.float(
        "ExposureTime",
        "Exposure time (under ExposureAuto: the last frame's).",
        "ExposureTimeReg",
        Some(registers::EXPOSURE_RANGE),
        "us",
    );
    x.float_reg("ExposureTimeReg", addr::EXPOSURE_TIME, Access::Rw);
}

fn analog(x: &mut X) {
    x.float(
        "Gain",
        "Analog gain.",
        "GainReg",
        Some(registers::GAIN_RANGE),
        "dB",
    );
    x.float_reg("GainReg", addr::GAIN, Access::Rw);
    x.enumeration(
        "GainAuto",
        "Automatic gain (not modelled).",
        false,
        "GainAutoReg",
        &[("Off", 0, "Gain.")],
    );
    x.int_reg("GainAutoReg", addr::GAIN_AUTO, 4, Access::Rw);
    x.float(
        "BlackLevel",
        "Black level, DN at 12 bits (an 8-bit format shows it divided by 16).",
        "BlackLevelReg",
        Some(registers::BLACK_LEVEL_RANGE),
        "DN",
    );
    x.float_reg("BlackLevelReg", addr::BLACK_LEVEL, Access::Rw);
}

/// Chunk features: (feature, chunk, byte offset in the chunk, float or integer).
const CHUNK_FEATURES: [(&str, ChunkKind, u32, bool); 14] = [
    ("ChunkExposureTime", ChunkKind::ExposureTime, 0, true),
    ("ChunkGain", ChunkKind::Gain, 0, true),
    ("ChunkTimestamp", ChunkKind::Timestamp, 0, false),
    ("ChunkFrameIndex", ChunkKind::FrameIndex, 0, false),
    ("ChunkAttitudeW", ChunkKind::Attitude, 0, true),
    ("ChunkAttitudeX", ChunkKind::Attitude, 8, true),
    ("ChunkAttitudeY", ChunkKind::Attitude, 16, true),
    ("ChunkAttitudeZ", ChunkKind::Attitude, 24, true),
    ("ChunkSunAzimuth", ChunkKind::SunPosition, 0, true),
    ("ChunkSunElevation", ChunkKind::SunPosition, 8, true),
    ("ChunkOffsetX", ChunkKind::OffsetX, 0, false),
    ("ChunkOffsetY", ChunkKind::OffsetY, 0, false),
    ("ChunkWidth", ChunkKind::Width, 0, false),
    ("ChunkHeight", ChunkKind::Height, 0, false),
];

fn chunks(x: &mut X) {
    x.boolean(
        "ChunkModeActive",
        "Appends the enabled chunks to every image.",
        false,
        true,
        "ChunkModeActiveReg",
    );
    x.int_reg("ChunkModeActiveReg", addr::CHUNK_MODE_ACTIVE, 4, Access::Rw);
    let entries: Vec<(&str, u32, &str)> = ChunkKind::ALL
        .iter()
        .map(|k| (k.name(), *k as u32, "A chunk."))
        .collect();
    x.enumeration(
        "ChunkSelector",
        "The chunk ChunkEnable applies to.",
        false,
        "ChunkSelectorReg",
        &entries,
    );
    x.int_reg("ChunkSelectorReg", addr::CHUNK_SELECTOR, 4, Access::Rw);
    x.boolean(
        "ChunkEnable",
        "Whether the selected chunk is sent.",
        false,
        true,
        "ChunkEnableReg",
    );
    x.register(
        "IntReg",
        "ChunkEnableReg",
        addr::CHUNK_ENABLE,
        4,
        Access::Rw,
        "Device",
        Some("ChunkSelectorReg"),
        &[("Sign", "Unsigned"), ("Endianess", "BigEndian")],
    );
    for k in ChunkKind::ALL {
        x.port(&format!("Chunk{}Port", k.name()), Some(k.id()));
    }
    for (name, k, offset, float) in CHUNK_FEATURES {
        let port = format!("Chunk{}Port", k.name());
        let tail: &[(&str, &str)] = if float {
            &[("Endianess", "BigEndian")]
        } else {
            &[("Sign", "Unsigned"), ("Endianess", "BigEndian")]
        };
        let kind = if float { "FloatReg" } else { "IntReg" };
        x.open(
            kind,
            name,
            !matches!(
                k,
                ChunkKind::FrameIndex | ChunkKind::Attitude | ChunkKind::SunPosition
            ),
        );
        x.head(chunk_tip(name), false);
        x.el(2, "Address", &format!("0x{offset:X}"));
        x.el(2, "Length", if k.data_len() == 4 { "4" } else { "8" });
        x.el(2, "AccessMode", "RO");
        x.el(2, "pPort", &port);
        x.el(2, "Cachable", "NoCache");
        for (a, b) in tail {
            x.el(2, a, b);
        }
        x.close(kind);
    }
    // the pixel format chunk, as an enumeration of the formats
    let entries: Vec<(&str, u32, &str)> = GevPixelFormat::ALL
        .iter()
        .map(|f| (f.name(), f.code(), "A pixel format."))
        .collect();
    x.enumeration(
        "ChunkPixelFormat",
        "Pixel format of the frame.",
        false,
        "ChunkPixelFormatReg",
        &entries,
    );
    x.register(
        "IntReg",
        "ChunkPixelFormatReg",
        0,
        4,
        Access::Ro,
        "ChunkPixelFormatPort",
        None,
        &[("Sign", "Unsigned"), ("Endianess", "BigEndian")],
    );
}

fn chunk_tip(name: &str) -> &'static str {
    match name {
        "ChunkExposureTime" => "Exposure time of the frame, us.",
        "ChunkGain" => "Gain of the frame, dB.",
        "ChunkTimestamp" => "Timestamp of the frame (the leader's), ticks.",
        "ChunkFrameIndex" => "psns's frame index (block id k carries frame k - 1).",
        "ChunkAttitudeW" | "ChunkAttitudeX" | "ChunkAttitudeY" | "ChunkAttitudeZ" => {
            "Attitude quaternion of the camera, camera to ENU (w, x, y, z)."
        }
        "ChunkSunAzimuth" => "Sun azimuth at mid-exposure, degrees from north.",
        "ChunkOffsetX" | "ChunkOffsetY" | "ChunkWidth" | "ChunkHeight" => "Region of the frame.",
        _ => "Sun elevation at mid-exposure, degrees.",
    }
}

fn transport(x: &mut X) {
    x.integer(
        "PayloadSize",
        "Bytes of one block (image and chunks).",
        false,
        false,
        "PayloadSizeReg",
        &[],
        Some("B"),
        None,
    );
    x.int_reg("PayloadSizeReg", addr::PAYLOAD_SIZE, 4, Access::Ro);
    x.integer(
        "GevCurrentIPAddress",
        "Address of the device.",
        true,
        false,
        "CurrentIPReg",
        &[],
        None,
        Some("IPV4Address"),
    );
    x.int_reg("CurrentIPReg", addr::CURRENT_IP, 4, Access::Ro);
    x.integer(
        "GevMACAddress",
        "MAC address.",
        true,
        false,
        "MACReg",
        &[],
        None,
        Some("MACAddress"),
    );
    x.int_reg("MACReg", addr::MAC_HIGH, 8, Access::Ro);
    x.integer(
        "GevStreamChannelCount",
        "Stream channels.",
        true,
        false,
        "StreamChannelsReg",
        &[],
        None,
        None,
    );
    x.int_reg("StreamChannelsReg", addr::STREAM_CHANNELS, 4, Access::Ro);
    x.integer(
        "GevHeartbeatTimeout",
        "Control is released when the controlling application is silent this long.",
        true,
        false,
        "HeartbeatReg",
        &[
            ("Min", registers::HEARTBEAT_MIN_MS.to_string()),
            ("Max", registers::HEARTBEAT_MAX_MS.to_string()),
        ],
        Some("ms"),
        None,
    );
    x.int_reg("HeartbeatReg", addr::HEARTBEAT_TIMEOUT, 4, Access::Rw);
    x.integer(
        "GevTimestampTickFrequency",
        "Timestamp ticks per second.",
        true,
        false,
        "TickFrequencyReg",
        &[],
        Some("Hz"),
        None,
    );
    x.int_reg("TickFrequencyReg", addr::TICK_FREQUENCY_HIGH, 8, Access::Ro);
    x.integer(
        "GevSCPSPacketSize",
        "Stream packet size, bytes with IP and UDP headers.",
        true,
        true,
        "SCPSPacketSizeReg",
        &[
            ("Min", registers::PACKET_SIZE_MIN.to_string()),
            ("Max", registers::PACKET_SIZE_MAX.to_string()),
            ("Inc", "4".into()),
        ],
        Some("B"),
        None,
    );
    x.masked(
        "SCPSPacketSizeReg",
        addr::SCPS,
        Access::Rw,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.command(
        "GevSCPSFireTestPacket",
        "Sends one test packet of the packet size.",
        true,
        "SCPSFireTestPacketReg",
        1,
    );
    x.masked(
        "SCPSFireTestPacketReg",
        addr::SCPS,
        Access::Rw,
        &[("Bit", "0")],
    );
    x.boolean(
        "GevSCPSDoNotFragment",
        "Stream packets must not be fragmented.",
        true,
        false,
        "SCPSDoNotFragmentReg",
    );
    x.masked(
        "SCPSDoNotFragmentReg",
        addr::SCPS,
        Access::Rw,
        &[("Bit", "1")],
    );
    x.integer(
        "GevSCPD",
        "Delay between stream packets, ticks (ns).",
        true,
        false,
        "SCPDReg",
        &[
            ("Min", "0".into()),
            ("Max", registers::PACKET_DELAY_MAX.to_string()),
        ],
        None,
        None,
    );
    x.int_reg("SCPDReg", addr::SCPD, 4, Access::Rw);
    x.integer(
        "GevSCDA",
        "Stream destination address.",
        true,
        false,
        "SCDAReg",
        &[],
        None,
        Some("IPV4Address"),
    );
    x.int_reg("SCDAReg", addr::SCDA, 4, Access::Rw);
    x.integer(
        "GevSCPHostPort",
        "Stream destination port (0: closed).",
        true,
        false,
        "SCPHostPortReg",
        &[],
        None,
        None,
    );
    x.masked(
        "SCPHostPortReg",
        addr::SCP,
        Access::Rw,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.integer(
        "GevSCSP",
        "Source port of the stream packets.",
        true,
        false,
        "SCSPReg",
        &[],
        None,
        None,
    );
    x.masked(
        "SCSPReg",
        addr::SCSP,
        Access::Ro,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.integer(
        "TLParamsLocked",
        "Set by the client while it streams.",
        false,
        false,
        "TLParamsLockedReg",
        &[("Min", "0".into()), ("Max", "1".into())],
        None,
        None,
    );
    x.int_reg("TLParamsLockedReg", addr::TL_PARAMS_LOCKED, 4, Access::Rw);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_pointers_resolve() {
        let xml = genicam_xml();
        let mut names = Vec::new();
        for part in xml.split(" Name=\"").skip(1) {
            names.push(part.split('"').next().unwrap().to_string());
        }
        let mut sorted = names.clone();
        sorted.sort();
        let before = sorted.len();
        sorted.dedup();
        // EnumEntry names repeat across enumerations (Off, On...) and pVariable names are local
        let nodes: std::collections::HashSet<&str> = xml
            .lines()
            .filter(|l| {
                let t = l.trim_start();
                t.starts_with('<') && !t.starts_with("<EnumEntry") && !t.starts_with("<pVariable")
            })
            .filter_map(|l| l.split(" Name=\"").nth(1))
            .map(|p| p.split('"').next().unwrap())
            .collect();
        assert!(before >= nodes.len());
        // every pointer names a node
        for tag in [
            "pValue",
            "pMax",
            "pFeature",
            "pPort",
            "pIsLocked",
            "pIndex Offset=\"4\"",
            "pVariable Name=\"S\"",
        ] {
            let open = format!("<{tag}>");
            for part in xml.split(&open).skip(1) {
                let target = part.split('<').next().unwrap();
                assert!(nodes.contains(target), "{tag} -> {target} is not a node");
            }
        }
    }
}
