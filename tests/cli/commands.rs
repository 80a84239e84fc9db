//! End-to-end tests of the `psns` binary: outputs, bad input (exit code 2, nothing written),
//! and the reference values of sky.md through `psns sky` and `psns sun`.

use crate::common;
use common::{psns, psns_stdin, stderr};
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

/// A small camera with the default field of view (pitch scaled up).
const SMALL: [&str; 6] = ["--width", "96", "--height", "80", "--pixel-pitch", "88"];

#[test]
fn render_writes_every_file_and_reproduces_from_scene_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a");
    let mut args = vec!["render", "--out", out.to_str().unwrap()];
    args.extend(SMALL);
    let o = psns(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "li.npy",
        "dop.npy",
        "aop.npy",
        "i0.png",
        "i45.png",
        "i90.png",
        "i135.png",
        "i0_16bit.png",
        "i45_16bit.png",
        "i90_16bit.png",
        "i135_16bit.png",
        "li.png",
        "dop.png",
        "aop.png",
        "scene.json",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    let li = psns::io::read_npy_f32(&out.join("li.npy")).unwrap();
    assert_eq!((li.width, li.height), (96, 80));
    let dop = psns::io::read_npy_f32(&out.join("dop.npy")).unwrap();
    assert!(dop.data.iter().all(|v| (0.0..=1.0).contains(v)));
    let aop = psns::io::read_npy_f32(&out.join("aop.npy")).unwrap();
    assert!(aop.data.iter().all(|v| (0.0..180.0).contains(v)));
    // brightest polarizer sample maps to full scale
    let i16 = [
        "i0_16bit.png",
        "i45_16bit.png",
        "i90_16bit.png",
        "i135_16bit.png",
    ]
    .iter()
    .map(|f| {
        psns::io::read_gray(&out.join(f))
            .unwrap()
            .image
            .data
            .into_iter()
            .max()
            .unwrap()
    })
    .max()
    .unwrap();
    assert_eq!(i16, 65535);
    // same scene again from scene.json, into another directory: identical arrays
    let out2 = dir.path().join("b");
    let o = psns(&[
        "render",
        "--config",
        out.join("scene.json").to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["li.npy", "dop.npy", "aop.npy", "i45.png"] {
        assert_eq!(
            std::fs::read(out.join(f)).unwrap(),
            std::fs::read(out2.join(f)).unwrap(),
            "{f} differs"
        );
    }
}

fn assert_rejected(args: &[&str], needle: &str, out: &Path) {
    let o = psns(args);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    assert!(
        stderr(&o).contains(needle),
        "{args:?}: stderr lacks '{needle}': {}",
        stderr(&o)
    );
    assert!(
        !out.exists() || std::fs::read_dir(out).unwrap().next().is_none(),
        "{args:?} wrote output"
    );
}

#[test]
fn other_commands_print_short_range_messages() {
    let cases: &[(&[&str], &str)] = &[
        (
            &[
                "sun",
                "--time",
                "2020-06-01T12:00:00Z",
                "--lat",
                "0",
                "--lon",
                "0",
                "--refraction",
                "--pressure",
                "1e308",
            ],
            "pressure = 1e308 is out of range (allowed 1..1100)",
        ),
        // refraction settings without --refraction would be ignored
        (
            &[
                "sun",
                "--time",
                "2020-06-01T12:00:00Z",
                "--lat",
                "0",
                "--lon",
                "0",
                "--pressure",
                "900",
            ],
            "--refraction",
        ),
        (
            &["stream", "--frames", "-1", "--out", "/dev/null"],
            "-1 is out of range",
        ),
        (
            &["bench", "sky", "--runs", "0"],
            "0 is out of range (allowed 1..1000)",
        ),
        // integers: a value, not "invalid digit found in string"
        (
            &["extract", "x.psns", "--frame", "-1"],
            "-1 is out of range (allowed a whole number 0..",
        ),
        (
            &["render", "--width", "640.0", "--out", "never"],
            "'640.0' is not an integer",
        ),
        (
            &["render", "--bit-depth", "12.5", "--raw", "--out", "never"],
            "'12.5' is not an integer",
        ),
        (
            &["render", "--sky-grid", "x", "--raw", "--out", "never"],
            "'x' is not an integer",
        ),
        (
            &["render", "--height", "1e30", "--out", "never"],
            "1e30 is out of range (allowed a whole number",
        ),
        (
            &["dataset", "build", "--jobs", "2.5", "--out", "never"],
            "'2.5' is not an integer",
        ),
        (
            &[
                "dataset",
                "preview",
                "d",
                "--out",
                "x.png",
                "--per-split",
                "-1",
            ],
            "-1 is out of range",
        ),
    ];
    for (args, needle) in cases {
        let o = psns(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains(needle), "{args:?}: stderr lacks '{needle}': {e}");
        assert!(!e.contains("invalid digit"), "{args:?}: {e}");
        assert!(e.len() < 300, "{args:?}: message too long: {e}");
    }
}

/// A typed quaternion rounded to four decimals is accepted, normalised, and the note says so.
#[test]
fn rounded_quaternion_is_normalised() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("q");
    let o = psns(&[
        "render",
        "--quaternion",
        "0.7071,0,0,0.7071",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("normalised"), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap();
    let q: Vec<f64> = v["camera"]["attitude"]["wxyz"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((n - 1.0).abs() < 1e-12, "{q:?}");
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["--turbidity", "12"], "turbidity = 12"),
        (
            &["--turbidity", "0.5"],
            "allowed 1.7..10 with --dop-model wang-bounded",
        ),
        (&["--turbidity", "1.5"], "1..10 with --dop-model wang-paper"),
        (&["--wavelength", "300"], "wavelength = 300"),
        (&["--albedo", "1.5"], "albedo = 1.5"),
        (
            &["--sun-zenith", "95"],
            "sun altitude -5 deg: the sun is below the horizon",
        ),
        (
            &["--sun-altitude", "-5"],
            "sun altitude -5 deg: the sun is below the horizon",
        ),
        (
            &[
                "--time",
                "2020-01-01T00:00:00Z",
                "--lat",
                "48",
                "--lon",
                "11",
            ],
            "--time 2020-01-01T00:00:00Z: sun altitude",
        ),
        // huge numbers are printed short, and both out-of-range zeniths give one range
        (
            &["--sun-zenith", "1e308"],
            "sun-zenith = 1e308 is out of range (allowed 0..180)",
        ),
        (&["--sun-zenith", "200"], "(allowed 0..180)"),
        (&["--yaw", "1e308"], "yaw = 1e308 is out of range"),
        (&["--pitch", "-400"], "pitch = -400 is out of range"),
        (&["--roll", "1000"], "roll = 1000 is out of range"),
        // negative values reach the range message instead of clap's "unexpected argument"
        (&["--seed", "-1"], "-1 is out of range"),
        (&["--frame-index", "-3"], "-3 is out of range"),
        (&["--neutral-distance", "70"], "babinet = 70"),
        (&["--focal-length", "0"], "focal-length = 0"),
        (&["--pixel-pitch", "-3"], "pixel-pitch = -3"),
        (&["--width", "0"], "width = 0"),
        (&["--quaternion", "1,1,0,0"], "not a unit quaternion"),
        (&["--quaternion", "1,0,0"], "expected 4"),
        (&["--turbidity", "inf"], "not a finite number"),
        (&["--yaw", "NaN"], "not a finite number"),
        (&["--model", "mie"], "mie"),
        (&["--bogus"], "--bogus"),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["render", "--out", o];
        args.extend_from_slice(extra);
        assert_rejected(&args, needle, &out);
    }
}

/// sky.md §9 default-configuration table through `psns sky`.
#[test]
fn sky_command_matches_default_table() {
    let input = "zenith_deg,azimuth_deg\n0,0\n30,200\n30,20\n45,110\n45,290\n60,200\n70,20\n80,110\n30,245\n";
    let o = psns_stdin(&["sky"], input);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg"
    );
    // gamma, L450, DOP, chi, AOP_m (AOP_m at the zenith = chi)
    let expect = [
        (50.000, 7.4140e-2, 0.15881, -70.000, -70.000),
        (20.000, 1.4797e-1, 0.01831, 20.000, 0.000),
        (80.000, 7.5182e-2, 0.49123, -70.000, 90.000),
        (62.966, 9.4944e-2, 0.41589, -36.337, 33.663),
        (62.966, 9.4944e-2, 0.41589, 76.337, -33.663),
        (10.000, 3.6339e-1, 0.06307, 20.000, 0.000),
        (120.000, 1.4437e-1, 0.35767, -70.000, 90.000),
        (83.591, 1.7833e-1, 0.56946, -30.278, 39.722),
        (34.156, 1.0461e-1, 0.10935, 65.521, 0.521),
    ];
    let axial = |a: f64, b: f64| {
        let d = (a - b).rem_euclid(180.0);
        d.min(180.0 - d)
    };
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), expect.len(), "{text}");
    for (line, e) in rows.into_iter().zip(expect.iter()) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert!((v[2] - e.0).abs() < 1e-3, "{line}");
        assert!((v[3] / e.1 - 1.0).abs() < 1e-4, "{line}: radiance");
        assert!((v[4] - e.2).abs() < 1e-5, "{line}: dop");
        assert!(axial(v[5], e.4) < 1e-3, "{line}: aop_m");
        assert!(axial(v[6], e.3) < 1e-3, "{line}: chi");
    }
}

#[test]
fn config_values_are_kept_unless_overridden() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("q.json");
    std::fs::write(
        &cfg,
        r#"{"camera": {"attitude": {"kind": "quaternion", "frame": "enu", "wxyz": [0.9659258262890683, 0.0, 0.0, 0.25881904510252074]}},
            "sun": {"time": "2025-06-21T10:00:00Z", "place": {"lat_deg": 48.0, "lon_deg": 11.0, "height_m": 0.0}}}"#,
    )
    .unwrap();
    let c = cfg.to_str().unwrap();
    let scene = |out: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap()
    };
    // --quaternion alone keeps the config's frame
    let out = dir.path().join("a");
    let o = psns(&[
        "render",
        "--config",
        c,
        "--quaternion",
        "1,0,0,0",
        "--out",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(scene(&out)["camera"]["attitude"]["frame"], "enu");
    // --frame alone changes only the quaternion's frame
    let out = dir.path().join("b");
    let o = psns(&[
        "render",
        "--config",
        c,
        "--frame",
        "solar",
        "--out",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let a = &scene(&out)["camera"]["attitude"];
    assert_eq!(
        (a["kind"].as_str(), a["frame"].as_str()),
        (Some("quaternion"), Some("solar"))
    );
    // a partial Euler override of a quaternion, or an azimuth alone over a timed sun: refused
    for extra in [&["--yaw", "10"][..], &["--sun-azimuth", "100"][..]] {
        let out = dir.path().join("c");
        let mut args = vec!["render", "--config", c, "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = psns(&args);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
    // a missing config file is bad input too
    let o = psns(&["render", "--config", "/nonexistent/scene.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
}

#[test]
fn sky_command_reports_bad_line_numbers() {
    let o = psns_stdin(&["sky"], "zenith_deg,azimuth_deg\n10,20\n10,abc\n");
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("line 3"), "{}", stderr(&o));
    let o = psns_stdin(&["sky"], "zenith_deg,azimuth_deg\n10,20,30\n");
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("line 2") && stderr(&o).contains("3"),
        "{}",
        stderr(&o)
    );
    let o = psns_stdin(&["sky"], "az,zen\n");
    assert_eq!(o.status.code(), Some(2));
    // every field is range-checked as the options are (--sun-zenith, --sun-azimuth)
    for (row, says) in [
        (
            "10,1e9",
            "line 3: azimuth_deg = 1e9 is out of range (allowed -360..720)",
        ),
        (
            "10,-361",
            "line 3: azimuth_deg = -361 is out of range (allowed -360..720)",
        ),
        (
            "181,20",
            "line 3: zenith_deg = 181 is out of range (allowed 0..180)",
        ),
    ] {
        let o = psns_stdin(&["sky"], &format!("zenith_deg,azimuth_deg\n10,20\n{row}\n"));
        assert_eq!(o.status.code(), Some(2), "{row}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{row}: {}", stderr(&o));
    }
    let o = psns_stdin(&["sky"], "zenith_deg,azimuth_deg\n10,-360\n10,720\n");
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `psns sky` reads its input as CSV: quoted fields and spaced headers are fields like any other;
/// bytes that are not UTF-8 are bad input with their line, and a 10 MB line is quoted, not echoed.
#[test]
fn sky_input_is_csv_and_bad_lines_are_short() {
    let run = |input: Vec<u8>| {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_psns"))
            .arg("sky")
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        // psns may stop reading at the bad line: a broken pipe here is expected
        let w = std::thread::spawn(move || {
            let _ = std::io::Write::write_all(&mut stdin, &input);
        });
        let o = child.wait_with_output().unwrap();
        w.join().unwrap();
        o
    };
    let o = run(b"zenith_deg, azimuth_deg\n\"10\",20\n".to_vec());
    assert!(o.status.success(), "{}", stderr(&o));
    let plain = psns_stdin(&["sky"], "zenith_deg,azimuth_deg\n10,20\n");
    assert_eq!(o.stdout, plain.stdout);
    let o = run(b"zenith_deg,azimuth_deg\n10,20\n10,\xff\n".to_vec());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("line 3"), "{}", stderr(&o));
    let mut long = b"zenith_deg,azimuth_deg\n".to_vec();
    long.extend(std::iter::repeat_n(b'1', 10 << 20));
    long.extend(b",x\n");
    let o = run(long);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stderr.len() < 250, "{} bytes of stderr", o.stderr.len());
}

#[test]
fn sun_command_nrel_reference() {
    let o = psns(&[
        "sun",
        "--time",
        "2003-10-17T19:30:30Z",
        "--lat",
        "39.742476",
        "--lon",
        "-105.1786",
        "--height",
        "1830.14",
        "--delta-t",
        "67",
        "--refraction",
        "--pressure",
        "820",
        "--temperature",
        "11",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let t = String::from_utf8(o.stdout).unwrap();
    let mut l = t.lines();
    assert_eq!(l.next(), Some("zenith_deg,azimuth_deg"));
    let v: Vec<f64> = l
        .next()
        .unwrap()
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    assert!(
        (v[0] - 50.111622).abs() < 1e-5 && (v[1] - 194.340241).abs() < 1e-5,
        "{v:?}"
    );
    // night: still printed, zenith > 90
    let o = psns(&[
        "sun",
        "--time",
        "2003-10-17T08:00:00Z",
        "--lat",
        "39.74",
        "--lon",
        "-105.18",
    ]);
    assert!(o.status.success());
    let t = String::from_utf8(o.stdout).unwrap();
    let z: f64 = t
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(z > 90.0);
    let o = psns(&["sun", "--time", "yesterday", "--lat", "0", "--lon", "0"]);
    assert_eq!(o.status.code(), Some(2));
    let o = psns(&[
        "sun",
        "--time",
        "2003-10-17T08:00:00Z",
        "--lat",
        "95",
        "--lon",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("lat = 95"), "{}", stderr(&o));
}

#[test]
fn closed_stdout_ends_quietly() {
    // `psns sky | head -1` style: a reader that goes away must not cause an error message.
    let mut input = String::from("zenith_deg,azimuth_deg\n");
    for i in 0..200_000 {
        input.push_str(&format!("{},{}\n", i % 80, i % 360));
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .arg("sky")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(input.as_bytes());
    });
    drop(child.stdout.take()); // close the read end at once
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
}

/// `--out` naming an existing file, or a directory holding the user's own files: exit 2, and
/// the file and directory are left as they were.
#[test]
fn out_onto_a_file_or_a_foreign_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("notes.txt");
    std::fs::write(&f, "mine").unwrap();
    for out in [f.clone(), dir.path().to_path_buf()] {
        let o = psns(&[
            "render",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("not a directory") || stderr(&o).contains("does not write"),
            "{}",
            stderr(&o)
        );
    }
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "mine");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// Options that would do nothing are refused instead of ignored, and scene.json writes the sun
/// out for the default scene.
#[test]
fn ignored_options_are_refused_and_the_sun_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o_s = out.to_str().unwrap();
    for (extra, needle) in [
        (
            &["--lat", "10", "--lon", "20"][..],
            "--lat places the observer for --time",
        ),
        (
            &["--exposure-us", "100"][..],
            "--exposure-us applies to the raw frame",
        ),
        (&["--seed", "3"][..], "--seed applies to the raw frame"),
    ] {
        let mut a = vec!["render", "--width", "8", "--height", "8", "--out", o_s];
        a.extend_from_slice(extra);
        let o = psns(&a);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{extra:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
    let o = psns(&["render", "--width", "8", "--height", "8", "--out", o_s]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap();
    assert_eq!(v["sun"]["zenith_deg"], 50.0);
    assert_eq!(v["sun"]["azimuth_deg"], 200.0);
}

/// `psns sky --stability --out DIR` writes the stability map of both DOP models and the other
/// models' rows: the published formula has unstable cells at T >= 1.7, the default none, and
/// refuses T < 1.7; no model's AOP flips with the sun.
#[test]
fn sky_stability_map() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("st");
    let o = psns(&["sky", "--stability", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "dop_stability.csv",
        "dop_stability.svg",
        "dop_stability.png",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let csv = std::fs::read_to_string(out.join("dop_stability.csv")).unwrap();
    let (mut paper_bad, mut bounded_bad, mut bounded_refused, mut bounded_ok) = (0, 0, 0, 0);
    let mut other = std::collections::HashMap::new();
    for l in csv.lines().skip(1) {
        let c: Vec<&str> = l.split(',').collect();
        if !c[0].starts_with("wang") {
            // the models without turbidity or wavelength: one row per sun zenith, no AOP flip
            assert_eq!((c[1], c[3]), ("any", "any"), "{l}");
            let shift: f64 = c[12].parse().unwrap();
            assert!(shift < 1.0, "{l}");
            *other.entry(c[0].to_string()).or_insert(0) += 1;
            continue;
        }
        let t: f64 = c[1].parse().unwrap();
        match (c[0], c[4]) {
            ("wang-paper", "unstable") if t >= 1.7 => paper_bad += 1,
            ("wang-bounded", "unstable") => bounded_bad += 1,
            ("wang-bounded", "refused") => bounded_refused += 1,
            ("wang-bounded", "stable") => bounded_ok += 1,
            _ => {}
        }
    }
    assert_eq!((bounded_bad, bounded_ok), (0, 4140));
    assert_eq!(bounded_refused, 460);
    assert!(paper_bad > 500, "{paper_bad}");
    for m in [
        "depolarized-rayleigh",
        "berry",
        "pan",
        "queen",
        "asymmetric",
    ] {
        assert_eq!(other.get(m), Some(&46), "{m}");
    }
    // --out belongs to --stability, and --stability sweeps what it would otherwise take
    let o = psns(&["sky", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let o = psns(&[
        "sky",
        "--stability",
        "--turbidity",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--turbidity would be ignored"),
        "{}",
        stderr(&o)
    );
}
