//! Hosek–Wilkie spectral sky model v1.4a (Hošek & Wilkie 2012, 2013), with the solar disc.
//!
//! Coefficients ship inside the crate (`data/hosek-wilkie`, 3-clause BSD, © Lukas Hosek and
//! Alexander Wilkie; the notice is in `data/hosek-wilkie/LICENSE`).

use crate::error::Result;

/// Angular radius of the solar disc used by the model, radians (0.255°).
pub const SUN_RADIUS_RAD: f64 = 0.255 * std::f64::consts::PI / 180.0;

/// The model cooked for one (turbidity, albedo, sun elevation, wavelength).
#[derive(Clone, Debug)]
pub struct HosekWilkie {}

impl HosekWilkie {
    /// Cooks the two channels around `wavelength_nm` (320..720).
    pub fn new(
        turbidity: f64,
        albedo: f64,
        sun_elevation_rad: f64,
        wavelength_nm: f64,
    ) -> Result<Self> {
        let _ = (turbidity, albedo, sun_elevation_rad, wavelength_nm);
        todo!()
    }

    /// Sky radiance (W m⁻² sr⁻¹ nm⁻¹) at view zenith θ and scattering angle γ (radians); cos θ ≥ 0.
    pub fn radiance(&self, theta_rad: f64, gamma_rad: f64) -> f64 {
        let _ = (theta_rad, gamma_rad);
        todo!()
    }

    /// Radiance of the solar disc (limb-darkened) at angle γ from the sun's centre; 0 outside it.
    pub fn sun_radiance(&self, gamma_rad: f64) -> f64 {
        let _ = gamma_rad;
        todo!()
    }
}
