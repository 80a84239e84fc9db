//! Spectral response of the sensor: the quantum efficiency η(λ) and the wire
//! grid's pass transmission T∥(λ) follow a wavelength curve, so `--wavelength` (the band-pass
//! centre λ_c) changes electron counts as a real sensor's response does.

use psns::camera::Intrinsics;
use psns::config::SceneConfig;
use psns::sensor::spectral::{Spectral, PASS_TRANSMISSION_IMX250MZR, QE_IMX250};
use psns::sensor::{flat_field, Sensor, SensorConfig, Stages};

/// Noise-free electron rate of an on-axis pixel under an unpolarized flat field of radiance 0.1
/// at band-pass centre `nm`, ideal polarizer or with ER(λ).
fn rate(nm: f64, er: bool) -> f64 {
    let mut cfg = SensorConfig {
        filter_center_nm: nm,
        ..SensorConfig::default()
    };
    cfg.stages = Stages {
        polarizer_er: er,
        ..Stages::none()
    };
    let s = Sensor::new(&cfg, &Intrinsics::with_size(8, 8), 0).unwrap();
    s.electron_rate(&flat_field(8, 8, 0.1, 0.0, 0.0).unwrap())
        .unwrap()[0]
}

#[test]
fn electrons_at_450_and_650_nm_follow_the_curves() {
    let cfg = SensorConfig::default();
    let (qe, tp) = (&cfg.qe, &cfg.pass_transmission);
    // photons per watt ∝ λ, times η(λ) T∥(λ); ideal polarizer
    let want = 650.0 / 450.0 * (qe.at(650.0) * tp.at(650.0)) / (qe.at(450.0) * tp.at(450.0));
    let got = rate(650.0, false) / rate(450.0, false);
    assert!(
        (got / want - 1.0).abs() < 1e-12,
        "ratio {got}, curves {want}"
    );
    // the curves really differ from constants: η falls to 0.5625 and T∥ rises to 0.87 at 650 nm
    assert!((want - 650.0 / 450.0 * 0.5625 * 0.87 / (0.60 * 0.8)).abs() < 1e-12);
    assert!(
        (got - 1.444).abs() > 0.02,
        "constant QE and T∥ would give 650/450 = 1.444"
    );
    // with the extinction ratio as well: × (1 + 1/ER(650)) / (1 + 1/ER(450)), ER 180 and 60
    let want_er = want * (1.0 + 1.0 / 180.0) / (1.0 + 1.0 / 60.0);
    let got_er = rate(650.0, true) / rate(450.0, true);
    assert!(
        (got_er / want_er - 1.0).abs() < 1e-12,
        "{got_er} vs {want_er}"
    );
    // blue end: 400 nm has η 0.45, T∥ 0.68
    let want_400 = 400.0 / 450.0 * 0.45 * 0.68 / (0.60 * 0.8);
    assert!((rate(400.0, false) / rate(450.0, false) / want_400 - 1.0).abs() < 1e-12);
}

#[test]
fn curve_values_at_tabulated_points_and_between() {
    let cfg = SensorConfig::default();
    for p in QE_IMX250 {
        assert_eq!(cfg.qe.at(p[0]), p[1], "η at {} nm", p[0]);
    }
    for p in PASS_TRANSMISSION_IMX250MZR {
        assert_eq!(cfg.pass_transmission.at(p[0]), p[1], "T∥ at {} nm", p[0]);
    }
    // the specification's values at the default 450 nm, exactly: the default frames stay
    assert_eq!(cfg.qe_at_filter(), 0.60);
    assert_eq!(cfg.pass_transmission_at_filter(), 0.8);
    // peak near 540 nm (Pregius mono ≈ 70 %), linear in between, flat beyond the ends
    assert_eq!(cfg.qe.at(530.0), 0.70);
    assert!((cfg.qe.at(470.0) - 0.6375).abs() < 1e-12);
    assert!((cfg.pass_transmission.at(410.0) - 0.705).abs() < 1e-12);
    assert_eq!(cfg.qe.at(380.0), 0.33);
    assert_eq!(cfg.qe.at(720.0), 0.43);
    let max = QE_IMX250.iter().map(|p| p[1]).fold(0.0, f64::max);
    assert_eq!(max, 0.70);
}

/// A scene file written before the curves holds `qe = 0.6` and `pass_transmission = 0.8`: it
/// still loads, as constants, and reproduces its old electron counts at any wavelength.
#[test]
fn numbers_load_as_constants_and_bad_curves_are_refused() {
    let c: SensorConfig =
        serde_json::from_str(r#"{"qe": 0.6, "pass_transmission": 0.8, "filter_center_nm": 650}"#)
            .unwrap();
    assert_eq!(c.qe, Spectral::Constant(0.6));
    assert_eq!(c.qe_at_filter(), 0.6);
    assert_eq!(c.pass_transmission_at_filter(), 0.8);
    let t: SensorConfig = toml::from_str("qe = [[400.0, 0.5], [700.0, 0.4]]\n").unwrap();
    assert_eq!(t.qe.at(550.0), 0.45);
    for bad in [
        r#"{"qe": 1.2}"#,
        r#"{"qe": [[400, 0.5], [400, 0.6]]}"#,
        r#"{"pass_transmission": [[400, -0.1]]}"#,
        r#"{"qe": []}"#,
    ] {
        let c: SensorConfig = serde_json::from_str(bad).unwrap();
        let e = c.validate(8, 8).unwrap_err();
        assert!(e.is_usage(), "{bad}: {e}");
    }
}

/// The sky wavelength sets λ_c for raw frames (`--wavelength`): the pipeline's sensor evaluates
/// the curves there.
#[test]
fn scene_wavelength_sets_the_curves_point() {
    let mut cfg = SceneConfig::default();
    cfg.sky.wavelength_nm = 650.0;
    let s = cfg.raw.effective_sensor(cfg.sky.wavelength_nm);
    assert_eq!(s.filter_center_nm, 650.0);
    assert!((s.qe_at_filter() - 0.5625).abs() < 1e-12);
    assert_eq!(s.pass_transmission_at_filter(), 0.87);
}
