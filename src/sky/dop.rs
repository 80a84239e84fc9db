//! Degree of polarization of the clear sky: PSNS eq. (5) after Wang et al. 2016.
//!
//! Physics (Liang & Bai, PSNS, arXiv:2007.13081, eq. (5); Wang, Gao, Fan & Roberts, J. Opt.
//! 18:065601, 2016; `sky.md` §5):
//!
//! DOP = clamp₍₀,₁₎( |w| · [θ·E + (π/2 − θ)·S] · M_DOP(τ) ),
//!
//! with θ the view zenith angle in radians, |w| the Berry field modulus ([`super::berry`]),
//! E = cos(θ)^ρ (ρ the ground albedo), M_DOP(τ) = exp(−τ/4 + 0.12) (τ the turbidity T) and the
//! sky-brightness weight
//!
//! S = (1/S_D − 1/S_sun) · S_90 S_sun / (S_sun − S_90),
//!
//! 0 where the sky is as bright as at the sun, 1 where it is as bright as 90° from the sun on
//! the solar vertical, above 1 in darker regions. S_D(θ, γ, λ) is the spectral radiance of
//! Preetham, Shirley & Smits (SIGGRAPH 1999): the Perez et al. (1993) distribution
//! F(θ, γ) = (1 + A e^{B/cos θ})(1 + C e^{Dγ} + E cos²γ) (cos θ floored at 0.01) for luminance Y
//! and chromaticity x, y, scaled by their zenith values, turned into a spectrum with the CIE
//! daylight basis S0 + M₁S1 + M₂S2 normalised to luminance (CIE 15; table [`CIE_DAYLIGHT`]).
//! Only ratios of S_D enter S, so the absolute scale of Y cancels.
//!
//! By default no 2/π factor is applied ([`DopNorm::Clamp`]); Wilkie et al.'s 2/π normalisation is
//! [`DopNorm::Wilkie`]. Frame: θ, γ as in `sky.md` §1.
//!
//! Two forms ([`DopModel`], `docs/sky.md` "Where the published DOP fails"):
//!
//! * [`DopModel::WangPaper`]: S as above, the DOP clamped to [0, 1]. S assumes S_D is largest at
//!   the sun, smaller at S_90 and positive; Preetham's sky breaks all three inside the accepted
//!   range (S_sun/S_90 passes through 1 for a low sun, e.g. T = 4 at θ_s ≈ 86.3°; S_D exceeds
//!   S_sun 40° from the sun at T = 10, θ_s = 70°; S_D < 0 near the zenith for 1.203 < T < 1.645,
//!   where the luminance gradation 1 + A_Y e^{B_Y/cos θ} changes sign inside the sky), and the
//!   clamp turns the blow-ups into plateaus of DOP 0 or 1.
//! * [`DopModel::WangBounded`] (default): S = (S_ref/S_D − 1)/(S_ref/S_90 − 1) with S_ref the
//!   brightest S_D of the sky, S_D and S_90 floored at [`S_D_FLOOR`]·S_ref, the contrast
//!   S_ref/S_90 floored at [`R_MIN`], S ≥ 0 saturating above [`S_KNEE`] toward [`S_CEILING`], and
//!   the DOP saturating above [`DOP_KNEE`] toward [`DOP_CEILING`]; turbidity 1.7..10. Every
//!   threshold lies outside the default scene's range, so there the two forms agree bit for bit.

pub use super::DopModel;
use super::DopNorm;
use super::{Lane, LANES};
use crate::error::{check_range, Result};
use crate::vmath;
use std::f64::consts::{FRAC_PI_2, PI};

/// First wavelength of [`CIE_DAYLIGHT`], nm.
pub const CIE_LAMBDA0_NM: f64 = 320.0;
/// Step of [`CIE_DAYLIGHT`], nm.
pub const CIE_STEP_NM: f64 = 10.0;

/// CIE daylight basis and luminosity function, 320–780 nm every 10 nm (CIE 15;
/// `fixtures/sky-cie-daylight.csv`): rows [S0, S1, S2, ȳ (CIE 1931, zero below 380 nm)].
pub const CIE_DAYLIGHT: [[f64; 4]; 47] = [
    [29.6, 22.4, 4.0, 0.0],
    [55.3, 42.0, 8.5, 0.0],
    [57.3, 40.6, 7.8, 0.0],
    [61.8, 41.6, 6.7, 0.0],
    [61.5, 38.0, 5.3, 0.0],
    [68.8, 42.4, 6.1, 0.0],
    [63.4, 38.5, 3.0, 0.000039],
    [65.8, 35.0, 1.2, 0.00012],
    [94.8, 43.4, -1.1, 0.000396],
    [104.8, 46.3, -0.5, 0.00121],
    [105.9, 43.9, -0.7, 0.004],
    [96.8, 37.1, -1.2, 0.0116],
    [113.9, 36.7, -2.6, 0.023],
    [125.6, 35.9, -2.9, 0.038],
    [125.5, 32.6, -2.8, 0.06],
    [121.3, 27.9, -2.6, 0.09098],
    [121.3, 24.3, -2.6, 0.13902],
    [113.5, 20.1, -1.8, 0.20802],
    [113.1, 16.2, -1.5, 0.323],
    [110.8, 13.2, -1.3, 0.503],
    [106.5, 8.6, -1.2, 0.71],
    [108.8, 6.1, -1.0, 0.862],
    [105.3, 4.2, -0.5, 0.954],
    [104.4, 1.9, -0.3, 0.99495],
    [100.0, 0.0, 0.0, 0.995],
    [96.0, -1.6, 0.2, 0.952],
    [95.1, -3.5, 0.5, 0.87],
    [89.1, -3.5, 2.1, 0.757],
    [90.5, -5.8, 3.2, 0.631],
    [90.3, -7.2, 4.1, 0.503],
    [88.4, -8.6, 4.7, 0.381],
    [84.0, -9.5, 5.1, 0.265],
    [85.1, -10.9, 6.7, 0.175],
    [81.9, -10.7, 7.3, 0.107],
    [82.6, -12.0, 8.6, 0.061],
    [84.9, -14.0, 9.8, 0.032],
    [81.3, -13.6, 10.2, 0.017],
    [71.9, -12.0, 8.3, 0.00821],
    [74.3, -13.3, 9.6, 0.004102],
    [76.4, -12.9, 8.5, 0.002091],
    [63.3, -10.6, 7.0, 0.001047],
    [71.7, -11.6, 7.6, 0.00052],
    [77.0, -12.2, 8.0, 0.0002492],
    [65.2, -10.2, 6.7, 0.00012],
    [47.7, -7.8, 5.2, 0.00006],
    [68.6, -11.2, 7.4, 0.00003],
    [65.0, -10.4, 6.8, 0.00001499],
];

/// Perez coefficients (A, B, C, D, E) of Preetham et al. 1999 for luminance Y and chromaticity
/// x, y at turbidity T (`sky.md` §5 table).
pub fn perez_coefficients(t: f64) -> [[f64; 5]; 3] {
    [
        [
            0.1787 * t - 1.4630,
            -0.3554 * t + 0.4275,
            -0.0227 * t + 5.3251,
            0.1206 * t - 2.5771,
            -0.0670 * t + 0.3703,
        ],
        [
            -0.0193 * t - 0.2592,
            -0.0665 * t + 0.0008,
            -0.0004 * t + 0.2125,
            -0.0641 * t - 0.8989,
            -0.0033 * t + 0.0452,
        ],
        [
            -0.0167 * t - 0.2608,
            -0.0950 * t + 0.0092,
            -0.0079 * t + 0.2102,
            -0.0441 * t - 1.6537,
            -0.0109 * t + 0.0529,
        ],
    ]
}

/// Zenith luminance Y_z (kcd m⁻²) and chromaticity x_z, y_z of Preetham et al. 1999, App. A.2,
/// for turbidity T and sun zenith θ_s in radians.
pub fn preetham_zenith(t: f64, sun_zenith_rad: f64) -> [f64; 3] {
    const MX: [[f64; 4]; 3] = [
        [0.00166, -0.00375, 0.00209, 0.0],
        [-0.02903, 0.06377, -0.03202, 0.00394],
        [0.11693, -0.21196, 0.06052, 0.25886],
    ];
    const MY: [[f64; 4]; 3] = [
        [0.00275, -0.00610, 0.00317, 0.0],
        [-0.04214, 0.08970, -0.04153, 0.00516],
        [0.15346, -0.26756, 0.06670, 0.26688],
    ];
    let ts = sun_zenith_rad;
    let u = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * ts);
    let yz = (4.0453 * t - 4.9710) * u.tan() - 0.2155 * t + 2.4192;
    let tv = [t * t, t, 1.0];
    let sv = [ts * ts * ts, ts * ts, ts, 1.0];
    let quad = |m: &[[f64; 4]; 3]| -> f64 {
        (0..3)
            .map(|i| tv[i] * (0..4).map(|j| m[i][j] * sv[j]).sum::<f64>())
            .sum()
    };
    [yz, quad(&MX), quad(&MY)]
}

/// Perez distribution F(θ, γ) = (1 + A e^{B/cos θ})(1 + C e^{Dγ} + E cos²γ), cos θ floored at 0.01.
#[inline(always)]
pub fn perez(c: &[f64; 5], cos_theta: f64, gamma: f64, cos_gamma: f64) -> f64 {
    let ct = cos_theta.max(0.01);
    perez_exp(
        c,
        vmath::exp(c[1] / ct),
        vmath::exp(c[3] * gamma),
        cos_gamma,
    )
}

/// [`perez`] given its two exponentials e^{B/cos θ} (`ea`, cos θ floored) and e^{Dγ} (`eb`).
#[inline(always)]
fn perez_exp(c: &[f64; 5], ea: f64, eb: f64, cos_gamma: f64) -> f64 {
    (1.0 + c[0] * ea) * (1.0 + c[2] * eb + c[4] * cos_gamma * cos_gamma)
}

/// CIE daylight basis at `wavelength_nm` (linear interpolation, 320..780 nm): (S0, S1, S2).
pub fn cie_basis_at(wavelength_nm: f64) -> [f64; 3] {
    let n = CIE_DAYLIGHT.len();
    let x = ((wavelength_nm - CIE_LAMBDA0_NM) / CIE_STEP_NM).clamp(0.0, (n - 1) as f64);
    let i = (x.floor() as usize).min(n - 2);
    let f = x - i as f64;
    let (a, b) = (&CIE_DAYLIGHT[i], &CIE_DAYLIGHT[i + 1]);
    [
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
    ]
}

/// Luminance normalisation sums Σ_{380…780} S_k ȳ Δλ for k = 0, 1, 2 (Δλ = 10 nm).
pub fn cie_luminance_sums() -> [f64; 3] {
    let mut s = [0.0; 3];
    for row in CIE_DAYLIGHT.iter().skip(6) {
        for k in 0..3 {
            s[k] += row[k] * row[3] * CIE_STEP_NM;
        }
    }
    s
}

/// Preetham et al.'s spectral sky S_D(θ, γ, λ) at one wavelength, cooked for one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Preetham {
    /// Perez coefficients for Y, x, y.
    coef: [[f64; 5]; 3],
    /// Q_z / F_Q(0, θ_s) for Q = Y, x, y.
    scale: [f64; 3],
    /// (S0, S1, S2) at the wavelength.
    basis: [f64; 3],
    /// Σ S_k ȳ Δλ.
    sums: [f64; 3],
}

impl Preetham {
    /// Cooks the model for turbidity T, sun zenith θ_s (radians) and wavelength (nm, 320..780).
    pub fn new(turbidity: f64, sun_zenith_rad: f64, wavelength_nm: f64) -> Self {
        let coef = perez_coefficients(turbidity);
        let z = preetham_zenith(turbidity, sun_zenith_rad);
        let cs = sun_zenith_rad.cos();
        let mut scale = [0.0; 3];
        for q in 0..3 {
            scale[q] = z[q] / perez(&coef[q], 1.0, sun_zenith_rad, cs);
        }
        Preetham {
            coef,
            scale,
            basis: cie_basis_at(wavelength_nm),
            sums: cie_luminance_sums(),
        }
    }

    /// Luminance Y and chromaticity x, y at view zenith cos θ and scattering angle γ.
    #[inline(always)]
    pub fn yxy(&self, cos_theta: f64, gamma: f64, cos_gamma: f64) -> [f64; 3] {
        std::array::from_fn(|q| self.scale[q] * perez(&self.coef[q], cos_theta, gamma, cos_gamma))
    }

    /// S_D at view zenith cos θ and scattering angle γ (radians, with its cosine).
    #[inline(always)]
    pub fn s_d(&self, cos_theta: f64, gamma: f64, cos_gamma: f64) -> f64 {
        self.s_d_yxy(self.yxy(cos_theta, gamma, cos_gamma))
    }

    /// [`Self::s_d`] of lanes 0..n (n ≤ [`LANES`]): each exponential one loop over the lanes;
    /// `work` is scratch (5 lanes).
    #[inline(always)]
    fn s_d_lanes(
        &self,
        n: usize,
        cos_theta: &Lane,
        gamma: &Lane,
        cos_gamma: &Lane,
        out: &mut Lane,
        work: &mut [Lane],
    ) {
        assert!(n <= LANES);
        let [y0, y1, y2, ea, eb, ..] = work else {
            panic!("s_d_lanes needs 5 work lanes")
        };
        for (q, yq) in [&mut *y0, &mut *y1, &mut *y2].into_iter().enumerate() {
            let c = &self.coef[q];
            for j in 0..n {
                ea[j] = c[1] / cos_theta[j].max(0.01);
            }
            vmath::exp_in_place(&mut ea[..n]);
            for j in 0..n {
                eb[j] = c[3] * gamma[j];
            }
            vmath::exp_in_place(&mut eb[..n]);
            for j in 0..n {
                yq[j] = self.scale[q] * perez_exp(c, ea[j], eb[j], cos_gamma[j]);
            }
        }
        for j in 0..n {
            out[j] = self.s_d_yxy([y0[j], y1[j], y2[j]]);
        }
    }

    /// S_D from luminance Y and chromaticity x, y ([`Self::yxy`]).
    #[inline(always)]
    fn s_d_yxy(&self, [yl, x, y]: [f64; 3]) -> f64 {
        // M₁ = a₁/m, M₂ = a₂/m; multiplying numerator and denominator by m saves two divisions.
        let m = 0.0241 + 0.2562 * x - 0.7341 * y;
        let a1 = -1.3515 - 1.7703 * x + 5.9114 * y;
        let a2 = 0.0300 - 31.4424 * x + 30.0717 * y;
        let b = &self.basis;
        let s = &self.sums;
        yl * (m * b[0] + a1 * b[1] + a2 * b[2]) / (m * s[0] + a1 * s[1] + a2 * s[2])
    }
}

/// M_DOP(τ) = exp(−τ/4 + 0.12).
pub fn m_dop(turbidity: f64) -> f64 {
    (-turbidity / 4.0 + 0.12).exp()
}

/// Smallest contrast S_ref/S_90 the bounded model divides by (`wang-bounded`, `sky.md` §5).
///
/// The paper's S divides by S_sun/S_90 − 1, which is 2.62 at the default scene but passes through
/// 0 as the sun sinks (T = 4: S_sun/S_90 = 1.17 at θ_s = 85°, 0.98 at 86.5°) and is 0.19 at
/// T = 2, θ_s = 10°. Below this floor the bounded model divides by `R_MIN − 1` instead.
pub const R_MIN: f64 = 2.0;
/// DOP above which the bounded model starts to saturate. The default scene's sky maximum is
/// 0.588 at the default neutral-point distance of 25° and at most 0.645 (δ = 0), so the
/// default scene is untouched for every δ.
pub const DOP_KNEE: f64 = 0.65;
/// Ceiling the bounded DOP approaches but never reaches: the Rayleigh limit of air,
/// (1 − ρ_n)/(1 + ρ_n) with depolarization ratio ρ_n ≈ 0.03.
pub const DOP_CEILING: f64 = 0.94;
/// Floor of S_D in the bounded model, as a fraction of S_ref: S_D ≤ 0 (Preetham's luminance
/// gradation for T < 1.645; the CIE daylight basis at 320–400 nm for the bluest chromaticities
/// at high turbidity) and S_D → 0 would otherwise send 1/S_D through ±∞. The default scene's
/// darkest sky is 0.179 S_sun, so it is untouched.
pub const S_D_FLOOR: f64 = 0.1;
/// S above which the bounded model's S starts to saturate (the default scene's largest S is
/// 1.75, so it is untouched).
pub const S_KNEE: f64 = 1.8;
/// Ceiling of the bounded model's S.
pub const S_CEILING: f64 = 2.2;
/// Lowest turbidity of the bounded model: below T ≈ 1.645 Preetham's luminance gradation
/// 1 + A_Y e^{B_Y/cos θ} is negative at the zenith, so S_D changes sign inside the sky.
pub const BOUNDED_MIN_TURBIDITY: f64 = 1.7;

/// Largest S_D over the sky (zenith 0°…89.9° every 1°, azimuth from the sun 0°…180° every 2°;
/// the sky is symmetric about the solar meridian).
fn sky_max_s_d(p: &Preetham, sun_zenith_rad: f64) -> f64 {
    let (ss, cs) = sun_zenith_rad.sin_cos();
    let mut m = f64::MIN;
    for i in 0..=90 {
        let th = (i as f64).min(89.9).to_radians();
        let (st, ct) = th.sin_cos();
        for j in 0..=90 {
            let da = (2.0 * j as f64).to_radians();
            let cg = (ct * cs + st * ss * da.cos()).clamp(-1.0, 1.0);
            m = m.max(p.s_d(ct, cg.acos(), cg));
        }
    }
    m
}

/// PSNS eq. (5) cooked for one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct WangDop {
    preetham: Preetham,
    /// S_sun = S_D(θ_s, 0).
    pub s_sun: f64,
    /// S_90 = S_D(|θ_s − 90°|, 90°).
    pub s_90: f64,
    /// Bright reference S_ref: S_sun for the paper, max(S_sun, brightest S_D of the sky) bounded.
    pub s_ref: f64,
    inv_s_ref: f64,
    /// S_90 S_ref / (S_ref − S_90) (paper, or bounded with S_ref/S_90 ≥ R_MIN), else
    /// S_ref / (R_MIN − 1).
    s_coef: f64,
    albedo: f64,
    /// M_DOP(τ).
    m: f64,
    /// 1 or 2/π.
    norm: f64,
    model: DopModel,
}

impl WangDop {
    /// The paper's formula ([`DopModel::WangPaper`]) for sun zenith θ_s (degrees, 0..90),
    /// turbidity (1..10), wavelength (nm, 320..720), albedo (0..1) and normalisation.
    pub fn new(
        sun_zenith_deg: f64,
        turbidity: f64,
        wavelength_nm: f64,
        albedo: f64,
        norm: DopNorm,
    ) -> Result<Self> {
        Self::with_model(
            sun_zenith_deg,
            turbidity,
            wavelength_nm,
            albedo,
            norm,
            DopModel::WangPaper,
        )
    }

    /// As [`WangDop::new`] with a choice of model; [`DopModel::WangBounded`] needs turbidity
    /// 1.7..10.
    pub fn with_model(
        sun_zenith_deg: f64,
        turbidity: f64,
        wavelength_nm: f64,
        albedo: f64,
        norm: DopNorm,
        model: DopModel,
    ) -> Result<Self> {
        check_range("sun-zenith", sun_zenith_deg, 0.0, 90.0)?;
        check_turbidity(turbidity, model)?;
        check_range("wavelength", wavelength_nm, 320.0, 720.0)?;
        check_range("albedo", albedo, 0.0, 1.0)?;
        let ts = sun_zenith_deg.to_radians();
        let preetham = Preetham::new(turbidity, ts, wavelength_nm);
        let s_sun = preetham.s_d(ts.cos(), 0.0, 1.0);
        let t90 = (ts - FRAC_PI_2).abs();
        let s_90 = preetham.s_d(t90.cos(), FRAC_PI_2, 0.0);
        let (s_ref, s_coef) = match model {
            DopModel::WangPaper => (s_sun, s_90 * s_sun / (s_sun - s_90)),
            DopModel::WangBounded => {
                let b = s_sun.max(sky_max_s_d(&preetham, ts));
                let s_90 = s_90.max(S_D_FLOOR * b);
                if b >= R_MIN * s_90 {
                    (b, s_90 * b / (b - s_90))
                } else {
                    (b, b / (R_MIN - 1.0))
                }
            }
        };
        Ok(WangDop {
            preetham,
            s_sun,
            s_90,
            s_ref,
            inv_s_ref: 1.0 / s_ref,
            s_coef,
            albedo,
            m: m_dop(turbidity),
            norm: match norm {
                DopNorm::Clamp => 1.0,
                DopNorm::Wilkie => 2.0 / PI,
            },
            model,
        })
    }

    /// The cooked Preetham model.
    pub fn preetham(&self) -> &Preetham {
        &self.preetham
    }

    /// The model.
    pub fn model(&self) -> DopModel {
        self.model
    }

    /// Brightness weight S at view zenith cos θ and scattering angle γ (with its cosine):
    /// (1/S_D − 1/S_ref)·coef, floored at 0 for the bounded model.
    #[inline(always)]
    pub fn s_weight(&self, cos_theta: f64, gamma: f64, cos_gamma: f64) -> f64 {
        let sd = self.preetham.s_d(cos_theta, gamma, cos_gamma);
        match self.model {
            DopModel::WangPaper => self.s_paper(sd),
            DopModel::WangBounded => soft_cap(self.s_bounded_uncapped(sd), S_KNEE, S_CEILING),
        }
    }

    /// The paper's S from S_D.
    #[inline(always)]
    fn s_paper(&self, sd: f64) -> f64 {
        (1.0 / sd - self.inv_s_ref) * self.s_coef
    }

    /// The bounded model's S from S_D, before [`soft_cap`].
    #[inline(always)]
    fn s_bounded_uncapped(&self, sd: f64) -> f64 {
        // f64::max ignores a NaN S_D
        let sd = sd.max(S_D_FLOOR * self.s_ref);
        ((1.0 / sd - self.inv_s_ref) * self.s_coef).max(0.0)
    }

    /// Unnormalised, unclamped DOP |w|·[θE + (π/2 − θ)S]·M_DOP (θ in radians).
    #[inline(always)]
    pub fn seed(&self, abs_w: f64, theta: f64, cos_theta: f64, gamma: f64, cos_gamma: f64) -> f64 {
        let e = vmath::powf(cos_theta.max(0.0), self.albedo);
        let s = self.s_weight(cos_theta, gamma, cos_gamma);
        self.seed_es(abs_w, theta, e, s)
    }

    /// [`Self::seed`] from E = cos(θ)^ρ and S.
    #[inline(always)]
    fn seed_es(&self, abs_w: f64, theta: f64, e: f64, s: f64) -> f64 {
        abs_w * (theta * e + (FRAC_PI_2 - theta) * s) * self.m
    }

    /// The DOP: seed × (1 or 2/π), then clamped to [0, 1] (paper; a non-finite seed, possible
    /// where Preetham's luminance crosses zero for T < 1.645, gives 0 or 1, never NaN) or
    /// passed through [`soft_ceiling`] (bounded).
    #[inline(always)]
    pub fn dop(&self, abs_w: f64, theta: f64, cos_theta: f64, gamma: f64, cos_gamma: f64) -> f64 {
        let x = self.seed(abs_w, theta, cos_theta, gamma, cos_gamma) * self.norm;
        match self.model {
            DopModel::WangPaper => clamp01(x),
            DopModel::WangBounded => soft_ceiling(x),
        }
    }

    /// [`Self::dop`] of lanes 0..n (n ≤ [`LANES`]) of the row evaluator, the same bits: each
    /// transcendental one loop over the lanes, the model chosen outside the loops, and the soft
    /// caps' tanh (rare: above the knees) in a scalar pass over the lanes that need it. `work`
    /// is scratch (7 lanes).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn dop_lanes(
        &self,
        n: usize,
        abs_w: &Lane,
        theta: &Lane,
        cos_theta: &Lane,
        gamma: &Lane,
        cos_gamma: &Lane,
        out: &mut Lane,
        work: &mut [Lane],
    ) {
        assert!(n <= LANES);
        let [s, e, rest @ ..] = work else {
            panic!("dop_lanes needs 7 work lanes")
        };
        self.preetham
            .s_d_lanes(n, cos_theta, gamma, cos_gamma, s, rest);
        match self.model {
            DopModel::WangPaper => {
                for v in &mut s[..n] {
                    *v = self.s_paper(*v);
                }
            }
            DopModel::WangBounded => {
                for v in &mut s[..n] {
                    *v = self.s_bounded_uncapped(*v);
                }
                cap_lanes(&mut s[..n], S_KNEE, S_CEILING);
            }
        }
        let x = &mut rest[0];
        for j in 0..n {
            x[j] = cos_theta[j].max(0.0);
        }
        vmath::powf_lanes(&x[..n], self.albedo, &mut e[..n]);
        for j in 0..n {
            out[j] = self.seed_es(abs_w[j], theta[j], e[j], s[j]) * self.norm;
        }
        match self.model {
            DopModel::WangPaper => {
                for v in &mut out[..n] {
                    *v = clamp01(*v);
                }
            }
            DopModel::WangBounded => {
                // soft_ceiling: 0 for x ≤ 0 and NaN, then soft_cap
                for v in &mut out[..n] {
                    *v = if *v > 0.0 { *v } else { 0.0 };
                }
                cap_lanes(&mut out[..n], DOP_KNEE, DOP_CEILING);
            }
        }
    }
}

/// Turbidity range of a DOP model: 1..10 for the paper, 1.7..10 for the bounded model.
pub fn check_turbidity(turbidity: f64, model: DopModel) -> Result<f64> {
    match model {
        DopModel::WangPaper => check_range("turbidity", turbidity, 1.0, 10.0),
        DopModel::WangBounded => {
            if turbidity.is_finite() && (BOUNDED_MIN_TURBIDITY..=10.0).contains(&turbidity) {
                Ok(turbidity)
            } else {
                Err(crate::Error::range(
                    "turbidity",
                    turbidity,
                    "1.7..10 with --dop-model wang-bounded, where Preetham's sky stays positive; \
                     1..10 with --dop-model wang-paper",
                ))
            }
        }
    }
}

/// [`soft_cap`] of every lane, the tanh only where x > knee.
#[inline(always)]
fn cap_lanes(x: &mut [f64], knee: f64, c: f64) {
    for v in x {
        if *v > knee {
            *v = soft_cap(*v, knee, c);
        }
    }
}

/// x up to `knee`, then knee + (c − knee)·tanh((x − knee)/(c − knee)): continuous with a
/// continuous slope, non-decreasing, never above c.
#[inline]
pub fn soft_cap(x: f64, knee: f64, c: f64) -> f64 {
    if x > knee {
        let w = c - knee;
        knee + w * ((x - knee) / w).tanh()
    } else {
        x
    }
}

/// The bounded model's output map: 0 for x ≤ 0 (and NaN), x up to [`DOP_KNEE`], then
/// k + (c − k)·tanh((x − k)/(c − k)) (c = [`DOP_CEILING`]): continuous with a continuous
/// slope, non-decreasing, never above c (reached only in floating point, for x far above).
#[inline]
pub fn soft_ceiling(x: f64) -> f64 {
    if x > 0.0 {
        soft_cap(x, DOP_KNEE, DOP_CEILING)
    } else {
        0.0
    }
}

/// Clamp to [0, 1] with NaN → 0.
#[inline(always)]
pub fn clamp01(x: f64) -> f64 {
    if x > 1.0 {
        1.0
    } else if x > 0.0 {
        x
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_table_matches_fixture() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/sky-cie-daylight.csv");
        let text = std::fs::read_to_string(path).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split(',').map(|x| x.trim().parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), CIE_DAYLIGHT.len());
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r[0], CIE_LAMBDA0_NM + CIE_STEP_NM * i as f64);
            assert_eq!(&r[1..5], &CIE_DAYLIGHT[i][..]);
        }
    }

    #[test]
    fn m_dop_at_4() {
        assert!((m_dop(4.0) - 0.414783).abs() < 1e-6);
    }

    #[test]
    fn s_is_zero_at_sun_and_one_at_90() {
        let d = WangDop::new(50.0, 4.0, 450.0, 0.1, DopNorm::Clamp).unwrap();
        let ts = 50f64.to_radians();
        assert!(d.s_weight(ts.cos(), 0.0, 1.0).abs() < 1e-12);
        assert!((d.s_weight(40f64.to_radians().cos(), FRAC_PI_2, 0.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn soft_ceiling_is_identity_below_the_knee_and_below_the_ceiling_above() {
        for i in 0..=650 {
            let x = i as f64 * 1e-3;
            assert_eq!(soft_ceiling(x), x.min(DOP_KNEE));
        }
        assert_eq!(soft_ceiling(-1.0), 0.0);
        assert_eq!(soft_ceiling(f64::NAN), 0.0);
        let mut prev = soft_ceiling(DOP_KNEE);
        for i in 1..20_000 {
            let y = soft_ceiling(DOP_KNEE + i as f64 * 1e-3);
            assert!(y >= prev && y <= DOP_CEILING && y - prev <= 1e-3 + 1e-15);
            prev = y;
        }
        assert!(soft_ceiling(1e300) <= DOP_CEILING);
        assert!(soft_cap(1e300, S_KNEE, S_CEILING) <= S_CEILING);
    }

    #[test]
    fn bounded_s_is_finite_and_capped_where_preetham_turns_negative() {
        // T = 1.8, sun on the horizon, 380 nm: S_D < 0 within ~20° of the sun
        let d = WangDop::with_model(90.0, 1.8, 380.0, 0.1, DopNorm::Clamp, DopModel::WangBounded)
            .unwrap();
        assert!(d.s_sun < 0.0 && d.s_ref > 0.0);
        let s = d.s_weight(0.01745, 0.01745, 0.01745f64.cos());
        assert!(s > 2.0 && s <= S_CEILING, "{s}");
        let p = WangDop::new(90.0, 1.8, 380.0, 0.1, DopNorm::Clamp).unwrap();
        assert!(p.s_weight(0.01745, 0.01745, 0.01745f64.cos()) < 0.0);
    }

    #[test]
    fn interpolation_between_rows() {
        let b = cie_basis_at(455.0);
        assert!((b[0] - 0.5 * (125.6 + 125.5)).abs() < 1e-12);
        assert_eq!(cie_basis_at(780.0)[0], 65.0);
    }
}
