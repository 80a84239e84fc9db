//! The GigE Vision protocol module without sockets: property tests of the packet codecs
//! (round trips; arbitrary bytes never panic) and the device state machine (privilege,
//! heartbeat, register errors, acquisition, triggers, settings that persist).

use proptest::prelude::*;
use psns::gige::chunk::{self, ChunkKind, ChunkValues};
use psns::gige::gvcp::{self, decode_command, Ack, Command, Request, Status};
use psns::gige::gvsp::{self, BlockLayout, Content, Leader};
use psns::gige::pixel::GevPixelFormat;
use psns::gige::registers::{addr, Action, Device, DeviceInfo, Poll};
use std::net::{Ipv4Addr, SocketAddrV4};

fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::Discovery),
        Just(Command::Bye),
        prop::collection::vec(any::<u32>(), 1..=gvcp::READREG_MAX).prop_map(Command::ReadReg),
        prop::collection::vec(any::<(u32, u32)>(), 1..=gvcp::WRITEREG_MAX)
            .prop_map(Command::WriteReg),
        (any::<u32>(), any::<u16>())
            .prop_map(|(address, count)| Command::ReadMem { address, count }),
        (
            any::<u32>(),
            prop::collection::vec(any::<u8>(), 4..=gvcp::MEM_MAX)
        )
            .prop_map(|(address, data)| Command::WriteMem { address, data }),
        (
            any::<u16>(),
            any::<u16>(),
            0u32..0x0100_0000,
            0u32..0x0100_0000
        )
            .prop_map(|(channel, b, first, last)| Command::PacketResend {
                channel,
                block_id: b as u64,
                first,
                last,
                extended: false
            }),
        (any::<u16>(), any::<u64>(), any::<u32>(), any::<u32>()).prop_map(
            |(channel, block_id, first, last)| Command::PacketResend {
                channel,
                block_id,
                first,
                last,
                extended: true
            }
        ),
    ]
}

fn app(port: u16) -> SocketAddrV4 {
    SocketAddrV4::new(Ipv4Addr::LOCALHOST, port)
}

fn ack_of(out: &psns::gige::registers::Outcome) -> Ack {
    Ack::decode(out.reply.as_ref().expect("a reply")).expect("a well-formed acknowledge")
}

fn send(dev: &mut Device, from: SocketAddrV4, cmd: Command, now: u64) -> Ack {
    let r = Request {
        flags: gvcp::FLAG_ACK_REQUIRED,
        req_id: 0x55,
        command: cmd,
    };
    ack_of(&dev.handle(from, Ipv4Addr::LOCALHOST, &r.encode(), now))
}

fn write(dev: &mut Device, from: SocketAddrV4, a: u32, v: u32, now: u64) -> u16 {
    send(dev, from, Command::WriteReg(vec![(a, v)]), now).status
}

fn read(dev: &mut Device, from: SocketAddrV4, a: u32, now: u64) -> Result<u32, u16> {
    let ack = send(dev, from, Command::ReadReg(vec![a]), now);
    if ack.status == 0 {
        Ok(u32::from_be_bytes(ack.body[..4].try_into().unwrap()))
    } else {
        Err(ack.status)
    }
}

fn write_f64(dev: &mut Device, from: SocketAddrV4, a: u32, v: f64, now: u64) -> u16 {
    let data = v.to_be_bytes().to_vec();
    send(dev, from, Command::WriteMem { address: a, data }, now).status
}

fn read_f64(dev: &mut Device, from: SocketAddrV4, a: u32, now: u64) -> f64 {
    let ack = send(
        dev,
        from,
        Command::ReadMem {
            address: a,
            count: 8,
        },
        now,
    );
    assert_eq!(ack.status, 0);
    f64::from_be_bytes(ack.body[4..12].try_into().unwrap())
}

fn device() -> Device {
    Device::new(DeviceInfo::default(), psns::gige::xml::genicam_xml())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn gvcp_commands_round_trip(cmd in command(), flags in any::<u8>(), req_id in any::<u16>()) {
        // the extended-id flag belongs to PACKETRESEND's form
        let flags = match &cmd {
            Command::PacketResend { extended, .. } => {
                if *extended { flags | gvcp::FLAG_EXTENDED_IDS } else { flags & !gvcp::FLAG_EXTENDED_IDS }
            }
            _ => flags,
        };
        let r = Request { flags, req_id, command: cmd };
        prop_assert_eq!(decode_command(&r.encode()), Ok(r));
    }

    #[test]
    fn gvcp_acks_round_trip(status in any::<u16>(), answer in any::<u16>(), ack_id in any::<u16>(),
                            body in prop::collection::vec(any::<u8>(), 0..600)) {
        let a = Ack { status, answer, ack_id, body };
        prop_assert_eq!(Ack::decode(&a.encode()), Some(a));
    }

    #[test]
    fn gvcp_decoders_take_any_bytes(b in prop::collection::vec(any::<u8>(), 0..700)) {
        let _ = decode_command(&b);
        let _ = Ack::decode(&b);
        // a header with a consistent length is decoded or rejected with a status, never dropped
        let mut c = b.clone();
        if c.len() >= 8 {
            c[0] = gvcp::KEY;
            let n = (c.len() - 8) as u16;
            c[4..6].copy_from_slice(&n.to_be_bytes());
            prop_assert_ne!(decode_command(&c), Err(gvcp::DecodeError::NotGvcp));
        }
    }

    #[test]
    fn gvsp_packets_round_trip(
        block_id in 1u16.., timestamp in any::<u64>(), pf in 0usize..8,
        w in any::<u32>(), h in any::<u32>(), ox in any::<u32>(), oy in any::<u32>(),
        chunked in any::<bool>(),
        payload in prop::collection::vec(any::<u8>(), 1..5000), packet_size in 37u32..2000,
    ) {
        let l = Leader {
            payload_type: if chunked { gvsp::PAYLOAD_IMAGE_CHUNK } else { gvsp::PAYLOAD_IMAGE },
            timestamp,
            pixel_format: GevPixelFormat::ALL[pf].code(),
            width: w, height: h, offset_x: ox, offset_y: oy,
        };
        let mut out = Vec::new();
        gvsp::leader_packet(block_id, &l, &mut out);
        let p = gvsp::decode(&out).unwrap();
        prop_assert_eq!((p.block_id, p.packet_id, p.content), (block_id, 0, Content::Leader(l)));
        // data packets rebuild the payload, split anywhere between two parts
        let layout = BlockLayout::new(payload.len(), packet_size);
        let cut = (timestamp as usize) % payload.len();
        let mut got = Vec::new();
        for id in 1..=layout.data_packets() {
            layout.data_packet(block_id, id, &[&payload[..cut], &payload[cut..]], &mut out);
            prop_assert!(out.len() <= packet_size as usize - gvsp::IP_UDP_LEN);
            let p = gvsp::decode(&out).unwrap();
            prop_assert_eq!((p.block_id, p.packet_id), (block_id, id));
            match p.content {
                Content::Payload(d) => got.extend_from_slice(d),
                c => prop_assert!(false, "{:?}", c),
            }
        }
        prop_assert_eq!(&got, &payload);
        gvsp::trailer_packet(block_id, layout.trailer_id(), l.payload_type, h, &mut out);
        let p = gvsp::decode(&out).unwrap();
        prop_assert_eq!(p.packet_id, layout.trailer_id());
        prop_assert_eq!(p.content, Content::Trailer { payload_type: l.payload_type, height: h });
    }

    #[test]
    fn gvsp_decoder_takes_any_bytes(b in prop::collection::vec(any::<u8>(), 0..200)) {
        let _ = gvsp::decode(&b);
    }

    #[test]
    fn chunks_round_trip(mask in 0u32..=chunk::ALL_MASK, image in prop::collection::vec(any::<u8>(), 0..300),
                         e in -1e9f64..1e9, g in -1e3f64..1e3, ts in any::<u64>(), k in any::<u64>(),
                         q in prop::array::uniform4(-1f64..1.0), az in 0f64..360.0, el in -90f64..90.0) {
        let v = ChunkValues { exposure_us: e, gain_db: g, timestamp: ts, frame_index: k,
                              attitude_wxyz: q, sun_azimuth_deg: az, sun_elevation_deg: el,
                              region: [k as u32, ts as u32, e as u32, g as u32],
                              pixel_format: GevPixelFormat::ALL[(k % 8) as usize].code() };
        let mut tail = Vec::new();
        chunk::append(&mut tail, image.len(), mask, &v);
        prop_assert_eq!(tail.len(), chunk::tail_len(mask));
        let block = [&image[..], &tail].concat();
        let found = chunk::chunks(&block).unwrap();
        prop_assert_eq!(found.last().unwrap(), &(chunk::IMAGE_CHUNK_ID, &image[..]));
        let ids: Vec<u32> = found.iter().rev().skip(1).map(|c| c.0).collect();
        let want: Vec<u32> = ChunkKind::ALL.iter().filter(|k| mask & (1 << **k as u32) != 0).map(|k| k.id()).collect();
        prop_assert_eq!(ids, want);
    }

    #[test]
    fn chunk_walk_takes_any_bytes(b in prop::collection::vec(any::<u8>(), 0..200)) {
        let _ = chunk::chunks(&b);
    }

    /// Any datagram from anyone, at any time: the device answers (with a well-formed
    /// acknowledge whose id is the request's) or stays silent, and never panics.
    #[test]
    fn device_takes_any_datagram(
        datagrams in prop::collection::vec((prop::collection::vec(any::<u8>(), 0..64), 0u16..3, any::<u32>()), 1..40),
        cmds in prop::collection::vec((command(), 0u16..3), 0..40),
    ) {
        let mut dev = device();
        let mut now = 0u64;
        for (b, who, dt) in datagrams {
            now += dt as u64;
            let mut b = b;
            if b.len() >= 8 && who == 0 {
                b[0] = gvcp::KEY; // most of them GVCP-shaped
            }
            let out = dev.handle(app(50000 + who), Ipv4Addr::LOCALHOST, &b, now);
            if let Some(r) = out.reply {
                let a = Ack::decode(&r).expect("well-formed acknowledge");
                prop_assert_eq!(a.ack_id, u16::from_be_bytes([b[6], b[7]]));
            }
            dev.tick(now);
            let _ = dev.poll_frame(now);
        }
        for (c, who) in cmds {
            now += 1_000_000;
            let r = Request { flags: gvcp::FLAG_ACK_REQUIRED, req_id: 9, command: c };
            let _ = dev.handle(app(50000 + who), Ipv4Addr::LOCALHOST, &r.encode(), now);
            let _ = dev.poll_frame(now);
        }
    }
}

#[test]
fn privilege_one_controller_at_a_time() {
    let mut dev = device();
    let (a, b) = (app(40000), app(40001));
    // nobody may write without control
    assert_eq!(
        write(&mut dev, a, addr::WIDTH, 640, 0),
        Status::AccessDenied as u16
    );
    // a takes control; b cannot take it, nor write, but may read
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(
        write(&mut dev, b, addr::CCP, 2, 0),
        Status::AccessDenied as u16
    );
    assert_eq!(
        write(&mut dev, b, addr::WIDTH, 640, 0),
        Status::AccessDenied as u16
    );
    assert_eq!(read(&mut dev, b, addr::WIDTH, 0), Ok(2448));
    assert_eq!(read(&mut dev, a, addr::CCP, 0), Ok(2));
    assert_eq!(read(&mut dev, b, addr::CCP, 0), Ok(0));
    // exclusive: b cannot even read (discovery still answers)
    assert_eq!(write(&mut dev, a, addr::CCP, 3, 0), 0);
    assert_eq!(
        read(&mut dev, b, addr::WIDTH, 0),
        Err(Status::AccessDenied as u16)
    );
    assert_eq!(send(&mut dev, b, Command::Discovery, 0).status, 0);
    // a releases; b takes it
    assert_eq!(write(&mut dev, a, addr::CCP, 0, 0), 0);
    assert_eq!(write(&mut dev, b, addr::CCP, 2, 0), 0);
    assert_eq!(write(&mut dev, b, addr::WIDTH, 640, 0), 0);
}

#[test]
fn heartbeat_timeout_releases_control_and_settings_persist() {
    let mut dev = device();
    let (a, b) = (app(40000), app(40001));
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(write(&mut dev, a, addr::HEARTBEAT_TIMEOUT, 1000, 0), 0);
    assert_eq!(write(&mut dev, a, addr::WIDTH, 1024, 0), 0);
    assert_eq!(write_f64(&mut dev, a, addr::EXPOSURE_TIME, 2500.0, 0), 0);
    assert_eq!(write(&mut dev, a, addr::SCDA, 0x7F00_0001, 0), 0);
    assert_eq!(write(&mut dev, a, addr::SCP, 50123, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    assert!(dev.acquiring());
    // a read within the timeout keeps control
    assert_eq!(read(&mut dev, a, addr::CCP, 900_000_000), Ok(2));
    assert!(!dev.tick(1_800_000_000));
    assert!(dev.tick(1_900_000_001));
    assert_eq!(dev.controller(), None);
    assert!(!dev.acquiring(), "the acquisition stops with the session");
    assert_eq!(
        dev.channel().destination(),
        None,
        "the stream channel closes"
    );
    assert_eq!(read(&mut dev, a, addr::CCP, 2_000_000_000), Ok(0));
    // the next session sees the same settings
    assert_eq!(write(&mut dev, b, addr::CCP, 2, 2_000_000_000), 0);
    assert_eq!(read(&mut dev, b, addr::WIDTH, 2_000_000_000), Ok(1024));
    assert_eq!(
        read_f64(&mut dev, b, addr::EXPOSURE_TIME, 2_000_000_000),
        2500.0
    );
    // heartbeat bounds
    assert_eq!(
        write(&mut dev, b, addr::HEARTBEAT_TIMEOUT, 100, 0),
        Status::InvalidParameter as u16
    );
}

#[test]
fn register_errors_have_their_status() {
    let mut dev = device();
    let a = app(40000);
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(
        write(&mut dev, a, 0x0BAD_0000, 1, 0),
        Status::InvalidAddress as u16
    );
    assert_eq!(
        read(&mut dev, a, 0x0BAD_0000, 0),
        Err(Status::InvalidAddress as u16)
    );
    assert_eq!(
        write(&mut dev, a, addr::SENSOR_WIDTH, 1, 0),
        Status::WriteProtect as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::PAYLOAD_SIZE, 1, 0),
        Status::WriteProtect as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::VERSION, 1, 0),
        Status::WriteProtect as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::WIDTH + 2, 1, 0),
        Status::BadAlignment as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::WIDTH, 5000, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::WIDTH, 641, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::OFFSET_X, 1, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::PIXEL_FORMAT, 0x0108_0008, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write_f64(&mut dev, a, addr::GAIN, 60.0, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write_f64(&mut dev, a, addr::EXPOSURE_TIME, f64::NAN, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(write_f64(&mut dev, a, addr::FRAME_RATE, 1000.0, 0), 0);
    assert_eq!(
        write_f64(&mut dev, a, addr::FRAME_RATE, 1000.5, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(
        write(&mut dev, a, addr::SCPS, 100, 0),
        Status::InvalidParameter as u16
    );
    let rm = send(
        &mut dev,
        a,
        Command::ReadMem {
            address: 0x201,
            count: 4,
        },
        0,
    );
    assert_eq!(rm.status, Status::BadAlignment as u16);
    let rm = send(
        &mut dev,
        a,
        Command::ReadMem {
            address: 0x200,
            count: 600,
        },
        0,
    );
    assert_eq!(rm.status, Status::InvalidParameter as u16);
    // a WRITEREG stops at the first error and says how many it wrote
    let ack = send(
        &mut dev,
        a,
        Command::WriteReg(vec![
            (addr::WIDTH, 640),
            (addr::HEIGHT, 3),
            (addr::OFFSET_X, 2),
        ]),
        0,
    );
    assert_eq!(ack.status, Status::InvalidParameter as u16);
    assert_eq!(ack.body, [0, 0, 0, 1]);
    assert_eq!(read(&mut dev, a, addr::OFFSET_X, 0), Ok(0));
    // an offset that would push the region off the sensor
    assert_eq!(
        write(&mut dev, a, addr::OFFSET_X, 2448 - 640 + 2, 0),
        Status::InvalidParameter as u16
    );
    assert_eq!(write(&mut dev, a, addr::OFFSET_X, 2448 - 640, 0), 0);
    // unknown command
    let b = [gvcp::KEY, 1, 0x12, 0x34, 0, 0, 0, 7];
    let out = dev.handle(a, Ipv4Addr::LOCALHOST, &b, 0);
    let ack = ack_of(&out);
    assert_eq!(
        (ack.status, ack.answer, ack.ack_id),
        (Status::NotImplemented as u16, 0x1235, 7)
    );
}

#[test]
fn bootstrap_and_xml_are_readable_in_memory() {
    let mut dev = device();
    let a = app(40000);
    let disc = send(&mut dev, a, Command::Discovery, 0);
    assert_eq!(disc.body.len(), gvcp::DISCOVERY_ACK_LEN);
    assert_eq!(&disc.body[0x48..0x4C], b"psns");
    assert_eq!(&disc.body[0x24..0x28], &[127, 0, 0, 1]);
    // the URL, then the XML it names, read the way a client does (512-byte blocks, last one
    // rounded up to 4 bytes)
    let url = send(
        &mut dev,
        a,
        Command::ReadMem {
            address: 0x200,
            count: 512,
        },
        0,
    );
    let url = String::from_utf8(url.body[4..].split(|&c| c == 0).next().unwrap().to_vec()).unwrap();
    let mut parts = url.strip_prefix("Local:psns.xml;").unwrap().split(';');
    let at = u32::from_str_radix(parts.next().unwrap(), 16).unwrap();
    let len = usize::from_str_radix(parts.next().unwrap(), 16).unwrap();
    let mut xml = Vec::new();
    while xml.len() < len {
        let n = (len - xml.len()).min(512).div_ceil(4) * 4;
        let ack = send(
            &mut dev,
            a,
            Command::ReadMem {
                address: at + xml.len() as u32,
                count: n as u16,
            },
            0,
        );
        assert_eq!(ack.status, 0);
        xml.extend_from_slice(&ack.body[4..]);
    }
    xml.truncate(len);
    assert_eq!(xml, psns::gige::xml::genicam_xml().as_bytes());
    // the user name is writable by the controller and kept
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    let ack = send(
        &mut dev,
        a,
        Command::WriteMem {
            address: addr::USER_NAME,
            data: b"rig-left\0\0\0\0\0\0\0\0".to_vec(),
        },
        0,
    );
    assert_eq!(ack.status, 0);
    let disc = send(&mut dev, app(9), Command::Discovery, 0);
    assert_eq!(&disc.body[0xE8..0xF0], b"rig-left");
}

#[test]
fn acquisition_modes_triggers_and_block_ids() {
    let mut dev = device();
    let a = app(40000);
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(dev.poll_frame(0), Poll::Idle);
    // SingleFrame: one frame
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_MODE, 1, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    let Poll::Frame(f) = dev.poll_frame(10) else {
        panic!()
    };
    assert_eq!((f.k, f.block_id, f.frame_index, f.timestamp), (1, 1, 0, 10));
    assert_eq!(dev.poll_frame(11), Poll::Idle);
    // MultiFrame: AcquisitionFrameCount frames
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_MODE, 2, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_FRAME_COUNT, 3, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    for k in 2..=4 {
        let Poll::Frame(f) = dev.poll_frame(20) else {
            panic!()
        };
        assert_eq!(f.k, k);
    }
    assert_eq!(dev.poll_frame(21), Poll::Idle);
    // software trigger: exactly one frame per trigger
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_MODE, 0, 0), 0);
    assert_eq!(write(&mut dev, a, addr::TRIGGER_MODE, 1, 0), 0);
    assert_eq!(
        write(&mut dev, a, addr::TRIGGER_SOFTWARE, 1, 0),
        0,
        "a trigger before the start is ignored"
    );
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    assert_eq!(dev.poll_frame(30), Poll::Idle);
    for _ in 0..2 {
        assert_eq!(write(&mut dev, a, addr::TRIGGER_SOFTWARE, 1, 0), 0);
    }
    assert!(matches!(dev.poll_frame(31), Poll::Frame(_)));
    assert!(matches!(dev.poll_frame(31), Poll::Frame(_)));
    assert_eq!(dev.poll_frame(32), Poll::Idle);
    // transport and format settings are locked while acquiring
    assert_eq!(write(&mut dev, a, addr::WIDTH, 640, 0), Status::Busy as u16);
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::PIXEL_FORMAT,
            GevPixelFormat::Mono16.code(),
            0
        ),
        Status::Busy as u16
    );
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_STOP, 1, 0), 0);
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::PIXEL_FORMAT,
            GevPixelFormat::PolarizeMono16.code(),
            0
        ),
        0
    );
    // free running continuous: block ids wrap from 65535 to 1, the frame index keeps counting
    assert_eq!(write(&mut dev, a, addr::TRIGGER_MODE, 0, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    let mut last = None;
    for _ in 0..70000 {
        if let Poll::Frame(f) = dev.poll_frame(40) {
            assert_ne!(f.block_id, 0);
            assert_eq!(f.frame_index, f.k - 1);
            last = Some(f);
        }
    }
    let f = last.unwrap();
    assert_eq!(f.k, 70006);
    assert_eq!(f.block_id, (70006 - 65535) as u16);
    assert_eq!(f.settings.pixel_format, GevPixelFormat::PolarizeMono16);
}

#[test]
fn frame_rate_paces_frames_and_reports_what_it_delivers() {
    let mut dev = device();
    let a = app(40000);
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(write(&mut dev, a, addr::FRAME_RATE_ENABLE, 1, 0), 0);
    assert_eq!(write_f64(&mut dev, a, addr::FRAME_RATE, 100.0, 0), 0);
    assert_eq!(write(&mut dev, a, addr::ACQUISITION_START, 1, 0), 0);
    assert!(matches!(dev.poll_frame(0), Poll::Frame(_)));
    assert_eq!(dev.poll_frame(1_000_000), Poll::At(10_000_000));
    assert!(matches!(dev.poll_frame(10_000_000), Poll::Frame(_)));
    // the device delivers only every 25 ms: the reading says 40 Hz, not 100
    let mut t = 10_000_000;
    for _ in 0..40 {
        t += 25_000_000;
        assert!(matches!(dev.poll_frame(t), Poll::Frame(_)));
    }
    let r = read_f64(&mut dev, a, addr::FRAME_RATE, t);
    assert!((r - 40.0).abs() < 0.5, "{r}");
    let rr = read_f64(&mut dev, a, addr::RESULTING_FRAME_RATE, t);
    assert!((rr - 40.0).abs() < 0.5, "{rr}");
    // asking for less than it can do reads back as asked
    assert_eq!(write_f64(&mut dev, a, addr::FRAME_RATE, 10.0, t), 0);
    assert_eq!(read_f64(&mut dev, a, addr::FRAME_RATE, t), 10.0);
}

#[test]
fn payload_size_follows_region_format_and_chunks() {
    let mut dev = device();
    let a = app(40000);
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(read(&mut dev, a, addr::PAYLOAD_SIZE, 0), Ok(2448 * 2048));
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::PIXEL_FORMAT,
            GevPixelFormat::Mono12p.code(),
            0
        ),
        0
    );
    assert_eq!(
        read(&mut dev, a, addr::PAYLOAD_SIZE, 0),
        Ok(2448 * 2048 * 3 / 2)
    );
    assert_eq!(write(&mut dev, a, addr::WIDTH, 640, 0), 0);
    assert_eq!(write(&mut dev, a, addr::HEIGHT, 480, 0), 0);
    assert_eq!(write(&mut dev, a, addr::CHUNK_MODE_ACTIVE, 1, 0), 0);
    let all = chunk::tail_len(chunk::ALL_MASK) as u32;
    assert_eq!(
        read(&mut dev, a, addr::PAYLOAD_SIZE, 0),
        Ok(640 * 480 * 3 / 2 + all)
    );
    // ChunkEnable is indexed by ChunkSelector
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::CHUNK_SELECTOR,
            ChunkKind::Attitude as u32,
            0
        ),
        0
    );
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::CHUNK_ENABLE + 4 * ChunkKind::Attitude as u32,
            0,
            0
        ),
        0
    );
    assert_eq!(
        read(&mut dev, a, addr::PAYLOAD_SIZE, 0),
        Ok(640 * 480 * 3 / 2 + all - 40)
    );
    assert_eq!(
        write(
            &mut dev,
            a,
            addr::CHUNK_SELECTOR,
            ChunkKind::ALL.len() as u32,
            0
        ),
        Status::InvalidParameter as u16
    );
}

#[test]
fn fire_test_packet_and_resend_become_actions() {
    let mut dev = device();
    let a = app(40000);
    assert_eq!(write(&mut dev, a, addr::CCP, 2, 0), 0);
    assert_eq!(write(&mut dev, a, addr::SCDA, 0x7F00_0001, 0), 0);
    assert_eq!(write(&mut dev, a, addr::SCP, 40002, 0), 0);
    let r = Request {
        flags: gvcp::FLAG_ACK_REQUIRED,
        req_id: 3,
        command: Command::WriteReg(vec![(addr::SCPS, (1 << 31) | (1 << 30) | 8192)]),
    };
    let out = dev.handle(a, Ipv4Addr::LOCALHOST, &r.encode(), 0);
    assert_eq!(
        out.actions,
        [Action::FireTestPacket {
            dest: SocketAddrV4::new(Ipv4Addr::LOCALHOST, 40002),
            packet_size: 8192,
            do_not_fragment: true
        }]
    );
    assert_eq!(read(&mut dev, a, addr::SCPS, 0), Ok((1 << 30) | 8192));
    let r = Request {
        flags: 0,
        req_id: 4,
        command: Command::PacketResend {
            channel: 0,
            block_id: 7,
            first: 3,
            last: 5,
            extended: false,
        },
    };
    let out = dev.handle(app(40003), Ipv4Addr::LOCALHOST, &r.encode(), 0);
    assert_eq!(out.reply, None, "PACKETRESEND has no acknowledge");
    assert_eq!(
        out.actions,
        [Action::Resend {
            block_id: 7,
            first: 3,
            last: 5
        }]
    );
}
