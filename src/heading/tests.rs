use super::*;
use crate::camera::{Attitude, Camera};
use crate::render::render_ideal;
use crate::sky::{PolarizationModel, Sky, SkyParams};

fn axial360(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

fn estimate(
    model: PolarizationModel,
    sun: SunPosition,
    yaw: f64,
    pitch: f64,
    roll: f64,
) -> HeadingEstimate {
    let (im, setup) = ideal(model, sun, yaw, pitch, roll);
    eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap()
}

/// The true yaw and tilt read back from a stream quaternion are the Euler angles of
/// `psns render --frame enu` (round trip through `camera_to_enu_quaternion`).
#[test]
fn sensor_basis_residual_is_the_wrapped_aop_difference() {
    use crate::camera::Lens;
    let rays = [
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(0.3, -0.2, 1.0),
        DVec3::new(-0.7, 0.5, 0.6),
        DVec3::new(0.01, 0.9, 0.2),
    ];
    for lens in [Lens::Pinhole, Lens::Ideal] {
        for d in rays {
            let d = d.normalize();
            for phi_deg in [-80.0f64, -10.0, 0.0, 33.0, 89.0, 135.0] {
                let phi = phi_deg.to_radians();
                let b = SensorBasis::new(lens, d, phi);
                for k in 0..12 {
                    // an E-vector perpendicular to the ray
                    let t = (k as f64 * 31.0).to_radians();
                    let u = d.any_orthonormal_pair();
                    let e = u.0 * t.cos() + u.1 * t.sin();
                    let want = wrap_half_pi(phi - lens.sensor_angle(d, e));
                    let got = b.residual(e);
                    let diff = wrap_half_pi(got - want).abs();
                    assert!(diff < 1e-9, "{lens:?} {d} {phi_deg} {t}: {got} vs {want}");
                }
            }
        }
    }
}

/// The model fit's residual from per-pixel constants equals the direct one (Berry E-vector at
/// the view direction C(ψ)ᵀ r, rotated into the camera, [`SensorBasis::residual`]) for both
/// lenses, tilts and the tied (elevation) form, and its analytic derivatives equal central
/// differences of it.
#[test]
fn fit_residuals_match_the_direct_model_and_their_derivatives() {
    use crate::camera::Lens;
    use crate::sky::berry::BerryField;
    let rays: Vec<DVec3> = (0..60)
        .map(|k| {
            let a = k as f64 * 0.7;
            DVec3::new(0.6 * a.cos() * (k % 7) as f64 / 7.0, 0.5 * a.sin(), 1.0).normalize()
        })
        .collect();
    let samples: Vec<(DVec3, f64, f64)> = rays
        .iter()
        .enumerate()
        .map(|(k, &r)| (r, (k as f64 * 37.0 - 90.0).to_radians(), 0.3))
        .collect();
    let az = 200.0;
    for lens in [Lens::Pinhole, Lens::Ideal] {
        for (pitch, roll) in [(0.0f64, 0.0f64), (4.0, -5.0)] {
            let tilt = rot_y(roll.to_radians()) * rot_x(pitch.to_radians());
            let px = fit_pixels(&samples, tilt, lens);
            for (tied, p) in [
                (false, [37.0, 22.0, 27.0, 50.0]),
                (false, [210.5, 30.0, 18.0, 70.0]),
                (true, [300.0, 25.0, 25.0, 35.0]),
            ] {
                let n = px.len();
                let (mut r, mut j) = (vec![0.0; n], vec![[0.0; 4]; n]);
                fit_residuals(&px, p, az, tied, &mut r, &mut j);
                let c = tilt * crate::camera::rot_z(p[0].to_radians());
                let f = BerryField::new(p[3], az, p[1], p[2]);
                for (k, &(ray, phi, _)) in samples.iter().enumerate() {
                    let b = SensorBasis::new(lens, ray, phi);
                    let want = b.residual(c * f.e_only(c.transpose() * ray));
                    let d = wrap_half_pi(r[k] - want).abs();
                    assert!(d < 1e-10, "{lens:?} {p:?} pixel {k}: {} vs {want}", r[k]);
                }
                // central differences, per parameter (ψ, δ or δ_Ba, δ_Br or θ_s)
                let cols: [&[usize]; 3] = if tied {
                    [&[0], &[1, 2], &[3]]
                } else {
                    [&[0], &[1], &[2]]
                };
                let h = 1e-4;
                for (col, idx) in cols.iter().enumerate() {
                    let (mut a, mut b) = (p, p);
                    for &i in *idx {
                        a[i] += h;
                        b[i] -= h;
                    }
                    let (mut ra, mut rb, mut jj) = (vec![0.0; n], vec![0.0; n], vec![[0.0; 4]; n]);
                    fit_residuals(&px, a, az, tied, &mut ra, &mut jj);
                    fit_residuals(&px, b, az, tied, &mut rb, &mut jj);
                    let big = (0..n).map(|k| j[k][col].abs()).fold(0.0, f64::max);
                    assert!(big > 1e-3, "column {col} vanishes: {big}");
                    for k in 0..n {
                        let num = wrap_half_pi(ra[k] - rb[k]) / (2.0 * h);
                        assert!(
                            (num - j[k][col]).abs() < 1e-6 * (1.0 + num.abs()),
                            "{lens:?} {p:?} tied {tied} column {col} pixel {k}: {} vs {num}",
                            j[k][col]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn atan2_fit_matches_std() {
    let mut worst = 0f64;
    for i in 0..200_000 {
        let a = i as f64 * 3.3e-5 - 3.3;
        for r in [1e-9f64, 1.0, 3e7] {
            let (y, x) = (r * a.sin(), r * a.cos());
            worst = worst.max((atan2_fit(y, x) - y.atan2(x)).abs());
        }
    }
    assert!(worst < 2e-11, "worst {worst}");
    assert_eq!(atan2_fit(0.0, 0.0), 0.0);
    assert_eq!(atan2_fit(0.0, -1.0), std::f64::consts::PI);
    assert_eq!(atan2_fit(-1.0, 0.0), -std::f64::consts::FRAC_PI_2);
}

#[test]
fn sampled_view_matches_the_full_frame() {
    // the sampled intrinsics' rays are the full frame's at the blocks' centres
    let i = Intrinsics::with_size(2448, 2048);
    let k = superpixel_step(i.width, i.height).unwrap();
    assert_eq!(k, 10);
    assert_eq!(superpixel_step(612, 512), None);
    let si = sampled_intrinsics(&i, k);
    assert_eq!((si.width, si.height), (244, 204));
    for (j, r) in [(0usize, 0usize), (100, 50), (243, 203)] {
        let a = si.ray(j as f64, r as f64).unwrap().normalize();
        let b = i
            .ray((k * j) as f64 + 0.5, (k * r) as f64 + 0.5)
            .unwrap()
            .normalize();
        assert!((a - b).length() < 1e-12, "{a} {b}");
    }
    // and its samples are the superpixel blocks at those positions
    let raw = Image::from_vec(
        40,
        24,
        (0..40 * 24).map(|v| (v * 7 % 1000) as u16).collect(),
    );
    let layout = crate::sensor::mosaic::MosaicLayout::default();
    let half = crate::demosaic::superpixel_half(&raw, layout).unwrap();
    let p = crate::demosaic::superpixel::superpixel_sampled(&raw, layout, 4, 0.0).unwrap();
    assert_eq!((p.dolp.width, p.dolp.height), (10, 6));
    for r in 0..6 {
        for j in 0..10 {
            let h = (2 * r) * half.s0.width + 2 * j;
            let q = r * 10 + j;
            assert_eq!(p.stokes.s0.data[q], half.s0.data[h]);
            assert_eq!(p.stokes.s1.data[q], half.s1.data[h]);
            assert_eq!(p.stokes.s2.data[q], half.s2.data[h]);
        }
    }
    // a full-scale code masks the samples around it and counts its 3 x 3 neighbourhood
    let mut codes = Image::from_vec(40, 24, vec![100u16; 40 * 24]);
    codes.data[9 * 40 + 8] = 4095;
    let mut d = Image::from_vec(10, 6, vec![0.5f32; 60]);
    assert_eq!(mask_saturated_sampled(&mut d, &codes, 4095, 4), 9);
    let nan: Vec<usize> = (0..60).filter(|&q| d.data[q].is_nan()).collect();
    assert_eq!(nan, vec![2 * 10 + 2]); // block (8..10, 8..10) plus one pixel around
}

#[test]
fn attitude_yaw_and_tilt_round_trip() {
    for (y, p, r) in [
        (0.0, 0.0, 0.0),
        (137.0, 3.0, -4.0),
        (290.0, -5.0, 2.0),
        (359.5, 30.0, 40.0),
        (45.0, -60.0, -70.0),
    ] {
        let q = crate::camera::camera_to_enu_quaternion(&crate::camera::euler_matrix(y, p, r));
        let (pp, rr) = attitude_tilt_deg(q);
        assert!(
            wrap180(attitude_yaw_deg(q) - y).abs() < 1e-9,
            "{y} {p} {r}: {}",
            attitude_yaw_deg(q)
        );
        assert!(
            (pp - p).abs() < 1e-9 && (rr - r).abs() < 1e-9,
            "{p} {r}: {pp} {rr}"
        );
    }
}

#[test]
fn wrap_and_stats() {
    assert_eq!(wrap180(190.0), -170.0);
    assert_eq!(wrap180(-180.0), 180.0);
    assert_eq!(wrap180(540.0), 180.0);
    let s = error_stats(&[3.0, -4.0, f64::NAN]);
    assert_eq!((s.count, s.max, s.p95), (2, 4.0, 4.0));
    assert!((s.rms - 12.5f64.sqrt()).abs() < 1e-12);
    let v: Vec<f64> = (1..=100).map(|i| i as f64).collect();
    assert_eq!(error_stats(&v).p95, 95.0);
    assert!(error_stats(&[]).rms.is_nan());
}

#[test]
fn jacobi_recovers_a_known_basis() {
    let r = crate::camera::euler_matrix(30.0, 20.0, -40.0);
    let d = DMat3::from_diagonal(DVec3::new(3.0, 0.5, 2.0));
    let (vals, vecs) = symmetric_eigen(r * d * r.transpose());
    assert!(
        (vals[0] - 0.5).abs() < 1e-12 && (vals[2] - 3.0).abs() < 1e-12,
        "{vals:?}"
    );
    assert!(vecs[0].dot(r.col(1)).abs() > 1.0 - 1e-12);
}

/// Analytic oracle: on a Rayleigh sky every E-vector is perpendicular to the sun, so the
/// estimate is exact up to the float images (issue target: ≤ 0.05°).
#[test]
fn rayleigh_sky_gives_the_true_yaw() {
    for (yaw, pitch, roll, zen, az) in [
        (0.0, 0.0, 0.0, 50.0, 200.0),
        (123.0, 0.0, 0.0, 30.0, 10.0),
        (-75.0, 4.0, -3.0, 70.0, 300.0),
        (250.0, -5.0, 5.0, 80.0, 95.0),
    ] {
        let e = estimate(
            PolarizationModel::Rayleigh,
            SunPosition::new(zen, az),
            yaw,
            pitch,
            roll,
        );
        let err = axial360(e.yaw_deg, yaw);
        eprintln!(
            "rayleigh yaw {yaw} sun {zen}: err {err:.6} conf {:.3} px {}",
            e.confidence, e.pixels
        );
        assert!(
            err < 0.05,
            "yaw {yaw} pitch {pitch} roll {roll} sun {zen}/{az}: got {} (err {err})",
            e.yaw_deg
        );
        assert!(e.confidence > 0.5, "{e:?}");
    }
}

/// On the default (Wang/Berry) sky the eigenvector answer is biased by the neutral points but
/// stays within a degree; the model fit is what removes that bias.
#[test]
fn default_sky_bias_is_bounded() {
    let e = estimate(
        PolarizationModel::Wang,
        SunPosition::new(50.0, 200.0),
        40.0,
        0.0,
        0.0,
    );
    let err = axial360(e.yaw_deg, 40.0);
    eprintln!("default sky: err {err:.4} conf {:.3}", e.confidence);
    assert!(err < 1.0, "{e:?} err {err}");
}

fn ideal(
    model: PolarizationModel,
    sun: SunPosition,
    yaw: f64,
    pitch: f64,
    roll: f64,
) -> (crate::render::IdealImages, HeadingSetup) {
    let p = SkyParams {
        model,
        ..SkyParams::default()
    };
    let sky = Sky::new(sun, &p).unwrap();
    // the full sensor's field of view at 1/8 of its pixels
    let i = Intrinsics {
        pixel_pitch_um: 3.45 * 8.0,
        ..Intrinsics::with_size(306, 256)
    };
    let cam = Camera::new(i, &Attitude::enu(yaw, pitch, roll), sun.azimuth_deg).unwrap();
    let mut setup = HeadingSetup::new(i, sun);
    setup.pitch_deg = pitch;
    setup.roll_deg = roll;
    setup.step = 2;
    (render_ideal(&sky, &cam), setup)
}

/// The model fit removes the eigenvector method's bias on the default (Berry) sky: noise-free
/// images give the yaw to well under the 0.1° target (the eigenvector answer is off by
/// 0.1-0.5° on the same images), and the fitted neutral-point distances are the sky's 25°.
#[test]
fn model_fit_removes_the_berry_bias() {
    let mut worst_eigen: f64 = 0.0;
    for (yaw, pitch, roll, zen, az) in [
        (40.0, 0.0, 0.0, 50.0, 200.0),
        (123.0, 4.0, -3.0, 30.0, 10.0),
        (-75.0, -5.0, 5.0, 70.0, 300.0),
        (250.0, 2.0, 5.0, 80.0, 95.0),
    ] {
        let sun = SunPosition::new(zen, az);
        let (im, setup) = ideal(PolarizationModel::Wang, sun, yaw, pitch, roll);
        let e = eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap();
        let (m, info) = model_fit_heading(&im.aop_deg, &im.dop, &setup, &e, false).unwrap();
        let (ee, em) = (axial360(e.yaw_deg, yaw), axial360(m.yaw_deg, yaw));
        eprintln!(
            "berry yaw {yaw} sun {zen}: eigen {ee:.4} fit {em:.5} conf {:.3} {info:?}",
            m.confidence
        );
        worst_eigen = worst_eigen.max(ee);
        assert!(em < 0.01, "yaw {yaw} sun {zen}: fit error {em} ({info:?})");
        assert!(m.confidence > 0.5, "{m:?}");
    }
    assert!(
        worst_eigen > 0.1,
        "the eigen bias this test relies on is gone"
    );
}

/// The model fit's answer does not depend on the number of threads (pixels in parallel,
/// sums in a fixed order), and with analytic derivatives it needs few residual evaluations
/// (forward differences took at least 11 iterations of 4 or more).
#[test]
fn model_fit_is_thread_count_independent_and_cheap() {
    let sun = SunPosition::new(40.0, 200.0);
    let (im, setup) = ideal(PolarizationModel::Wang, sun, 123.0, 4.0, -3.0);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let e = eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap();
                model_fit_heading(&im.aop_deg, &im.dop, &setup, &e, false).unwrap()
            })
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a, b);
    eprintln!("{:?}", a.1);
    assert!(a.1.evaluations <= 8, "{:?}", a.1);
    assert!(axial360(a.0.yaw_deg, 123.0) < 0.01, "{a:?}");
}

/// The sampled saturation mask and count equal a direct window search, for blobs at the
/// frame's edges and inside.
#[test]
fn sampled_saturation_mask_matches_a_direct_search() {
    let (w, h, k) = (64usize, 40usize, 4usize);
    let mut codes = Image::from_vec(w, h, vec![100u16; w * h]);
    for &(r, c) in &[
        (0usize, 0usize),
        (5, 63),
        (39, 10),
        (20, 30),
        (21, 31),
        (12, 7),
    ] {
        codes.data[r * w + c] = 4095;
    }
    let mut d = Image::from_vec(w / k, h / k, vec![0.5f32; (w / k) * (h / k)]);
    let n = mask_saturated_sampled(&mut d, &codes, 4095, k);
    let mut full = Image::from_vec(w, h, vec![0.5f32; w * h]);
    assert_eq!(n, mask_saturated(&mut full, &codes, 4095));
    for i in 0..h / k {
        for j in 0..w / k {
            let (r, c) = (k * i, k * j);
            let want = (r.saturating_sub(1)..(r + 3).min(h)).any(|rr| {
                (c.saturating_sub(1)..(c + 3).min(w)).any(|cc| codes.data[rr * w + cc] >= 4095)
            });
            assert_eq!(d.data[i * (w / k) + j].is_nan(), want, "sample {i} {j}");
        }
    }
}

/// The fit also works with the sun's elevation free, and on a Rayleigh sky (δ → 0).
#[test]
fn model_fit_free_elevation_and_rayleigh() {
    let sun = SunPosition::new(45.0, 120.0);
    let (im, setup) = ideal(PolarizationModel::Wang, sun, 200.0, 3.0, -2.0);
    let e = eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap();
    let mut wrong = setup;
    wrong.sun = SunPosition::new(50.0, 120.0);
    let (m, info) = model_fit_heading(&im.aop_deg, &im.dop, &wrong, &e, true).unwrap();
    eprintln!("free elevation: {m:?} {info:?}");
    assert!(axial360(m.yaw_deg, 200.0) < 0.02, "{m:?} {info:?}");
    assert!((info.sun_zenith_deg - 45.0).abs() < 0.1, "{info:?}");
    let (im, setup) = ideal(PolarizationModel::Rayleigh, sun, 200.0, 3.0, -2.0);
    let e = eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap();
    let (m, info) = model_fit_heading(&im.aop_deg, &im.dop, &setup, &e, false).unwrap();
    assert!(axial360(m.yaw_deg, 200.0) < 0.01, "{m:?} {info:?}");
    assert!(
        info.babinet_deg < 1.0 && info.brewster_deg < 1.0,
        "{info:?}"
    );
}

fn view(im: &crate::render::IdealImages) -> PolarView<'_> {
    PolarView {
        aolp_deg: &im.aop_deg,
        dolp: &im.dop,
        s0: Some(&im.li),
        mask: None,
    }
}

/// The solar-meridian (Hough) method on ideal images of both skies (the Berry field is
/// symmetric about the meridian, so the method has no bias there), tilt compensated, the sun's
/// side from the intensity.
#[test]
fn hough_finds_the_solar_meridian() {
    for model in [PolarizationModel::Rayleigh, PolarizationModel::Wang] {
        for (yaw, pitch, roll, zen, az) in [
            (40.0, 0.0, 0.0, 50.0, 200.0),
            (123.0, 4.0, -3.0, 30.0, 10.0),
            (-75.0, -5.0, 5.0, 70.0, 300.0),
            (250.0, 2.0, 5.0, 80.0, 95.0),
        ] {
            let (im, setup) = ideal(model, SunPosition::new(zen, az), yaw, pitch, roll);
            let e = hough_heading(&view(&im), &setup).unwrap();
            let err = axial360(e.yaw_deg, yaw);
            eprintln!(
                "hough {model:?} yaw {yaw} sun {zen}: err {err:.4} conf {:.3} votes {}",
                e.confidence, e.pixels
            );
            assert!(err < 0.2, "{model:?} yaw {yaw} sun {zen}: {e:?} err {err}");
            assert!(e.confidence > 0.3, "{e:?}");
        }
    }
}

/// Sun on the horizon: "the sun is above the horizon" cannot fix the eigenvector's sign (the
/// old rule gets some of these yaws 180° wrong); the brighter half of the sky does.
#[test]
fn horizon_ambiguity_is_resolved_by_intensity() {
    let mut old_wrong = 0;
    for k in 0..8 {
        let yaw = 45.0 * k as f64 + 7.0;
        let (im, setup) = ideal(
            PolarizationModel::Wang,
            SunPosition::new(90.0, 200.0),
            yaw,
            2.0,
            -3.0,
        );
        let mut setup = setup;
        setup.relative_illumination = RelativeIllumination::None; // ideal radiance: no lens falloff to flat-field
        let old = eigenvector_heading(&im.aop_deg, &im.dop, &setup).unwrap();
        if axial360(old.yaw_deg, yaw) > 90.0 {
            old_wrong += 1;
        }
        for m in HeadingMethod::ALL {
            let e = estimate_heading(m, &view(&im), &setup).unwrap();
            let err = axial360(e.yaw_deg, yaw);
            eprintln!(
                "horizon {m} yaw {yaw}: err {err:.3} conf {:.3}",
                e.confidence
            );
            assert!(err < 1.0, "{m} yaw {yaw}: {e:?}");
        }
    }
    eprintln!("old sign rule: {old_wrong} of 8 wrong by 180 deg");
    assert!(
        old_wrong > 0,
        "the ambiguity this test relies on did not occur"
    );
}

/// A sun near the zenith cannot fix the yaw: the confidence says so.
#[test]
fn sun_near_the_zenith_has_low_confidence() {
    let e = estimate(
        PolarizationModel::Rayleigh,
        SunPosition::new(1.0, 200.0),
        40.0,
        0.0,
        0.0,
    );
    eprintln!("zenith sun: {e:?}");
    assert!(e.confidence < 0.2, "{e:?}");
}

#[test]
fn saturated_codes_mask_their_neighbourhood() {
    let mut codes = Image::from_vec(5, 4, vec![100u16; 20]);
    codes.data[2 * 5 + 2] = 4095;
    let mut d = Image::from_vec(5, 4, vec![0.3f32; 20]);
    assert_eq!(mask_saturated(&mut d, &codes, 4095), 9);
    assert!(d.data[5 + 1].is_nan() && d.data[3 * 5 + 3].is_nan() && !d.data[0].is_nan());
}

#[test]
fn mismatched_sizes_and_unpolarized_frames_are_errors() {
    let i = Intrinsics::with_size(20, 10);
    let setup = HeadingSetup::new(i, SunPosition::new(50.0, 200.0));
    let a = Image::from_vec(20, 10, vec![0f32; 200]);
    let d = Image::from_vec(20, 10, vec![0f32; 200]);
    assert!(eigenvector_heading(&a, &d, &setup)
        .unwrap_err()
        .to_string()
        .contains("only 0 pixels"));
    let small = Image::from_vec(10, 10, vec![0f32; 100]);
    assert!(eigenvector_heading(&small, &d, &setup).is_err());
}

/// Inputs the sky does not fit lower the confidence: a roll 40° wrong moved the model fit's yaw
/// by about 30° at confidence 0.91; its residual now says so. The right inputs keep a high
/// confidence and a residual near zero (ideal images).
#[test]
fn a_wrong_tilt_lowers_the_confidence() {
    let sun = SunPosition::new(50.0, 200.0);
    for yaw in [30.0, 200.0] {
        let (im, setup) = ideal(PolarizationModel::Wang, sun, yaw, 0.0, 0.0);
        let v = view(&im);
        let right = estimate_heading(HeadingMethod::ModelFit, &v, &setup).unwrap();
        eprintln!("yaw {yaw} right: {right:?}");
        assert!(axial360(right.yaw_deg, yaw) < 0.01, "{right:?}");
        assert!(right.confidence > 0.85, "{right:?}");
        assert!(right.residual_deg < 0.5, "{right:?}");
        for roll in [40.0, -40.0] {
            let mut wrong = setup;
            wrong.roll_deg = roll;
            let e = estimate_heading(HeadingMethod::ModelFit, &v, &wrong).unwrap();
            eprintln!("yaw {yaw} roll {roll}: {e:?}");
            assert!(
                axial360(e.yaw_deg, yaw) > 5.0,
                "the test needs a wrong yaw: {e:?}"
            );
            assert!(e.confidence < 0.5, "roll {roll}: {e:?}");
            assert!(e.residual_deg > 3.0, "roll {roll}: {e:?}");
        }
    }
}

/// With the sun within the solar disc's radius of the zenith no method gives a yaw (the front
/// ends print NaN at confidence 0 with the reason); just outside it they do.
#[test]
fn a_zenith_sun_gives_no_yaw() {
    for zen in [0.0, 0.2] {
        let sun = SunPosition::new(zen, 200.0);
        let (im, setup) = ideal(PolarizationModel::Wang, sun, 40.0, 0.0, 0.0);
        for m in HeadingMethod::ALL {
            match estimate_heading(m, &view(&im), &setup) {
                Err(Error::Undetermined(msg)) => assert!(msg.contains("zenith"), "{msg}"),
                other => panic!("{m} with the sun {zen} deg from the zenith: {other:?}"),
            }
        }
    }
    let sun = SunPosition::new(1.0, 200.0);
    let (im, setup) = ideal(PolarizationModel::Wang, sun, 40.0, 0.0, 0.0);
    let e = estimate_heading(HeadingMethod::ModelFit, &view(&im), &setup).unwrap();
    assert!(e.yaw_deg.is_finite() && e.confidence < 0.2, "{e:?}");
}

/// Pictures that are not of the sky: uniformly random AoLP (residual RMS ≈ 52°), and one AoLP
/// everywhere (a polarizing filter in front of a flat field). No method is confident on them,
/// with or without the sky mask found from the frame; without it the random picture's residual
/// says so, with it the mask finds next to no sky there (the few pixels it keeps agree by
/// chance, so their residual is smaller).
#[test]
fn a_picture_of_no_sky_has_low_confidence() {
    let sun = SunPosition::new(50.0, 200.0);
    let (im, setup) = ideal(PolarizationModel::Wang, sun, 40.0, 0.0, 0.0);
    let n = im.aop_deg.data.len();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let random: Vec<f32> = (0..n)
        .map(|_| {
            // splitmix64: a fixed sequence, uniform over ±90°
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 53) as f32 * 180.0 - 90.0
        })
        .collect();
    let w = im.aop_deg.width;
    let h = im.aop_deg.height;
    let dolp = Image::from_vec(w, h, vec![0.3f32; n]);
    for (name, aolp) in [
        ("random", Image::from_vec(w, h, random)),
        ("uniform", Image::from_vec(w, h, vec![30.0f32; n])),
    ] {
        let v = PolarView {
            aolp_deg: &aolp,
            dolp: &dolp,
            s0: Some(&im.li),
            mask: None,
        };
        for (m, find) in HeadingMethod::ALL
            .into_iter()
            .flat_map(|m| [(m, false), (m, true)])
        {
            let mut setup = setup;
            setup.find_mask = find;
            let c = match estimate_heading(m, &v, &setup) {
                Ok(e) => {
                    eprintln!("{name} {m} found mask {find}: {e:?}");
                    if name == "random" && !find {
                        assert!(e.residual_deg > 40.0, "{e:?}");
                    }
                    if name == "random" && find {
                        assert!(e.sky_fraction < 0.1, "{e:?}");
                    }
                    e.confidence
                }
                Err(e) => {
                    eprintln!("{name} {m} found mask {find}: {e}");
                    0.0
                }
            };
            assert!(c < 0.5, "{name}: {m} confidence {c}");
        }
    }
}

#[test]
fn residual_splits_noise_from_a_smooth_misfit() {
    let rays: Vec<DVec3> = (0..400)
        .map(|k| DVec3::new(0.01 * k as f64, 0.0, 1.0).normalize())
        .collect();
    // a smooth misfit of 5°: all systematic
    let smooth: Vec<f64> = (0..400).map(|_| 5f64.to_radians()).collect();
    let r = Residual::of(&smooth, &rays);
    assert!(
        (r.rms_deg - 5.0).abs() < 1e-9 && (r.systematic_deg - 5.0).abs() < 1e-6,
        "{r:?}"
    );
    // alternating ±5°: all noise (neighbours never share it)
    let noise: Vec<f64> = (0..400)
        .map(|k| if k % 2 == 0 { 5f64 } else { -5.0 }.to_radians())
        .collect();
    let r = Residual::of(&noise, &rays);
    assert!(
        (r.rms_deg - 5.0).abs() < 1e-9 && r.systematic_deg < 1e-6,
        "{r:?}"
    );
    // NaN (no prediction) is left out
    let mut gap = smooth.clone();
    gap[7] = f64::NAN;
    assert!((Residual::of(&gap, &rays).rms_deg - 5.0).abs() < 1e-9);
}
