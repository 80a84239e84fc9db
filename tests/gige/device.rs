//! `psns gige` against GenICam clients nobody here wrote: Aravis's command-line tools
//! (`arv-tool-0.8`, `arv-camera-test-0.8`, `arv-test-0.8`'s GenApi schema) and its Python bindings
//! (Debian's python3-gi with gir1.2-aravis-0.8, driven by `tests/gige/aravis.py`).
//!
//! The tools are required: `tools/test` installs them, and these tests fail (never skip) when
//! they are missing. Every device runs on its own loopback address (127.x.y.z; GigE Vision's
//! control port is always 3956), every external command runs under `timeout`, and every server
//! is stopped at the end of its test (SIGTERM, then SIGKILL).

use psns::gige::chunk::ChunkKind;
use psns::sensor::packing::{self, PixelFormat};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::net::{Ipv4Addr, UdpSocket};
use std::process::{Command, Stdio};
use std::time::Duration;

use super::harness::*;

#[test]
fn genicam_xml_validates_against_the_genapi_schema() {
    require_tools();
    let s = Server::start(&["--width", "64", "--height", "48"]);
    let dir = tmpdir();
    // the XML as Aravis reads it from the device's memory
    let o = bounded(60, "arv-tool-0.8", &["-a", &s.ip(), "genicam"]);
    assert!(o.status.success(), "{}", text(&o));
    let xml = String::from_utf8(o.stdout).unwrap();
    let start = xml.find("<?xml").expect("an XML document");
    let xml_path = dir.path().join("psns.xml");
    std::fs::write(&xml_path, &xml[start..]).unwrap();
    assert_eq!(
        xml[start..].trim_end(),
        psns::gige::xml::genicam_xml().trim_end()
    );
    // GenApi schema 1.1, as arv-test-0.8 carries it
    let xsd = dir.path().join("GenApiSchema_Version_1_1.xsd");
    let o = bounded(
        30,
        "gresource",
        &[
            "extract",
            "/usr/bin/arv-test-0.8",
            "/org/aravis/GenApiSchema_Version_1_1.xsd",
        ],
    );
    assert!(
        o.status.success() && o.stdout.len() > 10_000,
        "{}",
        text(&o)
    );
    std::fs::write(&xsd, &o.stdout).unwrap();
    let o = bounded(
        60,
        "xmllint",
        &[
            "--noout",
            "--schema",
            xsd.to_str().unwrap(),
            xml_path.to_str().unwrap(),
        ],
    );
    assert!(
        o.status.success(),
        "schema validation failed:\n{}",
        text(&o)
    );
    assert!(text(&o).contains("validates"), "{}", text(&o));
    // and a broken document fails it (the check can fail)
    std::fs::write(
        &xml_path,
        xml[start..].replacen("<Length>4</Length>", "<Length>four</Length>", 1),
    )
    .unwrap();
    let o = bounded(
        60,
        "xmllint",
        &[
            "--noout",
            "--schema",
            xsd.to_str().unwrap(),
            xml_path.to_str().unwrap(),
        ],
    );
    assert!(!o.status.success());
    s.stop();
}

/// Aravis's own test suite for cameras: the GenICam data, properties, acquisitions (multiple,
/// single, software trigger), chunks, GigE Vision specifics.
#[test]
fn arv_test_passes() {
    require_tools();
    let serial = format!("arvt-{}", std::process::id());
    let s = Server::start(&["--width", "256", "--height", "128", "--serial", &serial]);
    let o = bounded(
        600,
        "arv-test-0.8",
        &["-n", &format!("psns-IMX250MZR-sky-{serial}")],
    );
    let t = text(&o);
    s.stop();
    let passed = t.lines().filter(|l| l.contains(" SUCCESS")).count();
    assert!(passed >= 15, "{passed} tests passed:\n{t}");
    assert!(!t.contains("FAILURE"), "{t}");
    for test in [
        "MultipleAcquisitionA:BufferCheck",
        "SoftwareTrigger:BufferCheck",
        "Chunks:BufferCheck",
    ] {
        assert!(
            t.lines()
                .any(|l| l.starts_with(test) && l.contains("SUCCESS")),
            "{test}:\n{t}"
        );
    }
}

#[test]
fn discovery_finds_the_device() {
    require_tools();
    let s = Server::start(&["--width", "64", "--height", "48", "--serial", "disc-test"]);
    // broadcast discovery (arv-tool with no command lists every device it finds)
    let o = bounded(60, "arv-tool-0.8", &[]);
    let t = text(&o);
    assert!(
        t.contains(&format!("psns-IMX250MZR-sky-disc-test ({})", s.ip())),
        "broadcast discovery:\n{t}"
    );
    // unicast: opening by address reads the device's identity
    let o = bounded(
        60,
        "arv-tool-0.8",
        &["-a", &s.ip(), "control", "DeviceSerialNumber"],
    );
    assert!(
        text(&o).contains("DeviceSerialNumber = disc-test"),
        "{}",
        text(&o)
    );
    s.stop();
}

#[test]
fn arv_tool_reads_and_writes_features() {
    require_tools();
    let s = Server::start(&["--width", "640", "--height", "480", "--gain-db", "3"]);
    let ip = s.ip();
    let control = |args: &[&str]| {
        let mut a = vec!["-a", ip.as_str(), "control"];
        a.extend_from_slice(args);
        text(&bounded(60, "arv-tool-0.8", &a))
    };
    let t = control(&[
        "SensorWidth",
        "SensorHeight",
        "DeviceVendorName",
        "DeviceModelName",
        "Gain",
        "ExposureTime",
        "PixelFormat",
        "DeviceTemperature",
        "AcquisitionFrameRate",
    ]);
    for want in [
        "SensorWidth = 640",
        "SensorHeight = 480",
        "DeviceVendorName = psns",
        "DeviceModelName = IMX250MZR-sky",
        "Gain = 3 dB",
        "PixelFormat = Mono8",
    ] {
        assert!(t.contains(want), "{want}:\n{t}");
    }
    // writes, each arv-tool run its own control session: the settings persist
    let t = control(&[
        "Width=320",
        "Height=240",
        "OffsetX=64",
        "OffsetY=32",
        "PixelFormat=PolarizeMono12p",
        "ExposureTime=2500",
        "Gain=6",
        "BlackLevel=16",
        "DeviceUserID=left",
        "DeviceLinkThroughputLimitMode=On",
        "DeviceLinkThroughputLimit=125000000",
    ]);
    assert!(!t.to_lowercase().contains("error"), "{t}");
    let t = control(&[
        "Width",
        "Height",
        "OffsetX",
        "OffsetY",
        "PixelFormat",
        "PayloadSize",
        "ExposureTime",
        "Gain",
        "BlackLevel",
        "DeviceUserID",
        "DeviceLinkThroughputLimit",
    ]);
    for want in [
        "Width = 320",
        "Height = 240",
        "OffsetX = 64",
        "OffsetY = 32",
        "PixelFormat = PolarizeMono12p",
        "PayloadSize = 115200",
        "ExposureTime = 2500",
        "Gain = 6",
        "BlackLevel = 16",
        "DeviceUserID = left",
        "DeviceLinkThroughputLimit = 125000000",
    ] {
        assert!(t.contains(want), "{want}:\n{t}");
    }
    // registers by address: PixelFormat's, and the XML URL's first word ("Loca")
    let t = control(&["R[0x100018]", "R[0x200]"]);
    assert!(t.contains("0x810c0047") || t.contains("0x810C0047"), "{t}");
    assert!(t.contains("0x4c6f6361") || t.contains("0x4C6F6361"), "{t}");
    // refused writes leave the value as it was
    for bad in [
        "Width=321",
        "Width=4000",
        "Gain=99",
        "OffsetX=3",
        "R[0x100000]=5",
    ] {
        let _ = control(&[bad]);
    }
    let t = control(&["Width", "Gain", "OffsetX", "SensorWidth"]);
    for want in [
        "Width = 320",
        "Gain = 6",
        "OffsetX = 64",
        "SensorWidth = 640",
    ] {
        assert!(t.contains(want), "{want} after refused writes:\n{t}");
    }
    s.stop();
}

/// GVCP from a plain UDP socket: status codes of refused writes, malformed datagrams.
#[test]
fn raw_gvcp_errors_and_malformed_datagrams() {
    use psns::gige::gvcp::{Ack, Command as Cmd, Request, Status, FLAG_ACK_REQUIRED};
    use psns::gige::registers::addr;
    let s = Server::start(&["--width", "64", "--height", "48"]);
    let sock = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let dev = (s.addr, 3956);
    let ask = |cmd: Cmd, id: u16| -> Ack {
        let r = Request {
            flags: FLAG_ACK_REQUIRED,
            req_id: id,
            command: cmd,
        };
        sock.send_to(&r.encode(), dev).unwrap();
        let mut b = [0u8; 1024];
        let n = sock.recv(&mut b).expect("an acknowledge");
        let a = Ack::decode(&b[..n]).unwrap();
        assert_eq!(a.ack_id, id);
        a
    };
    // no privilege
    assert_eq!(
        ask(Cmd::WriteReg(vec![(addr::WIDTH, 32)]), 1).status,
        Status::AccessDenied as u16
    );
    assert_eq!(ask(Cmd::WriteReg(vec![(addr::CCP, 2)]), 2).status, 0);
    assert_eq!(
        ask(Cmd::WriteReg(vec![(addr::SENSOR_WIDTH, 1)]), 3).status,
        Status::WriteProtect as u16
    );
    assert_eq!(
        ask(Cmd::WriteReg(vec![(0x0DEA_D000, 1)]), 4).status,
        Status::InvalidAddress as u16
    );
    assert_eq!(
        ask(Cmd::WriteReg(vec![(addr::WIDTH, 66)]), 5).status,
        Status::InvalidParameter as u16
    );
    assert_eq!(
        ask(
            Cmd::ReadMem {
                address: 2,
                count: 4
            },
            6
        )
        .status,
        Status::BadAlignment as u16
    );
    // garbage: dropped or answered, and the device keeps answering
    let junk: Vec<Vec<u8>> = vec![
        vec![],
        vec![0x42],
        vec![0x42, 1, 0, 0x80, 0xFF, 0xFF, 0, 9],
        vec![0x42, 1, 0xAB, 0xCD, 0, 0, 0, 10],
        (0..1400).map(|i| (i * 7) as u8).collect(),
    ];
    for j in &junk {
        sock.send_to(j, dev).unwrap();
    }
    // answered with a status: the length that disagrees and the unknown command
    let mut statuses = Vec::new();
    let mut b = [0u8; 1024];
    sock.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    while let Ok(n) = sock.recv(&mut b) {
        statuses.push(Ack::decode(&b[..n]).unwrap().status);
    }
    assert_eq!(
        statuses,
        [Status::InvalidHeader as u16, Status::NotImplemented as u16]
    );
    sock.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let a = ask(Cmd::ReadReg(vec![addr::WIDTH]), 11);
    assert_eq!((a.status, a.body.as_slice()), (0, &64u32.to_be_bytes()[..]));
    s.stop();
}

#[test]
fn arv_camera_test_streams_without_failed_buffers() {
    require_tools();
    // 127.0.0.1, the address clients use by default, unless something else holds it
    let s = Server::start_at(Ipv4Addr::LOCALHOST, &[]).unwrap_or_else(|| {
        eprintln!("127.0.0.1:3956 is taken: using another loopback address");
        Server::start(&[])
    });
    let o = bounded(
        90,
        "arv-camera-test-0.8",
        &["-n", &s.ip(), "-i", "8192", "--duration", "5"],
    );
    let t = text(&o);
    let get = |k: &str| -> u64 {
        t.lines()
            .find_map(|l| l.strip_prefix(k).and_then(|r| r.trim().strip_prefix('=')))
            .unwrap_or_else(|| panic!("{k} missing:\n{t}"))
            .trim()
            .parse()
            .unwrap()
    };
    assert!(t.contains("vendor name            = psns"), "{t}");
    assert!(get("n_completed_buffers") >= 3, "{t}");
    assert_eq!(get("n_failures"), 0, "{t}");
    assert_eq!(get("n_missing_packets"), 0, "{t}");
    s.stop();
}

const OPTS: [&str; 4] = ["--yaw-rate", "25", "--seed", "7"];

#[test]
fn python_frames_equal_psns_stream_mono8_and_mono16() {
    require_tools();
    let s = Server::start(&OPTS);
    let ip = s.ip();
    // blocks 1..20 in Mono8 (packet size 8192), 21..40 in PolarizeMono16, 41..45 in Mono12p
    let m8 = client(
        300,
        &[
            "grab",
            &ip,
            "--format",
            "Mono8",
            "--frames",
            "20",
            "--packet-size",
            "8192",
        ],
    );
    let m16 = client(
        300,
        &[
            "grab",
            &ip,
            "--format",
            "PolarizeMono16",
            "--frames",
            "20",
            "--packet-size",
            "8192",
        ],
    );
    let m12 = client(300, &["grab", &ip, "--format", "Mono12p", "--frames", "5"]);
    s.stop();
    let want8 = stream_hashes(&OPTS, &["--bit-depth", "8", "--pixel-format", "mono8"], 20);
    let want16 = stream_hashes(
        &OPTS,
        &["--bit-depth", "12", "--pixel-format", "mono16"],
        40,
    );
    let want12 = stream_hashes(
        &OPTS,
        &["--bit-depth", "12", "--pixel-format", "mono12p"],
        45,
    );
    for (lines, want, first, code, size) in [
        (&m8, &want8, 1u64, 0x0108_0001u64, 2448 * 2048),
        (&m16, &want16, 21, 0x8110_0007, 2448 * 2048 * 2),
        (&m12, &want12, 41, 0x010C_0047, 2448 * 2048 * 3 / 2),
    ] {
        let b = buffers(lines);
        let n = if first == 41 { 5 } else { 20 };
        let ids: Vec<u64> = b.iter().map(|f| f["block"].as_u64().unwrap()).collect();
        assert_eq!(ids, (first..first + n).collect::<Vec<_>>(), "{lines:?}");
        for f in &b {
            let block = f["block"].as_u64().unwrap();
            assert_eq!(f["status"], "success", "{f}");
            assert_eq!(f["pixel_format"].as_u64(), Some(code));
            assert_eq!(f["size"].as_u64(), Some(size));
            assert_eq!(
                f["sha256"].as_str().unwrap(),
                want[(block - 1) as usize],
                "block {block} differs from frame {} of psns stream",
                block - 1
            );
        }
        assert_eq!(stats(lines)["n_failures"], 0);
    }
    // different frames, not one frame repeated
    assert_ne!(want8[0], want8[1]);
}

#[test]
fn region_crops_the_full_sensor_frame() {
    require_tools();
    let opts = ["--width", "320", "--height", "240"];
    let s = Server::start(&opts);
    let lines = client(
        120,
        &[
            "grab",
            &s.ip(),
            "--format",
            "Mono12Packed",
            "--frames",
            "3",
            "--region",
            "100,50,36,22",
        ],
    );
    s.stop();
    let mut full = Vec::new();
    each_stream_frame(
        &opts,
        &["--bit-depth", "12", "--pixel-format", "mono16"],
        3,
        |p| full.push(p.to_vec()),
    );
    for (i, f) in buffers(&lines).iter().enumerate() {
        assert_eq!(f["block"].as_u64(), Some(i as u64 + 1));
        assert_eq!(
            (f["width"].as_u64(), f["height"].as_u64()),
            (Some(100), Some(50))
        );
        assert_eq!(
            (f["offset_x"].as_u64(), f["offset_y"].as_u64()),
            (Some(36), Some(22))
        );
        let codes: Vec<u16> = full[i]
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        let region: Vec<u16> = (22..72)
            .flat_map(|r| codes[r * 320 + 36..r * 320 + 136].to_vec())
            .collect();
        let mut packed = Vec::new();
        packing::pack(&region, 12, PixelFormat::Mono12Packed, false, &mut packed).unwrap();
        assert_eq!(
            f["sha256"].as_str().unwrap(),
            hex(&Sha256::digest(&packed)),
            "block {}",
            i + 1
        );
    }
}

#[test]
fn resends_heal_every_frame_under_dropped_packets() {
    require_tools();
    let opts = ["--width", "640", "--height", "480", "--seed", "3"];
    let mut args = opts.to_vec();
    args.extend(["--drop-packets", "0.03"]);
    let s = Server::start(&args);
    let lines = client(
        300,
        &[
            "grab",
            &s.ip(),
            "--format",
            "Mono8",
            "--frames",
            "15",
            "--packet-size",
            "1500",
        ],
    );
    let log = s.stop();
    let want = stream_hashes(&opts, &["--bit-depth", "8", "--pixel-format", "mono8"], 15);
    let b = buffers(&lines);
    assert_eq!(b.len(), 15);
    for f in &b {
        let block = f["block"].as_u64().unwrap();
        assert_eq!(f["status"], "success", "{f}");
        assert_eq!(
            f["sha256"].as_str().unwrap(),
            want[(block - 1) as usize],
            "block {block}"
        );
    }
    let st = stats(&lines);
    let resent = st["n_resent_packets"].as_u64().unwrap();
    // 15 frames x 211 data packets x 3 %: about 95 dropped, every one resent
    assert!(resent >= 40, "{st}");
    assert_eq!(st["n_failures"], 0, "{st}");
    let dropped: u64 = log
        .split(" dropped by --drop-packets")
        .next()
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{log}"));
    assert!(
        dropped >= 40 && resent >= dropped,
        "dropped {dropped}, resent {resent}\n{log}"
    );
}

#[test]
fn software_trigger_gives_one_frame_per_trigger() {
    require_tools();
    // a size no other test streams: a stray block from another test's device, still streaming
    // to a port the system has since given to this client, cannot pass for one of these
    let s = Server::start(&["--width", "136", "--height", "104"]);
    let lines = client(
        120,
        &["trigger", &s.ip(), "--count", "5", "--interval", "0.5"],
    );
    s.stop();
    let ours = |f: &&Value| f["status"] == "success" && f["width"] == 136 && f["height"] == 104;
    let before: Vec<&Value> = lines[0]["before"].as_array().unwrap().iter().collect();
    assert!(
        !before.iter().any(ours),
        "no frame without a trigger: {before:?}"
    );
    let b: Vec<&Value> = buffers(&lines).into_iter().filter(ours).collect();
    assert_eq!(b.len(), 5, "{lines:?}");
    let ids: Vec<u64> = b.iter().map(|f| f["block"].as_u64().unwrap()).collect();
    // five triggers, five whole frames of this device, in order
    assert_eq!(ids, [1, 2, 3, 4, 5]);
}

#[test]
fn chunks_decoded_by_aravis_equal_the_truth_file() {
    require_tools();
    let dir = tmpdir();
    let truth = dir.path().join("truth.csv");
    let s = Server::start(&[
        "--width",
        "128",
        "--height",
        "96",
        "--time",
        "2024-06-01T09:00:00Z",
        "--lat",
        "48.1",
        "--lon",
        "11.6",
        "--yaw-rate",
        "40",
        "--truth-csv",
        truth.to_str().unwrap(),
    ]);
    let lines = client(
        120,
        &[
            "grab",
            &s.ip(),
            "--format",
            "Mono16",
            "--frames",
            "6",
            "--chunks",
        ],
    );
    s.stop();
    let csv = std::fs::read_to_string(&truth).unwrap();
    let mut rows = csv.lines();
    let head: Vec<&str> = rows.next().unwrap().split(',').collect();
    let rows: HashMap<u64, HashMap<&str, &str>> = rows
        .map(|l| {
            let m: HashMap<&str, &str> = head.iter().copied().zip(l.split(',')).collect();
            (m["block_id"].parse().unwrap(), m)
        })
        .collect();
    let f64_of = |v: &Value| -> f64 {
        // Python's float.hex
        let s = v.as_str().unwrap();
        let (neg, s) = s.strip_prefix('-').map_or((false, s), |r| (true, r));
        let s = s.strip_prefix("0x").unwrap();
        let (m, e) = s.split_once('p').unwrap();
        let (i, f) = m.split_once('.').unwrap_or((m, ""));
        let mut x = i.parse::<f64>().unwrap();
        for (k, c) in f.chars().enumerate() {
            x += c.to_digit(16).unwrap() as f64 * 16f64.powi(-(k as i32 + 1));
        }
        let x = x * 2f64.powi(e.parse().unwrap());
        if neg {
            -x
        } else {
            x
        }
    };
    let b = buffers(&lines);
    assert_eq!(b.len(), 6);
    for f in b {
        let block = f["block"].as_u64().unwrap();
        let row = &rows[&block];
        let c = &f["chunks"];
        // Aravis reads every feature of the chunk table, found in the device's XML
        let mut read: Vec<&str> = c.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        read.sort();
        let mut table: Vec<&str> = ChunkKind::ALL
            .iter()
            .flat_map(|k| k.chunk().features.iter().map(|f| f.name))
            .collect();
        table.sort();
        assert_eq!(read, table, "block {block}");
        let num = |k: &str| row[k].parse::<f64>().unwrap();
        assert_eq!(f64_of(&c["ChunkExposureTime"]), num("exposure_us"));
        assert_eq!(f64_of(&c["ChunkGain"]), num("gain_db"));
        assert_eq!(f64_of(&c["ChunkAttitudeW"]), num("qw"));
        assert_eq!(f64_of(&c["ChunkAttitudeX"]), num("qx"));
        assert_eq!(f64_of(&c["ChunkAttitudeY"]), num("qy"));
        assert_eq!(f64_of(&c["ChunkAttitudeZ"]), num("qz"));
        assert_eq!(f64_of(&c["ChunkSunAzimuth"]), num("sun_azimuth_deg"));
        assert_eq!(f64_of(&c["ChunkSunElevation"]), num("sun_elevation_deg"));
        assert_eq!(
            c["ChunkTimestamp"].as_u64().unwrap().to_string(),
            row["timestamp_ns"]
        );
        assert_eq!(c["ChunkFrameIndex"].as_u64().unwrap(), block - 1);
        for (chunk, col) in [
            ("ChunkOffsetX", "offset_x"),
            ("ChunkOffsetY", "offset_y"),
            ("ChunkWidth", "width"),
            ("ChunkHeight", "height"),
        ] {
            assert_eq!(c[chunk].as_u64().unwrap().to_string(), row[col], "{chunk}");
        }
        assert_eq!(c["ChunkPixelFormat"].as_u64(), Some(0x0110_0007));
        assert_eq!(row["pixel_format"], "Mono16");
        assert_eq!(
            f["timestamp"].as_u64().unwrap().to_string(),
            row["timestamp_ns"]
        );
    }
    // the sun moves along the trajectory's clock, and the camera turns
    assert_ne!(rows[&1]["sun_azimuth_deg"], rows[&6]["sun_azimuth_deg"]);
    assert_ne!(rows[&1]["qz"], rows[&6]["qz"]);
}

#[test]
fn a_second_client_cannot_take_control_until_the_heartbeat_expires() {
    require_tools();
    let s = Server::start(&["--width", "64", "--height", "48"]);
    let ip = s.ip();
    // client A takes control (heartbeat timeout 1.5 s) and holds it
    let mut holder = Command::new(python())
        .args([
            client_script().to_str().unwrap(),
            "hold",
            &ip,
            "--seconds",
            "60",
            "--heartbeat",
            "1500",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(holder.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("holding"), "{first}");
    // B cannot write
    let o = bounded(60, "arv-tool-0.8", &["-a", &ip, "control", "Width=32"]);
    let t = text(&o);
    let o = bounded(60, "arv-tool-0.8", &["-a", &ip, "control", "Width"]);
    assert!(
        text(&o).contains("Width = 64"),
        "B changed Width:\n{t}\n{}",
        text(&o)
    );
    // A dies without releasing control: after the heartbeat timeout B can write
    let _ = holder.kill();
    let _ = holder.wait();
    std::thread::sleep(Duration::from_millis(2500));
    let o = bounded(60, "arv-tool-0.8", &["-a", &ip, "control", "Width=32"]);
    let o2 = bounded(
        60,
        "arv-tool-0.8",
        &["-a", &ip, "control", "Width", "DeviceUserID"],
    );
    assert!(
        text(&o2).contains("Width = 32"),
        "{}\n{}",
        text(&o),
        text(&o2)
    );
    // A's settings outlived its session
    assert!(text(&o2).contains("DeviceUserID = holder"), "{}", text(&o2));
    let log = s.stop();
    assert!(log.contains("heartbeat timeout"), "{log}");
}

#[test]
fn sigint_and_sigterm_end_cleanly_and_release_the_port() {
    for sig in [libc::SIGINT, libc::SIGTERM] {
        let s = Server::start(&["--width", "64", "--height", "48"]);
        let addr = s.addr;
        let (st, log) = s.stop_with(sig);
        assert_eq!(st.code(), Some(0), "signal {sig}: {st}\n{log}");
        assert!(log.contains("stopped after"), "{log}");
        UdpSocket::bind((addr, 3956)).expect("the port is free again");
    }
}

#[test]
fn bad_options_exit_2_and_write_nothing() {
    let dir = tmpdir();
    let truth = dir.path().join("t.csv");
    for bad in [
        vec!["--bit-depth", "8"],
        vec!["--pixel-format", "mono16"],
        vec!["--drop-packets", "1.5"],
        vec!["--width", "63"],
        vec!["--serial", "much-too-long-serial"],
        vec!["--address", "not-an-address"],
        vec!["--exposure-us", "5"],
    ] {
        let mut a = vec!["gige"];
        a.extend(bad.iter().copied());
        a.extend(["--port", "0", "--truth-csv", truth.to_str().unwrap()]);
        let o = bounded(60, BIN, &a);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", text(&o));
        assert!(!truth.exists(), "{bad:?} wrote the truth file");
    }
    // an address in use: an I/O error, exit 1
    let taken = UdpSocket::bind((unique_addr(), 0)).unwrap();
    let a = taken.local_addr().unwrap();
    let o = bounded(
        60,
        BIN,
        &[
            "gige",
            "--address",
            &a.ip().to_string(),
            "--port",
            &a.port().to_string(),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("in use"), "{}", text(&o));
}
