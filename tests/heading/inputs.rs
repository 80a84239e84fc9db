//! Where `psns heading` takes what it is not told: the sun of an image from the scene.json beside
//! it (or a refusal), the attitude frame of the yaw it reports, and a damaged stream's exit code.

use crate::common;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The columns of the CSV rows on stdout, by name: (header, rows).
fn rows(o: &std::process::Output) -> (Vec<String>, Vec<Vec<String>>) {
    let text = String::from_utf8(o.stdout.clone()).unwrap();
    let mut lines = text.lines();
    let head = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (head, rows)
}

fn col(head: &[String], row: &[String], name: &str) -> f64 {
    let i = head.iter().position(|h| h == name).unwrap();
    row[i].parse().unwrap()
}

fn gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Renders a 612 x 512 raw frame (the sensor's field of view, auto-exposed) into `out`, with
/// `extra` options.
fn render_small(out: &Path, extra: &[&str]) {
    let mut args = vec![
        "render",
        "--raw",
        "--auto-exposure",
        "--width",
        "612",
        "--height",
        "512",
        "--pixel-pitch",
        "13.8",
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    let o = common::psns(&args);
    assert!(o.status.success(), "{}", common::stderr(&o));
}

/// [`render_small`] with the sun at zenith 30 deg, azimuth 100 deg and the camera at ENU yaw
/// 30 deg.
fn render_off_default_sun(out: &Path) {
    render_small(
        out,
        &["--sun-zenith", "30", "--sun-azimuth", "100", "--yaw", "30"],
    );
}

/// An image rendered under a sun that is not the default: `psns heading` reads the sun and the
/// camera from the scene.json beside it and says so; without that file and without sun options
/// it refuses (exit 2) naming the options; with them (or `--config`) it gives the yaw again.
#[test]
fn image_sun_comes_from_the_scene_file_or_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path().join("r");
    render_off_default_sun(&r);
    let raw = r.join("raw.png");
    let o = common::psns(&["heading", s(&raw)]);
    let err = common::stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("scene.json") && err.contains("zenith 30"),
        "{err}"
    );
    let (head, row) = rows(&o);
    let yaw = col(&head, &row[0], "yaw_deg");
    assert!(gap(yaw, 30.0) < 0.5, "yaw {yaw} (want 30)");
    assert!(col(&head, &row[0], "confidence") > 0.5, "{row:?}");

    // the same picture alone: no sun anywhere
    let alone = dir.path().join("alone");
    std::fs::create_dir(&alone).unwrap();
    let copy = alone.join("raw.png");
    std::fs::copy(&raw, &copy).unwrap();
    let geom = ["--width", "612", "--height", "512", "--pixel-pitch", "13.8"];
    let mut a = vec!["heading", s(&copy)];
    a.extend(geom);
    let o = common::psns(&a);
    let err = common::stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for name in ["--sun-zenith", "--sun-azimuth", "--time", "--config"] {
        assert!(err.contains(name), "{name}: {err}");
    }
    assert!(o.stdout.is_empty());
    // half a sun is no sun
    a.extend(["--sun-azimuth", "100"]);
    let o = common::psns(&a);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    // the sun given: the right yaw, and no scene file mentioned
    a.extend(["--sun-zenith", "30"]);
    let o = common::psns(&a);
    assert!(o.status.success(), "{}", common::stderr(&o));
    assert!(!common::stderr(&o).contains("scene.json"));
    let (head, row) = rows(&o);
    assert!(gap(col(&head, &row[0], "yaw_deg"), 30.0) < 0.5, "{row:?}");
    // or the scene file named
    let scene = r.join("scene.json");
    let o = common::psns(&["heading", s(&copy), "--config", s(&scene)]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let (head, row) = rows(&o);
    assert!(gap(col(&head, &row[0], "yaw_deg"), 30.0) < 0.5, "{row:?}");
    // options override the scene file: a wrong sun azimuth moves the yaw by as much
    let o = common::psns(&["heading", s(&raw), "--sun-azimuth", "120"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let (head, row) = rows(&o);
    assert!(gap(col(&head, &row[0], "yaw_deg"), 50.0) < 1.0, "{row:?}");
}

/// `--frame solar` reports the yaw from the sun's azimuth (ψ_a = ψ_n − A_s), as `psns render
/// --frame solar` takes it: for an image, and for a stream's yaw and true yaw (same error).
#[test]
fn heading_reports_the_yaw_in_the_frame_asked() {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path().join("r");
    render_off_default_sun(&r);
    let raw = r.join("raw.png");
    let yaw = |extra: &[&str]| -> f64 {
        let mut a = vec!["heading", s(&raw)];
        a.extend(extra);
        let o = common::psns(&a);
        assert!(o.status.success(), "{}", common::stderr(&o));
        let (head, row) = rows(&o);
        col(&head, &row[0], "yaw_deg")
    };
    let enu = yaw(&[]);
    assert!(gap(enu, 30.0) < 0.5, "{enu}");
    assert_eq!(yaw(&["--frame", "enu"]), enu);
    let solar = yaw(&["--frame", "solar"]);
    assert!(gap(solar, 30.0 - 100.0) < 0.5, "solar {solar}, enu {enu}");
    assert!((0.0..360.0).contains(&solar), "{solar}");
    // a render in the solar frame comes back in it
    let r2 = dir.path().join("r2");
    render_small(&r2, &["--frame", "solar", "--yaw", "75"]);
    let o = common::psns(&["heading", s(&r2.join("raw.png")), "--frame", "solar"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let (head, row) = rows(&o);
    let got = col(&head, &row[0], "yaw_deg");
    assert!(gap(got, 75.0) < 0.5, "solar yaw {got} (want 75)");

    // a stream: both yaw columns move by the sun's azimuth (200 deg), the error does not
    let stream = dir.path().join("s.psns");
    let o = common::psns(&[
        "stream",
        "--frames",
        "2",
        "--width",
        "304",
        "--height",
        "256",
        "--pixel-pitch",
        "27.6",
        "--auto-exposure",
        "--yaw-rate",
        "300",
        "--out",
        s(&stream),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let run = |frame: &str| {
        let o = common::psns(&["heading", s(&stream), "--frame", frame]);
        assert!(o.status.success(), "{}", common::stderr(&o));
        rows(&o)
    };
    let (he, re) = run("enu");
    let (hs, rs) = run("solar");
    assert_eq!(re.len(), 2);
    for (e, so) in re.iter().zip(&rs) {
        for name in ["yaw_deg", "true_yaw_deg"] {
            let (a, b) = (col(&he, e, name), col(&hs, so, name));
            assert!(gap(b, a - 200.0) < 1e-3, "{name}: enu {a}, solar {b}");
        }
        let (a, b) = (col(&he, e, "error_deg"), col(&hs, so, "error_deg"));
        assert!((a - b).abs() < 1e-3, "error {a} / {b}");
        assert!(a.abs() < 1.0, "{e:?}");
    }
}

/// A stream cut short inside its last record: the intact frames' rows, then exit 1 as `psns
/// verify` exits for damage; no Rust debug text in the messages.
#[test]
fn heading_of_a_truncated_stream_prints_the_intact_rows_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let stream = dir.path().join("s.psns");
    let o = common::psns(&[
        "stream",
        "--frames",
        "3",
        "--width",
        "304",
        "--height",
        "256",
        "--pixel-pitch",
        "27.6",
        "--auto-exposure",
        "--out",
        s(&stream),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let bytes = std::fs::read(&stream).unwrap();
    let cut = dir.path().join("cut.psns");
    std::fs::write(&cut, &bytes[..bytes.len() - 5000]).unwrap();
    let v = common::psns(&["verify", s(&cut)]);
    assert_eq!(v.status.code(), Some(1), "{}", common::stderr(&v));
    let o = common::psns(&["heading", s(&cut)]);
    let err = common::stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let (head, rows) = rows(&o);
    assert_eq!(rows.len(), 2, "{rows:?}");
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(col(&head, r, "frame_index"), k as f64);
        assert!(col(&head, r, "error_deg").abs() < 1.0, "{r:?}");
    }
    assert!(err.contains("frame 2"), "{err}");
    assert!(err.contains("damaged"), "{err}");
    for debug in ["Some(", "None"] {
        assert!(!err.contains(debug), "{debug}: {err}");
    }
    // the whole stream: exit 0
    let o = common::psns(&["heading", s(&stream)]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    assert_eq!(rows_of(&o), 3);
}

fn rows_of(o: &std::process::Output) -> usize {
    rows(o).1.len()
}

/// A right answer is a confident one on every projection: clear-sky camera-preset frames of
/// 1024 x 1024 pixels through a 1 mm lens (the fisheyes see the whole sky; the rectilinear
/// 120°), default sun, four yaws. Such frames are read as sampled superpixels, each pixel
/// flat-fielded by the lens falloff the frame was made with; before that, the falloff across a
/// superpixel near a fisheye's rim read as polarization (confidence 0.15-0.55, residual 6-8.6°).
#[test]
fn right_answers_are_confident_on_every_projection() {
    let dir = tempfile::tempdir().unwrap();
    let sizes: [&[&str]; 1] = [&["--width", "1024", "--height", "1024"]];
    let projections = [
        "rectilinear",
        "equidistant",
        "equisolid",
        "stereographic",
        "orthographic",
    ];
    for size in sizes {
        let px = size[1];
        for proj in projections {
            for yaw in ["17", "103", "211", "298"] {
                let out = dir.path().join(format!("{proj}{yaw}_{px}"));
                let mut a = vec![
                    "render",
                    "--raw",
                    "--focal-length",
                    "1",
                    "--projection",
                    proj,
                    "--yaw",
                    yaw,
                    "--out",
                    s(&out),
                ];
                a.extend(size.iter());
                let o = common::psns(&a);
                assert!(o.status.success(), "{}", common::stderr(&o));
                let o = common::psns(&["heading", s(&out.join("raw.png"))]);
                assert!(o.status.success(), "{}", common::stderr(&o));
                let (head, row) = rows(&o);
                let got = col(&head, &row[0], "yaw_deg");
                let conf = col(&head, &row[0], "confidence");
                let res = col(&head, &row[0], "residual_deg");
                let err = gap(got, yaw.parse().unwrap());
                let case = format!("{px}² {proj} yaw {yaw}");
                eprintln!("{case}: error {err:.4}, confidence {conf:.3}, residual {res:.2}");
                assert!(err < 0.2, "{case}: error {err}");
                assert!(conf >= 0.8, "{case}: confidence {conf} (residual {res})");
            }
        }
    }
}

/// `--mask`: the sky fraction used is the last column; a given mask (the frame's size, nonzero =
/// sky) that hides the left half of the frame takes that half out of it and leaves the yaw; `--mask none` uses
/// every polarized pixel (at least what the found mask keeps); a mask of another size is refused
/// (exit 2).
#[test]
fn heading_takes_a_sky_mask_and_reports_the_sky_fraction() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    render_small(&out, &["--yaw", "75"]);
    let raw = out.join("raw.png");
    let heading = |extra: &[&str]| {
        let mut a = vec!["heading", s(&raw)];
        a.extend_from_slice(extra);
        let o = common::psns(&a);
        assert!(o.status.success(), "{extra:?}: {}", common::stderr(&o));
        let (head, row) = rows(&o);
        assert_eq!(
            head.join(","),
            "yaw_deg,confidence,pixels,saturated_pixels,residual_deg,sky_fraction"
        );
        let v = |n: &str| col(&head, &row[0], n);
        (v("yaw_deg"), v("confidence"), v("sky_fraction"))
    };
    let auto = heading(&[]);
    assert_eq!(auto, heading(&["--mask", "auto"]));
    let none = heading(&["--mask", "none"]);
    let mut half = psns::image::Image::<u8>::new(612, 512);
    for r in 0..512 {
        for c in 306..612 {
            half.data[r * 612 + c] = 255;
        }
    }
    let mask = dir.path().join("half.png");
    psns::io::write_png_gray8(&mask, &half).unwrap();
    let given = heading(&["--mask", s(&mask)]);
    eprintln!("auto {auto:?}, none {none:?}, right half given {given:?}");
    for (yaw, conf, _) in [auto, none, given] {
        assert!(gap(yaw, 75.0) < 0.1 && conf > 0.7, "{yaw} {conf}");
    }
    assert!(auto.2 > 0.85 && none.2 >= auto.2, "{auto:?} {none:?}");
    // the right half: at most half of the image, and at least what the left half's (77 of the
    // 153 sampled columns) leaves of the whole
    assert!(
        given.2 <= 0.5 && given.2 >= none.2 - 77.0 / 153.0 - 1e-3,
        "{given:?} {none:?}"
    );
    let small = dir.path().join("small.png");
    psns::io::write_png_gray8(&small, &psns::image::Image::new(100, 100)).unwrap();
    let o = common::psns(&["heading", s(&raw), "--mask", s(&small)]);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("100 x 100"),
        "{}",
        common::stderr(&o)
    );
    // a stream: the same mask for every frame, the sky fraction the last column of each row
    let stream = dir.path().join("s.psns");
    let o = common::psns(&[
        "stream",
        "--frames",
        "2",
        "--width",
        "612",
        "--height",
        "512",
        "--pixel-pitch",
        "13.8",
        "--auto-exposure",
        "--out",
        s(&stream),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    for (mask, range) in [("auto", 0.85..=1.0), (s(&mask), 0.3..=0.5)] {
        let o = common::psns(&["heading", s(&stream), "--mask", mask]);
        assert!(o.status.success(), "{}", common::stderr(&o));
        let (head, rows) = rows(&o);
        assert_eq!(head.last().map(String::as_str), Some("sky_fraction"));
        assert_eq!(rows.len(), 2);
        for r in &rows {
            let f = col(&head, r, "sky_fraction");
            assert!(range.contains(&f), "--mask {mask}: {f}");
            assert!(col(&head, r, "error_deg").abs() < 0.1, "{r:?}");
        }
    }
}
