//! Attitude angles, error statistics, and the sampling that sizes each estimator's work.

use super::*;

/// The camera-to-ENU rotation of a stream attitude quaternion `[w, x, y, z]` (normalised here).
pub(super) fn camera_to_enu(wxyz: [f64; 4]) -> DMat3 {
    let q = glam::DQuat::from_xyzw(wxyz[1], wxyz[2], wxyz[3], wxyz[0]).normalize();
    DMat3::from_quat(q)
}

/// The ENU yaw (degrees, [0, 360)) of an attitude quaternion `[w, x, y, z]` rotating camera
/// vectors into ENU (the stream's `attitude_wxyz`): the ψ of C = R_y(roll) R_x(pitch) R_z(ψ), i.e.
/// what `psns render --frame enu --yaw` means. Row 2 of C is R_z(ψ)ᵀ (0, cos ϑ, ±sin ϑ), so
/// ψ = atan2 of its east and north components (defined for |pitch| < 90°).
pub fn attitude_yaw_deg(wxyz: [f64; 4]) -> f64 {
    let h = camera_to_enu(wxyz) * DVec3::Y;
    h.x.atan2(h.y).to_degrees().rem_euclid(360.0)
}

/// Pitch and roll (degrees) of an attitude quaternion `[w, x, y, z]` (camera → ENU), as
/// `--pitch/--roll` mean in `psns render`: what an IMU measures, from the up direction in the
/// camera frame, C e_z = (−sin φ cos ϑ, sin ϑ, cos φ cos ϑ). Independent of the yaw.
pub fn attitude_tilt_deg(wxyz: [f64; 4]) -> (f64, f64) {
    let up = camera_to_enu(wxyz).transpose() * DVec3::Z;
    (
        up.y.clamp(-1.0, 1.0).asin().to_degrees(),
        (-up.x).atan2(up.z).to_degrees(),
    )
}

/// A signed angle difference wrapped to (−180, 180] degrees.
pub fn wrap180(d: f64) -> f64 {
    let r = d.rem_euclid(360.0);
    if r > 180.0 {
        r - 360.0
    } else {
        r
    }
}

/// Summary of heading errors (degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorStats {
    /// Errors summarised (finite ones).
    pub count: usize,
    /// Root mean square.
    pub rms: f64,
    /// 95th percentile of |error| (nearest rank).
    pub p95: f64,
    /// Largest |error|.
    pub max: f64,
}

/// RMS, 95th percentile (nearest rank) and maximum of the finite values of `errors_deg`; NaN
/// statistics when there are none.
pub fn error_stats(errors_deg: &[f64]) -> ErrorStats {
    let mut a: Vec<f64> = errors_deg
        .iter()
        .filter(|e| e.is_finite())
        .map(|e| e.abs())
        .collect();
    if a.is_empty() {
        return ErrorStats {
            count: 0,
            rms: f64::NAN,
            p95: f64::NAN,
            max: f64::NAN,
        };
    }
    a.sort_by(f64::total_cmp);
    let n = a.len();
    let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
    ErrorStats {
        count: n,
        rms: (a.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
        p95: a[rank - 1],
        max: a[n - 1],
    }
}

/// Confidence factor of a robust residual spread (degrees): 1 / (1 + (spread / 10°)²), so a
/// clean sky (spread of a few degrees) keeps most of its confidence and a noise-dominated frame
/// (spread of tens of degrees) loses it.
pub(super) fn spread_factor(spread_deg: f64) -> f64 {
    1.0 / (1.0 + (spread_deg / 10.0).powi(2))
}

/// Votes within ±1.5° of the solar meridian at which the Hough method's confidence is no longer
/// reduced for lack of support (the 612 × 512 bench frames put 90-220 there on a clear sky).
pub const HOUGH_FULL_VOTES: f64 = 100.0;

/// Pixels the eigenvector and Hough methods and the intensity vote sample at most (larger frames
/// are sampled more sparsely): a full 2448 × 2048 frame is read at every 11th pixel.
pub const EIGEN_SAMPLES: f64 = 40_000.0;

/// The sampling step of a frame: every `setup.step`-th pixel, or sparser so that no more than
/// about [`EIGEN_SAMPLES`] pixels are read (frames up to about 800 × 800 are unaffected).
pub fn sample_step(setup: &HeadingSetup) -> usize {
    step_for_samples(setup, EIGEN_SAMPLES)
}

/// Every `setup.step`-th pixel in each direction, or sparser so that about `samples` pixels of
/// the frame are read.
pub(super) fn step_for_samples(setup: &HeadingSetup, samples: f64) -> usize {
    let i = &setup.intrinsics;
    let n_px = (i.width * i.height) as f64;
    setup
        .step
        .max((n_px / samples).sqrt().floor() as usize)
        .max(1)
}

/// The horizontal sun component (sin of the sun's zenith angle) from which the eigenvector
/// method's confidence is not reduced: sin 45°.
pub const EIGEN_FULL_HORIZ: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The systematic residual at which [`residual_factor`] halves the confidence, degrees.
pub const SYSTEMATIC_HALF_DEG: f64 = 3.0;
/// The residual RMS at which [`rms_factor`] halves the confidence, degrees.
pub const RESIDUAL_HALF_DEG: f64 = 30.0;

/// Confidence factor of the model fit's [`Residual`]: 1 / (1 + (systematic /
/// [`SYSTEMATIC_HALF_DEG`])⁴) × [`rms_factor`]. The first falls when the sky does not fit the
/// inputs (a misfit that varies smoothly across the frame: wrong tilt, lens, or a picture that is
/// not of the sky), the second when the residual is noise as large as a picture of no sky gives.
///
/// ```
/// use psns::heading::{residual_factor, Residual};
/// let r = |rms_deg, systematic_deg| Residual { rms_deg, systematic_deg };
/// assert!(residual_factor(&r(2.0, 0.5)) > 0.99);
/// assert!((residual_factor(&r(3.0, 3.0)) - 0.5).abs() < 0.01);
/// assert!(residual_factor(&r(52.0, 0.0)) < 0.2); // uniformly random AoLP
/// assert_eq!(residual_factor(&r(f64::NAN, f64::NAN)), 0.0);
/// ```
pub fn residual_factor(r: &Residual) -> f64 {
    let f = rms_factor(r.rms_deg) / (1.0 + (r.systematic_deg / SYSTEMATIC_HALF_DEG).powi(4));
    if f.is_nan() {
        0.0
    } else {
        f
    }
}

/// Confidence factor of a residual RMS alone: 1 / (1 + (RMS / [`RESIDUAL_HALF_DEG`])⁴), 0.1 for
/// uniformly random AoLP (RMS 90°/√3 ≈ 52°), 0 for NaN. The eigenvector and Hough methods take
/// only this factor: their model, the Rayleigh sky, misses the Berry sky near its neutral points
/// by more (≈ 10° RMS on the default sky) than a wrong tilt adds.
///
/// ```
/// use psns::heading::rms_factor;
/// assert!(rms_factor(10.0) > 0.98);
/// assert!(rms_factor(52.0) < 0.11);
/// assert_eq!(rms_factor(f64::NAN), 0.0);
/// ```
pub fn rms_factor(rms_deg: f64) -> f64 {
    let f = 1.0 / (1.0 + (rms_deg / RESIDUAL_HALF_DEG).powi(4));
    if f.is_nan() {
        0.0
    } else {
        f
    }
}
