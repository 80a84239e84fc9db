//! The Python (numpy) and C readers in tools/ return the same pixels and metadata as the Rust
//! reader; the golden stream in fixtures/stream/ is reproduced byte for byte.

use crate::common;
use psns::sensor::packing::{self, PixelFormat};
use psns::stream::*;
use sha2::{Digest, Sha256};
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::Command;

pub(crate) fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub(crate) fn stream(fmt: PixelFormat, w: u32, h: u32, n: u64, msb: bool) -> Vec<u8> {
    let ix: Vec<u64> = (0..n).collect();
    stream_ix(fmt, w, h, &ix, msb, 0.0)
}

/// A stream with the given frame indexes (a jump = dropped frames) and black level.
pub(crate) fn stream_ix(
    fmt: PixelFormat,
    w: u32,
    h: u32,
    ix: &[u64],
    msb: bool,
    black: f64,
) -> Vec<u8> {
    // (these codes are all even: the golden fixtures keep them; `large_cases` uses every bit)
    stream_with(fmt, w, h, ix, msb, black, &|k, i| {
        ((k * 37 + i * 1000 + k * k) % 4096) as u16
    })
}

/// A stream whose frame `i` has code `code(k, i)` at pixel k.
fn stream_with(
    fmt: PixelFormat,
    w: u32,
    h: u32,
    ix: &[u64],
    msb: bool,
    black: f64,
    code: &dyn Fn(u64, u64) -> u16,
) -> Vec<u8> {
    let hd = FileHeader {
        width: w,
        height: h,
        pixel_format: fmt,
        bits_valid: if fmt == PixelFormat::Mono8 { 8 } else { 12 },
        msb_aligned: msb,
        seed: 11,
        producer: "psns golden".into(),
        json: r#"{"golden":1}"#.into(),
        ..Default::default()
    };
    let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
    for &i in ix {
        let m = FrameMeta {
            index: i,
            exposure_start_ns: 1_718_000_000_000_000_000 + i as i64 * 100_000_000,
            exposure_end_ns: 1_718_000_000_001_000_000 + i as i64 * 100_000_000,
            exposure_us: 1000.0,
            gain_db: 0.1 * i as f64,
            black_level: black,
            sun_azimuth_deg: 123.456 + i as f64,
            sun_elevation_deg: 33.3,
            sun_camera: [0.3, -0.1, 0.948_683_298],
            attitude_wxyz: [0.5f64.sqrt(), 0.0, 0.0, 0.5f64.sqrt()],
            lat_deg: 30.5,
            lon_deg: 114.3,
            height_m: 25.0,
            saturated: [i as u32, 0, 1, 2],
            turbidity: 3.0,
            albedo: 0.1,
            // every other frame with a world's class fractions
            flags: if i % 2 == 1 { FLAG_CLASSES } else { 0 },
            class_fractions: match i % 2 {
                1 => [0.2, 0.3, 0.1, 0.25, 0.14, 0.01],
                _ => [0.0; 6],
            },
            ..Default::default()
        };
        let c: Vec<u16> = (0..(w * h) as u64).map(|k| code(k, i)).collect();
        wr.write_frame(&m, &c).unwrap();
    }
    wr.finish().unwrap()
}

/// Canonical lines from the Rust reader (same format as the tools' `dump`).
fn rust_dump(bytes: &[u8]) -> String {
    let mut rd = StreamReader::new(Cursor::new(bytes)).unwrap();
    let mut s = header_line(rd.header());
    while let Some(ev) = rd.next_event().unwrap() {
        let id = |i: Option<u64>| i.map_or("-".to_string(), |i| i.to_string());
        match ev {
            Event::Frame(f) => s += &frame_line(&f, rd.header()),
            Event::Gap { from, to } => s += &format!("gap {from}..{to}\n"),
            Event::Corrupt { index, offset, .. } => {
                s += &format!("corrupt {} {offset}\n", id(index))
            }
            Event::Truncated {
                index,
                offset,
                have,
                need,
            } => s += &format!("truncated {} {offset} {have} {need}\n", id(index)),
            Event::Skipped { offset, bytes } => s += &format!("skipped {offset} {bytes}\n"),
            Event::Restart(h) => s += &format!("restart\n{}", header_line(&h)),
            Event::Aborted {
                offset,
                frames,
                reason,
            } => s += &format!("aborted {offset} {frames} {reason}\n"),
        }
    }
    s
}

fn header_line(h: &FileHeader) -> String {
    let a = h.layout.angles_deg();
    format!(
        "header {} {} {:08x} {} {} {} {} {} {} {},{},{},{}{}\n",
        h.width,
        h.height,
        h.pixel_format.pfnc_code(),
        h.bits_valid,
        h.msb_aligned as u8,
        h.seed,
        h.frame_count,
        h.payload_size(),
        h.stride(),
        a[0],
        a[1],
        a[2],
        a[3],
        if h.aborted { " aborted" } else { "" }
    )
}

fn frame_line(f: &Frame, h: &FileHeader) -> String {
    let m = f.meta;
    let v = f.codes(h).unwrap();
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let f64s: Vec<String> = m
        .f64_fields()
        .iter()
        .map(|x| format!("{:016x}", x.to_bits()))
        .collect();
    let classes: Vec<String> = m
        .class_fractions
        .iter()
        .map(|x| format!("{:08x}", x.to_bits()))
        .collect();
    format!(
        "frame {} {} {} {} {} {} {} {},{},{},{} {:08x},{:08x},{} {} {:08x}\n",
        m.index,
        m.flags,
        f.payload_crc_ok as u8,
        m.exposure_start_ns,
        m.exposure_end_ns,
        m.host_time_ns,
        f64s.join(","),
        m.saturated[0],
        m.saturated[1],
        m.saturated[2],
        m.saturated[3],
        m.turbidity.to_bits(),
        m.albedo.to_bits(),
        classes.join(","),
        v.iter().map(|&x| x as u64).sum::<u64>(),
        crc32(&bytes)
    )
}

fn python(args: &[&str]) -> String {
    let out = common::python_cmd()
        .arg(root().join("tools/psns_stream.py"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn c_reader(dir: &Path) -> PathBuf {
    c_reader_with(dir, "psns_stream_c", &[])
}

/// The C reader built twice: as shipped (with the PCLMULQDQ CRC where the compiler and CPU have
/// it, and the SSE2/SSSE3 sum and unpacking) and with the portable C99 loops only (`-DPSNS_PORTABLE_CRC
/// -DPSNS_PORTABLE_SIMD`).
fn c_readers(dir: &Path) -> [PathBuf; 2] {
    [
        c_reader(dir),
        c_reader_with(
            dir,
            "psns_stream_c_portable",
            &["-DPSNS_PORTABLE_CRC", "-DPSNS_PORTABLE_SIMD"],
        ),
    ]
}

fn c_reader_with(dir: &Path, name: &str, flags: &[&str]) -> PathBuf {
    let exe = dir.join(name);
    let st = Command::new("cc")
        .args(["-std=c99", "-O2", "-Wall", "-Werror"])
        .args(flags)
        .arg("-o")
        .arg(&exe)
        .arg(root().join("tools/psns_stream.c"))
        .status()
        .expect("a C compiler (cc) is required");
    assert!(st.success());
    exe
}

fn cases() -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for fmt in PixelFormat::ALL {
        v.push((format!("{fmt}"), stream(fmt, 16, 8, 3, false)));
        v.push((format!("{fmt}-odd"), stream(fmt, 5, 3, 2, false)));
    }
    v.push(("msb".into(), stream(PixelFormat::Mono16, 16, 8, 2, true)));
    // damaged: frame 1 payload bit flip, frame 3 header bit flip, garbage before frame 4
    let mut b = stream(PixelFormat::Mono12p, 64, 32, 6, false);
    let stride = 4096; // 256 + 3072 bytes
    b[4096 + stride + 300] ^= 0x10;
    b[4096 + 3 * stride + 40] ^= 0x01;
    let tail = b.split_off(4096 + 4 * stride);
    b.extend_from_slice(b"garbage\x89PSNSxx");
    b.extend_from_slice(&tail);
    v.push(("damaged".into(), b));
    for (name, b) in event_cases() {
        v.push((name.into(), b));
    }
    v.extend(large_cases(333, 77));
    v
}

/// Frames whose payload is long enough for the C reader's two-halves CRC (>= 4096 bytes), an odd
/// pixel count, in every format: frame 1's payload damaged in its first half, frame 2's in its
/// last byte (the tail after the halves), frame 0 intact. Every reader must report crc_ok = 0
/// for frames 1 and 2 and the CRC of their (damaged) values as crc32fast computes it.
fn large_cases(w: u32, h: u32) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for fmt in PixelFormat::ALL {
        // codes that use all 12 bits (odd and even, every bit position)
        let hash = |k: u64, i: u64| ((k.wrapping_mul(0x9E37_79B9) ^ (i << 20)) >> 9) as u16 & 0xFFF;
        let mut b = stream_with(fmt, w, h, &[0, 1, 2], false, 0.0, &hash);
        let p = packing::payload_size(fmt, w as usize, h as usize);
        assert!(p >= 4096 || w * h < 4096, "{fmt}: payload {p}");
        let stride = stride_for(p as u64) as usize;
        let payload = |k: usize| 4096 + k * stride + FRAME_HEADER_SIZE;
        b[payload(1) + p / 3] ^= 0x20;
        b[payload(2) + p - 1] ^= 0x01;
        v.push((format!("{fmt}-{w}x{h}-damaged"), b));
    }
    v
}

/// Streams exercising gaps, out-of-order indexes, producer restarts (at a record boundary and
/// inside a record) and a resynchronisation whose magic straddles a 64 KiB read.
fn event_cases() -> Vec<(&'static str, Vec<u8>)> {
    let mut v = Vec::new();
    // dropped frames 2, 3 and 6..8
    v.push((
        "gap",
        stream_ix(PixelFormat::Mono12p, 16, 8, &[0, 1, 4, 5, 9], false, 0.0),
    ));
    // record 1 repeated, then record 0 again after 2: both rejected (index not increasing)
    let s = stream(PixelFormat::Mono12p, 16, 8, 4, false);
    let rec = |i: usize| s[4096 + i * 4096..4096 + (i + 1) * 4096].to_vec();
    let mut b = s[..4096].to_vec();
    for r in [rec(0), rec(1), rec(1), rec(2), rec(0), rec(3)] {
        b.extend_from_slice(&r);
    }
    v.push(("backwards", b));
    // producer restart at a record boundary, Mono16 -> Mono8 of another size; indexes restart
    let mut b = stream(PixelFormat::Mono16, 16, 8, 3, false);
    b.extend_from_slice(&stream_ix(
        PixelFormat::Mono8,
        24,
        6,
        &[0, 1, 3],
        false,
        0.0,
    ));
    v.push(("restart", b));
    // producer died inside record 2 (in its header, its payload, its pad) and restarted
    for (name, cut) in [
        ("restart-in-header", 100),
        ("restart-in-payload", 256 + 100),
        ("restart-in-pad", 256 + 256 + 10),
    ] {
        let mut b = stream(PixelFormat::Mono16, 16, 8, 3, false);
        b.truncate(4096 + 2 * 4096 + cut);
        b.extend_from_slice(&stream_ix(
            PixelFormat::Mono8,
            24,
            6,
            &[5, 6, 8],
            false,
            0.0,
        ));
        v.push((name, b));
    }
    // garbage from record 2 on, record 2's magic 4 bytes before a 64 KiB boundary of the
    // reader's reads (4096 + 65536 - 4): Python used to skip it
    let s = stream(PixelFormat::Mono12p, 16, 8, 20, false);
    let at = 4096 + 65536 - 4;
    let mut b = s[..4096 + 2 * 4096].to_vec();
    while b.len() < at {
        b.push((b.len() * 7 % 251) as u8);
    }
    b.extend_from_slice(&s[4096 + 2 * 4096..]);
    v.push(("straddle", b));
    // EOF inside a record and a few stray bytes at the end
    let mut b = stream(PixelFormat::Mono8, 16, 8, 3, false);
    b.truncate(b.len() - 4000);
    v.push(("truncated", b));
    let mut b = stream(PixelFormat::Mono8, 16, 8, 2, false);
    b.extend_from_slice(b"\x89PS");
    v.push(("stray-tail", b));
    // producers that stopped on a failure: an end record after the last frame (a pipe), also
    // with the header's mark (a file), one after damage (found by resynchronisation), one whose
    // CRC fails (damage), one cut short (truncated), and the header's mark alone
    let aborted = |n: u64, reason: &str| {
        let mut b = stream(PixelFormat::Mono12p, 16, 8, n, false);
        b.extend_from_slice(&EndRecord::aborted(n, reason).encode());
        b
    };
    v.push((
        "aborted",
        aborted(2, "trajectory line 4: 'NaN' is not a finite number"),
    ));
    let mut b = aborted(
        3,
        "writing stream frame 3: No space left on device (os error 28)",
    );
    mark_aborted(&mut b);
    v.push(("aborted-marked", b));
    let mut b = aborted(2, "stopped by SIGTERM — ünïcode");
    b.splice(4096 + 4096 + 30..4096 + 4096 + 30, *b"garbage");
    v.push(("aborted-after-damage", b));
    let mut b = aborted(1, &"x".repeat(400));
    let n = b.len();
    b[n - 100] ^= 1;
    v.push(("aborted-bad-crc", b));
    let mut b = aborted(1, "cut");
    b.truncate(b.len() - 10);
    v.push(("aborted-cut", b));
    let mut b = stream(PixelFormat::Mono8, 16, 8, 2, false);
    mark_aborted(&mut b);
    v.push(("aborted-header-only", b));
    v
}

/// Sets the file header's aborted mark (offset 46) and its CRC.
fn mark_aborted(b: &mut [u8]) {
    b[46] = 1;
    let c = crc32(&b[..4092]);
    b[4092..4096].copy_from_slice(&c.to_le_bytes());
}

#[test]
fn c_reader_matches_rust() {
    let dir = tempfile::tempdir().unwrap();
    for exe in c_readers(dir.path()) {
        matches_rust(&exe, dir.path());
    }
}

fn matches_rust(exe: &Path, dir: &Path) {
    for (name, bytes) in cases() {
        let p = dir.join(format!("{name}.psns"));
        std::fs::write(&p, &bytes).unwrap();
        let out = Command::new(exe).arg("dump").arg(&p).output().unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let want = rust_dump(&bytes);
        assert_eq!(String::from_utf8(out.stdout).unwrap(), want, "{name}");
        check_matches_dump(exe, &p, &want, &name);
        // frame dump equals Rust's codes
        let raw = dir.join("f.raw");
        let st = Command::new(exe)
            .arg("frame")
            .arg(&p)
            .arg("0")
            .arg(&raw)
            .status()
            .unwrap();
        assert!(st.success());
        let x = extract_frame(Cursor::new(&bytes), 0).unwrap();
        let want: Vec<u8> = x.codes.iter().flat_map(|c| c.to_le_bytes()).collect();
        assert_eq!(std::fs::read(&raw).unwrap(), want, "{name}");
    }
}

/// `check` (the consumer's mode): one `frame INDEX SUM` line per frame whose payload CRC holds,
/// with the sum of its values as the Rust reader unpacks them, and exit status 1 exactly when
/// the Rust reader reports damage or loss (a failed payload CRC, a gap, a corrupt, truncated or
/// skipped record); `want` is the Rust reader's `dump`.
fn check_matches_dump(exe: &Path, p: &Path, want: &str, name: &str) {
    let out = Command::new(exe).arg("check").arg(p).output().unwrap();
    let mut lines = String::new();
    let (mut damaged, mut restarted) = (false, false);
    for l in want.lines() {
        let f: Vec<&str> = l.split(' ').collect();
        match f[0] {
            "frame" if f[3] == "1" => lines += &format!("frame {} {}\n", f[1], f[f.len() - 2]),
            "frame" => damaged = true,
            "gap" | "corrupt" | "truncated" | "skipped" | "aborted" => damaged = true,
            "header" if l.ends_with(" aborted") => damaged = true,
            "restart" => restarted = true,
            _ => {}
        }
    }
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        lines,
        "check: {name}"
    );
    assert_eq!(
        out.status.code(),
        Some(damaged as i32),
        "check status: {name}"
    );
    // a restart is reported on stderr, but is not damage
    let quiet = !damaged && !restarted;
    assert_eq!(out.stderr.is_empty(), quiet, "check reports: {name}");
}

/// The C reader's CRC-32 (slicing by 16, long buffers in two halves joined by crc32_combine)
/// equals crc32fast's at every length around its thresholds, on random bytes, and a flipped bit
/// anywhere changes it as it changes crc32fast's.
#[test]
fn c_reader_crc_equals_crc32fast() {
    let dir = tempfile::tempdir().unwrap();
    for exe in c_readers(dir.path()) {
        crc_equals_crc32fast(&exe, dir.path());
    }
}

fn crc_equals_crc32fast(exe: &Path, dir: &Path) {
    let name = exe.file_name().unwrap().to_string_lossy().to_string();
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let bytes: Vec<u8> = (0..10_027_008 + 19)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 32) as u8
        })
        .collect();
    let mut lens: Vec<usize> = (0..=40).collect();
    lens.extend([
        255, 256, 4095, 4096, 4097, 4111, 4112, 4113, 4127, 4128, 8191, 65_537,
    ]);
    lens.extend([
        (1 << 20) - 1,
        1 << 20,
        (1 << 20) + 17,
        3 * (1 << 20) + 5,
        bytes.len(),
    ]);
    let crc_of = |data: &[u8]| {
        let p = dir.join("crc.bin");
        std::fs::write(&p, data).unwrap();
        let out = Command::new(exe).arg("crc").arg(&p).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    for n in lens {
        assert_eq!(
            crc_of(&bytes[..n]),
            format!("{:08x}", crc32(&bytes[..n])),
            "{name}: length {n}"
        );
    }
    assert_eq!(crc_of(b"123456789"), "cbf43926");
    // one flipped bit in the first half, the second half and the tail of a 100 003-byte buffer
    for at in [0, 17, 50_000, 50_001, 99_990, 100_002] {
        let mut b = bytes[..100_003].to_vec();
        b[at] ^= 0x80;
        let got = crc_of(&b);
        assert_eq!(got, format!("{:08x}", crc32(&b)), "{name}: flip at {at}");
        assert_ne!(
            got,
            format!("{:08x}", crc32(&bytes[..100_003])),
            "{name}: flip at {at}"
        );
    }
    // from stdin, read in pieces
    let mut child = Command::new(exe)
        .args(["crc", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        for part in bytes[..3_000_001].chunks(77_777) {
            stdin.write_all(part).unwrap();
        }
    }
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().trim(),
        format!("{:08x}", crc32(&bytes[..3_000_001]))
    );
}

/// Full-size frames (2448 x 2048) in every format, one damaged in the middle of its payload:
/// the C reader prints the Rust reader's lines (payload CRC, pixel sum, CRC of the values), and
/// its `check` the sums of the intact frames.
#[test]
fn c_reader_full_size_frames_match_rust() {
    let dir = tempfile::tempdir().unwrap();
    let exes = c_readers(dir.path());
    for (name, bytes) in large_cases(2448, 2048) {
        let p = dir.path().join("full.psns");
        std::fs::write(&p, &bytes).unwrap();
        let want = rust_dump(&bytes);
        let bad: Vec<&str> = want
            .lines()
            .filter(|l| l.starts_with("frame ") && l.split(' ').nth(3) == Some("0"))
            .map(|l| l.split(' ').nth(1).unwrap())
            .collect();
        assert_eq!(bad, ["1", "2"], "{name}: payload CRC failures");
        for exe in &exes {
            let out = Command::new(exe).arg("dump").arg(&p).output().unwrap();
            assert!(out.status.success(), "{name}");
            assert_eq!(
                String::from_utf8(out.stdout).unwrap(),
                want,
                "{exe:?}: {name}"
            );
            check_matches_dump(exe, &p, &want, &name);
        }
    }
}

#[test]
fn python_reader_matches_rust() {
    common::require_numpy();
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in cases() {
        let p = dir.path().join(format!("{name}.psns"));
        std::fs::write(&p, &bytes).unwrap();
        let got = python(&["dump", p.to_str().unwrap()]);
        assert_eq!(got, rust_dump(&bytes), "{name}");
    }
}

#[test]
fn python_memmap_full_size_mono16() {
    common::require_numpy();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("full.psns");
    let hd = FileHeader::default();
    let mut w = FileStreamWriter::create(&p, &hd).unwrap();
    let n = 2448 * 2048;
    let codes: Vec<u16> = (0..n).map(|k| ((k * 7 + k / 2448) % 4096) as u16).collect();
    for i in 0..2 {
        let m = FrameMeta {
            index: i,
            ..Default::default()
        };
        w.write_frame(&m, &codes).unwrap();
    }
    assert_eq!(w.finish().unwrap(), 2);
    assert_eq!(std::fs::metadata(&p).unwrap().len(), 4096 + 2 * 10_031_104);
    let script = format!(
        "import sys, zlib; sys.path.insert(0, {:?}); import psns_stream as ps\n\
         h, fr = ps.open_memmap({:?})\n\
         assert fr.shape == (2,) and fr.dtype.itemsize == 10031104\n\
         a = fr[1]['payload']\n\
         assert a.shape == (2048, 2448) and a.dtype.str == '<u2'\n\
         assert zlib.crc32(fr[1]['payload'].tobytes()) == int(fr[1]['payload_crc'])\n\
         print(int(a.sum(dtype='u8')), int(a[2047, 2447]), int(fr['index'][1]), h['frame_count'])\n",
        root().join("tools").to_str().unwrap(),
        p.to_str().unwrap()
    );
    let out = common::python_cmd().args(["-c", &script]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sum: u64 = codes.iter().map(|&c| c as u64).sum();
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().trim(),
        format!("{sum} {} 1 2", codes[n - 1])
    );
}

#[test]
fn golden_stream_fixture() {
    let bytes = stream(PixelFormat::Mono12p, 16, 8, 3, false);
    let dir = root().join("fixtures/stream");
    let file = dir.join("golden-mono12p-16x8x3.psns");
    let hash = format!("{:x}", Sha256::digest(&bytes));
    if std::env::var_os("PSNS_BLESS").is_some() {
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(&file, &bytes).unwrap();
        std::fs::write(
            dir.join("golden-mono12p-16x8x3.sha256"),
            format!("{hash}\n"),
        )
        .unwrap();
    }
    let want = std::fs::read(&file).expect("fixture (regenerate with PSNS_BLESS=1)");
    let want_hash = std::fs::read_to_string(dir.join("golden-mono12p-16x8x3.sha256")).unwrap();
    assert_eq!(hash, want_hash.trim());
    assert_eq!(bytes, want);
    let rep = verify(Cursor::new(&want)).unwrap();
    assert!(rep.intact() && rep.frames == 3, "{rep}");
}

/// A stream whose file header is `base` with fields patched (and its CRC recomputed, so only the
/// field checks can reject it), followed by one record with a valid header and payload CRC sized
/// by the patched payload/stride fields (capped), so a reader that accepts the header goes on to
/// unpack a frame.
fn crafted(patch: &dyn Fn(&mut [u8])) -> Vec<u8> {
    let base = FileHeader {
        width: 16,
        height: 8,
        pixel_format: PixelFormat::Mono16,
        bits_valid: 12,
        ..Default::default()
    };
    let mut h = base.encode().unwrap();
    patch(&mut h);
    let c = crc32(&h[..4092]);
    h[4092..].copy_from_slice(&c.to_le_bytes());
    let p = u64::from_le_bytes(h[48..56].try_into().unwrap()).min(1 << 20) as usize;
    let stride = u64::from_le_bytes(h[56..64].try_into().unwrap()).min(1 << 21) as usize;
    let payload = vec![0x5au8; p];
    let mut b = h;
    b.extend_from_slice(&FrameMeta::default().encode(crc32(&payload)));
    b.extend_from_slice(&payload);
    b.resize(4096 + stride.max(256 + p), 0);
    b
}

fn set(b: &mut [u8], off: usize, v: &[u8]) {
    b[off..off + v.len()].copy_from_slice(v);
}

fn set_sizes(b: &mut [u8], p: u64) {
    set(b, 48, &p.to_le_bytes());
    set(b, 56, &stride_for(p).to_le_bytes());
}

/// Headers with a valid CRC but fields Rust's `FileHeader::validate` rejects. The C reader used
/// to crash on the first (w·h·3 wraps in uint64_t to a 13-byte payload) and accept the others
/// (negative shift for 17 MSB-aligned bits, ...); Python accepted most of them.
fn crafted_cases() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        (
            "wrapping size",
            crafted(&|b| {
                set(b, 20, &3_062_868_337u32.to_le_bytes());
                set(b, 24, &2_007_567_422u32.to_le_bytes());
                set(b, 28, &0x010C_0047u32.to_le_bytes());
                set_sizes(b, 13);
            }),
        ),
        (
            "width 70000",
            crafted(&|b| {
                set(b, 20, &70_000u32.to_le_bytes());
                set(b, 24, &1u32.to_le_bytes());
                set_sizes(b, 140_000);
            }),
        ),
        (
            "width 0",
            crafted(&|b| {
                set(b, 20, &0u32.to_le_bytes());
                set_sizes(b, 0);
            }),
        ),
        (
            "MSB 17 bits",
            crafted(&|b| {
                set(b, 32, &17u16.to_le_bytes());
                set(b, 34, &1u16.to_le_bytes());
            }),
        ),
        (
            "MSB 0 bits",
            crafted(&|b| {
                set(b, 32, &0u16.to_le_bytes());
                set(b, 34, &1u16.to_le_bytes());
            }),
        ),
        ("alignment 2", crafted(&|b| set(b, 34, &2u16.to_le_bytes()))),
        (
            "MSB Mono12p",
            crafted(&|b| {
                set(b, 28, &0x010C_0047u32.to_le_bytes());
                set(b, 34, &1u16.to_le_bytes());
                set_sizes(b, 192);
            }),
        ),
        (
            "Mono12p 13 bits",
            crafted(&|b| {
                set(b, 28, &0x010C_0047u32.to_le_bytes());
                set(b, 32, &13u16.to_le_bytes());
                set_sizes(b, 192);
            }),
        ),
        (
            "Mono8 12 bits",
            crafted(&|b| {
                set(b, 28, &0x0108_0001u32.to_le_bytes());
                set_sizes(b, 128);
            }),
        ),
        (
            "angle sense 0",
            crafted(&|b| set(b, 44, &0i16.to_le_bytes())),
        ),
        (
            "angles repeated",
            crafted(&|b| set(b, 36, &45i16.to_le_bytes())),
        ),
        (
            "payload 1 GiB + 2",
            crafted(&|b| {
                set(b, 20, &32_769u32.to_le_bytes());
                set(b, 24, &16_384u32.to_le_bytes());
                set_sizes(b, 2 * 32_769 * 16_384);
            }),
        ),
        (
            "stride off",
            crafted(&|b| set(b, 56, &8192u64.to_le_bytes())),
        ),
        (
            "end status 2",
            crafted(&|b| set(b, 46, &2u16.to_le_bytes())),
        ),
    ]
}

#[test]
fn crafted_headers_rejected_by_all_readers() {
    let dir = tempfile::tempdir().unwrap();
    let exe = c_reader(dir.path());
    common::require_numpy();
    // the unpatched header is accepted by all three (the cases differ only in the patch)
    let ok = crafted(&|_| {});
    assert!(StreamReader::new(Cursor::new(&ok)).is_ok());
    for (name, bytes) in std::iter::once(("unpatched", ok)).chain(crafted_cases()) {
        let good = name == "unpatched";
        assert_eq!(
            StreamReader::new(Cursor::new(&bytes)).is_ok(),
            good,
            "Rust: {name}"
        );
        let p = dir.path().join("crafted.psns");
        std::fs::write(&p, &bytes).unwrap();
        let out = Command::new(&exe).arg("dump").arg(&p).output().unwrap();
        let code = out.status.code();
        assert_eq!(
            code,
            Some(if good { 0 } else { 1 }),
            "C: {name}: status {:?} (None = killed by a signal) {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        if !good {
            assert!(out.stdout.is_empty(), "C printed for {name}");
        }
        // every command of the numpy reader: a message, never a traceback
        for cmd in ["dump", "info", "mmdump"] {
            let out = common::python_cmd()
                .arg(root().join("tools/psns_stream.py"))
                .arg(cmd)
                .arg(&p)
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(
                out.status.code(),
                Some(if good { 0 } else { 1 }),
                "Python {cmd}: {name}: {err}"
            );
            assert!(!err.contains("Traceback"), "Python {cmd}: {name}: {err}");
        }
        // the same header after a valid stream is a restart only if it is valid: otherwise
        // the readers skip it as damage (no restart line), like Rust
        if !good {
            let mut s = stream(PixelFormat::Mono16, 16, 8, 2, false);
            s.extend_from_slice(&bytes);
            let want = rust_dump(&s);
            assert!(!want.contains("restart"), "{name}");
            let p = dir.path().join("crafted-restart.psns");
            std::fs::write(&p, &s).unwrap();
            let out = Command::new(&exe).arg("dump").arg(&p).output().unwrap();
            assert!(
                out.status.success(),
                "C: {name} as restart: {:?}",
                out.status
            );
            assert_eq!(String::from_utf8(out.stdout).unwrap(), want, "C: {name}");
            {
                assert_eq!(
                    python(&["dump", p.to_str().unwrap()]),
                    want,
                    "Python: {name}"
                );
            }
        }
    }
}

/// Ctrl-C while the numpy reader waits for a pipe (Ctrl-C's default restored, should the run
/// ignore SIGINT), and a missing file: a message or nothing, never a traceback.
#[test]
fn python_reader_ends_quietly_on_ctrl_c_and_missing_files() {
    common::require_numpy();
    let tool = root().join("tools/psns_stream.py");
    for args in [vec!["dump", "-"], vec!["info", "/nonexistent.psns"]] {
        let mut child = common::sigint_disposition(&mut common::python_cmd(), libc::SIG_DFL)
            .arg(&tool)
            .args(&args)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // let the interpreter start and block reading the pipe, then interrupt it
        std::thread::sleep(std::time::Duration::from_millis(1500));
        let _ = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status();
        let stdin = child.stdin.take();
        let out = common::wait_deadline(child, 30);
        drop(stdin);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("Traceback"), "{args:?}: {err}");
        if args[0] == "dump" {
            assert_eq!(out.status.code(), Some(130), "{args:?}: {err}");
        } else {
            assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
            assert!(err.contains("No such file"), "{err}");
        }
    }
}

const GOLDEN: [(&str, PixelFormat, bool); 5] = [
    ("golden-mono12p-16x8x3", PixelFormat::Mono12p, false),
    ("golden-mono8-16x8x3", PixelFormat::Mono8, false),
    (
        "golden-mono12packed-16x8x3",
        PixelFormat::Mono12Packed,
        false,
    ),
    ("golden-mono16-16x8x3", PixelFormat::Mono16, false),
    ("golden-mono16msb-16x8x3", PixelFormat::Mono16, true),
];

/// Every golden stream is regenerated byte for byte by the writer (PSNS_BLESS=1 rewrites them)
/// and is < 20 KB.
#[test]
fn golden_streams_every_format() {
    let dir = root().join("fixtures/stream");
    for (name, fmt, msb) in GOLDEN {
        let bytes = stream(fmt, 16, 8, 3, msb);
        let file = dir.join(format!("{name}.psns"));
        let sha = dir.join(format!("{name}.sha256"));
        let hash = format!("{:x}", Sha256::digest(&bytes));
        if std::env::var_os("PSNS_BLESS").is_some() {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&file, &bytes).unwrap();
            std::fs::write(&sha, format!("{hash}\n")).unwrap();
        }
        let want = std::fs::read(&file).expect("fixture (regenerate with PSNS_BLESS=1)");
        assert_eq!(
            hash,
            std::fs::read_to_string(&sha).unwrap().trim(),
            "{name}"
        );
        assert_eq!(bytes, want, "{name}");
        assert!(want.len() < 20_000, "{name}: {} bytes", want.len());
        let rep = verify(Cursor::new(&want)).unwrap();
        assert!(rep.intact() && rep.frames == 3, "{name}: {rep}");
    }
}

/// The C reader and numpy (sequential reader and memmap) read the checked-in golden files and
/// print the Rust reader's canonical lines.
#[test]
fn golden_streams_read_by_c_and_numpy() {
    let dir = tempfile::tempdir().unwrap();
    let exe = c_reader(dir.path());
    common::require_numpy();
    for (name, _, _) in GOLDEN {
        let file = root().join(format!("fixtures/stream/{name}.psns"));
        let bytes = std::fs::read(&file).unwrap();
        let want = rust_dump(&bytes);
        assert_eq!(want.lines().filter(|l| l.starts_with("frame ")).count(), 3);
        let out = Command::new(&exe).arg("dump").arg(&file).output().unwrap();
        assert!(out.status.success(), "{name}");
        assert_eq!(String::from_utf8(out.stdout).unwrap(), want, "C: {name}");
        {
            let f = file.to_str().unwrap();
            assert_eq!(python(&["dump", f]), want, "Python: {name}");
            assert_eq!(python(&["mmdump", f]), want, "numpy memmap: {name}");
        }
    }
}

/// Without numpy the Python readers say what is missing, not a traceback (numpy is hidden from
/// the interpreter to test this wherever it is installed).
#[test]
fn python_readers_without_numpy_say_so() {
    for tool in ["psns_stream.py", "nav_reader.py"] {
        let path = root().join("tools").join(tool);
        let code = format!(
            "import sys; sys.modules['numpy'] = None; sys.argv = ['{tool}', 'dump', 'x']; \
             exec(compile(open(r'{}').read(), '{tool}', 'exec'))",
            path.display()
        );
        let o = common::python_cmd().args(["-c", &code]).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{tool}: {e}");
        assert!(
            e.contains("needs numpy") && !e.contains("Traceback"),
            "{tool}: {e}"
        );
    }
}
