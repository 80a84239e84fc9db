//! Optics and photon budget (`sensor.md` §3, §5).
//!
//! Irradiance on a pixel behind a lens of f-number N, for scene radiance L (W m⁻² sr⁻¹ nm⁻¹):
//! E = π τ_L T_F RI / (4N²) · L · Δλ (the camera equation, small-angle form, with the field
//! falloff carried entirely by the relative illumination RI). Photons per second on a pixel of area
//! A_pix: E · A_pix · λ_c / (hc). The band-pass filter is rectangular, centred on λ_c with width Δλ
//! and in-band transmission T_F; the radiance enters as L(λ_c)·Δλ.
//!
//! Relative illumination RI(ϕ) of the field angle ϕ: cos^n ϕ (default n = 1.5, corner ≈ 0.45 for
//! the 4 mm lens on the 2/3" array; cos⁴ is the thin-lens limit), or the lensfun PA polynomial
//! V(r) = 1 + k₁r² + k₂r⁴ + k₃r⁶ with r normalised to the half-diagonal. The field angle is the
//! projection's ([`crate::camera::Projection`]): for a fisheye ϕ of a pixel at image radius r is
//! the inverse of r(ϕ), not atan(r/f), and RI is 0 outside the image circle (`camera.md` §3).

use crate::camera::Intrinsics;
use crate::error::{check_range, Error, Result};
use serde::{Deserialize, Serialize};

/// Planck constant, J s.
pub const PLANCK: f64 = 6.626_070_15e-34;
/// Speed of light, m/s.
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// Relative illumination (vignetting) model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum RelativeIllumination {
    /// cos^n of the field angle (default n = 1.5).
    CosPower {
        /// Exponent n, 0..8.
        n: f64,
    },
    /// lensfun PA model 1 + k₁r² + k₂r⁴ + k₃r⁶, r = distance from the principal point over the
    /// half-diagonal; clamped to [0, 1].
    Polynomial {
        /// k₁.
        k1: f64,
        /// k₂.
        k2: f64,
        /// k₃.
        k3: f64,
    },
    /// No falloff.
    None,
}

impl Default for RelativeIllumination {
    fn default() -> Self {
        RelativeIllumination::CosPower { n: 1.5 }
    }
}

impl RelativeIllumination {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        match *self {
            RelativeIllumination::CosPower { n } => {
                check_range("ri cos power", n, 0.0, 8.0)?;
            }
            RelativeIllumination::Polynomial { k1, k2, k3 } => {
                for (name, k) in [("ri k1", k1), ("ri k2", k2), ("ri k3", k3)] {
                    check_range(name, k, -10.0, 10.0)?;
                }
            }
            RelativeIllumination::None => {}
        }
        Ok(())
    }

    /// RI at the pixel centre (col, row), in [0, 1].
    #[inline]
    pub fn factor(&self, intr: &Intrinsics, col: f64, row: f64) -> f64 {
        let (c0, r0) = intr.principal();
        let (x, y) = (col - c0, row - r0);
        match *self {
            RelativeIllumination::CosPower { n } => {
                let c = if intr.projection == crate::camera::Projection::Rectilinear {
                    rect_cos(intr.focal_px(), x, y)
                } else {
                    // the field angle of the projection; 0 outside a fisheye's image circle
                    match intr.ray(col, row) {
                        Some(d) => (d.z / d.length()).max(0.0),
                        None => return 0.0,
                    }
                };
                cos_power(c, n)
            }
            RelativeIllumination::Polynomial { k1, k2, k3 } => {
                let hd2 = 0.25 * ((intr.width * intr.width + intr.height * intr.height) as f64);
                let r2 = (x * x + y * y) / hd2;
                (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))).clamp(0.0, 1.0)
            }
            RelativeIllumination::None => 1.0,
        }
    }

    /// RI map of the whole frame, row-major.
    pub fn map(&self, intr: &Intrinsics) -> Vec<f32> {
        use rayon::prelude::*;
        let w = intr.width;
        let mut out = vec![0f32; w * intr.height];
        // the rectilinear cos^1.5 and cos^4 as a plain loop the compiler vectorises (the
        // functions `factor` uses, so the same bits); the others pixel by pixel
        let rect = intr.projection == crate::camera::Projection::Rectilinear;
        let cos_pow = match *self {
            RelativeIllumination::CosPower { n } if rect && (n == 1.5 || n == 4.0) => Some(n),
            _ => None,
        };
        let (c0, r0) = intr.principal();
        let f = intr.focal_px();
        out.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(r, row)| match cos_pow {
                Some(n) => {
                    let y = r as f64 - r0;
                    for (c, v) in row.iter_mut().enumerate() {
                        *v = cos_power(rect_cos(f, c as f64 - c0, y), n) as f32;
                    }
                }
                None => {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v = self.factor(intr, c as f64, r as f64) as f32;
                    }
                }
            });
        out
    }
}

/// cos ϕ of the rectilinear field angle at (x, y) pixels from the principal point, focal length
/// `f` in pixels.
#[inline(always)]
fn rect_cos(f: f64, x: f64, y: f64) -> f64 {
    f / (x * x + y * y + f * f).sqrt()
}

/// cⁿ, without a `powf` for the common n = 1.5 and 4 (so the map's loop vectorises).
#[inline(always)]
fn cos_power(c: f64, n: f64) -> f64 {
    if n == 1.5 {
        c * c.sqrt()
    } else if n == 4.0 {
        (c * c) * (c * c)
    } else {
        c.powf(n)
    }
}

/// Photons per second reaching one on-axis pixel (RI = 1, before the polarizer) per unit
/// spectral radiance (1 W m⁻² sr⁻¹ nm⁻¹): π τ_L T_F / (4N²) · A_pix · Δλ · λ_c/(hc).
///
/// ```
/// // sensor.md §5: 1.72e8 photons/s for f/2, τ_L = T_F = 0.9, 3.45 µm, 450/40 nm
/// let p = psns::sensor::optics::photon_rate_per_radiance(2.0, 0.9, 0.9, 40.0, 450.0, 3.45).unwrap();
/// assert!((p / 1.72e8 - 1.0).abs() < 0.005);
/// ```
pub fn photon_rate_per_radiance(
    f_number: f64,
    lens_transmission: f64,
    filter_transmission: f64,
    filter_width_nm: f64,
    wavelength_nm: f64,
    pixel_pitch_um: f64,
) -> Result<f64> {
    if !(f_number.is_finite()
        && f_number > 0.0
        && pixel_pitch_um.is_finite()
        && pixel_pitch_um > 0.0)
    {
        return Err(Error::Invalid(format!(
            "f-number {f_number} and pixel pitch {pixel_pitch_um} um must be > 0"
        )));
    }
    let a_pix = (pixel_pitch_um * 1e-6).powi(2);
    let photon_per_joule = wavelength_nm * 1e-9 / (PLANCK * SPEED_OF_LIGHT);
    Ok(
        std::f64::consts::PI * lens_transmission * filter_transmission
            / (4.0 * f_number * f_number)
            * a_pix
            * filter_width_nm
            * photon_per_joule,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_ri_matches_spec() {
        let intr = Intrinsics::default();
        let ri = RelativeIllumination::default();
        let corner = ri.factor(&intr, 0.0, 0.0);
        assert!((corner - 0.45).abs() < 0.01, "corner {corner}");
        let c4 = RelativeIllumination::CosPower { n: 4.0 }.factor(&intr, 0.0, 0.0);
        assert!((c4 - 0.119).abs() < 0.002, "cos4 corner {c4}");
        let centre = ri.factor(&intr, 1223.5, 1023.5);
        assert!((centre - 1.0).abs() < 1e-12);
        let poly = RelativeIllumination::Polynomial {
            k1: -0.5,
            k2: 0.0,
            k3: 0.0,
        };
        assert!((poly.factor(&intr, 0.0, 0.0) - 0.5).abs() < 1e-3);
        assert!(RelativeIllumination::CosPower { n: 9.0 }
            .validate()
            .is_err());
    }

    /// `map` gives `factor`'s value at every pixel, bit for bit: the vectorised rectilinear
    /// cos-power loop (n = 1.5 and 4, principal point off centre) and the per-pixel others.
    #[test]
    fn map_is_factor_at_every_pixel() {
        use crate::camera::Projection;
        let mut intr = Intrinsics {
            width: 61,
            height: 37,
            principal_point: Some([27.25, 20.5]),
            ..Intrinsics::default()
        };
        intr.focal_length_mm = 0.2;
        let cases = [
            (
                RelativeIllumination::CosPower { n: 1.5 },
                Projection::Rectilinear,
            ),
            (
                RelativeIllumination::CosPower { n: 4.0 },
                Projection::Rectilinear,
            ),
            (
                RelativeIllumination::CosPower { n: 2.0 },
                Projection::Rectilinear,
            ),
            (
                RelativeIllumination::CosPower { n: 1.5 },
                Projection::Equidistant,
            ),
            (
                RelativeIllumination::Polynomial {
                    k1: -0.3,
                    k2: 0.1,
                    k3: 0.0,
                },
                Projection::Rectilinear,
            ),
        ];
        for (ri, p) in cases {
            intr.projection = p;
            let m = ri.map(&intr);
            for r in 0..intr.height {
                for c in 0..intr.width {
                    let want = ri.factor(&intr, c as f64, r as f64) as f32;
                    assert_eq!(
                        m[r * intr.width + c].to_bits(),
                        want.to_bits(),
                        "{ri:?} {p:?}"
                    );
                }
            }
            // the corners are well below 1, so the test sees the falloff
            assert!(m[0] < 0.9, "{ri:?} {p:?}: {}", m[0]);
        }
    }

    /// RI takes the projection's field angle: 300 px off axis behind a 1.8 mm lens (ρ = 0.575)
    /// the field angle is 29.899° rectilinear, 32.945° equidistant, 35.100° orthographic (by
    /// hand: atan ρ, ρ, asin ρ), so cos^1.5 is 0.80716, 0.76876, 0.74003; outside a fisheye's
    /// image circle RI is 0.
    #[test]
    fn ri_uses_the_projections_field_angle() {
        use crate::camera::Projection;
        for (p, want) in [
            (Projection::Rectilinear, 0.807_157),
            (Projection::Equidistant, 0.768_763),
            (Projection::Orthographic, 0.740_035),
        ] {
            let intr = Intrinsics {
                projection: p,
                focal_length_mm: 1.8,
                ..Intrinsics::default()
            };
            let (c0, r0) = intr.principal();
            let ri = RelativeIllumination::default().factor(&intr, c0 + 300.0, r0);
            assert!((ri - want).abs() < 1e-5, "{p}: {ri}, by hand {want}");
            if p != Projection::Rectilinear {
                let outside = RelativeIllumination::default().factor(&intr, 0.0, 0.0);
                assert_eq!(outside, 0.0, "{p}");
            }
        }
    }
}
