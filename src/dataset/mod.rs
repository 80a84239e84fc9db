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
use crate::sky::cie::Radiance;
use crate::sky::{DopModel, PolarizationModel};
use crate::sun::SunPosition;
use rand::Rng;
use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::fmt;

mod dist;
mod plan;
mod sample;
#[cfg(test)]
mod tests;
mod world;
pub use dist::*;
pub use plan::*;
pub use sample::*;
pub use world::*;

/// Frame-index stride between splits: sample `n` of split id `s` is frame `s · STRIDE + n`.
pub const SPLIT_STRIDE: u64 = 1_000_000_000;
/// Most samples in one split (so a description holds at most six times as many).
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
                allowed: Split::ALL.map(Split::name).join(", "),
            })
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
    /// Polarization model (`psns render --model`): a name or `{ values = [...] }`.
    pub model: Pick<PolarizationModel>,
    /// Sky radiance (`psns render --radiance`): `hosek`, `cie:N`, or a choice.
    pub radiance: Pick<Radiance>,
    /// Form of the Wang DOP (`psns render --dop-model`).
    pub dop_model: Pick<DopModel>,
    /// Distance of both neutral points from the sun, degrees (`psns render --neutral-distance`);
    /// with `babinet` and `brewster` absent too, each model's own law.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub neutral_distance: Option<Dist>,
    /// Babinet point's distance above the sun, degrees (`psns render --babinet`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub babinet: Option<Dist>,
    /// Brewster point's distance below the sun, degrees (`psns render --brewster`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brewster: Option<Dist>,
    /// Fraction of samples (0..1, drawn per sample) with soft unpolarized clouds blended into the
    /// sky (`psns render --clouds`). Above 0 every sample gets a camera seed of its own, drawn
    /// from the dataset seed and its frame index, so that the clouds (seeded by the camera seed)
    /// differ from sample to sample.
    pub soft_clouds: f64,
    /// A world preset: defaults of the world keys below, filled in by [`Self::from_toml`]
    /// ([`WorldPreset::fill`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldPreset>,
    /// A street canyon around every sample (`psns render --canyon`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub canyon: Option<CanyonDist>,
    /// Height of the camera above the ground, metres (`psns render --camera-height`).
    #[serde(skip_serializing_if = "Option::is_none", alias = "camera_height")]
    pub camera_height_m: Option<Dist>,
    /// Fraction of the sky covered by seeded clouds (`psns render --cloud-cover`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cloud_cover: Option<Dist>,
    /// The clouds' drift (`psns render --wind`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindDist>,
    /// Trees standing around the observer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trees: Option<TreesDist>,
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
            model: Pick::Fixed(PolarizationModel::default()),
            radiance: Pick::Fixed(Radiance::default()),
            dop_model: Pick::Fixed(DopModel::default()),
            neutral_distance: None,
            babinet: None,
            brewster: None,
            soft_clouds: 0.0,
            world: None,
            canyon: None,
            camera_height_m: None,
            cloud_cover: None,
            wind: None,
            trees: None,
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
        let mut cfg: DatasetConfig = toml::from_str(text).map_err(|e| {
            Error::Invalid(format!(
                "{what} is not a valid dataset description: {}",
                e.to_string().trim_end()
            ))
        })?;
        if let Some(p) = cfg.world {
            p.fill(&mut cfg);
        }
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
            return Err(Error::Invalid(format!(
                "splits is empty: list at least one folder ({}) with its number of samples",
                Split::ALL.map(Split::name).join(", ")
            )));
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
        self.validate_neutral_points()?;
        check_range("soft_clouds", self.soft_clouds, 0.0, 1.0)?;
        self.validate_world()?;
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

    /// The neutral-point keys: in range, `neutral_distance` or the other two, and both points
    /// for a model on Pan's law (as `psns render` takes them).
    fn validate_neutral_points(&self) -> Result<()> {
        let keys = [
            ("neutral_distance", &self.neutral_distance),
            ("babinet", &self.babinet),
            ("brewster", &self.brewster),
        ];
        for (k, d) in keys {
            if let Some(d) = d {
                d.validate(k, 0.0, 60.0)?;
            }
        }
        if self.neutral_distance.is_some() && (self.babinet.is_some() || self.brewster.is_some()) {
            return Err(Error::Invalid(
                "give the neutral points by neutral_distance or by babinet and brewster, not both"
                    .into(),
            ));
        }
        let given = |d: &Option<Dist>| d.as_ref().map(|_| 25.0);
        for model in self.model.values() {
            let mut sky = crate::sky::SkyParams {
                model,
                ..Default::default()
            };
            sky.fix_neutral_points(
                given(&self.neutral_distance),
                given(&self.babinet),
                given(&self.brewster),
                |k| k.to_string(),
            )?;
            sky.validate()?;
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
            model: self
                .model
                .draw(&mut crate::rng::dataset_rng(self.seed, frame_index, 16)),
            radiance: self
                .radiance
                .draw(&mut crate::rng::dataset_rng(self.seed, frame_index, 17)),
            dop_model: self.dop_model.draw(&mut crate::rng::dataset_rng(
                self.seed,
                frame_index,
                18,
            )),
            neutral_distance: None,
            babinet: None,
            brewster: None,
            when: None,
            raw12_exposure_us: None,
            soft_clouds: false,
            world: self.draw_world(frame_index)?,
        };
        let points = [
            (&self.neutral_distance, &mut sample.neutral_distance, 19),
            (&self.babinet, &mut sample.babinet, 20),
            (&self.brewster, &mut sample.brewster, 21),
        ];
        for (d, out, id) in points {
            if let Some(d) = d {
                let mut rng = crate::rng::dataset_rng(self.seed, frame_index, id);
                *out = Some(d.draw(&mut rng, 0.1));
            }
        }
        if self.soft_clouds > 0.0 {
            let mut rng = crate::rng::dataset_rng(self.seed, frame_index, 14);
            sample.soft_clouds = rng.random::<f64>() < self.soft_clouds;
        }
        if self.soft_clouds > 0.0 || self.world_seeded() {
            // a camera of its own (soft clouds, the world's clouds and the trees' gaps are
            // seeded by the camera seed), below 2^63
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

    /// The plan of every sample in canonical order, each drawn when needed ([`Plan`]), after
    /// checking that every sample can be drawn (the first that cannot is the error).
    pub fn plan(&self) -> Result<Plan<'_>> {
        let plan = Plan::new(self);
        plan.check()?;
        Ok(plan)
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
