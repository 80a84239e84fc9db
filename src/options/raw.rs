//! Sensor and raw-frame options (`render --raw`, `stream`, `bench`), applied onto a
//! [`SceneConfig`].

use super::{finite, first_given, integer, parsed, whole};
use crate::config::{SceneConfig, SceneKind};
use crate::sensor::packing::PixelFormat;
use crate::sensor::{Exposure, Preset, SensorConfig, Stages};
use clap::{Args, ValueEnum};

/// The values of `--sun-disc`.
// the variants are the option values (clap shows no help for them)
#[allow(missing_docs)]
#[derive(Clone, Copy, ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

/// Sensor and raw-frame options (`render --raw`, `stream`, `bench`).
#[derive(Args, Clone, Default)]
pub struct RawArgs {
    /// Sensor preset: camera (realistic IMX250MZR), nfpi, gniipi, gniicpi (PSNS dataset variants).
    #[arg(long, value_parser = parsed::<Preset>)]
    pub preset: Option<Preset>,
    /// Scene for raw frames: the sky or a uniform flat field.
    #[arg(long, value_enum)]
    pub scene: Option<SceneKind>,
    /// Flat-field radiance, W m^-2 sr^-1 nm^-1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "R")]
    pub flat_radiance: Option<f64>,
    /// Flat-field degree of linear polarization, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "D")]
    pub flat_dolp: Option<f64>,
    /// Flat-field angle of linear polarization, degrees (sensor frame).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub flat_aolp: Option<f64>,
    /// Exposure time, µs (20..10,000,000).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "US", conflicts_with = "auto_exposure")]
    pub exposure_us: Option<f64>,
    /// Auto-exposure: 99th percentile of the sky at 70 % of full well.
    #[arg(long)]
    pub auto_exposure: bool,
    /// Analog gain, dB (0..48).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DB")]
    pub gain_db: Option<f64>,
    /// Black level, DN at 12 bit (0..200).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DN")]
    pub black_level: Option<f64>,
    /// Output bit depth: 8, 10 or 12.
    #[arg(long, value_parser = integer, allow_negative_numbers = true, value_name = "BITS")]
    pub bit_depth: Option<i64>,
    /// Packed pixel format of raw.bin / the stream payload: mono8, mono12p, mono12packed, mono16.
    #[arg(long, value_parser = parsed::<PixelFormat>)]
    pub pixel_format: Option<PixelFormat>,
    /// Camera seed (fixed patterns and noise).
    #[arg(long, value_parser = whole)]
    pub seed: Option<u64>,
    /// Frame index of that camera (temporal noise).
    #[arg(long, value_parser = whole)]
    pub frame_index: Option<u64>,
    /// Draw the solar disc (default: on for the camera preset, off for PSNS presets).
    #[arg(long, value_enum)]
    pub sun_disc: Option<OnOff>,
    /// Add soft unpolarized clouds to the scene.
    #[arg(long)]
    pub clouds: bool,
    /// Sky nodes every N pixels of the fast path, refined where interpolation would be off by
    /// more than a fortieth of the shot noise (1 = every pixel; default 16).
    #[arg(long, value_name = "N", value_parser = integer, allow_negative_numbers = true)]
    pub sky_grid: Option<i64>,
    /// Reference run: the sky model at every pixel, no caches, and the exact sensor path (exact
    /// Poisson sampling, per-row ChaCha8 streams), the bit-stable reference of the fast path.
    #[arg(long)]
    pub exact: bool,
    /// Lens f-number.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub f_number: Option<f64>,
    /// Read (dark) noise, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    pub read_noise: Option<f64>,
    /// Full-well capacity, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    pub full_well: Option<f64>,
    /// Sensor temperature, °C (dark current).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "C")]
    pub sensor_temperature: Option<f64>,
    /// Pixel crosstalk fraction (0..0.03).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub crosstalk: Option<f64>,
    /// Band-pass filter width, nm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    pub filter_width: Option<f64>,
    /// Switch stages off: any of ri, polarizer_er, polarizer_orientation, prnu, crosstalk, dark,
    /// shot, fwc_clip, dsnu, read, quantize (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "STAGE")]
    pub off: Vec<String>,
    /// Set any sensor field: KEY=VALUE with VALUE in JSON (e.g. prnu=0.01, ri={"kind":"cospower","n":4}).
    #[arg(long = "sensor-set", value_name = "KEY=VALUE")]
    pub sensor_set: Vec<String>,
}

impl RawArgs {
    /// The first raw-frame option given on the command line (they do nothing for ideal images).
    pub fn first_given(&self) -> Option<&'static str> {
        self.first_given_but("")
    }

    /// [`Self::first_given`] leaving out the option `skip` (e.g. `seed`, when the world uses it).
    pub fn first_given_but(&self, skip: &str) -> Option<&'static str> {
        let given = [
            ("preset", self.preset.is_some()),
            ("flat-radiance", self.flat_radiance.is_some()),
            ("flat-dolp", self.flat_dolp.is_some()),
            ("flat-aolp", self.flat_aolp.is_some()),
            ("exposure-us", self.exposure_us.is_some()),
            ("auto-exposure", self.auto_exposure),
            ("gain-db", self.gain_db.is_some()),
            ("black-level", self.black_level.is_some()),
            ("bit-depth", self.bit_depth.is_some()),
            ("pixel-format", self.pixel_format.is_some()),
            ("seed", self.seed.is_some()),
            ("frame-index", self.frame_index.is_some()),
            ("sun-disc", self.sun_disc.is_some()),
            ("clouds", self.clouds),
            ("sky-grid", self.sky_grid.is_some()),
            ("exact", self.exact),
            ("f-number", self.f_number.is_some()),
            ("read-noise", self.read_noise.is_some()),
            ("full-well", self.full_well.is_some()),
            ("sensor-temperature", self.sensor_temperature.is_some()),
            ("crosstalk", self.crosstalk.is_some()),
            ("filter-width", self.filter_width.is_some()),
            ("off", !self.off.is_empty()),
            ("sensor-set", !self.sensor_set.is_empty()),
        ];
        first_given(&given.map(|(n, g)| (n, g && n != skip)))
    }

    /// Applies the raw options to a scene.
    pub fn apply(&self, c: &mut SceneConfig) -> crate::Result<()> {
        let r = &mut c.raw;
        if let Some(p) = self.preset {
            r.preset = p;
            r.sensor = None;
        }
        if let Some(k) = self.scene {
            r.scene = k;
        }
        r.flat.radiance = self.flat_radiance.unwrap_or(r.flat.radiance);
        r.flat.dolp = self.flat_dolp.unwrap_or(r.flat.dolp);
        r.flat.aolp_deg = self.flat_aolp.unwrap_or(r.flat.aolp_deg);
        if let Some(f) = self.pixel_format {
            r.pixel_format = f;
        }
        r.seed = self.seed.unwrap_or(r.seed);
        r.frame_index = self.frame_index.unwrap_or(r.frame_index);
        if let Some(d) = self.sun_disc {
            r.sun_disc = Some(matches!(d, OnOff::On));
        }
        if self.clouds {
            r.soft_clouds = Some(Default::default());
        }
        if let Some(g) = self.sky_grid {
            if !(1..=64).contains(&g) {
                return Err(crate::Error::range("sky-grid", g as f64, "1..64"));
            }
            r.sky_grid = g as usize;
        }
        if self.exact {
            if self.sky_grid.is_some_and(|g| g != 1) {
                return Err(crate::Error::Invalid(
                    "--sky-grid chooses the fast path's grid; --exact evaluates every pixel: give one of them".into(),
                ));
            }
            r.exact = true;
            r.sky_grid = 1;
        }
        let mut s = r
            .sensor
            .clone()
            .unwrap_or_else(|| SensorConfig::preset(r.preset));
        if let Some(us) = self.exposure_us {
            s.exposure = Exposure::Fixed { us };
        }
        if self.auto_exposure {
            s.exposure = Exposure::auto();
        }
        s.gain_db = self.gain_db.unwrap_or(s.gain_db);
        s.black_level_dn = self.black_level.unwrap_or(s.black_level_dn);
        if let Some(b) = self.bit_depth {
            if ![8, 10, 12].contains(&b) {
                return Err(crate::Error::range("bit-depth", b as f64, "8, 10 or 12"));
            }
            s.bit_depth = b as u8;
        }
        s.f_number = self.f_number.unwrap_or(s.f_number);
        s.read_noise_e = self.read_noise.unwrap_or(s.read_noise_e);
        s.full_well_e = self.full_well.unwrap_or(s.full_well_e);
        s.temperature_c = self.sensor_temperature.unwrap_or(s.temperature_c);
        s.crosstalk = self.crosstalk.unwrap_or(s.crosstalk);
        s.filter_width_nm = self.filter_width.unwrap_or(s.filter_width_nm);
        if !self.off.is_empty() || !self.sensor_set.is_empty() {
            let mut v = serde_json::to_value(&s).expect("sensor serializes");
            for st in &self.off {
                let st = st.trim();
                match v["stages"].get_mut(st) {
                    Some(x) => *x = false.into(),
                    None => {
                        return Err(crate::Error::OutOfRange {
                            name: "off".into(),
                            value: st.into(),
                            allowed: Stages::NAMES.join(", "),
                        })
                    }
                }
            }
            for kv in &self.sensor_set {
                let (k, val) = kv.split_once('=').ok_or_else(|| {
                    crate::Error::Invalid(format!("--sensor-set '{kv}' is not KEY=VALUE"))
                })?;
                let parsed: serde_json::Value = serde_json::from_str(val)
                    .unwrap_or_else(|_| serde_json::Value::String(val.to_string()));
                if v.get(k.trim()).is_none() {
                    return Err(crate::Error::Invalid(format!(
                        "--sensor-set: unknown sensor field '{k}'"
                    )));
                }
                v[k.trim()] = parsed;
            }
            s = serde_json::from_value(v)
                .map_err(|e| crate::Error::Invalid(format!("sensor settings: {e}")))?;
        }
        r.sensor = Some(s);
        Ok(())
    }
}
