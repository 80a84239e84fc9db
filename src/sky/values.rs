//! The sky's values for one direction as `psns sky` and Python's `psns.sky` report them.

use super::{aop_chart_deg, aop_meridian_deg, direction, Sky};

/// What the sky gives for one direction (zenith, compass azimuth).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyValues {
    /// Angle from the sun, degrees.
    pub gamma_deg: f64,
    /// Radiance, W m⁻² sr⁻¹ nm⁻¹ (0 below the horizon).
    pub radiance: f64,
    /// Degree of polarization (0 below the horizon).
    pub dop: f64,
    /// AOP from the local meridian, degrees (0 below the horizon and where unpolarized).
    pub aop_meridian_deg: f64,
    /// AOP from north, degrees (0 below the horizon and where unpolarized).
    pub aop_north_deg: f64,
}

impl Sky {
    /// The values for the direction at `zenith_deg` and compass `azimuth_deg`: angle from the
    /// sun, radiance, DOP, AOP from the meridian and from north; zero below the horizon and
    /// where the sky is unpolarized.
    pub fn values(&self, zenith_deg: f64, azimuth_deg: f64) -> SkyValues {
        let v = direction(zenith_deg, azimuth_deg);
        let s = self.sample(v);
        let (am, an) = if s.valid && s.dop > 0.0 {
            (aop_meridian_deg(v, s.e), aop_chart_deg(v, s.e))
        } else {
            (0.0, 0.0)
        };
        let gamma = v
            .dot(self.sun().vector())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        SkyValues {
            gamma_deg: gamma,
            radiance: s.radiance,
            dop: s.dop,
            aop_meridian_deg: am,
            aop_north_deg: an,
        }
    }
}
