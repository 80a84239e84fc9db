//! The asymmetric quartic sky: four independently placed neutral points on the solar meridian,
//! and the OpenSky/QuEEN map from polarization intensity to DOP.
//!
//! Physics. Berry, Dennis & Lee's field ([`super::berry`]) has four zeros, the Brewster and
//! Babinet points and their antipodes (Arago, fourth point). Observed skies do not keep the
//! anti-solar pair antipodal, so this model places all four on the solar meridian by their own
//! distances, each given as a signed zenith angle ψ_k along the sun's azimuth (negative: on the
//! anti-solar side):
//!
//! ψ_Br = θ_s + δ_Br, ψ_Ba = θ_s − δ_Ba, ψ_Ar = θ_s − 180° + δ_Ar, ψ_4 = θ_s − 180° − δ_4.
//!
//! **AOP.** With the chart ζ = tan(θ/2) e^{iA} turned so the sun's azimuth is the real axis,
//! z = ζ e^{−iA_s}, the field's phase is that of p(z) = −∏_k (cos(ψ_k/2) z − sin(ψ_k/2)) and the
//! chart AOP is χ = A_s + ½ arg p (the e^{−2iA_s} convention of `sky.md` §4). Each factor is
//! the root factor z − tan(ψ_k/2) times cos(ψ_k/2), so it stays finite when a root passes the
//! nadir (ψ_k through ±180°, tan(ψ_k/2) through ±∞): the field is continuous in every
//! parameter. The literal product ∏(ζ − ζ_k) of pyskylumos 0.1.3 lacks the factors cos(ψ_k/2)
//! and turns every AOP by 90° when one of them changes sign (with the default distances: the
//! fourth point passes the nadir when θ_s < δ_4, above about 44° of solar elevation). With
//! δ_Ar = δ_Br and δ_4 = δ_Ba the field is Berry's ([`super::berry::BerryField`]).
//!
//! **DOP.** The modulus is m = ∏_k sin(Γ_k/2) / max over the sphere (Γ_k the angular distance
//! to root k; sin²(Γ_k/2) = |cos(ψ_k/2) z − sin(ψ_k/2)|²/(1 + |z|²), so m ∝ |p|(1 + v_z)²), and
//! DOP = DOP_max m/(2 − m) (Moutenet et al., IEEE TIM 2024: polarized intensity P = m against
//! the unpolarized 2(1 − m) of Rayleigh's two orthogonal components). The maximum is found
//! semi-analytically: a point at meridian angle φ and angle β out of the meridian plane has
//! cos Γ_k = cos β cos(φ − ψ_k), so for each φ the product ∏(1 − c cos(φ − ψ_k)) is a quartic
//! in c = cos β ∈ [0, 1], maximised exactly (endpoints and the roots of its derivative); φ is
//! scanned every 0.1° and refined by golden-section search.
//!
//! Frame: ENU, compass azimuths (`sky.md` §1).

use super::berry::half_angle;
use glam::DVec3;
use num_complex::Complex64;

/// OpenSky's intensity-to-DOP map DOP_max m/(2 − m) of the QuEEN and asymmetric models
/// (m ∈ [0, 1]).
///
/// ```
/// use psns::sky::quartic::intensity_to_dop;
/// assert_eq!(intensity_to_dop(1.0, 1.0), 1.0);
/// assert_eq!(intensity_to_dop(1.0, 0.5), 0.5 / 1.5);
/// ```
#[inline(always)]
pub fn intensity_to_dop(dop_max: f64, m: f64) -> f64 {
    dop_max * m / (2.0 - m)
}

/// The four roots of the asymmetric field, as signed zenith angles ψ (degrees) along the sun's
/// azimuth: (Brewster, Babinet, Arago, fourth).
pub fn meridian_angles(
    sun_zenith_deg: f64,
    babinet_deg: f64,
    brewster_deg: f64,
    arago_deg: f64,
    fourth_deg: f64,
) -> [f64; 4] {
    [
        sun_zenith_deg + brewster_deg,
        sun_zenith_deg - babinet_deg,
        sun_zenith_deg - 180.0 + arago_deg,
        sun_zenith_deg - 180.0 - fourth_deg,
    ]
}

/// The asymmetric quartic field of one scene, cooked.
#[derive(Clone, Debug, PartialEq)]
pub struct QuarticField {
    /// (cos(ψ_k/2), sin(ψ_k/2)) of the four roots.
    roots: [(f64, f64); 4],
    /// e^{iA_s}.
    sun_dir: Complex64,
    /// 1 / max over the sphere of ∏ sin(Γ_k/2).
    inv_peak: f64,
}

/// m and the unit E-vector at one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuarticEval {
    /// Normalised modulus m ∈ [0, 1] (1 at the field's strongest point on the sphere).
    pub m: f64,
    /// Unit E-vector in ENU, ⟂ v; the chart's north at a neutral point.
    pub e: DVec3,
}

impl QuarticField {
    /// Cooks the field for the sun's azimuth and the four meridian angles ψ_k (degrees,
    /// [`meridian_angles`]).
    pub fn new(sun_azimuth_deg: f64, psi_deg: [f64; 4]) -> Self {
        let roots = psi_deg.map(|p| {
            let (s, c) = (0.5 * p.to_radians()).sin_cos();
            (c, s)
        });
        let (sa, ca) = sun_azimuth_deg.to_radians().sin_cos();
        let psi = psi_deg.map(f64::to_radians);
        QuarticField {
            roots,
            sun_dir: Complex64::new(ca, sa),
            inv_peak: 1.0 / peak_half_angle_product(psi),
        }
    }

    /// The largest ∏_k sin(Γ_k/2) over the sphere (the normalisation of m).
    pub fn peak(&self) -> f64 {
        1.0 / self.inv_peak
    }

    /// p(z) of the rotated chart coordinate z (the field up to a positive factor).
    #[inline(always)]
    fn p(&self, z: Complex64) -> Complex64 {
        let mut p = Complex64::new(-1.0, 0.0);
        for &(c, s) in &self.roots {
            p *= Complex64::new(c * z.re - s, c * z.im);
        }
        p
    }

    /// m and the E-vector for a unit ENU view vector `v` with v.z > −1 (any point but the
    /// nadir).
    #[inline]
    pub fn eval(&self, v: DVec3) -> QuarticEval {
        let k = 1.0 / (1.0 + v.z);
        let zeta = Complex64::new(v.y * k, v.x * k);
        let z = zeta * self.sun_dir.conj();
        let p = self.p(z);
        let r = p.norm();
        // ∏ sin(Γ_k/2) = |p| / (1 + |z|²)² and 1 + |z|² = 2/(1 + v_z)
        let opz = 1.0 + v.z;
        let m = (r * opz * opz * 0.25 * self.inv_peak).min(1.0);
        let (n, east) = super::berry::chart_basis(v);
        let (hx, hy) = half_angle(p, r);
        let h2 = hx * hx + hy * hy;
        if h2 <= 0.0 {
            return QuarticEval { m: 0.0, e: n };
        }
        let inv = 1.0 / h2.sqrt();
        let q = self.sun_dir * Complex64::new(hx * inv, hy * inv);
        QuarticEval {
            m,
            e: n * q.re + east * q.im,
        }
    }

    /// Chart AOP χ = A_s + ½ arg p in degrees, wrapped to (−90°, 90°] (reference form of
    /// [`Self::eval`]'s E-vector).
    pub fn chi_deg(&self, zeta: Complex64) -> f64 {
        let p = self.p(zeta * self.sun_dir.conj());
        crate::angle::wrap_pm90(self.sun_dir.arg().to_degrees() + 0.5 * p.arg().to_degrees())
    }
}

/// max over c ∈ [0, 1] of ∏_k (1 − c a_k): the endpoints and the stationary points of the
/// quartic, found by bisection of its derivative's sign changes on 32 sub-intervals.
fn max_over_c(a: [f64; 4]) -> f64 {
    // G(c) = ∏ (1 − c a_k) = Σ g_j c^j
    let mut g = [1.0, 0.0, 0.0, 0.0, 0.0];
    for &ak in &a {
        for j in (1..5).rev() {
            g[j] -= ak * g[j - 1];
        }
    }
    let val = |c: f64| (((g[4] * c + g[3]) * c + g[2]) * c + g[1]) * c + g[0];
    let der = |c: f64| ((4.0 * g[4] * c + 3.0 * g[3]) * c + 2.0 * g[2]) * c + g[1];
    let mut best = val(0.0).max(val(1.0));
    const N: usize = 32;
    let mut c0 = 0.0;
    let mut d0 = der(0.0);
    for i in 1..=N {
        let c1 = i as f64 / N as f64;
        let d1 = der(c1);
        if d0 > 0.0 && d1 <= 0.0 {
            // a maximum inside [c0, c1]
            let (mut lo, mut hi) = (c0, c1);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if der(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            best = best.max(val(0.5 * (lo + hi)));
        }
        (c0, d0) = (c1, d1);
    }
    best
}

/// H(φ) = max over the points at meridian angle φ of ∏ (1 − cos Γ_k) (= 16 ∏ sin²(Γ_k/2)).
fn h(phi: f64, psi: &[f64; 4]) -> f64 {
    max_over_c(psi.map(|p| (phi - p).cos()))
}

/// The largest ∏ sin(Γ_k/2) over the sphere for roots on one great circle at angles `psi`
/// (radians): a scan of the meridian angle every 0.1°, then golden-section refinement.
pub fn peak_half_angle_product(psi: [f64; 4]) -> f64 {
    use std::f64::consts::TAU;
    const STEPS: usize = 3600;
    let step = TAU / STEPS as f64;
    let (mut best_i, mut best) = (0, f64::MIN);
    for i in 0..STEPS {
        let v = h(i as f64 * step, &psi);
        if v > best {
            (best_i, best) = (i, v);
        }
    }
    // golden-section search on [φ − step, φ + step]
    let gr = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = ((best_i as f64 - 1.0) * step, (best_i as f64 + 1.0) * step);
    let mut x1 = b - gr * (b - a);
    let mut x2 = a + gr * (b - a);
    let (mut f1, mut f2) = (h(x1, &psi), h(x2, &psi));
    for _ in 0..80 {
        if f1 < f2 {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + gr * (b - a);
            f2 = h(x2, &psi);
        } else {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - gr * (b - a);
            f1 = h(x1, &psi);
        }
    }
    let hmax = best.max(f1).max(f2);
    0.25 * hmax.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::direction;
    use crate::sky::berry::BerryField;

    #[test]
    fn antipodal_roots_are_berrys_field() {
        // δ_Ar = δ_Br, δ_4 = δ_Ba: m = |w| and the same E-vector
        let (ts, az, ba, br) = (50.0, 200.0, 20.0, 35.0);
        let q = QuarticField::new(az, meridian_angles(ts, ba, br, br, ba));
        assert!((q.peak() - 0.25).abs() < 1e-12, "{}", q.peak());
        let b = BerryField::new(ts, az, ba, br);
        for &(z, a) in &[
            (0.0, 0.0),
            (15.0, 10.0),
            (45.0, 110.0),
            (70.0, 20.0),
            (89.0, 245.0),
        ] {
            let v = direction(z, a);
            let (qe, be) = (q.eval(v), b.eval(v));
            assert!((qe.m - be.abs_w).abs() < 1e-13, "{z} {a}");
            assert!(qe.e.dot(be.e).abs() > 1.0 - 1e-12, "{z} {a}");
        }
    }

    #[test]
    fn peak_matches_a_brute_force_scan() {
        let psi = meridian_angles(30.0, 25.0, 40.0, 10.0, 55.0).map(f64::to_radians);
        let q = QuarticField::new(0.0, psi.map(f64::to_degrees));
        let mut best = 0.0f64;
        for i in 0..=720 {
            for j in 0..1440 {
                let v = direction(i as f64 * 0.25, j as f64 * 0.25);
                if v.z <= -1.0 + 1e-12 {
                    continue;
                }
                let k = 1.0 / (1.0 + v.z);
                let z = Complex64::new(v.y * k, v.x * k);
                let opz = 1.0 + v.z;
                best = best.max(q.p(z).norm() * opz * opz * 0.25);
            }
        }
        assert!(best <= q.peak() * (1.0 + 1e-12));
        assert!(best > q.peak() * (1.0 - 1e-4), "{best} {}", q.peak());
        assert!(
            q.peak() > 0.25,
            "asymmetric roots raise the peak above Berry's 1/4"
        );
    }
}
