//! Wavelength curves of the pixel: quantum efficiency η(λ) of the bare (mono) pixel and pass-axis
//! transmission T∥(λ) of the on-chip wire grid (`docs/sensor.md`, "Spectral response").
//!
//! Both are evaluated at the band-pass centre λ_c, which is the sky model's wavelength, so
//! `--wavelength` changes the electron counts as a real sensor's response does, together with the
//! extinction ratio ER(λ) ([`super::polarizer::ErTable`]), the photon energy and the sky.
//!
//! **Sources and status.** Sony publishes the IMX250MZR response only as figures (the IMX250/253MZR
//! flyer; the camera makers' pages for the LUCID Phoenix PHX050S-P and the Teledyne FLIR Blackfly S
//! BFS-U3-51S5P reproduce them), and no numeric table was found. The tables below are therefore
//! \[assumed\] curves of the published *shape*, anchored to two published or specified numbers:
//!
//! * η: the 3.45 µm Pregius mono pixel peaks near 70 % around 540 nm (Basler, "About EMVA1288
//!   Reports for Color Sensors": QE 70 % at 545 nm for the mono IMX304, the same pixel as the
//!   IMX250; `sensor.md` §1: mono Pregius peak ≈ 0.65–0.72), falls to about half of that at
//!   380–400 nm and declines slowly toward the near infrared; scaled so that η(450 nm) = 0.60,
//!   the specification's value (`sensor.md` §5), which keeps the default camera's frames
//!   unchanged.
//! * T∥: an aluminium wire grid passes 0.85–0.9 of the light polarized across its wires in the
//!   green and red and less toward the blue, where the grid period approaches the wavelength (the
//!   same cause as the weak blue extinction ratio of the Montana State characterisation, 2020);
//!   T∥(450 nm) = 0.8, the specification's value.
//!
//! Replace either with a measured curve through `SensorConfig::qe` / `pass_transmission`
//! (`--sensor-set 'qe=[[400,0.45],[550,0.7],[700,0.47]]'`); a single number is a constant
//! (`--sensor-set qe=0.6`, what scene files written before the curves hold).

use crate::error::{check_range, Error, Result};
use serde::{Deserialize, Serialize};

/// η(λ) of the bare IMX250 pixel, `[λ_nm, η]`, 380..720 nm [assumed shape, see the module docs].
pub const QE_IMX250: [[f64; 2]; 19] = [
    [380.0, 0.33],
    [400.0, 0.45],
    [420.0, 0.53],
    [440.0, 0.58],
    [450.0, 0.60],
    [460.0, 0.62],
    [480.0, 0.655],
    [500.0, 0.685],
    [520.0, 0.70],
    [540.0, 0.70],
    [560.0, 0.69],
    [580.0, 0.67],
    [600.0, 0.645],
    [620.0, 0.615],
    [640.0, 0.58],
    [660.0, 0.545],
    [680.0, 0.51],
    [700.0, 0.47],
    [720.0, 0.43],
];

/// T∥(λ) of the IMX250MZR wire grid, `[λ_nm, T∥]`, 380..720 nm [assumed shape, see the module
/// docs].
pub const PASS_TRANSMISSION_IMX250MZR: [[f64; 2]; 13] = [
    [380.0, 0.62],
    [400.0, 0.68],
    [420.0, 0.73],
    [440.0, 0.78],
    [450.0, 0.80],
    [460.0, 0.815],
    [480.0, 0.835],
    [500.0, 0.85],
    [520.0, 0.86],
    [540.0, 0.865],
    [560.0, 0.87],
    [640.0, 0.87],
    [720.0, 0.87],
];

/// A quantity that may depend on wavelength: a constant, or a table interpolated linearly.
///
/// Serialized as a bare number or as a list of `[λ_nm, value]` pairs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Spectral {
    /// The same value at every wavelength.
    Constant(f64),
    /// `[λ_nm, value]` pairs, λ strictly increasing; linear in between, constant beyond the ends.
    Table(Vec<[f64; 2]>),
}

impl Spectral {
    /// The default η(λ) of the camera ([`QE_IMX250`]).
    pub fn imx250_qe() -> Self {
        Spectral::Table(QE_IMX250.to_vec())
    }

    /// The default T∥(λ) of the camera ([`PASS_TRANSMISSION_IMX250MZR`]).
    pub fn imx250mzr_pass_transmission() -> Self {
        Spectral::Table(PASS_TRANSMISSION_IMX250MZR.to_vec())
    }

    /// The value at `wavelength_nm`.
    ///
    /// ```
    /// use psns::sensor::spectral::Spectral;
    /// let qe = Spectral::imx250_qe();
    /// assert_eq!(qe.at(450.0), 0.60);
    /// assert!((qe.at(650.0) - 0.5625).abs() < 1e-12); // halfway between 640 and 660 nm
    /// assert_eq!(Spectral::Constant(0.6).at(700.0), 0.6);
    /// ```
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        match self {
            Spectral::Constant(v) => *v,
            Spectral::Table(t) => interpolate(t, wavelength_nm),
        }
    }

    /// Checks: values in `lo..hi`; a table is non-empty with wavelengths in 100..2000 nm,
    /// strictly increasing. `name` names the option in the message.
    pub fn validate(&self, name: &str, lo: f64, hi: f64) -> Result<()> {
        match self {
            Spectral::Constant(v) => {
                check_range(name, *v, lo, hi)?;
            }
            Spectral::Table(t) => {
                if t.is_empty() {
                    return Err(Error::Invalid(format!("the {name} table is empty")));
                }
                for (i, p) in t.iter().enumerate() {
                    check_range(&format!("{name} table wavelength"), p[0], 100.0, 2000.0)?;
                    check_range(name, p[1], lo, hi)?;
                    if i > 0 && p[0] <= t[i - 1][0] {
                        return Err(Error::Invalid(format!(
                            "{name} table wavelengths must increase (entry {i}: {} nm)",
                            p[0]
                        )));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Linear interpolation in `[x, y]` pairs sorted by x, constant beyond the ends; exactly the
/// tabulated y at a tabulated x. `points` must not be empty.
pub fn interpolate(points: &[[f64; 2]], x: f64) -> f64 {
    if x <= points[0][0] {
        return points[0][1];
    }
    for w in points.windows(2) {
        if x <= w[1][0] {
            let t = (x - w[0][0]) / (w[1][0] - w[0][0]);
            return w[0][1] + t * (w[1][1] - w[0][1]);
        }
    }
    points[points.len() - 1][1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_cover_the_sensor_range_and_validate() {
        for (t, lo, hi) in [
            (&QE_IMX250[..], 0.3, 0.72),
            (&PASS_TRANSMISSION_IMX250MZR[..], 0.6, 0.9),
        ] {
            assert_eq!(t[0][0], 380.0);
            assert_eq!(t[t.len() - 1][0], 720.0);
            assert!(t.iter().all(|p| p[1] >= lo && p[1] <= hi));
            Spectral::Table(t.to_vec()).validate("x", 0.0, 1.0).unwrap();
        }
        let bad = Spectral::Table(vec![[500.0, 0.5], [400.0, 0.5]]);
        assert!(bad.validate("qe", 0.0, 1.0).is_err());
        let e = Spectral::Constant(1.5)
            .validate("qe", 0.0, 1.0)
            .unwrap_err();
        assert!(e.to_string().contains("qe") && e.is_usage(), "{e}");
        assert!(Spectral::Table(vec![]).validate("qe", 0.0, 1.0).is_err());
    }

    #[test]
    fn serde_number_or_table() {
        let c: Spectral = serde_json::from_str("0.6").unwrap();
        assert_eq!(c, Spectral::Constant(0.6));
        let t: Spectral = serde_json::from_str("[[400, 0.5], [700, 0.4]]").unwrap();
        assert_eq!(t, Spectral::Table(vec![[400.0, 0.5], [700.0, 0.4]]));
        assert_eq!(t.at(550.0), 0.45);
    }
}
