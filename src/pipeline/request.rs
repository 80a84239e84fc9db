//! One way to make a frame: a [`FrameRequest`] in, a [`FrameResult`] (the raw frame and its
//! [`FrameRecord`]) out, the path chosen in one place ([`RawPipeline::render`]).

use super::{RawPipeline, SceneInfo};
use crate::camera::{camera_to_enu_quaternion, Attitude, Camera, Intrinsics, Projection};
use crate::config::SceneKind;
use crate::error::Result;
use crate::image::StokesImage;
use crate::record::FrameRecord;
use crate::render::{self, StokesOptions};
use crate::sensor::packing::{self, PixelFormat};
use crate::sensor::{FastSink, FrameOptions, Radiance, RawFrame};
use crate::sky::SkyParams;
use crate::sun::{Place, SunPosition};
use glam::{DMat3, DVec3};

/// What a frame shows.
#[derive(Clone, Copy, Debug)]
pub enum Scene<'a> {
    /// The configured scene (sky or flat field) for a sun and an attitude, `t_s` seconds into
    /// the scene (drifting clouds), under `sky` (None: the configured sky parameters).
    Sky {
        /// The sun at mid-exposure.
        sun: SunPosition,
        /// The camera's attitude.
        attitude: Attitude,
        /// Scene time, s.
        t_s: f64,
        /// Sky parameters in place of the configured ones.
        sky: Option<&'a SkyParams>,
    },
    /// Sensor-frame Stokes radiance given by the caller.
    Planes(&'a StokesImage),
}

/// What to render and what to return with it.
#[derive(Debug)]
pub struct FrameRequest<'a> {
    /// Frame index (the sensor's temporal noise is drawn from it).
    pub index: u64,
    /// What the frame shows.
    pub scene: Scene<'a>,
    /// Exposure start on the scene clock, ns since the Unix epoch (0: no clock).
    pub exposure_start_ns: i64,
    /// Where the camera is (recorded only; the sun is already resolved).
    pub place: Option<Place>,
    /// Return the noise-free ground truth in [`RawFrame::truth`] (else it is 0 × 0).
    pub truth: bool,
    /// Take the exact sensor path whatever the configuration.
    pub exact: bool,
    /// A code buffer to reuse; the codes start after its first `lead` elements, which are kept
    /// (room for a message header in front of the pixels: the frame's `codes` is then 0 × 0 and
    /// the buffer comes back in [`RawFrame::lead_buffer`]).
    pub codes: Vec<u16>,
    /// See `codes`.
    pub lead: usize,
    /// Also return the frame's payload in this stream format with its CRC-32
    /// ([`FrameResult::payload_crc`], [`FrameResult::bytes`]).
    pub payload: Option<PixelFormat>,
    /// A byte buffer to reuse for a packed payload.
    pub bytes: Vec<u8>,
}

impl<'a> FrameRequest<'a> {
    /// Frame `index` of the configured scene for `sun` and `attitude` at scene time 0, codes
    /// only.
    pub fn sky(index: u64, sun: SunPosition, attitude: Attitude) -> Self {
        FrameRequest::of(
            index,
            Scene::Sky {
                sun,
                attitude,
                t_s: 0.0,
                sky: None,
            },
        )
    }

    /// Frame `index` of the Stokes radiance `stokes`.
    pub fn planes(index: u64, stokes: &'a StokesImage) -> Self {
        FrameRequest::of(index, Scene::Planes(stokes))
    }

    fn of(index: u64, scene: Scene<'a>) -> Self {
        FrameRequest {
            index,
            scene,
            exposure_start_ns: 0,
            place: None,
            truth: false,
            exact: false,
            codes: Vec::new(),
            lead: 0,
            payload: None,
            bytes: Vec::new(),
        }
    }

    /// At scene time `t_s`, its exposure starting at `exposure_start_ns`, at `place`.
    pub fn at(mut self, t_s: f64, exposure_start_ns: i64, place: Option<Place>) -> Self {
        if let Scene::Sky { t_s: t, .. } = &mut self.scene {
            *t = t_s;
        }
        self.exposure_start_ns = exposure_start_ns;
        self.place = place;
        self
    }

    /// Under the sky parameters `sky` instead of the configured ones.
    pub fn under(mut self, params: &'a SkyParams) -> Self {
        if let Scene::Sky { sky, .. } = &mut self.scene {
            *sky = Some(params);
        }
        self
    }

    /// With the ground truth.
    pub fn with_truth(mut self) -> Self {
        self.truth = true;
        self
    }

    /// By the exact sensor path.
    pub fn exact(mut self) -> Self {
        self.exact = true;
        self
    }

    /// Into `codes`, after its first `lead` elements.
    pub fn into_codes(mut self, codes: Vec<u16>, lead: usize) -> Self {
        self.codes = codes;
        self.lead = lead;
        self
    }

    /// With the payload in `fmt` (packed into `bytes` unless the codes are the payload).
    pub fn with_payload(mut self, fmt: PixelFormat, bytes: Vec<u8>) -> Self {
        self.payload = Some(fmt);
        self.bytes = bytes;
        self
    }
}

/// A rendered frame with its record.
#[derive(Debug)]
pub struct FrameResult {
    /// The raw frame.
    pub frame: RawFrame,
    /// Everything known about it.
    pub record: FrameRecord,
    /// The payload's CRC-32 when asked for and it came cheaply (`None`: the caller takes it).
    pub payload_crc: Option<u32>,
    /// The packed payload when the codes are not the payload (else the request's buffer).
    pub bytes: Vec<u8>,
    /// Seconds spent on the scene's radiance (the rest is the sensor's).
    pub scene_seconds: f64,
}

impl RawPipeline {
    /// The frame `req` asks for, with its record. The one place the path is chosen:
    /// - Stokes planes go to the fast sensor unless `exact` or a configuration only the exact
    ///   path models ([`Self::fast`]; the ground truth from the same planes);
    /// - a sky frame without its truth, on the fast path or of a PSNS preset, is read row by
    ///   row from the refined node grid ([`render::SkyGrid`]): no full-size planes;
    /// - any other sky frame makes the sky's planes ([`Self::stokes_in`]) and goes the first way.
    ///
    /// The planes and the rows come from one grid tolerance, so a frame has the same codes
    /// whichever way it is made.
    pub fn render(&self, req: FrameRequest) -> Result<FrameResult> {
        let FrameRequest {
            index,
            scene,
            exposure_start_ns,
            place,
            truth,
            exact,
            codes,
            lead,
            payload,
            mut bytes,
        } = req;
        let codes_are_payload = payload.is_some_and(packing::codes_are_payload);
        let sink = match codes_are_payload && lead == 0 {
            true => FastSink::CodesCrc32,
            false => FastSink::None,
        };
        let buf = (codes, lead);
        let (frame, info, scene_seconds, sky) = match scene {
            Scene::Planes(st) => {
                let f = self.planes_frame(st, index, truth, exact, buf, sink)?;
                (f, SceneInfo::default(), 0.0, None)
            }
            Scene::Sky {
                sun,
                attitude,
                t_s,
                sky,
            } => {
                let params = sky.unwrap_or(&self.cfg.sky);
                let on_grid = !truth && !exact && self.grid_rows(sun);
                let (f, info, scene_s) = if on_grid {
                    let (f, info) =
                        self.grid_frame(params, sun, &attitude, t_s, index, buf, sink)?;
                    (f, info, 0.0)
                } else {
                    let t0 = std::time::Instant::now();
                    let (st, info) = self.stokes_in(params, sun, &attitude, t_s)?;
                    let scene_s = t0.elapsed().as_secs_f64();
                    let f = self.planes_frame(&st, index, truth, exact, buf, sink)?;
                    (f, info, scene_s)
                };
                (f, info, scene_s, Some((sun, attitude, t_s, params)))
            }
        };
        let payload_crc = match payload {
            Some(_) if lead > 0 => None,
            Some(_) if codes_are_payload => frame.codes_crc32,
            Some(fmt) => Some(packing::pack_crc32(
                &frame.codes.data,
                frame.bit_depth,
                fmt,
                false,
                &mut bytes,
            )?),
            None => None,
        };
        let mut record = FrameRecord {
            frame_index: index,
            exposure_start_ns,
            exposure_end_ns: exposure_start_ns
                .saturating_add(super::seconds_to_ns(frame.exposure_us * 1e-6)?),
            exposure_us: frame.exposure_us,
            auto_exposed: frame.auto_exposed,
            exposure_clipped: frame.exposure_clipped,
            gain_db: frame.gain_db,
            bit_depth: frame.bit_depth,
            black_level_dn: frame.black_level_dn,
            dn_per_electron: frame.dn_per_electron,
            temperature_c: self.sensor_cfg.temperature_c,
            saturated: frame.saturated,
            sky_valid: info.sky_valid,
            sun_disc_pixels: info.sun_pixels,
            ground_pixels: info.ground_pixels,
            lat_deg: place.map_or(0.0, |p| p.lat_deg),
            lon_deg: place.map_or(0.0, |p| p.lon_deg),
            height_m: place.map_or(0.0, |p| p.height_m),
            ..Default::default()
        };
        if let Some((sun, attitude, t_s, params)) = sky {
            let intr = &self.cfg.camera.intrinsics;
            let m = attitude.enu_to_camera(sun.azimuth_deg);
            let sun_c = m * sun.vector();
            record.t_s = t_s;
            record.sun_azimuth_deg = sun.azimuth_deg;
            record.sun_zenith_deg = sun.zenith_deg;
            record.sun_camera = sun_c.to_array();
            record.attitude_wxyz = camera_to_enu_quaternion(&m);
            record.sun_in_view =
                sun_in_view(intr, sun_c, sun.elevation_deg()) || info.sun_pixels > 0;
            record.ground_in_view = ground_in_view(intr, &m);
            record.turbidity = params.turbidity as f32;
            record.albedo = params.albedo as f32;
            record.class_fractions = self.class_fractions(sun, &attitude, t_s, params, &info)?;
        }
        Ok(FrameResult {
            frame,
            record,
            payload_crc,
            bytes,
            scene_seconds,
        })
    }

    /// The request of the configured scene's frame (`cfg.raw.frame_index`, the configured sun
    /// and attitude) with its ground truth, as `psns render --raw` makes it; refused when a sky
    /// scene's sun is down.
    pub fn configured_request(&self) -> Result<FrameRequest<'static>> {
        let sun = self.cfg.sun.resolve()?;
        if self.cfg.raw.scene == SceneKind::Sky {
            // a static render needs the sun up (sky.md §8)
            self.cfg.sun.check_up(sun)?;
        }
        let req = FrameRequest::sky(self.cfg.raw.frame_index, sun, self.cfg.camera.attitude);
        Ok(req.with_truth())
    }

    /// Whether a sky frame can be read from the node grid row by row.
    fn grid_rows(&self, sun: SunPosition) -> bool {
        let raw = &self.cfg.raw;
        let psns = self.sensor_cfg.psns.is_some() && !raw.exact;
        (self.fast() || psns)
            && raw.scene == SceneKind::Sky
            && raw.soft_clouds.is_none()
            && raw.sky_grid >= 2
            && (0.0..=90.0).contains(&sun.zenith_deg)
    }

    /// A sky frame read row by row from the node grid (see [`Self::grid_rows`]).
    #[allow(clippy::too_many_arguments)]
    fn grid_frame(
        &self,
        params: &SkyParams,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        index: u64,
        (codes, lead): (Vec<u16>, usize),
        sink: FastSink,
    ) -> Result<(RawFrame, SceneInfo)> {
        let raw = &self.cfg.raw;
        let cam = Camera::new(self.cfg.camera.intrinsics, attitude, sun.azimuth_deg)?;
        let sky = self.sky_for(sun, params, t_s)?;
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
        let f = self.sensor.frame(Radiance::Rows(&grid), index, opts)?;
        Ok((f, info))
    }

    /// The frame of Stokes planes: the fast sensor unless `exact` or a configuration only the
    /// exact path models.
    fn planes_frame(
        &self,
        st: &StokesImage,
        index: u64,
        truth: bool,
        exact: bool,
        (codes, lead): (Vec<u16>, usize),
        sink: FastSink,
    ) -> Result<RawFrame> {
        if self.fast() && !exact {
            let opts = FrameOptions::fast()
                .into_codes_after(codes, lead)
                .with_sink(sink);
            let mut f = self.sensor.frame(Radiance::Planes(st), index, opts)?;
            if truth {
                f.truth = self.sensor.truth_for(st, f.exposure_us);
            }
            return Ok(f);
        }
        let mut opts = FrameOptions::exact().into_codes_after(codes, lead);
        if truth {
            opts = opts.with_truth();
        }
        self.sensor.frame(Radiance::Planes(st), index, opts)
    }

    /// The fraction of the image in each class when a world is around the camera and the sun
    /// is up: `psns render`'s class image on every [`render::class_stride`]-th pixel.
    fn class_fractions(
        &self,
        sun: SunPosition,
        attitude: &Attitude,
        t_s: f64,
        params: &SkyParams,
        info: &SceneInfo,
    ) -> Result<Option<[f64; 6]>> {
        if self.world.is_none() || self.cfg.raw.scene != SceneKind::Sky || !info.sky_valid {
            return Ok(None);
        }
        let cam = Camera::new(self.cfg.camera.intrinsics, attitude, sun.azimuth_deg)?;
        let sky = self.sky_for(sun, params, t_s)?;
        let i = &self.cfg.camera.intrinsics;
        let stride = render::class_stride(i.width, i.height);
        let sun_disc = self.cfg.raw.sun_disc_on();
        let class = render::class_image_every(&sky, &cam, sun_disc, stride);
        Ok(Some(render::fractions(&class)))
    }
}

/// The sun's centre projects inside the image (and the sun is above the horizon).
fn sun_in_view(intr: &Intrinsics, sun_c: DVec3, elevation_deg: f64) -> bool {
    if elevation_deg < 0.0 {
        return false;
    }
    match intr.project(sun_c) {
        Some((c, r)) => {
            (-0.5..=intr.width as f64 - 0.5).contains(&c)
                && (-0.5..=intr.height as f64 - 0.5).contains(&r)
        }
        None => false,
    }
}

/// Some pixel looks below the horizon. The up component of a ray is linear over the image plane,
/// so its minimum over the image is at a corner.
/// A fisheye's horizon is curved: its pixels are checked every 4 pixels and along the border.
fn ground_in_view(intr: &Intrinsics, enu_to_camera: &DMat3) -> bool {
    let cam_to_enu = enu_to_camera.transpose();
    let below = |c: f64, r: f64| intr.ray(c, r).is_some_and(|d| (cam_to_enu * d).z < 0.0);
    let (w, h) = (intr.width as f64 - 0.5, intr.height as f64 - 0.5);
    if intr.projection == Projection::Rectilinear {
        return [(-0.5, -0.5), (w, -0.5), (-0.5, h), (w, h)]
            .iter()
            .any(|&(c, r)| below(c, r));
    }
    let (wu, hu) = (intr.width, intr.height);
    let cols = (0..wu).step_by(4).chain([wu - 1]);
    cols.flat_map(|c| (0..hu).step_by(4).chain([hu - 1]).map(move |r| (c, r)))
        .any(|(c, r)| below(c as f64, r as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ground_in_view_by_corners() {
        let i = Intrinsics {
            width: 64,
            height: 48,
            pixel_pitch_um: 130.0,
            ..Default::default()
        };
        let up = Attitude::enu(0.0, 0.0, 0.0).enu_to_camera(0.0);
        assert!(!ground_in_view(&i, &up));
        let tilted = Attitude::enu(0.0, 80.0, 0.0).enu_to_camera(0.0);
        assert!(ground_in_view(&i, &tilted));
    }

    #[test]
    fn sun_at_zenith_is_in_view() {
        let i = Intrinsics {
            width: 64,
            height: 48,
            pixel_pitch_um: 130.0,
            ..Default::default()
        };
        let m = Attitude::enu(0.0, 0.0, 0.0).enu_to_camera(0.0);
        let s = SunPosition::new(1.0, 100.0);
        assert!(sun_in_view(&i, m * s.vector(), s.elevation_deg()));
        let s = SunPosition::new(85.0, 100.0);
        assert!(!sun_in_view(&i, m * s.vector(), s.elevation_deg()));
    }
}
