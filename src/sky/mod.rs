//! The clear sky: radiance, degree and angle of polarization in any direction above the horizon.
//!
//! * radiance: Hosek–Wilkie spectral model v1.4a ([`hosek`]), W m⁻² sr⁻¹ nm⁻¹,
//!   or a CIE standard general sky scaled to its zenith ([`cie`]);
//! * E-vector (AOP): Berry, Dennis & Lee's four-neutral-point field ([`berry`]), with fixed
//!   distances or Pan et al.'s law ([`pan`]), four independent neutral points ([`quartic`]), or
//!   the single-scattering Rayleigh field ([`rayleigh`]);
//! * DOP: PSNS eq. (5) after Wang et al. 2016 ([`dop`]), Rayleigh, depolarized Rayleigh
//!   ([`depolarized`]), Berry's |w|, or the QuEEN map |w|/(2 − |w|) ([`quartic`]).
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
pub mod cie;
pub mod clouds;
pub mod depolarized;
pub mod dop;
pub mod hosek;
pub mod pan;
pub mod quartic;
pub mod rayleigh;
pub mod stability;
pub mod surroundings;
pub mod values;

use crate::error::{check_range, Result};
use crate::sun::SunPosition;
use crate::vmath;
use glam::DVec3;
use serde::{Deserialize, Serialize};
pub use surroundings::Surroundings;
pub use values::SkyValues;

/// Which polarization model to use (`docs/sky.md` gives each one's formulas, source and range).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PolarizationModel {
    /// Berry AOP + Wang/PSNS DOP (default).
    #[default]
    Wang,
    /// Single-scattering Rayleigh baseline.
    Rayleigh,
    /// Rayleigh with anisotropic molecules (Wu et al. 2014): DOP sin²γ/(1 + cos²γ + a).
    DepolarizedRayleigh,
    /// Berry, Dennis & Lee 2004: the Berry field with DOP = DOP_max |w|.
    Berry,
    /// Pan et al. 2023: the Berry field with the neutral points at Pan's elevation law, DOP =
    /// DOP_max |w|.
    Pan,
    /// QuEEN (Moutenet et al. 2024): Pan's neutral points, DOP = DOP_max |w|/(2 − |w|).
    Queen,
    /// Four independent neutral points on the solar meridian (the quartic field with explicit
    /// roots), DOP = DOP_max m/(2 − m).
    Asymmetric,
}

crate::names::name_table!(PolarizationModel {
    Wang => "wang",
    Rayleigh => "rayleigh",
    DepolarizedRayleigh => "depolarized-rayleigh",
    Berry => "berry",
    Pan => "pan",
    Queen => "queen",
    Asymmetric => "asymmetric",
});

impl PolarizationModel {
    /// True for the models built on Berry's quartic field (their neutral points can be placed).
    pub fn is_quartic(self) -> bool {
        !matches!(
            self,
            PolarizationModel::Rayleigh | PolarizationModel::DepolarizedRayleigh
        )
    }

    /// The neutral-point law a model uses when the scene sets none: Pan's for `pan`, `queen`
    /// and `asymmetric`, the fixed distances otherwise.
    pub fn default_law(self) -> NeutralLaw {
        match self {
            PolarizationModel::Pan | PolarizationModel::Queen | PolarizationModel::Asymmetric => {
                NeutralLaw::Pan
            }
            PolarizationModel::Wang
            | PolarizationModel::Rayleigh
            | PolarizationModel::DepolarizedRayleigh
            | PolarizationModel::Berry => NeutralLaw::Fixed,
        }
    }
}

impl std::fmt::Display for PolarizationModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PolarizationModel {
    type Err = crate::Error;
    fn from_str(s: &str) -> Result<Self> {
        PolarizationModel::from_name(s).ok_or_else(|| crate::Error::OutOfRange {
            name: "model".into(),
            value: s.into(),
            allowed: PolarizationModel::names(),
        })
    }
}

/// Where the Babinet and Brewster points of a quartic model lie.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NeutralLaw {
    /// At the fixed distances `babinet_deg` and `brewster_deg` from the sun.
    Fixed,
    /// At Pan et al.'s distances for the sun's elevation ([`pan`]), moving with the sun.
    Pan,
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

crate::names::name_table!(DopNorm {
    Clamp => "clamp",
    Wilkie => "wilkie",
});

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

crate::names::name_table!(DopModel {
    WangBounded => "wang-bounded",
    WangPaper => "wang-paper",
});

impl std::fmt::Display for DopModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for DopModel {
    type Err = crate::Error;
    fn from_str(s: &str) -> Result<Self> {
        DopModel::from_name(s).ok_or_else(|| crate::Error::OutOfRange {
            name: "dop-model".into(),
            value: s.into(),
            allowed: DopModel::names(),
        })
    }
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
    /// Maximum DOP of the Rayleigh, depolarized-Rayleigh, Berry, Pan, QuEEN and asymmetric
    /// models, 0..1 (default 1, as in their papers).
    pub dop_max: f64,
    /// Molecular depolarization ratio D of the depolarized Rayleigh model, 0..0.5 (default
    /// 0.0279, Bodhaine et al.'s dry air).
    pub depolarization_ratio: f64,
    /// Neutral-point law of the quartic models: `None` = the model's own
    /// ([`PolarizationModel::default_law`]); `pan` and `queen` accept only Pan's.
    pub neutral_law: Option<NeutralLaw>,
    /// Asymmetric model: distance of the Arago point above the anti-sun, degrees 0..90
    /// (`None` = the Brewster distance).
    pub arago_deg: Option<f64>,
    /// Asymmetric model: distance of the fourth point below the anti-sun, degrees 0..90
    /// (`None` = the Brewster distance).
    pub fourth_deg: Option<f64>,
    /// Sky radiance: Hosek–Wilkie (default) or a CIE standard sky (`cie:N`).
    pub radiance: cie::Radiance,
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
            depolarization_ratio: depolarized::DEFAULT_DEPOLARIZATION_RATIO,
            neutral_law: None,
            arago_deg: None,
            fourth_deg: None,
            radiance: cie::Radiance::Hosek,
            dop_norm: DopNorm::Clamp,
            dop_model: DopModel::WangBounded,
            ground_radiance: None,
        }
    }
}

impl SkyParams {
    /// The neutral-point law in force: the scene's, or the model's own.
    pub fn law(&self) -> NeutralLaw {
        self.neutral_law.unwrap_or(self.model.default_law())
    }

    /// Fixes the neutral points as every front-end does: `distance` places both, `babinet` and
    /// `brewster` each (after `distance`), and any of them sets the fixed law. A model on Pan's
    /// law moves both points, so fixing one alone is refused. `key` spells an option's name the
    /// front-end's way in that message (`--babinet`, or `babinet` in a dataset description).
    ///
    /// ```
    /// use psns::sky::{NeutralLaw, PolarizationModel, SkyParams};
    /// let mut k = SkyParams { model: PolarizationModel::Pan, ..Default::default() };
    /// let e = k.fix_neutral_points(None, Some(20.0), None, |o| o.to_string()).unwrap_err();
    /// assert!(e.to_string().contains("give both babinet and brewster, or neutral_distance"));
    /// k.fix_neutral_points(Some(30.0), None, None, |o| o.to_string()).unwrap();
    /// assert_eq!((k.law(), k.babinet_deg, k.brewster_deg), (NeutralLaw::Fixed, 30.0, 30.0));
    /// ```
    pub fn fix_neutral_points(
        &mut self,
        distance: Option<f64>,
        babinet: Option<f64>,
        brewster: Option<f64>,
        key: impl Fn(&str) -> String,
    ) -> Result<()> {
        if distance.is_none() && babinet.is_none() && brewster.is_none() {
            return Ok(());
        }
        if babinet.is_some() != brewster.is_some() && self.law() == NeutralLaw::Pan {
            return Err(crate::Error::Invalid(format!(
                "{} {} places both neutral points by Pan's law: to fix them give both {} and \
                 {}, or {}",
                key("model"),
                self.model,
                key("babinet"),
                key("brewster"),
                key("neutral_distance")
            )));
        }
        self.neutral_law = Some(NeutralLaw::Fixed);
        if let Some(d) = distance {
            self.babinet_deg = d;
            self.brewster_deg = d;
        }
        self.babinet_deg = babinet.unwrap_or(self.babinet_deg);
        self.brewster_deg = brewster.unwrap_or(self.brewster_deg);
        Ok(())
    }

    /// (Babinet, Brewster) distances from the sun, degrees, for a sun at zenith angle
    /// `sun_zenith_deg`: the fixed ones or Pan's law ([`Self::law`]).
    pub fn neutral_distances(&self, sun_zenith_deg: f64) -> (f64, f64) {
        match self.law() {
            NeutralLaw::Fixed => (self.babinet_deg, self.brewster_deg),
            NeutralLaw::Pan => pan::distances(sun_zenith_deg),
        }
    }

    /// Checks every range of `sky.md` §8 (turbidity from 1.7 for the `wang-bounded` DOP).
    pub fn validate(&self) -> Result<()> {
        match self.model {
            PolarizationModel::Wang => dop::check_turbidity(self.turbidity, self.dop_model)?,
            PolarizationModel::Rayleigh
            | PolarizationModel::DepolarizedRayleigh
            | PolarizationModel::Berry
            | PolarizationModel::Pan
            | PolarizationModel::Queen
            | PolarizationModel::Asymmetric => check_range("turbidity", self.turbidity, 1.0, 10.0)?,
        };
        check_range("wavelength", self.wavelength_nm, 320.0, 720.0)?;
        check_range("albedo", self.albedo, 0.0, 1.0)?;
        check_range("babinet", self.babinet_deg, 0.0, 60.0)?;
        check_range("brewster", self.brewster_deg, 0.0, 60.0)?;
        check_range("dop-max", self.dop_max, 0.0, 1.0)?;
        check_range(
            "depolarization-ratio",
            self.depolarization_ratio,
            0.0,
            depolarized::MAX_DEPOLARIZATION_RATIO,
        )?;
        if let Some(a) = self.arago_deg {
            check_range("arago", a, 0.0, 90.0)?;
        }
        if let Some(f) = self.fourth_deg {
            check_range("fourth", f, 0.0, 90.0)?;
        }
        if matches!(
            self.model,
            PolarizationModel::Pan | PolarizationModel::Queen
        ) && self.neutral_law == Some(NeutralLaw::Fixed)
        {
            return Err(crate::Error::Invalid(format!(
                "--model {} places its neutral points by Pan's law; fixed distances \
                 (--babinet, --brewster, --neutral-distance) go with --model berry or asymmetric",
                self.model
            )));
        }
        if (self.arago_deg.is_some() || self.fourth_deg.is_some())
            && self.model != PolarizationModel::Asymmetric
        {
            return Err(crate::Error::Invalid(format!(
                "--arago and --fourth place the anti-solar neutral points of --model asymmetric, \
                 not of --model {}",
                self.model
            )));
        }
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

use crate::angle::direction;

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
    /// Anisotropy term a of the depolarized Rayleigh model (0 for the others).
    depol_a: f64,
    /// The asymmetric model's field (`None` for the others).
    quartic: Option<quartic::QuarticField>,
    /// (Babinet, Brewster) distances in force, degrees.
    neutral: (f64, f64),
}

impl PolarizationField {
    /// Cooks the field. Errors for parameters out of range or θ_s outside 0..90.
    pub fn new(sun: SunPosition, params: &SkyParams) -> Result<Self> {
        params.validate()?;
        sun.check_up()?;
        check_range("sun-azimuth", sun.azimuth_deg, -720.0, 720.0)?;
        let (babinet, brewster) = params.neutral_distances(sun.zenith_deg);
        let quartic = (params.model == PolarizationModel::Asymmetric).then(|| {
            quartic::QuarticField::new(
                sun.azimuth_deg,
                quartic::meridian_angles(
                    sun.zenith_deg,
                    babinet,
                    brewster,
                    params.arago_deg.unwrap_or(brewster),
                    params.fourth_deg.unwrap_or(brewster),
                ),
            )
        });
        Ok(PolarizationField {
            model: params.model,
            sun_vec: sun.vector(),
            berry: berry::BerryField::new(sun.zenith_deg, sun.azimuth_deg, babinet, brewster),
            wang: dop::WangDop::with_model(
                sun.zenith_deg,
                params.turbidity,
                params.wavelength_nm,
                params.albedo,
                params.dop_norm,
                match params.model {
                    // the other models never evaluate eq. (5): cook the paper's form, which
                    // accepts every turbidity the radiance does
                    PolarizationModel::Wang => params.dop_model,
                    _ => DopModel::WangPaper,
                },
            )?,
            dop_max: params.dop_max,
            depol_a: match params.model {
                PolarizationModel::DepolarizedRayleigh => {
                    depolarized::anisotropy(params.depolarization_ratio)
                }
                _ => 0.0,
            },
            quartic,
            neutral: (babinet, brewster),
        })
    }

    /// The model.
    pub fn model(&self) -> PolarizationModel {
        self.model
    }

    /// (Babinet, Brewster) distances from the sun in force, degrees (the fixed ones or Pan's
    /// law at this sun; unused by the Rayleigh models).
    pub fn neutral_distances(&self) -> (f64, f64) {
        self.neutral
    }

    /// The asymmetric model's field.
    pub fn quartic(&self) -> Option<&quartic::QuarticField> {
        self.quartic.as_ref()
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
            PolarizationModel::Rayleigh | PolarizationModel::DepolarizedRayleigh => {
                self.rayleigh(v, cross, sin_g2, cos_g)
            }
            PolarizationModel::Berry
            | PolarizationModel::Pan
            | PolarizationModel::Queen
            | PolarizationModel::Asymmetric => self.quartic_dop_e(v),
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

    /// DOP and E-vector of the Berry, Pan, QuEEN and asymmetric models (not Wang's, whose DOP
    /// needs θ and γ).
    #[inline(always)]
    fn quartic_dop_e(&self, v: DVec3) -> (f64, DVec3) {
        match self.model {
            PolarizationModel::Berry | PolarizationModel::Pan => {
                let b = self.berry.eval(v);
                (dop::clamp01(self.dop_max * b.abs_w), b.e)
            }
            PolarizationModel::Queen => {
                let b = self.berry.eval(v);
                let m = b.abs_w.min(1.0);
                (quartic::intensity_to_dop(self.dop_max, m), b.e)
            }
            PolarizationModel::Asymmetric => {
                let q = self
                    .quartic
                    .as_ref()
                    .expect("the asymmetric model cooks its field")
                    .eval(v);
                (quartic::intensity_to_dop(self.dop_max, q.m), q.e)
            }
            _ => unreachable!("quartic_dop_e is for the quartic models without eq. (5)"),
        }
    }

    /// The Rayleigh (a = 0) and depolarized Rayleigh models' DOP and E-vector ∝ s × v; at the
    /// sun and the anti-sun (s ∥ v) DOP 0 and the chart's north. Branch-free but for selects.
    #[inline(always)]
    fn rayleigh(&self, v: DVec3, cross: DVec3, sin_g2: f64, cos_g: f64) -> (f64, DVec3) {
        let c2 = cos_g * cos_g;
        let d = self.dop_max * sin_g2 / (sin_g2 + 2.0 * c2 + self.depol_a);
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
    /// The CIE standard sky when the radiance is `cie:N`.
    cie: Option<cie::CieSky>,
    /// Hosek–Wilkie zenith radiance, the CIE sky's scale.
    cie_zenith: f64,
    /// The world around the camera, lit by this sky.
    surroundings: Option<std::sync::Arc<Surroundings>>,
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
        let (cie, cie_zenith) = match params.radiance {
            cie::Radiance::Hosek => (None, 0.0),
            cie::Radiance::Cie(n) => {
                let ts = sun.zenith_deg.to_radians();
                let zenith = hw.radiance_cos(1.0, ts, ts.cos()).max(0.0);
                (Some(cie::CieSky::new(n, ts)?), zenith)
            }
        };
        Ok(Sky {
            sun,
            params: params.clone(),
            pol,
            hw,
            cie,
            cie_zenith,
            surroundings: None,
        })
    }

    /// This sky with `world` around the camera (lit by it: [`Surroundings`]); an empty world
    /// leaves the plain sky.
    pub fn with_world(mut self, world: crate::world::World) -> Sky {
        self.surroundings = if world.is_empty() {
            None
        } else {
            Some(std::sync::Arc::new(Surroundings::new(&self, world)))
        };
        self
    }

    /// This sky with the clouds of `world` moved to scene time `t_s` (the lighting kept: it is
    /// the clear sky's).
    pub fn with_clouds_at(mut self, world: &crate::world::World, t_s: f64) -> Sky {
        if let Some(s) = &self.surroundings {
            self.surroundings = Some(std::sync::Arc::new(s.with_world(world.at(t_s))));
        }
        self
    }

    /// This sky without the clouds in front of it ([`Surroundings::without_direct_clouds`]);
    /// None when it has no clouds.
    pub fn without_direct_clouds(&self) -> Option<Sky> {
        let s = self.surroundings.as_ref()?;
        if s.world().clouds().is_empty() {
            return None;
        }
        let mut sky = self.clone();
        sky.surroundings = Some(std::sync::Arc::new(s.without_direct_clouds()));
        Some(sky)
    }

    /// The world around the camera, when there is one.
    pub fn surroundings(&self) -> Option<&Surroundings> {
        self.surroundings.as_deref()
    }

    /// Whether the sun's disc is in view of the sky: not under an overcast CIE sky (types 1–5).
    pub fn sun_visible(&self) -> bool {
        !self.cie.is_some_and(|c| c.overcast())
    }

    /// Radiance at cos θ, γ and cos γ of a direction above the horizon: Hosek–Wilkie floored
    /// at 0, or the CIE sky scaled to Hosek–Wilkie's zenith.
    #[inline(always)]
    fn radiance(&self, cos_t: f64, gamma: f64, cos_g: f64) -> f64 {
        match &self.cie {
            // HW v1.4a dips slightly below zero within ~0.005° of the horizon for low suns (e.g.
            // θ_s = 84°, A − A_s = 100°, 450 nm, T = 4; docs/sky.md); radiance cannot be negative.
            None => self.hw.radiance_cos(cos_t, gamma, cos_g).max(0.0),
            Some(c) => self.cie_zenith * c.relative(cos_t, gamma),
        }
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
        s.radiance = self.radiance(cos_t, s.gamma_rad, cos_g);
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
            PolarizationModel::Rayleigh | PolarizationModel::DepolarizedRayleigh => {
                for j in 0..n {
                    let vj = DVec3::new(v[0][j], v[1][j], v[2][j]);
                    let x = DVec3::new(cx[j], cy[j], cz[j]);
                    let (d, ej) = p.rayleigh(vj, x, sg2[j], cg[j]);
                    dop[j] = d;
                    (e[0][j], e[1][j], e[2][j]) = (ej.x, ej.y, ej.z);
                }
            }
            PolarizationModel::Berry
            | PolarizationModel::Pan
            | PolarizationModel::Queen
            | PolarizationModel::Asymmetric => {
                for j in 0..n {
                    let (d, ej) = p.quartic_dop_e(DVec3::new(v[0][j], v[1][j], v[2][j]));
                    dop[j] = d;
                    (e[0][j], e[1][j], e[2][j]) = (ej.x, ej.y, ej.z);
                }
            }
        }
        match &self.cie {
            None => {
                self.hw.radiance_lanes(n, ct, gamma, cg, radiance, rest);
                for r in &mut radiance[..n] {
                    *r = r.max(0.0);
                }
            }
            Some(c) => {
                for j in 0..n {
                    radiance[j] = self.cie_zenith * c.relative(ct[j], gamma[j]);
                }
            }
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
