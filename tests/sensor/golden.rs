//! Golden hashes of a small default-camera frame by each path, which pin the random-stream
//! derivation (`sensor.md` §6). (Full-size timing: `cargo bench --bench sensor`.)

use psns::camera::Intrinsics;
use psns::image::StokesImage;
use psns::sensor::{FrameOptions, Radiance, Sensor, SensorConfig};
use sha2::{Digest, Sha256};

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
    let f = golden_sensor()
        .frame(
            Radiance::Planes(&sky(32, 16)),
            7,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    // recorded from the first implementation; a change means every emulated camera changed
    assert_eq!(codes_sha256(&f.codes.data), GOLDEN);
}
const GOLDEN: &str = "876bf6db25c474c39e8ba4f9a1ab88871abcea0d618c6a2c75e8e081df721f4f";

/// The fast path's golden hash, recorded with its current noise generator (AES-round draws and
/// the binade normals; its noise differs from the exact path's by design). A change means every
/// fast-path camera changed.
#[test]
fn golden_fast_frame_hash() {
    let f = golden_sensor()
        .frame(Radiance::Planes(&sky(32, 16)), 7, FrameOptions::fast())
        .unwrap();
    assert_eq!(codes_sha256(&f.codes.data), GOLDEN_FAST);
}
const GOLDEN_FAST: &str = "303dddea17465c4bcc835ee71b37c1cbcfce55e43619bbcc3189095513cc99a1";
