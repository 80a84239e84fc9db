//! Polarizer model, ground truth and the exact float model of the sensor emulator.

use crate::common;
use common::{simulate, simulate_float};
use psns::camera::Intrinsics;
use psns::image::{Image, StokesImage};
use psns::sensor::mosaic::MosaicLayout;
use psns::sensor::optics::RelativeIllumination;
use psns::sensor::polarizer::diattenuation;
use psns::sensor::{flat_field, FrameOptions, Radiance, Sensor, SensorConfig, Stages};

/// A smooth sky-like scene: S0 0.07..0.28, DoLP 0..0.6, AoLP sweeping the frame.
fn sky(w: usize, h: usize) -> StokesImage {
    let mut s = StokesImage::zeros(w, h);
    for r in 0..h {
        for c in 0..w {
            let (x, y) = (c as f64 / w as f64, r as f64 / h as f64);
            let s0 = 0.07 + 0.21 * x * x * (1.0 - 0.5 * y);
            let p = 0.6 * (std::f64::consts::PI * y).sin();
            let a = (30.0 + 170.0 * x + 40.0 * y).to_radians();
            *s.s0.get_mut(r, c) = s0 as f32;
            *s.s1.get_mut(r, c) = (s0 * p * (2.0 * a).cos()) as f32;
            *s.s2.get_mut(r, c) = (s0 * p * (2.0 * a).sin()) as f32;
        }
    }
    s
}

/// Noise-free flat field at AoLP 0..180° in 15° steps: every pixel follows
/// I = ½T∥(1 + 1/ER)·[S0 + D·DoLP·S0·cos 2(θ_k − AoLP)] with its own pass axis θ_k.
#[test]
fn flat_field_follows_partial_polarizer_law() {
    let (w, h) = (64, 64);
    let i = Intrinsics::with_size(w, h);
    let mut cfg = SensorConfig::default();
    cfg.black_level_dn = 10.0;
    cfg.stages = Stages {
        ri: true,
        polarizer_er: true,
        polarizer_orientation: true,
        ..Stages::none()
    };
    let sensor = Sensor::new(&cfg, &i, 11).unwrap();
    // the mosaic positions carry their nominal angle (orientation error σ = 0.5°)
    let nominal = [[90.0, 45.0], [135.0, 0.0]];
    for r in 0..h {
        for c in 0..w {
            let d = psns::angle::SensorAngle::from_deg(sensor.pass_axis_deg(r, c))
                .diff(psns::angle::SensorAngle::from_deg(nominal[r & 1][c & 1]));
            assert!(
                d < 2.5,
                "pixel ({r},{c}) axis {}",
                sensor.pass_axis_deg(r, c)
            );
        }
    }
    let er = 60.0; // ER(450 nm) of the spec table
    let d = (er - 1.0) / (er + 1.0);
    let (l, dolp) = (0.1, 0.7);
    let t = 1e-3;
    let e_per_l = sensor.photon_rate_per_radiance() * 0.60 * t; // η · photons · t per unit L
    let mut max_rel = 0f64;
    for step in 0..=12 {
        let aolp = 15.0 * step as f64;
        let f = sensor
            .frame(
                Radiance::Planes(&flat_field(w, h, l, dolp, aolp).unwrap()),
                0,
                FrameOptions::exact(),
            )
            .unwrap();
        let an = f.analog.as_ref().expect("quantize off gives analog values");
        for r in 0..h {
            for c in 0..w {
                let th = sensor.pass_axis_deg(r, c);
                let ri = cfg.ri.factor(&i, c as f64, r as f64);
                let ik = 0.5
                    * 0.8
                    * (1.0 + 1.0 / er)
                    * l
                    * (1.0 + d * dolp * (2.0 * (th - aolp).to_radians()).cos());
                let want = 10.0 + f.dn_per_electron * e_per_l * ri * ik;
                let got = *an.get(r, c) as f64;
                max_rel = max_rel.max((got - want).abs() / want);
            }
        }
    }
    assert!(max_rel < 2e-6, "max relative deviation {max_rel}");
}

/// Spec §5 anchor: 4 190 e⁻/ms for an unpolarized on-axis pixel at L = 0.1.
#[test]
fn electron_rate_anchor() {
    let mut cfg = SensorConfig::default();
    cfg.stages = Stages {
        polarizer_er: true,
        ..Stages::none()
    };
    let s = Sensor::new(&cfg, &Intrinsics::with_size(8, 8), 0).unwrap();
    let rate = s
        .electron_rate(&flat_field(8, 8, 0.1, 0.0, 0.0).unwrap())
        .unwrap();
    let per_ms = rate[0] * 1e-3;
    assert!((per_ms / 4190.0 - 1.0).abs() < 0.01, "{per_ms} e/ms");
}

/// Ideal polarizer: superpixel Stokes from the analog output return the input (scaled), for a
/// fully polarized input at every 15°; with ER on the DoLP reads D(λ_c).
#[test]
fn ideal_polarizer_superpixel_returns_input() {
    let (w, h) = (8, 8);
    for er_on in [false, true] {
        let mut cfg = SensorConfig::default();
        cfg.black_level_dn = 5.0;
        cfg.stages = Stages {
            polarizer_er: er_on,
            ..Stages::none()
        };
        let s = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 1).unwrap();
        for step in 0..12 {
            let aolp = 15.0 * step as f64;
            let f = s
                .frame(
                    Radiance::Planes(&flat_field(w, h, 0.1, 1.0, aolp).unwrap()),
                    0,
                    FrameOptions::exact().with_truth(),
                )
                .unwrap();
            let an = f.analog.unwrap();
            let v = |r: usize, c: usize| *an.get(r, c) as f64 - 5.0;
            // IMX250MZR: (0,0)=90, (0,1)=45, (1,0)=135, (1,1)=0
            let (i90, i45, i135, i0) = (v(2, 2), v(2, 3), v(3, 2), v(3, 3));
            let s0 = 0.5 * (i0 + i45 + i90 + i135);
            let (s1, s2) = (i0 - i90, i45 - i135);
            let dolp = s1.hypot(s2) / s0;
            let a = psns::angle::SensorAngle::from_stokes(s1, s2);
            assert!(
                a.diff(psns::angle::SensorAngle::from_deg(aolp)) < 1e-3,
                "{aolp}: {}",
                a.deg()
            );
            let want = if er_on { diattenuation(60.0) } else { 1.0 };
            assert!((dolp - want).abs() < 1e-5, "er {er_on}: dolp {dolp}");
            if !er_on {
                // and equals the ground truth at that pixel
                let t0 = *f.truth.s0.get(3, 3) as f64;
                assert!((s0 / t0 - 1.0).abs() < 1e-5);
                assert!((s1 - *f.truth.s1.get(3, 3) as f64).abs() < 1e-4 * t0);
            }
        }
    }
}

/// With polarizer non-idealities, fixed patterns and noise off, a 12-bit render equals
/// black level + (S0 + S1 cos 2a + S2 sin 2a)/2 of the truth, rounded.
#[test]
fn render_equals_truth_reading_rounded() {
    let (w, h) = (64, 48);
    let mut cfg = SensorConfig::default();
    cfg.black_level_dn = 16.0;
    cfg.stages = Stages::ideal();
    cfg.exposure = psns::sensor::Exposure::Fixed { us: 500.0 };
    for ri in [
        RelativeIllumination::CosPower { n: 1.5 },
        RelativeIllumination::CosPower { n: 4.0 },
        RelativeIllumination::Polynomial {
            k1: -0.3,
            k2: 0.05,
            k3: 0.0,
        },
    ] {
        cfg.ri = ri;
        let scene = sky(w, h);
        let f = simulate(&scene, &Intrinsics::with_size(w, h), &cfg, 3, 0).unwrap();
        let float = simulate_float(&scene, &Intrinsics::with_size(w, h), &cfg).unwrap();
        let (mut exact, mut ties) = (0, 0);
        for r in 0..h {
            for c in 0..w {
                let a = cfg.layout.angle_deg(r, c).to_radians();
                let reading = 0.5
                    * (*f.truth.s0.get(r, c) as f64
                        + *f.truth.s1.get(r, c) as f64 * (2.0 * a).cos()
                        + *f.truth.s2.get(r, c) as f64 * (2.0 * a).sin());
                let want = 16.0 + reading;
                assert!((*float.get(r, c) as f64 - want).abs() < 1e-3);
                let code = *f.codes.get(r, c) as f64;
                // f32 truth cannot decide exact .5 ties; skip those (none expected in practice)
                if (want.fract() - 0.5).abs() < 1e-3 {
                    ties += 1;
                    assert!((code - want).abs() <= 0.5 + 1e-3);
                } else {
                    assert_eq!(code, want.round(), "({r},{c})");
                    exact += 1;
                }
            }
        }
        assert!(exact > w * h - 20, "exact {exact}, ties {ties}");
        assert!(f.codes.data.iter().any(|&v| v > 1000));
        assert!(
            f.codes.data.iter().all(|&v| v < 4095),
            "scene must not clip"
        );
    }
}

/// Another layout can be given: each pixel reads the law of its own angle.
#[test]
fn other_layout() {
    let (w, h) = (8, 8);
    let mut cfg = SensorConfig::default();
    cfg.layout = "0,45/135,90".parse::<MosaicLayout>().unwrap();
    cfg.stages = Stages::none();
    let f = simulate(
        &flat_field(w, h, 0.1, 1.0, 0.0).unwrap(),
        &Intrinsics::with_size(w, h),
        &cfg,
        0,
        0,
    )
    .unwrap();
    let an = f.analog.unwrap();
    // AoLP 0 fully polarized: 0° pixel reads T∥·S0, 90° pixel reads 0, 45/135 read half
    let full = *an.get(0, 0) as f64;
    assert!(full > 0.0);
    assert!((*an.get(1, 1) as f64).abs() < 1e-6 * full);
    assert!((*an.get(0, 1) as f64 / full - 0.5).abs() < 1e-6);
    assert!((*an.get(1, 0) as f64 / full - 0.5).abs() < 1e-6);
}

/// flat_field builds the requested Stokes vector.
#[test]
fn flat_field_values() {
    let f = flat_field(4, 4, 2.0, 0.5, 30.0).unwrap();
    let (s0, s1, s2) = (
        f.s0.data[5] as f64,
        f.s1.data[5] as f64,
        f.s2.data[5] as f64,
    );
    assert!((s0 - 2.0).abs() < 1e-6);
    assert!((s1.hypot(s2) / s0 - 0.5).abs() < 1e-6);
    assert!((psns::angle::SensorAngle::from_stokes(s1, s2).deg() - 30.0).abs() < 1e-4);
    assert!(flat_field(4, 4, 1.0, 1.5, 0.0).is_err());
    let _unused: Image<f32> = f.s0;
}

/// 8-bit output: codes and truth share the output units (12-bit DN / 16), black level too.
#[test]
fn eight_bit_truth_units() {
    let (w, h) = (32, 32);
    let mut cfg = SensorConfig::default();
    cfg.bit_depth = 8;
    cfg.black_level_dn = 32.0;
    cfg.stages = Stages::ideal();
    cfg.exposure = psns::sensor::Exposure::Fixed { us: 500.0 };
    let f = simulate(&sky(w, h), &Intrinsics::with_size(w, h), &cfg, 0, 0).unwrap();
    assert_eq!(f.black_level_dn, 2.0);
    let mut twelve = cfg.clone();
    twelve.bit_depth = 12;
    let g = simulate(&sky(w, h), &Intrinsics::with_size(w, h), &twelve, 0, 0).unwrap();
    for k in 0..w * h {
        assert!((f.truth.s0.data[k] * 16.0 / g.truth.s0.data[k] - 1.0).abs() < 1e-6);
        let a = cfg.layout.angle_deg(k / w, k % w).to_radians();
        let reading = 0.5
            * (f.truth.s0.data[k] as f64
                + f.truth.s1.data[k] as f64 * (2.0 * a).cos()
                + f.truth.s2.data[k] as f64 * (2.0 * a).sin());
        assert!((f.codes.data[k] as f64 - 2.0 - reading).abs() <= 0.5 + 1e-4);
    }
    let (dolp, aolp) = f.truth_dolp_aolp();
    let k = 16 * w + 16;
    let (s1, s2) = (f.truth.s1.data[k] as f64, f.truth.s2.data[k] as f64);
    assert!((dolp.data[k] as f64 - s1.hypot(s2) / f.truth.s0.data[k] as f64).abs() < 1e-6);
    assert!(
        (aolp.data[k] as f64 - psns::angle::SensorAngle::from_stokes(s1, s2).deg()).abs() < 1e-3
    );
}

/// Crosstalk conserves a flat signal and lowers the measured DoLP (effective ER).
#[test]
fn crosstalk_lowers_dolp() {
    let (w, h) = (16, 16);
    let dolp_of = |c: f64| {
        let mut cfg = SensorConfig::default();
        cfg.crosstalk = c;
        cfg.stages = Stages {
            crosstalk: true,
            ..Stages::none()
        };
        let f = simulate(
            &flat_field(w, h, 0.1, 1.0, 0.0).unwrap(),
            &Intrinsics::with_size(w, h),
            &cfg,
            0,
            0,
        )
        .unwrap();
        let an = f.analog.unwrap();
        let v = |r: usize, c: usize| *an.get(r, c) as f64;
        let (i90, i45, i135, i0) = (v(6, 6), v(6, 7), v(7, 6), v(7, 7));
        let s0 = 0.5 * (i0 + i45 + i90 + i135);
        ((i0 - i90).hypot(i45 - i135) / s0, s0)
    };
    let (d0, s00) = dolp_of(0.0);
    let (d3, s03) = dolp_of(0.03);
    assert!((d0 - 1.0).abs() < 1e-6);
    // 0° pixel: edge neighbours 45°/135° (½), corners 90° (0): I0 = 1 − c + 4·c/6·½ = 1 − 2c/3;
    // 90° pixel: edges ½, corners 1: I90 = 2c/6 + 4c/12 = 2c/3; I45 = I135 = ½ → DoLP = 1 − 4c/3
    assert!((d3 - (1.0 - 4.0 * 0.03 / 3.0)).abs() < 1e-5, "{d3}");
    assert!((s03 / s00 - 1.0).abs() < 1e-6);
}
