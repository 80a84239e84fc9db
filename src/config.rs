//! Scene configuration: sun, sky, camera (and, for raw frames, the sensor), as one serde struct.
//!
//! The same structure is read from `--config FILE` (TOML or JSON), overridden by command-line
//! options, and written back as `scene.json`, so any run can be reproduced from its `scene.json`.
//! Fields under `derived` are outputs (resolved sun position, timings, counts); they are ignored on
//! input.

use crate::camera::{Attitude, Camera, Intrinsics, Lens};
use crate::error::{check_range, Error, Result};
use crate::sensor::packing::PixelFormat;
use crate::sensor::{Preset, SensorConfig};
use crate::sky::clouds::SoftClouds;
use crate::sky::{Sky, SkyParams};
use crate::sun::{self, Place, Refraction, SunPosition};
use crate::world::{World, WorldConfig};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How the sun position is given: directly, or from a UTC time and a place.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SunConfig {
    /// Sun zenith angle θ_s in degrees (direct input).
    pub zenith_deg: Option<f64>,
    /// Sun altitude (elevation) in degrees, 90 − θ_s (direct input, alternative to zenith).
    pub altitude_deg: Option<f64>,
    /// Compass azimuth A_s in degrees (direct input).
    pub azimuth_deg: Option<f64>,
    /// UTC time, ISO 8601 (e.g. `2003-10-17T19:30:30Z`): use SPA with `place`.
    pub time: Option<String>,
    /// Observer place for SPA.
    pub place: Option<Place>,
    /// ΔT in seconds for SPA (`None`: the crate's estimate).
    pub delta_t_s: Option<f64>,
    /// Refraction for SPA (`None`: geometric position, the default).
    pub refraction: Option<Refraction>,
}

/// Default direct sun: zenith 50°, azimuth 200° (the project's default scene).
pub const DEFAULT_SUN: SunPosition = SunPosition {
    zenith_deg: 50.0,
    azimuth_deg: 200.0,
};

impl SunConfig {
    /// Resolves the sun position. Does not check the zenith range (a timed sequence may have the sun
    /// below the horizon); [`Sky::new`] rejects that for a render.
    pub fn resolve(&self) -> Result<SunPosition> {
        if let Some(t) = &self.time {
            if self.zenith_deg.is_some()
                || self.altitude_deg.is_some()
                || self.azimuth_deg.is_some()
            {
                return Err(Error::Invalid(
                    "give the sun either as --time/--lat/--lon or as --sun-zenith/--sun-altitude/--sun-azimuth, not both"
                        .into(),
                ));
            }
            let place = self.place.ok_or_else(|| {
                Error::Invalid("--time needs --lat and --lon (the observer's place)".into())
            })?;
            let t = sun::parse_time(t)?;
            return sun::spa(&t, &place, self.delta_t_s, self.refraction);
        }
        if self.zenith_deg.is_some() && self.altitude_deg.is_some() {
            return Err(Error::Invalid(
                "give either --sun-zenith or --sun-altitude, not both".into(),
            ));
        }
        let zenith = match (self.zenith_deg, self.altitude_deg) {
            (Some(z), _) => check_range("sun-zenith", z, 0.0, 180.0)?,
            (None, Some(a)) => 90.0 - check_range("sun-altitude", a, -90.0, 90.0)?,
            (None, None) => DEFAULT_SUN.zenith_deg,
        };
        let az = match self.azimuth_deg {
            Some(a) => check_range("sun-azimuth", a, -360.0, 720.0)?,
            None => DEFAULT_SUN.azimuth_deg,
        };
        Ok(SunPosition::new(zenith, az))
    }
}

impl SunConfig {
    /// For the record (`scene.json`): a directly given sun with its defaults written out, so the
    /// file says where the sun was without reading `derived`. A timed sun is left as given.
    pub fn filled(&self) -> SunConfig {
        let mut s = self.clone();
        if s.time.is_none() {
            if s.zenith_deg.is_none() && s.altitude_deg.is_none() {
                s.zenith_deg = Some(DEFAULT_SUN.zenith_deg);
            }
            s.azimuth_deg = s.azimuth_deg.or(Some(DEFAULT_SUN.azimuth_deg));
        }
        s
    }

    /// Checks that the resolved `sun` is up, as a sky render needs; the error names the `--time`
    /// that put it below the horizon, if one did.
    pub fn check_up(&self, sun: SunPosition) -> Result<()> {
        sun.check_up().map_err(|e| match (&self.time, e) {
            (Some(t), Error::Invalid(m)) => Error::Invalid(format!("--time {t}: {m}")),
            (_, e) => e,
        })
    }
}

/// Camera: intrinsics and attitude.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Intrinsics, projection and lens.
    pub intrinsics: Intrinsics,
    /// Attitude (default: zenith-looking, zero yaw in the solar frame).
    pub attitude: Attitude,
}

/// Values computed during a run, written to `scene.json` for the record and ignored on input.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Derived {
    /// Resolved sun position.
    pub sun: Option<SunPosition>,
    /// Anything else the command wants to record (timings, counts, kappa).
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// What the camera looks at for raw frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// The sky model (default).
    #[default]
    Sky,
    /// A uniform flat field (EMVA 1288 calibration).
    Flat,
}

crate::names::name_table!(SceneKind {
    Sky => "sky",
    Flat => "flat",
});

/// Flat-field scene parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlatConfig {
    /// Radiance S0, W m⁻² sr⁻¹ nm⁻¹ (default 0.1).
    pub radiance: f64,
    /// Degree of linear polarization, 0..1 (default 0).
    pub dolp: f64,
    /// Angle of linear polarization, degrees in the sensor frame (default 0).
    pub aolp_deg: f64,
}

impl Default for FlatConfig {
    fn default() -> Self {
        FlatConfig {
            radiance: 0.1,
            dolp: 0.0,
            aolp_deg: 0.0,
        }
    }
}

impl FlatConfig {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        check_range("flat-radiance", self.radiance, 0.0, 1e6)?;
        check_range("flat-dolp", self.dolp, 0.0, 1.0)?;
        check_range("flat-aolp", self.aolp_deg, -360.0, 360.0)?;
        Ok(())
    }
}

/// Raw-frame settings: sensor preset and overrides, scene kind, seed and output format.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RawConfig {
    /// Sensor preset (default `camera`).
    pub preset: Preset,
    /// Full sensor configuration; `None` = the preset's.
    pub sensor: Option<SensorConfig>,
    /// Sky or flat field.
    pub scene: SceneKind,
    /// Flat-field parameters (for `scene = flat`).
    pub flat: FlatConfig,
    /// Camera seed: fixed patterns and noise (default 1).
    pub seed: u64,
    /// Which frame of that camera (temporal noise), default 0.
    pub frame_index: u64,
    /// Packed output format (stream payload, `raw.bin`).
    pub pixel_format: PixelFormat,
    /// Solar disc; `None` = on for the camera preset, off for the PSNS presets.
    pub sun_disc: Option<bool>,
    /// Soft unpolarized clouds added to the scene (off by default).
    pub soft_clouds: Option<SoftClouds>,
    /// Sky evaluated exactly every `sky_grid` pixels and interpolated between (1 = exact;
    /// default 16, see docs/performance.md for the accuracy cost).
    pub sky_grid: usize,
    /// Reference run: the sky at every pixel (implies `sky_grid = 1`) and the exact sensor path
    /// (per-row ChaCha8 streams, exact Poisson); default false = the fast path where it applies.
    pub exact: bool,
}

impl Default for RawConfig {
    fn default() -> Self {
        RawConfig {
            preset: Preset::Camera,
            sensor: None,
            scene: SceneKind::Sky,
            flat: FlatConfig::default(),
            seed: 1,
            frame_index: 0,
            pixel_format: PixelFormat::Mono16,
            sun_disc: None,
            soft_clouds: None,
            sky_grid: 16,
            exact: false,
        }
    }
}

impl RawConfig {
    /// The sensor in force: the explicit one or the preset's, with the band-pass filter centred
    /// on the sky model's wavelength.
    pub fn effective_sensor(&self, wavelength_nm: f64) -> SensorConfig {
        let mut s = self
            .sensor
            .clone()
            .unwrap_or_else(|| SensorConfig::preset(self.preset));
        s.filter_center_nm = wavelength_nm;
        s
    }

    /// The lens when the scene sets none (`camera.md` §2): `ideal` for the camera preset (a real
    /// rotationally symmetric lens), `pinhole` for the PSNS presets (the paper's eqs. (19)–(20)).
    pub fn lens(&self) -> Lens {
        if self.preset == Preset::Camera {
            Lens::Ideal
        } else {
            Lens::Pinhole
        }
    }

    /// Whether the solar disc is drawn.
    pub fn sun_disc_on(&self) -> bool {
        self.sun_disc.unwrap_or(self.preset == Preset::Camera)
    }
}

/// A full scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Sun position.
    pub sun: SunConfig,
    /// Sky model parameters.
    pub sky: SkyParams,
    /// Camera.
    pub camera: CameraConfig,
    /// Raw-frame (sensor) settings.
    pub raw: RawConfig,
    /// The world around the camera (empty: the open sky).
    #[serde(skip_serializing_if = "WorldConfig::is_empty")]
    pub world: WorldConfig,
    /// Outputs of the run that wrote this file (ignored on input).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub derived: Option<Derived>,
}

impl SceneConfig {
    /// Reads a TOML (`.toml`) or JSON (anything else that starts with `{`) scene file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, e))?;
        let empty = text
            .trim()
            .trim_start_matches('{')
            .trim_end_matches('}')
            .trim()
            .is_empty();
        if empty {
            // an empty file is a failed redirect or a typo far more often than a wish for defaults
            return Err(Error::Invalid(format!(
                "config {} sets nothing; give at least one setting, or leave out --config for the default scene",
                path.display()
            )));
        }
        let mut cfg: SceneConfig = if text.trim_start().starts_with('{') {
            serde_json::from_str(&text).map_err(|e| {
                Error::Invalid(format!(
                    "config {} is not a valid scene: {e}",
                    path.display()
                ))
            })?
        } else {
            toml::from_str(&text).map_err(|e| {
                Error::Invalid(format!(
                    "config {} is not a valid scene: {e}",
                    path.display()
                ))
            })?
        };
        cfg.derived = None;
        Ok(cfg)
    }

    /// The intrinsics with the lens resolved: the configured one, or the preset's
    /// ([`RawConfig::lens`]).
    pub fn intrinsics(&self) -> Intrinsics {
        let mut i = self.camera.intrinsics;
        i.lens = Some(i.lens.unwrap_or(self.raw.lens()));
        i
    }

    /// Resolves the sun, validates everything and builds the sky (with the world, at scene time
    /// 0) and the posed camera (lens resolved, [`Self::intrinsics`]).
    pub fn build(&self) -> Result<(Sky, Camera)> {
        self.build_at(0.0)
    }

    /// [`Self::build`] with the world's clouds `t_s` seconds into the scene.
    pub fn build_at(&self, t_s: f64) -> Result<(Sky, Camera)> {
        let sun = self.sun.resolve()?;
        self.sun.check_up(sun)?;
        let world = self.world_at(t_s)?;
        let sky = Sky::new(sun, &self.sky)?.with_world(world);
        let cam = Camera::new(self.intrinsics(), &self.camera.attitude, sun.azimuth_deg)?;
        Ok((sky, cam))
    }

    /// The world prepared with its clouds `t_s` seconds into the scene, its camera mask read
    /// and checked against the image size; seeded by the camera's seed unless it sets one.
    pub fn world_at(&self, t_s: f64) -> Result<World> {
        let mask = match &self.world.camera_mask {
            None => None,
            Some(p) => {
                let g = crate::io::read_gray(p)?;
                let i = &self.camera.intrinsics;
                if (g.image.width, g.image.height) != (i.width, i.height) {
                    return Err(Error::Invalid(format!(
                        "camera mask {} is {} x {} pixels; it must be the image's size, {} x {}",
                        p.display(),
                        g.image.width,
                        g.image.height,
                        i.width,
                        i.height
                    )));
                }
                let (w, h) = (g.image.width, g.image.height);
                Some((w, h, g.image.data.iter().map(|&v| (v != 0) as u8).collect()))
            }
        };
        World::new(&self.world, self.raw.seed, t_s, mask)
    }

    /// Pretty JSON of this scene.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("scene serializes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_round_trip() {
        let mut c = SceneConfig::default();
        c.sun.zenith_deg = Some(30.0);
        c.camera.attitude = Attitude::enu(10.0, 5.0, -2.0);
        c.derived = Some(Derived {
            sun: Some(SunPosition::new(30.0, 200.0)),
            ..Default::default()
        });
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("scene.json");
        std::fs::write(&p, c.to_json()).unwrap();
        let back = SceneConfig::load(&p).unwrap();
        c.derived = None;
        assert_eq!(back, c);
    }

    #[test]
    fn toml_scene_and_unknown_key() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.toml");
        std::fs::write(
            &p,
            "[sun]\nzenith_deg = 40\nazimuth_deg = 10\n[sky]\nturbidity = 3\n[camera.attitude]\nkind = \"euler\"\nframe = \"enu\"\nyaw_deg = 5\npitch_deg = 0\nroll_deg = 0\n",
        )
        .unwrap();
        let c = SceneConfig::load(&p).unwrap();
        assert_eq!(c.sky.turbidity, 3.0);
        assert_eq!(c.sun.resolve().unwrap(), SunPosition::new(40.0, 10.0));
        std::fs::write(&p, "[sky]\nturbidty = 3\n").unwrap();
        let e = SceneConfig::load(&p).unwrap_err().to_string();
        assert!(e.contains("turbidty"), "{e}");
    }

    #[test]
    fn sun_altitude_and_conflicts() {
        let s = SunConfig {
            altitude_deg: Some(40.0),
            ..Default::default()
        };
        assert_eq!(s.resolve().unwrap().zenith_deg, 50.0);
        let s = SunConfig {
            altitude_deg: Some(40.0),
            zenith_deg: Some(50.0),
            ..Default::default()
        };
        assert!(s.resolve().is_err());
        let s = SunConfig {
            time: Some("2003-10-17T19:30:30Z".into()),
            ..Default::default()
        };
        assert!(s.resolve().unwrap_err().to_string().contains("--lat"));
    }
}
