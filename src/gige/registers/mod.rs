//! The device: its register map (the GigE Vision bootstrap registers and psns's feature
//! registers) and its behaviour as a state machine — privilege, heartbeat, acquisition, triggers —
//! with no sockets and no clock: the caller passes each datagram with its sender and the time.
//!
//! Time is the device clock in nanoseconds since the device started; the timestamp counter
//! ticks at 1 GHz on the same clock.
//!
//! ```
//! use psns::gige::gvcp::{Ack, Command, Request, FLAG_ACK_REQUIRED};
//! use psns::gige::registers::{addr, Device, DeviceInfo};
//! use std::net::{Ipv4Addr, SocketAddrV4};
//! let mut dev = Device::new(DeviceInfo::default(), "<x/>".into());
//! let app = SocketAddrV4::new(Ipv4Addr::LOCALHOST, 50000);
//! let take = Request { flags: FLAG_ACK_REQUIRED, req_id: 1,
//!                      command: Command::WriteReg(vec![(addr::CCP, 2)]) };
//! let out = dev.handle(app, Ipv4Addr::LOCALHOST, &take.encode(), 0);
//! assert_eq!(Ack::decode(&out.reply.unwrap()).unwrap().status, 0);
//! // another application cannot write while the first has control
//! let other = SocketAddrV4::new(Ipv4Addr::LOCALHOST, 50001);
//! let w = Request { flags: FLAG_ACK_REQUIRED, req_id: 1,
//!                   command: Command::WriteReg(vec![(addr::WIDTH, 640)]) };
//! let out = dev.handle(other, Ipv4Addr::LOCALHOST, &w.encode(), 1);
//! assert_eq!(Ack::decode(&out.reply.unwrap()).unwrap().status, 0x8006); // access denied
//! ```

use super::chunk::{self, ChunkKind};
use super::gvcp::{self, decode_command, Ack, Command, DecodeError, Request, Status};
use super::gvsp;
use super::pixel::GevPixelFormat;
use std::net::{Ipv4Addr, SocketAddrV4};

pub mod addr;

mod settings;
pub use settings::*;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Controller {
    app: SocketAddrV4,
    exclusive: bool,
    last_ns: u64,
}

#[derive(Clone, Debug, Default)]
struct Acquisition {
    running: bool,
    remaining: Option<u32>,
    triggers: u32,
    next_due: Option<u64>,
    last_start: Option<u64>,
    /// Mean frames/s over recent consecutive frames (exponential average of 1 / interval).
    achieved: f64,
    /// Consecutive frames that started late against the frame rate.
    late: u32,
}

/// The device.
#[derive(Clone, Debug)]
pub struct Device {
    info: DeviceInfo,
    xml: Vec<u8>,
    xml_len: usize,
    url: String,
    user_id: [u8; 16],
    settings: Settings,
    channel: Channel,
    controller: Option<Controller>,
    heartbeat_ms: u32,
    gvcp_config: u32,
    ts_origin: u64,
    latched: u64,
    acq: Acquisition,
    blocks: u64,
    /// The exposure of the last frame rendered (what ExposureTime reads under ExposureAuto).
    last_exposure_us: Option<f64>,
}

fn put_str(out: &mut [u8], s: &str) {
    let b = s.as_bytes();
    let n = b.len().min(out.len().saturating_sub(1));
    out[..n].copy_from_slice(&b[..n]);
}

fn in_range(v: f64, r: (f64, f64)) -> bool {
    v.is_finite() && v >= r.0 && v <= r.1
}

impl Device {
    /// A device that serves `xml` as its GenICam description.
    pub fn new(info: DeviceInfo, xml: String) -> Self {
        let xml_len = xml.len();
        let mut xml = xml.into_bytes();
        // reads come in 4-byte words: the last word is padded with zeros
        xml.resize(xml_len.div_ceil(4) * 4, 0);
        let url = format!("Local:psns.xml;{:X};{:X}", addr::XML, xml_len);
        let mut user_id = [0u8; 16];
        put_str(&mut user_id, &info.user_id);
        let settings = info.defaults.clone();
        Device {
            xml,
            xml_len,
            url,
            user_id,
            settings,
            channel: Channel {
                host_port: 0,
                dest: Ipv4Addr::UNSPECIFIED,
                packet_size: PACKET_SIZE_DEFAULT,
                do_not_fragment: false,
                packet_delay: 0,
                source_port: 0,
            },
            controller: None,
            heartbeat_ms: HEARTBEAT_DEFAULT_MS,
            gvcp_config: 0,
            ts_origin: 0,
            latched: 0,
            acq: Acquisition::default(),
            blocks: 0,
            last_exposure_us: None,
            info,
        }
    }

    /// The device information.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// The GenICam XML text.
    pub fn xml(&self) -> &[u8] {
        &self.xml[..self.xml_len]
    }

    /// The current settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The stream channel.
    pub fn channel(&self) -> &Channel {
        &self.channel
    }

    /// Sets the source port the stream packets leave from (register SCSP).
    pub fn set_source_port(&mut self, port: u16) {
        self.channel.source_port = port;
    }

    /// The application with control, if any.
    pub fn controller(&self) -> Option<SocketAddrV4> {
        self.controller.map(|c| c.app)
    }

    /// Whether an acquisition is running.
    pub fn acquiring(&self) -> bool {
        self.acq.running
    }

    /// Device timestamp (ticks) at device time `now_ns`.
    pub fn timestamp(&self, now_ns: u64) -> u64 {
        now_ns.saturating_sub(self.ts_origin)
    }

    /// Releases control when the controller has been silent longer than the heartbeat
    /// timeout; returns whether it did.
    pub fn tick(&mut self, now_ns: u64) -> bool {
        match self.controller {
            Some(c) if now_ns.saturating_sub(c.last_ns) > self.heartbeat_ms as u64 * 1_000_000 => {
                self.release();
                true
            }
            _ => false,
        }
    }

    fn release(&mut self) {
        self.controller = None;
        self.stop();
        self.channel.host_port = 0;
        self.channel.dest = Ipv4Addr::UNSPECIFIED;
    }

    fn stop(&mut self) {
        self.acq.running = false;
        self.acq.triggers = 0;
        self.acq.next_due = None;
        self.acq.last_start = None;
        self.acq.late = 0;
    }

    fn start(&mut self) {
        if self.acq.running {
            return;
        }
        self.acq = Acquisition {
            running: true,
            remaining: match self.settings.acquisition_mode {
                AcquisitionMode::Continuous => None,
                AcquisitionMode::SingleFrame => Some(1),
                AcquisitionMode::MultiFrame => Some(self.settings.frame_count.max(1)),
            },
            achieved: self.acq.achieved,
            ..Default::default()
        };
    }

    /// Whether a frame should start at `now_ns`, and if so which (the device counts it as
    /// started). Software triggers, the frame rate and the acquisition mode decide.
    pub fn poll_frame(&mut self, now_ns: u64) -> Poll {
        if !self.acq.running {
            return Poll::Idle;
        }
        if self.settings.trigger_mode {
            if self.acq.triggers == 0 {
                return Poll::Idle;
            }
            self.acq.triggers -= 1;
        } else if self.settings.frame_rate_enable {
            let period = (1e9 / self.settings.frame_rate) as u64;
            match self.acq.next_due {
                Some(due) if now_ns < due => return Poll::At(due),
                Some(due) => {
                    let late = now_ns - due;
                    self.acq.late = if late > period / 10 {
                        self.acq.late + 1
                    } else {
                        0
                    };
                    // a device that fell behind does not burst to catch up
                    self.acq.next_due = Some(if late > period {
                        now_ns + period
                    } else {
                        due + period
                    });
                }
                None => self.acq.next_due = Some(now_ns + period),
            }
        }
        if let Some(last) = self.acq.last_start {
            let dt = now_ns.saturating_sub(last).max(1) as f64 * 1e-9;
            let fps = 1.0 / dt;
            self.acq.achieved = if self.acq.achieved > 0.0 {
                0.8 * self.acq.achieved + 0.2 * fps
            } else {
                fps
            };
        }
        self.acq.last_start = Some(now_ns);
        if let Some(n) = &mut self.acq.remaining {
            *n -= 1;
            if *n == 0 {
                self.acq.running = false;
            }
        }
        self.blocks += 1;
        Poll::Frame(Box::new(FrameOrder {
            k: self.blocks,
            block_id: gvsp::block_id_of(self.blocks),
            frame_index: self.blocks - 1,
            timestamp: self.timestamp(now_ns),
            settings: self.settings.clone(),
            channel: self.channel,
        }))
    }

    /// The front-end rendered a frame with this exposure (what ExposureTime reads while
    /// ExposureAuto is Continuous).
    pub fn frame_rendered(&mut self, exposure_us: f64) {
        self.last_exposure_us = Some(exposure_us);
    }

    /// The frame rate AcquisitionFrameRate reads: the one asked for, or, when the device cannot
    /// keep up with it, the rate it delivers.
    pub fn frame_rate_reading(&self) -> f64 {
        if self.settings.frame_rate_enable && self.acq.late >= 3 && self.acq.achieved > 0.0 {
            self.acq.achieved.min(self.settings.frame_rate)
        } else {
            self.settings.frame_rate
        }
    }

    /// AcquisitionResultingFrameRate: the rate of recent frames while acquiring, else the rate
    /// asked for (0 when free running and idle).
    pub fn resulting_frame_rate(&self) -> f64 {
        if self.acq.running && self.acq.achieved > 0.0 {
            self.acq.achieved
        } else if self.settings.frame_rate_enable {
            self.settings.frame_rate
        } else {
            0.0
        }
    }

    /// Handles one datagram from `from` received at device time `now_ns`; `local_ip` is the
    /// device's address as the sender reaches it (reported in discovery and CurrentIP).
    /// Anything malformed is answered with a status or dropped; nothing panics.
    pub fn handle(
        &mut self,
        from: SocketAddrV4,
        local_ip: Ipv4Addr,
        datagram: &[u8],
        now_ns: u64,
    ) -> Outcome {
        let req = match decode_command(datagram) {
            Ok(r) => r,
            Err(DecodeError::NotGvcp) => return Outcome::default(),
            Err(DecodeError::Reject {
                command,
                req_id,
                status,
            }) => {
                let ack_required = datagram
                    .get(1)
                    .is_some_and(|f| f & gvcp::FLAG_ACK_REQUIRED != 0);
                return Outcome {
                    reply: ack_required
                        .then(|| Ack::new(command, req_id, status, Vec::new()).encode()),
                    actions: Vec::new(),
                };
            }
        };
        if let Some(c) = &mut self.controller {
            if c.app == from {
                c.last_ns = now_ns;
            }
        }
        let Request {
            flags,
            req_id,
            command,
        } = req;
        let code = command.code();
        let mut actions = Vec::new();
        let (status, body) = match command {
            Command::Discovery => {
                // discovery answers whoever asks, even while another application has exclusive
                // access
                let mut b = Vec::with_capacity(gvcp::DISCOVERY_ACK_LEN);
                for a in (0..gvcp::DISCOVERY_ACK_LEN as u32).step_by(4) {
                    b.extend(
                        self.word(from, local_ip, a, now_ns)
                            .unwrap_or(0)
                            .to_be_bytes(),
                    );
                }
                (Status::Success, b)
            }
            Command::Bye => {
                if self.controller.is_some_and(|c| c.app == from) {
                    self.release();
                }
                (Status::Success, Vec::new())
            }
            Command::PacketResend {
                block_id,
                first,
                last,
                ..
            } => {
                actions.push(Action::Resend {
                    block_id,
                    first,
                    last,
                });
                return Outcome {
                    reply: None,
                    actions,
                };
            }
            Command::ReadReg(addrs) => {
                let mut body = Vec::with_capacity(4 * addrs.len());
                let mut status = Status::Success;
                for a in addrs {
                    match self.read_register(from, local_ip, a, now_ns) {
                        Ok(v) => body.extend(v.to_be_bytes()),
                        Err(s) => {
                            status = s;
                            break;
                        }
                    }
                }
                (status, body)
            }
            Command::WriteReg(pairs) => {
                let mut n = 0u16;
                let mut status = Status::Success;
                for (a, v) in pairs {
                    match self.write_register(from, a, v, now_ns, &mut actions) {
                        Ok(()) => n += 1,
                        Err(s) => {
                            status = s;
                            break;
                        }
                    }
                }
                (status, gvcp::index_body(n))
            }
            Command::ReadMem { address, count } => {
                let count = count as usize;
                if !address.is_multiple_of(4) || !count.is_multiple_of(4) {
                    (Status::BadAlignment, Vec::new())
                } else if count == 0 || count > gvcp::MEM_MAX {
                    (Status::InvalidParameter, Vec::new())
                } else {
                    let mut data = vec![0u8; count];
                    match self.read_bytes(from, local_ip, address, &mut data, now_ns) {
                        Ok(()) => {
                            let mut body = address.to_be_bytes().to_vec();
                            body.extend(data);
                            (Status::Success, body)
                        }
                        Err(s) => (s, Vec::new()),
                    }
                }
            }
            Command::WriteMem { address, data } => {
                if !address.is_multiple_of(4) || !data.len().is_multiple_of(4) {
                    (Status::BadAlignment, gvcp::index_body(0))
                } else {
                    let (n, status) = self.write_bytes(from, address, &data, now_ns, &mut actions);
                    (status, gvcp::index_body(n as u16))
                }
            }
        };
        let reply = (flags & gvcp::FLAG_ACK_REQUIRED != 0 || code == gvcp::code::DISCOVERY)
            .then(|| Ack::new(code, req_id, status, body).encode());
        Outcome { reply, actions }
    }

    fn may_read(&self, from: SocketAddrV4) -> bool {
        match self.controller {
            Some(c) => !c.exclusive || c.app == from,
            None => true,
        }
    }

    fn read_bytes(
        &self,
        from: SocketAddrV4,
        local_ip: Ipv4Addr,
        address: u32,
        out: &mut [u8],
        now_ns: u64,
    ) -> Result<(), Status> {
        for (i, w) in out.chunks_mut(4).enumerate() {
            let v = self.read_register(from, local_ip, address + 4 * i as u32, now_ns)?;
            w.copy_from_slice(&v.to_be_bytes()[..w.len()]);
        }
        Ok(())
    }

    /// Reads the 32-bit register at `a` (a multiple of 4) as `from` sees it.
    pub fn read_register(
        &self,
        from: SocketAddrV4,
        local_ip: Ipv4Addr,
        a: u32,
        now_ns: u64,
    ) -> Result<u32, Status> {
        if !a.is_multiple_of(4) {
            return Err(Status::BadAlignment);
        }
        if !self.may_read(from) {
            return Err(Status::AccessDenied);
        }
        self.word(from, local_ip, a, now_ns)
    }

    /// The register at `a` (a multiple of 4) as `from` sees it, whatever `from` may access.
    fn word(
        &self,
        from: SocketAddrV4,
        local_ip: Ipv4Addr,
        a: u32,
        now_ns: u64,
    ) -> Result<u32, Status> {
        let s = &self.settings;
        let f64_word = |v: f64, at: u32| -> u32 {
            let b = v.to_bits();
            if a == at {
                (b >> 32) as u32
            } else {
                b as u32
            }
        };
        let text = |base: u32, len: usize, s: &str| -> u32 {
            let mut buf = vec![0u8; len];
            put_str(&mut buf, s);
            let o = (a - base) as usize;
            u32::from_be_bytes(buf[o..o + 4].try_into().expect("4 bytes"))
        };
        let _ = now_ns;
        use addr::*;
        Ok(match a {
            VERSION => 0x0002_0000,
            // big-endian registers, UTF-8 strings
            DEVICE_MODE => 0x8000_0001,
            MAC_HIGH => u16::from_be_bytes([self.info.mac[0], self.info.mac[1]]) as u32,
            MAC_LOW => u32::from_be_bytes(self.info.mac[2..6].try_into().expect("4 bytes")),
            SUPPORTED_IP_CONFIG => 0x0000_0007,
            CURRENT_IP_CONFIG => 0x0000_0004,
            CURRENT_IP => u32::from(local_ip),
            SUBNET_MASK => {
                if local_ip.is_loopback() {
                    0xFF00_0000
                } else {
                    0xFFFF_FF00
                }
            }
            GATEWAY => 0,
            x if (MANUFACTURER..MANUFACTURER + 32).contains(&x) => {
                text(MANUFACTURER, 32, &self.info.vendor)
            }
            x if (MODEL..MODEL + 32).contains(&x) => text(MODEL, 32, &self.info.model),
            x if (DEVICE_VERSION..DEVICE_VERSION + 32).contains(&x) => {
                text(DEVICE_VERSION, 32, &self.info.version)
            }
            x if (MANUFACTURER_INFO..MANUFACTURER_INFO + 48).contains(&x) => {
                text(MANUFACTURER_INFO, 48, &self.info.manufacturer_info)
            }
            x if (SERIAL..SERIAL + 16).contains(&x) => text(SERIAL, 16, &self.info.serial),
            x if (USER_NAME..USER_NAME + 16).contains(&x) => {
                let o = (x - USER_NAME) as usize;
                u32::from_be_bytes(self.user_id[o..o + 4].try_into().expect("4 bytes"))
            }
            x if (0xF8..XML_URL_0).contains(&x) => 0,
            x if (XML_URL_0..XML_URL_0 + 512).contains(&x) => text(XML_URL_0, 512, &self.url),
            x if (XML_URL_1..XML_URL_1 + 512).contains(&x) => 0,
            NET_INTERFACES => 1,
            PERSISTENT_IP | PERSISTENT_MASK | PERSISTENT_GATEWAY => 0,
            MESSAGE_CHANNELS => 0,
            STREAM_CHANNELS => 1,
            // user-defined name, serial number, packet resend, WRITEMEM, concatenation
            GVCP_CAPABILITY => (1 << 31) | (1 << 30) | (1 << 2) | (1 << 1) | 1,
            HEARTBEAT_TIMEOUT => self.heartbeat_ms,
            TICK_FREQUENCY_HIGH => (TICK_FREQUENCY >> 32) as u32,
            TICK_FREQUENCY_LOW => TICK_FREQUENCY as u32,
            TIMESTAMP_CONTROL => 0,
            TIMESTAMP_LATCH_HIGH => (self.latched >> 32) as u32,
            TIMESTAMP_LATCH_LOW => self.latched as u32,
            GVCP_CONFIG => self.gvcp_config,
            CCP => match self.controller {
                Some(c) if c.app == from => {
                    CCP_CONTROL | if c.exclusive { CCP_EXCLUSIVE } else { 0 }
                }
                _ => 0,
            },
            SCP => self.channel.host_port as u32,
            SCPS => {
                self.channel.packet_size
                    | if self.channel.do_not_fragment {
                        1 << 30
                    } else {
                        0
                    }
            }
            SCPD => self.channel.packet_delay,
            SCDA => u32::from(self.channel.dest),
            SCSP => self.channel.source_port as u32,
            SCC | SCCFG => 0,
            SENSOR_WIDTH => self.info.sensor_width,
            SENSOR_HEIGHT => self.info.sensor_height,
            WIDTH => s.width,
            HEIGHT => s.height,
            OFFSET_X => s.offset_x,
            OFFSET_Y => s.offset_y,
            PIXEL_FORMAT => s.pixel_format.code(),
            PAYLOAD_SIZE => s.payload_size().min(u32::MAX as usize) as u32,
            ACQUISITION_MODE => s.acquisition_mode as u32,
            ACQUISITION_FRAME_COUNT => s.frame_count,
            ACQUISITION_START | ACQUISITION_STOP | TRIGGER_SOFTWARE => 0,
            FRAME_RATE_ENABLE => s.frame_rate_enable as u32,
            TRIGGER_SELECTOR => 0,
            TRIGGER_MODE => s.trigger_mode as u32,
            TRIGGER_SOURCE => 0,
            EXPOSURE_AUTO => {
                if s.exposure_auto {
                    2
                } else {
                    0
                }
            }
            GAIN_AUTO => 0,
            THROUGHPUT_LIMIT_MODE => s.throughput_limit_on as u32,
            CHUNK_MODE_ACTIVE => s.chunk_mode as u32,
            CHUNK_SELECTOR => s.chunk_selector,
            TL_PARAMS_LOCKED => s.tl_locked as u32,
            x if x == EXPOSURE_TIME || x == EXPOSURE_TIME + 4 => {
                let e = match (s.exposure_auto, self.last_exposure_us) {
                    (true, Some(e)) => e,
                    _ => s.exposure_us,
                };
                f64_word(e, EXPOSURE_TIME)
            }
            x if x == GAIN || x == GAIN + 4 => f64_word(s.gain_db, GAIN),
            x if x == BLACK_LEVEL || x == BLACK_LEVEL + 4 => f64_word(s.black_level, BLACK_LEVEL),
            x if x == FRAME_RATE || x == FRAME_RATE + 4 => {
                f64_word(self.frame_rate_reading(), FRAME_RATE)
            }
            x if x == RESULTING_FRAME_RATE || x == RESULTING_FRAME_RATE + 4 => {
                f64_word(self.resulting_frame_rate(), RESULTING_FRAME_RATE)
            }
            THROUGHPUT_LIMIT => (s.throughput_limit >> 32) as u32,
            x if x == THROUGHPUT_LIMIT + 4 => s.throughput_limit as u32,
            x if x == DEVICE_TEMPERATURE || x == DEVICE_TEMPERATURE + 4 => {
                f64_word(self.info.temperature_c, DEVICE_TEMPERATURE)
            }
            x if (CHUNK_ENABLE..CHUNK_ENABLE + 4 * ChunkKind::ALL.len() as u32).contains(&x) => {
                (s.chunk_mask >> ((x - CHUNK_ENABLE) / 4)) & 1
            }
            x if (XML..XML + self.xml.len() as u32).contains(&x) => {
                let o = (x - XML) as usize;
                u32::from_be_bytes(self.xml[o..o + 4].try_into().expect("4 bytes"))
            }
            _ => return Err(Status::InvalidAddress),
        })
    }

    fn write_bytes(
        &mut self,
        from: SocketAddrV4,
        address: u32,
        data: &[u8],
        now_ns: u64,
        actions: &mut Vec<Action>,
    ) -> (usize, Status) {
        let mut i = 0;
        while i < data.len() {
            let a = address.wrapping_add(i as u32);
            // an 8-byte register written whole is one write (a double is never half updated)
            let r = if is_wide(a) && data.len() - i >= 8 {
                let v = u64::from_be_bytes(data[i..i + 8].try_into().expect("8 bytes"));
                self.write_wide(from, a, v).map(|()| 8)
            } else {
                let v = u32::from_be_bytes(data[i..i + 4].try_into().expect("4 bytes"));
                self.write_register(from, a, v, now_ns, actions).map(|()| 4)
            };
            match r {
                Ok(n) => i += n,
                Err(s) => return (i, s),
            }
        }
        (i, Status::Success)
    }

    fn check_writer(&self, from: SocketAddrV4) -> Result<(), Status> {
        match self.controller {
            Some(c) if c.app == from => Ok(()),
            _ => Err(Status::AccessDenied),
        }
    }

    fn unlocked(&self) -> Result<(), Status> {
        if self.acq.running {
            Err(Status::Busy)
        } else {
            Ok(())
        }
    }

    fn write_wide(&mut self, from: SocketAddrV4, a: u32, v: u64) -> Result<(), Status> {
        self.check_writer(from)?;
        use addr::*;
        let f = f64::from_bits(v);
        let s = &mut self.settings;
        match a {
            EXPOSURE_TIME if in_range(f, EXPOSURE_RANGE) => s.exposure_us = f,
            GAIN if in_range(f, GAIN_RANGE) => s.gain_db = f,
            BLACK_LEVEL if in_range(f, BLACK_LEVEL_RANGE) => s.black_level = f,
            FRAME_RATE if in_range(f, FRAME_RATE_RANGE) => {
                s.frame_rate = f;
                self.acq.late = 0;
            }
            THROUGHPUT_LIMIT if (THROUGHPUT_RANGE.0..=THROUGHPUT_RANGE.1).contains(&v) => {
                s.throughput_limit = v
            }
            EXPOSURE_TIME | GAIN | BLACK_LEVEL | FRAME_RATE | THROUGHPUT_LIMIT => {
                return Err(Status::InvalidParameter)
            }
            RESULTING_FRAME_RATE | DEVICE_TEMPERATURE | TIMESTAMP_LATCH_HIGH => {
                return Err(Status::WriteProtect)
            }
            _ => return Err(Status::InvalidAddress),
        }
        Ok(())
    }

    /// Writes the 32-bit register at `a` as `from`; any work for the front-end is pushed to
    /// `actions`.
    pub fn write_register(
        &mut self,
        from: SocketAddrV4,
        a: u32,
        v: u32,
        now_ns: u64,
        actions: &mut Vec<Action>,
    ) -> Result<(), Status> {
        use addr::*;
        if !a.is_multiple_of(4) {
            return Err(Status::BadAlignment);
        }
        if a == CCP {
            return self.write_ccp(from, v, now_ns);
        }
        // a register that does not exist is an address error whoever asks
        self.word(from, Ipv4Addr::UNSPECIFIED, a, now_ns)?;
        self.check_writer(from)?;
        let sensor_w = self.info.sensor_width;
        let sensor_h = self.info.sensor_height;
        let bad = Err(Status::InvalidParameter);
        // the halves of an 8-byte register: write the whole value with this half replaced
        if let Some(base) = wide_base(a) {
            let hi = self.word(from, Ipv4Addr::UNSPECIFIED, base, now_ns)?;
            let lo = self.word(from, Ipv4Addr::UNSPECIFIED, base + 4, now_ns)?;
            let (hi, lo) = if a == base { (v, lo) } else { (hi, v) };
            return self.write_wide(from, base, ((hi as u64) << 32) | lo as u64);
        }
        let s = &mut self.settings;
        match a {
            x if (USER_NAME..USER_NAME + 16).contains(&x) => {
                let o = (x - USER_NAME) as usize;
                self.user_id[o..o + 4].copy_from_slice(&v.to_be_bytes());
                self.user_id[15] = 0;
            }
            HEARTBEAT_TIMEOUT => {
                if !(HEARTBEAT_MIN_MS..=HEARTBEAT_MAX_MS).contains(&v) {
                    return bad;
                }
                self.heartbeat_ms = v;
            }
            GVCP_CONFIG => self.gvcp_config = v,
            TIMESTAMP_CONTROL => {
                if v & 1 != 0 {
                    self.ts_origin = now_ns;
                }
                if v & 2 != 0 {
                    self.latched = self.timestamp(now_ns);
                }
            }
            SCP => self.channel.host_port = (v & 0xFFFF) as u16,
            SCPS => {
                let size = (v & 0xFFFF) & !3;
                if !(PACKET_SIZE_MIN..=PACKET_SIZE_MAX).contains(&size) {
                    return bad;
                }
                if size != self.channel.packet_size {
                    self.unlocked()?;
                }
                self.channel.packet_size = size;
                self.channel.do_not_fragment = v & (1 << 30) != 0;
                if v & (1 << 31) != 0 {
                    if let Some(dest) = self.channel.destination() {
                        actions.push(Action::FireTestPacket {
                            dest,
                            packet_size: size,
                            do_not_fragment: self.channel.do_not_fragment,
                        });
                    }
                }
            }
            SCPD => {
                if v > PACKET_DELAY_MAX {
                    return bad;
                }
                self.channel.packet_delay = v;
            }
            SCDA => self.channel.dest = Ipv4Addr::from(v),
            WIDTH | HEIGHT | OFFSET_X | OFFSET_Y => {
                let (size, off, full) = match a {
                    WIDTH | OFFSET_X => (&mut s.width, &mut s.offset_x, sensor_w),
                    _ => (&mut s.height, &mut s.offset_y, sensor_h),
                };
                let (new_size, new_off) = if a == WIDTH || a == HEIGHT {
                    (v, *off)
                } else {
                    (*size, v)
                };
                if !v.is_multiple_of(2)
                    || new_size < 2
                    || new_size.checked_add(new_off).is_none_or(|e| e > full)
                {
                    return bad;
                }
                if (new_size, new_off) != (*size, *off) {
                    if self.acq.running {
                        return Err(Status::Busy);
                    }
                    *size = new_size;
                    *off = new_off;
                }
            }
            PIXEL_FORMAT => {
                let f = GevPixelFormat::from_code(v).ok_or(Status::InvalidParameter)?;
                if f != s.pixel_format {
                    if self.acq.running {
                        return Err(Status::Busy);
                    }
                    s.pixel_format = f;
                }
            }
            ACQUISITION_MODE => {
                s.acquisition_mode = match v {
                    0 => AcquisitionMode::Continuous,
                    1 => AcquisitionMode::SingleFrame,
                    2 => AcquisitionMode::MultiFrame,
                    _ => return bad,
                }
            }
            ACQUISITION_FRAME_COUNT => {
                if !(1..=65535).contains(&v) {
                    return bad;
                }
                s.frame_count = v;
            }
            ACQUISITION_START => {
                if v != 0 {
                    self.start();
                }
            }
            ACQUISITION_STOP => {
                if v != 0 {
                    self.stop();
                }
            }
            FRAME_RATE_ENABLE if v <= 1 => {
                s.frame_rate_enable = v == 1;
                self.acq.next_due = None;
                self.acq.late = 0;
            }
            TRIGGER_SELECTOR | TRIGGER_SOURCE if v == 0 => {}
            TRIGGER_MODE if v <= 1 => s.trigger_mode = v == 1,
            TRIGGER_SOFTWARE => {
                if v != 0 && self.acq.running && s.trigger_mode {
                    self.acq.triggers = (self.acq.triggers + 1).min(MAX_PENDING_TRIGGERS);
                }
            }
            EXPOSURE_AUTO if v == 0 || v == 2 => s.exposure_auto = v == 2,
            GAIN_AUTO if v == 0 => {}
            THROUGHPUT_LIMIT_MODE if v <= 1 => s.throughput_limit_on = v == 1,
            CHUNK_MODE_ACTIVE if v <= 1 => {
                if s.chunk_mode != (v == 1) {
                    if self.acq.running {
                        return Err(Status::Busy);
                    }
                    s.chunk_mode = v == 1;
                }
            }
            CHUNK_SELECTOR => {
                if v as usize >= ChunkKind::ALL.len() {
                    return bad;
                }
                s.chunk_selector = v;
            }
            TL_PARAMS_LOCKED if v <= 1 => s.tl_locked = v == 1,
            x if (CHUNK_ENABLE..CHUNK_ENABLE + 4 * ChunkKind::ALL.len() as u32).contains(&x) => {
                if v > 1 {
                    return bad;
                }
                let bit = 1 << ((x - CHUNK_ENABLE) / 4);
                let mask = if v == 1 {
                    s.chunk_mask | bit
                } else {
                    s.chunk_mask & !bit
                };
                if mask != s.chunk_mask {
                    if self.acq.running && s.chunk_mode {
                        return Err(Status::Busy);
                    }
                    s.chunk_mask = mask;
                }
            }
            FRAME_RATE_ENABLE
            | TRIGGER_SELECTOR
            | TRIGGER_SOURCE
            | TRIGGER_MODE
            | EXPOSURE_AUTO
            | GAIN_AUTO
            | THROUGHPUT_LIMIT_MODE
            | CHUNK_MODE_ACTIVE
            | TL_PARAMS_LOCKED => return bad,
            _ => return Err(Status::WriteProtect),
        }
        Ok(())
    }

    fn write_ccp(&mut self, from: SocketAddrV4, v: u32, now_ns: u64) -> Result<(), Status> {
        let bits = v & (CCP_CONTROL | CCP_EXCLUSIVE);
        match self.controller {
            Some(c) if c.app != from => Err(Status::AccessDenied),
            Some(_) if bits == 0 => {
                self.release();
                Ok(())
            }
            Some(c) => {
                self.controller = Some(Controller {
                    exclusive: bits & CCP_EXCLUSIVE != 0,
                    last_ns: now_ns,
                    ..c
                });
                Ok(())
            }
            None => {
                if bits != 0 {
                    self.controller = Some(Controller {
                        app: from,
                        exclusive: bits & CCP_EXCLUSIVE != 0,
                        last_ns: now_ns,
                    });
                }
                Ok(())
            }
        }
    }
}

/// The registers that hold 8 bytes (doubles and 64-bit integers).
const WIDE: [u32; 8] = [
    addr::EXPOSURE_TIME,
    addr::GAIN,
    addr::BLACK_LEVEL,
    addr::FRAME_RATE,
    addr::RESULTING_FRAME_RATE,
    addr::THROUGHPUT_LIMIT,
    addr::DEVICE_TEMPERATURE,
    addr::TIMESTAMP_LATCH_HIGH,
];

fn is_wide(a: u32) -> bool {
    WIDE.contains(&a)
}

fn wide_base(a: u32) -> Option<u32> {
    WIDE.iter()
        .copied()
        .find(|&b| b != addr::TIMESTAMP_LATCH_HIGH && (a == b || a == b + 4))
}
