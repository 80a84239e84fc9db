//! Every value of the library's name tables through the stream's front-ends: each pixel format
//! through `psns stream`, the Rust reader, `psns verify`, `psns extract` and degraded-mode
//! recovery; each sky model through `psns stream`. A value one of them forgets fails here.

use crate::common;
use common::{psns, stderr};
use psns::sensor::packing::{payload_size, PixelFormat};
use psns::sky::PolarizationModel;
use psns::stream::{
    extract_frame, verify_with, Event, FileHeader, Frame, RecoverHint, StreamReader, VerifyStatus,
};
use std::io::Cursor;
use std::path::Path;

/// A small camera; f/16 and 20 µs keep it out of saturation.
const SMALL: [&str; 10] = [
    "--width",
    "64",
    "--height",
    "48",
    "--pixel-pitch",
    "130",
    "--f-number",
    "16",
    "--exposure-us",
    "20",
];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `psns stream` with the small camera, `extra` and 2 frames into `dir/name`; its bytes.
fn stream(dir: &Path, name: &str, extra: &[&str]) -> Vec<u8> {
    let p = dir.join(name);
    let mut args = vec!["stream"];
    args.extend(SMALL);
    args.extend(extra);
    args.extend(["--frames", "2", "--out", s(&p)]);
    let o = psns(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    std::fs::read(&p).unwrap()
}

/// Header and intact frames (every payload CRC checked).
fn read(bytes: &[u8]) -> (FileHeader, Vec<Frame>) {
    let mut r = StreamReader::new(Cursor::new(bytes)).unwrap();
    let h = r.header().clone();
    let mut out = Vec::new();
    while let Some(e) = r.next_event().unwrap() {
        match e {
            Event::Frame(f) => {
                assert!(f.payload_crc_ok, "frame {} payload CRC", f.meta.index);
                out.push(f)
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    (h, out)
}

/// Every pixel format: `psns stream --pixel-format NAME` writes it (header, payload size), the
/// reader gives back the same codes as the Mono16 stream (Mono8 their top 8 bits), `psns verify`
/// finds it clean, `psns extract` reads a frame, and a damaged file header is recovered with the
/// format inferred (the width lost) or given (the format field lost).
#[test]
fn every_pixel_format_through_stream_reader_verify_and_recovery() {
    let d = tempfile::tempdir().unwrap();
    let reference = stream(d.path(), "ref.psns", &["--pixel-format", "mono16"]);
    let (rh, want) = read(&reference);
    for fmt in PixelFormat::ALL {
        let name = fmt.name();
        let file = format!("{name}.psns");
        let bytes = stream(d.path(), &file, &["--pixel-format", name]);
        let (h, frames) = read(&bytes);
        assert_eq!(h.pixel_format, fmt, "{name}");
        assert_eq!((h.width, h.height), (64, 48), "{name}");
        assert_eq!(frames.len(), 2, "{name}");
        for (f, w) in frames.iter().zip(&want) {
            assert_eq!(f.payload.len(), payload_size(fmt, 64, 48), "{name}");
            let codes = f.codes(&h).unwrap();
            let expect: Vec<u16> = match fmt {
                PixelFormat::Mono8 => w.codes(&rh).unwrap().iter().map(|c| c >> 4).collect(),
                PixelFormat::Mono12p | PixelFormat::Mono12Packed | PixelFormat::Mono16 => {
                    w.codes(&rh).unwrap()
                }
            };
            assert_eq!(codes, expect, "{name} frame {}", f.meta.index);
        }
        let p = d.path().join(&file);
        let o = psns(&["verify", s(&p)]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        let x = d.path().join(format!("x-{name}"));
        let o = psns(&["extract", s(&p), "--frame", "1", "--out", s(&x)]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let x1 = extract_frame(Cursor::new(&bytes), 1).unwrap();
        assert_eq!(x1.codes, frames[1].codes(&h).unwrap(), "{name}");

        // the width lost: inferred from the frames, the format from its field
        let mut b = bytes.clone();
        b[20] ^= 0x40;
        let rep = verify_with(Cursor::new(&b), Some(&RecoverHint::default()))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(rep.status, VerifyStatus::Damaged, "{name}");
        assert_eq!(rep.frames, 2, "{name}: {rep}");
        assert_eq!(
            (rep.header.width, rep.header.height, rep.header.pixel_format),
            (64, 48, fmt),
            "{name}: {rep}"
        );
        // the format field lost: given on the command line, the frames read as written
        let mut b = bytes.clone();
        b[28] ^= 0xff;
        let f = d.path().join(format!("damaged-{name}.psns"));
        std::fs::write(&f, &b).unwrap();
        let o = psns(&["verify", "--recover", "--pixel-format", name, s(&f)]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(1), "{name}: {out}{}", stderr(&o));
        assert!(
            out.contains(&format!("64 x 48 {}", fmt.pfnc_name())),
            "{name}: {out}"
        );
        assert!(out.contains("frames: 2 intact"), "{name}: {out}");
    }
}

/// Every sky model through `psns stream`: the header's scene names it, and its frames differ
/// from every other model's.
#[test]
fn every_sky_model_through_stream() {
    let d = tempfile::tempdir().unwrap();
    let mut seen: Vec<(PolarizationModel, Vec<u16>)> = Vec::new();
    for m in PolarizationModel::ALL {
        let bytes = stream(d.path(), &format!("{m}.psns"), &["--model", m.name()]);
        let (h, frames) = read(&bytes);
        let v: serde_json::Value = serde_json::from_str(&h.json).unwrap();
        assert_eq!(v["scene"]["sky"]["model"], m.name(), "{m}");
        let codes = frames[0].codes(&h).unwrap();
        for (other, c) in &seen {
            assert_ne!(&codes, c, "{m} streams the frame of {other}");
        }
        seen.push((m, codes));
    }
}
