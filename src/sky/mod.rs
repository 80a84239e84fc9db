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
//!
//! [`Sky::new`] cooks every per-scene constant (the two Hosek–Wilkie channels, Berry's t±,
//! Preetham's zenith values and Perez coefficients, S_sun, S_90 and the CIE normalisation);
//! [`Sky::sample`] is the per-pixel path: no allocation, three inverse trigonometric/square-root
//! calls shared between radiance and polarization, and ground (v.z ≤ 0) short-circuited to
//! [`SkySample::GROUND`] — Hosek–Wilkie and Preetham are never evaluated below the horizon
//! (`sky.md` §8). [`PolarizationField`] is the same without radiance. [`Sky::sample_lanes`]
//! computes the same bits for a chunk of [`LANES`] directions at once, in structure-of-arrays
//! form (`render::pixel_sky_cols`, the row evaluator); both paths take their elementary
//! functions from [`crate::vmath`] and share the per-direction arithmetic.
//!
//! References: Hošek & Wilkie, ACM TOG 31(4):95 (2012) and IEEE CG&A 33(3):44 (2013);
//! Berry, Dennis & Lee, New J. Phys. 6:162 (2004); Wang, Gao, Fan & Roberts, J. Opt.
//! 18:065601 (2016); Preetham, Shirley & Smits, SIGGRAPH 1999; Liang & Bai, PSNS,
//! arXiv:2007.13081 (2020).

pub mod berry;
pub mod clouds;
pub mod dop;
pub mod hosek;
pub mod rayleigh;
pub mod stability;
pub mod values;

use crate::error::{check_range, Result};
pub use crate::sun::SunPosition;
use crate::vmath;
use glam::DVec3;
use serde::{Deserialize, Serialize};
pub use values::SkyValues;

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

/// Form of the PSNS eq. (5) DOP (`sky.md` §5, `docs/sky.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DopModel {
    /// Eq. (5) with a sign-aware, bounded brightness weight S (bright reference the brightest
    /// Preetham sky, contrast floored at [`dop::R_MIN`], S ≥ 0) and a soft ceiling of 0.94;
    /// identical to the paper at the default scene. Turbidity 1.7..10. Default.
    #[default]
    WangBounded,
    /// Eq. (5) exactly as published (clamped to [0, 1]); pins to 0 or 1 in parts of the
    /// domain (low sun, T = 10 at θ_s = 70°, T < 2.5 with a high sun, 1.2 < T < 1.645).
    WangPaper,
}

/// Sky parameters other than the sun position.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SkyParams {
    /// `wang` (default) or `rayleigh`.
    pub model: PolarizationModel,
    /// Atmospheric turbidity T, 1.7..10 for the default `wang-bounded` DOP, 1..10 for
    /// `wang-paper` and the Rayleigh model (default 4).
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
    /// Form of the Wang model's DOP: `wang-bounded` (default) or `wang-paper`.
    pub dop_model: DopModel,
    /// Uniform unpolarized radiance of ground pixels (rays at or below the horizon), W m⁻² sr⁻¹
    /// nm⁻¹; `None` = 0 (default). Ground pixels stay marked invalid either way.
    pub ground_radiance: Option<f64>,
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
            dop_model: DopModel::WangBounded,
            ground_radiance: None,
        }
    }
}

impl SkyParams {
    /// Checks every range of `sky.md` §8 (turbidity from 1.7 for the `wang-bounded` DOP).
    pub fn validate(&self) -> Result<()> {
        match self.model {
            PolarizationModel::Wang => dop::check_turbidity(self.turbidity, self.dop_model)?,
            PolarizationModel::Rayleigh => check_range("turbidity", self.turbidity, 1.0, 10.0)?,
        };
        check_range("wavelength", self.wavelength_nm, 320.0, 720.0)?;
        check_range("albedo", self.albedo, 0.0, 1.0)?;
        check_range("babinet", self.babinet_deg, 0.0, 60.0)?;
        check_range("brewster", self.brewster_deg, 0.0, 60.0)?;
        check_range("dop-max", self.dop_max, 0.0, 1.0)?;
        if let Some(g) = self.ground_radiance {
            check_range("ground-radiance", g, 0.0, 100.0)?;
        }
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

pub use crate::angle::{direction, zenith_azimuth_deg};

/// The polarization half of the sky (`sky.md` §4–§6), cooked for one scene: DOP and E-vector
/// in any direction above the horizon, no radiance. [`Sky`] adds Hosek–Wilkie radiance to it.
#[derive(Clone, Debug)]
pub struct PolarizationField {
    model: PolarizationModel,
    /// Unit sun vector in ENU.
    sun_vec: DVec3,
    berry: berry::BerryField,
    wang: dop::WangDop,
    dop_max: f64,
}

impl PolarizationField {
    /// Cooks the field. Errors for parameters out of range or θ_s outside 0..90.
    pub fn new(sun: SunPosition, params: &SkyParams) -> Result<Self> {
        params.validate()?;
        sun.check_up()?;
        check_range("sun-azimuth", sun.azimuth_deg, -720.0, 720.0)?;
        Ok(PolarizationField {
            model: params.model,
            sun_vec: sun.vector(),
            berry: berry::BerryField::new(
                sun.zenith_deg,
                sun.azimuth_deg,
                params.babinet_deg,
                params.brewster_deg,
            ),
            wang: dop::WangDop::with_model(
                sun.zenith_deg,
                params.turbidity,
                params.wavelength_nm,
                params.albedo,
                params.dop_norm,
                match params.model {
                    // the Rayleigh model never evaluates eq. (5): cook the paper's form, which
                    // accepts every turbidity the radiance does
                    PolarizationModel::Wang => params.dop_model,
                    PolarizationModel::Rayleigh => DopModel::WangPaper,
                },
            )?,
            dop_max: params.dop_max,
        })
    }

    /// The cooked Berry field.
    pub fn berry(&self) -> &berry::BerryField {
        &self.berry
    }

    /// The cooked PSNS eq. (5) DOP.
    pub fn wang(&self) -> &dop::WangDop {
        &self.wang
    }

    /// DOP, γ and E-vector for a unit ENU view vector (radiance left 0); `SkySample::GROUND`
    /// for v.z ≤ 0 (or NaN).
    pub fn sample(&self, v: DVec3) -> SkySample {
        if v.z.is_nan() || v.z <= 0.0 {
            return SkySample::GROUND;
        }
        self.eval(v).2
    }

    /// cos θ, cos γ and the sample; requires v.z > 0.
    #[inline(always)]
    fn eval(&self, v: DVec3) -> (f64, f64, SkySample) {
        let (cos_t, cross, sin_g2, cos_g) = self.geometry(v);
        let theta = vmath::acos(cos_t);
        let gamma = vmath::atan2(sin_g2.sqrt(), cos_g);
        let (dop, e) = match self.model {
            PolarizationModel::Wang => {
                let b = self.berry.eval(v);
                let d = self.wang.dop(b.abs_w, theta, cos_t, gamma, cos_g);
                (d, b.e)
            }
            PolarizationModel::Rayleigh => self.rayleigh(v, cross, sin_g2, cos_g),
        };
        (
            cos_t,
            cos_g,
            SkySample {
                valid: true,
                gamma_rad: gamma,
                radiance: 0.0,
                dop,
                e,
            },
        )
    }

    /// cos θ (at most 1), s × v, |s × v|² = sin²γ and cos γ of a unit view vector `v`.
    #[inline(always)]
    fn geometry(&self, v: DVec3) -> (f64, DVec3, f64, f64) {
        let cross = self.sun_vec.cross(v);
        (
            v.z.min(1.0),
            cross,
            cross.length_squared(),
            self.sun_vec.dot(v),
        )
    }

    /// The Rayleigh model's DOP and E-vector ∝ s × v; at the sun and the anti-sun (s ∥ v) DOP 0
    /// and the chart's north. Branch-free but for selects.
    #[inline(always)]
    fn rayleigh(&self, v: DVec3, cross: DVec3, sin_g2: f64, cos_g: f64) -> (f64, DVec3) {
        let c2 = cos_g * cos_g;
        let d = self.dop_max * sin_g2 / (sin_g2 + 2.0 * c2);
        let e = cross / sin_g2.sqrt();
        let north = berry::chart_basis(v).0;
        if sin_g2 > 0.0 {
            (dop::clamp01(d), e)
        } else {
            (0.0, north)
        }
    }
}

/// Number of lanes of the chunk evaluators ([`Sky::sample_lanes`], `render::pixel_sky_row`).
pub const LANES: usize = 64;

/// One f64 per lane.
pub type Lane = [f64; LANES];

/// Scratch lanes of [`Sky::sample_lanes`]: 9 of its own, 7 for the DOP.
const WORK: usize = 16;

/// Up to [`LANES`] directions and their sky, structure of arrays: the chunk that
/// [`Sky::sample_lanes`] evaluates. One `SkyLanes` serves chunk after chunk (its arrays are
/// zeroed once, when made).
#[derive(Clone, Debug)]
pub struct SkyLanes {
    /// Lanes in use, at most [`LANES`].
    pub n: usize,
    /// Unit ENU view vectors (x, y, z), above the horizon (v.z > 0).
    pub v: [Lane; 3],
    /// Radiance, as [`SkySample::radiance`].
    pub radiance: Lane,
    /// DOP, as [`SkySample::dop`].
    pub dop: Lane,
    /// E-vector (x, y, z), as [`SkySample::e`].
    pub e: [Lane; 3],
    /// Intermediate values.
    work: [Lane; WORK],
}

impl Default for SkyLanes {
    fn default() -> Self {
        SkyLanes {
            n: 0,
            v: [[0.0; LANES]; 3],
            radiance: [0.0; LANES],
            dop: [0.0; LANES],
            e: [[0.0; LANES]; 3],
            work: [[0.0; LANES]; WORK],
        }
    }
}

/// A prepared sky: sun position and parameters with every per-scene constant cooked.
#[derive(Clone, Debug)]
pub struct Sky {
    sun: SunPosition,
    params: SkyParams,
    pol: PolarizationField,
    hw: hosek::HosekWilkie,
}

impl Sky {
    /// Prepares the sky. Errors for parameters out of range or a sun below the horizon
    /// (θ_s outside 0..90).
    pub fn new(sun: SunPosition, params: &SkyParams) -> Result<Sky> {
        let pol = PolarizationField::new(sun, params)?;
        let hw = hosek::HosekWilkie::new(
            params.turbidity,
            params.albedo,
            (90.0 - sun.zenith_deg).to_radians(),
            params.wavelength_nm,
        )?;
        Ok(Sky {
            sun,
            params: params.clone(),
            pol,
            hw,
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

    /// The polarization half (DOP and E-vector without radiance).
    pub fn polarization(&self) -> &PolarizationField {
        &self.pol
    }

    /// The cooked Hosek–Wilkie model (e.g. for the solar disc, [`hosek::HosekWilkie::sun_radiance`]).
    pub fn hosek(&self) -> &hosek::HosekWilkie {
        &self.hw
    }

    /// Radiance, DOP and E-vector for a unit view vector `v` in ENU. Below or on the horizon
    /// (v.z ≤ 0) returns [`SkySample::GROUND`]. The sun disc is not included (see
    /// [`Sky::hosek`]). The Hosek–Wilkie radiance is floored at 0 (it turns slightly negative
    /// in the last few thousandths of a degree above the horizon for some channels).
    #[inline]
    pub fn sample(&self, v: DVec3) -> SkySample {
        if v.z.is_nan() || v.z <= 0.0 {
            return SkySample::GROUND;
        }
        let (cos_t, cos_g, mut s) = self.pol.eval(v);
        // HW v1.4a dips slightly below zero within ~0.005° of the horizon for low suns (e.g.
        // θ_s = 84°, A − A_s = 100°, 450 nm, T = 4; docs/sky.md); radiance cannot be negative.
        s.radiance = self.hw.radiance_cos(cos_t, s.gamma_rad, cos_g).max(0.0);
        s
    }

    /// [`Sky::sample`]'s radiance, DOP and E-vector for lanes 0..`l.n` of `l`, the same bits;
    /// every `l.v` above the horizon. Geometry and each transcendental run as one loop over the
    /// lanes, the model is chosen outside the loops, so with vectorised [`vmath`] the loops
    /// vectorise (the caller builds this for the CPU's instruction set, `render::pixel_sky_row`).
    #[inline(always)]
    pub fn sample_lanes(&self, l: &mut SkyLanes) {
        let SkyLanes {
            n,
            v,
            radiance,
            dop,
            e,
            work,
        } = l;
        let n = *n;
        assert!(n <= LANES);
        let [ct, sg2, cg, gamma, theta, abs_w, cx, cy, cz, rest @ ..] = work;
        let p = &self.pol;
        for j in 0..n {
            let (c, x, s, g) = p.geometry(DVec3::new(v[0][j], v[1][j], v[2][j]));
            (ct[j], sg2[j], cg[j]) = (c, s, g);
            (cx[j], cy[j], cz[j]) = (x.x, x.y, x.z);
        }
        for j in 0..n {
            gamma[j] = vmath::atan2(sg2[j].sqrt(), cg[j]);
        }
        match p.model {
            PolarizationModel::Wang => {
                for j in 0..n {
                    theta[j] = vmath::acos(ct[j]);
                }
                p.berry.eval_lanes(n, v, abs_w, e, rest);
                p.wang.dop_lanes(n, abs_w, theta, ct, gamma, cg, dop, rest);
            }
            PolarizationModel::Rayleigh => {
                for j in 0..n {
                    let vj = DVec3::new(v[0][j], v[1][j], v[2][j]);
                    let x = DVec3::new(cx[j], cy[j], cz[j]);
                    let (d, ej) = p.rayleigh(vj, x, sg2[j], cg[j]);
                    dop[j] = d;
                    (e[0][j], e[1][j], e[2][j]) = (ej.x, ej.y, ej.z);
                }
            }
        }
        self.hw.radiance_lanes(n, ct, gamma, cg, radiance, rest);
        for r in &mut radiance[..n] {
            *r = r.max(0.0);
        }
    }
}

/// Meridian AOP (`sky.md` §1) of E-vector `e` seen in direction `v`: angle from e_θ (outward
/// along the meridian) toward e_A, wrapped to (−90°, 90°]. At the zenith (undefined) the chart
/// AOP χ is returned, as in the spec's tables.
pub fn aop_meridian_deg(v: DVec3, e: DVec3) -> f64 {
    let rh = v.x.hypot(v.y);
    if rh <= 1e-15 * v.z.abs() {
        return aop_chart_deg(v, e);
    }
    let (sa, ca) = (v.x / rh, v.y / rh);
    let e_theta = DVec3::new(v.z * sa, v.z * ca, -rh);
    let e_a = DVec3::new(ca, -sa, 0.0);
    crate::angle::wrap_pm90(e.dot(e_a).atan2(e.dot(e_theta)).to_degrees())
}

/// Chart AOP χ (`sky.md` §1): angle of `e` from north toward east in the stereographic chart,
/// = AOP_m + A, wrapped to (−90°, 90°].
pub fn aop_chart_deg(v: DVec3, e: DVec3) -> f64 {
    let (n, east) = berry::chart_basis(v);
    crate::angle::wrap_pm90(e.dot(east).atan2(e.dot(n)).to_degrees())
}
