//! Oracles #1 and #2 of `sky.md` §9 for the Hosek–Wilkie model, plus the solar disc and ranges.

use psns::sky::hosek::{embedded_data, HosekWilkie, LICENSE, SUN_RADIUS_RAD};
use sha2::{Digest, Sha256};

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn embedded_data_sha256_matches_readme() {
    let want = [
        (
            "sky_params_spectral.f64le",
            "2c6f374440ae95dc1d0d59c88edd5c3ead251498f50522ef85879555d8d50193",
        ),
        (
            "sky_radiance_spectral.f64le",
            "a6b3eb5e14485e18c626754031bb16501ad9b3f8b1156b106d4c89fcf93afada",
        ),
        (
            "sun_radiance_spectral.f64le",
            "7cc33a40eedc6ad76d51e3c98b9e5706225349cce766a8c4d8c8c7afd24fd773",
        ),
        (
            "sun_limb_darkening_spectral.f64le",
            "08e31d5ad992c444306abd5ea3e74cabf69d5b2c366d9eb9e4e7307c37af9ba2",
        ),
    ];
    let got = embedded_data();
    assert_eq!(got.len(), want.len());
    for ((name, bytes), (wname, whash)) in got.iter().zip(want.iter()) {
        assert_eq!(name, wname);
        let h = Sha256::digest(bytes);
        let hex: String = h.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(&hex, whash, "{name}");
    }
    assert!(LICENSE.contains("Lukas Hosek and Alexander Wilkie"));
}

#[test]
fn readme_check_table() {
    let hw: Vec<HosekWilkie> = [440.0, 450.0, 555.0]
        .iter()
        .map(|&l| HosekWilkie::new(4.0, 0.1, 40f64.to_radians(), l).unwrap())
        .collect();
    let g3 = (45f64.to_radians().cos() * 50f64.to_radians().cos()).acos();
    assert!((g3.to_degrees() - 62.965979).abs() < 1e-6);
    let rows: [(f64, f64, [f64; 3]); 4] = [
        (
            0.0,
            50f64.to_radians(),
            [7.630329e-2, 7.414022e-2, 3.765946e-2],
        ),
        (
            30.0,
            20f64.to_radians(),
            [1.464068e-1, 1.479656e-1, 1.102958e-1],
        ),
        (45.0, g3, [9.751332e-2, 9.494446e-2, 4.791516e-2]),
        (
            60.0,
            10f64.to_radians(),
            [3.484945e-1, 3.633880e-1, 3.413121e-1],
        ),
    ];
    let mut worst = 0.0f64;
    for (theta, gamma, want) in rows {
        for (m, w) in hw.iter().zip(want) {
            let l = m.radiance(theta.to_radians(), gamma);
            let e = rel(l, w);
            worst = worst.max(e);
            // The table is printed to 7 significant digits: allow its rounding (≤ 7e-7 rel.).
            assert!(
                e <= 1e-6,
                "theta {theta} gamma {gamma} lambda {}: {l} vs {w} ({e:e})",
                m.wavelength_nm()
            );
        }
    }
    println!("README check table: max rel. error {worst:e}");
}

#[test]
fn all_testvectors() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/sky-hw-testvectors.csv"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let mut n = 0;
    let mut worst = 0.0f64;
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line.split(',').map(|s| s.trim().parse().unwrap()).collect();
        let [t, a, eta, theta, gamma, lambda, want] = v[..] else {
            panic!("bad line {line}")
        };
        let m = HosekWilkie::new(t, a, eta.to_radians(), lambda).unwrap();
        let l = m.radiance(theta.to_radians(), gamma.to_radians());
        let e = rel(l, want);
        worst = worst.max(e);
        assert!(e <= 1e-6, "{line}: got {l:e} ({e:e})");
        // The fast entry point is the same function.
        let l2 = m.radiance_cos(
            theta.to_radians().cos(),
            gamma.to_radians(),
            gamma.to_radians().cos(),
        );
        assert_eq!(l, l2);
        n += 1;
    }
    assert_eq!(n, 144);
    println!("sky-hw-testvectors: {n} rows, max rel. error {worst:e}");
}

#[test]
fn wavelength_interpolates_radiances_not_coefficients() {
    // 450 nm = 0.75 L(440) + 0.25 L(480), at a direction where the two differ.
    let eta = 40f64.to_radians();
    let l = |lam: f64| {
        HosekWilkie::new(4.0, 0.1, eta, lam)
            .unwrap()
            .radiance(1.2, 0.3)
    };
    let mix = 0.75 * l(440.0) + 0.25 * l(480.0);
    assert!(rel(l(450.0), mix) < 1e-14, "{} vs {mix}", l(450.0));
    // Continuity at a channel and at the ends.
    assert!(rel(l(440.0 + 1e-9), l(440.0)) < 1e-9);
    assert!(rel(l(720.0 - 1e-9), l(720.0)) < 1e-9);
    assert!(rel(l(320.0 + 1e-9), l(320.0)) < 1e-9);
}

#[test]
fn turbidity_ten_and_continuity() {
    let eta = 25f64.to_radians();
    let l = |t: f64| {
        HosekWilkie::new(t, 0.3, eta, 500.0)
            .unwrap()
            .radiance(0.7, 0.9)
    };
    assert!(l(10.0).is_finite() && l(10.0) > 0.0);
    assert!(rel(l(10.0 - 1e-9), l(10.0)) < 1e-7);
    assert!(rel(l(4.0 - 1e-9), l(4.0)) < 1e-7);
    assert!(rel(l(1.0 + 1e-9), l(1.0)) < 1e-7);
}

#[test]
fn horizon_and_sun_extremes_are_finite() {
    for &eta in &[0.0, 1e-6, 0.3, std::f64::consts::FRAC_PI_2] {
        for &t in &[1.0, 5.5, 10.0] {
            let m = HosekWilkie::new(t, 1.0, eta, 720.0).unwrap();
            for &(th, g) in &[(0.0, 0.0), (std::f64::consts::FRAC_PI_2, 0.0), (1.0, 3.1)] {
                let l = m.radiance(th, g);
                assert!(l.is_finite() && l > 0.0, "T {t} eta {eta} ({th},{g}): {l}");
            }
            let s = m.sun_radiance(0.0);
            assert!(s.is_finite() && s >= 0.0);
        }
    }
}

#[test]
fn sun_disc() {
    let eta = 40f64.to_radians();
    let m = HosekWilkie::new(4.0, 0.1, eta, 450.0).unwrap();
    let centre = m.sun_radiance(0.0);
    let zenith = m.radiance(0.0, std::f64::consts::FRAC_PI_2 - eta);
    println!(
        "sun centre 450 nm T4 eta40: {centre:.6e} W m-2 sr-1 nm-1 (unlimbed {:.6e}), zenith sky {zenith:.6e}, ratio {:.4e}",
        m.sun_radiance_unlimbed(),
        centre / zenith
    );
    // sky.md §3: ~1.6e4 and ~2e5 times the zenith sky.
    assert!((1.4e4..1.8e4).contains(&centre), "{centre}");
    assert!(
        (1.7e5..2.3e5).contains(&(centre / zenith)),
        "{}",
        centre / zenith
    );
    // Limb darkening: monotone decrease toward the edge, clearly darker there.
    let mut prev = centre;
    for i in 1..=20 {
        let g = SUN_RADIUS_RAD * (i as f64 / 20.0) * 0.999_999;
        let s = m.sun_radiance(g);
        assert!(s > 0.0 && s < prev, "gamma {g}: {s} !< {prev}");
        prev = s;
    }
    assert!(prev < 0.6 * centre, "limb {prev} vs centre {centre}");
    assert_eq!(m.sun_radiance(SUN_RADIUS_RAD), 0.0);
    assert_eq!(m.sun_radiance(0.01), 0.0);
    assert_eq!(m.sun_radiance(f64::NAN), 0.0);
    // Redder light: the disc is brighter at 555 nm than 320 nm.
    let red = HosekWilkie::new(4.0, 0.1, eta, 555.0)
        .unwrap()
        .sun_radiance(0.0);
    let uv = HosekWilkie::new(4.0, 0.1, eta, 320.0)
        .unwrap()
        .sun_radiance(0.0);
    assert!(red > uv);
    // Turbidity dims the disc.
    let hazy = HosekWilkie::new(8.0, 0.1, eta, 450.0)
        .unwrap()
        .sun_radiance(0.0);
    assert!(hazy < centre);
}

#[test]
fn range_errors() {
    let e = 0.5;
    assert!(HosekWilkie::new(0.99, 0.1, e, 450.0).is_err());
    assert!(HosekWilkie::new(10.01, 0.1, e, 450.0).is_err());
    assert!(HosekWilkie::new(f64::NAN, 0.1, e, 450.0).is_err());
    assert!(HosekWilkie::new(4.0, -0.01, e, 450.0).is_err());
    assert!(HosekWilkie::new(4.0, 1.01, e, 450.0).is_err());
    assert!(HosekWilkie::new(4.0, 0.1, -0.01, 450.0).is_err());
    assert!(HosekWilkie::new(4.0, 0.1, 1.6, 450.0).is_err());
    assert!(HosekWilkie::new(4.0, 0.1, e, 319.9).is_err());
    assert!(HosekWilkie::new(4.0, 0.1, e, 720.1).is_err());
    assert!(HosekWilkie::new(4.0, 0.1, e, f64::INFINITY).is_err());
    let err = HosekWilkie::new(12.0, 0.1, e, 450.0).unwrap_err();
    assert!(err.is_usage());
    assert_eq!(
        err.to_string(),
        "turbidity = 12 is out of range (allowed 1..10)"
    );
    assert!(HosekWilkie::new(1.0, 0.0, 0.0, 320.0).is_ok());
    assert!(HosekWilkie::new(10.0, 1.0, std::f64::consts::FRAC_PI_2, 720.0).is_ok());
}
