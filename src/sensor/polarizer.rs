//! Per-pixel partial polarizer (`sensor.md` §4).
//!
//! Pixel k with pass axis θ_k = θ_k⁰ + δ_k (δ_k a fixed-pattern orientation error), extinction
//! ratio ER and D = (ER − 1)/(ER + 1) reads
//!
//!   I_k = g_k · ½ T∥ (1 + 1/ER) · [S0 + D (S1 cos 2θ_k + S2 sin 2θ_k)],
//!
//! T∥ the pass-axis transmission, g_k the PRNU gain (applied in the electron domain). An ideal
//! polarizer (ER = ∞, D = 1) gives ½ T∥ (S0 + S1 cos 2θ + S2 sin 2θ). ER(λ) is a table
//! interpolated linearly in λ (shape after the Montana State DoFP characterisation, 2020: weak in
//! the blue, peak near 532 nm).

use crate::error::{check_range, Error, Result};
use serde::{Deserialize, Serialize};

/// Extinction ratio against wavelength, `[λ_nm, ER]` pairs sorted by λ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErTable(pub Vec<[f64; 2]>);

impl Default for ErTable {
    /// The table of `sensor.md` §4.
    fn default() -> Self {
        ErTable(vec![
            [400.0, 15.0],
            [450.0, 60.0],
            [500.0, 200.0],
            [532.0, 320.0],
            [600.0, 250.0],
            [650.0, 180.0],
            [700.0, 120.0],
        ])
    }
}

impl ErTable {
    /// Checks: at least one point, λ strictly increasing, ER in 1..1e6.
    pub fn validate(&self) -> Result<()> {
        if self.0.is_empty() {
            return Err(Error::Invalid("extinction-ratio table is empty".into()));
        }
        for (i, p) in self.0.iter().enumerate() {
            check_range("er table wavelength", p[0], 100.0, 2000.0)?;
            check_range("extinction ratio", p[1], 1.0, 1e6)?;
            if i > 0 && p[0] <= self.0[i - 1][0] {
                return Err(Error::Invalid(format!(
                    "extinction-ratio table wavelengths must increase (entry {i}: {} nm)",
                    p[0]
                )));
            }
        }
        Ok(())
    }

    /// ER at `wavelength_nm`, linear interpolation, constant beyond the ends.
    ///
    /// ```
    /// let t = psns::sensor::polarizer::ErTable::default();
    /// assert_eq!(t.at(450.0), 60.0);
    /// assert_eq!(t.at(516.0), 260.0);
    /// assert_eq!(t.at(300.0), 15.0);
    /// ```
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        super::spectral::interpolate(&self.0, wavelength_nm)
    }
}

/// Diattenuation D = (ER − 1)/(ER + 1); ER = ∞ gives 1.
#[inline]
pub fn diattenuation(er: f64) -> f64 {
    if er.is_infinite() {
        1.0
    } else {
        (er - 1.0) / (er + 1.0)
    }
}

/// Partial-polarizer coefficients (a, b) with I = a · [S0 + b (S1 cos 2θ + S2 sin 2θ)]:
/// a = ½ T∥ (1 + 1/ER), b = D.
#[inline]
pub fn coefficients(pass_transmission: f64, er: f64) -> (f64, f64) {
    (
        0.5 * pass_transmission * (1.0 + 1.0 / er),
        diattenuation(er),
    )
}

/// I_k without PRNU for Stokes (s0, s1, s2) and pass axis given as (cos 2θ, sin 2θ); clamped at 0
/// so slightly unphysical input (DoLP > 1 by rounding) cannot give negative light.
#[inline]
pub fn reading(s0: f64, s1: f64, s2: f64, cos2: f64, sin2: f64, a: f64, b: f64) -> f64 {
    (a * (s0 + b * (s1 * cos2 + s2 * sin2))).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d_at_450() {
        let d = diattenuation(ErTable::default().at(450.0));
        assert!((d - 0.967).abs() < 5e-4, "{d}");
        let (a, b) = coefficients(0.8, f64::INFINITY);
        assert_eq!((a, b), (0.4, 1.0));
        // fully polarized light along the axis: ½T∥(1+1/ER)(1+D) = T∥
        let (a, b) = coefficients(0.8, 60.0);
        assert!((a * (1.0 + b) - 0.8).abs() < 1e-12);
        // crossed: ½T∥(1+1/ER)(1−D) = T∥/ER
        assert!((a * (1.0 - b) - 0.8 / 60.0).abs() < 1e-12);
        assert!(ErTable(vec![[500.0, 10.0], [400.0, 20.0]])
            .validate()
            .is_err());
    }
}
