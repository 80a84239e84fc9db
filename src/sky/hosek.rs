//! Hosek–Wilkie spectral sky model v1.4a, with the solar disc.
//!
//! # Physics
//!
//! The model is an analytic fit to brute-force path-traced radiative transfer in a
//! plane-parallel atmosphere (Rayleigh + Mie scattering, ozone, a Lambertian ground of albedo
//! a), for sun elevations η ∈ [0°, 90°], turbidity T ∈ [1, 10] and eleven channels
//! 320, 360, …, 720 nm. For one channel the sky radiance in a direction with view zenith θ at
//! angle γ from the sun is
//!
//!   L(θ, γ) = L_M · (1 + A e^{B/(cos θ + 0.01)}) ·
//!             (C + D e^{Eγ} + F cos²γ + G χ(H, γ) + I √cos θ),
//!   χ(H, γ) = (1 + cos²γ) / (1 + H² − 2H cos γ)^{3/2},
//!
//! an extended Perez formula: the first factor is the horizon gradient, D e^{Eγ} the
//! circumsolar aureole, F cos²γ the Rayleigh lobe, the Henyey–Greenstein-like χ the Mie peak and
//! I √cos θ the zenith brightening. The nine coefficients and L_M are quintic Bézier curves in
//! (η/(π/2))^{1/3}, tabulated at the integer turbidities and albedo 0 and 1, and interpolated
//! linearly in T and a ("cooking", done once in [`HosekWilkie::new`]). Between channels the two
//! neighbouring channels are evaluated fully and their *radiances* interpolated linearly in
//! wavelength; the coefficients are never interpolated across channels.
//!
//! The solar disc (angular radius [`SUN_RADIUS_RAD`] = 0.255°) has the radiance of the 2013
//! extension: a piecewise cubic in η over 45 segments (segment edges cubic in η), linear in T
//! and wavelength, times a fifth-order limb-darkening polynomial in the cosine of the
//! emission angle on the solar surface. It is unpolarized and is *added* to the sky radiance by
//! the caller ([`HosekWilkie::sun_radiance`] returns the disc alone). This module uses the
//! cooked sun elevation for the disc; the v1.4a C code uses the elevation of the view ray,
//! which differs from it by at most 0.255° inside the disc.
//!
//! # Units and frame
//!
//! Radiance in W m⁻² sr⁻¹ nm⁻¹ (spectral radiance at the given wavelength). Angles in radians:
//! θ is the view zenith angle (the model is undefined below the horizon, cos θ < 0 — the caller
//! must not evaluate there), γ the angle between the view ray and the sun's centre, η the sun
//! elevation = π/2 − sun zenith (`sky.md` §1, §3).
//!
//! # References
//!
//! * L. Hošek, A. Wilkie, "An analytic model for full spectral sky-dome radiance",
//!   ACM Transactions on Graphics 31(4):95 (SIGGRAPH 2012).
//! * L. Hošek, A. Wilkie, "Adding a solar-radiance function to the Hošek–Wilkie skylight model",
//!   IEEE Computer Graphics and Applications 33(3):44–52 (2013).
//! * Reference implementation v1.4a (`ArHosekSkyModel.c`), whose spectral datasets are the
//!   embedded data.
//!
//! # Data and licence
//!
//! The fitted coefficients ship inside the crate (`data/hosek-wilkie/*.f64le`, embedded with
//! `include_bytes!`; layout, cooking and check values in `data/hosek-wilkie/README.md`). They are published
//! under the 3-clause BSD licence, © 2012–2013 Lukas Hosek and Alexander Wilkie; the notice is
//! in `data/hosek-wilkie/LICENSE` and available at run time as [`LICENSE`]. Anything that
//! redistributes this crate must ship that notice.

use super::{Lane, LANES};
use crate::error::{check_range, Result};
use crate::vmath;
use std::f64::consts::FRAC_PI_2;

/// Angular radius of the solar disc used by the model, radians (0.255°).
pub const SUN_RADIUS_RAD: f64 = 0.255 * std::f64::consts::PI / 180.0;

/// The 3-clause BSD notice that covers the embedded Hosek–Wilkie coefficients.
pub const LICENSE: &str = include_str!("../../data/hosek-wilkie/LICENSE");

const SKY_PARAMS: &[u8] = include_bytes!("../../data/hosek-wilkie/sky_params_spectral.f64le");
const SKY_RADIANCE: &[u8] = include_bytes!("../../data/hosek-wilkie/sky_radiance_spectral.f64le");
const SUN_RADIANCE: &[u8] = include_bytes!("../../data/hosek-wilkie/sun_radiance_spectral.f64le");
const SUN_LIMB: &[u8] = include_bytes!("../../data/hosek-wilkie/sun_limb_darkening_spectral.f64le");

const N_TURB: usize = 10;
const N_ALB: usize = 2;
const N_CTRL: usize = 6;
const N_CHAN: usize = 11;
const N_COEF: usize = 9;
const N_SEG: usize = 45;
const N_SUN_K: usize = 4;
const N_LIMB: usize = 6;

// Shapes of the README; a wrong file fails the build, not a run.
const _: () = assert!(SKY_PARAMS.len() == 8 * N_TURB * N_ALB * N_CTRL * N_CHAN * N_COEF);
const _: () = assert!(SKY_RADIANCE.len() == 8 * N_TURB * N_ALB * N_CTRL * N_CHAN);
const _: () = assert!(SUN_RADIANCE.len() == 8 * N_TURB * N_SEG * N_CHAN * N_SUN_K);
const _: () = assert!(SUN_LIMB.len() == 8 * N_CHAN * N_LIMB);

/// The four embedded data files as (file name, bytes), e.g. to verify their SHA-256.
pub fn embedded_data() -> [(&'static str, &'static [u8]); 4] {
    [
        ("sky_params_spectral.f64le", SKY_PARAMS),
        ("sky_radiance_spectral.f64le", SKY_RADIANCE),
        ("sun_radiance_spectral.f64le", SUN_RADIANCE),
        ("sun_limb_darkening_spectral.f64le", SUN_LIMB),
    ]
}

/// Element `i` of a little-endian f64 array (the sizes are checked at compile time).
#[inline]
fn f64_at(bytes: &[u8], i: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[8 * i..8 * i + 8]);
    f64::from_le_bytes(b)
}

/// One channel cooked for a scene. The second factor's coefficients (C, D, F, G, I) are
/// pre-multiplied by L_M and the channel's wavelength weight, so a call returns its share of
/// the interpolated radiance directly (a per-channel scale, not a coefficient interpolation).
#[derive(Clone, Copy, Debug)]
struct Channel {
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    e: f64,
    f: f64,
    g: f64,
    i: f64,
    /// 1 + H².
    h1: f64,
    /// 2H.
    h2: f64,
}

impl Channel {
    /// Cooks channel `chan` (0..11) and scales it by `weight`.
    fn cook(chan: usize, t0: usize, t1: usize, ft: f64, albedo: f64, x: f64, weight: f64) -> Self {
        let bern = bernstein5(x);
        // Blend of the four (turbidity, albedo) corners, each a Bézier curve in x.
        let corners = [
            (t0, 0, (1.0 - albedo) * (1.0 - ft)),
            (t1, 0, (1.0 - albedo) * ft),
            (t0, 1, albedo * (1.0 - ft)),
            (t1, 1, albedo * ft),
        ];
        let mut p = [0.0f64; N_COEF];
        let mut lm = 0.0;
        for &(t, m, w) in &corners {
            if w == 0.0 {
                continue; // also skips t1 = t0 + 1 beyond the table at T = 10
            }
            for (k, &bk) in bern.iter().enumerate() {
                let base = ((t * N_ALB + m) * N_CTRL + k) * N_CHAN + chan;
                for (j, pj) in p.iter_mut().enumerate() {
                    *pj += w * bk * f64_at(SKY_PARAMS, base * N_COEF + j);
                }
                lm += w * bk * f64_at(SKY_RADIANCE, base);
            }
        }
        // Stored order A, B, C, D, E, F, G, I, H.
        let s = lm * weight;
        let h = p[8];
        Channel {
            a: p[0],
            b: p[1],
            c: s * p[2],
            d: s * p[3],
            e: p[4],
            f: s * p[5],
            g: s * p[6],
            i: s * p[7],
            h1: 1.0 + h * h,
            h2: 2.0 * h,
        }
    }

    /// Weighted radiance from the shared per-direction inputs.
    #[inline(always)]
    fn eval(&self, inv_ct: f64, sqrt_ct: f64, gamma: f64, cg: f64, cg2: f64) -> f64 {
        let (ea, eb) = (vmath::exp(self.b * inv_ct), vmath::exp(self.e * gamma));
        self.eval_exp(sqrt_ct, cg, cg2, ea, eb)
    }

    /// [`Self::eval`] given its two exponentials e^{B/(cos θ + 0.01)} (`ea`) and e^{Eγ} (`eb`).
    #[inline(always)]
    fn eval_exp(&self, sqrt_ct: f64, cg: f64, cg2: f64, ea: f64, eb: f64) -> f64 {
        let q = self.h1 - self.h2 * cg;
        let mie = (1.0 + cg2) / (q * q.sqrt());
        (1.0 + self.a * ea)
            * (self.c + self.d * eb + self.f * cg2 + self.g * mie + self.i * sqrt_ct)
    }

    /// Adds (`add`) or writes this channel's [`Self::eval`] for `n` lanes of
    /// [`HosekWilkie::radiance_lanes`], given its per-direction lanes `sh` (1/(cos θ + 0.01),
    /// √cos θ, cos²γ): each exponential one loop over the lanes ([`vmath::exp_in_place`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn eval_lanes(
        &self,
        n: usize,
        gamma: &Lane,
        cg: &Lane,
        [inv_ct, sqrt_ct, cg2]: [&Lane; 3],
        out: &mut Lane,
        add: bool,
        [ea, eb]: [&mut Lane; 2],
    ) {
        for j in 0..n {
            ea[j] = self.b * inv_ct[j];
        }
        vmath::exp_in_place(&mut ea[..n]);
        for j in 0..n {
            eb[j] = self.e * gamma[j];
        }
        vmath::exp_in_place(&mut eb[..n]);
        for j in 0..n {
            let l = self.eval_exp(sqrt_ct[j], cg[j], cg2[j], ea[j], eb[j]);
            out[j] = if add { out[j] + l } else { l };
        }
    }
}

/// Quintic Bernstein weights C(5,k) (1−x)^{5−k} x^k.
fn bernstein5(x: f64) -> [f64; 6] {
    let y = 1.0 - x;
    [
        y.powi(5),
        5.0 * y.powi(4) * x,
        10.0 * y.powi(3) * x.powi(2),
        10.0 * y.powi(2) * x.powi(3),
        5.0 * y * x.powi(4),
        x.powi(5),
    ]
}

/// The model cooked for one (turbidity, albedo, sun elevation, wavelength).
///
/// ```
/// use psns::sky::hosek::HosekWilkie;
/// // T = 4, albedo 0.1, sun elevation 40°, 450 nm; zenith view (γ = 50°).
/// let hw = HosekWilkie::new(4.0, 0.1, 40f64.to_radians(), 450.0).unwrap();
/// let l = hw.radiance(0.0, 50f64.to_radians());
/// assert!((l / 7.414022e-2 - 1.0).abs() < 1e-6); // W m⁻² sr⁻¹ nm⁻¹
/// assert!(hw.sun_radiance(0.0) > 1e4 && hw.sun_radiance(0.01) == 0.0);
/// ```
#[derive(Clone, Debug)]
pub struct HosekWilkie {
    turbidity: f64,
    albedo: f64,
    sun_elevation_rad: f64,
    wavelength_nm: f64,
    /// Lower and upper channel, already weighted; `chan[1]` is unused when `two` is false.
    chan: [Channel; 2],
    two: bool,
    /// Disc-centre radiance (no limb darkening), W m⁻² sr⁻¹ nm⁻¹.
    sun_center: f64,
    /// Limb-darkening polynomial d0..d5, interpolated in wavelength.
    limb: [f64; N_LIMB],
    /// 1 / sin²(r_sun).
    inv_sin2_r: f64,
}

impl HosekWilkie {
    /// Cooks the two channels around `wavelength_nm` (320..720) for turbidity 1..10, ground
    /// albedo 0..1 and sun elevation 0..π/2 rad. Out-of-range or non-finite values give
    /// [`crate::Error::OutOfRange`].
    pub fn new(
        turbidity: f64,
        albedo: f64,
        sun_elevation_rad: f64,
        wavelength_nm: f64,
    ) -> Result<Self> {
        check_range("turbidity", turbidity, 1.0, 10.0)?;
        check_range("albedo", albedo, 0.0, 1.0)?;
        check_range("sun-elevation", sun_elevation_rad, 0.0, FRAC_PI_2)?;
        check_range("wavelength", wavelength_nm, 320.0, 720.0)?;

        // Turbidity: value t sits at index t−1; at T = 10 only t0 is used.
        let t0 = (turbidity.floor() as usize).clamp(1, N_TURB) - 1;
        let ft = turbidity - (t0 + 1) as f64;
        let t1 = (t0 + 1).min(N_TURB - 1);

        // Wavelength: channel index and weight of the upper neighbour.
        let pos = (wavelength_nm - 320.0) / 40.0;
        let c0 = (pos.floor() as usize).min(N_CHAN - 1);
        let fw = pos - c0 as f64;
        let two = fw > 0.0 && c0 + 1 < N_CHAN;
        let c1 = if two { c0 + 1 } else { c0 };

        let x = (sun_elevation_rad / FRAC_PI_2).cbrt();
        let lo = Channel::cook(c0, t0, t1, ft, albedo, x, if two { 1.0 - fw } else { 1.0 });
        let hi = if two {
            Channel::cook(c1, t0, t1, ft, albedo, x, fw)
        } else {
            lo
        };

        // Sun disc: piecewise polynomial in η, linear in T and λ (as the v1.4a code).
        let seg = ((((2.0 * sun_elevation_rad / std::f64::consts::PI).cbrt()) * N_SEG as f64)
            .floor() as usize)
            .min(N_SEG - 1);
        let eta_b = (seg as f64 / N_SEG as f64).powi(3) * FRAC_PI_2;
        let dx = sun_elevation_rad - eta_b;
        let sun_at = |t: usize, c: usize| -> f64 {
            let base = ((t * N_SEG + seg) * N_CHAN + c) * N_SUN_K;
            (0..N_SUN_K)
                .rev()
                .fold(0.0, |acc, k| acc * dx + f64_at(SUN_RADIANCE, base + k))
        };
        let fw_sun = if two { fw } else { 0.0 };
        let at_t = |t: usize| (1.0 - fw_sun) * sun_at(t, c0) + fw_sun * sun_at(t, c1);
        let sun_center = if ft > 0.0 {
            (1.0 - ft) * at_t(t0) + ft * at_t(t1)
        } else {
            at_t(t0)
        };
        let mut limb = [0.0; N_LIMB];
        for (i, d) in limb.iter_mut().enumerate() {
            *d = (1.0 - fw_sun) * f64_at(SUN_LIMB, c0 * N_LIMB + i)
                + fw_sun * f64_at(SUN_LIMB, c1 * N_LIMB + i);
        }
        let sr = SUN_RADIUS_RAD.sin();

        Ok(HosekWilkie {
            turbidity,
            albedo,
            sun_elevation_rad,
            wavelength_nm,
            chan: [lo, hi],
            two,
            sun_center,
            limb,
            inv_sin2_r: 1.0 / (sr * sr),
        })
    }

    /// Turbidity T.
    pub fn turbidity(&self) -> f64 {
        self.turbidity
    }

    /// Ground albedo.
    pub fn albedo(&self) -> f64 {
        self.albedo
    }

    /// Sun elevation η in radians.
    pub fn sun_elevation_rad(&self) -> f64 {
        self.sun_elevation_rad
    }

    /// Wavelength in nm.
    pub fn wavelength_nm(&self) -> f64 {
        self.wavelength_nm
    }

    /// Sky radiance (W m⁻² sr⁻¹ nm⁻¹) at view zenith θ and scattering angle γ (radians); cos θ ≥ 0.
    pub fn radiance(&self, theta_rad: f64, gamma_rad: f64) -> f64 {
        self.radiance_cos(theta_rad.cos(), gamma_rad, gamma_rad.cos())
    }

    /// The same as [`radiance`](Self::radiance) from cos θ, γ and cos γ, which the caller
    /// usually has already (a dot product with the sun vector). For the per-pixel loop: the
    /// work is the two channels' F(θ, γ) sharing cos θ, √cos θ, 1/(cos θ + 0.01) and cos²γ.
    /// cos θ must be ≥ 0 (above the horizon); γ = arccos(cos γ) in radians.
    #[inline]
    pub fn radiance_cos(&self, cos_theta: f64, gamma_rad: f64, cos_gamma: f64) -> f64 {
        let inv_ct = 1.0 / (cos_theta + 0.01);
        let sqrt_ct = cos_theta.sqrt();
        let cg2 = cos_gamma * cos_gamma;
        let l = self.chan[0].eval(inv_ct, sqrt_ct, gamma_rad, cos_gamma, cg2);
        if self.two {
            l + self.chan[1].eval(inv_ct, sqrt_ct, gamma_rad, cos_gamma, cg2)
        } else {
            l
        }
    }

    /// [`radiance_cos`](Self::radiance_cos) of lanes 0..n (n ≤ [`LANES`]) of the row evaluator
    /// (`render::pixel_sky_row`), the same bits; `work` is scratch (5 lanes). The channels share
    /// 1/(cos θ + 0.01), √cos θ and cos²γ, computed once.
    #[inline(always)]
    pub fn radiance_lanes(
        &self,
        n: usize,
        cos_theta: &Lane,
        gamma: &Lane,
        cos_gamma: &Lane,
        out: &mut Lane,
        work: &mut [Lane],
    ) {
        assert!(n <= LANES);
        let [ea, eb, inv_ct, sqrt_ct, cg2, ..] = work else {
            panic!("radiance_lanes needs 5 work lanes")
        };
        let (ct, g, cg) = (cos_theta, gamma, cos_gamma);
        for j in 0..n {
            inv_ct[j] = 1.0 / (ct[j] + 0.01);
            sqrt_ct[j] = ct[j].sqrt();
            cg2[j] = cg[j] * cg[j];
        }
        let sh = [&*inv_ct, &*sqrt_ct, &*cg2];
        self.chan[0].eval_lanes(n, g, cg, sh, out, false, [&mut *ea, &mut *eb]);
        if self.two {
            self.chan[1].eval_lanes(n, g, cg, sh, out, true, [ea, eb]);
        }
    }

    /// Radiance of the solar disc (limb-darkened) at angle γ from the sun's centre; 0 outside
    /// it (γ ≥ [`SUN_RADIUS_RAD`]). W m⁻² sr⁻¹ nm⁻¹, to be added to the sky radiance.
    pub fn sun_radiance(&self, gamma_rad: f64) -> f64 {
        let g = gamma_rad.abs();
        if g.is_nan() || g >= SUN_RADIUS_RAD {
            return 0.0;
        }
        let sg = g.sin();
        let s = (1.0 - sg * sg * self.inv_sin2_r).max(0.0).sqrt();
        let dark = self.limb.iter().rev().fold(0.0, |acc, &d| acc * s + d);
        self.sun_center * dark
    }

    /// Disc-centre radiance without limb darkening (the model's L_sun at this scene).
    pub fn sun_radiance_unlimbed(&self) -> f64 {
        self.sun_center
    }
}
