//! Noise statistics, determinism, robustness and input checks of the sensor emulator.

use crate::common;
use common::simulate;
use psns::camera::Intrinsics;
use psns::image::StokesImage;
use psns::sensor::{
    flat_field, Exposure, FrameOptions, Preset, Radiance, Sensor, SensorConfig, Stages,
};

fn sky(w: usize, h: usize) -> StokesImage {
    let mut s = StokesImage::zeros(w, h);
    for r in 0..h {
        for c in 0..w {
            let x = c as f64 / w as f64;
            let s0 = 0.07 + 0.05 * x;
            let a = (20.0 + 150.0 * x).to_radians();
            *s.s0.get_mut(r, c) = s0 as f32;
            *s.s1.get_mut(r, c) = (0.4 * s0 * (2.0 * a).cos()) as f32;
            *s.s2.get_mut(r, c) = (0.4 * s0 * (2.0 * a).sin()) as f32;
        }
    }
    s
}

/// Electrons of every pixel of a shot-noise-only frame (analog / DN per electron).
fn shot_electrons(radiance: f64, exposure_us: f64, frame: u64) -> (Vec<f64>, f64) {
    let (w, h) = (128, 128);
    let mut cfg = SensorConfig::default();
    cfg.exposure = Exposure::Fixed { us: exposure_us };
    cfg.stages = Stages {
        shot: true,
        ..Stages::none()
    };
    let s = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 5).unwrap();
    let scene = flat_field(w, h, radiance, 0.0, 0.0).unwrap();
    let mean = s.electron_rate(&scene).unwrap()[0] * exposure_us * 1e-6;
    let f = s
        .frame(
            Radiance::Planes(&scene),
            frame,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    let e = f
        .analog
        .unwrap()
        .data
        .iter()
        .map(|&v| v as f64 / f.dn_per_electron)
        .collect();
    (e, mean)
}

fn mean_var(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (
        m,
        v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0),
    )
}

/// Shot noise: mean equals variance (electrons) at low and high counts; integers; P(0) = e^−μ.
#[test]
fn shot_noise_mean_equals_variance() {
    for (radiance, t_us, label) in [
        (1e-4, 60.0, "low"),
        (2e-3, 60.0, "5 e"),
        (6e-3, 60.0, "15 e"),
        (0.1, 1200.0, "high"),
    ] {
        let (e, mu) = shot_electrons(radiance, t_us, 0);
        let (m, v) = mean_var(&e);
        // 16384 samples: mean to ~1 %/sqrt(mu), variance to ~1.1 % (4 sigma bounds)
        let n = e.len() as f64;
        assert!(
            (m - mu).abs() < 4.0 * (mu / n).sqrt(),
            "{label}: mean {m} vs {mu}"
        );
        let sv = v * (2.0 / n + 1.0 / (mu * n)).sqrt();
        assert!((v - mu).abs() < 4.0 * sv, "{label}: var {v} vs mean {mu}");
        assert!(e.iter().all(|x| (x - x.round()).abs() < 1e-2 * x.max(1.0)));
        println!("{label}: mu {mu:.4} e, measured mean {m:.4}, variance {v:.4}");
        if mu < 1.0 {
            let p0 = e.iter().filter(|&&x| x < 0.5).count() as f64 / n;
            assert!(
                (p0 - (-mu).exp()).abs() < 0.02,
                "P(0) {p0} vs {}",
                (-mu).exp()
            );
        }
    }
}

/// Same seed and frame: same bytes with 1 or 2 threads; another frame index: other noise;
/// fixed-pattern maps identical across frames and rebuilds, different for another seed.
#[test]
fn deterministic_across_threads_and_frames() {
    let (w, h) = (256, 128);
    let mut cfg = SensorConfig::default();
    cfg.black_level_dn = 16.0;
    cfg.crosstalk = 0.01;
    let scene = sky(w, h);
    let run = |threads: usize, frame: u64| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 77, frame).unwrap())
    };
    let a1 = run(1, 0);
    let a2 = run(2, 0);
    assert_eq!(a1.codes, a2.codes);
    assert_eq!(a1.truth, a2.truth);
    assert_eq!(a1.saturated, a2.saturated);
    let b = run(2, 1);
    let differ = a1
        .codes
        .data
        .iter()
        .zip(&b.codes.data)
        .filter(|(x, y)| x != y)
        .count();
    assert!(differ > w * h / 2, "only {differ} pixels differ");
    assert_eq!(a1.truth, b.truth);

    let s1 = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 77).unwrap();
    let s2 = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 77).unwrap();
    let s3 = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 78).unwrap();
    assert_eq!(s1.prnu_map(), s2.prnu_map());
    assert_eq!(s1.dsnu_map(), s2.dsnu_map());
    assert_ne!(s1.prnu_map(), s3.prnu_map());
    assert_eq!(s1.pass_axis_deg(5, 9), s2.pass_axis_deg(5, 9));
    assert_ne!(s1.pass_axis_deg(5, 9), s3.pass_axis_deg(5, 9));

    // fixed patterns only (no temporal noise): frames 0 and 5 are identical, and differ from the
    // pattern-free render
    let mut fp = cfg.clone();
    fp.stages = Stages {
        shot: false,
        read: false,
        dark: false,
        ..Stages::default()
    };
    let sp = Sensor::new(&fp, &Intrinsics::with_size(w, h), 77).unwrap();
    let f0 = sp
        .frame(
            Radiance::Planes(&scene),
            0,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    let f5 = sp
        .frame(
            Radiance::Planes(&scene),
            5,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    assert_eq!(f0.codes, f5.codes);
    let mut np = fp.clone();
    np.stages.prnu = false;
    np.stages.dsnu = false;
    np.stages.polarizer_orientation = false;
    let g = simulate(&scene, &Intrinsics::with_size(w, h), &np, 77, 0).unwrap();
    assert_ne!(f0.codes, g.codes);
}

/// No NaN or out-of-range code with the sun in view, at 48 dB, every depth, with and without the
/// full-well clip, with NaN and negative input pixels.
#[test]
fn sun_in_view_and_max_gain() {
    let (w, h) = (128, 96);
    let mut scene = sky(w, h);
    for r in 40..46 {
        for c in 60..66 {
            *scene.s0.get_mut(r, c) = 1.6e4;
            *scene.s1.get_mut(r, c) = 0.0;
            *scene.s2.get_mut(r, c) = 0.0;
        }
    }
    *scene.s0.get_mut(0, 0) = f32::NAN;
    *scene.s1.get_mut(0, 1) = f32::INFINITY;
    *scene.s0.get_mut(1, 1) = -1.0;
    for bits in [8u8, 10, 12] {
        for gain in [0.0, 24.0, 48.0] {
            for (fwc, quant) in [(true, true), (false, true), (true, false)] {
                for exposure in [Exposure::Fixed { us: 20.0 }, Exposure::auto()] {
                    let mut cfg = SensorConfig::default();
                    cfg.bit_depth = bits;
                    cfg.gain_db = gain;
                    cfg.black_level_dn = 16.0;
                    cfg.exposure = exposure;
                    cfg.stages.fwc_clip = fwc;
                    cfg.stages.quantize = quant;
                    let f = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 1, 2).unwrap();
                    let max = (1u16 << bits) - 1;
                    assert!(f.codes.data.iter().all(|&v| v <= max));
                    assert_eq!(*f.codes.get(42, 62), max, "sun saturates");
                    assert!(f.saturated.iter().all(|&n| n >= 9), "{:?}", f.saturated);
                    for p in [&f.truth.s0, &f.truth.s1, &f.truth.s2] {
                        assert!(p.data.iter().all(|v| v.is_finite()));
                    }
                    if let Some(a) = &f.analog {
                        assert!(a.data.iter().all(|v| v.is_finite()));
                    }
                    assert!(f.exposure_us >= 20.0 && f.exposure_us <= 1e7);
                }
            }
        }
    }
}

/// The PSNS presets stay in range with the sun in view too (κ then follows the sun).
#[test]
fn psns_presets_with_sun() {
    let (w, h) = (64, 64);
    let mut scene = sky(w, h);
    *scene.s0.get_mut(10, 10) = 1.6e4;
    *scene.s0.get_mut(11, 11) = f32::NAN;
    for p in [Preset::Nfpi, Preset::Gniipi, Preset::Gniicpi] {
        let f = simulate(
            &scene,
            &Intrinsics::with_size(w, h),
            &SensorConfig::preset(p),
            1,
            0,
        )
        .unwrap();
        // the sun's pixel reads the top of the scale, less the preset's noise (5 σ of it)
        let sigma = SensorConfig::preset(p).psns.unwrap().noise_fraction * 255.0;
        let sun = *f.codes.get(10, 10) as f64;
        assert!(sun >= 255.0 - (5.0 * sigma).ceil(), "{p:?}: {sun}");
        if sigma == 0.0 {
            assert_eq!(sun, 255.0);
        }
        assert!(f.codes.data.iter().all(|&v| v <= 255));
        assert!(f.truth.s0.data.iter().all(|v| v.is_finite()));
    }
}

/// Auto-exposure puts the 99th percentile of the noise-free electrons at 70 % of full well,
/// quantised to the line time; limits set the clipped flag.
#[test]
fn auto_exposure() {
    let (w, h) = (64, 64);
    let mut cfg = SensorConfig::default();
    cfg.exposure = Exposure::auto();
    cfg.stages = Stages::ideal();
    let scene = sky(w, h);
    let s = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 0).unwrap();
    let f = s
        .frame(
            Radiance::Planes(&scene),
            0,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    assert!(f.auto_exposed && !f.exposure_clipped);
    let line = 25.0 / 3.0;
    let n = f.exposure_us / line;
    assert!((n - n.round()).abs() < 1e-9, "{} us", f.exposure_us);
    let mut rate = s.electron_rate(&scene).unwrap();
    rate.sort_by(|a, b| a.total_cmp(b));
    let p99 = rate[(0.99 * rate.len() as f64).ceil() as usize - 1] * f.exposure_us * 1e-6;
    let want = 0.7 * 10_500.0;
    assert!(
        (p99 - want).abs() <= rate[rate.len() - 1] * line * 1e-6,
        "{p99} e"
    );
    // in DN: the brightest noise-free pixels sit near 70 % of 4095
    let top = *f.codes.data.iter().max().unwrap() as f64;
    assert!(top > 0.6 * 4095.0 && top < 0.8 * 4095.0, "{top}");

    let dark = flat_field(w, h, 1e-9, 0.0, 0.0).unwrap();
    let fd = s
        .frame(
            Radiance::Planes(&dark),
            0,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    assert!(fd.exposure_clipped && (fd.exposure_us - 1e7).abs() < line);
    let bright = flat_field(w, h, 1e4, 0.0, 0.0).unwrap();
    let fb = s
        .frame(
            Radiance::Planes(&bright),
            0,
            FrameOptions::exact().with_truth(),
        )
        .unwrap();
    assert!(fb.exposure_clipped && fb.exposure_us >= 20.0 && fb.exposure_us < 30.0);
}

/// Bad input: clear messages naming value and range.
#[test]
fn bad_input() {
    let i = Intrinsics::with_size(64, 64);
    let scene = flat_field(64, 64, 0.1, 0.0, 0.0).unwrap();
    let err = |cfg: &SensorConfig| simulate(&scene, &i, cfg, 0, 0).unwrap_err().to_string();
    let mut c = SensorConfig::default();
    c.exposure = Exposure::Fixed { us: 10.0 };
    assert_eq!(
        err(&c),
        "exposure-us = 10 is out of range (allowed 20..10000000)"
    );
    c.exposure = Exposure::Fixed { us: 2e7 };
    assert!(err(&c).contains("exposure-us = 20000000"));
    let mut c = SensorConfig::default();
    c.gain_db = 48.5;
    assert_eq!(err(&c), "gain-db = 48.5 is out of range (allowed 0..48)");
    c.gain_db = -1.0;
    assert!(err(&c).contains("gain-db = -1"));
    let mut c = SensorConfig::default();
    c.bit_depth = 14;
    assert!(err(&c).contains("bit-depth = 14") && err(&c).contains("8, 10 or 12"));
    let c = SensorConfig::default();
    let e = simulate(
        &flat_field(62, 64, 0.1, 0.0, 0.0).unwrap(),
        &Intrinsics::with_size(62, 64),
        &c,
        0,
        0,
    )
    .unwrap_err();
    assert!(e.is_usage());
    assert_eq!(
        e.to_string(),
        "width = 62 is out of range (allowed a non-zero multiple of 4)"
    );
    // scene and sensor of different sizes
    let e = simulate(&scene, &Intrinsics::with_size(64, 32), &c, 0, 0).unwrap_err();
    assert!(e.to_string().contains("64x64"), "{e}");
    let e = "fisheye".parse::<Preset>().unwrap_err();
    assert_eq!(
        e.to_string(),
        "preset = fisheye is out of range (allowed camera, nfpi, gniipi, gniicpi)"
    );
    assert_eq!(
        SensorConfig::preset(Preset::Camera),
        SensorConfig::default()
    );
}

/// Dark current doubles every 7 °C: at 60 °C, 5 · 2^5 = 160 e⁻/s; a 10 s dark frame holds
/// Poisson(1600) electrons.
#[test]
fn dark_current_with_temperature() {
    let (w, h) = (64, 64);
    let mut cfg = SensorConfig::default();
    cfg.temperature_c = 60.0;
    cfg.exposure = Exposure::Fixed { us: 1e7 };
    cfg.stages = Stages {
        dark: true,
        shot: true,
        ..Stages::none()
    };
    assert!((cfg.dark_current_at_temperature() - 160.0).abs() < 1e-9);
    let f = simulate(
        &flat_field(w, h, 0.0, 0.0, 0.0).unwrap(),
        &Intrinsics::with_size(w, h),
        &cfg,
        3,
        0,
    )
    .unwrap();
    let e: Vec<f64> = f
        .analog
        .unwrap()
        .data
        .iter()
        .map(|&v| v as f64 / f.dn_per_electron)
        .collect();
    let (m, v) = mean_var(&e);
    assert!(
        (m - 1600.0).abs() < 4.0 * (1600.0f64 / 4096.0).sqrt(),
        "{m}"
    );
    assert!((v / 1600.0 - 1.0).abs() < 0.1, "{v}");
    cfg.stages.dark = false;
    let g = simulate(
        &flat_field(w, h, 0.0, 0.0, 0.0).unwrap(),
        &Intrinsics::with_size(w, h),
        &cfg,
        3,
        0,
    )
    .unwrap();
    assert!(g.analog.unwrap().data.iter().all(|&v| v == 0.0));
}

/// Option: gain above 24 dB applied after a 12-bit ADC leaves missing codes; all-analog gain does
/// not. Both keep the mean.
#[test]
fn digital_gain_missing_codes() {
    let (w, h) = (128, 128);
    let scene = flat_field(w, h, 0.02, 0.0, 0.0).unwrap();
    let run = |digital: Option<f64>| {
        let mut cfg = SensorConfig::default();
        cfg.gain_db = 36.0;
        cfg.black_level_dn = 0.0;
        cfg.exposure = Exposure::Fixed { us: 60.0 };
        cfg.digital_gain_above_db = digital;
        let f = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 8, 0).unwrap();
        let mut used = [false; 4096];
        for &v in &f.codes.data {
            used[v as usize] = true;
        }
        // central 90 % of the histogram (the tails are sparse anyway)
        let mut sorted = f.codes.data.clone();
        sorted.sort_unstable();
        let lo = sorted[sorted.len() / 20] as usize;
        let hi = sorted[sorted.len() * 19 / 20] as usize;
        let missing = (lo..=hi).filter(|&v| !used[v]).count() as f64 / (hi - lo + 1) as f64;
        let mean = f.codes.data.iter().map(|&v| v as f64).sum::<f64>() / (w * h) as f64;
        (missing, mean, hi)
    };
    let (m_an, mean_an, hi_an) = run(None);
    let (m_dig, mean_dig, _) = run(Some(24.0));
    assert!(hi_an < 4095);
    // 12 dB digital = ×3.98: about 3 of 4 codes unused
    assert!(m_dig > 0.6, "digital: {m_dig} of codes missing");
    assert!(m_an < 0.2, "analog: {m_an} of codes missing");
    assert!(
        (mean_dig / mean_an - 1.0).abs() < 0.02,
        "{mean_dig} vs {mean_an}"
    );
}
