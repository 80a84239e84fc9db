//! The clear sky: radiance, degree and angle of polarization in any direction above the horizon.
//!
//! * radiance: Hosek–Wilkie spectral model v1.4a ([`hosek`]), W m⁻² sr⁻¹ nm⁻¹;
//! * E-vector (AOP): Berry, Dennis & Lee's four-neutral-point field ([`berry`]) or the single-scattering
//!   Rayleigh field ([`rayleigh`]);
//! * DOP: PSNS eq. (5) after Wang et al. 2016 ([`dop`]) or Rayleigh.
//!
//! Frame: ENU (x east, y north, z up); directions as zenith angle θ and compass azimuth A
//! (`sky.md` §1). The E-vector is returned as a 3-D unit vector perpendicular to the view
//! direction, which is the only route into the camera (`sky.md` §4, §7).

pub mod berry;
pub mod clouds;
pub mod dop;
pub mod hosek;
pub mod rayleigh;

use crate::error::{check_range, Error, Result};
pub use crate::sun::SunPosition;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Which polarization model to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PolarizationModel {
    /// Berry AOP + Wang/PSNS DOP (default).
    #[default]
    Wang,
    /// Single-scattering Rayleigh baseline.
    Rayleigh,
}

/// Normalisation of the PSNS eq. (5) DOP before the clamp to [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DopNorm {
    /// No factor, clamp to [0, 1] (project default, `sky.md` §5).
    #[default]
    Clamp,
    /// Wilkie et al.'s 2/π factor, then clamp.
    Wilkie,
}

/// Sky parameters other than the sun position.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SkyParams {
    /// `wang` (default) or `rayleigh`.
    pub model: PolarizationModel,
    /// Atmospheric turbidity T, 1..10 (default 4).
    pub turbidity: f64,
    /// Wavelength in nm, 320..720 (default 450).
    pub wavelength_nm: f64,
    /// Ground albedo ρ, 0..1 (default 0.1).
    pub albedo: f64,
    /// Babinet point distance above the sun, degrees, 0..60 (default 25).
    pub babinet_deg: f64,
    /// Brewster point distance below the sun, degrees, 0..60 (default 25).
    pub brewster_deg: f64,
    /// Maximum DOP of the Rayleigh model, 0..1 (default 1).
    pub dop_max: f64,
    /// DOP normalisation of the Wang model.
    pub dop_norm: DopNorm,
}

impl Default for SkyParams {
    fn default() -> Self {
        SkyParams {
            model: PolarizationModel::Wang,
            turbidity: 4.0,
            wavelength_nm: 450.0,
            albedo: 0.1,
            babinet_deg: 25.0,
            brewster_deg: 25.0,
            dop_max: 1.0,
            dop_norm: DopNorm::Clamp,
        }
    }
}

impl SkyParams {
    /// Checks every range of `sky.md` §8.
    pub fn validate(&self) -> Result<()> {
        check_range("turbidity", self.turbidity, 1.0, 10.0)?;
        check_range("wavelength", self.wavelength_nm, 320.0, 720.0)?;
        check_range("albedo", self.albedo, 0.0, 1.0)?;
        check_range("babinet", self.babinet_deg, 0.0, 60.0)?;
        check_range("brewster", self.brewster_deg, 0.0, 60.0)?;
        check_range("dop-max", self.dop_max, 0.0, 1.0)?;
        Ok(())
    }
}

/// The sky in one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkySample {
    /// False below (or on) the horizon; then radiance = dop = 0 and `e` = 0.
    pub valid: bool,
    /// Scattering angle γ (angle to the sun) in radians.
    pub gamma_rad: f64,
    /// Sky radiance in W m⁻² sr⁻¹ nm⁻¹ at the model wavelength.
    pub radiance: f64,
    /// Degree of linear polarization in [0, 1].
    pub dop: f64,
    /// Unit E-vector in ENU, perpendicular to the view direction (zero where invalid; arbitrary
    /// but finite where dop = 0).
    pub e: DVec3,
}

impl SkySample {
    /// The value written for ground pixels (`sky.md` §8): everything zero.
    pub const GROUND: SkySample = SkySample {
        valid: false,
        gamma_rad: 0.0,
        radiance: 0.0,
        dop: 0.0,
        e: DVec3::ZERO,
    };
}

/// Unit view vector in ENU for zenith angle θ and compass azimuth A (degrees):
/// v = (sin θ sin A, sin θ cos A, cos θ).
///
/// ```
/// let v = psns::sky::direction(90.0, 0.0);
/// assert!((v.y - 1.0).abs() < 1e-12); // north on the horizon
/// ```
pub fn direction(zenith_deg: f64, azimuth_deg: f64) -> DVec3 {
    let (st, ct) = zenith_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    DVec3::new(st * sa, st * ca, ct)
}

/// Zenith angle and compass azimuth (degrees) of a unit ENU vector; azimuth in [0, 360).
pub fn zenith_azimuth_deg(v: DVec3) -> (f64, f64) {
    let z = v.z.clamp(-1.0, 1.0).acos().to_degrees();
    let a = crate::angle::CompassAzimuth::from_deg(v.x.atan2(v.y).to_degrees()).deg();
    (z, a)
}

/// A prepared sky: sun position and parameters with every per-scene constant cooked.
#[derive(Clone, Debug)]
pub struct Sky {
    sun: SunPosition,
    params: SkyParams,
    // filled in by the implementation: cooked Hosek–Wilkie, Berry and DOP constants
}

impl Sky {
    /// Prepares the sky. Errors for parameters out of range or a sun below the horizon
    /// (θ_s outside 0..90).
    pub fn new(sun: SunPosition, params: &SkyParams) -> Result<Sky> {
        params.validate()?;
        check_range("sun-zenith", sun.zenith_deg, 0.0, 90.0)?;
        let _ = Error::Invalid(String::new());
        Ok(Sky {
            sun,
            params: params.clone(),
        })
    }

    /// The sun position.
    pub fn sun(&self) -> SunPosition {
        self.sun
    }

    /// The parameters.
    pub fn params(&self) -> &SkyParams {
        &self.params
    }

    /// Radiance, DOP and E-vector for a unit view vector `v` in ENU.
    pub fn sample(&self, v: DVec3) -> SkySample {
        let _ = v;
        todo!("sky composition")
    }
}

/// Meridian AOP (`sky.md` §1) of E-vector `e` seen in direction `v`: angle from e_θ (outward
/// along the meridian) toward e_A, wrapped to (−90°, 90°]. At the zenith (undefined) the chart
/// AOP χ is returned, as in the spec's tables.
pub fn aop_meridian_deg(v: DVec3, e: DVec3) -> f64 {
    let _ = (v, e);
    todo!("aop_meridian_deg")
}

/// Chart AOP χ (`sky.md` §1): angle of `e` from north toward east in the stereographic chart,
/// = AOP_m + A, wrapped to (−90°, 90°].
pub fn aop_chart_deg(v: DVec3, e: DVec3) -> f64 {
    let _ = (v, e);
    todo!("aop_chart_deg")
}
