use super::*;

/// The truth's DoLP and AoLP by vmath agree with libm's (hypot, atan2, SensorAngle) to the
/// last f32 bit but for rare roundings, and exactly at the edge cases tested (zeros of both
/// signs, s0 ≤ 0, subnormals; infinite S1 and S2 would differ: truth Stokes are finite).
#[test]
fn truth_dolp_aolp_is_libm_to_an_ulp() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let (w, h) = (1000, 200);
    let mut t = StokesImage::zeros(w, h);
    for k in 0..w * h {
        let s0: f32 = rng.random_range(0.0..1e4);
        let (p, a): (f32, f32) = (rng.random_range(0.0..1.0), rng.random_range(-3.2..3.2));
        (t.s0.data[k], t.s1.data[k], t.s2.data[k]) = (s0, s0 * p * a.cos(), s0 * p * a.sin());
    }
    let edges = [
        (0.0, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (1.0, -0.0, 0.0),
        (1.0, -1.0, 0.0),
        (1.0, -1.0, -0.0),
        (1.0, 0.0, 1.0),
        (1.0, 0.0, -1.0),
        (-1.0, 0.5, 0.5),
        (0.0, 1e-30, -1e-30),
        (2.0, f32::MIN_POSITIVE, -f32::MIN_POSITIVE),
    ];
    for (k, &(a, b, c)) in edges.iter().enumerate() {
        (t.s0.data[k], t.s1.data[k], t.s2.data[k]) = (a, b, c);
    }
    let (dolp, aolp) = dolp_aolp_f64(&t);
    let ulps = |a: f32, b: f32| (a.to_bits() as i64 - b.to_bits() as i64).abs();
    let mut off = 0;
    for k in 0..w * h {
        let (s0, s1, s2) = (
            t.s0.data[k] as f64,
            t.s1.data[k] as f64,
            t.s2.data[k] as f64,
        );
        let d = if s0 > 0.0 {
            (s1.hypot(s2) / s0) as f32
        } else {
            0.0
        };
        let a = crate::angle::SensorAngle::from_stokes(s1, s2).deg() as f32;
        let (ud, ua) = (ulps(dolp.data[k], d), ulps(aolp.data[k], a));
        if k < edges.len() {
            assert_eq!(
                (dolp.data[k].to_bits(), aolp.data[k].to_bits()),
                (d.to_bits(), a.to_bits()),
                "{:?}",
                edges[k]
            );
        }
        // (AoLP just below 180 may round up to 180 in f32 either way: compare mod 180)
        let ua = ua
            .min(ulps((aolp.data[k] - 180.0).abs(), a).min(ulps(aolp.data[k], (a - 180.0).abs())));
        assert!(ud <= 1 && ua <= 1, "pixel {k}: {ud} and {ua} ulp");
        off += (ud + ua > 0) as usize;
    }
    // every instruction set gives the same bits (the kernel on this thread, where
    // `with_simd` applies)
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for level in crate::simd::Simd::available() {
        let (mut d, mut a) = (vec![0f32; w * h], vec![0f32; w * h]);
        crate::simd::with_simd(level, || {
            dolp_aolp_row(&t.s0.data, &t.s1.data, &t.s2.data, &mut d, &mut a)
        });
        assert_eq!(bits(&d), bits(&dolp.data), "{level:?}");
        assert_eq!(bits(&a), bits(&aolp.data), "{level:?}");
    }
    // rare: a last-bit difference needs the f64 value within 2 ulp of an f32 rounding point
    assert!(off < 20, "{off} of {} pixels differ in the last bit", w * h);
}

#[test]
fn config_serde_round_trip() {
    for p in Preset::ALL {
        let c = SensorConfig::preset(p);
        let j = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<SensorConfig>(&j).unwrap(), c);
        let t = toml::to_string(&c).unwrap();
        assert_eq!(toml::from_str::<SensorConfig>(&t).unwrap(), c);
    }
    let c: SensorConfig =
        toml::from_str("gain_db = 6.0\nlayout = \"0,45/135,90\"\n[exposure]\nmode = \"auto\"\npercentile = 95.0\nfraction = 0.5\n")
            .unwrap();
    assert_eq!(c.gain_db, 6.0);
    assert_eq!(c.layout.angle_deg(0, 0), 0.0);
    assert!(matches!(c.exposure, Exposure::Auto { .. }));
    assert!(toml::from_str::<SensorConfig>("gain = 6.0").is_err());
}

#[test]
fn sizes() {
    assert!(check_size(2448, 2048).is_ok());
    assert!(check_size(8, 4).is_ok());
    assert!(check_size(6, 4).is_err());
    assert!(check_size(0, 4).is_err());
}
