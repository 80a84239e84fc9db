//! One sample: its parameters drawn from the seed and its frame index, its scene, its label row.

use super::*;

/// Draws a time and place with the sun at least `min_altitude_deg` high: the place and time,
/// and the sun's altitude and azimuth rounded to 0.001 degree.
pub(super) fn draw_sun_time(st: &SunTime, seed: u64, frame_index: u64) -> Result<(When, f64, f64)> {
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
    /// Polarization model.
    pub model: PolarizationModel,
    /// Sky radiance.
    pub radiance: Radiance,
    /// Form of the Wang DOP.
    pub dop_model: DopModel,
    /// Distance of both neutral points from the sun, degrees (`None`: not given).
    pub neutral_distance: Option<f64>,
    /// Babinet point's distance, degrees (`None`: not given).
    pub babinet: Option<f64>,
    /// Brewster point's distance, degrees (`None`: not given).
    pub brewster: Option<f64>,
    /// Time and place of the sun (descriptions with `sun_time`).
    pub when: Option<When>,
    /// Exposure of the 12-bit camera frame, µs; `None` = auto-exposure.
    pub raw12_exposure_us: Option<f64>,
    /// Soft clouds in the sky (`psns render --clouds`).
    pub soft_clouds: bool,
    /// The world around the camera (`None`: the description sets no world key).
    pub world: Option<crate::world::WorldConfig>,
}

/// Header of `labels.csv`.
pub const LABEL_HEADER: &str = concat!("split,file,yaw_deg,pitch_deg,roll_deg,frame,focal_length_mm,pixel_pitch_um,sun_altitude_deg,sun_azimuth_deg,turbidity,wavelength_nm,albedo,seed,frame_index,sun_cam_x,sun_cam_y,sun_cam_z,preset,width,height,sky_grid,number,time_utc,lat_deg,lon_deg,raw12_exposure_us,soft_clouds,model,radiance,dop_model,babinet,brewster,", super::world::world_label_header!());

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
        c.sky.model = self.model;
        c.sky.radiance = self.radiance;
        c.sky.dop_model = self.dop_model;
        c.sky
            .fix_neutral_points(self.neutral_distance, self.babinet, self.brewster, |k| {
                k.to_string()
            })
            .expect("the description's neutral points are checked with its models");
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
        if let Some(w) = &self.world {
            c.world = w.clone();
        }
        c
    }

    /// The row of `labels.csv` (columns of [`LABEL_HEADER`]); `raw12` says whether the 12-bit
    /// frame is written (its exposure column is empty otherwise). Fails only when the sample's
    /// world cannot be built for its class fractions.
    pub fn label_row_with(&self, raw12: bool) -> Result<String> {
        let exposure = match (raw12, self.raw12_exposure_us) {
            (false, _) => String::new(),
            (true, None) => "auto".into(),
            (true, Some(us)) => us.to_string(),
        };
        Ok(format!(
            "{},{exposure},{},{},{}",
            self.label_row_base(),
            u8::from(self.soft_clouds),
            self.sky_labels(),
            self.world_labels()?
        ))
    }

    /// The row of `labels.csv` of a dataset without the 12-bit frame.
    pub fn label_row(&self) -> Result<String> {
        self.label_row_with(false)
    }

    /// The sky columns: model, radiance, DOP form, and the neutral points in force (degrees from
    /// the sun when fixed, `pan` on Pan's law, empty for a model without them).
    fn sky_labels(&self) -> String {
        let sky = self.scene(self.split.preset()).sky;
        let (b, w) = if !sky.model.is_quartic() {
            (String::new(), String::new())
        } else if sky.law() == crate::sky::NeutralLaw::Pan {
            ("pan".into(), "pan".into())
        } else {
            (sky.babinet_deg.to_string(), sky.brewster_deg.to_string())
        };
        format!(
            "{},{},{},{b},{w}",
            self.model, self.radiance, self.dop_model
        )
    }

    pub(super) fn label_row_base(&self) -> String {
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
