//! tools/nav_reader.py, the reference navigation-side reader: dropped frames and black levels
//! of MSB-aligned payloads as the stream records them.

use super::readers::{root, stream, stream_ix};
use crate::common;
use psns::sensor::packing::PixelFormat;
use psns::stream::*;
use std::path::Path;

fn nav(path: &Path) -> std::process::Output {
    common::python_cmd()
        .arg(root().join("tools/nav_reader.py"))
        .arg(path)
        .output()
        .unwrap()
}

/// nav_reader reports dropped frames (index gaps) and exits with status 1; a clean stream 0.
#[test]
fn nav_reader_reports_dropped_frames() {
    common::require_numpy();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("clean.psns");
    std::fs::write(&p, stream(PixelFormat::Mono12p, 16, 8, 3, false)).unwrap();
    let out = nav(&p);
    let so = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{so}");
    assert!(so.contains("read 3 frames, 0 dropped, 0 damaged"), "{so}");
    let p = dir.path().join("gap.psns");
    std::fs::write(
        &p,
        stream_ix(PixelFormat::Mono12p, 16, 8, &[0, 1, 4, 5, 9], false, 0.0),
    )
    .unwrap();
    let out = nav(&p);
    let so = String::from_utf8_lossy(&out.stdout);
    let se = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{so}{se}");
    assert!(so.contains("dropped: frames 2..3 missing"), "{so}");
    assert!(so.contains("dropped: frames 6..8 missing"), "{so}");
    assert!(so.contains("read 5 frames, 5 dropped, 0 damaged"), "{so}");
    assert!(se.contains("dropped: 5 frames"), "{se}");
}

/// The header's black level is in payload DN; for MSB-aligned Mono16 nav_reader must shift it
/// like the values (it subtracted 16x too much). Superpixel (90, 45, 135, 0) codes 300, 500,
/// 500, 700 over a black level of 100 codes give DoLP = (600 - 200) / (600 + 200) = 0.5.
#[test]
fn nav_reader_black_level_msb_aligned() {
    common::require_numpy();
    let dir = tempfile::tempdir().unwrap();
    for msb in [false, true] {
        let hd = FileHeader {
            width: 16,
            height: 8,
            pixel_format: PixelFormat::Mono16,
            bits_valid: 12,
            msb_aligned: msb,
            ..Default::default()
        };
        let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
        let codes: Vec<u16> = (0..128)
            .map(|k| [300, 500, 500, 700][((k / 16) % 2) * 2 + k % 2])
            .collect();
        let m = FrameMeta {
            black_level: if msb { 100.0 * 16.0 } else { 100.0 },
            sun_camera: [0.0, -1.0, 0.0],
            ..Default::default()
        };
        wr.write_frame(&m, &codes).unwrap();
        let p = dir.path().join("black.psns");
        std::fs::write(&p, wr.finish().unwrap()).unwrap();
        let out = nav(&p);
        let so = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{so}");
        let dolp: f64 = so
            .split("dolp=")
            .nth(1)
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!((dolp - 0.5).abs() < 1e-4, "msb {msb}: {so}");
        // AoLP: 0 deg intensity 700 > 90 deg 300, 45 = 135: AoLP 0
        assert!(
            so.contains("aolp=0.0 ") || so.contains("aolp=180.0 "),
            "{so}"
        );
    }
}
