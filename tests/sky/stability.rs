//! The default DOP (`wang-bounded`) is stable over the accepted domain
//! (turbidity 1.7..10, sun zenith 0..90°, wavelength 380..720 nm), the published formula
//! (`wang-paper`) is not, and the two agree exactly at the default scene.

use psns::angle::direction;
use psns::sky::dop::WangDop;
use psns::sky::stability::{stability, Grid, Stability};
use psns::sky::{DopModel, DopNorm, PolarizationField, SkyParams};
use psns::sun::SunPosition;

fn params(model: DopModel, t: f64, lambda: f64) -> SkyParams {
    SkyParams {
        turbidity: t,
        wavelength_nm: lambda,
        dop_model: model,
        ..SkyParams::default()
    }
}

/// Unstable cases on a coarse grid of the domain, with their statistics.
fn unstable(
    model: DopModel,
    ts: &[f64],
    zs: &[f64],
    ls: &[f64],
) -> Vec<(f64, f64, f64, Stability)> {
    let mut bad = Vec::new();
    for &t in ts {
        for &z in zs {
            for &l in ls {
                let st = stability(z, &params(model, t, l), Grid::default()).unwrap();
                if !st.is_stable() {
                    bad.push((t, z, l, st));
                }
            }
        }
    }
    bad
}

const T_COARSE: [f64; 6] = [1.7, 2.0, 3.0, 4.0, 6.0, 10.0];
const Z_COARSE: [f64; 11] = [
    0.0, 10.0, 30.0, 50.0, 70.0, 80.0, 84.0, 85.0, 86.5, 88.0, 90.0,
];
const L_COARSE: [f64; 4] = [380.0, 450.0, 550.0, 720.0];

/// No direction pinned at ≤ 0.001 (40..140° from the sun) or ≥ 0.95, no jump above 0.15
/// between directions 2° apart in zenith, over a coarse grid of the domain. Fails for the
/// published formula (checked: 92 of the 264 cases fail with it as the default).
#[test]
fn default_dop_is_stable_over_the_domain() {
    let bad = unstable(DopModel::default(), &T_COARSE, &Z_COARSE, &L_COARSE);
    assert!(
        bad.is_empty(),
        "{} unstable: {:?}",
        bad.len(),
        &bad[..bad.len().min(5)]
    );
}

/// The failing cases, measured with the published formula: the statistics this module reports.
#[test]
fn paper_formula_fails_in_the_known_cases() {
    let paper =
        |t, z| stability(z, &params(DopModel::WangPaper, t, 450.0), Grid::default()).unwrap();
    let s = paper(4.0, 85.0);
    assert!(s.low_fraction() > 0.05, "{s:?}"); // 246 of 3408
    let s = paper(4.0, 86.5);
    assert!(
        s.pinned_low > 1000 && s.pinned_high > 1000 && s.max_jump > 0.15,
        "{s:?}"
    );
    let s = paper(10.0, 70.0);
    assert!(s.low_fraction() > 0.25, "{s:?}"); // 995 of 3360
    let s = paper(2.0, 10.0);
    assert!(s.high_fraction() > 0.3, "{s:?}"); // 1479 of 4050
    let s = paper(1.5, 50.0);
    assert!(s.low_fraction() > 0.5 && s.max_jump > 0.9, "{s:?}");
    let bad = unstable(DopModel::WangPaper, &T_COARSE, &Z_COARSE, &L_COARSE);
    assert_eq!(bad.len(), 92);
}

/// Continuous in sun position: moving the sun by 0.25° changes no direction's DOP by more than
/// 0.05 (sun zenith 0..90°). The published formula jumps by up to 1 near θ_s = 86°.
#[test]
fn default_dop_is_continuous_in_sun_position() {
    fn worst(model: DopModel, t: f64, l: f64) -> (f64, f64) {
        let dirs: Vec<_> = (0..15)
            .flat_map(|i| (0..12).map(move |j| direction(3.0 + 6.0 * i as f64, 30.0 * j as f64)))
            .collect();
        let p = params(model, t, l);
        let eval = |z: f64| -> Vec<f64> {
            let f = PolarizationField::new(SunPosition::new(z, 0.0), &p).unwrap();
            dirs.iter().map(|&v| f.sample(v).dop).collect()
        };
        let (mut w, mut at) = (0.0f64, 0.0);
        let mut prev = eval(0.0);
        for k in 1..=360 {
            let z = k as f64 * 0.25;
            let cur = eval(z);
            for (a, b) in prev.iter().zip(&cur) {
                if (a - b).abs() > w {
                    w = (a - b).abs();
                    at = z;
                }
            }
            prev = cur;
        }
        (w, at)
    }
    for (t, l) in [(4.0, 450.0), (1.7, 450.0), (10.0, 380.0), (2.0, 720.0)] {
        let (w, at) = worst(DopModel::default(), t, l);
        assert!(w < 0.05, "T {t} λ {l}: ΔDOP {w} at sun zenith {at}");
    }
    let (w, at) = worst(DopModel::WangPaper, 4.0, 450.0);
    assert!(w > 0.5 && at > 85.0 && at < 88.0, "{w} at {at}");
}

/// At the default scene (sun zenith 50°, T 4, 450 nm, albedo 0.1) the default model gives the
/// published formula's values bit for bit, for every neutral-point distance and both norms.
#[test]
fn default_scene_is_the_paper_bit_for_bit() {
    for delta in [0.0, 15.0, 25.0, 60.0] {
        for norm in [DopNorm::Clamp, DopNorm::Wilkie] {
            let mk = |m| {
                let p = SkyParams {
                    babinet_deg: delta,
                    brewster_deg: delta,
                    dop_norm: norm,
                    dop_model: m,
                    ..SkyParams::default()
                };
                PolarizationField::new(SunPosition::new(50.0, 200.0), &p).unwrap()
            };
            let (a, b) = (mk(DopModel::WangBounded), mk(DopModel::WangPaper));
            for i in 0..90 {
                for j in 0..180 {
                    let v = direction(0.5 + i as f64, 2.0 * j as f64);
                    assert_eq!(a.sample(v).dop, b.sample(v).dop, "δ {delta} {v}");
                }
            }
        }
    }
}

#[test]
fn bounded_model_refuses_turbidity_below_1_7() {
    let e = WangDop::with_model(50.0, 1.5, 450.0, 0.1, DopNorm::Clamp, DopModel::WangBounded)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("turbidity = 1.5 is out of range (allowed 1.7..10"),
        "{e}"
    );
    assert!(e.contains("1..10 with --dop-model wang-paper"), "{e}");
    assert!(
        WangDop::with_model(50.0, 1.7, 450.0, 0.1, DopNorm::Clamp, DopModel::WangBounded).is_ok()
    );
    // the Rayleigh model does not use eq. (5): every turbidity of the radiance is accepted
    let p = SkyParams {
        model: psns::sky::PolarizationModel::Rayleigh,
        turbidity: 1.0,
        ..SkyParams::default()
    };
    assert!(PolarizationField::new(SunPosition::new(50.0, 0.0), &p).is_ok());
}

#[test]
fn scene_files_without_dop_model_load_with_the_default() {
    let p: SkyParams = serde_json::from_str(r#"{"turbidity": 3.0}"#).unwrap();
    assert_eq!(p.dop_model, DopModel::WangBounded);
    let p: SkyParams = serde_json::from_str(r#"{"dop_model": "wang-paper"}"#).unwrap();
    assert_eq!(p.dop_model, DopModel::WangPaper);
    let j = serde_json::to_string(&SkyParams::default()).unwrap();
    assert!(j.contains(r#""dop_model":"wang-bounded""#), "{j}");
}

/// Dense sweep: turbidity 1.7..10 every 0.1, sun zenith 0..90 every 1°, wavelength 380..720
/// every 20 nm (`cargo test --release --test sky -- --ignored --nocapture`; measured:
/// 0 of 137 592 unstable, 14 min at low priority on 2 shared cores).
#[test]
#[ignore]
fn dense_sweep_of_the_domain() {
    let ts: Vec<f64> = (0..=83).map(|i| 1.7 + 0.1 * i as f64).collect();
    let zs: Vec<f64> = (0..=90).map(|i| i as f64).collect();
    let ls: Vec<f64> = (0..=17).map(|i| 380.0 + 20.0 * i as f64).collect();
    let bad = unstable(DopModel::WangBounded, &ts, &zs, &ls);
    println!(
        "{} of {} unstable",
        bad.len(),
        ts.len() * zs.len() * ls.len()
    );
    for b in bad.iter().take(20) {
        println!("{b:?}");
    }
    assert!(bad.is_empty());
}
