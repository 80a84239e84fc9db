//! Rayleigh scattering by anisotropic molecules: the depolarized Rayleigh sky (Wu et al. 2014).
//!
//! Physics (Wu, Zhang, Fan & Gao, Acta Phys. Sin. 63:114201, 2014, eqs. (3)–(5)): an air
//! molecule is not isotropic, so its induced dipole is not exactly parallel to the incident
//! field and some light stays unpolarized even 90° from the sun. With the molecular
//! depolarization ratio D, the King factor K = (1 − D)/(1 + D/2) and a = 4(1 − K)/(3K), the
//! single-scattering DOP of unpolarized sunlight is
//!
//! DOP(γ) = sin²γ / (1 + cos²γ + a),
//!
//! whose maximum (γ = 90°) is 1/(1 + a) = (1 − D)/(1 + D) (a = 2D/(1 − D)). The E-vector is
//! Rayleigh's, ∝ s × v ([`super::rayleigh`]). Default D = 0.0279, the dry-air value of
//! Bodhaine, Wood, Dutton & Slusser (J. Atmos. Ocean. Technol. 16:1854, 1999): peak 0.9457.

/// Bodhaine et al.'s dry-air depolarization ratio, the default.
pub const DEFAULT_DEPOLARIZATION_RATIO: f64 = 0.0279;
/// Largest depolarization ratio accepted (the range over which Wu et al. validate the phase
/// matrix).
pub const MAX_DEPOLARIZATION_RATIO: f64 = 0.5;

/// The anisotropy term a = 4(1 − K)/(3K), K = (1 − D)/(1 + D/2), of depolarization ratio D.
///
/// ```
/// use psns::sky::depolarized::anisotropy;
/// assert_eq!(anisotropy(0.0), 0.0);
/// // a = 2D/(1 − D)
/// assert!((anisotropy(0.0279) - 2.0 * 0.0279 / (1.0 - 0.0279)).abs() < 1e-15);
/// ```
pub fn anisotropy(depolarization_ratio: f64) -> f64 {
    let k = (1.0 - depolarization_ratio) / (1.0 + 0.5 * depolarization_ratio);
    4.0 * (1.0 - k) / (3.0 * k)
}

/// DOP_max sin²γ/(1 + cos²γ + a) from sin²γ and cos γ (the form the sky's per-pixel path uses:
/// sin²γ comes from |s × v|²).
#[inline(always)]
pub fn dop_sin2(dop_max: f64, a: f64, sin_g2: f64, cos_g: f64) -> f64 {
    dop_max * sin_g2 / (sin_g2 + 2.0 * cos_g * cos_g + a)
}

/// The largest DOP of the model, at γ = 90°: DOP_max/(1 + a) = DOP_max (1 − D)/(1 + D).
///
/// ```
/// let p = psns::sky::depolarized::peak_dop(1.0, 0.0279);
/// assert!((p - 0.945714).abs() < 1e-6);
/// ```
pub fn peak_dop(dop_max: f64, depolarization_ratio: f64) -> f64 {
    dop_max / (1.0 + anisotropy(depolarization_ratio))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduces_to_rayleigh_at_zero_ratio() {
        for i in 0..=180 {
            let g = (i as f64).to_radians();
            let (s, c) = g.sin_cos();
            let r = super::super::rayleigh::dop(0.8, c);
            assert!((dop_sin2(0.8, 0.0, s * s, c) - r).abs() < 1e-15);
        }
    }

    #[test]
    fn peak_is_one_minus_d_over_one_plus_d() {
        for d in [0.0, 0.01, 0.0279, 0.1, 0.5] {
            let want = (1.0 - d) / (1.0 + d);
            assert!((peak_dop(1.0, d) - want).abs() < 1e-15);
            assert!((dop_sin2(1.0, anisotropy(d), 1.0, 0.0) - want).abs() < 1e-15);
        }
    }
}
