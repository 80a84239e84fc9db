//! Angle of polarization of the clear sky: Berry, Dennis & Lee's four-neutral-point field.
//!
//! Physics (Berry, Dennis & Lee, "Polarization singularities in the clear sky", New J. Phys. 6:162,
//! 2004): the polarization pattern of the sky is the complex field
//!
//! w(ζ) = −4 (ζ−ζ₊)(ζ−ζ₋)(ζ+1/ζ̄₊)(ζ+1/ζ̄₋) / [(1+|ζ|²)² |ζ₊+1/ζ̄₊| |ζ₋+1/ζ̄₋|]
//!
//! on the stereographic chart ζ = tan(θ/2) e^{iA} (from the nadir; zenith → 0, horizon → |ζ| = 1).
//! Its zeros are the Brewster (ζ₊, below the sun) and Babinet (ζ₋, above the sun) neutral points
//! and their antipodes (Arago, and the fourth point). The project uses the *signed* form of
//! `sky.md` §4, with t₊ = tan((θ_s+δ_Br)/2), t₋ = tan((θ_s−δ_Ba)/2):
//!
//! w = −4 e^{2iA_s} (ζ−t₊e^{iA_s})(ζ−t₋e^{iA_s})(1+t₊ζe^{−iA_s})(1+t₋ζe^{−iA_s}) / [(1+|ζ|²)²(1+t₊²)(1+t₋²)],
//!
//! which stays correct when the sun is closer to the zenith than δ_Ba and the Babinet point
//! crosses to the anti-solar side (t₋ < 0); Berry's literal form flips every AOP by 90° there.
//! The E-vector angle in the chart, from north toward east, is χ = ½ arg(w e^{−2iA_s}); the 3-D
//! E-vector is e = cos(χ−A) e_θ + sin(χ−A) e_A. |w| = sin γ₊ sin γ₋ (angular distances to the two
//! neutral points) lies in [0, 1] and is the field's contribution to the DOP ([`super::dop`]).
//! As δ → 0 (Wang et al., J. Opt. 18:065601, 2016: the "Rayleigh limit") |w| → sin²γ and e → s × v.
//!
//! Frame: ENU (x east, y north, z up), compass azimuths (`sky.md` §1). Chart coordinates are
//! (Re ζ, Im ζ) = (north, east) components, so ζ = (v_y + i v_x)/(1 + v_z) — no trigonometry on
//! the per-pixel path.

use super::{Lane, LANES};
use glam::DVec3;
use num_complex::Complex64;

/// Stereographic chart coordinate ζ = tan(θ/2) e^{iA} = (v_y + i v_x)/(1 + v_z) of a unit ENU
/// vector (infinite at the nadir).
#[inline]
pub fn chart(v: DVec3) -> Complex64 {
    let k = 1.0 / (1.0 + v.z);
    Complex64::new(v.y * k, v.x * k)
}

/// Unit 3-D vectors (in ENU) of the chart's north (real) and east (imaginary) directions at the
/// point of the sphere seen along unit `v`. The stereographic chart is conformal, so these are
/// orthonormal and perpendicular to `v`; at the zenith they are north and east. Not defined at
/// the nadir.
///
/// A chart angle χ (from north toward east) becomes the 3-D direction cos χ N + sin χ E, which
/// equals cos(χ−A) e_θ + sin(χ−A) e_A away from the zenith.
#[inline(always)]
pub fn chart_basis(v: DVec3) -> (DVec3, DVec3) {
    let k = 1.0 / (1.0 + v.z);
    let xy = v.x * v.y * k;
    let n = DVec3::new(-xy, 1.0 - v.y * v.y * k, -v.y);
    let e = DVec3::new(1.0 - v.x * v.x * k, -xy, -v.x);
    (n, e)
}

/// Zenith angles (degrees) of the four neutral points, as points on the full sphere; values
/// above 90° are below the horizon. Babinet and Brewster lie on the solar vertical at the sun's
/// azimuth (a negative Babinet angle means it has crossed the zenith to the anti-solar side);
/// Arago and the fourth point are their antipodes, at the anti-solar azimuth A_s + 180°.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeutralPoints {
    /// Babinet, θ_s − δ_Ba (signed, at A_s).
    pub babinet: f64,
    /// Brewster, θ_s + δ_Br (at A_s).
    pub brewster: f64,
    /// Arago, 180° − (θ_s + δ_Br), at A_s + 180°.
    pub arago: f64,
    /// Fourth point, 180° − (θ_s − δ_Ba), at A_s + 180°.
    pub fourth: f64,
}

impl NeutralPoints {
    /// Neutral-point geometry for sun zenith θ_s and distances δ_Ba, δ_Br (degrees).
    pub fn new(sun_zenith_deg: f64, babinet_deg: f64, brewster_deg: f64) -> Self {
        let babinet = sun_zenith_deg - babinet_deg;
        let brewster = sun_zenith_deg + brewster_deg;
        NeutralPoints {
            babinet,
            brewster,
            arago: 180.0 - brewster,
            fourth: 180.0 - babinet,
        }
    }

    /// Unit ENU vectors of (Babinet, Brewster, Arago, fourth) for sun azimuth A_s (degrees).
    pub fn directions(&self, sun_azimuth_deg: f64) -> [DVec3; 4] {
        let anti = sun_azimuth_deg + 180.0;
        [
            super::direction(self.babinet, sun_azimuth_deg),
            super::direction(self.brewster, sun_azimuth_deg),
            super::direction(self.arago, anti),
            super::direction(self.fourth, anti),
        ]
    }
}

/// The Berry field of one scene, cooked: everything that depends only on the sun and δ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BerryField {
    /// t₊ = tan((θ_s + δ_Br)/2), signed chart distance of the Brewster point along A_s.
    pub t_plus: f64,
    /// t₋ = tan((θ_s − δ_Ba)/2), signed chart distance of the Babinet point along A_s.
    pub t_minus: f64,
    /// e^{iA_s}.
    sun_dir: Complex64,
    /// 1/((1 + t₊²)(1 + t₋²)).
    inv_norm: f64,
}

/// |w| and the unit E-vector at one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BerryEval {
    /// |w| = sin γ₊ sin γ₋ ∈ [0, 1].
    pub abs_w: f64,
    /// Unit E-vector in ENU, ⟂ v (sign arbitrary: the E-vector is axial). At a neutral point,
    /// where it is undefined, the chart north direction (χ = 0) is returned.
    pub e: DVec3,
}

impl BerryField {
    /// Cooks the field for sun zenith θ_s, sun azimuth A_s and neutral-point distances δ_Ba
    /// (Babinet, above the sun) and δ_Br (Brewster, below it), all in degrees. With
    /// θ_s ∈ [0, 90] and δ ∈ [0, 60] every constant is finite.
    pub fn new(
        sun_zenith_deg: f64,
        sun_azimuth_deg: f64,
        babinet_deg: f64,
        brewster_deg: f64,
    ) -> Self {
        let t_plus = (0.5 * (sun_zenith_deg + brewster_deg).to_radians()).tan();
        let t_minus = (0.5 * (sun_zenith_deg - babinet_deg).to_radians()).tan();
        let (sa, ca) = sun_azimuth_deg.to_radians().sin_cos();
        BerryField {
            t_plus,
            t_minus,
            sun_dir: Complex64::new(ca, sa),
            inv_norm: 1.0 / ((1.0 + t_plus * t_plus) * (1.0 + t_minus * t_minus)),
        }
    }

    /// The complex field w(ζ) of `sky.md` §4, literally (reference implementation; the per-pixel
    /// path is [`BerryField::eval`]).
    pub fn w(&self, zeta: Complex64) -> Complex64 {
        let s = self.sun_dir;
        let sc = s.conj();
        let one = Complex64::new(1.0, 0.0);
        let num = (zeta - s * self.t_plus)
            * (zeta - s * self.t_minus)
            * (one + zeta * sc * self.t_plus)
            * (one + zeta * sc * self.t_minus);
        let d = 1.0 + zeta.norm_sqr();
        -4.0 * s * s * num * self.inv_norm / (d * d)
    }

    /// Chart AOP χ = ½ arg(w e^{−2iA_s}) in degrees, in (−90°, 90°] (reference implementation).
    pub fn chi_deg(&self, zeta: Complex64) -> f64 {
        let s = self.sun_dir;
        let u = self.w(zeta) * (s * s).conj();
        crate::angle::wrap_pm90(0.5 * u.arg().to_degrees())
    }

    /// The E-vector direction of [`Self::eval`] alone, with |p| as √(Re² + Im²) instead of
    /// `hypot` (the same to rounding; the heading model fit evaluates it ~10⁶ times a frame).
    #[inline]
    pub fn e_only(&self, v: DVec3) -> DVec3 {
        let (k, p) = self.chart_p(v);
        self.finish(v, k, p, (p.re * p.re + p.im * p.im).sqrt()).e
    }

    /// |w| and the unit 3-D E-vector for a unit ENU view vector `v` with v.z > −1 (any point of
    /// the sphere but the nadir). No trigonometric calls: two square roots and a few complex
    /// products.
    #[inline(always)]
    pub fn eval(&self, v: DVec3) -> BerryEval {
        let (k, p) = self.chart_p(v);
        self.finish(v, k, p, crate::vmath::hypot(p.re, p.im))
    }

    /// [`Self::eval`] of lanes 0..n (n ≤ [`LANES`]) of the row evaluator, unit ENU vectors
    /// `v` (x, y, z), the same bits: |w| into `abs_w`, the E-vector into `e` (x, y, z); `work`
    /// is scratch (4 lanes).
    #[inline(always)]
    pub fn eval_lanes(
        &self,
        n: usize,
        v: &[Lane; 3],
        abs_w: &mut Lane,
        e: &mut [Lane; 3],
        work: &mut [Lane],
    ) {
        assert!(n <= LANES);
        let [k, re, im, r, ..] = work else {
            panic!("eval_lanes needs 4 work lanes")
        };
        for j in 0..n {
            let (kj, p) = self.chart_p(DVec3::new(v[0][j], v[1][j], v[2][j]));
            (k[j], re[j], im[j]) = (kj, p.re, p.im);
        }
        for j in 0..n {
            r[j] = crate::vmath::hypot(re[j], im[j]);
        }
        for j in 0..n {
            let vj = DVec3::new(v[0][j], v[1][j], v[2][j]);
            let b = self.finish(vj, k[j], Complex64::new(re[j], im[j]), r[j]);
            abs_w[j] = b.abs_w;
            (e[0][j], e[1][j], e[2][j]) = (b.e.x, b.e.y, b.e.z);
        }
    }

    /// |w| and the E-vector of direction χ = A_s + ½ arg p at `v`, from k and p of
    /// [`Self::chart_p`] and r = |p|; at a neutral point (half-angle direction undefined) |w| = 0
    /// and χ = 0, the chart's north. Branch-free but for selects.
    #[inline(always)]
    fn finish(&self, v: DVec3, k: f64, p: Complex64, r: f64) -> BerryEval {
        // (1 + |ζ|²)² = 4/(1 + v_z)², so |w| = |p| (1 + v_z)² / ((1+t₊²)(1+t₋²)).
        let opz = 1.0 + v.z;
        let (hx, hy) = half_angle(p, r);
        let h2 = hx * hx + hy * hy;
        let inv = 1.0 / h2.sqrt();
        // Rotate back by A_s: e^{iχ} = e^{iA_s} (c + i s).
        let q = self.sun_dir * Complex64::new(hx * inv, hy * inv);
        // the chart basis (chart_basis) with k = 1/(1 + v_z)
        let xy = v.x * v.y * k;
        let n = DVec3::new(-xy, 1.0 - v.y * v.y * k, -v.y);
        let east = DVec3::new(1.0 - v.x * v.x * k, -xy, -v.x);
        if h2 <= 0.0 {
            BerryEval { abs_w: 0.0, e: n }
        } else {
            BerryEval {
                abs_w: r * opz * opz * self.inv_norm,
                e: n * q.re + east * q.im,
            }
        }
    }

    /// k = 1/(1 + v_z) and p, with w e^{−2iA_s} = e^{2iA_s} p × (positive), so χ = A_s + ½ arg p.
    #[inline(always)]
    fn chart_p(&self, v: DVec3) -> (f64, Complex64) {
        let k = 1.0 / (1.0 + v.z);
        // ζ' = ζ e^{−iA_s}: chart rotated so the sun's azimuth is the real axis.
        let zeta = Complex64::new(v.y * k, v.x * k);
        let zr = zeta * self.sun_dir.conj();
        let (tp, tm) = (self.t_plus, self.t_minus);
        let f1 = Complex64::new(zr.re - tp, zr.im);
        let f2 = Complex64::new(zr.re - tm, zr.im);
        let f3 = Complex64::new(1.0 + tp * zr.re, tp * zr.im);
        let f4 = Complex64::new(1.0 + tm * zr.re, tm * zr.im);
        (k, -((f1 * f2) * (f3 * f4)))
    }
}

/// Half-angle direction of p without trig: ∝ (r + Re p, Im p), or (Im p, r − Re p) when Re p < 0
/// (the same direction, better conditioned); r = |p|.
#[inline(always)]
pub(crate) fn half_angle(p: Complex64, r: f64) -> (f64, f64) {
    if p.re >= 0.0 {
        (r + p.re, p.im)
    } else {
        (p.im, r - p.re)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn e_only_is_evals_e_vector() {
        let f = BerryField::new(40.0, 200.0, 22.0, 27.0);
        for &(z, a) in &[
            (0.0, 0.0),
            (10.0, 33.0),
            (60.0, 200.0),
            (89.0, 300.0),
            (50.0, 20.0),
        ] {
            let v = super::super::direction(z, a);
            let (e1, e2) = (f.eval(v).e, f.e_only(v));
            assert!((e1 - e2).length() < 1e-12, "{e1} {e2}");
        }
    }

    #[test]
    fn chart_basis_is_orthonormal_and_tangent() {
        for &(z, a) in &[
            (0.0, 0.0),
            (10.0, 33.0),
            (60.0, 200.0),
            (89.0, 300.0),
            (120.0, 45.0),
        ] {
            let v = super::super::direction(z, a);
            let (n, e) = chart_basis(v);
            assert!((n.length() - 1.0).abs() < 1e-14);
            assert!((e.length() - 1.0).abs() < 1e-14);
            assert!(n.dot(e).abs() < 1e-14 && n.dot(v).abs() < 1e-14 && e.dot(v).abs() < 1e-14);
            // orientation: north × east = −v (seen from inside the sphere, as a map seen from below)
            assert!((n.cross(e) + v).length() < 1e-14);
        }
    }

    #[test]
    fn eval_matches_literal_formula() {
        let f = BerryField::new(50.0, 200.0, 25.0, 25.0);
        for &(z, a) in &[(15.0, 0.0), (45.0, 110.0), (70.0, 20.0), (80.0, 245.0)] {
            let v = super::super::direction(z, a);
            let ev = f.eval(v);
            let zeta = chart(v);
            assert!((ev.abs_w - f.w(zeta).norm()).abs() < 1e-14);
            let (n, e) = chart_basis(v);
            let chi = ev.e.dot(e).atan2(ev.e.dot(n)).to_degrees();
            let d = (chi - f.chi_deg(zeta)).rem_euclid(180.0);
            assert!(
                d.min(180.0 - d) < 1e-10,
                "{z} {a}: {chi} vs {}",
                f.chi_deg(zeta)
            );
        }
    }
}
