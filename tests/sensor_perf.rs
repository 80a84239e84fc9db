//! Full-size timing of the camera preset (run with `--ignored --nocapture`). Also a golden hash
//! of a small default-camera frame, which pins the random-stream derivation (`sensor.md` §6).

use psns::camera::Intrinsics;
use psns::image::StokesImage;
use psns::sensor::{Sensor, SensorConfig};
use sha2::{Digest, Sha256};
use std::time::Instant;

fn sky(w: usize, h: usize) -> StokesImage {
    let mut s = StokesImage::zeros(w, h);
    for r in 0..h {
        for c in 0..w {
            let (x, y) = (c as f64 / w as f64, r as f64 / h as f64);
            let s0 = 0.071 + 0.2 * (x - 0.8).powi(2) * (1.0 - y);
            let p = 0.6 * (std::f64::consts::PI * y).sin();
            let a = (30.0 + 170.0 * x + 40.0 * y).to_radians();
            *s.s0.get_mut(r, c) = s0 as f32;
            *s.s1.get_mut(r, c) = (s0 * p * (2.0 * a).cos()) as f32;
            *s.s2.get_mut(r, c) = (s0 * p * (2.0 * a).sin()) as f32;
        }
    }
    s
}

/// utime + stime of this process from /proc (Linux), seconds.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ is 100 on Linux
}

#[test]
#[ignore = "timing: full-size frames"]
fn full_size_camera_frame_timing() {
    let intr = Intrinsics::default();
    let scene = sky(intr.width, intr.height);
    let cfg = SensorConfig::default();
    let threads = rayon::current_num_threads();
    let t0 = Instant::now();
    let sensor = Sensor::new(&cfg, &intr, 1).unwrap();
    let setup = t0.elapsed().as_secs_f64();
    let mut times = Vec::new();
    let cpu0 = cpu_seconds();
    for i in 0..5 {
        let t = Instant::now();
        let f = sensor.frame(&scene, i).unwrap();
        times.push(t.elapsed().as_secs_f64());
        assert_eq!(f.codes.data.len(), 2448 * 2048);
    }
    if let (Some(a), Some(b)) = (cpu0, cpu_seconds()) {
        println!(
            "process CPU time per frame {:.3} s (all threads)",
            (b - a) / 5.0
        );
    }
    times.sort_by(|a, b| a.total_cmp(b));
    if std::env::var("PSNS_PERF_BREAKDOWN").is_ok() {
        let t = Instant::now();
        let _ = sensor.electron_rate(&scene).unwrap();
        println!("electron_rate {:.3}", t.elapsed().as_secs_f64());
        for (name, f) in [
            (
                "no shot",
                (|c: &mut SensorConfig| c.stages.shot = false) as fn(&mut SensorConfig),
            ),
            ("no read", |c: &mut SensorConfig| c.stages.read = false),
            ("no noise", |c: &mut SensorConfig| {
                c.stages.read = false;
                c.stages.shot = false
            }),
        ] {
            let mut c = cfg.clone();
            f(&mut c);
            let s = Sensor::new(&c, &intr, 1).unwrap();
            let t = Instant::now();
            let _ = s.frame(&scene, 0).unwrap();
            println!("{name}: {:.3}", t.elapsed().as_secs_f64());
        }
    }
    println!(
        "{threads} threads: camera setup (fixed-pattern maps) {setup:.3} s; frame min {:.3} s, median {:.3} s",
        times[0], times[2]
    );
}

/// The golden camera (32 × 16, black level 16, seed 12345) and the SHA-256 of a frame's codes.
fn golden_sensor() -> Sensor {
    let intr = Intrinsics {
        width: 32,
        height: 16,
        ..Default::default()
    };
    let mut cfg = SensorConfig::default();
    cfg.black_level_dn = 16.0;
    Sensor::new(&cfg, &intr, 12345).unwrap()
}

fn codes_sha256(codes: &[u16]) -> String {
    let bytes: Vec<u8> = codes.iter().flat_map(|v| v.to_le_bytes()).collect();
    Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn golden_frame_hash() {
    let f = golden_sensor().frame(&sky(32, 16), 7).unwrap();
    // recorded from the first implementation; a change means every emulated camera changed
    assert_eq!(codes_sha256(&f.codes.data), GOLDEN);
}
const GOLDEN: &str = "876bf6db25c474c39e8ba4f9a1ab88871abcea0d618c6a2c75e8e081df721f4f";

/// The fast path's golden hash, recorded when it was introduced (issue 9; its noise differs from
/// the exact path's by design). A change means every fast-path camera changed.
#[test]
fn golden_fast_frame_hash() {
    let f = golden_sensor()
        .frame_fast(&sky(32, 16), 7, Vec::new())
        .unwrap();
    assert_eq!(codes_sha256(&f.codes.data), GOLDEN_FAST);
}
const GOLDEN_FAST: &str = "07b2489a7ad34b6d4568cf8fadf71ac26cfc75f7cc47b2ba3d0ab2ff81bbe6fc";
