//! Single-scattering Rayleigh polarization: the baseline of the authors' earlier hypothetical
//! polarization camera (Liang & Bai, Bioinspir. Biomim. 2020; `sky.md` §6).
//!
//! Physics: light singly scattered by particles much smaller than the wavelength is polarized
//! perpendicular to the scattering plane (the plane through the sun, the observer and the view
//! direction), with DOP = DOP_max sin²γ / (1 + cos²γ), γ the scattering angle. The E-vector is
//! therefore ∝ s × v (s the unit sun vector, v the unit view vector). The radiance of the sky
//! stays Hosek–Wilkie; only polarization comes from this model.
//!
//! Frame: ENU (x east, y north, z up).

use glam::DVec3;

/// Rayleigh DOP for cos γ: DOP_max (1 − cos²γ)/(1 + cos²γ).
///
/// ```
/// // fully polarized 90° from the sun, unpolarized at the sun
/// assert_eq!(psns::sky::rayleigh::dop(1.0, 0.0), 1.0);
/// assert_eq!(psns::sky::rayleigh::dop(1.0, 1.0), 0.0);
/// ```
#[inline]
pub fn dop(dop_max: f64, cos_gamma: f64) -> f64 {
    let c2 = cos_gamma * cos_gamma;
    dop_max * (1.0 - c2) / (1.0 + c2)
}

/// Unit E-vector ∝ s × v in ENU, or `None` where s ∥ v (at the sun and the anti-sun, where the
/// DOP is 0 and the AOP undefined).
#[inline]
pub fn e_vector(sun: DVec3, v: DVec3) -> Option<DVec3> {
    let c = sun.cross(v);
    let n2 = c.length_squared();
    if n2 > 0.0 {
        Some(c / n2.sqrt())
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dop_formula_against_angle_form() {
        for i in 0..=180 {
            let g = (i as f64).to_radians();
            let want = 0.7 * g.sin().powi(2) / (1.0 + g.cos().powi(2));
            assert!((dop(0.7, g.cos()) - want).abs() < 1e-15);
        }
    }
}
