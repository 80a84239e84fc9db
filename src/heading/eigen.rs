//! The sun-vector (eigenvector) estimator: the E-vectors' scatter matrix and its smallest
//! eigenvector, made robust by reweighting.

use super::*;

/// Eigen-decomposition of a symmetric 3×3 matrix by Jacobi rotations: (eigenvalues ascending,
/// eigenvectors as the matching columns).
pub fn symmetric_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m.to_cols_array_2d(); // a[col][row]; symmetric, so a[i][j] = a[j][i]
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        if off < 1e-30 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A' = Jᵀ A J with J the rotation in the (p, q) plane
            for ak in &mut a {
                let (akp, akq) = (ak[p], ak[q]);
                ak[p] = c * akp - s * akq;
                ak[q] = s * akp + c * akq;
            }
            #[allow(clippy::needless_range_loop)] // rows p and q change together
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let vals = idx.map(|i| a[i][i]);
    let vecs = idx.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize());
    (vals, vecs)
}

/// The camera-frame E-vector of a pixel with sensor AoLP `aolp_deg`, seen along camera ray `ray`
/// through a pinhole ([`crate::camera::Lens::e_vector`] for either lens).
pub fn e_vector(ray: DVec3, aolp_deg: f64) -> DVec3 {
    crate::camera::Lens::Pinhole.e_vector(ray, aolp_deg.to_radians())
}

/// Yaw (degrees, [0, 360)) that turns the ENU sun `sun_enu` into the level-frame sun `u`
/// (u = R_z(yaw) s), and how well the horizontal components fix it (0 at the zenith).
pub(super) fn yaw_from(u: DVec3, sun_enu: DVec3) -> (f64, f64) {
    let yaw = u.y.atan2(u.x) - sun_enu.y.atan2(sun_enu.x);
    let horiz = (u.x * u.x + u.y * u.y)
        .sqrt()
        .min((sun_enu.x.powi(2) + sun_enu.y.powi(2)).sqrt());
    (yaw.to_degrees().rem_euclid(360.0), horiz)
}

/// The sun-vector estimator on AoLP (degrees, sensor frame) and DoLP images of one frame.
///
/// Errors when the images and intrinsics disagree in size, a setting is out of range, or fewer
/// than 10 pixels are polarized enough to use. Every pixel with a usable DoLP is read: a mask is
/// applied by NaN in `dolp` ([`masked_dolp`], [`estimate_heading`]).
pub fn eigenvector_heading(
    aolp_deg: &Image<f32>,
    dolp: &Image<f32>,
    setup: &HeadingSetup,
) -> Result<HeadingEstimate> {
    let i = &setup.intrinsics;
    check_image_sizes(aolp_deg, dolp, i)?;
    check_range("pitch", setup.pitch_deg, -90.0, 90.0)?;
    check_range("roll", setup.roll_deg, -90.0, 90.0)?;
    check_range("min-dolp", setup.min_dolp, 0.0, 1.0)?;
    setup.sun.check_up()?;
    check_sun_defines_yaw(&setup.sun)?;
    let step = sample_step(setup);
    let mut samples: Vec<(DVec3, f64)> = Vec::new();
    for row in (0..i.height).step_by(step) {
        for col in (0..i.width).step_by(step) {
            let k = row * i.width + col;
            let (a, d) = (aolp_deg.data[k] as f64, dolp.data[k] as f64);
            if !(a.is_finite() && d.is_finite()) || d < setup.min_dolp || d > 1.0 {
                continue;
            }
            let Some(ray) = i.ray(col as f64, row as f64) else {
                continue;
            };
            if ray.z <= 1e-6 {
                continue;
            }
            samples.push((i.lens().e_vector(ray, a.to_radians()), d));
        }
    }
    if samples.len() < 10 {
        return Err(Error::TooFewPixels(format!(
            "heading: only {} pixels with DoLP >= {} (need 10)",
            samples.len(),
            setup.min_dolp
        )));
    }
    let solve = |weight: &dyn Fn(DVec3, f64) -> f64| {
        let mut m = DMat3::ZERO;
        for &(e, d) in &samples {
            let w = weight(e, d);
            m += DMat3::from_cols(e * (w * e.x), e * (w * e.y), e * (w * e.z));
        }
        symmetric_eigen(m)
    };
    let (mut vals, mut vecs) = solve(&|_, d| d);
    // robust refinement: Tukey biweight on the residual sin(angle) = e·s, scale from the MAD
    for _ in 0..4 {
        let s = vecs[0];
        let mut r: Vec<f64> = samples.iter().map(|(e, _)| e.dot(s).abs()).collect();
        let c = (4.685 * 1.4826 * median_of(&mut r)).max(1e-4);
        (vals, vecs) = solve(&|e, d| {
            let u = e.dot(s) / c;
            if u.abs() >= 1.0 {
                0.0
            } else {
                d * (1.0 - u * u).powi(2)
            }
        });
    }
    let mut s_c = vecs[0];
    // the sun is above the horizon: choose the sign that puts it there
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let mut u = tilt.transpose() * s_c;
    if u.z < 0.0 {
        s_c = -s_c;
        u = -u;
    }
    let sun_enu = setup.sun.vector();
    let (yaw_deg, horiz) = yaw_from(u, sun_enu);
    let separation = if vals[1] > 0.0 {
        1.0 - vals[0] / vals[1]
    } else {
        0.0
    };
    // the robust spread of the residual angles: noise (low light, low DoLP) and clouds widen it
    let mut r: Vec<f64> = samples.iter().map(|(e, _)| e.dot(s_c).abs()).collect();
    let spread_deg = (1.4826 * median_of(&mut r)).asin().to_degrees();
    // A sun-direction error δ becomes a yaw error of about δ / sin(sun zenith). This method has a
    // bias of a few tenths of a degree in the sun's direction on the Berry sky, so its
    // confidence falls below sin 45° of horizontal sun component (with a 5° tilt and the sun at
    // 70° its error reaches 2-3° in the bench).
    // The residual of the Rayleigh sky of the given sun and tilt at this yaw: reported, and its
    // RMS lowers the confidence of a picture of no sky. Its systematic part is not used: the
    // Berry sky's own misfit to Rayleigh's (≈ 10° RMS) is larger than a wrong tilt adds.
    let view = PolarView::new(aolp_deg, dolp, None);
    let res = rayleigh_residual(&view, setup, yaw_deg);
    let residual_deg = res.rms_deg;
    let sky = sky_fraction(aolp_deg, dolp, setup);
    let confidence = (separation
        * (horiz / EIGEN_FULL_HORIZ).min(1.0)
        * spread_factor(spread_deg)
        * (samples.len() as f64 / 500.0).min(1.0)
        * rms_factor(res.rms_deg)
        * sky_factor(sky))
    .clamp(0.0, 1.0);
    Ok(HeadingEstimate {
        yaw_deg,
        confidence,
        pixels: samples.len(),
        sun_camera: s_c,
        residual_deg,
        sky_fraction: sky,
    })
}
