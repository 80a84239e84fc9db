//! The model fit: the yaw (and the neutral points' distances) that make the sky model's AoP
//! best match the measured one, by reweighted Gauss-Newton on sampled pixels.

use super::*;

/// What the model fit found besides the yaw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelFitInfo {
    /// Fitted Babinet distance, degrees.
    pub babinet_deg: f64,
    /// Fitted Brewster distance, degrees.
    pub brewster_deg: f64,
    /// Fitted (or given) sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Weighted RMS of the AoLP residuals of the inliers, degrees.
    pub rms_residual_deg: f64,
    /// Fraction of the DoLP weight kept by the robust weights.
    pub inlier_fraction: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Evaluations of the residuals (each with its analytic derivatives) over all pixels: the
    /// fit's cost.
    pub evaluations: usize,
}

/// Solves the n × n system `a x = b` (n ≤ 4) by Gaussian elimination with partial pivoting.
pub(super) fn solve_small(mut a: [[f64; 4]; 4], mut b: [f64; 4], n: usize) -> Option<[f64; 4]> {
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))?;
        if a[p][k].abs() < 1e-300 {
            return None;
        }
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..n {
            let f = a[i][k] / a[k][k];
            let ak = a[k];
            for (aij, akj) in a[i][k..n].iter_mut().zip(&ak[k..n]) {
                *aij -= f * akj;
            }
            b[i] -= f * b[k];
        }
    }
    let mut x = [0.0; 4];
    for k in (0..n).rev() {
        let mut v = b[k];
        for j in k + 1..n {
            v -= a[k][j] * x[j];
        }
        x[k] = v / a[k][k];
    }
    Some(x)
}

/// The element of rank len/2 (the upper median; what sorting and indexing [len / 2] gave), by
/// selection instead of a full sort. `v` must not be empty; its order is changed.
pub(super) fn median_of(v: &mut [f64]) -> f64 {
    let m = v.len() / 2;
    *v.select_nth_unstable_by(m, f64::total_cmp).1
}

/// A pixel's lens basis for the model fit's residual: the sensor vector of an E-vector e is
/// (e·m) ρ̂ + (e·s) φ̂ ([`crate::camera::Lens::sensor_vector`]; for the pinhole m = x̂, s = ŷ,
/// ρ̂ = x̂, φ̂ = ŷ), so its AOP relative to ρ̂ is atan2(e·s, e·m); the observed AoLP φ relative to
/// ρ̂ is kept as (cos 2φ′, sin 2φ′).
pub(super) struct SensorBasis {
    pub(super) m: DVec3,
    pub(super) s: DVec3,
    pub(super) c2: f64,
    pub(super) s2: f64,
}

impl SensorBasis {
    pub(super) fn new(lens: crate::camera::Lens, d: DVec3, phi: f64) -> Self {
        let h = d.x.hypot(d.y);
        let (m, s, rho) = match lens {
            crate::camera::Lens::Ideal if h >= 1e-12 => {
                let (ux, uy) = (d.x / h, d.y / h);
                (
                    DVec3::new(d.z * ux, d.z * uy, -h),
                    DVec3::new(-uy, ux, 0.0),
                    uy.atan2(ux),
                )
            }
            _ => (DVec3::X, DVec3::Y, 0.0),
        };
        let (s2, c2) = (2.0 * (phi - rho)).sin_cos();
        SensorBasis { m, s, c2, s2 }
    }

    /// Observed minus predicted AoLP of E-vector `e` (camera frame), wrapped to (−π/2, π/2]
    /// (what [`fit_residuals`] computes from per-pixel constants; the tests' reference, and the
    /// Rayleigh residual of the eigen and Hough estimates).
    pub(super) fn residual(&self, e: DVec3) -> f64 {
        let (a, b) = (e.dot(self.m), e.dot(self.s));
        // doubled predicted angle: (a² − b², 2ab) ∝ (cos 2θ, sin 2θ)
        let (pc, ps) = (a * a - b * b, 2.0 * a * b);
        0.5 * (self.s2 * pc - self.c2 * ps).atan2(self.c2 * pc + self.s2 * ps)
    }
}

/// An angle difference wrapped to (−π/2, π/2] (AoLP is axial).
#[cfg(test)]
pub(super) fn wrap_half_pi(d: f64) -> f64 {
    let h = std::f64::consts::FRAC_PI_2;
    let r = (d + h).rem_euclid(std::f64::consts::PI) - h;
    if r <= -h {
        r + std::f64::consts::PI
    } else {
        r
    }
}

/// Pixels of the estimate: unit camera ray, AoLP (radians, sensor frame) and DoLP; every `step`-th
/// pixel with a finite AoLP and min_dolp ≤ DoLP ≤ 1, looking forward.
pub(super) fn fit_samples(
    aolp_deg: &Image<f32>,
    dolp: &Image<f32>,
    setup: &HeadingSetup,
    step: usize,
) -> Vec<(DVec3, f64, f64)> {
    let i = &setup.intrinsics;
    let mut out = Vec::new();
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
            out.push((ray.normalize(), a.to_radians(), d));
        }
    }
    out
}

/// Stages of Tukey reweighting of the model fit after its first (DoLP² weights).
pub(super) const FIT_REWEIGHTS: usize = 3;
/// The model fit's step below which a stage has converged: yaw, then the other parameters
/// (degrees).
pub(super) const FIT_STEP_TOL: [f64; 2] = [1e-4, 1e-2];
/// Iterations of a model-fit stage before its weights are re-estimated, at most (the fixed
/// schedule before converged stages reweighted after 2, 3 and 4 iterations).
pub(super) const FIT_STAGE_ITERATIONS: usize = 4;
/// Levenberg-Marquardt iterations of the model fit at most (all stages).
pub(super) const FIT_MAX_ITERATIONS: usize = 40;

/// One pixel of the model fit, reduced to what its residual needs. With the yaw ψ entering as
/// the sun's azimuth in the level frame (C(ψ)ᵀ r = R_z(−ψ) u and R_z(ψ) E(R_z(−ψ) u; A) =
/// E(u; A − ψ): the sky turns with the sun), the pixel's level-frame ray u, and so its chart
/// point ζ and chart basis (N, E), are fixed: the predicted E-vector is cos χ N + sin χ E with
/// e^{2iχ} = e^{2iA'} p/|p| (A' = A − ψ, p the Berry polynomial at ζ e^{−iA'},
/// [`crate::sky::berry`]), and its sensor angle against the observed AoLP
/// ([`SensorBasis::residual`]) is ½ atan2(Y, X) with X, Y linear in (cos 2χ, sin 2χ):
/// X = x₀ + x₁ cos 2χ + x₂ sin 2χ, Y likewise.
#[derive(Clone, Copy, Debug)]
pub(super) struct FitPixel {
    pub(super) zeta: num_complex::Complex64,
    pub(super) x: [f64; 3],
    pub(super) y: [f64; 3],
    /// The ray is above the level horizon (else residual 0, as the Berry field is not used).
    pub(super) up: bool,
}

/// The [`FitPixel`]s of the fit samples (unit camera ray, AoLP radians, DoLP), for a camera of
/// known tilt `tilt` (R_y(roll) R_x(pitch)) and lens.
pub(super) fn fit_pixels(
    samples: &[(DVec3, f64, f64)],
    tilt: DMat3,
    lens: crate::camera::Lens,
) -> Vec<FitPixel> {
    let tt = tilt.transpose();
    samples
        .iter()
        .map(|&(ray, phi, _)| {
            let b = SensorBasis::new(lens, ray, phi);
            let u = tt * ray;
            if u.z <= 0.0 {
                return FitPixel {
                    zeta: num_complex::Complex64::new(0.0, 0.0),
                    x: [0.0; 3],
                    y: [0.0; 3],
                    up: false,
                };
            }
            let (n, e) = crate::sky::berry::chart_basis(u);
            let (n, e) = (tilt * n, tilt * e);
            let (nm, ns, em, es) = (n.dot(b.m), n.dot(b.s), e.dot(b.m), e.dot(b.s));
            // doubled predicted sensor angle (a² − b², 2ab) for a = e·m, b = e·s,
            // e = cos χ N + sin χ E: P₀ + P₁ cos 2χ + P₂ sin 2χ and Q₀ + Q₁ cos 2χ + Q₂ sin 2χ
            let pp = [
                0.5 * (nm * nm - ns * ns + em * em - es * es),
                0.5 * (nm * nm - ns * ns - em * em + es * es),
                nm * em - ns * es,
            ];
            let qq = [nm * ns + em * es, nm * ns - em * es, nm * es + em * ns];
            FitPixel {
                zeta: crate::sky::berry::chart(u),
                x: std::array::from_fn(|k| b.c2 * pp[k] + b.s2 * qq[k]),
                y: std::array::from_fn(|k| b.s2 * pp[k] - b.c2 * qq[k]),
                up: true,
            }
        })
        .collect()
}

/// atan2 in f64 to within 2e-11 rad (octant reduction, then |z| ≤ tan(π/8) and the Taylor
/// series of atan to z²³), with selects only; the model fit's residual, where libm's atan2 was
/// half the cost. atan2(0, 0) = 0.
#[inline(always)]
pub(super) fn atan2_fit(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (mn, mx) = (ax.min(ay), ax.max(ay));
    let t = mn / mx.max(f64::MIN_POSITIVE);
    let big = t > std::f64::consts::SQRT_2 - 1.0;
    let z = if big { (t - 1.0) / (t + 1.0) } else { t };
    let z2 = z * z;
    // atan z = z + z³ Σ_{k=1..11} (−1)^k z^{2k−2}/(2k+1), the first term left out below
    // |z|²⁵/25 ≤ 1.2e-11
    const C: [f64; 11] = [
        -1.0 / 3.0,
        1.0 / 5.0,
        -1.0 / 7.0,
        1.0 / 9.0,
        -1.0 / 11.0,
        1.0 / 13.0,
        -1.0 / 15.0,
        1.0 / 17.0,
        -1.0 / 19.0,
        1.0 / 21.0,
        -1.0 / 23.0,
    ];
    let mut p = C[10];
    for &c in C[..10].iter().rev() {
        p = p * z2 + c;
    }
    let a = z + z * z2 * p + if big { FRAC_PI_4 } else { 0.0 };
    let a = if ay > ax { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// Pixels per parallel chunk of [`fit_residuals`]: each pixel's residual and derivatives depend
/// on that pixel only, so the answers do not depend on the number of threads.
pub(super) const FIT_CHUNK: usize = 2048;

/// Residuals (observed − predicted AoLP, radians, wrapped to ±90°) of the model fit's pixels at
/// parameters `p` = [ψ°, δ_Ba°, δ_Br°, θ_s°] (sun compass azimuth `az_deg`), and their
/// derivatives per degree of each parameter, analytic: r = ½ atan2(Y, X) depends on the
/// parameters through Φ = 2χ = 2A' + arg p only, ∂r/∂Φ = ½ (X ∂Y/∂Φ − Y ∂X/∂Φ)/(X² + Y²), and
/// ∂ ln p/∂z = Σ 1/(z − t±) + t±/(1 + t± z), ∂ ln p/∂t± = −1/(z − t±) + z/(1 + t± z), with
/// z = ζ e^{−iA'}. With `tied` (the elevation fit, δ_Ba = δ_Br), column 1 is ∂/∂δ of both.
pub(super) fn fit_residuals(
    px: &[FitPixel],
    p: [f64; 4],
    az_deg: f64,
    tied: bool,
    r: &mut [f64],
    jac: &mut [[f64; 4]],
) {
    use num_complex::Complex64 as C;
    let deg = std::f64::consts::PI / 180.0;
    let t_plus = (0.5 * (p[3] + p[2]) * deg).tan();
    let t_minus = (0.5 * (p[3] - p[1]) * deg).tan();
    let a = (az_deg - p[0]) * deg;
    let sd = C::new(a.cos(), a.sin());
    let sd_conj = sd.conj();
    let e2 = sd * sd;
    // dt/d(parameter degrees)
    let dtp = 0.5 * (1.0 + t_plus * t_plus) * deg;
    let dtm = 0.5 * (1.0 + t_minus * t_minus) * deg;
    px.par_chunks(FIT_CHUNK)
        .zip(r.par_chunks_mut(FIT_CHUNK))
        .zip(jac.par_chunks_mut(FIT_CHUNK))
        .for_each(|((px, r), jac)| {
            for ((q, r), j) in px.iter().zip(r).zip(jac) {
                if !q.up {
                    *r = 0.0;
                    *j = [0.0; 4];
                    continue;
                }
                let z = q.zeta * sd_conj;
                let f1 = C::new(z.re - t_plus, z.im);
                let f2 = C::new(z.re - t_minus, z.im);
                let f3 = C::new(1.0 + t_plus * z.re, t_plus * z.im);
                let f4 = C::new(1.0 + t_minus * z.re, t_minus * z.im);
                let pz = -((f1 * f2) * (f3 * f4));
                let m2 = pz.norm_sqr();
                if m2 <= 0.0 || !m2.is_finite() {
                    // a neutral point: the field's direction is undefined (χ = 0, as the sky
                    // model), no derivative
                    let (x, y) = (q.x[0] + q.x[1], q.y[0] + q.y[1]);
                    *r = 0.5 * atan2_fit(y, x);
                    *j = [0.0; 4];
                    continue;
                }
                let u = e2 * pz / m2.sqrt(); // e^{2iχ}
                let (cc, ss) = (u.re, u.im);
                let x = q.x[0] + q.x[1] * cc + q.x[2] * ss;
                let y = q.y[0] + q.y[1] * cc + q.y[2] * ss;
                *r = 0.5 * atan2_fit(y, x);
                let (dx, dy) = (q.x[2] * cc - q.x[1] * ss, q.y[2] * cc - q.y[1] * ss);
                let h2 = x * x + y * y;
                let g = if h2 > 0.0 {
                    0.5 * (x * dy - y * dx) / h2
                } else {
                    0.0
                };
                let (i1, i2, i3, i4) = (f1.inv(), f2.inv(), f3.inv(), f4.inv());
                let l = i1 + i2 + i3 * t_plus + i4 * t_minus;
                // ∂Φ/∂A' = 2 − Re(z L); A' = A − ψ
                let d_psi = -(2.0 - (z * l).re) * deg;
                let d_tp = (z * i3 - i1).im;
                let d_tm = (z * i4 - i2).im;
                let (d_ba, d_br) = (-d_tm * dtm, d_tp * dtp);
                let d_th = d_tp * dtp + d_tm * dtm;
                *j = if tied {
                    [g * d_psi, g * (d_ba + d_br), g * d_th, 0.0]
                } else {
                    [g * d_psi, g * d_ba, g * d_br, 0.0]
                };
            }
        });
}

/// Pixels the model fit aims for (every k-th pixel in each direction).
pub const MODEL_FIT_SAMPLES: f64 = 12_000.0;

/// The model fit's sampling step: every `setup.step`-th pixel, or sparser so that about
/// [`MODEL_FIT_SAMPLES`] pixels are read. Its eigenvector start reads the same pixels.
pub fn model_fit_step(setup: &HeadingSetup) -> usize {
    step_for_samples(setup, MODEL_FIT_SAMPLES)
}

/// The model fit: the yaw ψ and the Berry field's neutral-point distances δ_Ba,
/// δ_Br (and with `fit_elevation` the sun zenith) that best explain the observed AoLP,
/// started from `start` (the eigenvector answer). The predicted AoLP of a pixel is the Berry
/// E-vector ([`crate::sky::berry::BerryField`]) at its ENU view direction C(ψ)ᵀ r, projected on
/// the sensor with C(ψ) = R_y(roll) R_x(pitch) R_z(ψ); residuals are wrapped to ±90°, weighted by
/// DoLP (inverse variance: weights DoLP²), and made robust by Tukey weights (MAD scale,
/// re-estimated `FIT_REWEIGHTS` times, each time the steps have converged). Solved by
/// Levenberg-Marquardt with analytic derivatives (`fit_residuals`; pixels in parallel, the
/// sums in a fixed order, so the answer does not depend on the number of threads) on about
/// [`MODEL_FIT_SAMPLES`] pixels.
///
/// On a Rayleigh sky the fit drives δ to 0 (the Berry field's Rayleigh limit), so it is exact
/// there too.
pub fn model_fit_heading(
    aolp_deg: &Image<f32>,
    dolp: &Image<f32>,
    setup: &HeadingSetup,
    start: &HeadingEstimate,
    fit_elevation: bool,
) -> Result<(HeadingEstimate, ModelFitInfo)> {
    let i = &setup.intrinsics;
    check_sun_defines_yaw(&setup.sun)?;
    let samples = fit_samples(aolp_deg, dolp, setup, model_fit_step(setup));
    if samples.len() < 10 {
        return Err(Error::TooFewPixels(format!(
            "heading: only {} pixels with DoLP >= {} (need 10)",
            samples.len(),
            setup.min_dolp
        )));
    }
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let az = setup.sun.azimuth_deg;
    // p = [ψ deg, δ_Ba, δ_Br, θ_s]. The Berry field depends on the sun only through its neutral
    // points, so with the elevation free one distance δ_Ba = δ_Br is fitted (the sun is then
    // midway between Babinet and Brewster).
    let active: &[usize] = if fit_elevation {
        &[0, 1, 3]
    } else {
        &[0, 1, 2]
    };
    let np = active.len();
    let clamp = |p: [f64; 4]| {
        let d = p[1].clamp(0.0, 60.0);
        [
            p[0],
            d,
            if fit_elevation {
                d
            } else {
                p[2].clamp(0.0, 60.0)
            },
            p[3].clamp(0.0, 90.0),
        ]
    };
    // per pixel, once: the constants of its residual as a function of the doubled chart angle
    // (`FitPixel`), so a residual and its derivatives cost a few complex products and one atan2
    let pixels = fit_pixels(&samples, tilt, i.lens());
    let n = pixels.len();
    let (d_ba, d_br) = setup.warm_start.unwrap_or((25.0, 25.0));
    let warm = setup.warm_start.is_some();
    let mut p = clamp([start.yaw_deg, d_ba, d_br, setup.sun.zenith_deg]);
    // inverse-variance weights: the AoLP noise of a pixel is ∝ 1/DoLP
    let mut w: Vec<f64> = samples.iter().map(|s| s.2 * s.2).collect();
    let cost = |r: &[f64], w: &[f64]| r.iter().zip(w).map(|(r, w)| w * r * r).sum::<f64>();
    let (mut r, mut rt) = (vec![0.0; n], vec![0.0; n]);
    let (mut jac, mut jact) = (vec![[0.0; 4]; n], vec![[0.0; 4]; n]);
    let eval = |p: [f64; 4], r: &mut [f64], jac: &mut [[f64; 4]]| {
        fit_residuals(&pixels, p, az, fit_elevation, r, jac)
    };
    eval(p, &mut r, &mut jac);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut evaluations = 1;
    let reweight = |r: &[f64], w: &mut Vec<f64>| {
        let mut a: Vec<f64> = r.iter().map(|x| x.abs()).collect();
        let c = (4.685 * 1.4826 * median_of(&mut a)).max(0.5f64.to_radians());
        for (k, s) in samples.iter().enumerate() {
            let u = r[k] / c;
            w[k] = if u.abs() >= 1.0 {
                0.0
            } else {
                s.2 * s.2 * (1.0 - u * u).powi(2)
            };
        }
    };
    // Iteratively reweighted Levenberg-Marquardt: each stage iterates until the step is below
    // FIT_STEP_TOL (or no step lowers the cost), then the Tukey weights are re-estimated from the
    // residuals; FIT_REWEIGHTS stages after the first (a warm start reweights before its first
    // step too, its residuals being those of the previous frame's field).
    let mut reweights = 0;
    let mut stage_iterations = 0;
    if warm {
        reweight(&r, &mut w);
    }
    for it in 0..FIT_MAX_ITERATIONS {
        iterations = it + 1;
        stage_iterations += 1;
        let mut jtj = [[0.0; 4]; 4];
        let mut jtr = [0.0; 4];
        for ((row, &rj), &wj) in jac.iter().zip(&r).zip(&w) {
            for a in 0..np {
                jtr[a] += wj * row[a] * rj;
                for b in 0..np {
                    jtj[a][b] += wj * row[a] * row[b];
                }
            }
        }
        let c0 = cost(&r, &w);
        let mut improved = false;
        let mut converged = false;
        for attempt in 0..8 {
            let mut m = jtj;
            let tr: f64 = (0..np).map(|k| jtj[k][k]).sum::<f64>().max(1e-300);
            for (k, mk) in m.iter_mut().enumerate().take(np) {
                mk[k] += lambda * jtj[k][k] + 1e-9 * tr;
            }
            let Some(d) = solve_small(m, jtr, np) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p;
            for (k, &pk) in active.iter().enumerate() {
                q[pk] -= d[k];
            }
            let q = clamp(q);
            if attempt == 0
                && (q[0] - p[0]).abs() < FIT_STEP_TOL[0]
                && (1..4).all(|k| (q[k] - p[k]).abs() < FIT_STEP_TOL[1])
            {
                // the undamped step is below the tolerance: converged without evaluating it
                converged = true;
                break;
            }
            eval(q, &mut rt, &mut jact);
            evaluations += 1;
            if cost(&rt, &w) < c0 {
                converged = (q[0] - p[0]).abs() < FIT_STEP_TOL[0]
                    && (1..4).all(|k| (q[k] - p[k]).abs() < FIT_STEP_TOL[1]);
                p = q;
                std::mem::swap(&mut r, &mut rt);
                std::mem::swap(&mut jac, &mut jact);
                lambda = (lambda / 3.0).max(1e-9);
                improved = true;
                break;
            }
            lambda *= 4.0;
        }
        // a stage also ends after FIT_STAGE_ITERATIONS (a noisy frame's steps can zig-zag slowly
        // toward the minimum of the unweighted cost; the Tukey weights end that); the last one
        // runs to convergence
        let last = reweights == FIT_REWEIGHTS;
        if !improved || converged || (!last && stage_iterations >= FIT_STAGE_ITERATIONS) {
            if last {
                break;
            }
            reweight(&r, &mut w);
            reweights += 1;
            stage_iterations = 0;
        }
    }
    let wsum: f64 = w.iter().sum();
    let dsum: f64 = samples.iter().map(|s| s.2 * s.2).sum();
    let rms = (cost(&r, &w) / wsum.max(1e-300)).sqrt().to_degrees();
    let inlier = wsum / dsum.max(1e-300);
    // the residual of every pixel used (above the level horizon), without the robust weights:
    // inputs the sky does not fit show here, while the Tukey weights drop the misfits
    let rr: Vec<f64> = pixels
        .iter()
        .zip(&r)
        .map(|(q, &x)| if q.up { x } else { f64::NAN })
        .collect();
    let rays: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
    let res = Residual::of(&rr, &rays);
    let residual_deg = res.rms_deg;
    // the camera-frame sun of the fitted attitude
    let c = tilt * crate::camera::rot_z(p[0].to_radians());
    let sun = SunPosition::new(p[3], az);
    let s_c = c * sun.vector();
    let horiz = sun.vector().truncate().length();
    // how much of the image is sky, here; the start's confidence without it (it would count
    // twice)
    let sky = sky_fraction(aolp_deg, dolp, setup);
    let start_sky = sky_factor(start.sky_fraction);
    let start_conf = if start_sky > 0.0 {
        start.confidence / start_sky
    } else {
        start.confidence
    };
    // how well the yaw is fixed (sun height), how much of the sky agrees with the model, how
    // tight the residuals are, how many pixels there are, and (halved at worst) the starting
    // answer's own confidence, which carries the 180° decision near the horizon
    let confidence = ((horiz / 0.17).min(1.0)
        * inlier
        * spread_factor(rms)
        * (samples.len() as f64 / 300.0).min(1.0)
        * (0.5 + 0.5 * start_conf.clamp(0.0, 1.0))
        * residual_factor(&res)
        * sky_factor(sky))
    .clamp(0.0, 1.0);
    Ok((
        HeadingEstimate {
            yaw_deg: p[0].rem_euclid(360.0),
            confidence,
            pixels: samples.len(),
            sun_camera: s_c,
            residual_deg,
            sky_fraction: sky,
        },
        ModelFitInfo {
            babinet_deg: p[1],
            brewster_deg: p[2],
            sun_zenith_deg: p[3],
            rms_residual_deg: rms,
            inlier_fraction: inlier,
            iterations,
            evaluations,
        },
    ))
}
