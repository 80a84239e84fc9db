//! PSNS-style datasets (`psns dataset`): the description of a dataset, the deterministic
//! parameters of every sample, its file names and its label row (this file, pure); the build into
//! a directory ([`build`]) and its manifest ([`manifest`]).
//!
//! Sample `i` of split `s` gets parameters drawn from seeded streams keyed by the dataset seed,
//! the sample's frame index and the parameter ([`crate::rng::dataset_rng`]), so a sample never
//! depends on threads, shards, jobs or restarts.
//!
//! Layout (`docs/dataset.md`): six folders, NFPI, GNIIPI, GNIICPI (training) and TNFPI, TGNIIPI,
//! TGNIICPI (test), rendered with the presets nfpi / gniipi / gniicpi. Sample `n` (1-based) of the
//! split with id `s` (0..5 in that order) is frame `s · 10⁹ + n` of the dataset's camera (seed
//! `seed`), so splits never share noise and the counts of one split never change another's
//! samples.

pub mod build;
pub mod manifest;

use crate::camera::{Attitude, AttitudeFrame, Intrinsics};
use crate::config::{SceneConfig, SunConfig};
use crate::error::{check_range, num, Error, Result};
use crate::sensor::Preset;
use crate::sun::SunPosition;
use rand::Rng;
use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::fmt;

/// Peak bytes per sample of a build's plan: its index, the drawn sample and its result, the
/// shard's copy and its label row.
const PLAN_BYTES_PER_SAMPLE: u64 = 16 + 3 * std::mem::size_of::<Result<Sample>>() as u64 + 256;

/// Frame-index stride between splits: sample `n` of split id `s` is frame `s · STRIDE + n`.
pub const SPLIT_STRIDE: u64 = 1_000_000_000;
/// Most samples in one split (so a description holds at most six times as many): the plan of
/// a build holds every sample's parameters, a few hundred bytes each.
pub const MAX_SAMPLES_PER_SPLIT: u64 = 10_000_000;

/// One of the six PSNS folders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Split {
    /// Training, no noise (preset nfpi).
    Nfpi,
    /// Training, Gaussian noise and illumination falloff (preset gniipi).
    Gniipi,
    /// Training, as GNIIPI plus clouds (preset gniicpi).
    Gniicpi,
    /// Test, preset nfpi.
    Tnfpi,
    /// Test, preset gniipi.
    Tgniipi,
    /// Test, preset gniicpi.
    Tgniicpi,
}

impl Split {
    /// The six splits in their canonical order (the order of ids, labels and manifests).
    pub const ALL: [Split; 6] = [
        Split::Nfpi,
        Split::Gniipi,
        Split::Gniicpi,
        Split::Tnfpi,
        Split::Tgniipi,
        Split::Tgniicpi,
    ];

    /// Folder name, e.g. `NFPI`.
    pub fn name(self) -> &'static str {
        match self {
            Split::Nfpi => "NFPI",
            Split::Gniipi => "GNIIPI",
            Split::Gniicpi => "GNIICPI",
            Split::Tnfpi => "TNFPI",
            Split::Tgniipi => "TGNIIPI",
            Split::Tgniicpi => "TGNIICPI",
        }
    }

    /// File-name prefix: N, G, C, TN, TG, TC.
    pub fn prefix(self) -> &'static str {
        match self {
            Split::Nfpi => "N",
            Split::Gniipi => "G",
            Split::Gniicpi => "C",
            Split::Tnfpi => "TN",
            Split::Tgniipi => "TG",
            Split::Tgniicpi => "TC",
        }
    }

    /// The sensor preset the split is rendered with.
    pub fn preset(self) -> Preset {
        match self {
            Split::Nfpi | Split::Tnfpi => Preset::Nfpi,
            Split::Gniipi | Split::Tgniipi => Preset::Gniipi,
            Split::Gniicpi | Split::Tgniicpi => Preset::Gniicpi,
        }
    }

    /// Position in [`Split::ALL`].
    pub fn id(self) -> u64 {
        Split::ALL.iter().position(|&s| s == self).expect("listed") as u64
    }

    /// The split of a folder name (exact, upper case).
    pub fn from_name(name: &str) -> Result<Split> {
        Split::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| Error::OutOfRange {
                name: "splits".into(),
                value: name.into(),
                allowed: "NFPI, GNIIPI, GNIICPI, TNFPI, TGNIIPI, TGNIICPI".into(),
            })
    }
}

/// The distribution of one parameter.
///
/// In TOML: a number (fixed), `{ min = A, max = B }` with an optional `step` (uniform over the
/// grid A, A + step, …, ≤ B; `step = 0` draws a continuous uniform value in [A, B)), or
/// `{ values = [a, b, …] }` (uniform choice).
#[derive(Clone, Debug, PartialEq)]
pub enum Dist {
    /// Always this value.
    Fixed(f64),
    /// Uniform over a grid (or continuous for step 0).
    Uniform {
        /// Smallest value.
        min: f64,
        /// Largest value.
        max: f64,
        /// Grid step; `None` = the parameter's default step.
        step: Option<f64>,
    },
    /// Uniform choice among values.
    Choice(Vec<f64>),
}

impl Serialize for Dist {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Dist::Fixed(v) => s.serialize_f64(*v),
            Dist::Uniform { min, max, step } => {
                let mut m = s.serialize_map(None)?;
                m.serialize_entry("min", min)?;
                m.serialize_entry("max", max)?;
                if let Some(st) = step {
                    m.serialize_entry("step", st)?;
                }
                m.end()
            }
            Dist::Choice(v) => {
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry("values", v)?;
                m.end()
            }
        }
    }
}

impl<'de> Deserialize<'de> for Dist {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        const KEYS: &[&str] = &["min", "max", "step", "values"];
        impl<'de> Visitor<'de> for V {
            type Value = Dist;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, { min = A, max = B, step = S } or { values = [...] }")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v as f64))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> std::result::Result<Dist, A::Error> {
                let (mut min, mut max, mut step, mut values) = (None, None, None, None);
                while let Some(k) = m.next_key::<String>()? {
                    match k.as_str() {
                        "min" => min = Some(m.next_value::<f64>()?),
                        "max" => max = Some(m.next_value::<f64>()?),
                        "step" => step = Some(m.next_value::<f64>()?),
                        "values" => values = Some(m.next_value::<Vec<f64>>()?),
                        other => return Err(de::Error::unknown_field(other, KEYS)),
                    }
                }
                match (min, max, step, values) {
                    (Some(min), Some(max), step, None) => Ok(Dist::Uniform { min, max, step }),
                    (None, None, None, Some(v)) => Ok(Dist::Choice(v)),
                    (_, _, _, Some(_)) => Err(de::Error::custom(
                        "give either values = [...] or min/max/step, not both",
                    )),
                    (None, _, _, None) => Err(de::Error::missing_field("min")),
                    (_, None, _, None) => Err(de::Error::missing_field("max")),
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// A uniform distribution over `min..=max` in steps of `step`.
fn uniform(min: f64, max: f64, step: f64) -> Dist {
    Dist::Uniform {
        min,
        max,
        step: Some(step),
    }
}

/// Most grid points a uniform distribution may have.
const MAX_GRID: f64 = 1e12;

/// Decimal places of a step or bound as written (`0.05` → 2), at most 9.
fn decimals(v: f64) -> usize {
    let s = format!("{v}");
    s.split_once('.').map_or(0, |(_, f)| f.len()).min(9)
}

/// `v` rounded to `d` decimal places, as the f64 nearest that decimal (so it prints as written).
fn round_decimal(v: f64, d: usize) -> f64 {
    let r: f64 = format!("{v:.d$}").parse().expect("formatted number parses");
    r + 0.0 // -0 prints as "-0"; +0.0 makes it 0
}

impl Dist {
    /// Checks the distribution of parameter `name` against its allowed range `lo..=hi`.
    fn validate(&self, name: &str, lo: f64, hi: f64) -> Result<()> {
        match self {
            Dist::Fixed(v) => check_range(name, *v, lo, hi).map(|_| ()),
            Dist::Uniform { min, max, step } => {
                check_range(&format!("{name}.min"), *min, lo, hi)?;
                check_range(&format!("{name}.max"), *max, *min, hi)?;
                if let Some(s) = step {
                    check_range(&format!("{name}.step"), *s, 0.0, hi - lo)?;
                    if *s > 0.0 && (max - min) / s > MAX_GRID {
                        return Err(Error::range(
                            &format!("{name}.step"),
                            *s,
                            &format!(
                                "at least {} (at most 1e12 grid points)",
                                num((max - min) / MAX_GRID)
                            ),
                        ));
                    }
                }
                Ok(())
            }
            Dist::Choice(v) => {
                if v.is_empty() {
                    return Err(Error::Invalid(format!(
                        "{name}.values is empty (give at least one value)"
                    )));
                }
                for x in v {
                    check_range(&format!("{name}.values"), *x, lo, hi)?;
                }
                Ok(())
            }
        }
    }

    /// Draws one value from `rng` (`default_step` for a uniform distribution without a step).
    fn draw<R: Rng>(&self, rng: &mut R, default_step: f64) -> f64 {
        match self {
            Dist::Fixed(v) => *v,
            Dist::Choice(v) => v[rng.random_range(0..v.len())],
            Dist::Uniform { min, max, step } => {
                let step = step.unwrap_or(default_step);
                if step == 0.0 || max == min {
                    if max == min {
                        return *min;
                    }
                    return min + (max - min) * rng.random::<f64>();
                }
                let n = ((max - min) / step + 1e-9).floor() as u64;
                let k = rng.random_range(0..=n);
                let d = decimals(step).max(decimals(*min));
                round_decimal(min + k as f64 * step, d).min(*max)
            }
        }
    }
}

/// Optional per-sample outputs besides the 8-bit raw mosaic.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Outputs {
    /// The four polarizer-direction images (the mosaic's 90/45/135/0 sub-images, half size,
    /// 8 bit): `extras/<split>/<stem>_i0.png` … `_i135.png`.
    pub polarizer_images: bool,
    /// The 12-bit frame of the realistic camera preset for the same scene, as `psns render --raw
    /// --preset camera` writes it (16-bit PNG, LSB-aligned): `extras/<split>/<stem>_raw12.png`.
    pub raw12: bool,
    /// Exposure of the 12-bit frame, µs (20..10,000,000): a distribution, or `None` for the
    /// camera's auto-exposure (99th percentile of the sky at 70 % of full well).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub raw12_exposure_us: Option<Dist>,
    /// Truth DOP and AOP (degrees) of the PSNS frame, `.npy` f32: `extras/<split>/<stem>_dop.npy`,
    /// `_aop.npy`.
    pub truth: bool,
}

/// The sun from a UTC time and a place (SPA, geometric position) instead of `sun_altitude_deg`
/// and `sun_azimuth_deg`: each sample draws a whole second uniformly in `start..=end`, a latitude
/// and a longitude, and draws again (up to [`MAX_SUN_DRAWS`] times) until the sun is at least
/// `min_altitude_deg` high. The sun's altitude and azimuth are rounded to 0.001 degree and
/// rendered as such (they are in the labels and the file name; the time and place are in the
/// labels too).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunTime {
    /// First instant, ISO 8601 UTC (e.g. `2024-01-01T00:00:00Z`).
    pub start: String,
    /// Last instant, ISO 8601 UTC.
    pub end: String,
    /// Latitude, degrees north (-90..90).
    #[serde(default = "default_lat")]
    pub lat_deg: Dist,
    /// Longitude, degrees east (-180..180).
    #[serde(default = "default_lon")]
    pub lon_deg: Dist,
    /// Lowest sun altitude accepted, degrees (0..89; default 0).
    #[serde(default)]
    pub min_altitude_deg: f64,
}

fn default_lat() -> Dist {
    uniform(-60.0, 60.0, 0.01)
}
fn default_lon() -> Dist {
    uniform(-180.0, 180.0, 0.01)
}

/// Most draws of a time and place for one sample before the description is refused.
pub const MAX_SUN_DRAWS: u32 = 1000;

/// A dataset description (`docs/dataset.md`): every key has a default, and the defaults are PSNS
/// at full size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DatasetConfig {
    /// Dataset seed: the camera seed of every frame and the key of every parameter draw.
    pub seed: u64,
    /// Frame width, pixels (a multiple of 4).
    pub width: usize,
    /// Frame height, pixels (a multiple of 4).
    pub height: usize,
    /// Pixel pitch, µm.
    pub pixel_pitch_um: f64,
    /// Reference frame of yaw/pitch/roll: `solar` (yaw from the sun's azimuth, as PSNS) or `enu`.
    pub frame: AttitudeFrame,
    /// Sky evaluated every `sky_grid` pixels and interpolated (as `psns render --sky-grid`).
    pub sky_grid: usize,
    /// Folder name → number of samples; folders not listed are not built.
    pub splits: BTreeMap<String, u64>,
    /// Yaw ψ, degrees.
    pub yaw_deg: Dist,
    /// Pitch ϑ, degrees.
    pub pitch_deg: Dist,
    /// Roll φ, degrees.
    pub roll_deg: Dist,
    /// Focal length, mm.
    pub focal_length_mm: Dist,
    /// Projection of every frame (`psns render --projection`; default rectilinear).
    pub projection: crate::camera::Projection,
    /// Lens of every frame (`psns render --lens`); absent = each preset's own (`camera.md`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lens: Option<crate::camera::Lens>,
    /// Sun altitude, degrees.
    pub sun_altitude_deg: Dist,
    /// Sun compass azimuth, degrees.
    pub sun_azimuth_deg: Dist,
    /// The sun from times and places instead (`None`: from the two keys above).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sun_time: Option<SunTime>,
    /// Turbidity.
    pub turbidity: Dist,
    /// Wavelength, nm.
    pub wavelength_nm: Dist,
    /// Ground albedo.
    pub albedo: Dist,
    /// Fraction of samples (0..1, drawn per sample) with soft unpolarized clouds blended into the
    /// sky (`psns render --clouds`). Above 0 every sample gets a camera seed of its own, drawn
    /// from the dataset seed and its frame index, so that the clouds (seeded by the camera seed)
    /// differ from sample to sample.
    pub soft_clouds: f64,
    /// Optional outputs.
    pub outputs: Outputs,
}

impl Default for DatasetConfig {
    fn default() -> Self {
        let splits = Split::ALL
            .iter()
            .map(|s| {
                let n = if s.name().starts_with('T') {
                    6_000
                } else {
                    40_000
                };
                (s.name().to_string(), n)
            })
            .collect();
        DatasetConfig {
            seed: 1,
            width: 2448,
            height: 2048,
            pixel_pitch_um: 3.45,
            frame: AttitudeFrame::Solar,
            // psns render's default, so a sample re-renders with the default command line
            sky_grid: crate::config::RawConfig::default().sky_grid,
            splits,
            yaw_deg: uniform(0.0, 359.9, 0.1),
            pitch_deg: Dist::Fixed(0.0),
            roll_deg: Dist::Fixed(0.0),
            focal_length_mm: Dist::Fixed(4.0),
            projection: crate::camera::Projection::Rectilinear,
            lens: None,
            sun_altitude_deg: uniform(0.0, 90.0, 0.1),
            sun_azimuth_deg: uniform(0.0, 359.9, 0.1),
            sun_time: None,
            turbidity: uniform(1.7, 10.0, 0.1),
            wavelength_nm: uniform(380.0, 720.0, 1.0),
            albedo: uniform(0.0, 1.0, 0.01),
            soft_clouds: 0.0,
            outputs: Outputs::default(),
        }
    }
}

/// A parameter: key, allowed range, default grid step and the id of its random stream.
struct Param {
    key: &'static str,
    lo: f64,
    hi: f64,
    step: f64,
    id: u32,
}

const PARAMS: [Param; 9] = [
    Param {
        key: "yaw_deg",
        lo: -360.0,
        hi: 360.0,
        step: 0.1,
        id: 1,
    },
    Param {
        key: "pitch_deg",
        lo: -90.0,
        hi: 90.0,
        step: 0.1,
        id: 2,
    },
    Param {
        key: "roll_deg",
        lo: -180.0,
        hi: 180.0,
        step: 0.1,
        id: 3,
    },
    Param {
        key: "focal_length_mm",
        lo: 0.5,
        hi: 1000.0,
        step: 0.1,
        id: 4,
    },
    Param {
        key: "sun_altitude_deg",
        lo: 0.0,
        hi: 90.0,
        step: 0.1,
        id: 5,
    },
    Param {
        key: "sun_azimuth_deg",
        lo: 0.0,
        hi: 360.0,
        step: 0.1,
        id: 6,
    },
    Param {
        key: "turbidity",
        lo: 1.7,
        hi: 10.0,
        step: 0.1,
        id: 7,
    },
    Param {
        key: "wavelength_nm",
        lo: 380.0,
        hi: 720.0,
        step: 1.0,
        id: 8,
    },
    Param {
        key: "albedo",
        lo: 0.0,
        hi: 1.0,
        step: 0.01,
        id: 9,
    },
];

impl DatasetConfig {
    fn dists(&self) -> [&Dist; 9] {
        [
            &self.yaw_deg,
            &self.pitch_deg,
            &self.roll_deg,
            &self.focal_length_mm,
            &self.sun_altitude_deg,
            &self.sun_azimuth_deg,
            &self.turbidity,
            &self.wavelength_nm,
            &self.albedo,
        ]
    }

    /// Parses a TOML description (`what` names it in messages) and validates it.
    pub fn from_toml(text: &str, what: &str) -> Result<Self> {
        if let Ok(t) = text.parse::<toml::Table>() {
            if t.contains_key("sun_time") {
                for k in ["sun_altitude_deg", "sun_azimuth_deg"] {
                    if t.contains_key(k) {
                        return Err(Error::Invalid(format!(
                            "{what}: give the sun either by sun_time or by {k}, not both"
                        )));
                    }
                }
            }
        }
        let cfg: DatasetConfig = toml::from_str(text).map_err(|e| {
            Error::Invalid(format!(
                "{what} is not a valid dataset description: {}",
                e.to_string().trim_end()
            ))
        })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// The description as TOML (what `DIR/dataset.toml` holds); [`Self::from_toml`] reads it back.
    pub fn to_toml(&self) -> String {
        let mut t = toml::Table::try_from(self).expect("dataset description serializes");
        if self.sun_time.is_some() {
            t.remove("sun_altitude_deg");
            t.remove("sun_azimuth_deg");
        }
        toml::to_string(&t).expect("dataset description serializes")
    }

    /// Checks every key's range; the message names the key, its value and the allowed range.
    pub fn validate(&self) -> Result<()> {
        crate::sensor::check_size(self.width, self.height)?;
        Intrinsics::with_size(self.width, self.height).validate()?;
        check_range("pixel_pitch_um", self.pixel_pitch_um, 0.1, 1000.0)?;
        if !(1..=64).contains(&self.sky_grid) {
            return Err(Error::range("sky_grid", self.sky_grid as f64, "1..64"));
        }
        if self.splits.is_empty() {
            return Err(Error::Invalid(
                "splits is empty: list at least one folder (NFPI, GNIIPI, GNIICPI, TNFPI, TGNIIPI, TGNIICPI) with its number of samples".into(),
            ));
        }
        for (name, &n) in &self.splits {
            Split::from_name(name)?;
            if !(1..=MAX_SAMPLES_PER_SPLIT).contains(&n) {
                return Err(Error::range(
                    &format!("splits.{name}"),
                    n as f64,
                    &format!("1..{MAX_SAMPLES_PER_SPLIT}"),
                ));
            }
        }
        for (p, d) in PARAMS.iter().zip(self.dists()) {
            d.validate(p.key, p.lo, p.hi)?;
        }
        check_range("soft_clouds", self.soft_clouds, 0.0, 1.0)?;
        if let Some(d) = &self.outputs.raw12_exposure_us {
            if !self.outputs.raw12 {
                return Err(Error::Invalid(
                    "outputs.raw12_exposure_us applies to the 12-bit frame: add raw12 = true under [outputs] (or leave it out)".into(),
                ));
            }
            d.validate("outputs.raw12_exposure_us", 20.0, 1e7)?;
        }
        if let Some(st) = &self.sun_time {
            let start = crate::sun::parse_time(&st.start)
                .map_err(|e| Error::Invalid(format!("sun_time.start: {e}")))?;
            let end = crate::sun::parse_time(&st.end)
                .map_err(|e| Error::Invalid(format!("sun_time.end: {e}")))?;
            if end < start {
                return Err(Error::OutOfRange {
                    name: "sun_time.end".into(),
                    value: st.end.clone(),
                    allowed: format!("{} or later (sun_time.start)", st.start),
                });
            }
            crate::sun::delta_t_estimate(&start)?;
            crate::sun::delta_t_estimate(&end)?;
            st.lat_deg.validate("sun_time.lat_deg", -90.0, 90.0)?;
            st.lon_deg.validate("sun_time.lon_deg", -180.0, 180.0)?;
            check_range("sun_time.min_altitude_deg", st.min_altitude_deg, 0.0, 89.0)?;
        }
        Ok(())
    }

    /// The listed splits in canonical order with their sample counts.
    pub fn split_counts(&self) -> Vec<(Split, u64)> {
        Split::ALL
            .into_iter()
            .filter_map(|s| self.splits.get(s.name()).map(|&n| (s, n)))
            .collect()
    }

    /// Number of samples in the dataset.
    pub fn total(&self) -> u64 {
        self.split_counts().iter().map(|(_, n)| n).sum()
    }

    /// Sample `number` (1-based) of `split`: its parameters drawn from the seed and its frame
    /// index only. Fails only for a `sun_time` that puts the sun too low in [`MAX_SUN_DRAWS`]
    /// draws.
    pub fn sample(&self, split: Split, number: u64) -> Result<Sample> {
        let frame_index = split.id() * SPLIT_STRIDE + number;
        let mut v = [0.0; 9];
        for ((p, d), out) in PARAMS.iter().zip(self.dists()).zip(v.iter_mut()) {
            let mut rng = crate::rng::dataset_rng(self.seed, frame_index, p.id);
            *out = d.draw(&mut rng, p.step);
        }
        let mut sample = Sample {
            split,
            number,
            frame_index,
            seed: self.seed,
            width: self.width,
            height: self.height,
            pixel_pitch_um: self.pixel_pitch_um,
            frame: self.frame,
            sky_grid: self.sky_grid,
            yaw_deg: v[0],
            pitch_deg: v[1],
            roll_deg: v[2],
            focal_length_mm: v[3],
            projection: self.projection,
            lens: self.lens,
            sun_altitude_deg: v[4],
            sun_azimuth_deg: v[5],
            turbidity: v[6],
            wavelength_nm: v[7],
            albedo: v[8],
            when: None,
            raw12_exposure_us: None,
            soft_clouds: false,
        };
        if self.soft_clouds > 0.0 {
            let mut rng = crate::rng::dataset_rng(self.seed, frame_index, 14);
            sample.soft_clouds = rng.random::<f64>() < self.soft_clouds;
            // a camera of its own (the clouds are seeded by the camera seed), below 2^63
            sample.seed = crate::rng::dataset_rng(self.seed, frame_index, 15).random::<u64>() >> 1;
        }
        if let Some(d) = &self.outputs.raw12_exposure_us {
            let mut rng = crate::rng::dataset_rng(self.seed, frame_index, 13);
            sample.raw12_exposure_us = Some(d.draw(&mut rng, 1.0));
        }
        if let Some(st) = &self.sun_time {
            let when = draw_sun_time(st, self.seed, frame_index)
                .map_err(|e| Error::Invalid(format!("{} sample {number}: {e}", split.name())))?;
            sample.sun_altitude_deg = when.1;
            sample.sun_azimuth_deg = when.2;
            sample.when = Some(when.0);
        }
        Ok(sample)
    }

    /// Every sample in canonical order (split order, then number).
    pub fn samples(&self) -> impl Iterator<Item = Result<Sample>> + '_ {
        self.split_counts()
            .into_iter()
            .flat_map(move |(s, n)| (1..=n).map(move |k| self.sample(s, k)))
    }

    /// Every sample in canonical order, or the first that cannot be drawn.
    ///
    /// The plan's memory is checked against what the process may use before it is allocated: a
    /// description too big for this machine is bad input, not an allocation abort.
    pub fn plan(&self) -> Result<Vec<Sample>> {
        use rayon::prelude::*;
        crate::memory::check_memory(
            &format!("the plan of {} samples", self.total()),
            self.total().saturating_mul(PLAN_BYTES_PER_SAMPLE),
            crate::memory::memory_available(),
        )?;
        // SPA draws (with `sun_time`) cost a few microseconds each: spread them over the cores
        let ids: Vec<(Split, u64)> = self
            .split_counts()
            .into_iter()
            .flat_map(|(s, n)| (1..=n).map(move |k| (s, k)))
            .collect();
        // a description that keeps the sun down fails on its first sample: fail fast there
        if let Some(&(s, k)) = ids.first() {
            self.sample(s, k)?;
        }
        let all: Vec<Result<Sample>> = ids.par_iter().map(|&(s, k)| self.sample(s, k)).collect();
        // the first sample that fails, in order (not whichever thread failed first)
        all.into_iter().collect()
    }

    /// The files of one sample, relative to the dataset directory: the 8-bit mosaic first, then
    /// the optional outputs.
    pub fn files(&self, s: &Sample) -> Vec<String> {
        let mut v = vec![s.file()];
        let stem = s.stem();
        let dir = format!("extras/{}", s.split.name());
        let o = &self.outputs;
        if o.polarizer_images {
            for a in [0, 45, 90, 135] {
                v.push(format!("{dir}/{stem}_i{a}.png"));
            }
        }
        if o.raw12 {
            v.push(format!("{dir}/{stem}_raw12.png"));
        }
        if o.truth {
            v.push(format!("{dir}/{stem}_dop.npy"));
            v.push(format!("{dir}/{stem}_aop.npy"));
        }
        v
    }
}

/// Draws a time and place with the sun at least `min_altitude_deg` high: the place and time,
/// and the sun's altitude and azimuth rounded to 0.001 degree.
fn draw_sun_time(st: &SunTime, seed: u64, frame_index: u64) -> Result<(When, f64, f64)> {
    let start = crate::sun::parse_time(&st.start)?;
    let end = crate::sun::parse_time(&st.end)?;
    let span = (end - start).num_seconds().max(0) as u64;
    let mut rt = crate::rng::dataset_rng(seed, frame_index, 10);
    let mut rlat = crate::rng::dataset_rng(seed, frame_index, 11);
    let mut rlon = crate::rng::dataset_rng(seed, frame_index, 12);
    for _ in 0..MAX_SUN_DRAWS {
        let t = start + chrono::Duration::seconds(rt.random_range(0..=span) as i64);
        let lat = st.lat_deg.draw(&mut rlat, 0.01);
        let lon = st.lon_deg.draw(&mut rlon, 0.01);
        let place = crate::sun::Place {
            lat_deg: lat,
            lon_deg: lon,
            height_m: 0.0,
        };
        let sun = crate::sun::spa(&t, &place, None, None)?;
        let alt = round_decimal(90.0 - sun.zenith_deg, 3);
        if alt >= st.min_altitude_deg && alt <= 90.0 {
            let az = round_decimal(sun.azimuth_deg, 3);
            let when = When {
                time_utc: t.format("%Y-%m-%dT%H:%M:%SZ").to_string(),
                lat_deg: lat,
                lon_deg: lon,
            };
            return Ok((when, alt, az));
        }
    }
    Err(Error::Invalid(format!(
        "sun_time: the sun was below min_altitude_deg = {} in {MAX_SUN_DRAWS} draws of time and place; widen the times or places",
        num(st.min_altitude_deg)
    )))
}

/// The time and place a sample's sun comes from (with `sun_time`).
#[derive(Clone, Debug, PartialEq)]
pub struct When {
    /// UTC time, `YYYY-MM-DDTHH:MM:SSZ`.
    pub time_utc: String,
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
}

/// One sample's parameters: everything needed to render it again.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Its folder.
    pub split: Split,
    /// 1-based number within the split.
    pub number: u64,
    /// Frame of the dataset's camera (temporal noise, clouds): `split id · 10⁹ + number`.
    pub frame_index: u64,
    /// Camera seed (the dataset seed).
    pub seed: u64,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Pixel pitch, µm.
    pub pixel_pitch_um: f64,
    /// Reference frame of the attitude.
    pub frame: AttitudeFrame,
    /// Sky grid.
    pub sky_grid: usize,
    /// Yaw, degrees.
    pub yaw_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Roll, degrees.
    pub roll_deg: f64,
    /// Focal length, mm.
    pub focal_length_mm: f64,
    /// Projection.
    pub projection: crate::camera::Projection,
    /// Lens (`None`: the preset's).
    pub lens: Option<crate::camera::Lens>,
    /// Sun altitude, degrees.
    pub sun_altitude_deg: f64,
    /// Sun compass azimuth, degrees.
    pub sun_azimuth_deg: f64,
    /// Turbidity.
    pub turbidity: f64,
    /// Wavelength, nm.
    pub wavelength_nm: f64,
    /// Ground albedo.
    pub albedo: f64,
    /// Time and place of the sun (descriptions with `sun_time`).
    pub when: Option<When>,
    /// Exposure of the 12-bit camera frame, µs; `None` = auto-exposure.
    pub raw12_exposure_us: Option<f64>,
    /// Soft clouds in the sky (`psns render --clouds`).
    pub soft_clouds: bool,
}

/// Header of `labels.csv`.
pub const LABEL_HEADER: &str = "split,file,yaw_deg,pitch_deg,roll_deg,frame,focal_length_mm,pixel_pitch_um,sun_altitude_deg,sun_azimuth_deg,turbidity,wavelength_nm,albedo,seed,frame_index,sun_cam_x,sun_cam_y,sun_cam_z,preset,width,height,sky_grid,number,time_utc,lat_deg,lon_deg,raw12_exposure_us,soft_clouds";

impl Sample {
    /// `<prefix><Number>_<Yaw>_<Pitch>_<Roll>_<FocalLength>_<SolarAltitude>_<Turbidity>_<Wavelength>_<GroundAlbedo>`.
    pub fn stem(&self) -> String {
        format!(
            "{}{}_{}_{}_{}_{}_{}_{}_{}_{}",
            self.split.prefix(),
            self.number,
            self.yaw_deg,
            self.pitch_deg,
            self.roll_deg,
            self.focal_length_mm,
            self.sun_altitude_deg,
            self.turbidity,
            self.wavelength_nm,
            self.albedo
        )
    }

    /// The 8-bit mosaic's path relative to the dataset directory, `<SPLIT>/<stem>.png`.
    pub fn file(&self) -> String {
        format!("{}/{}.png", self.split.name(), self.stem())
    }

    /// The sun position.
    pub fn sun(&self) -> SunPosition {
        SunPosition::new(90.0 - self.sun_altitude_deg, self.sun_azimuth_deg)
    }

    /// The camera attitude.
    pub fn attitude(&self) -> Attitude {
        Attitude::Euler {
            frame: self.frame,
            yaw_deg: self.yaw_deg,
            pitch_deg: self.pitch_deg,
            roll_deg: self.roll_deg,
        }
    }

    /// Unit vector toward the sun in the camera frame (+x columns, +y rows, +z optical axis).
    pub fn sun_camera(&self) -> glam::DVec3 {
        let sun = self.sun();
        self.attitude().enu_to_camera(sun.azimuth_deg) * sun.vector()
    }

    /// The scene `psns render --raw --preset <preset>` renders from this sample's label values.
    pub fn scene(&self, preset: Preset) -> SceneConfig {
        let mut c = SceneConfig {
            sun: SunConfig {
                altitude_deg: Some(self.sun_altitude_deg),
                azimuth_deg: Some(self.sun_azimuth_deg),
                ..Default::default()
            },
            ..Default::default()
        };
        c.sky.turbidity = self.turbidity;
        c.sky.wavelength_nm = self.wavelength_nm;
        c.sky.albedo = self.albedo;
        c.camera.intrinsics = Intrinsics {
            width: self.width,
            height: self.height,
            focal_length_mm: self.focal_length_mm,
            pixel_pitch_um: self.pixel_pitch_um,
            principal_point: None,
            projection: self.projection,
            lens: self.lens,
        };
        c.camera.attitude = self.attitude();
        c.raw.preset = preset;
        if preset == Preset::Camera {
            // as `psns render --preset camera --exposure-us X` or `--auto-exposure`
            let mut sensor = crate::sensor::SensorConfig::preset(Preset::Camera);
            sensor.exposure = match self.raw12_exposure_us {
                Some(us) => crate::sensor::Exposure::Fixed { us },
                None => crate::sensor::Exposure::auto(),
            };
            c.raw.sensor = Some(sensor);
        }
        c.raw.seed = self.seed;
        c.raw.frame_index = self.frame_index;
        c.raw.sky_grid = self.sky_grid;
        if self.soft_clouds {
            c.raw.soft_clouds = Some(crate::sky::clouds::SoftClouds::default());
        }
        c
    }

    /// The row of `labels.csv` (columns of [`LABEL_HEADER`]); `raw12` says whether the 12-bit
    /// frame is written (its exposure column is empty otherwise).
    pub fn label_row_with(&self, raw12: bool) -> String {
        let exposure = match (raw12, self.raw12_exposure_us) {
            (false, _) => String::new(),
            (true, None) => "auto".into(),
            (true, Some(us)) => us.to_string(),
        };
        format!(
            "{},{exposure},{}",
            self.label_row_base(),
            u8::from(self.soft_clouds)
        )
    }

    /// The row of `labels.csv` of a dataset without the 12-bit frame.
    pub fn label_row(&self) -> String {
        self.label_row_with(false)
    }

    fn label_row_base(&self) -> String {
        let v = self.sun_camera();
        let frame = match self.frame {
            AttitudeFrame::Solar => "solar",
            AttitudeFrame::Enu => "enu",
        };
        let (t, lat, lon) = match &self.when {
            Some(w) => (
                w.time_utc.clone(),
                w.lat_deg.to_string(),
                w.lon_deg.to_string(),
            ),
            None => Default::default(),
        };
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{t},{lat},{lon}",
            self.split.name(),
            self.file(),
            self.yaw_deg,
            self.pitch_deg,
            self.roll_deg,
            frame,
            self.focal_length_mm,
            self.pixel_pitch_um,
            self.sun_altitude_deg,
            self.sun_azimuth_deg,
            self.turbidity,
            self.wavelength_nm,
            self.albedo,
            self.seed,
            self.frame_index,
            v.x,
            v.y,
            v.z,
            self.split.preset(),
            self.width,
            self.height,
            self.sky_grid,
            self.number
        )
    }
}

/// `--shard K/N`: this process builds the samples whose position in the canonical order `j`
/// (0-based) has `j mod N = K − 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based shard number K.
    pub k: u64,
    /// Number of shards N.
    pub n: u64,
}

/// Most shards.
pub const MAX_SHARDS: u64 = 1_000_000;

impl Shard {
    /// The whole dataset.
    pub const ALL: Shard = Shard { k: 1, n: 1 };

    /// Whether sample position `j` (0-based, canonical order) is in this shard.
    pub fn contains(&self, j: u64) -> bool {
        j % self.n == self.k - 1
    }
}

impl std::str::FromStr for Shard {
    type Err = Error;
    /// Parses `K/N` with 1 ≤ K ≤ N ≤ 1000000.
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || Error::OutOfRange {
            name: "shard".into(),
            value: s.into(),
            allowed: format!("K/N with 1 <= K <= N <= {MAX_SHARDS}, e.g. 2/8"),
        };
        let (k, n) = s.trim().split_once('/').ok_or_else(bad)?;
        let k: u64 = k.trim().parse().map_err(|_| bad())?;
        let n: u64 = n.trim().parse().map_err(|_| bad())?;
        if k == 0 || n == 0 || k > n || n > MAX_SHARDS {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> DatasetConfig {
        DatasetConfig::from_toml(
            "seed = 7\nwidth = 64\nheight = 48\n[splits]\nNFPI = 3\nTGNIICPI = 2\n",
            "test",
        )
        .unwrap()
    }

    /// The `projection` and `lens` keys reach every sample's scene (and so its render); absent,
    /// the projection is rectilinear and the lens each preset's; a bad name is refused by name.
    #[test]
    fn projection_and_lens_keys_reach_the_samples() {
        use crate::camera::{Lens, Projection};
        let t = tiny();
        let s = t.sample(Split::Nfpi, 1).unwrap().scene(Preset::Nfpi);
        assert_eq!(s.camera.intrinsics.projection, Projection::Rectilinear);
        assert_eq!(s.intrinsics().lens, Some(Lens::Pinhole));
        let d = DatasetConfig::from_toml(
            "seed = 7\nwidth = 64\nheight = 48\nprojection = \"equisolid\"\nlens = \"ideal\"\n[splits]\nNFPI = 1\n",
            "test",
        )
        .unwrap();
        let s = d.sample(Split::Nfpi, 1).unwrap().scene(Preset::Nfpi);
        assert_eq!(s.camera.intrinsics.projection, Projection::Equisolid);
        assert_eq!(s.intrinsics().lens, Some(Lens::Ideal));
        let back = DatasetConfig::from_toml(&d.to_toml(), "round trip").unwrap();
        assert_eq!(back, d);
        let e = DatasetConfig::from_toml("projection = \"fish\"\n", "bad")
            .unwrap_err()
            .to_string();
        assert!(e.contains("fish") && e.contains("equisolid"), "{e}");
    }

    #[test]
    fn default_is_psns_at_full_size_and_round_trips() {
        let d = DatasetConfig::default();
        d.validate().unwrap();
        assert_eq!(d.total(), 138_000);
        assert_eq!((d.width, d.height), (2448, 2048));
        assert_eq!(d.split_counts().len(), 6);
        let back = DatasetConfig::from_toml(&d.to_toml(), "round trip").unwrap();
        assert_eq!(back, d);
        let t = tiny();
        assert_eq!(DatasetConfig::from_toml(&t.to_toml(), "x").unwrap(), t);
    }

    #[test]
    fn draws_depend_on_seed_and_index_only() {
        let c = tiny();
        let all: Vec<Sample> = c.plan().unwrap();
        assert_eq!(all.len(), 5);
        // the same sample drawn alone, in another order, equals the one in the full list
        assert_eq!(c.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
        assert_eq!(all[4].frame_index, 5 * SPLIT_STRIDE + 2);
        // another split's count does not move this split's samples
        let mut c2 = c.clone();
        c2.splits.insert("NFPI".into(), 100);
        assert_eq!(c2.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
        // another seed does
        let mut c3 = c.clone();
        c3.seed = 8;
        assert_ne!(c3.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
        // golden: the draw derivation is part of the dataset format
        assert_eq!(all[0].stem(), GOLDEN_STEM, "{}", all[0].stem());
        for s in &all {
            assert!((0.0..=359.9).contains(&s.yaw_deg));
            assert_eq!(s.yaw_deg, round_decimal(s.yaw_deg, 1));
            assert_eq!(s.albedo, round_decimal(s.albedo, 2));
            assert!((1.7..=10.0).contains(&s.turbidity));
        }
    }
    const GOLDEN_STEM: &str = "N1_172.8_0_0_4_16.4_8.8_392_0.2";

    #[test]
    fn grid_draws_cover_the_grid_and_print_as_decimals() {
        let d = uniform(1.7, 10.0, 0.1);
        let mut seen = std::collections::BTreeSet::new();
        for i in 0..20_000 {
            let mut r = crate::rng::dataset_rng(1, i, 7);
            let v = d.draw(&mut r, 0.5);
            assert!((1.7..=10.0).contains(&v), "{v}");
            let s = format!("{v}");
            assert!(decimals(v) <= 1 && !s.contains('e'), "{s}");
            seen.insert(s);
        }
        assert_eq!(seen.len(), 84); // 1.7, 1.8, ..., 10
        assert!(seen.contains("10") && seen.contains("1.7"));
        // a grid through zero from below never prints "-0"
        let d = uniform(-0.3, 0.3, 0.1);
        let mut seen = std::collections::BTreeSet::new();
        for i in 0..500 {
            let mut r = crate::rng::dataset_rng(1, i, 2);
            seen.insert(format!("{}", d.draw(&mut r, 0.1)));
        }
        assert_eq!(seen.len(), 7, "{seen:?}");
        assert!(seen.contains("0") && !seen.contains("-0"), "{seen:?}");
        assert_eq!(format!("{}", round_decimal(-1e-17, 1)), "0");
        let c = Dist::Choice(vec![400.0, 550.0]);
        let mut r = crate::rng::dataset_rng(1, 0, 8);
        assert!([400.0, 550.0].contains(&c.draw(&mut r, 1.0)));
    }

    #[test]
    fn bad_descriptions_name_the_key_and_range() {
        let cases = [
            ("turbidty = 3\n", "turbidty"),
            (
                "[turbidity]\nmin = 1\nmax = 5\n",
                "turbidity.min = 1 is out of range (allowed 1.7..10)",
            ),
            (
                "[albedo]\nmin = 0.5\nmax = 0.2\n",
                "albedo.max = 0.2 is out of range (allowed 0.5..1)",
            ),
            ("[albedo]\nmin = 0\nmax = 1\nstp = 0.1\n", "stp"),
            (
                "wavelength_nm = 300\n",
                "wavelength_nm = 300 is out of range (allowed 380..720)",
            ),
            (
                "width = 66\n",
                "width = 66 is out of range (allowed a non-zero multiple of 4)",
            ),
            ("[splits]\nNFP = 3\n", "splits = NFP is out of range"),
            (
                "[splits]\nNFPI = 0\n",
                "splits.NFPI = 0 is out of range (allowed 1..10000000)",
            ),
            ("sky_grid = 0\n", "sky_grid = 0"),
            ("[outputs]\nraw = true\n", "raw"),
            ("[yaw_deg]\nvalues = []\n", "yaw_deg.values is empty"),
            ("[yaw_deg]\nmin = 1\n", "max"),
            ("frame = \"ned\"\n", "ned"),
            ("[outputs]\nraw12_exposure_us = 500\n", "add raw12 = true"),
            (
                "soft_clouds = 1.5\n",
                "soft_clouds = 1.5 is out of range (allowed 0..1)",
            ),
            (
                "[outputs]\nraw12 = true\nraw12_exposure_us = 5\n",
                "outputs.raw12_exposure_us = 5 is out of range (allowed 20..10000000)",
            ),
        ];
        for (text, want) in cases {
            let e = DatasetConfig::from_toml(text, "c.toml").unwrap_err();
            assert!(e.is_usage(), "{text}: {e}");
            assert!(e.to_string().contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn shard_parsing_and_partition() {
        assert_eq!("2/3".parse::<Shard>().unwrap(), Shard { k: 2, n: 3 });
        for bad in ["0/3", "4/3", "3", "a/b", "1/0", "-1/3", "1/2000000"] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(
                e.is_usage() && e.to_string().contains("1 <= K <= N"),
                "{bad}: {e}"
            );
        }
        // every position in exactly one of N shards
        for j in 0..30 {
            let owners = (1..=4).filter(|&k| Shard { k, n: 4 }.contains(j)).count();
            assert_eq!(owners, 1);
        }
    }

    #[test]
    fn label_row_has_every_column_and_the_scene_matches() {
        let c = tiny();
        let s = c.sample(Split::Nfpi, 1).unwrap();
        let row = s.label_row();
        assert_eq!(row.split(',').count(), LABEL_HEADER.split(',').count());
        assert!(row.starts_with(&format!("NFPI,NFPI/{}.png,", s.stem())));
        let v = s.sun_camera();
        assert!((v.length() - 1.0).abs() < 1e-12);
        let scene = s.scene(Preset::Nfpi);
        assert_eq!(scene.sun.resolve().unwrap(), s.sun());
        assert_eq!(scene.raw.frame_index, s.frame_index);
    }

    #[test]
    fn sun_from_times_and_places() {
        let text = "width = 64\nheight = 48\n[splits]\nNFPI = 20\n[sun_time]\nstart = \"2024-06-01T00:00:00Z\"\nend = \"2024-06-30T23:59:59Z\"\nlat_deg = 45\nlon_deg = { min = 0, max = 10 }\nmin_altitude_deg = 20\n";
        let c = DatasetConfig::from_toml(text, "t").unwrap();
        assert_eq!(DatasetConfig::from_toml(&c.to_toml(), "again").unwrap(), c);
        let plan = c.plan().unwrap();
        for s in &plan {
            let w = s.when.as_ref().unwrap();
            assert!(s.sun_altitude_deg >= 20.0 && s.sun_altitude_deg <= 90.0);
            assert_eq!(s.sun_altitude_deg, round_decimal(s.sun_altitude_deg, 3));
            // the label's sun is SPA's for the label's time and place, to 0.001 degree
            let t = crate::sun::parse_time(&w.time_utc).unwrap();
            let place = crate::sun::Place {
                lat_deg: w.lat_deg,
                lon_deg: w.lon_deg,
                height_m: 0.0,
            };
            let sun = crate::sun::spa(&t, &place, None, None).unwrap();
            assert!((90.0 - sun.zenith_deg - s.sun_altitude_deg).abs() <= 0.0005);
            assert!((sun.azimuth_deg - s.sun_azimuth_deg).abs() <= 0.0005);
            assert_eq!(w.lat_deg, 45.0);
            assert!(w.time_utc.starts_with("2024-06-"), "{}", w.time_utc);
            let row = s.label_row();
            assert!(
                row.ends_with(&format!(",{},45,{},,0", w.time_utc, w.lon_deg)),
                "{row}"
            );
        }
        // a polar night never has the sun up: refused, naming the key
        let polar = text.replace("lat_deg = 45", "lat_deg = -85");
        let c = DatasetConfig::from_toml(&polar, "t").unwrap();
        let e = c.plan().unwrap_err().to_string();
        assert!(
            e.contains("NFPI sample 1: sun_time: the sun was below min_altitude_deg = 20"),
            "{e}"
        );
        // both ways of giving the sun, a bad time, an end before the start
        let both = format!("sun_altitude_deg = 30\n{text}");
        let e = DatasetConfig::from_toml(&both, "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("either by sun_time or by sun_altitude_deg"),
            "{e}"
        );
        let bad = text.replace("2024-06-01T00:00:00Z", "June 1st");
        let e = DatasetConfig::from_toml(&bad, "t").unwrap_err().to_string();
        assert!(e.contains("sun_time.start: time 'June 1st'"), "{e}");
        let back = text.replace("2024-06-30T23:59:59Z", "2024-05-30T23:59:59Z");
        let e = DatasetConfig::from_toml(&back, "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sun_time.end = 2024-05-30T23:59:59Z is out of range"),
            "{e}"
        );
        let e = DatasetConfig::from_toml(&text.replace("= 45", "= 95"), "t").unwrap_err();
        assert!(e
            .to_string()
            .contains("sun_time.lat_deg = 95 is out of range (allowed -90..90)"));
    }
}
