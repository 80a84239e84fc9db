//! The world options through `psns render` and `psns stream`: bad input exits 2 naming the
//! value and its range with nothing written; the class image and its fractions come out.

use crate::common;
use common::{psns, stderr};
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const SMALL: [&str; 6] = ["--width", "160", "--height", "128", "--pixel-pitch", "55.2"];

/// Runs `psns render` with `args` into a fresh directory: (output, dir).
fn render(args: &[&str]) -> (std::process::Output, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let mut a = vec!["render", "--out", s(&out)];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(args);
    (psns(&a), dir)
}

#[test]
fn bad_worlds_exit_2_with_the_value_and_its_range() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let backwards = write("back.csv", "azimuth_deg,elevation_deg\n10,5\n5,6\n");
    let high = write("high.csv", "azimuth_deg,elevation_deg\n10,95\n");
    let nan = write("nan.csv", "azimuth_deg,elevation_deg\n10,NaN\n");
    let around = write(
        "around.toml",
        "[[world.buildings]]\neast_m = 1.0\nnorth_m = 0.0\nwidth_m = 10.0\ndepth_m = 10.0\nheight_m = 5.0\n",
    );
    let cases: [(Vec<&str>, &[&str]); 7] = [
        (vec!["--skyline", &backwards], &["does not increase", "5"]),
        (vec!["--skyline", &high], &["95", "-90..90"]),
        (vec!["--skyline", &nan], &["not a finite number"]),
        (vec!["--canyon", "20,NaN,0"], &["not a finite number"]),
        (vec!["--canyon=-3,6,0"], &["canyon width", "-3", "allowed"]),
        (vec!["--config", &around], &["around the observer"]),
        (
            vec!["--cloud-cover", "1.5"],
            &["cloud-cover", "1.5", "0..1"],
        ),
    ];
    for (args, want) in cases {
        let (o, d) = render(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        for w in want {
            assert!(e.contains(w), "{args:?}: {e}");
        }
        assert!(!d.path().join("o").exists(), "{args:?} wrote output");
    }
}

#[test]
fn render_writes_the_class_image_and_its_fractions() {
    let cloudy_canyon = |seed: &str| {
        render(&[
            "--projection",
            "equidistant",
            "--focal-length",
            "1.8",
            "--canyon",
            "20,6,0",
            "--cloud-cover",
            "0.3",
            "--seed",
            seed,
        ])
    };
    let class =
        |d: &tempfile::TempDir| std::fs::read(d.path().join("o").join("class.npy")).unwrap();
    let (o, d) = cloudy_canyon("3");
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.path().join("o");
    let bytes = std::fs::read(out.join("class.npy")).unwrap();
    assert!(bytes.starts_with(b"\x93NUMPY"));
    let text = std::fs::read_to_string(out.join("scene.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let f = &v["derived"]["class_fractions"];
    let total: f64 = ["outside", "sky", "cloud", "obstruction", "ground", "sun"]
        .iter()
        .map(|k| f[k].as_f64().unwrap())
        .sum();
    assert!((total - 1.0).abs() < 1e-9, "{f}");
    assert!(f["obstruction"].as_f64().unwrap() > 0.1, "{f}");
    assert!(f["cloud"].as_f64().unwrap() > 0.01, "{f}");
    assert_eq!(v["world"]["cloud_cover"], 0.3);
    // the same seed, the same clouds; another, others
    assert_eq!(bytes, class(&cloudy_canyon("3").1));
    assert_ne!(bytes, class(&cloudy_canyon("4").1));
}

/// A stream with a world renders the frame `psns render --raw` renders with the same options,
/// and the world is in it (the frame differs from the open sky's).
#[test]
fn stream_frame_0_is_render_raw_with_a_world() {
    let dir = tempfile::tempdir().unwrap();
    // 16 times the pixel area with the shortest exposure: no pixel saturated; looking toward
    // the horizon, where the walls are
    const SMALL: [&str; 6] = ["--width", "320", "--height", "256", "--pixel-pitch", "13.8"];
    let camera = ["--pitch", "60", "--exposure-us", "20"];
    let open_sky = dir.path().join("open");
    let mut a = vec!["render", "--raw", "--out", s(&open_sky)];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(&camera);
    let o = psns(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("saturated"), "{}", stderr(&o));
    let world = [
        "--canyon",
        "20,6,30",
        "--camera-height",
        "1.5",
        "--cloud-cover",
        "0.2",
        "--pitch",
        "60",
        "--exposure-us",
        "20",
    ];
    let out = dir.path().join("r");
    let mut a = vec!["render", "--raw", "--out", s(&out)];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(&world);
    let o = psns(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let stream = dir.path().join("s.psns");
    let mut a = vec!["stream", "--frames", "1", "--out", s(&stream)];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(&world);
    let o = psns(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let frame = dir.path().join("f");
    let o = psns(&["extract", s(&stream), "--frame", "0", "--out", s(&frame)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let raw = std::fs::read(out.join("raw.tiff")).unwrap();
    let got = std::fs::read(frame.join("frame_0.tiff")).unwrap();
    assert_eq!(raw, got, "render --raw and stream frame 0 differ");
    let open = std::fs::read(open_sky.join("raw.tiff")).unwrap();
    assert_ne!(raw, open, "the world is not in the frame");
    // the frame header carries the class fractions of the render's class image on every
    // k-th column and row
    let npy = std::fs::read(out.join("class.npy")).unwrap();
    let class = &npy[10 + u16::from_le_bytes([npy[8], npy[9]]) as usize..];
    let (w, h) = (320, 256);
    assert_eq!(class.len(), w * h);
    let k = psns::render::class_stride(w, h);
    assert_eq!(k, 3);
    let mut counts = [0usize; 6];
    for r in (0..h).step_by(k) {
        for c in (0..w).step_by(k) {
            counts[class[r * w + c] as usize] += 1;
        }
    }
    let n: usize = counts.iter().sum();
    let meta = first_frame(&stream);
    assert!(meta.flags & psns::stream::FLAG_CLASSES != 0);
    for (j, c) in psns::world::Class::ALL.iter().enumerate() {
        let want = counts[j] as f64 / n as f64;
        assert_eq!(meta.class_fractions[j], want as f32, "{}", c.name());
    }
    assert!(meta.class_fractions[psns::world::Class::Obstruction as usize] > 0.05);
    // the open sky's frames have none
    let open_stream = dir.path().join("open.psns");
    let mut a = vec!["stream", "--frames", "1", "--out", s(&open_stream)];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(&camera);
    assert!(psns(&a).status.success());
    let meta = first_frame(&open_stream);
    assert_eq!(meta.flags & psns::stream::FLAG_CLASSES, 0);
    assert_eq!(meta.class_fractions, [0.0; 6]);
}

/// The frame header of a stream file's first frame.
fn first_frame(p: &Path) -> psns::stream::FrameMeta {
    let f = std::fs::File::open(p).unwrap();
    let mut rd = psns::stream::StreamReader::new(std::io::BufReader::new(f)).unwrap();
    loop {
        match rd.next_event().unwrap().expect("a frame") {
            psns::stream::Event::Frame(f) => return f.meta,
            _ => continue,
        }
    }
}
