//! The solar-meridian (Hough) estimator.

use super::*;

/// The solar-meridian (Hough) method, after Lu et al. 2015: on the solar meridian the E-vector is
/// perpendicular to the meridian plane (AoLP 90° from the meridian, in Rayleigh and, by symmetry,
/// Berry skies). Every usable pixel whose level-frame E-vector lies within 3° of the normal of its
/// own vertical plane votes, with its DoLP times a kernel (1 − (ε/3°)²)² on that angle ε and
/// at least 15° from the zenith, for the azimuth of that vertical plane (an axial
/// angle); the peak of the histogram (0.25° bins, smoothed) is refined by the weighted axial mean
/// of the votes within ±1.5°. Which end of the line is the sun: the candidate the E-vectors are
/// more nearly perpendicular to at the known elevation, or, within 8° of the horizon, the brighter
/// side ([`intensity_side`]); its azimuth and the known elevation give the yaw. The known tilt is
/// compensated as in [`eigenvector_heading`].
///
/// Confidence: the share of the votes near the peak, times the horizontal-sun factor, times the
/// clarity of the side decision (|vote| / 0.2, at most 1), times the line's support (votes within
/// ±1.5° of it / [`HOUGH_FULL_VOTES`], at most 1), times [`sky_factor`]. Needs S0 near the
/// horizon. A given mask ([`PolarView::mask`]) is applied; none is found here
/// ([`estimate_heading`] finds one).
pub fn hough_heading(view: &PolarView, setup: &HeadingSetup) -> Result<HeadingEstimate> {
    let mut buf = None;
    let view = &apply_view_mask(view, &mut buf)?;
    let i = &setup.intrinsics;
    check_image_sizes(view.aolp_deg, view.dolp, i)?;
    setup.sun.check_up()?;
    check_sun_defines_yaw(&setup.sun)?;
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let tt = tilt.transpose();
    let tol = 3f64.to_radians().cos();
    // (1 − cos ε) ∝ ε², so q below is (ε / 3°)² and the kernel is (1 − (ε/3°)²)²
    let step = sample_step(setup);
    const BINS: usize = 720;
    let mut hist = vec![0.0f64; BINS];
    let mut votes: Vec<(f64, f64, DVec3)> = Vec::new();
    let mut usable = 0usize;
    let mut evecs: Vec<(DVec3, f64)> = Vec::new();
    for row in (0..i.height).step_by(step) {
        for col in (0..i.width).step_by(step) {
            let k = row * i.width + col;
            let (a, d) = (view.aolp_deg.data[k] as f64, view.dolp.data[k] as f64);
            if !(a.is_finite() && d.is_finite()) || d < setup.min_dolp || d > 1.0 {
                continue;
            }
            let Some(ray) = i.ray(col as f64, row as f64) else {
                continue;
            };
            if ray.z <= 1e-6 {
                continue;
            }
            usable += 1;
            let e_c = i.lens().e_vector(ray, a.to_radians());
            evecs.push((e_c, d));
            let v = tt * ray.normalize();
            let hz = v.x.hypot(v.y);
            if hz < 0.26 {
                continue; // within 15° of the zenith the azimuth of a pixel is imprecise
            }
            let e = tt * e_c;
            let n = DVec3::new(-v.y / hz, v.x / hz, 0.0);
            let c = e.dot(n).abs();
            if c < tol {
                continue;
            }
            // kernel on the E-vector's angle from the normal: a vote's weight peaks on the
            // meridian, so the votes' spread in azimuth has a peak, not a plateau
            let q = (1.0 - c) / (1.0 - tol);
            let wv = d * (1.0 - q) * (1.0 - q);
            let alpha = v.y.atan2(v.x).rem_euclid(std::f64::consts::PI);
            let b = ((alpha / std::f64::consts::PI * BINS as f64) as usize).min(BINS - 1);
            hist[b] += wv;
            votes.push((alpha, wv, v));
        }
    }
    if votes.len() < 10 {
        return Err(Error::TooFewPixels(format!(
            "heading: only {} pixels on the solar meridian of {usable} usable (need 10)",
            votes.len()
        )));
    }
    let smooth = |b: usize| -> f64 { (0..5).map(|o| hist[(b + BINS + o - 2) % BINS]).sum() };
    let peak = (0..BINS)
        .max_by(|&x, &y| smooth(x).total_cmp(&smooth(y)))
        .unwrap_or(0);
    let pi = std::f64::consts::PI;
    let mut alpha = (peak as f64 + 0.5) / BINS as f64 * pi;
    // Refinement: the weighted axial mean of the votes within ±1.5° of the line, using only votes
    // whose mirror image across the candidate meridian plane is also inside the image (the image
    // boundary would otherwise cut the band of votes asymmetrically); three passes, recentred.
    let win = 1.5f64.to_radians();
    let rectilinear = i.projection == crate::camera::Projection::Rectilinear;
    let inside = |v: DVec3| {
        let r = tilt * v;
        (!rectilinear || r.z > 1e-6) && {
            i.project(r).is_some_and(|(x, y)| {
                x >= 0.0 && y >= 0.0 && x <= (i.width - 1) as f64 && y <= (i.height - 1) as f64
            })
        }
    };
    let (mut wn, mut nline) = (0.0, 0usize);
    for _ in 0..3 {
        let n = DVec3::new(-alpha.sin(), alpha.cos(), 0.0);
        let (mut sc, mut ss) = (0.0, 0.0);
        (wn, nline) = (0.0, 0);
        for &(a, d, v) in &votes {
            let dd = (a - alpha).rem_euclid(pi);
            if dd.min(pi - dd) > win || !inside(v - 2.0 * v.dot(n) * n) {
                continue;
            }
            sc += d * (2.0 * a).cos();
            ss += d * (2.0 * a).sin();
            wn += d;
            nline += 1;
        }
        if wn > 0.0 {
            alpha = 0.5 * ss.atan2(sc);
        }
    }
    let total: f64 = votes.iter().map(|v| v.1).sum();
    let share = wn / total.max(1e-300);
    // The sun's side of the line. Above HORIZON_ELEVATION_DEG the known elevation decides: of the
    // two candidates (azimuth α or α + 180° at that elevation) the sun is the one the E-vectors
    // are more nearly perpendicular to (Σ DoLP (e·s)² smaller). Nearer the horizon the two
    // candidates coincide and the brighter half of the sky decides ([`intensity_side`]).
    let el = (90.0 - setup.sun.zenith_deg).to_radians();
    let mut u = DVec3::new(el.cos() * alpha.cos(), el.cos() * alpha.sin(), el.sin());
    let other = DVec3::new(-u.x, -u.y, u.z);
    let side = if 90.0 - setup.sun.zenith_deg >= HORIZON_ELEVATION_DEG {
        let (a, b) = (tilt * u, tilt * other);
        let (mut ca, mut cb) = (0.0, 0.0);
        for &(e, d) in &evecs {
            ca += d * e.dot(a).powi(2);
            cb += d * e.dot(b).powi(2);
        }
        // normalised difference in [−1, 1], positive for u
        if ca + cb > 0.0 {
            (cb - ca) / (ca + cb)
        } else {
            0.0
        }
    } else {
        intensity_side(view, setup, tilt * u).ok_or_else(|| {
            Error::Invalid("heading: the hough method needs the intensity S0".into())
        })?
    };
    if side < 0.0 {
        u = other;
    }
    let s_c = tilt * u;
    let sun_enu = setup.sun.vector();
    let (yaw_deg, horiz) = yaw_from(u, sun_enu);
    // The share of the votes on the line is a ratio: it stays high when clouds hide most of the
    // meridian and a handful of votes elsewhere make the peak (13 votes at 75 % cloud cover gave
    // a 5.4° error at share 0.51), so the line's support, its number of votes, counts too.
    // the Rayleigh residual at this yaw, as in the eigenvector method (RMS factor only)
    let res = rayleigh_residual(view, setup, yaw_deg);
    let residual_deg = res.rms_deg;
    let sky = sky_fraction(view.aolp_deg, view.dolp, setup);
    let confidence = (share
        * (horiz / 0.17).min(1.0)
        * (side.abs() / 0.2).min(1.0)
        * (nline as f64 / HOUGH_FULL_VOTES).min(1.0)
        * rms_factor(res.rms_deg)
        * sky_factor(sky))
    .clamp(0.0, 1.0);
    Ok(HeadingEstimate {
        yaw_deg,
        confidence,
        pixels: votes.len(),
        sun_camera: s_c,
        residual_deg,
        sky_fraction: sky,
    })
}
