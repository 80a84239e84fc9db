//! Issue test: the clear sky rendered by the real sky model and camera, through the sensor with
//! no noise, quantisation, fixed patterns or polarizer non-idealities (a float mosaic):
//! bilinear and better recover the true AoLP within 0.01°.

use crate::common;
use common::simulate_float;
use psns::camera::{Attitude, Camera, Intrinsics};
use psns::demosaic::{demosaic, Method};
use psns::image::StokesImage;
use psns::render::{render_stokes, StokesOptions};
use psns::sensor::SensorConfig;
use psns::sky::{Sky, SkyParams};
use psns::sun::SunPosition;

/// A 512 × 512 window of the default 2448 × 2048 camera (real pixel pitch and focal length), so the
/// sky varies across pixels exactly as in a full frame; `corner` picks where in the frame.
fn window(corner: (f64, f64)) -> (StokesImage, Intrinsics) {
    let full = Intrinsics::default();
    let (pc, pr) = full.principal();
    let i = Intrinsics {
        width: 512,
        height: 512,
        principal_point: Some([pc - corner.0, pr - corner.1]),
        ..full
    };
    let sky = Sky::new(SunPosition::new(50.0, 200.0), &SkyParams::default()).unwrap();
    let cam = Camera::new(i, &Attitude::default(), 200.0).unwrap();
    let (st, _) = render_stokes(&sky, &cam, StokesOptions { sun_disc: false });
    (st, i)
}

#[test]
fn float_mosaic_of_the_clear_sky_recovers_aolp_within_a_hundredth_degree() {
    let mut cfg = SensorConfig::default();
    cfg.stages = psns::sensor::Stages::none();
    for corner in [(0.0, 0.0), (968.0, 768.0), (1936.0, 1536.0)] {
        let (st, i) = window(corner);
        let raw = simulate_float(&st, &i, &cfg).unwrap();
        for m in [
            Method::Superpixel,
            Method::Bilinear,
            Method::Bicubic,
            Method::Ppid,
            Method::Newton,
            Method::Eari,
        ] {
            let est = demosaic(&raw, cfg.layout, m).unwrap();
            let (mut worst, mut n) = (0.0f64, 0);
            for r in 8..504 {
                for c in 8..504 {
                    let k = r * 512 + c;
                    let (t0, t1, t2) = (
                        st.s0.data[k] as f64,
                        st.s1.data[k] as f64,
                        st.s2.data[k] as f64,
                    );
                    if t1.hypot(t2) < 0.02 * t0 {
                        continue; // AoLP undefined near the neutral points
                    }
                    let a = psns::angle::SensorAngle::from_stokes(t1, t2);
                    let b = psns::angle::SensorAngle::from_stokes(
                        est.s1.data[k] as f64,
                        est.s2.data[k] as f64,
                    );
                    worst = worst.max(a.diff(b));
                    n += 1;
                }
            }
            assert!(
                n > 100_000,
                "{m} {corner:?}: too few polarized pixels ({n})"
            );
            eprintln!("{m} window {corner:?}: max AoLP error {worst:.5} deg over {n} px");
            if m == Method::Superpixel {
                // half resolution: the IFOV error of the 2 x 2 block is visible at this scale
                assert!(
                    worst > 0.01,
                    "superpixel {corner:?}: {worst} deg, expected > 0.01"
                );
            } else {
                assert!(
                    worst < 0.01,
                    "{m} window {corner:?}: max AoLP error {worst} deg"
                );
            }
        }
    }
}
