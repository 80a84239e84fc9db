//! End-to-end tests of `psns stream` (hardware in the loop): determinism across runs and outputs
//! (file, FIFO, stdout), trajectories from files and stdin, bad trajectory lines, early-closing and
//! slow readers, pacing, flags, the moving sun, and `psns verify` on what was written.

use crate::common;
use common::{mkfifo, wait_deadline};

use psns::stream::{
    Event, FileHeader, Frame, StreamReader, FLAG_GROUND_IN_VIEW, FLAG_LAST, FLAG_SKY_INVALID,
    FLAG_SUN_IN_VIEW,
};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A small camera with the default field of view (pitch scaled up); f/16 and 20 µs keep the big
/// pixels out of saturation (mean code ≈ 520 of 4095).
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

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_psns")
}

fn stream_cmd(extra: &[&str]) -> Command {
    let mut c = Command::new(exe());
    c.arg("stream").args(SMALL).args(extra);
    c
}

fn run(extra: &[&str]) -> Output {
    stream_cmd(extra).output().expect("run psns")
}

fn run_stdin(extra: &[&str], input: &str) -> Output {
    let mut child = stream_cmd(extra)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    child.wait_with_output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// All frames of a stream (panics on damage; an end record of an aborted stream may follow).
fn frames(bytes: &[u8]) -> (FileHeader, Vec<Frame>) {
    let mut r = StreamReader::new(bytes).unwrap();
    let h = r.header().clone();
    let mut out = Vec::new();
    while let Some(e) = r.next_event().unwrap() {
        match e {
            Event::Frame(f) => {
                assert!(f.payload_crc_ok, "frame {} payload CRC", f.meta.index);
                out.push(f)
            }
            Event::Aborted { frames, .. } => assert_eq!(frames, out.len() as u64),
            other => panic!("unexpected {other:?}"),
        }
    }
    (h, out)
}

fn verify(path: &Path) -> Output {
    Command::new(exe())
        .args(["verify", s(path)])
        .output()
        .unwrap()
}

const EULER: &str =
    "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.05,10,5,-3\n0.1,20,10,-6\n0.15,30,15,-9\n";

#[test]
fn same_options_give_identical_bytes_and_stdout_equals_file() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("a.psns"), d.path().join("b.psns"));
    for p in [&a, &b] {
        let o = run(&["--frames", "4", "--out", s(p)]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let (ba, bb) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert_eq!(ba, bb);
    let (h, f) = frames(&ba);
    assert_eq!(h.frame_count, 4);
    assert_eq!(f.len(), 4);
    // the turning camera really turns: payloads differ
    assert_ne!(f[0].payload, f[3].payload);
    // stdout: the same except the patched frame count (64..72) and the header CRC
    let o = run(&["--frames", "4"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(o.stdout.len(), ba.len());
    assert_eq!(o.stdout[..64], ba[..64]);
    assert_eq!(o.stdout[72..4092], ba[72..4092]);
    assert_eq!(o.stdout[4096..], ba[4096..]);
    assert_eq!(u64::from_le_bytes(o.stdout[64..72].try_into().unwrap()), 0);
    // a different seed changes the frames
    let o2 = run(&["--frames", "4", "--seed", "2"]);
    assert_ne!(o2.stdout[4096..], o.stdout[4096..]);
}

/// Pinning the render threads to CPUs (the default) or not (`--no-pin`), with 1, 2 or 3 workers
/// (more than this machine's cores, round robin), gives the same bytes; so does `--exact`.
#[test]
fn pinned_or_not_the_bytes_are_the_same() {
    let d = tempfile::tempdir().unwrap();
    for exact in [false, true] {
        let mut want: Option<Vec<u8>> = None;
        for threads in ["1", "2", "3"] {
            for pin in [true, false] {
                let p = d.path().join("s.psns");
                let mut c = stream_cmd(&["--frames", "3", "--out", s(&p)]);
                c.env("RAYON_NUM_THREADS", threads);
                if !pin {
                    c.arg("--no-pin");
                }
                if exact {
                    c.arg("--exact");
                }
                let o = c.output().unwrap();
                assert!(o.status.success(), "{}", stderr(&o));
                let b = std::fs::read(&p).unwrap();
                match &want {
                    None => want = Some(b),
                    Some(w) => assert!(
                        w == &b,
                        "exact {exact}, {threads} threads, pinned {pin}: bytes differ"
                    ),
                }
            }
        }
    }
}

#[test]
fn file_and_fifo_are_identical_except_the_count() {
    let d = tempfile::tempdir().unwrap();
    let (file, fifo) = (d.path().join("a.psns"), d.path().join("f.fifo"));
    let o = run(&["--frames", "6", "--out", s(&file)]);
    assert!(o.status.success(), "{}", stderr(&o));
    mkfifo(&fifo);
    let child = stream_cmd(&["--frames", "6", "--out", s(&fifo)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut got = Vec::new();
    std::fs::File::open(&fifo)
        .unwrap()
        .read_to_end(&mut got)
        .unwrap();
    let o = wait_deadline(child, 60);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = std::fs::read(&file).unwrap();
    assert_eq!(got.len(), want.len());
    let differ: Vec<usize> = (0..want.len()).filter(|&i| got[i] != want[i]).collect();
    assert!(
        differ
            .iter()
            .all(|&i| (64..72).contains(&i) || (4092..4096).contains(&i)),
        "bytes differ at {:?}",
        &differ[..differ.len().min(10)]
    );
    assert_eq!(u64::from_le_bytes(got[64..72].try_into().unwrap()), 0);
    assert_eq!(u64::from_le_bytes(want[64..72].try_into().unwrap()), 6);
}

#[test]
fn slow_reader_on_a_fifo_gets_every_frame_in_order() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("f.fifo");
    mkfifo(&fifo);
    let child = stream_cmd(&["--frames", "30", "--out", s(&fifo)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut r = StreamReader::new(std::fs::File::open(&fifo).unwrap()).unwrap();
    let mut idx = Vec::new();
    while let Some(e) = r.next_event().unwrap() {
        match e {
            Event::Frame(f) => {
                assert!(f.payload_crc_ok);
                idx.push(f.meta.index);
                std::thread::sleep(Duration::from_millis(15)); // slower than the producer
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    let o = wait_deadline(child, 60);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(idx, (0..30).collect::<Vec<u64>>());
}

#[test]
fn reader_closing_early_ends_psns_quietly() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("f.fifo");
    mkfifo(&fifo);
    // no --frames: the built-in trajectory is infinite, only the closed reader can end it
    let child = stream_cmd(&["--out", s(&fifo)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        let mut r = StreamReader::new(std::fs::File::open(&fifo).unwrap()).unwrap();
        for _ in 0..3 {
            assert!(matches!(r.next_event().unwrap(), Some(Event::Frame(_))));
        }
    } // closed here
    let o = wait_deadline(child, 60);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(!e.contains("error"), "{e}");
    assert!(e.contains("reader closed"), "{e}");
    // the same through stdout into a pipe
    let mut child = stream_cmd(&[])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut head = vec![0u8; 4096 + 3 * 8192];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut head)
        .unwrap();
    drop(child.stdout.take());
    let o = wait_deadline(child, 60);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("error"), "{}", stderr(&o));
}

#[test]
fn frames_option_and_last_flag() {
    let o = run(&["--frames", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, f) = frames(&o.stdout);
    assert_eq!(f.len(), 3);
    let last: Vec<bool> = f.iter().map(|f| f.meta.flags & FLAG_LAST != 0).collect();
    assert_eq!(last, [false, false, true]);
    // timestamps from the trajectory clock: default start, 50 ms apart, exposure 20 µs
    let t0 = 1_750_500_000_000_000_000i64; // 2025-06-21T10:00:00Z
    for (k, fr) in f.iter().enumerate() {
        assert_eq!(fr.meta.exposure_start_ns, t0 + k as i64 * 50_000_000);
        assert_eq!(fr.meta.exposure_end_ns, fr.meta.exposure_start_ns + 20_000);
        assert_eq!(fr.meta.host_time_ns, 0);
    }
    // a finite trajectory file: the last pose is flagged too
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("t.csv");
    std::fs::write(&t, EULER).unwrap();
    let o = run(&["--trajectory", s(&t)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, f) = frames(&o.stdout);
    let last: Vec<bool> = f.iter().map(|f| f.meta.flags & FLAG_LAST != 0).collect();
    assert_eq!(last, [false, false, false, true]);
}

#[test]
fn trajectory_from_stdin_equals_file() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("t.csv");
    std::fs::write(&t, EULER).unwrap();
    let (a, b) = (d.path().join("a.psns"), d.path().join("b.psns"));
    let o = run(&["--trajectory", s(&t), "--out", s(&a)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run_stdin(&["--trajectory", "-", "--out", s(&b)], EULER);
    assert!(o.status.success(), "{}", stderr(&o));
    let (ba, bb) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let (ha, fa) = frames(&ba);
    let (hb, fb) = frames(&bb);
    assert_eq!(ha, hb);
    assert_eq!(fa.len(), 4);
    // stdin cannot look ahead, so the last frame is not flagged; everything else is equal
    for (x, y) in fa.iter().zip(&fb) {
        let mut mx = x.meta;
        mx.flags &= !FLAG_LAST;
        assert_eq!(mx, y.meta);
        assert_eq!(x.payload, y.payload);
    }
}

#[test]
fn malformed_trajectory_lines_keep_earlier_frames_valid() {
    let cases = [
        ("0.1,1,2\n", "line 4", "columns"),
        ("0.1,x,2,3\n", "line 4", "'x'"),
        ("0.01,1,2,3\n", "line 4", "backwards"),
    ];
    let d = tempfile::tempdir().unwrap();
    for (k, (bad, line, what)) in cases.iter().enumerate() {
        let input =
            format!("t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.05,10,0,0\n{bad}0.2,0,0,0\n");
        let t = d.path().join(format!("t{k}.csv"));
        std::fs::write(&t, &input).unwrap();
        for from_stdin in [false, true] {
            let out = d.path().join(format!("o{k}{from_stdin}.psns"));
            let o = if from_stdin {
                run_stdin(&["--trajectory", "-", "--out", s(&out)], &input)
            } else {
                run(&["--trajectory", s(&t), "--out", s(&out)])
            };
            assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
            let e = stderr(&o);
            assert!(e.contains(line) && e.contains(what), "{e}");
            // the frames before the bad line are intact, and the stream reads aborted
            let v = verify(&out);
            let text = String::from_utf8_lossy(&v.stdout);
            assert_eq!(v.status.code(), Some(3), "{text}");
            assert!(text.contains("ABORTED") && text.contains(line), "{text}");
            let (h, f) = frames(&std::fs::read(&out).unwrap());
            assert_eq!(f.len(), 2);
            assert_eq!((h.frame_count, h.aborted), (0, true));
        }
    }
    // a bad header line: nothing is written at all
    let out = d.path().join("none.psns");
    let o = run_stdin(&["--trajectory", "-", "--out", s(&out)], "t,yaw\n0,1\n");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("line 1"), "{}", stderr(&o));
    assert!(!out.exists());
}

/// Trajectory input a new user might feed: a 10 MB line, bytes that are not UTF-8, a first pose
/// that cannot be streamed, and a last line cut off inside a number on a pipe.
#[test]
fn trajectory_input_errors_are_short_numbered_and_write_nothing_early() {
    let d = tempfile::tempdir().unwrap();
    let head = "t_s,yaw_deg,pitch_deg,roll_deg\n";
    // a 10 MB number on line 3: at most a few dozen of its characters on stderr
    let t = d.path().join("big.csv");
    std::fs::write(
        &t,
        format!("{head}0,0,0,0\n0.05,{},0,0\n", "9".repeat(10 << 20)),
    )
    .unwrap();
    let out = d.path().join("big.psns");
    let o = run(&["--trajectory", s(&t), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(o.stderr.len() < 250, "{} bytes of stderr", o.stderr.len());
    assert!(stderr(&o).contains("line 3"), "{}", stderr(&o));
    // not UTF-8: bad input (2) with the line, not an I/O error (1)
    let t = d.path().join("bytes.csv");
    std::fs::write(
        &t,
        [head.as_bytes(), b"0,0,0,0\n\n0.1,\xff\xfe,0,0\n"].concat(),
    )
    .unwrap();
    let out = d.path().join("bytes.psns");
    let o = run(&["--trajectory", s(&t), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("line 4") && stderr(&o).contains("UTF-8"),
        "{}",
        stderr(&o)
    );
    // a first pose that cannot be streamed: nothing is written (no header-only file)
    for (name, first, what) in [
        ("column", "0,0,0\n", "line 2: expected 4 columns"),
        ("time", "1e308,0,0,0\n", "line 2: t_s = 1e308"),
        ("yaw", "0,1e308,0,0\n", "line 2: yaw = 1e308"),
    ] {
        let t = d.path().join(format!("{name}.csv"));
        std::fs::write(&t, format!("{head}{first}")).unwrap();
        let out = d.path().join(format!("{name}.psns"));
        for o in [
            run(&["--trajectory", s(&t), "--out", s(&out)]),
            run_stdin(
                &["--trajectory", "-", "--out", s(&out)],
                &format!("{head}{first}"),
            ),
        ] {
            assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
            assert!(stderr(&o).contains(what), "{name}: {}", stderr(&o));
            assert!(!out.exists(), "{name}: a file was written");
        }
    }
    // a last line without its newline, from a pipe: refused (the stream reads aborted); from a
    // regular file it is a file saved without a final newline, and taken
    let cut = format!("{head}0,0,0,0\n0.05,12,0,0.2");
    let out = d.path().join("cut.psns");
    let o = run_stdin(&["--trajectory", "-", "--out", s(&out)], &cut);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("line 3") && stderr(&o).contains("no newline"),
        "{}",
        stderr(&o)
    );
    let v = verify(&out);
    assert_eq!(v.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&v.stdout).contains("ABORTED"));
    let t = d.path().join("cut.csv");
    std::fs::write(&t, &cut).unwrap();
    let o = run(&["--trajectory", s(&t), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(frames(&std::fs::read(&out).unwrap()).1.len(), 2);
}

#[test]
fn verify_catches_corruption_of_a_streamed_file() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("a.psns");
    let o = run(&["--frames", "3", "--out", s(&p)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(verify(&p).status.success());
    let good = std::fs::read(&p).unwrap();
    let stride = 8192;
    let damaged = [
        ("payload bit", 4096 + stride + 256 + 100, None),
        ("frame header bit", 4096 + 2 * stride + 90, None),
        ("frame magic", 4096 + 3, None),
        ("truncated", 0, Some(good.len() - 1000)),
    ];
    for (what, at, cut) in damaged {
        let mut b = good.clone();
        match cut {
            Some(n) => b.truncate(n),
            None => b[at] ^= 0x10,
        }
        let q = d.path().join("bad.psns");
        std::fs::write(&q, &b).unwrap();
        let v = verify(&q);
        assert_eq!(
            v.status.code(),
            Some(1),
            "{what} not caught: {}",
            String::from_utf8_lossy(&v.stdout)
        );
    }
}

#[test]
fn sun_moves_with_a_place_in_the_trajectory() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("t.csv");
    std::fs::write(
        &t,
        "t_s,yaw_deg,pitch_deg,roll_deg,lat_deg,lon_deg,height_m\n0,0,0,0,48.1,11.6,500\n600,0,0,0,48.1,11.6,500\n1200,0,0,0,48.1,11.6,500\n",
    )
    .unwrap();
    let start = "2025-06-21T08:00:00Z";
    let o = run(&["--trajectory", s(&t), "--start-time", start]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, f) = frames(&o.stdout);
    assert_eq!(f.len(), 3);
    let place = psns::sun::Place {
        lat_deg: 48.1,
        lon_deg: 11.6,
        height_m: 500.0,
    };
    let t0 = psns::sun::parse_time(start).unwrap();
    for (k, fr) in f.iter().enumerate() {
        let m = &fr.meta;
        assert_eq!((m.lat_deg, m.lon_deg, m.height_m), (48.1, 11.6, 500.0));
        // SPA at mid-exposure (10 µs after the start)
        let t = t0 + chrono::Duration::nanoseconds(k as i64 * 600_000_000_000 + 10_000);
        let sp = psns::sun::spa(&t, &place, None, None).unwrap();
        assert!(
            (m.sun_azimuth_deg - sp.azimuth_deg).abs() < 1e-9,
            "{} {}",
            m.sun_azimuth_deg,
            sp.azimuth_deg
        );
        assert!((m.sun_elevation_deg - sp.elevation_deg()).abs() < 1e-9);
    }
    // about 2.5 degrees of azimuth per 10 minutes in the morning
    let daz = f[2].meta.sun_azimuth_deg - f[0].meta.sun_azimuth_deg;
    assert!(daz > 2.0 && daz < 8.0, "{daz}");
    assert!(f[2].meta.sun_elevation_deg > f[0].meta.sun_elevation_deg + 1.0);
    // the sky pattern follows the sun: same attitude, different frames
    assert_ne!(f[0].payload, f[2].payload);
    // --time as the start and the trajectory's place: the same frames
    let o2 = run(&["--trajectory", s(&t), "--time", start]);
    assert!(o2.status.success(), "{}", stderr(&o2));
    let (_, f2) = frames(&o2.stdout);
    assert_eq!(f2, f);
    // --time without any place is refused before anything is written
    let none = d.path().join("none.psns");
    let o3 = run(&["--frames", "1", "--time", start, "--out", s(&none)]);
    assert_eq!(o3.status.code(), Some(2), "{}", stderr(&o3));
    assert!(stderr(&o3).contains("--lat"), "{}", stderr(&o3));
    assert!(!none.exists());
}

#[test]
fn night_sky_invalid_sun_and_ground_flags() {
    // the scene's time and place: SPA per frame; midnight in Munich is dark
    let o = run(&[
        "--frames",
        "2",
        "--time",
        "2025-06-21T23:00:00Z",
        "--lat",
        "48.1",
        "--lon",
        "11.6",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, f) = frames(&o.stdout);
    for fr in &f {
        assert!(fr.meta.flags & FLAG_SKY_INVALID != 0);
        assert!(fr.meta.sun_elevation_deg < 0.0);
        assert!(fr.meta.exposure_start_ns >= 1_750_546_800_000_000_000); // 23:00 on the 21st
        let codes = fr.codes(&h).unwrap();
        let mean = codes.iter().map(|&c| c as f64).sum::<f64>() / codes.len() as f64;
        assert!(mean < 20.0, "dark frame mean {mean}");
    }
    // sun near the zenith in view; a camera pitched 80 degrees sees the ground
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("t.csv");
    std::fs::write(&t, "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n1,0,80,0\n").unwrap();
    let o = run(&["--trajectory", s(&t), "--sun-zenith", "5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, f) = frames(&o.stdout);
    assert!(f[0].meta.flags & FLAG_SUN_IN_VIEW != 0);
    assert!(f[0].meta.flags & FLAG_GROUND_IN_VIEW == 0);
    assert!(f[1].meta.flags & FLAG_SUN_IN_VIEW == 0);
    assert!(f[1].meta.flags & FLAG_GROUND_IN_VIEW != 0);
    assert!(f.iter().all(|f| f.meta.flags & FLAG_SKY_INVALID == 0));
}

#[test]
fn quaternion_trajectory_equals_euler() {
    let angles = [
        (0.0, 0.0, 0.0),
        (10.0, 5.0, -3.0),
        (20.0, 10.0, -6.0),
        (30.0, 15.0, -9.0),
    ];
    let mut q = String::from("t_s,qw,qx,qy,qz\n");
    for (k, &(y, p, r)) in angles.iter().enumerate() {
        let m = psns::camera::euler_matrix(y, p, r);
        let w = psns::camera::camera_to_enu_quaternion(&m);
        q += &format!(
            "{},{:.17},{:.17},{:.17},{:.17}\n",
            k as f64 * 0.05,
            w[0],
            w[1],
            w[2],
            w[3]
        );
    }
    let a = run_stdin(&["--trajectory", "-"], EULER);
    let b = run_stdin(&["--trajectory", "-"], &q);
    assert!(a.status.success() && b.status.success(), "{}", stderr(&b));
    let (h, fa) = frames(&a.stdout);
    let (_, fb) = frames(&b.stdout);
    assert_eq!(fa.len(), 4);
    for (x, y) in fa.iter().zip(&fb) {
        for i in 0..4 {
            assert!((x.meta.attitude_wxyz[i] - y.meta.attitude_wxyz[i]).abs() < 1e-12);
        }
        for i in 0..3 {
            assert!((x.meta.sun_camera[i] - y.meta.sun_camera[i]).abs() < 1e-12);
        }
        // rounding in the rotation may move a code by one at a quantisation step, rarely
        let (cx, cy) = (x.codes(&h).unwrap(), y.codes(&h).unwrap());
        let diff = cx.iter().zip(&cy).filter(|(a, b)| a != b).count();
        let maxd = cx
            .iter()
            .zip(&cy)
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        assert!(
            maxd <= 1 && diff * 100 < cx.len(),
            "{diff} codes differ, max {maxd}"
        );
    }
    // and the frames of different attitudes do differ
    assert_ne!(fa[0].payload, fa[3].payload);
}

#[test]
fn rate_paces_output() {
    let t = Instant::now();
    let o = run(&["--frames", "10", "--rate", "40"]);
    let el = t.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", stderr(&o));
    // frame k is due 25 ms · k after frame 0
    assert!(el >= 9.0 / 40.0, "{el} s");
    let o = run(&["--frames", "2", "--rate", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn stamp_host_time_fills_the_field() {
    let o = run(&["--frames", "2", "--stamp-host-time"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, f) = frames(&o.stdout);
    assert!(f[0].meta.host_time_ns > 0 && f[1].meta.host_time_ns >= f[0].meta.host_time_ns);
}

#[test]
fn nav_reader_follows_a_live_fifo() {
    common::require_numpy();
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("cam.fifo");
    mkfifo(&fifo);
    let tool: PathBuf = [env!("CARGO_MANIFEST_DIR"), "tools", "nav_reader.py"]
        .iter()
        .collect();
    // paced at 20 fps so the reader really follows a running producer; sun at 40 deg elevation
    let producer = stream_cmd(&[
        "--frames",
        "12",
        "--rate",
        "20",
        "--yaw-rate",
        "30",
        "--out",
        s(&fifo),
    ])
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let reader = common::python_cmd()
        .arg(&tool)
        .arg(&fifo)
        .args(["--delay", "0.02"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let r = wait_deadline(reader, 120);
    let p = wait_deadline(producer, 60);
    assert!(p.status.success(), "{}", stderr(&p));
    assert!(r.status.success(), "{}", stderr(&r));
    let out = String::from_utf8_lossy(&r.stdout);
    let lines: Vec<&str> = out.lines().filter(|l| l.starts_with("frame ")).collect();
    assert_eq!(lines.len(), 12, "{out}");
    for (k, l) in lines.iter().enumerate() {
        assert!(l.starts_with(&format!("frame {k} ")), "{l}");
        assert!(l.contains("sun_az=200.00"), "{l}");
        // centre AoLP against the single-scattering prediction from the header's sun vector
        let err: f64 = l
            .rsplit("err=")
            .next()
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(err.abs() < 5.0, "{l}");
    }
    assert!(out.contains("read 12 frames"), "{out}");
}

/// The stream header and a bag's `psns.config` record the sun the frames were made with: the
/// default scene's zenith and azimuth written out, a timed sun's time and place as given.
#[test]
fn header_and_bag_record_the_resolved_sun() {
    use psns::config::DEFAULT_SUN;
    let d = tempfile::tempdir().unwrap();
    let sun_of = |json: &str| {
        let v: serde_json::Value = serde_json::from_str(json).unwrap();
        v["scene"]["sun"].clone()
    };
    let f = d.path().join("default.psns");
    let o = run(&["--frames", "1", "--out", s(&f)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, _) = frames(&std::fs::read(&f).unwrap());
    let sun = sun_of(&h.json);
    assert_eq!(
        sun["zenith_deg"].as_f64(),
        Some(DEFAULT_SUN.zenith_deg),
        "{sun}"
    );
    assert_eq!(
        sun["azimuth_deg"].as_f64(),
        Some(DEFAULT_SUN.azimuth_deg),
        "{sun}"
    );
    // a bag's psns.config (metadata.yaml's custom_data) is the header's JSON
    let bag = d.path().join("bag");
    let o = run(&["--frames", "1", "--format", "rosbag2", "--out", s(&bag)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let y = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap();
    let line = y
        .lines()
        .find(|l| l.trim_start().starts_with("\"psns.config\":"))
        .unwrap_or_else(|| panic!("no psns.config in {y}"));
    let zen = format!("zenith_deg\\\":{:?}", DEFAULT_SUN.zenith_deg);
    assert!(line.contains(&zen), "{zen} not in {line}");
    // a timed sun keeps its time and place
    let f = d.path().join("timed.psns");
    let o = run(&[
        "--frames",
        "1",
        "--time",
        "2025-06-21T10:00:00Z",
        "--lat",
        "48.1",
        "--lon",
        "11.6",
        "--out",
        s(&f),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, _) = frames(&std::fs::read(&f).unwrap());
    let sun = sun_of(&h.json);
    assert_eq!(sun["time"].as_str(), Some("2025-06-21T10:00:00Z"), "{sun}");
    assert!(sun["place"]["lat_deg"].as_f64().is_some(), "{sun}");
}

/// `psns extract --frame N` past the stream's last frame is out of range (exit 2) and says the
/// range; a frame in range is extracted.
#[test]
fn extract_past_the_last_frame_gives_the_range() {
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("five.psns");
    let o = run(&["--frames", "5", "--out", s(&f)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let extract = |n: &str| {
        Command::new(exe())
            .args(["extract", s(&f), "--frame", n, "--out"])
            .arg(d.path().join(format!("x{n}")))
            .output()
            .unwrap()
    };
    let o = extract("5");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("frame = 5 is out of range (allowed 0..4"),
        "{}",
        stderr(&o)
    );
    assert!(!d.path().join("x5").exists());
    let o = extract("4");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.path().join("x4/frame_4.png").exists());
}

/// `readers::python_reader_ends_quietly_on_ctrl_c_and_missing_files` passes in a test run started
/// with SIGINT ignored: this runs it in this test binary again, with SIGINT ignored as `nohup` or a background job leaves it.
#[test]
fn ctrl_c_test_passes_when_the_run_ignores_sigint() {
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    common::sigint_disposition(&mut cmd, libc::SIG_IGN).args([
        "readers::python_reader_ends_quietly_on_ctrl_c_and_missing_files",
        "--exact",
        "--test-threads=1",
    ]);
    let out = common::wait_deadline(
        cmd.stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
        60,
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("1 passed"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
