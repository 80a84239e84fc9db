//! The sky seen through the camera: yaw covariance of the AOP image, the Rayleigh oracle through
//! the projection (sky.md §9 #10), Berry's split-to-zero limit at the sensor, and no NaN for any
//! attitude.

use glam::DVec3;
use proptest::prelude::*;
use psns::camera::{Attitude, Camera, Intrinsics};
use psns::render::{pixel_sky, render_ideal};
use psns::sky::{PolarizationModel, Sky, SkyParams};
use psns::sun::SunPosition;

fn axial(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(180.0);
    d.min(180.0 - d)
}

fn cam(att: Attitude, sun_az: f64) -> Camera {
    Camera::new(Intrinsics::default(), &att, sun_az).unwrap()
}

#[test]
fn yaw_rotates_the_aop_image() {
    // A zenith camera yawed by ψ sees at offset R(ψ)u what the unyawed camera sees at u, with the
    // AOP turned by +ψ (sensor angles run from +x toward +y).
    let sky = Sky::new(SunPosition::new(50.0, 200.0), &SkyParams::default()).unwrap();
    let c0 = cam(Attitude::enu(0.0, 0.0, 0.0), 200.0);
    let (pc, pr) = Intrinsics::default().principal();
    for &psi in &[17.0f64, 90.0, 200.0, -45.0] {
        let cy = cam(Attitude::enu(psi, 0.0, 0.0), 200.0);
        let (s, c) = psi.to_radians().sin_cos();
        for &(ux, uy) in &[
            (0.0, 0.0),
            (300.0, -200.0),
            (-700.0, 650.0),
            (1000.0, 900.0),
        ] {
            let a0 = pixel_sky(&sky, &c0, pc + ux, pr + uy);
            let (rx, ry) = (c * ux - s * uy, s * ux + c * uy);
            let a1 = pixel_sky(&sky, &cy, pc + rx, pr + ry);
            assert!((a0.li - a1.li).abs() <= 1e-12 * a0.li, "LI at {ux},{uy}");
            assert!((a0.dop - a1.dop).abs() < 1e-12);
            let d = axial(a1.aop_deg(), a0.aop_deg() + psi);
            assert!(
                d < 1e-9,
                "psi {psi} u ({ux},{uy}): {} vs {} + psi",
                a1.aop_deg(),
                a0.aop_deg()
            );
        }
    }
    // sky.md §9 camera table: centre pixel AOP 160° at ψ = 0 and 0° at ψ = 200°
    let p = pixel_sky(&sky, &c0, pc, pr);
    assert!(axial(p.aop_deg(), 160.0) < 1e-3 && (p.dop - 0.1588).abs() < 1e-4);
}

#[test]
fn spec_camera_table() {
    let sky = Sky::new(SunPosition::new(50.0, 200.0), &SkyParams::default()).unwrap();
    let rows = [
        ((1223.5, 1023.5), (200.0, 0.0, 0.0), 0.1588, 0.000),
        ((0.0, 0.0), (0.0, 0.0, 0.0), 0.1348, 69.943),
        ((2447.0, 2047.0), (0.0, 0.0, 0.0), 0.5303, 144.333),
        ((1223.5, 1023.5), (30.0, 10.0, -5.0), 0.0958, 22.386),
        ((0.0, 0.0), (30.0, 10.0, -5.0), 0.3523, 92.082),
    ];
    for ((c, r), (y, p, ro), dop, aop) in rows {
        let cm = cam(Attitude::enu(y, p, ro), 200.0);
        let s = pixel_sky(&sky, &cm, c, r);
        assert!(
            (s.dop - dop).abs() < 1e-4,
            "({c},{r}) {y},{p},{ro}: dop {}",
            s.dop
        );
        assert!(
            axial(s.aop_deg(), aop) < 1e-3,
            "({c},{r}) {y},{p},{ro}: aop {}",
            s.aop_deg()
        );
    }
}

fn sensor_aop_of(e_enu: DVec3, cam: &Camera) -> f64 {
    let e = cam.enu_to_camera * e_enu;
    (e.y.atan2(e.x).to_degrees()).rem_euclid(180.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// sky.md §9 #10: Rayleigh through the camera equals the projected s × v.
    #[test]
    fn rayleigh_chain_equals_projected_s_cross_v(
        yaw in -180.0f64..180.0, pitch in -60.0f64..60.0, roll in -60.0f64..60.0,
        col in 0.0f64..2447.0, row in 0.0f64..2047.0,
        sz in 1.0f64..89.0, sa in 0.0f64..360.0,
    ) {
        let sun = SunPosition::new(sz, sa);
        let p = SkyParams { model: PolarizationModel::Rayleigh, ..SkyParams::default() };
        let sky = Sky::new(sun, &p).unwrap();
        let cm = cam(Attitude::enu(yaw, pitch, roll), sa);
        let v = cm.pixel_direction(col, row).unwrap();
        let px = pixel_sky(&sky, &cm, col, row);
        if v.z > 1e-6 && px.dop > 1e-6 {
            let e = sun.vector().cross(v);
            prop_assert!(axial(px.aop_deg(), sensor_aop_of(e, &cm)) < 1e-9);
        }
    }

    /// Berry with both neutral points at distance 0 is Rayleigh's E-vector field at the sensor.
    #[test]
    fn berry_split_zero_matches_rayleigh_at_the_sensor(
        yaw in -180.0f64..180.0, pitch in -40.0f64..40.0,
        col in 0.0f64..2447.0, row in 0.0f64..2047.0,
        sz in 1.0f64..89.0,
    ) {
        let sun = SunPosition::new(sz, 123.0);
        let w = SkyParams { babinet_deg: 0.0, brewster_deg: 0.0, ..SkyParams::default() };
        let r = SkyParams { model: PolarizationModel::Rayleigh, ..SkyParams::default() };
        let (sw, sr) = (Sky::new(sun, &w).unwrap(), Sky::new(sun, &r).unwrap());
        let cm = cam(Attitude::enu(yaw, pitch, 0.0), 123.0);
        let (a, b) = (pixel_sky(&sw, &cm, col, row), pixel_sky(&sr, &cm, col, row));
        if a.valid && a.dop > 1e-6 && b.dop > 1e-6 {
            prop_assert!(axial(a.aop_deg(), b.aop_deg()) < 1e-6, "{} vs {}", a.aop_deg(), b.aop_deg());
        }
    }

    /// Any attitude and sun zenith 0..90: finite images, DOP in [0, 1], AOP in [0, 180).
    #[test]
    fn no_nan_for_any_attitude(
        yaw in -720.0f64..720.0, pitch in -180.0f64..180.0, roll in -180.0f64..180.0,
        sz in 0.0f64..=90.0, sa in 0.0f64..360.0, rayleigh in any::<bool>(),
    ) {
        let p = SkyParams {
            model: if rayleigh { PolarizationModel::Rayleigh } else { PolarizationModel::Wang },
            ..SkyParams::default()
        };
        let sky = Sky::new(SunPosition::new(sz, sa), &p).unwrap();
        let i = Intrinsics { width: 24, height: 20, pixel_pitch_um: 3.45 * 2448.0 / 24.0, ..Intrinsics::default() };
        let cm = Camera::new(i, &Attitude::enu(yaw, pitch, roll), sa).unwrap();
        let im = render_ideal(&sky, &cm);
        for k in 0..im.li.data.len() {
            prop_assert!(im.li.data[k].is_finite() && im.li.data[k] >= 0.0);
            prop_assert!((0.0..=1.0).contains(&im.dop.data[k]));
            prop_assert!((0.0..180.0).contains(&im.aop_deg.data[k]));
            if im.valid.data[k] == 0 {
                prop_assert!(im.li.data[k] == 0.0 && im.dop.data[k] == 0.0 && im.aop_deg.data[k] == 0.0);
            }
        }
    }
}
