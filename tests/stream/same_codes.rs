//! `psns render --raw` and frame 0 of `psns stream` with the same options give the same codes:
//! both take the frame from one pipeline path (the sky grid at one tolerance, the same sensor
//! pass), across presets, projections, sky models and sensor settings.

use psns::stream::{Event, StreamReader};
use std::path::Path;
use std::process::Command;

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_psns")
}

fn run(args: &[&str]) {
    let o = Command::new(exe())
        .args(args)
        .env("PSNS_PROGRESS", "off")
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "psns {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The codes of `psns render --raw` (raw.bin, little-endian u16) and of frame 0 of `psns
/// stream` (Mono16 payload), for the same options.
fn codes(dir: &Path, opts: &[&str]) -> (Vec<u8>, Vec<u8>) {
    let out = dir.join("render");
    let s = dir.join("s.psns");
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(&s);
    let mut r = vec!["render", "--raw", "--out", out.to_str().unwrap()];
    r.extend_from_slice(opts);
    run(&r);
    let mut st = vec!["stream", "--frames", "1", "--out", s.to_str().unwrap()];
    st.extend_from_slice(opts);
    run(&st);
    let raw = std::fs::read(out.join("raw.bin")).unwrap();
    let bytes = std::fs::read(&s).unwrap();
    let mut rd = StreamReader::new(&bytes[..]).unwrap();
    let payload = match rd.next_event().unwrap() {
        Some(Event::Frame(f)) => f.payload,
        other => panic!("no frame 0: {other:?}"),
    };
    (raw, payload)
}

fn differing(a: &[u8], b: &[u8]) -> usize {
    let (a, b): (&[u16], &[u16]) = (bytemuck::cast_slice(a), bytemuck::cast_slice(b));
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

#[test]
fn render_raw_equals_stream_frame_0() {
    let d = tempfile::tempdir().unwrap();
    let small = [
        "--width",
        "1224",
        "--height",
        "1024",
        "--pixel-pitch",
        "6.9",
    ];
    let cases: Vec<Vec<&str>> = vec![
        // full size: these differed where the planes and the rows had different sky grids
        vec![
            "--preset",
            "camera",
            "--seed",
            "4",
            "--model",
            "rayleigh",
            "--projection",
            "equidistant",
            "--focal-length",
            "1.8",
            "--exposure-us",
            "3000",
            "--gain-db",
            "3",
            "--bit-depth",
            "12",
        ],
        vec![
            "--preset",
            "camera",
            "--seed",
            "6",
            "--projection",
            "equisolid",
            "--focal-length",
            "1.2",
            "--sun-zenith",
            "20",
        ],
        vec![
            "--preset",
            "camera",
            "--sun-zenith",
            "10",
            "--sun-azimuth",
            "120",
        ],
        vec!["--preset", "nfpi"],
        vec!["--preset", "gniipi", "--sun-zenith", "30"],
        vec!["--preset", "gniicpi", "--sun-zenith", "70"],
        vec![
            "--exact",
            "--width",
            "256",
            "--height",
            "192",
            "--pixel-pitch",
            "33",
        ],
    ];
    let mut all = cases;
    for (proj, model) in [
        ("rectilinear", "pan"),
        ("stereographic", "queen"),
        ("orthographic", "berry"),
        ("equidistant", "asymmetric"),
        ("equisolid", "depolarized-rayleigh"),
    ] {
        let mut v: Vec<&str> = small.to_vec();
        v.extend(["--projection", proj, "--model", model, "--sun-zenith", "15"]);
        if proj != "rectilinear" {
            v.extend(["--focal-length", "2"]);
        }
        all.push(v);
    }
    let mut bad = Vec::new();
    for opts in &all {
        let (raw, payload) = codes(d.path(), opts);
        assert_eq!(raw.len(), payload.len(), "{opts:?}");
        let n = differing(&raw, &payload);
        if n > 0 {
            bad.push(format!("{n} codes differ with {}", opts.join(" ")));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The stream's attitude options are used or refused, never ignored: beside a trajectory file
/// (whose rows give the attitude), and a quaternion for the turning camera, exit 2 and nothing
/// written.
#[test]
fn stream_refuses_attitude_options_it_cannot_use() {
    let d = tempfile::tempdir().unwrap();
    let traj = d.path().join("t.csv");
    std::fs::write(&traj, "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n").unwrap();
    let out = d.path().join("s.psns");
    for extra in [
        vec!["--trajectory", traj.to_str().unwrap(), "--pitch", "3"],
        vec!["--trajectory", traj.to_str().unwrap(), "--frame", "solar"],
        vec!["--quaternion", "1,0,0,0"],
    ] {
        let o = Command::new(exe())
            .args(["stream", "--frames", "1", "--width", "64", "--height", "48"])
            .args(["--out", out.to_str().unwrap()])
            .args(&extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains("--trajectory"), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} wrote {}", out.display());
    }
}
