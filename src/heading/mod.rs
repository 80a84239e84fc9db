//! Heading from the sky's polarization: the sun-vector (eigenvector) estimator.
//!
//! Physics: in single (Rayleigh) scattering the E-vector of the light from view direction v is
//! perpendicular to the sun direction s (e ∝ s × v). Each pixel's AoLP φ, measured in the sensor
//! frame (from +x, columns, toward +y, rows — `conventions.md`), is the angle of e projected onto
//! the focal plane, so e lies in the plane spanned by (cos φ, sin φ, 0) and the optical axis and
//! is perpendicular to v: e = (cos φ, sin φ, t) with t = −(v_x cos φ + v_y sin φ)/v_z. The sun is
//! then the direction most perpendicular to every e: the eigenvector of the DoLP-weighted scatter
//! matrix Σ w e eᵀ with the smallest eigenvalue (after Zhang et al. / Lu et al.), made robust by
//! iteratively reweighting pixels with a Tukey weight on their residual e·s.
//!
//! Frame: with C = R_y(roll) R_x(pitch) R_z(yaw) taking ENU vectors into the camera frame
//! (`sky.md` §7, [`crate::camera::euler_matrix`]), the camera-frame sun s_c and the known ENU sun
//! s give R_z(yaw) s = (R_y R_x)ᵀ s_c, from which the yaw follows; pitch and roll are the tilt an
//! IMU supplies. The sign of the eigenvector is fixed by the sun being above the horizon.
//!
//! Limits: the Berry four-neutral-point field is not exactly perpendicular to the sun away from
//! the neutral points, so on the default sky this estimator alone has a bias (measured below in the
//! tests); the yaw is ill-conditioned with the sun near the zenith (confidence says so).

use crate::camera::{rot_x, rot_y, Intrinsics};
use crate::demosaic::superpixel::{superpixel_sampled, superpixel_sampled_flat};
use crate::demosaic::{demosaic_codes, Method, PolarImages};
use crate::error::{check_range, Error, Result};
use crate::image::Image;
use crate::sensor::mosaic::MosaicLayout;
use crate::sensor::optics::RelativeIllumination;
use crate::sun::SunPosition;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

mod codes;
mod eigen;
mod hough;
mod mask;
mod model_fit;
mod stats;
#[cfg(test)]
mod tests;
pub use codes::*;
pub use eigen::*;
pub use hough::*;
pub use mask::*;
pub use model_fit::*;
pub use stats::*;

/// What the estimator is given besides the pixels.
#[derive(Clone, Copy, Debug)]
pub struct HeadingSetup {
    /// Camera intrinsics of the images (pinhole).
    pub intrinsics: Intrinsics,
    /// Known tilt from an IMU, degrees (the meaning of `--pitch/--roll` in `psns render`).
    pub pitch_deg: f64,
    /// Known roll, degrees.
    pub roll_deg: f64,
    /// Sun position (from SPA and the time and place, or given).
    pub sun: SunPosition,
    /// Pixels with a DoLP below this are not used (sky near the sun, neutral points, noise).
    pub min_dolp: f64,
    /// Use every `step`-th pixel in each direction (1 = all).
    pub step: usize,
    /// Flat-field correction of S0 for the intensity decision near the horizon: the frames'
    /// relative illumination (default cos^1.5 of the field angle, the camera preset's lens; the
    /// PSNS presets `gniipi`/`gniicpi` fall off as cos⁴, `nfpi` not at all:
    /// [`crate::sensor::SensorConfig::effective_ri`]). Without it a tilted camera's vignetting
    /// outvotes the sky.
    pub relative_illumination: RelativeIllumination,
    /// Model fit only: fit the sun's zenith angle too (with one neutral-point distance), starting
    /// from `sun`'s.
    pub fit_elevation: bool,
    /// Model fit only: start the neutral-point distances (δ_Ba, δ_Br, degrees) here instead of
    /// at 25°, e.g. from the previous frame of a stream ([`ModelFitInfo`]); the robust weights
    /// are then set from the first residuals. The yaw still starts from the eigenvector answer.
    pub warm_start: Option<(f64, f64)>,
    /// Find which pixels are sky from the frame ([`find_sky_mask`]: too dark or bright,
    /// disagreeing with the sky model at the estimated yaw, in a region that does) before
    /// [`estimate_heading`] estimates, within [`PolarView::mask`] if one is given. Default on
    /// (`psns heading --mask auto`); off, only the given mask and the DoLP threshold decide.
    pub find_mask: bool,
}

impl HeadingSetup {
    /// Defaults: level camera, DoLP ≥ 0.05, every 4th pixel, the sky mask found from the frame.
    pub fn new(intrinsics: Intrinsics, sun: SunPosition) -> Self {
        HeadingSetup {
            intrinsics,
            pitch_deg: 0.0,
            roll_deg: 0.0,
            sun,
            min_dolp: 0.05,
            step: 4,
            relative_illumination: RelativeIllumination::CosPower { n: 1.5 },
            fit_elevation: false,
            warm_start: None,
            find_mask: true,
        }
    }
}

/// A heading estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingEstimate {
    /// Yaw in the ENU frame, degrees in [0, 360) (as `--frame enu --yaw` in `psns render`).
    pub yaw_deg: f64,
    /// 0..1: how well the sun is determined and how well it fixes the yaw (low near the zenith),
    /// and how well the sky fits the inputs (the residual: [`residual_factor`], [`rms_factor`]).
    pub confidence: f64,
    /// RMS of the AoLP residual, degrees: observed AoLP minus the estimator's sky model at the
    /// estimated yaw, with the given tilt and sun, wrapped to ±90°, over the pixels used
    /// ([`Residual::rms_deg`]). The model fit's model is its fitted Berry field; eigen's and
    /// Hough's the Rayleigh sky (E-vector ⟂ sun), which misses the default sky near its neutral
    /// points (≈ 10°). The model fit's is 1.5–2° on a clear 612 × 512 frame at auto-exposure
    /// with the right inputs, and grows when the tilt or the lens is wrong or the picture is not
    /// of the sky (uniformly random AoLP: 90°/√3 ≈ 52°).
    pub residual_deg: f64,
    /// Pixels used.
    pub pixels: usize,
    /// Estimated sun direction in the camera frame.
    pub sun_camera: DVec3,
    /// The fraction of the image (inside the image circle of a fisheye) used as sky: usable
    /// pixels of the (masked) images over the pixels inside ([`sky_fraction`]). The confidence
    /// includes [`sky_factor`] of it.
    pub sky_fraction: f64,
}

/// How the heading is estimated (`psns heading --method`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum HeadingMethod {
    /// Sun vector: smallest eigenvector of the E-vector scatter ([`eigenvector_heading`]).
    Eigen,
    /// Berry-field model fit started from the eigenvector answer ([`model_fit_heading`]).
    #[default]
    ModelFit,
    /// Solar meridian by Hough voting (after Lu et al. 2015, [`hough_heading`]).
    Hough,
}

crate::names::name_table!(HeadingMethod {
    Eigen => "eigen",
    ModelFit => "model-fit",
    Hough => "hough",
});

impl std::fmt::Display for HeadingMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for HeadingMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        HeadingMethod::from_name(s).ok_or_else(|| {
            Error::Invalid(format!(
                "heading method '{s}' is unknown (allowed: {})",
                HeadingMethod::names()
            ))
        })
    }
}

/// The images an estimator reads: AoLP (degrees, sensor frame), DoLP and, for the 180° decision
/// near the horizon, the intensity S0; and which of their pixels are sky, if that is known.
#[derive(Clone, Copy)]
pub struct PolarView<'a> {
    /// AoLP, degrees, from +x toward +y.
    pub aolp_deg: &'a Image<f32>,
    /// DoLP; NaN marks an unusable pixel.
    pub dolp: &'a Image<f32>,
    /// Intensity S0 (optional).
    pub s0: Option<&'a Image<f32>>,
    /// A given sky mask of the same size: nonzero = sky. [`estimate_heading`] (and
    /// [`hough_heading`], [`eigen_resolved`], [`intensity_side`], [`find_sky_mask`]) use only
    /// its sky pixels, by setting the DoLP of the others to NaN ([`masked_dolp`]); with
    /// [`HeadingSetup::find_mask`] the mask found from the frame is found within it.
    pub mask: Option<&'a Image<u8>>,
}

impl<'a> PolarView<'a> {
    /// A view of AoLP, DoLP and S0 images without a given mask.
    pub fn new(aolp_deg: &'a Image<f32>, dolp: &'a Image<f32>, s0: Option<&'a Image<f32>>) -> Self {
        PolarView {
            aolp_deg,
            dolp,
            s0,
            mask: None,
        }
    }
}

/// Runs one estimator. The model fit starts from the eigenvector answer (sun elevation given).
pub fn estimate_heading(
    method: HeadingMethod,
    view: &PolarView,
    setup: &HeadingSetup,
) -> Result<HeadingEstimate> {
    estimate_heading_info(method, view, setup).map(|r| r.0)
}

/// [`estimate_heading`], with the model fit's [`ModelFitInfo`] (`None` for the other methods):
/// what a stream passes on as the next frame's [`HeadingSetup::warm_start`]. The view's given
/// mask is applied first; with [`HeadingSetup::find_mask`] the estimator then reads only the
/// pixels of the mask found from the frame ([`find_sky_mask`]).
pub fn estimate_heading_info(
    method: HeadingMethod,
    view: &PolarView,
    setup: &HeadingSetup,
) -> Result<(HeadingEstimate, Option<ModelFitInfo>)> {
    let mut buf = None;
    let view = apply_view_mask(view, &mut buf)?;
    if !setup.find_mask {
        return estimate_unmasked(method, &view, setup);
    }
    let found = find_sky_mask(&view, setup)?;
    let dolp = masked_dolp(view.dolp, &found.mask)?;
    let v = PolarView {
        dolp: &dolp,
        mask: None,
        ..view
    };
    estimate_unmasked(method, &v, setup)
}

/// One estimator on every pixel of `view` with a usable DoLP (its mask, if any, is not read).
fn estimate_unmasked(
    method: HeadingMethod,
    view: &PolarView,
    setup: &HeadingSetup,
) -> Result<(HeadingEstimate, Option<ModelFitInfo>)> {
    match method {
        HeadingMethod::Hough => hough_heading(view, setup).map(|e| (e, None)),
        HeadingMethod::Eigen => Ok((eigen_resolved(view, setup)?, None)),
        HeadingMethod::ModelFit => model_fit_view(view, setup).map(|(e, i)| (e, Some(i))),
    }
}

/// The model fit of `view` started from the eigenvector answer on the fit's own pixels.
pub(super) fn model_fit_view(
    view: &PolarView,
    setup: &HeadingSetup,
) -> Result<(HeadingEstimate, ModelFitInfo)> {
    // the start only has to be near the answer: the eigenvector method on the fit's own
    // (sparser) pixels
    let mut s = *setup;
    s.step = model_fit_step(setup);
    let eigen = eigen_resolved(view, &s)?;
    model_fit_heading(view.aolp_deg, view.dolp, setup, &eigen, setup.fit_elevation)
}

/// Sun zenith angle (degrees) below which the sun's azimuth defines no yaw: the solar disc's
/// angular radius (0.262–0.271° over the year). A sun-direction uncertainty δ turns into a yaw
/// uncertainty of about δ / sin(zenith angle); with the sun's centre within its own radius of the
/// zenith, the disc covers the zenith, the uncertainty of its centre's direction is at least its
/// radius, and a sun on the other side of the zenith (any yaw) fits the picture as well. Above
/// it the confidence falls with sin(zenith angle) (each estimator's sun-height factor).
pub const ZENITH_SUN_DEG: f64 = 0.27;

/// Refuses AoLP and DoLP images whose size is not the intrinsics' (both sizes named).
fn check_image_sizes(aolp_deg: &Image<f32>, dolp: &Image<f32>, i: &Intrinsics) -> Result<()> {
    if (aolp_deg.width, aolp_deg.height) != (i.width, i.height)
        || (dolp.width, dolp.height) != (i.width, i.height)
    {
        return Err(Error::Invalid(format!(
            "heading: images of {} x {} and {} x {} pixels for intrinsics of {} x {}",
            aolp_deg.width, aolp_deg.height, dolp.width, dolp.height, i.width, i.height
        )));
    }
    Ok(())
}

/// `Err(`[`Error::Undetermined`]`)` when the known sun is within [`ZENITH_SUN_DEG`] of the
/// zenith: the estimators then give no yaw (NaN in the front-ends, as for too few pixels).
///
/// ```
/// use psns::heading::check_sun_defines_yaw;
/// use psns::sun::SunPosition;
/// assert!(check_sun_defines_yaw(&SunPosition::new(0.0, 200.0)).is_err());
/// assert!(check_sun_defines_yaw(&SunPosition::new(0.2, 200.0)).is_err());
/// assert!(check_sun_defines_yaw(&SunPosition::new(1.0, 200.0)).is_ok());
/// ```
pub fn check_sun_defines_yaw(sun: &SunPosition) -> Result<()> {
    if sun.zenith_deg < ZENITH_SUN_DEG {
        return Err(Error::Undetermined(format!(
            "heading: the sun is {} deg from the zenith, within the solar disc's radius \
             ({ZENITH_SUN_DEG} deg): its azimuth defines no yaw",
            sun.zenith_deg
        )));
    }
    Ok(())
}

/// The AoLP residuals (radians, wrapped to ±90°) of `samples` (unit camera ray, AoLP radians,
/// DoLP, as `fit_samples` draws them) against the Rayleigh sky (E-vector s × v) of the known sun
/// and tilt at yaw `yaw_deg`.
pub(super) fn rayleigh_residuals(
    samples: &[(DVec3, f64, f64)],
    setup: &HeadingSetup,
    yaw_deg: f64,
) -> Vec<f64> {
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let s_c = tilt * crate::camera::rot_z(yaw_deg.to_radians()) * setup.sun.vector();
    let lens = setup.intrinsics.lens();
    samples
        .iter()
        .map(|&(ray, phi, _)| SensorBasis::new(lens, ray, phi).residual(s_c.cross(ray)))
        .collect()
}

/// The residual of a fit: its RMS and the part of it that is not pixel noise, degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// RMS of the wrapped AoLP residuals over the pixels used ([`HeadingEstimate::residual_deg`]).
    pub rms_deg: f64,
    /// The systematic part: √max(0, mean r_k r_k′) over pairs of neighbouring samples k, k′.
    /// A sky that does not fit the inputs (wrong tilt, sun or lens) leaves a residual that varies
    /// smoothly across the frame, so neighbours share it (r_k r_k′ ≈ m²), while pixel noise is
    /// independent from one sample to the next and averages out of the product; noise so large
    /// that the AoLP is uniformly random in (−90°, 90°] averages out too.
    pub systematic_deg: f64,
}

impl Residual {
    /// From residuals `r` (radians, wrapped to ±90°) of samples in row-major order with unit rays
    /// `rays`; `NaN`s (pixels without a prediction) are left out. Neighbours are consecutive
    /// samples at most 1.5 × the median consecutive angle apart.
    pub fn of(r: &[f64], rays: &[DVec3]) -> Residual {
        let (mut ss, mut n) = (0.0, 0usize);
        for &x in r.iter().filter(|x| x.is_finite()) {
            ss += x * x;
            n += 1;
        }
        let mut gaps: Vec<f64> = rays.windows(2).map(|w| w[0].angle_between(w[1])).collect();
        let (mut cov, mut m) = (0.0, 0usize);
        if !gaps.is_empty() {
            let lim = 1.5 * median_of(&mut gaps);
            for k in 1..r.len().min(rays.len()) {
                let p = r[k] * r[k - 1];
                if p.is_finite() && rays[k].angle_between(rays[k - 1]) <= lim {
                    cov += p;
                    m += 1;
                }
            }
        }
        let cov = if m > 0 { cov / m as f64 } else { 0.0 };
        Residual {
            rms_deg: (ss / n as f64).sqrt().to_degrees(),
            systematic_deg: cov.max(0.0).sqrt().to_degrees(),
        }
    }
}

/// [`Residual`] of the Rayleigh sky at yaw `yaw_deg` on the pixels the eigenvector and Hough
/// methods use.
pub(super) fn rayleigh_residual(view: &PolarView, setup: &HeadingSetup, yaw_deg: f64) -> Residual {
    let samples = fit_samples(view.aolp_deg, view.dolp, setup, sample_step(setup));
    let rays: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
    Residual::of(&rayleigh_residuals(&samples, setup, yaw_deg), &rays)
}

/// Below this known sun elevation (degrees) the sign of the eigenvector's sun, "above the
/// horizon", is unreliable: the intensity decides instead.
pub const HORIZON_ELEVATION_DEG: f64 = 8.0;

/// The intensity's vote on which of ±`s_c` is the sun. Each pixel on the sunward side is paired
/// with its mirror image across the vertical plane perpendicular to the sun's azimuth (level frame,
/// from the known tilt): the pair sees the sky at the same zenith angle, sunward and anti-sunward,
/// so neither the horizon brightening nor the shape of the field of view can bias the vote. Each
/// pair votes with its S0 difference (flat-fielded by the frames' relative illumination,
/// [`HeadingSetup::relative_illumination`]) times its distance from that plane: the sunward half
/// of the sky is brighter. Returned normalised to [−1, 1] (Σ ΔL x / Σ |ΔL| x); `None` without S0, with a
/// sun at the zenith, or with fewer than 10 pairs inside the image.
pub fn intensity_side(view: &PolarView, setup: &HeadingSetup, s_c: DVec3) -> Option<f64> {
    let mut buf = None;
    let view = &apply_view_mask(view, &mut buf).ok()?;
    let s0 = view.s0?;
    let i = &setup.intrinsics;
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let u = tilt.transpose() * s_c;
    let hl = u.x.hypot(u.y);
    if hl < 1e-9 {
        return None;
    }
    let h = DVec3::new(u.x / hl, u.y / hl, 0.0);
    let step = sample_step(setup);
    let ri = setup.relative_illumination;
    let usable = |k: usize, col: f64, row: f64| {
        let (l, d) = (s0.data[k] as f64, view.dolp.data[k] as f64);
        // flat-field: divide by the relative illumination at the pixel
        let f = ri.factor(i, col, row);
        (l.is_finite() && d.is_finite() && l > 0.0 && f > 0.0).then_some(l / f)
    };
    let (mut num, mut den, mut pairs) = (0.0, 0.0, 0usize);
    for row in (0..i.height).step_by(step) {
        for col in (0..i.width).step_by(step) {
            let Some(ray) = i.ray(col as f64, row as f64) else {
                continue;
            };
            let v = tilt.transpose() * ray.normalize();
            let x = v.dot(h);
            if x <= 0.0 {
                continue;
            }
            let Some((cm, rm)) = i.project(tilt * (v - 2.0 * x * h)) else {
                continue;
            };
            let (cm, rm) = (cm.round(), rm.round());
            if cm < 0.0 || rm < 0.0 || cm >= i.width as f64 || rm >= i.height as f64 {
                continue;
            }
            let k = row * i.width + col;
            let km = rm as usize * i.width + cm as usize;
            let (Some(l), Some(lm)) = (usable(k, col as f64, row as f64), usable(km, cm, rm))
            else {
                continue;
            };
            num += (l - lm) * x;
            den += (l - lm).abs() * x;
            pairs += 1;
        }
    }
    if pairs < 10 {
        return None;
    }
    Some(if den > 0.0 { num / den } else { 0.0 })
}

/// The eigenvector answer with the 180° ambiguity near the horizon decided by the intensity:
/// with the known sun elevation below [`HORIZON_ELEVATION_DEG`], "the sun is above the horizon"
/// no longer fixes the eigenvector's sign, so the brighter half of the sky does; the confidence is
/// scaled by how clearly it does (|vote| / 0.3, at most 1).
pub fn eigen_resolved(view: &PolarView, setup: &HeadingSetup) -> Result<HeadingEstimate> {
    let mut buf = None;
    let view = &apply_view_mask(view, &mut buf)?;
    let mut e = eigenvector_heading(view.aolp_deg, view.dolp, setup)?;
    if 90.0 - setup.sun.zenith_deg >= HORIZON_ELEVATION_DEG {
        return Ok(e);
    }
    match intensity_side(view, setup, e.sun_camera) {
        Some(c) => {
            if c < 0.0 {
                e.sun_camera = -e.sun_camera;
                e.yaw_deg = (e.yaw_deg + 180.0).rem_euclid(360.0);
                // the other end of the sun's axis: its own residual (near the horizon both fit
                // about equally)
                let samples = fit_samples(view.aolp_deg, view.dolp, setup, sample_step(setup));
                let rays: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
                let old = rayleigh_residual(view, setup, e.yaw_deg - 180.0);
                let new = Residual::of(&rayleigh_residuals(&samples, setup, e.yaw_deg), &rays);
                e.confidence *= rms_factor(new.rms_deg) / rms_factor(old.rms_deg).max(1e-300);
                e.residual_deg = new.rms_deg;
            }
            e.confidence *= (c.abs() / 0.3).min(1.0);
        }
        None => e.confidence *= 0.5,
    }
    Ok(e)
}
