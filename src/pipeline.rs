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
use crate::sensor::{self, FastSink, FrameOptions, Radiance, RawFrame, Sensor, SensorConfig};
use crate::sky::{Sky, SkyParams};
use crate::sun::{self, Place, Refraction, SunPosition};
use crate::trajectory::Pose;
use crate::world::World;
use chrono::{DateTime, Utc};

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

    /// Frame `frame_index` for a sun position and attitude, without the ground truth (`truth`
    /// is 0 × 0). The fast path reads the sky row by row from a refined node grid
    /// ([`render::SkyGrid`]) into the fast sensor kernel, so no full-size Stokes planes are made;
    /// so do the PSNS presets (two passes over the grid: κ, then the codes), with the grid of
    /// `psns render` (tolerance [`render::GRID_TOLERANCE`]), giving the codes of
    /// [`Self::stokes`] + [`Self::frame_codes`]. Otherwise (`exact`, soft clouds, a flat field,
    /// or a configuration only the exact path models) this is [`Self::stokes`] +
    /// [`Self::frame_codes`]. `codes` is a buffer to reuse.
    pub fn frame_at(
        &self,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        frame_index: u64,
        codes: Vec<u16>,
    ) -> Result<(RawFrame, SceneInfo)> {
        self.frame_at_in(&self.cfg.sky, sun, attitude, t_s, frame_index, codes)
    }

    /// [`Self::frame_at`] and the frame's stream payload in `fmt` with its CRC-32 where it comes
    /// cheaply: when [`sensor::packing::codes_are_payload`] the payload is the codes themselves
    /// (`bytes` is left alone) and the fast path takes their CRC band by band while they are in
    /// cache (the other paths return `None`: the writer computes it, beside the next render);
    /// else `bytes` holds the packed codes and their CRC, taken chunk by chunk
    /// ([`sensor::packing::pack_crc32`]).
    #[allow(clippy::too_many_arguments)]
    pub fn frame_payload_at(
        &self,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        frame_index: u64,
        codes: Vec<u16>,
        fmt: sensor::packing::PixelFormat,
        bytes: &mut Vec<u8>,
    ) -> Result<(RawFrame, SceneInfo, Option<u32>)> {
        use sensor::packing;
        let codes_are_payload = packing::codes_are_payload(fmt);
        let sink = if codes_are_payload {
            FastSink::CodesCrc32
        } else {
            FastSink::None
        };
        let (f, info) = self.frame_at_sink(
            &self.cfg.sky,
            sun,
            attitude,
            t_s,
            frame_index,
            codes,
            0,
            sink,
        )?;
        let crc = if codes_are_payload {
            f.codes_crc32
        } else {
            Some(packing::pack_crc32(
                &f.codes.data,
                f.bit_depth,
                fmt,
                false,
                bytes,
            )?)
        };
        Ok((f, info, crc))
    }

    /// [`Self::frame_at`] under the sky `sky` instead of the configured one.
    pub fn frame_at_in(
        &self,
        sky: &SkyParams,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        frame_index: u64,
        codes: Vec<u16>,
    ) -> Result<(RawFrame, SceneInfo)> {
        self.frame_at_sink(
            sky,
            sun,
            attitude,
            t_s,
            frame_index,
            codes,
            0,
            FastSink::None,
        )
    }

    /// [`Self::frame_at`] with the codes after the first `lead` elements of `buf`, which are
    /// kept (room for a message header in front of the pixels, e.g. a ROS 2 `Image`'s CDR
    /// prefix: the pixels need no copy). The frame's `codes` is 0 × 0; the buffer comes back in
    /// [`RawFrame::lead_buffer`], its codes the same as [`Self::frame_at`]'s.
    pub fn frame_at_after(
        &self,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        frame_index: u64,
        buf: Vec<u16>,
        lead: usize,
    ) -> Result<(RawFrame, SceneInfo)> {
        let (mut f, info) = self.frame_at_sink(
            &self.cfg.sky,
            sun,
            attitude,
            t_s,
            frame_index,
            buf,
            lead,
            FastSink::None,
        )?;
        if lead == 0 {
            f.lead_buffer = Some(std::mem::take(&mut f.codes.data));
            f.codes = crate::image::Image::from_vec(0, 0, Vec::new());
        }
        Ok((f, info))
    }

    /// [`Self::frame_at_in`], with `sink` for the fast path's frames (the other paths ignore it
    /// and leave [`RawFrame::codes_crc32`] `None`), the codes after `lead` elements of `codes`
    /// ([`FrameOptions::lead`]).
    #[allow(clippy::too_many_arguments)]
    fn frame_at_sink(
        &self,
        sky: &SkyParams,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        frame_index: u64,
        codes: Vec<u16>,
        lead: usize,
        sink: FastSink,
    ) -> Result<(RawFrame, SceneInfo)> {
        let raw = &self.cfg.raw;
        let psns = self.sensor_cfg.psns.is_some() && !raw.exact;
        if !self.fast() && !psns {
            let (st, info) = self.stokes_in(sky, sun, attitude, t_s)?;
            let opts = FrameOptions::exact().into_codes_after(codes, lead);
            return Ok((
                self.sensor
                    .frame(Radiance::Planes(&st), frame_index, opts)?,
                info,
            ));
        }
        let up = (0.0..=90.0).contains(&sun.zenith_deg);
        if raw.scene == SceneKind::Sky && raw.soft_clouds.is_none() && raw.sky_grid >= 2 && up {
            let i = self.cfg.camera.intrinsics;
            let cam = Camera::new(i, attitude, sun.azimuth_deg)?;
            let sky = self.sky_for(sun, sky, t_s)?;
            let opts = StokesOptions {
                sun_disc: raw.sun_disc_on(),
            };
            let grid = render::SkyGrid::new(&sky, &cam, opts, raw.sky_grid, self.sky_tolerance());
            let info = SceneInfo {
                sun: Some(sun),
                sky_valid: true,
                sun_pixels: grid.sun_pixels(),
                ground_pixels: render::ground_pixel_count(&cam),
                enu_to_camera: Some(cam.enu_to_camera),
            };
            // a PSNS preset takes its own model whichever path is asked
            let opts = FrameOptions::fast()
                .into_codes_after(codes, lead)
                .with_sink(sink);
            let f = self
                .sensor
                .frame(Radiance::Rows(&grid), frame_index, opts)?;
            return Ok((f, info));
        }
        let (st, info) = self.stokes_in(sky, sun, attitude, t_s)?;
        let opts = if psns {
            FrameOptions::exact().into_codes_after(codes, lead)
        } else {
            FrameOptions::fast()
                .into_codes_after(codes, lead)
                .with_sink(sink)
        };
        let f = self
            .sensor
            .frame(Radiance::Planes(&st), frame_index, opts)?;
        Ok((f, info))
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

    /// The raw frame of a Stokes scene by the path `psns render --raw` and `psns stream` take:
    /// the fast sensor unless `exact` or a configuration only the exact path models (see
    /// [`Self::fast`]); with the ground truth when `truth` (else `truth` is 0 × 0).
    pub fn frame_of(&self, st: &StokesImage, frame_index: u64, truth: bool) -> Result<RawFrame> {
        if self.fast() {
            let mut f =
                self.sensor
                    .frame(Radiance::Planes(st), frame_index, FrameOptions::fast())?;
            if truth {
                f.truth = self.sensor.truth_for(st, f.exposure_us);
            }
            Ok(f)
        } else if truth {
            self.frame(st, frame_index)
        } else {
            self.frame_codes(st, frame_index)
        }
    }

    /// The raw frame of a Stokes scene by the exact path.
    pub fn frame(&self, stokes: &StokesImage, frame_index: u64) -> Result<RawFrame> {
        let opts = FrameOptions::exact().with_truth();
        self.sensor
            .frame(Radiance::Planes(stokes), frame_index, opts)
    }

    /// The raw frame of a Stokes scene by the exact path without the ground truth (`truth` is
    /// 0 × 0).
    pub fn frame_codes(&self, stokes: &StokesImage, frame_index: u64) -> Result<RawFrame> {
        let opts = FrameOptions::exact();
        self.sensor
            .frame(Radiance::Planes(stokes), frame_index, opts)
    }

    /// The configured scene's frame `cfg.raw.frame_index` (sun and attitude from the config),
    /// with its ground truth; by the fast path unless `exact` (see [`Self::fast`]).
    pub fn render_configured(&self) -> Result<(RawFrame, SceneInfo)> {
        self.render_configured_timed().map(|(f, i, _)| (f, i))
    }

    /// [`Self::render_configured`], also returning the seconds spent on the scene (the rest of
    /// the call is the sensor).
    pub fn render_configured_timed(&self) -> Result<(RawFrame, SceneInfo, f64)> {
        let sun = self.cfg.sun.resolve()?;
        let t0 = std::time::Instant::now();
        let (st, info) = self.stokes(sun, &self.cfg.camera.attitude)?;
        let scene_s = t0.elapsed().as_secs_f64();
        if self.cfg.raw.scene == SceneKind::Sky && !info.sky_valid {
            // a static render needs the sun up (sky.md §8)
            self.cfg.sun.check_up(sun)?;
        }
        Ok((
            self.frame_of(&st, self.cfg.raw.frame_index, true)?,
            info,
            scene_s,
        ))
    }
}

/// Trajectory start time when neither the caller nor the scene's `sun.time` gives one.
pub const DEFAULT_START_TIME: &str = "2025-06-21T10:00:00Z";

/// Seconds as whole nanoseconds (rounded), refused when they do not fit the stream clock.
pub fn seconds_to_ns(t_s: f64) -> Result<i64> {
    let ns = (t_s * 1e9).round();
    if !(ns.is_finite() && ns.abs() < 9.0e18) {
        return Err(crate::error::Error::Invalid(format!(
            "trajectory time {} s does not fit the stream clock",
            crate::error::num(t_s)
        )));
    }
    Ok(ns as i64)
}

/// Where a frame's sun comes from.
#[derive(Clone, Copy, Debug)]
enum SunSource {
    /// Given directly by the scene: fixed.
    Fixed(SunPosition),
    /// SPA at the frame's time, at the pose's place or else this one (None: the pose must carry
    /// one).
    Spa(Option<Place>),
}

/// The clock and the sun of frames driven by a trajectory (`psns stream`, `psns gige`): a pose
/// at `t_s` starts its exposure at `start + t_s`, never at a host time, so the same options give
/// the same frames. The sun is the scene's when the scene gives it directly; with a place (the
/// scene's `sun.place` and `sun.time`, or the pose's lat/lon) it is NREL SPA at the time the
/// caller asks for (mid-exposure).
#[derive(Clone, Debug)]
pub struct SceneClock {
    sun: SunSource,
    place: Option<Place>,
    start: DateTime<Utc>,
    start_ns: i64,
    delta_t_s: Option<f64>,
    refraction: Option<Refraction>,
}

impl SceneClock {
    /// Time zero of the trajectory: `start_time`, else the scene's `sun.time`, else
    /// [`DEFAULT_START_TIME`].
    pub fn start_time(cfg: &SceneConfig, start_time: Option<&str>) -> Result<DateTime<Utc>> {
        let s = start_time
            .map(str::to_string)
            .or_else(|| cfg.sun.time.clone())
            .unwrap_or_else(|| DEFAULT_START_TIME.to_string());
        let t = sun::parse_time(&s)?;
        t.timestamp_nanos_opt().ok_or_else(|| {
            crate::error::Error::Invalid(format!("start time {s} is out of range"))
        })?;
        Ok(t)
    }

    /// The clock of `cfg` from `start`; `trajectory_has_place` when every pose carries a place
    /// (the scene's time and place must then be consistent with one).
    pub fn new(
        cfg: &SceneConfig,
        start: DateTime<Utc>,
        trajectory_has_place: bool,
    ) -> Result<Self> {
        let start_ns = start.timestamp_nanos_opt().ok_or_else(|| {
            crate::error::Error::Invalid(format!("start time {start} is out of range"))
        })?;
        let sun = if cfg.sun.time.is_some() {
            // the scene's time and place must be consistent; the trajectory may bring the place
            let mut check = cfg.sun.clone();
            if trajectory_has_place && check.place.is_none() {
                check.place = Some(Place {
                    lat_deg: 0.0,
                    lon_deg: 0.0,
                    height_m: 0.0,
                });
            }
            check.resolve()?;
            SunSource::Spa(cfg.sun.place)
        } else {
            SunSource::Fixed(cfg.sun.resolve()?)
        };
        Ok(SceneClock {
            sun,
            place: cfg.sun.place,
            start,
            start_ns,
            delta_t_s: cfg.sun.delta_t_s,
            refraction: cfg.sun.refraction,
        })
    }

    /// Time zero.
    pub fn start(&self) -> DateTime<Utc> {
        self.start
    }

    /// When `pose`'s exposure starts, ns since the Unix epoch.
    pub fn exposure_start_ns(&self, pose: &Pose) -> Result<i64> {
        self.start_ns
            .checked_add(seconds_to_ns(pose.t_s)?)
            .ok_or_else(|| {
                crate::error::Error::Invalid(format!(
                    "trajectory time {} s does not fit the stream clock",
                    crate::error::num(pose.t_s)
                ))
            })
    }

    /// The place of `pose`: its own, else the scene's.
    pub fn place(&self, pose: &Pose) -> Option<Place> {
        pose.place.or(self.place)
    }

    /// The sun for `pose` at `t_ns` (ns since the Unix epoch): the scene's fixed sun, or SPA
    /// at the pose's place (else the scene's).
    pub fn sun_at(&self, pose: &Pose, t_ns: i64) -> Result<SunPosition> {
        // a place in the trajectory always means SPA; otherwise the scene decides
        let place = match (pose.place, self.sun) {
            (Some(p), _) => Some(p),
            (None, SunSource::Fixed(s)) => return Ok(s),
            (None, SunSource::Spa(p)) => p,
        };
        let place = place.ok_or_else(|| {
            crate::error::Error::Invalid(
                "a moving sun needs a place: give --lat/--lon or lat_deg,lon_deg,height_m columns"
                    .into(),
            )
        })?;
        let t = self.start + chrono::Duration::nanoseconds(t_ns - self.start_ns);
        sun::spa(&t, &place, self.delta_t_s, self.refraction)
    }
}
