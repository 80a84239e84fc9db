//! The sensor's configuration: exposure control, the switchable stages and [`SensorConfig`]
//! with its checks.

use super::*;

/// Exposure control.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "lowercase")]
pub enum Exposure {
    /// Fixed exposure time in µs, 20 µs..10 s.
    Fixed {
        /// Exposure time, µs.
        us: f64,
    },
    /// t = fraction · FWC / P_percentile(μ̇) over sky pixels (S0 > 0), clamped to 20 µs..10 s and
    /// quantised to the line time (`sensor.md` §5).
    Auto {
        /// Percentile p of the noise-free electron-rate image, (0, 100] (default 99).
        percentile: f64,
        /// Target fraction f of full well, (0, 1] (default 0.70).
        fraction: f64,
    },
}

impl Default for Exposure {
    fn default() -> Self {
        Exposure::Fixed { us: 1000.0 }
    }
}

/// The exposure a frame gets ([`Sensor::exposure_for`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureChoice {
    /// Exposure time, µs.
    pub us: f64,
    /// Chosen by auto-exposure.
    pub auto: bool,
    /// Auto-exposure wanted a time outside the sensor's range and got its nearest end.
    pub clipped: bool,
}

impl Exposure {
    /// Auto-exposure with the spec defaults p = 99, f = 0.70.
    pub fn auto() -> Self {
        Exposure::Auto {
            percentile: 99.0,
            fraction: 0.70,
        }
    }
}

/// Stage switches of the electron-domain pipeline; `true` = stage active.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Stages {
    /// Relative illumination (vignetting).
    pub ri: bool,
    /// Finite extinction ratio ER(λ_c); off = ideal polarizer.
    pub polarizer_er: bool,
    /// Fixed-pattern orientation error δ_k.
    pub polarizer_orientation: bool,
    /// PRNU gain map g_k.
    pub prnu: bool,
    /// 3 × 3 crosstalk (active only when `SensorConfig::crosstalk` > 0).
    pub crosstalk: bool,
    /// Dark current.
    pub dark: bool,
    /// Shot noise (Poisson).
    pub shot: bool,
    /// Full-well clip.
    pub fwc_clip: bool,
    /// DSNU offset map.
    pub dsnu: bool,
    /// Read noise.
    pub read: bool,
    /// ADC rounding and clipping; when off, [`RawFrame::analog`] holds the unrounded values.
    pub quantize: bool,
}

impl Default for Stages {
    fn default() -> Self {
        Stages {
            ri: true,
            polarizer_er: true,
            polarizer_orientation: true,
            prnu: true,
            crosstalk: true,
            dark: true,
            shot: true,
            fwc_clip: true,
            dsnu: true,
            read: true,
            quantize: true,
        }
    }
}

impl Stages {
    /// Every stage's name (its field, as `--off` and scene files write it), in pipeline order.
    pub const NAMES: [&'static str; 11] = {
        // a stage added without a name here does not compile
        let Stages {
            ri: _,
            polarizer_er: _,
            polarizer_orientation: _,
            prnu: _,
            crosstalk: _,
            dark: _,
            shot: _,
            fwc_clip: _,
            dsnu: _,
            read: _,
            quantize: _,
        } = Stages::NONE;
        [
            "ri",
            "polarizer_er",
            "polarizer_orientation",
            "prnu",
            "crosstalk",
            "dark",
            "shot",
            "fwc_clip",
            "dsnu",
            "read",
            "quantize",
        ]
    };

    /// Every stage off (the exact float model of `sensor.md` §6).
    pub fn none() -> Self {
        Self::NONE
    }

    const NONE: Stages = Stages {
        ri: false,
        polarizer_er: false,
        polarizer_orientation: false,
        prnu: false,
        crosstalk: false,
        dark: false,
        shot: false,
        fwc_clip: false,
        dsnu: false,
        read: false,
        quantize: false,
    };

    /// Only the noise-free ideal model with RI and ADC: polarizer non-idealities, fixed patterns,
    /// crosstalk, dark current and noise off; RI, full-well clip and quantisation on.
    pub fn ideal() -> Self {
        Stages {
            ri: true,
            fwc_clip: true,
            quantize: true,
            ..Self::none()
        }
    }
}

/// Every sensor parameter, defaults of `sensor.md` §7 (the `camera` preset).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// 2 × 2 polarizer layout (default `90,45/135,0`).
    pub layout: MosaicLayout,
    /// Lens f-number N, 1..16 (default 2).
    pub f_number: f64,
    /// Lens transmission τ_L, 0..1 (default 0.9).
    pub lens_transmission: f64,
    /// Relative illumination model (default cos^1.5).
    pub ri: RelativeIllumination,
    /// Band-pass centre λ_c in nm, 380..720 (default 450; should equal the sky wavelength).
    pub filter_center_nm: f64,
    /// Band-pass width Δλ in nm, 1..400 (default 40).
    pub filter_width_nm: f64,
    /// In-band filter transmission T_F, 0..1 (default 0.9).
    pub filter_transmission: f64,
    /// Quantum efficiency η(λ) of the bare (mono) pixel, evaluated at λ_c, 0..1: a number or a
    /// `[λ_nm, η]` table (default the IMX250 curve [`spectral::QE_IMX250`], 0.60 at 450 nm).
    pub qe: Spectral,
    /// Pass-axis transmission T∥(λ) of the wire grid, evaluated at λ_c, 0..1: a number or a table
    /// (default [`spectral::PASS_TRANSMISSION_IMX250MZR`], 0.8 at 450 nm).
    pub pass_transmission: Spectral,
    /// Extinction ratio table (default `sensor.md` §4).
    pub er_table: ErTable,
    /// Standard deviation of the fixed orientation error δ_k, degrees, 0..2 (default 0.5).
    pub orientation_sigma_deg: f64,
    /// PRNU, relative standard deviation of g_k, 0..0.02 (default 0.005).
    pub prnu: f64,
    /// DSNU standard deviation in e⁻, 0..2 (default 0.5).
    pub dsnu_e: f64,
    /// Dark current at 25 °C, e⁻/s, 0..1e5 (default 5).
    pub dark_current_e_per_s: f64,
    /// Dark-current doubling temperature step, °C (default 7).
    pub dark_doubling_c: f64,
    /// Sensor temperature, °C, −40..85 (default 25).
    pub temperature_c: f64,
    /// Read (dark temporal) noise σ_d in e⁻, 0..50 (default 2.5).
    pub read_noise_e: f64,
    /// Full-well capacity in e⁻, 100..1e6 (default 10 500).
    pub full_well_e: f64,
    /// K₀: DN per e⁻ at 0 dB, 12 bit (default 4095/10 500).
    pub k0: f64,
    /// Analog gain in dB, 0..48 (default 0).
    pub gain_db: f64,
    /// Black level in 12-bit DN, 0..200 (default 0). The frame reports it in output DN.
    pub black_level_dn: f64,
    /// Output bit depth, 8, 10 or 12 (default 12).
    pub bit_depth: u8,
    /// Exposure (default fixed 1000 µs).
    pub exposure: Exposure,
    /// Crosstalk: fraction of a pixel's signal leaking to its 8 neighbours (c/6 to each edge
    /// neighbour, c/12 to each corner), 0..0.03 (default 0 = off).
    pub crosstalk: f64,
    /// Option (`sensor.md` §6): gain above this many dB is applied digitally after a 12-bit ADC
    /// (missing codes, as reported for LUCID cameras), e.g. `Some(24.0)`; `None` = all analog.
    pub digital_gain_above_db: Option<f64>,
    /// Stage switches.
    pub stages: Stages,
    /// PSNS dataset model (`sensor.md` §9) instead of the camera model; `None` for the camera.
    pub psns: Option<PsnsModel>,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            layout: MosaicLayout::IMX250MZR,
            f_number: 2.0,
            lens_transmission: 0.9,
            ri: RelativeIllumination::default(),
            filter_center_nm: 450.0,
            filter_width_nm: 40.0,
            filter_transmission: 0.9,
            qe: Spectral::imx250_qe(),
            pass_transmission: Spectral::imx250mzr_pass_transmission(),
            er_table: ErTable::default(),
            orientation_sigma_deg: 0.5,
            prnu: 0.005,
            dsnu_e: 0.5,
            dark_current_e_per_s: 5.0,
            dark_doubling_c: 7.0,
            temperature_c: 25.0,
            read_noise_e: 2.5,
            full_well_e: 10_500.0,
            k0: 4095.0 / 10_500.0,
            gain_db: 0.0,
            black_level_dn: 0.0,
            bit_depth: 12,
            exposure: Exposure::default(),
            crosstalk: 0.0,
            digital_gain_above_db: None,
            stages: Stages::default(),
            psns: None,
        }
    }
}

/// Shortest exposure, µs.
pub const MIN_EXPOSURE_US: f64 = 20.0;
/// Longest exposure, µs.
pub const MAX_EXPOSURE_US: f64 = 10_000_000.0;

impl SensorConfig {
    /// The configuration of a preset.
    pub fn preset(p: Preset) -> Self {
        presets::config(p)
    }

    /// The relative illumination the frames actually carry: `ri` when the RI stage is on (and,
    /// for a PSNS model, its own falloff switch), otherwise none. `nfpi` has none, `gniipi` and
    /// `gniicpi` cos⁴, the camera preset cos^1.5. What a flat-field (e.g. the heading's
    /// intensity vote) must divide by.
    pub fn effective_ri(&self) -> RelativeIllumination {
        let on = self.stages.ri && self.psns.as_ref().is_none_or(|p| p.relative_illumination);
        if on {
            self.ri
        } else {
            RelativeIllumination::None
        }
    }

    /// Checks every parameter and the frame size (multiples of 4, non-zero).
    pub fn validate(&self, width: usize, height: usize) -> Result<()> {
        check_size(width, height)?;
        if ![8u8, 10, 12].contains(&self.bit_depth) {
            return Err(Error::range(
                "bit-depth",
                self.bit_depth as f64,
                "8, 10 or 12",
            ));
        }
        check_range("gain-db", self.gain_db, 0.0, 48.0)?;
        check_range("black-level", self.black_level_dn, 0.0, 200.0)?;
        match self.exposure {
            Exposure::Fixed { us } => {
                check_range("exposure-us", us, MIN_EXPOSURE_US, MAX_EXPOSURE_US)?;
            }
            Exposure::Auto {
                percentile,
                fraction,
            } => {
                if !(percentile > 0.0 && percentile <= 100.0) {
                    return Err(Error::range(
                        "auto-exposure percentile",
                        percentile,
                        "(0, 100]",
                    ));
                }
                if !(fraction > 0.0 && fraction <= 1.0) {
                    return Err(Error::range("auto-exposure fraction", fraction, "(0, 1]"));
                }
            }
        }
        check_range("f-number", self.f_number, 1.0, 16.0)?;
        check_range("lens-transmission", self.lens_transmission, 0.0, 1.0)?;
        self.ri.validate()?;
        check_range("filter-center-nm", self.filter_center_nm, 380.0, 720.0)?;
        check_range("filter-width-nm", self.filter_width_nm, 1.0, 400.0)?;
        check_range("filter-transmission", self.filter_transmission, 0.0, 1.0)?;
        self.qe.validate("qe", 0.0, 1.0)?;
        self.pass_transmission
            .validate("pass-transmission", 0.0, 1.0)?;
        self.er_table.validate()?;
        check_range(
            "orientation-sigma-deg",
            self.orientation_sigma_deg,
            0.0,
            2.0,
        )?;
        check_range("prnu", self.prnu, 0.0, 0.02)?;
        check_range("dsnu-e", self.dsnu_e, 0.0, 2.0)?;
        check_range("dark-current", self.dark_current_e_per_s, 0.0, 1e5)?;
        check_range("dark-doubling-c", self.dark_doubling_c, 1.0, 100.0)?;
        check_range("temperature-c", self.temperature_c, -40.0, 85.0)?;
        check_range("read-noise-e", self.read_noise_e, 0.0, 50.0)?;
        check_range("full-well-e", self.full_well_e, 100.0, 1e6)?;
        check_range("k0", self.k0, 1e-4, 100.0)?;
        check_range("crosstalk", self.crosstalk, 0.0, 0.03)?;
        if let Some(g) = self.digital_gain_above_db {
            check_range("digital-gain-above-db", g, 0.0, 48.0)?;
        }
        if let Some(p) = &self.psns {
            p.validate()?;
        }
        Ok(())
    }

    /// η(λ_c): the quantum efficiency at the band-pass centre.
    pub fn qe_at_filter(&self) -> f64 {
        self.qe.at(self.filter_center_nm)
    }

    /// T∥(λ_c): the wire grid's pass-axis transmission at the band-pass centre.
    pub fn pass_transmission_at_filter(&self) -> f64 {
        self.pass_transmission.at(self.filter_center_nm)
    }

    /// Dark current at the configured temperature, e⁻/s: I_d(25 °C) · 2^((T − 25)/ΔT).
    pub fn dark_current_at_temperature(&self) -> f64 {
        self.dark_current_e_per_s * 2f64.powf((self.temperature_c - 25.0) / self.dark_doubling_c)
    }

    /// Readout line time in µs (6.25 at 8 bit, 8.333 at 10/12 bit; `sensor.md` §1).
    pub fn line_time_us(&self) -> f64 {
        if self.bit_depth == 8 {
            6.25
        } else {
            25.0 / 3.0
        }
    }
}

/// Checks a frame/ROI size: non-zero multiples of 4.
pub fn check_size(width: usize, height: usize) -> Result<()> {
    for (name, v) in [("width", width), ("height", height)] {
        if v == 0 || v % 4 != 0 {
            return Err(Error::OutOfRange {
                name: name.into(),
                value: v.to_string(),
                allowed: "a non-zero multiple of 4".into(),
            });
        }
    }
    Ok(())
}
