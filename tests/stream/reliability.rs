//! Reliability of `psns verify` / `psns extract` / `psns stream` (issue items 6, 7, 8, 13):
//! unfinished streams, concatenated streams, degraded mode for a damaged file header, refusing a
//! terminal, non-stream input, and the Python reader on a closed pipe.

use crate::common;
use common::{c_stream_reader, psns, python_cmd, require_numpy, stderr, Tmpfs};
use psns::sensor::packing::PixelFormat;
use psns::stream::{
    extract_frame, find_frame_with, verify, verify_with, FileHeader, FindOptions, FrameMeta,
    RecoverHint, StreamReader, StreamWriter, VerifyStatus, FLAG_LAST,
};
use std::io::Cursor;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Tiny frames for fast tests.
const SMALL: [&str; 4] = ["--width", "64", "--height", "48"];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A finished 3-frame stream file (count patched, LAST on frame 2) written by `psns stream`.
fn streamed(dir: &Path, name: &str, extra: &[&str]) -> std::path::PathBuf {
    let p = dir.join(name);
    let mut args = vec!["stream"];
    args.extend(SMALL);
    args.extend(extra);
    args.extend(["--frames", "3", "--out", s(&p)]);
    let o = psns(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

/// An in-memory stream of `n` frames; LAST on the final one if `last`.
fn make(fmt: PixelFormat, w: u32, h: u32, n: u64, last: bool) -> Vec<u8> {
    let hd = FileHeader {
        width: w,
        height: h,
        pixel_format: fmt,
        bits_valid: if fmt == PixelFormat::Mono8 { 8 } else { 12 },
        json: r#"{"test":1}"#.into(),
        ..Default::default()
    };
    let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
    for i in 0..n {
        let codes: Vec<u16> = (0..w * h)
            .map(|k| ((k as u64 * 2_654_435_761 + i * 97) % 4096) as u16)
            .collect();
        let m = FrameMeta {
            index: i,
            flags: if last && i + 1 == n { FLAG_LAST } else { 0 },
            exposure_us: 100.0 + i as f64,
            ..Default::default()
        };
        wr.write_frame(&m, &codes).unwrap();
    }
    wr.finish().unwrap()
}

// ---- A: unfinished and concatenated streams ----

#[test]
fn killed_producer_is_reported_unfinished_exit_3() {
    let d = tempfile::tempdir().unwrap();
    let k = d.path().join("k.psns");
    let mut child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .arg("stream")
        .args(SMALL)
        .args(["--frames", "1000000", "--out", s(&k)])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while std::fs::metadata(&k).map_or(0, |m| m.len()) < 4096 + 3 * 8192 {
        assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL: no chance to patch the count or flag a last frame
    child.wait().unwrap();
    // keep whole records only, so the test is about the missing end, not a truncated record
    let b = std::fs::read(&k).unwrap();
    let whole = 4096 + (b.len() - 4096) / 8192 * 8192;
    std::fs::write(&k, &b[..whole]).unwrap();
    let o = psns(&["verify", s(&k)]);
    assert_eq!(o.status.code(), Some(3), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("UNFINISHED"), "{}", stdout(&o));
    assert!(!stdout(&o).ends_with("clean\n"), "{}", stdout(&o));
    // the library says the same
    let rep = verify(Cursor::new(&b[..whole])).unwrap();
    assert_eq!(rep.status, VerifyStatus::Unfinished);
    assert!(rep.intact() && !rep.clean() && !rep.finished);
}

/// The end every reader reports for a stream file: `psns verify` (exit 3, the reason in the
/// report), the C reader's `check` (exit 1, the reason on stderr) and the numpy reader (`dump`'s
/// `aborted` line and `info`'s `aborted`).
fn assert_aborted_everywhere(p: &Path, reason: &str) {
    let o = psns(&["verify", s(p)]);
    assert_eq!(o.status.code(), Some(3), "{}{}", stdout(&o), stderr(&o));
    assert!(
        stdout(&o).contains("ABORTED") && stdout(&o).contains(reason),
        "{}",
        stdout(&o)
    );
    assert!(stderr(&o).contains(reason), "{}", stderr(&o));
    let o = psns(&["verify", "--json", s(p)]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["status"], "aborted");
    assert!(j["aborted"].as_str().unwrap().contains(reason), "{j}");
    let d = tempfile::tempdir().unwrap();
    let o = Command::new(c_stream_reader(d.path()))
        .args(["check", s(p)])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "C check: {}", stderr(&o));
    assert!(
        stderr(&o).contains("aborted by its producer") && stderr(&o).contains(reason),
        "C check: {}",
        stderr(&o)
    );
    require_numpy();
    let tool = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/psns_stream.py");
    let o = python_cmd().args([tool, "dump", s(p)]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let last = stdout(&o).lines().last().unwrap_or("").to_string();
    if !reason.starts_with("reason not recorded") {
        assert!(
            last.starts_with("aborted ") && last.contains(reason),
            "Python dump: {last}"
        );
    }
    let o = python_cmd().args([tool, "info", s(p)]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        j["aborted"].as_str().is_some_and(|r| r.contains(reason)),
        "Python info: {}",
        j["aborted"]
    );
}

/// A run that fails on bad input after writing frames used to leave a stream that verified
/// clean (the writer patched the frame count on its error path).
#[test]
fn stream_stopped_by_bad_input_reads_aborted() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("t.csv");
    std::fs::write(
        &t,
        "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.05,0,0,0\n0.1,NaN,0,0\n",
    )
    .unwrap();
    let out = d.path().join("t.psns");
    let o = psns(&[
        "stream",
        "--trajectory",
        s(&t),
        "--width",
        "64",
        "--height",
        "64",
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let why = "trajectory line 4: 'NaN' is not a finite number";
    assert!(stderr(&o).contains(why), "{}", stderr(&o));
    assert_aborted_everywhere(&out, why);
    let b = std::fs::read(&out).unwrap();
    let h = FileHeader::decode(&b).unwrap();
    assert!(h.aborted && h.frame_count == 0, "{h:?}");
    // the library, and the same stream through a pipe (no header mark: the end record says it)
    let rep = verify(Cursor::new(&b)).unwrap();
    assert_eq!(rep.status, VerifyStatus::Aborted, "{rep}");
    assert_eq!((rep.frames, rep.aborted.as_deref()), (2, Some(why)));
    let o = common::psns_stdin(
        &[
            "stream",
            "--width",
            "64",
            "--height",
            "64",
            "--trajectory",
            "-",
        ],
        &std::fs::read_to_string(&t).unwrap(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!FileHeader::decode(&o.stdout).unwrap().aborted);
    let rep = verify(Cursor::new(&o.stdout)).unwrap();
    assert_eq!(rep.status, VerifyStatus::Aborted, "{rep}");
    assert_eq!(rep.aborted.as_deref(), Some(why));
    let p = d.path().join("pipe.psns");
    std::fs::write(&p, &o.stdout).unwrap();
    assert_aborted_everywhere(&p, why);
}

/// A disk that fills mid-frame: the partial record is cut, the end record says why when it still
/// fits, and the header's mark says "aborted" when it does not; never a finished stream.
#[test]
fn stream_on_a_full_disk_reads_aborted() {
    // 64 x 64 Mono16: 4096-byte header, 12 288-byte records (three pages each); a 116 KiB tmpfs
    // holds 9 records and a page of the tenth, a 112 KiB one exactly 9 records
    for (kib, reason) in [
        (116, "writing stream frame 9: No space left on device"),
        (112, "reason not recorded"),
    ] {
        let fs = Tmpfs::new(kib);
        let out = fs.path().join("s.psns");
        let o = psns(&[
            "stream",
            "--width",
            "64",
            "--height",
            "64",
            "--frames",
            "100",
            "--out",
            s(&out),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("No space left on device"),
            "{}",
            stderr(&o)
        );
        let len = std::fs::metadata(&out).unwrap().len();
        assert_eq!(
            (len - 4096) % 12_288,
            if reason.starts_with("writing") {
                256
            } else {
                0
            }
        );
        assert_aborted_everywhere(&out, reason);
        let rep = verify(Cursor::new(std::fs::read(&out).unwrap())).unwrap();
        assert_eq!(
            (rep.status, rep.frames),
            (VerifyStatus::Aborted, 9),
            "{rep}"
        );
    }
}

/// SIGINT, SIGTERM and SIGHUP stop a run of `--frames N` between frames, mark it aborted, and
/// end psns by the same signal (a run without `--frames` is finished instead:
/// `recordings::ctrl_c_finishes_an_open_ended_stream_cleanly`).
#[test]
fn stream_stopped_by_a_signal_reads_aborted() {
    use std::os::unix::process::ExitStatusExt;
    let d = tempfile::tempdir().unwrap();
    for (sig, name) in [(15, "SIGTERM"), (2, "SIGINT"), (1, "SIGHUP")] {
        let out = d.path().join(format!("{name}.psns"));
        let child = Command::new(env!("CARGO_BIN_EXE_psns"))
            .args(["stream", "--width", "64", "--height", "64", "--rate", "20"])
            .args(["--frames", "1000000"])
            .args(["--out", s(&out)])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t = Instant::now();
        while std::fs::metadata(&out).map_or(0, |m| m.len()) < 4096 + 2 * 12_288 {
            assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
            std::thread::sleep(Duration::from_millis(10));
        }
        let st = Command::new("kill")
            .args([&format!("-{sig}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
        let o = common::wait_deadline(child, 30);
        assert_eq!(o.status.signal(), Some(sig), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("stopped by {name}")),
            "{}",
            stderr(&o)
        );
        assert_aborted_everywhere(&out, &format!("stopped by {name}"));
    }
}

#[test]
fn finished_streams_are_clean_to_a_file_and_through_a_pipe() {
    let d = tempfile::tempdir().unwrap();
    let f = streamed(d.path(), "a.psns", &[]);
    let o = psns(&["verify", s(&f)]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(stdout(&o).ends_with("clean\n"));
    // stdout: count 0, the LAST flag marks the end
    let mut args = vec!["stream"];
    args.extend(SMALL);
    args.extend(["--frames", "2"]);
    let o = psns(&args);
    assert!(o.status.success());
    let p = d.path().join("pipe.psns");
    std::fs::write(&p, &o.stdout).unwrap();
    assert_eq!(FileHeader::decode(&o.stdout).unwrap().frame_count, 0);
    let o = psns(&["verify", s(&p)]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    // library: LAST marks finished, no LAST and count 0 is unfinished
    assert!(
        verify(Cursor::new(make(PixelFormat::Mono8, 16, 8, 2, true)))
            .unwrap()
            .clean()
    );
    let rep = verify(Cursor::new(make(PixelFormat::Mono8, 16, 8, 2, false))).unwrap();
    assert_eq!(rep.status, VerifyStatus::Unfinished, "{rep}");
}

#[test]
fn concatenated_streams_are_not_clean_and_extract_names_the_copy() {
    let d = tempfile::tempdir().unwrap();
    let a = streamed(d.path(), "a.psns", &[]);
    let b = streamed(d.path(), "b.psns", &["--seed", "5"]);
    let c = d.path().join("c.psns");
    let mut bytes = std::fs::read(&a).unwrap();
    let second = bytes.len();
    bytes.extend(std::fs::read(&b).unwrap());
    std::fs::write(&c, &bytes).unwrap();
    let o = psns(&["verify", s(&c)]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    let out = stdout(&o);
    assert!(out.contains("streams: 2"), "{out}");
    assert!(out.contains(&format!("byte {second}")), "{out}");
    assert!(out.ends_with("NOT clean\n"), "{out}");
    let o = psns(&["verify", "--json", s(&c)]);
    assert!(
        stdout(&o).contains("\"status\": \"damaged\""),
        "{}",
        stdout(&o)
    );
    // extract says which copy it read
    let x = d.path().join("x");
    let o = psns(&["extract", s(&c), "--frame", "1", "--out", s(&x)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("frame 1 found in stream copy 1 of 2 (byte offset 12288)"),
        "{e}"
    );
    // a single stream gets no note
    let o = psns(&["extract", s(&a), "--frame", "1", "--out", s(&x)]);
    assert!(!stderr(&o).contains("copy"), "{}", stderr(&o));
}

// ---- D: non-stream input ----

#[test]
fn non_stream_input_is_bad_input_exit_2() {
    let d = tempfile::tempdir().unwrap();
    // a small PNG (shorter than a stream header) and a longer non-stream file
    let png = d.path().join("p.png");
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    b.extend([0u8; 200]);
    std::fs::write(&png, &b).unwrap();
    let big = d.path().join("big.bin");
    std::fs::write(&big, vec![7u8; 20_000]).unwrap();
    for (f, magic) in [(&png, "89 50 4e 47 0d 0a 1a 0a"), (&big, "07 07 07")] {
        for cmd in [
            vec!["verify", s(f)],
            vec!["extract", s(f), "--frame", "0", "--out", s(d.path())],
        ] {
            let o = psns(&cmd);
            assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", stderr(&o));
            let e = stderr(&o);
            assert!(
                e.contains("not a psns stream (magic ") && e.contains(magic),
                "{e}"
            );
            assert!(!e.contains("truncated"), "{e}");
        }
    }
    let empty = d.path().join("empty");
    std::fs::write(&empty, b"").unwrap();
    let o = psns(&["verify", s(&empty)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn python_dump_into_a_closed_pipe_ends_quietly() {
    require_numpy();
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("many.psns");
    let mut args = vec!["stream"];
    args.extend(SMALL);
    args.extend(["--frames", "300", "--out", s(&f)]);
    assert!(psns(&args).status.success());
    let py = python_cmd().get_program().to_owned();
    let tool = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/psns_stream.py");
    let o = Command::new("sh")
        .arg("-c")
        .arg("\"$0\" \"$1\" dump \"$2\" | head -n 2")
        .arg(&py)
        .arg(tool)
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 2);
    let e = stderr(&o);
    assert!(
        !e.contains("Traceback") && !e.contains("BrokenPipe"),
        "stderr: {e}"
    );
}

// ---- C: terminal ----

#[test]
fn stream_refuses_a_terminal_stdout() {
    let have_script = Command::new("script")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have_script {
        common::missing(
            "stream_refuses_a_terminal_stdout",
            "`script` (util-linux) is not installed, no tty to test with",
        );
        return;
    }
    let exe = env!("CARGO_BIN_EXE_psns");
    let t = Instant::now();
    let o = Command::new("script")
        .args([
            "-qec",
            &format!("{exe} stream --width 64 --height 48 --frames 1"),
            "/dev/null",
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(t.elapsed() < Duration::from_secs(60));
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(2), "{text}");
    assert!(
        text.contains("terminal") && text.contains("--out FILE"),
        "{text}"
    );
    assert!(
        !text.contains("PSNSRAW"),
        "frames were written to the terminal"
    );
}

// ---- B: damaged file header, degraded mode ----

#[test]
fn damaged_header_suggests_recover_and_recover_reads_every_frame() {
    let d = tempfile::tempdir().unwrap();
    let good = streamed(d.path(), "a.psns", &[]);
    let bytes = std::fs::read(&good).unwrap();
    let x0 = d.path().join("x0");
    let o = psns(&["extract", s(&good), "--frame", "2", "--out", s(&x0)]);
    assert!(o.status.success());
    let want_tiff = std::fs::read(x0.join("frame_2.tiff")).unwrap();
    // one byte wrong: magic, version, width, height, format, P, stride, count, JSON, CRC
    for pos in [1usize, 8, 20, 25, 28, 48, 57, 64, 300, 4093] {
        let mut b = bytes.clone();
        b[pos] ^= 0x5a;
        let f = d.path().join(format!("d{pos}.psns"));
        std::fs::write(&f, &b).unwrap();
        let o = psns(&["verify", s(&f)]);
        assert_eq!(o.status.code(), Some(1), "pos {pos}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("header damaged") && e.contains("--recover"),
            "pos {pos}: {e}"
        );
        let o = psns(&["verify", "--recover", s(&f)]);
        let out = stdout(&o);
        assert_eq!(o.status.code(), Some(1), "pos {pos}: {out}{}", stderr(&o));
        assert!(out.contains("DEGRADED MODE"), "pos {pos}: {out}");
        assert!(out.contains("64 x 48 Mono16"), "pos {pos}: {out}");
        assert!(
            out.contains("frames: 3 intact (index 0..2)"),
            "pos {pos}: {out}"
        );
        assert!(
            out.contains("corrupt: 0") && out.contains("truncated: 0"),
            "pos {pos}: {out}"
        );
        let x = d.path().join(format!("x{pos}"));
        let o = psns(&[
            "extract",
            "--recover",
            s(&f),
            "--frame",
            "2",
            "--out",
            s(&x),
        ]);
        assert!(o.status.success(), "pos {pos}: {}", stderr(&o));
        assert!(stderr(&o).contains("DEGRADED MODE"), "pos {pos}");
        assert_eq!(
            std::fs::read(x.join("frame_2.tiff")).unwrap(),
            want_tiff,
            "pos {pos}"
        );
    }
    // --recover on an intact stream changes nothing
    let o = psns(&["verify", "--recover", s(&good)]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    // geometry options need --recover
    let o = psns(&["verify", "--width", "64", s(&good)]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn recover_infers_geometry_or_asks_for_it() {
    let b = make(PixelFormat::Mono12p, 16, 8, 4, true);
    let x2 = extract_frame(Cursor::new(&b), 2).unwrap();
    let opts = |h| FindOptions {
        recover: Some(h),
        count_copies: false,
    };
    // the header's own CRC: nothing to infer beyond reading it
    let mut c = b.clone();
    c[4094] ^= 1;
    assert!(StreamReader::new(Cursor::new(&c)).is_err());
    let (r, rec) = StreamReader::new_recovering(Cursor::new(&c), &RecoverHint::default()).unwrap();
    assert!(rec.is_some());
    assert_eq!(r.header().pixel_format, PixelFormat::Mono12p);
    // the format's low byte: Mono12p and Mono12Packed have the same size -> ambiguous
    let mut c = b.clone();
    c[28] ^= 0xff;
    let e = verify_with(Cursor::new(&c), Some(&RecoverHint::default())).unwrap_err();
    assert!(e.to_string().contains("ambiguous"), "{e}");
    assert!(e.is_usage());
    let hint = RecoverHint {
        pixel_format: Some(PixelFormat::Mono12p),
        ..Default::default()
    };
    let x = find_frame_with(Cursor::new(&c), Some(2), opts(&hint)).unwrap();
    assert_eq!(x.codes, x2.codes);
    assert!(x.recovered.unwrap().geometry.contains("pixel format given"));
    // width and height both gone: two fields disagree -> the user gives one
    let mut c = b.clone();
    c[20] ^= 0x40;
    c[24] ^= 0x40;
    let e = verify_with(Cursor::new(&c), Some(&RecoverHint::default())).unwrap_err();
    assert!(
        e.to_string()
            .contains("give width, height and pixel format"),
        "{e}"
    );
    let hint = RecoverHint {
        width: Some(16),
        ..Default::default()
    };
    let rep = verify_with(Cursor::new(&c), Some(&hint)).unwrap();
    assert_eq!((rep.header.width, rep.header.height), (16, 8), "{rep}");
    assert_eq!(rep.frames, 4, "{rep}");
    assert_eq!(rep.status, VerifyStatus::Damaged);
    // a geometry that contradicts the frames found is refused
    let hint = RecoverHint {
        width: Some(32),
        height: Some(32),
        pixel_format: Some(PixelFormat::Mono16),
    };
    assert!(verify_with(Cursor::new(&c), Some(&hint)).is_err());
    // frame 0 damaged too: the stride comes from frames 1 and 2, frame 0 is reported corrupt
    let mut c = b.clone();
    c[100] ^= 1;
    c[4096 + 30] ^= 1;
    let rep = verify_with(Cursor::new(&c), Some(&RecoverHint::default())).unwrap();
    assert_eq!(rep.frames, 3, "{rep}");
    assert_eq!(rep.corrupt.len(), 1, "{rep}");
    assert_eq!(rep.corrupt[0].index, Some(0), "{rep}");
    // a single-frame stream (Mono8, 1 frame): the record runs to the end
    let one = make(PixelFormat::Mono8, 40, 30, 1, true);
    let mut c = one.clone();
    c[21] ^= 0x11;
    let rep = verify_with(Cursor::new(&c), Some(&RecoverHint::default())).unwrap();
    assert_eq!((rep.header.width, rep.header.height), (40, 30), "{rep}");
    assert_eq!(rep.frames, 1);
}

#[test]
fn python_reader_recovers_a_damaged_header() {
    require_numpy();
    let d = tempfile::tempdir().unwrap();
    let good = streamed(d.path(), "a.psns", &[]);
    let tool = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/psns_stream.py");
    let dump = |f: &Path, extra: &[&str]| {
        python_cmd()
            .arg(tool)
            .arg("dump")
            .args(extra)
            .arg(f)
            .output()
            .unwrap()
    };
    let want = stdout(&dump(&good, &[]));
    let want_frames: Vec<&str> = want.lines().skip(1).collect();
    assert_eq!(want_frames.len(), 3);
    let bytes = std::fs::read(&good).unwrap();
    for pos in [1usize, 20, 25, 28, 57, 300, 4093] {
        let mut b = bytes.clone();
        b[pos] ^= 0x5a;
        let f = d.path().join(format!("d{pos}.psns"));
        std::fs::write(&f, &b).unwrap();
        let o = dump(&f, &[]);
        assert_eq!(o.status.code(), Some(1), "pos {pos}");
        assert!(
            stderr(&o).contains("--recover"),
            "pos {pos}: {}",
            stderr(&o)
        );
        let o = dump(&f, &["--recover"]);
        assert!(o.status.success(), "pos {pos}: {}", stderr(&o));
        assert!(stderr(&o).contains("DEGRADED MODE"), "pos {pos}");
        let got = stdout(&o);
        assert!(
            got.starts_with("header 64 48 01100007 12 "),
            "pos {pos}: {got}"
        );
        assert_eq!(
            got.lines().skip(1).collect::<Vec<_>>(),
            want_frames,
            "pos {pos}"
        );
    }
}

// ---- memory: a header that declares huge frames ----

/// A valid header declaring 32768 x 16384 Mono16 frames (a 1 GiB payload, the largest allowed),
/// one frame header and 24 000 bytes of its payload: 28 KB on disk.
fn lying_stream() -> Vec<u8> {
    let h = FileHeader {
        width: 32_768,
        height: 16_384,
        pixel_format: PixelFormat::Mono16,
        bits_valid: 12,
        ..Default::default()
    };
    let mut b = h.encode().unwrap();
    b.extend_from_slice(&FrameMeta::default().encode(0));
    b.resize(b.len() + 24_000, 0);
    b
}

/// `verify`, `extract` and `demosaic` used to allocate the declared 1 GiB record before finding
/// that the file ends: under a 256 MiB address-space limit they died of a failed allocation.
/// The reader's buffer now grows with the bytes that arrive.
#[test]
fn a_header_declaring_huge_frames_costs_the_file_not_the_header() {
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("lying.psns");
    std::fs::write(&f, lying_stream()).unwrap();
    let out = d.path().join("out");
    let exe = env!("CARGO_BIN_EXE_psns");
    for (args, code, says) in [
        (
            vec!["verify", s(&f)],
            3,
            "cut short: the last record, frame 0",
        ),
        (
            vec!["extract", s(&f), "--frame", "0", "--out", s(&out)],
            2,
            "frame 0 is not in the stream",
        ),
        (
            vec!["demosaic", s(&f), "--out", s(&out)],
            2,
            "no intact frame",
        ),
    ] {
        let o = Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 262144; exec \"$@\"")
            .arg("sh")
            .arg(exe)
            .args(&args)
            .output()
            .unwrap();
        let text = format!("{}{}", stdout(&o), stderr(&o));
        assert_eq!(o.status.code(), Some(code), "{args:?}: {text}");
        assert!(text.contains(says), "{args:?}: {text}");
    }
    // the library reader on the bytes: a record cut short, no frame
    let rep = verify(Cursor::new(lying_stream())).unwrap();
    assert_eq!((rep.frames, rep.cut_short.is_some()), (0, true), "{rep}");
}
