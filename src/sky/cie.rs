//! CIE standard general skies (CIE S 011/E:2003, ISO 15469:2004): relative sky luminance for 15
//! sky types from overcast to cloudless.
//!
//! Physics: the luminance of a sky element at zenith angle Z and angular distance χ from the
//! sun, relative to the zenith, is
//!
//! L/L_z = φ(Z) f(χ) / (φ(0) f(Z_s)),
//!
//! with the gradation φ(Z) = 1 + a exp(b / cos Z) (φ(90°) = 1) and the scattering indicatrix
//! f(χ) = 1 + c [exp(dχ) − exp(dπ/2)] + e cos²χ. The standard combines six gradation groups
//! (a, b) and six indicatrix groups (c, d, e) into the 15 types of [`CIE_TYPES`]: 1–5 overcast
//! (the sun hidden), 6–10 partly cloudy, 11–15 cloudless. At the zenith L/L_z = 1 for every type.
//!
//! psns renders radiance in W m⁻² sr⁻¹ nm⁻¹, and the CIE skies give only ratios, so a CIE sky
//! takes its zenith radiance from the Hosek–Wilkie sky of the same sun, turbidity, albedo and
//! wavelength: L(Z, χ) = L_HW(zenith) · L/L_z. The polarization model is chosen separately.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// CIE S 011 parameters of one standard sky type: gradation (a, b), indicatrix (c, d, e).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CieParams {
    /// Gradation a.
    pub a: f64,
    /// Gradation b.
    pub b: f64,
    /// Indicatrix c.
    pub c: f64,
    /// Indicatrix d.
    pub d: f64,
    /// Indicatrix e.
    pub e: f64,
}

const fn p(a: f64, b: f64, c: f64, d: f64, e: f64) -> CieParams {
    CieParams { a, b, c, d, e }
}

/// The 15 standard skies of CIE S 011/E:2003, Table 1 (type N at index N − 1): gradation groups
/// I (4.0, −0.70), II (1.1, −0.8), III (0, −1), IV (−1, −0.55), V (−1, −0.32), VI (−1, −0.15);
/// indicatrix groups 1 (0, −1, 0), 2 (2, −1.5, 0.15), 3 (5, −2.5, 0.30), 4 (10, −3, 0.45),
/// 5 (16, −3, 0.30), 6 (24, −2.8, 0.15).
pub const CIE_TYPES: [CieParams; 15] = [
    p(4.0, -0.70, 0.0, -1.0, 0.00), // 1: overcast, steep gradation, azimuthal uniformity (CIE standard overcast)
    p(4.0, -0.70, 2.0, -1.5, 0.15), // 2: overcast, steep gradation, slight brightening toward the sun
    p(1.1, -0.8, 0.0, -1.0, 0.00),  // 3: overcast, moderate gradation, azimuthal uniformity
    p(1.1, -0.8, 2.0, -1.5, 0.15), // 4: overcast, moderate gradation, slight brightening toward the sun
    p(0.0, -1.0, 0.0, -1.0, 0.00), // 5: sky of uniform luminance
    p(0.0, -1.0, 2.0, -1.5, 0.15), // 6: partly cloudy, no gradation toward the zenith, slight brightening toward the sun
    p(0.0, -1.0, 5.0, -2.5, 0.30), // 7: partly cloudy, no gradation, brighter circumsolar region
    p(0.0, -1.0, 10.0, -3.0, 0.45), // 8: partly cloudy, no gradation, distinct solar corona
    p(-1.0, -0.55, 2.0, -1.5, 0.15), // 9: partly cloudy, the obscured sun
    p(-1.0, -0.55, 5.0, -2.5, 0.30), // 10: partly cloudy, brighter circumsolar region
    p(-1.0, -0.55, 10.0, -3.0, 0.45), // 11: white-blue sky, distinct solar corona
    p(-1.0, -0.32, 10.0, -3.0, 0.45), // 12: CIE standard clear sky, low luminance turbidity
    p(-1.0, -0.32, 16.0, -3.0, 0.30), // 13: CIE standard clear sky, polluted atmosphere
    p(-1.0, -0.15, 16.0, -3.0, 0.30), // 14: cloudless turbid sky, broad solar corona
    p(-1.0, -0.15, 24.0, -2.8, 0.15), // 15: white-blue turbid sky, broad solar corona
];

/// Which sky radiance a scene uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Radiance {
    /// Hosek–Wilkie spectral model v1.4a (default).
    #[default]
    Hosek,
    /// CIE standard general sky of type 1..15, scaled to the Hosek–Wilkie zenith radiance.
    Cie(u8),
}

impl std::str::FromStr for Radiance {
    type Err = Error;
    /// `hosek` or `cie:N` with N = 1..15.
    ///
    /// ```
    /// use psns::sky::cie::Radiance;
    /// assert_eq!("cie:12".parse::<Radiance>().unwrap(), Radiance::Cie(12));
    /// assert_eq!("hosek".parse::<Radiance>().unwrap(), Radiance::Hosek);
    /// assert!("cie:16".parse::<Radiance>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim().to_ascii_lowercase();
        if t == "hosek" {
            return Ok(Radiance::Hosek);
        }
        let bad = || Error::OutOfRange {
            name: "radiance".into(),
            value: s.into(),
            allowed: "hosek or cie:N with N = 1..15 (CIE S 011 standard skies)".into(),
        };
        let n: u8 = t
            .strip_prefix("cie:")
            .ok_or_else(bad)?
            .trim()
            .parse()
            .map_err(|_| bad())?;
        if (1..=15).contains(&n) {
            Ok(Radiance::Cie(n))
        } else {
            Err(bad())
        }
    }
}

impl std::fmt::Display for Radiance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Radiance::Hosek => f.write_str("hosek"),
            Radiance::Cie(n) => write!(f, "cie:{n}"),
        }
    }
}

impl TryFrom<String> for Radiance {
    type Error = Error;
    fn try_from(s: String) -> Result<Self> {
        s.parse()
    }
}

impl From<Radiance> for String {
    fn from(r: Radiance) -> String {
        r.to_string()
    }
}

/// A CIE standard sky cooked for one sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CieSky {
    /// The type's parameters.
    pub params: CieParams,
    /// The type, 1..15.
    pub sky_type: u8,
    /// 1 / (φ(0) f(Z_s)).
    inv_norm: f64,
}

impl CieSky {
    /// Cooks sky type `sky_type` (1..15) for the sun at zenith angle `sun_zenith_rad`.
    pub fn new(sky_type: u8, sun_zenith_rad: f64) -> Result<Self> {
        if !(1..=15).contains(&sky_type) {
            return Err(Error::range("cie sky type", sky_type as f64, "1..15"));
        }
        let params = CIE_TYPES[sky_type as usize - 1];
        let norm = gradation(&params, 1.0) * indicatrix(&params, sun_zenith_rad);
        Ok(CieSky {
            params,
            sky_type,
            inv_norm: 1.0 / norm,
        })
    }

    /// L/L_z at view zenith cos Z (> 0) and angular distance χ from the sun (radians).
    #[inline]
    pub fn relative(&self, cos_zenith: f64, chi: f64) -> f64 {
        gradation(&self.params, cos_zenith) * indicatrix(&self.params, chi) * self.inv_norm
    }

    /// Overcast types (1–5): the sun's disc is hidden.
    pub fn overcast(&self) -> bool {
        self.sky_type <= 5
    }
}

/// Gradation φ(Z) = 1 + a exp(b / cos Z); 1 at the horizon (cos Z → 0⁺, b < 0).
#[inline]
pub fn gradation(p: &CieParams, cos_zenith: f64) -> f64 {
    if cos_zenith <= 0.0 {
        return 1.0;
    }
    1.0 + p.a * (p.b / cos_zenith).exp()
}

/// Scattering indicatrix f(χ) = 1 + c [exp(dχ) − exp(dπ/2)] + e cos²χ, χ in radians.
#[inline]
pub fn indicatrix(p: &CieParams, chi: f64) -> f64 {
    let c = chi.cos();
    1.0 + p.c * ((p.d * chi).exp() - (p.d * std::f64::consts::FRAC_PI_2).exp()) + p.e * c * c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenith_is_one_for_every_type_and_sun() {
        for n in 1..=15 {
            for zs in [0.0f64, 20.0, 45.0, 80.0] {
                let s = CieSky::new(n, zs.to_radians()).unwrap();
                let r = s.relative(1.0, zs.to_radians());
                assert!((r - 1.0).abs() < 1e-14, "type {n}, sun {zs}: {r}");
            }
        }
        assert!(CieSky::new(0, 0.0).is_err() && CieSky::new(16, 0.0).is_err());
    }

    #[test]
    fn radiance_round_trips_through_text() {
        for r in [Radiance::Hosek, Radiance::Cie(1), Radiance::Cie(15)] {
            assert_eq!(r.to_string().parse::<Radiance>().unwrap(), r);
        }
        for bad in ["cie:0", "cie:x", "cie", "perez", "cie:3.5"] {
            assert!(bad.parse::<Radiance>().is_err(), "{bad}");
        }
    }
}
