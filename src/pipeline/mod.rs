//! The full chain for one camera: scene (sky or flat field) → sensor-frame Stokes radiance →
//! IMX250MZR raw frame with ground truth.
//!
//! A [`RawPipeline`] is built once per camera (it owns the sensor's fixed-pattern maps, which
//! depend only on the seed) and then renders any number of frames for changing sun positions and
//! attitudes — what `psns render --raw`, `psns stream` and the benchmarks share.

use crate::camera::{Attitude, Camera};
use crate::config::{RawConfig, SceneConfig, SceneKind};
use crate::error::Result;
use crate::image::StokesImage;
use crate::render::{self, StokesOptions};
use crate::sensor::{self, Sensor, SensorConfig};
use crate::sky::{Sky, SkyParams};
use crate::sun::SunPosition;
use crate::world::World;

mod clock;
mod request;
pub use clock::{seconds_to_ns, SceneClock, DEFAULT_START_TIME};
pub use request::{FrameRequest, FrameResult, Scene};

/// What one frame's scene looked like.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneInfo {
    /// Sun position used (None for a flat field).
    pub sun: Option<SunPosition>,
    /// False when the sun is below the horizon (the frame is rendered dark).
    pub sky_valid: bool,
    /// Pixels touched by the solar disc.
    pub sun_pixels: usize,
    /// Pixels looking at the ground.
    pub ground_pixels: usize,
    /// ENU → camera rotation used.
    pub enu_to_camera: Option<glam::DMat3>,
}

/// A camera with its fixed patterns, ready to render frames of a configured scene.
pub struct RawPipeline {
    cfg: SceneConfig,
    sensor_cfg: SensorConfig,
    sensor: Sensor,
    /// The last sky prepared, with its sun: a stream whose sun stands still (only the attitude
    /// changes) prepares it once.
    sky: std::sync::Mutex<Option<(SunPosition, SkyParams, std::sync::Arc<Sky>)>>,
    /// The world around the camera at scene time 0 (None: the open sky).
    world: Option<World>,
}

impl RawPipeline {
    /// Validates the scene and the sensor and builds the camera `cfg.raw.seed`.
    pub fn new(cfg: &SceneConfig) -> Result<Self> {
        let raw = &cfg.raw;
        let i = &cfg.camera.intrinsics;
        i.validate()?;
        sensor::check_size(i.width, i.height)?;
        cfg.sky.validate()?;
        cfg.camera.attitude.validate()?;
        crate::error::check_range("sky-grid", raw.sky_grid as f64, 1.0, 64.0)?;
        // the band-pass filter sits on the sky wavelength; the sensor model covers 380..720 nm
        crate::error::check_range(
            "wavelength (raw frames)",
            cfg.sky.wavelength_nm,
            380.0,
            720.0,
        )?;
        let sensor_cfg = raw.effective_sensor(cfg.sky.wavelength_nm);
        sensor_cfg.validate(i.width, i.height)?;
        if let Some(c) = &raw.soft_clouds {
            c.validate()?;
        }
        if raw.scene == SceneKind::Flat {
            raw.flat.validate()?;
        }
        let world = if cfg.world.is_empty() {
            None
        } else {
            Some(cfg.world_at(0.0)?)
        };
        let sensor = Sensor::new(&sensor_cfg, i, raw.seed)?;
        let mut cfg = cfg.clone();
        cfg.camera.intrinsics = cfg.intrinsics(); // the preset's lens unless one is set
        Ok(RawPipeline {
            cfg,
            sensor_cfg,
            sensor,
            sky: std::sync::Mutex::new(None),
            world,
        })
    }

    /// The scene configuration.
    pub fn config(&self) -> &SceneConfig {
        &self.cfg
    }

    /// The sensor configuration in force (preset + overrides, filter at the sky wavelength).
    pub fn sensor_config(&self) -> &SensorConfig {
        &self.sensor_cfg
    }

    /// The sensor.
    pub fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    /// The sky for `sun` and `params`, with the world (its clouds at scene time `t_s`): the one
    /// prepared for the previous call when the sun and the parameters are the same (`Sky::new`
    /// is a pure function of the sun and the sky parameters; the world's lighting is too).
    fn sky_for(
        &self,
        sun: SunPosition,
        params: &SkyParams,
        t_s: f64,
    ) -> Result<std::sync::Arc<Sky>> {
        let lock = || self.sky.lock().unwrap_or_else(|e| e.into_inner());
        let cached = lock()
            .as_ref()
            .filter(|(s, p, _)| *s == sun && p == params)
            .map(|(_, _, sky)| sky.clone());
        let sky = match cached {
            Some(sky) => sky,
            None => {
                // prepared outside the lock: threads rendering different suns do not wait
                let mut sky = Sky::new(sun, params)?;
                if let Some(w) = &self.world {
                    sky = sky.with_world(w.clone());
                }
                let sky = std::sync::Arc::new(sky);
                *lock() = Some((sun, params.clone(), sky.clone()));
                sky
            }
        };
        // drifting clouds: the same lighting, the clouds moved
        match &self.world {
            Some(w) if w.drifts() && t_s != 0.0 => Ok(std::sync::Arc::new(
                sky.as_ref().clone().with_clouds_at(w, t_s),
            )),
            _ => Ok(sky),
        }
    }

    /// Sensor-frame Stokes radiance for a sun position and attitude (ignored for a flat field).
    /// A sun below the horizon gives a dark (all-zero) scene with `sky_valid = false`.
    pub fn stokes(
        &self,
        sun: SunPosition,
        attitude: &Attitude,
    ) -> Result<(StokesImage, SceneInfo)> {
        self.stokes_in(&self.cfg.sky, sun, attitude, 0.0)
    }

    /// [`Self::stokes`] under the sky `sky` instead of the configured one (same camera and
    /// scene otherwise), `t_s` seconds into the scene (drifting clouds): one pipeline serves
    /// scenes that differ only in the sky.
    pub fn stokes_in(
        &self,
        sky_params: &SkyParams,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
    ) -> Result<(StokesImage, SceneInfo)> {
        let raw: &RawConfig = &self.cfg.raw;
        let i = self.cfg.camera.intrinsics;
        let mut info = SceneInfo::default();
        let mut st = match raw.scene {
            SceneKind::Flat => {
                info.sky_valid = true;
                sensor::flat_field(
                    i.width,
                    i.height,
                    raw.flat.radiance,
                    raw.flat.dolp,
                    raw.flat.aolp_deg,
                )?
            }
            SceneKind::Sky => {
                info.sun = Some(sun);
                let cam = Camera::new(i, attitude, sun.azimuth_deg)?;
                info.enu_to_camera = Some(cam.enu_to_camera);
                if !(0.0..=90.0).contains(&sun.zenith_deg) {
                    StokesImage::zeros(i.width, i.height)
                } else {
                    info.sky_valid = true;
                    let sky = self.sky_for(sun, sky_params, t_s)?;
                    let opts = StokesOptions {
                        sun_disc: raw.sun_disc_on(),
                    };
                    let step = if raw.exact { 1 } else { raw.sky_grid };
                    let (st, n) =
                        render::render_stokes_grid(&sky, &cam, opts, step, self.sky_tolerance());
                    info.sun_pixels = n;
                    info.ground_pixels = render::ground_pixel_count(&cam);
                    st
                }
            }
        };
        if let Some(c) = &raw.soft_clouds {
            crate::sky::clouds::apply_soft_clouds(&mut st, c, raw.seed ^ 0x636c_6f75_6473)?;
        }
        Ok((st, info))
    }

    /// Whether frames take the fast path ([`crate::sensor::fast`]): not `exact`, and a sensor
    /// configuration the fast path models.
    pub fn fast(&self) -> bool {
        !self.cfg.raw.exact && self.sensor.fast_capable()
    }

    /// The sky grid's interpolation tolerance for this pipeline's frames, the same for the
    /// Stokes planes ([`Self::stokes`]) and the rows the fast path reads, so that a frame made
    /// from either has the same codes: [`render::GRID_TOLERANCE`] for a PSNS preset (whose codes
    /// the sensor's noise does not set), else [`Self::grid_tolerance`].
    fn sky_tolerance(&self) -> f64 {
        match self.sensor_cfg.psns.is_some() {
            true => render::GRID_TOLERANCE,
            false => self.grid_tolerance(),
        }
    }

    /// Interpolation tolerance of the sky grid, relative to S0: a quarter of a tenth of the
    /// relative shot noise of a full well (2.4e-4 for the 10 500 e⁻ camera).
    pub fn grid_tolerance(&self) -> f64 {
        0.025 / self.sensor_cfg.full_well_e.sqrt()
    }
}
