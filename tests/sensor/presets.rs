//! PSNS presets (nfpi, gniipi, gniicpi) of the sensor emulator.

use crate::common;
use common::simulate;
use psns::camera::Intrinsics;
use psns::image::StokesImage;
use psns::sensor::{Preset, SensorConfig};

fn sky(w: usize, h: usize) -> StokesImage {
    let mut s = StokesImage::zeros(w, h);
    for r in 0..h {
        for c in 0..w {
            let (x, y) = (c as f64 / w as f64, r as f64 / h as f64);
            let s0 = 0.08 + 0.1 * x * y;
            let p = 0.2 + 0.5 * y;
            let a = (10.0 + 160.0 * x).to_radians();
            *s.s0.get_mut(r, c) = s0 as f32;
            *s.s1.get_mut(r, c) = (s0 * p * (2.0 * a).cos()) as f32;
            *s.s2.get_mut(r, c) = (s0 * p * (2.0 * a).sin()) as f32;
        }
    }
    s
}

/// PSNS eq. (24) reading of pixel (r, c) for κ.
fn psns_reading(s: &StokesImage, r: usize, c: usize, kappa: f64) -> f64 {
    let a = psns::sensor::mosaic::MosaicLayout::IMX250MZR
        .angle_deg(r, c)
        .to_radians();
    let (s0, s1, s2) = (
        *s.s0.get(r, c) as f64,
        *s.s1.get(r, c) as f64,
        *s.s2.get(r, c) as f64,
    );
    // ½ LI [1 + DOP cos 2(AOP − θ)]
    let dop = s1.hypot(s2) / s0;
    let aop = 0.5 * s2.atan2(s1);
    kappa * 0.5 * s0 * (1.0 + dop * (2.0 * (aop - a)).cos())
}

fn kappa(s: &StokesImage, full: f64) -> f64 {
    kappa_ri(s, full, |_| 1.0)
}

/// κ of the paper: the brightest sample after the relative illumination `ri(k)` reads `full`.
fn kappa_ri(s: &StokesImage, full: f64, ri: impl Fn(usize) -> f64) -> f64 {
    let m = (0..s.s0.data.len())
        .map(|k| {
            ri(k) * 0.5 * (s.s0.data[k] as f64 + (s.s1.data[k] as f64).hypot(s.s2.data[k] as f64))
        })
        .fold(0.0, f64::max);
    full / m
}

/// A small frame with the field of view of the full 2448 × 2048 frame behind the 4 mm lens
/// (corner field angle 54°), so the relative illumination falls as much as on the real frame.
fn wide(w: usize, h: usize) -> Intrinsics {
    Intrinsics {
        focal_length_mm: 4.0 * w as f64 / 2448.0,
        ..Intrinsics::with_size(w, h)
    }
}

#[test]
fn nfpi_is_eq24_rounded_and_brightest_is_full_scale() {
    let (w, h) = (64, 64);
    let scene = sky(w, h);
    for bits in [8u8, 12] {
        let mut cfg = SensorConfig::preset(Preset::Nfpi);
        assert_eq!(cfg.bit_depth, 8);
        cfg.bit_depth = bits; // --bit-depth override
        let full = ((1u32 << bits) - 1) as f64;
        let k = kappa(&scene, full);
        let f = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 9, 0).unwrap();
        assert_eq!(f.bit_depth, bits);
        let mut top = 0u16;
        for r in 0..h {
            for c in 0..w {
                let want = psns_reading(&scene, r, c, k);
                let code = *f.codes.get(r, c);
                assert!(
                    (code as f64 - want).abs() <= 0.5 + 1e-6,
                    "{bits}: {code} vs {want}"
                );
                top = top.max(code);
                // truth: κ·S
                let t0 = *f.truth.s0.get(r, c) as f64;
                assert!((t0 / (k * *scene.s0.get(r, c) as f64) - 1.0).abs() < 1e-5);
            }
        }
        // κ uses max ½(S0 + |S_lin|), which a pixel reaches only when its axis meets the AoLP
        assert!(top as f64 <= full && top as f64 > 0.95 * full, "{top}");
        let flat = psns::sensor::flat_field(w, h, 0.3, 0.4, 45.0).unwrap();
        let g = simulate(&flat, &Intrinsics::with_size(w, h), &cfg, 9, 0).unwrap();
        assert_eq!(*g.codes.get(0, 1) as f64, full, "45° pixel at full scale");
        let low = (full * 0.6 / 1.4).round();
        assert_eq!(*g.codes.get(1, 0) as f64, low, "135° pixel");
    }
}

#[test]
fn gniipi_noise_and_falloff() {
    let (w, h) = (256, 256);
    let scene = sky(w, h);
    let cfg = SensorConfig::preset(Preset::Gniipi);
    let f = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 4, 0).unwrap();
    let i = Intrinsics::with_size(w, h);
    let k = kappa_ri(&scene, 255.0, |k| {
        cfg.ri.factor(&i, (k % w) as f64, (k / w) as f64)
    });
    // falloff: truth = κ · RI · S with the configured RI (cos^4 of the field angle)
    let mut res = Vec::new();
    for r in 0..h {
        for c in 0..w {
            let ri = cfg.ri.factor(&i, c as f64, r as f64);
            let t0 = *f.truth.s0.get(r, c) as f64;
            assert!((t0 / (k * ri * *scene.s0.get(r, c) as f64) - 1.0).abs() < 1e-5);
            let want = ri * psns_reading(&scene, r, c, k);
            if want > 30.0 && want < 225.0 {
                res.push(*f.codes.get(r, c) as f64 - want);
            }
        }
    }
    assert!(res.len() > 30_000);
    let n = res.len() as f64;
    let m = res.iter().sum::<f64>() / n;
    let sd = (res.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt();
    // σ = 2 % of 255 = 5.1 DN, plus rounding (1/12 DN²)
    let want = (5.1f64 * 5.1 + 1.0 / 12.0).sqrt();
    assert!((sd / want - 1.0).abs() < 0.03, "noise sd {sd}");
    assert!(m.abs() < 0.1, "noise mean {m}");
    // different frames, different noise; same frame, same bytes
    let g = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 4, 1).unwrap();
    assert_ne!(f.codes, g.codes);
    assert_eq!(
        f.codes,
        simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 4, 0)
            .unwrap()
            .codes
    );
}

#[test]
fn gniicpi_clouds_are_full_scale_ellipses() {
    let (w, h) = (256, 192);
    let scene = sky(w, h);
    let base = simulate(
        &scene,
        &Intrinsics::with_size(w, h),
        &SensorConfig::preset(Preset::Gniipi),
        4,
        0,
    )
    .unwrap();
    let f = simulate(
        &scene,
        &Intrinsics::with_size(w, h),
        &SensorConfig::preset(Preset::Gniicpi),
        4,
        0,
    )
    .unwrap();
    let mut cloud = 0usize;
    for k in 0..w * h {
        if f.codes.data[k] != base.codes.data[k] {
            // only cloud pixels change, and they read full scale with unpolarized truth
            assert_eq!(f.codes.data[k], 255);
            assert_eq!(f.truth.s0.data[k], 510.0);
            assert_eq!(f.truth.s1.data[k], 0.0);
            cloud += 1;
        }
    }
    let full = f.codes.data.iter().filter(|&&v| v == 255).count();
    // 3..8 ellipses with semi-axes ≥ 5 % of the width cover at least π·12.8² px (clipped by
    // the frame edge at worst to a quarter)
    assert!(
        full as f64 > 0.25 * std::f64::consts::PI * 12.8 * 12.8,
        "{full}"
    );
    assert!(cloud > 0);
    assert_eq!(f.saturated.iter().sum::<u32>() as usize, full);
}

/// The `ri` stage switch applies to the PSNS presets too (`--off ri`), on top of their own
/// falloff flag.
#[test]
fn ri_stage_switch_applies_to_psns_presets() {
    let (w, h) = (64, 48);
    let flat = psns::sensor::flat_field(w, h, 0.1, 0.0, 0.0).unwrap();
    let i = Intrinsics {
        focal_length_mm: 0.1,
        ..Intrinsics::with_size(w, h)
    };
    let frame = |ri: bool| {
        let mut c = SensorConfig::preset(Preset::Gniipi);
        c.psns.as_mut().unwrap().noise_fraction = 0.0;
        c.stages.ri = ri;
        simulate(&flat, &i, &c, 1, 0).unwrap().codes
    };
    let (on, off) = (frame(true), frame(false));
    let (centre, corner) = ((h / 2) * w + w / 2, 0);
    assert!(
        on.data[corner] < on.data[centre],
        "falloff expected with ri on"
    );
    assert_eq!(off.data[corner], off.data[centre], "no falloff with ri off");
}

/// The paper's PSNS frames: the brightest sample of a `gniipi` frame is full scale
/// **after** the edge falloff, and the 2 % noise is 2 % of that brightest signal. On a frame with
/// the real field of view and the brightest sky off axis (as toward the sun), κ taken before the
/// falloff left the brightest sample at 179 of 255 and made the noise 2.8 % of it.
#[test]
fn gniipi_brightest_sample_is_full_scale_after_falloff_and_noise_is_2_percent_of_it() {
    let (w, h) = (256, 208);
    let scene = sky(w, h); // brightest toward the bottom-right corner
    let i = wide(w, h);
    let cfg = SensorConfig::preset(Preset::Gniipi);
    let mut quiet = cfg.clone();
    quiet.psns.as_mut().unwrap().noise_fraction = 0.0;
    let f = simulate(&scene, &i, &quiet, 4, 0).unwrap();
    // the brightest sample any pass axis can read, from the truth κ·RI·S
    let t = &f.truth;
    let brightest = (0..w * h)
        .map(|k| 0.5 * (t.s0.data[k] as f64 + (t.s1.data[k] as f64).hypot(t.s2.data[k] as f64)))
        .fold(0.0, f64::max);
    assert!(
        (brightest - 255.0).abs() < 1e-3,
        "brightest sample {brightest}, want 255"
    );
    let top = *f.codes.data.iter().max().unwrap();
    assert!(top >= 250, "brightest code {top}");
    // σ = 2 % of the brightest noise-free sample (5.1 DN), measured on the noisy frame
    let g = simulate(&scene, &i, &cfg, 4, 0).unwrap();
    let layout = psns::sensor::mosaic::MosaicLayout::IMX250MZR;
    let mut res = Vec::new();
    for k in 0..w * h {
        let a = 2.0 * layout.angle_deg(k / w, k % w).to_radians();
        let want = 0.5
            * (t.s0.data[k] as f64 + t.s1.data[k] as f64 * a.cos() + t.s2.data[k] as f64 * a.sin());
        if want > 30.0 && want < 225.0 {
            res.push(g.codes.data[k] as f64 - want);
        }
    }
    let n = res.len() as f64;
    assert!(n > 20_000.0, "{n}");
    let m = res.iter().sum::<f64>() / n;
    let sd = (res.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n - 1.0 / 12.0).sqrt();
    assert!(
        (sd / brightest / 0.02 - 1.0).abs() < 0.04,
        "noise {sd} DN = {:.2} % of the brightest sample",
        100.0 * sd / brightest
    );
}

/// The PSNS presets with edge falloff use cos⁴ of the field angle (corner 0.12 on the full frame),
/// the textbook law the paper cites; the camera keeps its cos^1.5 retrofocus lens (corner 0.45).
#[test]
fn psns_presets_fall_off_as_cos4_camera_as_cos1_5() {
    use psns::sensor::optics::RelativeIllumination;
    for p in [Preset::Nfpi, Preset::Gniipi, Preset::Gniicpi] {
        assert_eq!(
            SensorConfig::preset(p).ri,
            RelativeIllumination::CosPower { n: 4.0 },
            "{p}"
        );
    }
    assert_eq!(
        SensorConfig::preset(Preset::Camera).ri,
        RelativeIllumination::CosPower { n: 1.5 }
    );
    // a flat field: corner / centre of the noise-free gniipi codes = cos⁴ of the corner angle
    let (w, h) = (2448 / 4, 2048 / 4);
    let i = wide(w, h);
    let flat = psns::sensor::flat_field(w, h, 0.1, 0.0, 0.0).unwrap();
    let mut c = SensorConfig::preset(Preset::Gniipi);
    c.psns.as_mut().unwrap().noise_fraction = 0.0;
    c.bit_depth = 12;
    let f = simulate(&flat, &i, &c, 1, 0).unwrap();
    let (corner, centre) = (
        *f.truth.s0.get(0, 0) as f64,
        *f.truth.s0.get(h / 2, w / 2) as f64,
    );
    let cos = {
        let fp = i.focal_px();
        let (x, y) = (0.5 * (w - 1) as f64, 0.5 * (h - 1) as f64);
        fp / (x * x + y * y + fp * fp).sqrt()
    };
    let ratio = corner / centre;
    let want = cos.powi(4) / {
        let fp = i.focal_px();
        (fp / (0.25 + 0.25 + fp * fp).sqrt()).powi(4)
    };
    assert!(
        (ratio / want - 1.0).abs() < 1e-5,
        "corner/centre {ratio}, cos^4 {want}"
    );
    assert!((ratio - 0.119).abs() < 0.003, "corner {ratio}");
}
