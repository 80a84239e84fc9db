//! Calibrated least-squares Stokes (`psns::stokes`) against the uncalibrated superpixel
//! (`psns::demosaic`): an integration test because it uses both layers.

use psns::image::Image;
use psns::sensor::mosaic::MosaicLayout;
use psns::stokes::{least_squares_stokes, Calibration};

#[test]
fn least_squares_recovers_with_calibrated_angles_and_er() {
    let (w, h) = (16, 12);
    let layout = MosaicLayout::IMX250MZR;
    let mut cal = Calibration::with_extinction_ratio(w, h, layout, 60.0).unwrap();
    for (k, a) in cal.angle_deg.iter_mut().enumerate() {
        *a += ((k * 37 % 11) as f32 - 5.0) * 0.3; // ±1.5° orientation errors
    }
    for (k, g) in cal.gain.iter_mut().enumerate() {
        *g = 1.0 + ((k * 13 % 7) as f32 - 3.0) * 0.01;
    }
    let (s0, s1, s2) = (1000.0f64, -250.0f64, 410.0f64);
    let mut raw = Image::<f32>::new(w, h);
    for k in 0..w * h {
        let th = 2.0 * (cal.angle_deg[k] as f64).to_radians();
        let v = 0.5
            * cal.gain[k] as f64
            * (s0 + cal.diattenuation[k] as f64 * (s1 * th.cos() + s2 * th.sin()));
        raw.data[k] = v as f32;
    }
    let st = least_squares_stokes(&raw, &cal, 2).unwrap();
    assert_eq!((st.width(), st.height()), (8, 6));
    for i in 0..48 {
        assert!((st.s0.data[i] as f64 - s0).abs() < 1e-2);
        assert!((st.s1.data[i] as f64 - s1).abs() < 1e-2);
        assert!((st.s2.data[i] as f64 - s2).abs() < 1e-2);
    }
    // the uncalibrated superpixel is off by far more (ER 60 alone: S1, S2 3.3 % low)
    let sp = psns::demosaic::superpixel_half(&raw, layout).unwrap();
    let worst = (0..48)
        .map(|i| (sp.s1.data[i] as f64 - s1).abs())
        .fold(0.0, f64::max);
    assert!(worst > 5.0, "superpixel S1 error {worst}");
    assert!(least_squares_stokes(&raw, &cal, 3).is_err());
}
