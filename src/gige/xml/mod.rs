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

use super::chunk::{ChunkFeature, ChunkField, ChunkKind};
use super::pixel::GevPixelFormat;
use super::registers::{self, addr};
use std::fmt::Write;

mod imaging;
mod transport;

use imaging::*;
use transport::*;

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
    chunk_features.extend(transport::chunk_features());
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
