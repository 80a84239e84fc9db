//! Options of `psns heading` (and `psns.heading` in Python), and the estimator's setup they
//! describe for one image.

use super::{parsed, whole, SceneArgs};
use crate::camera::{Attitude, AttitudeFrame};
use crate::config::SceneConfig;
use crate::demosaic::Method;
use crate::heading::{
    attitude_tilt_deg, estimate_codes, CodesEstimate, HeadingMethod, HeadingSetup,
};
use crate::image::Image;
use crate::io::LoadedRaw;
use crate::sensor::optics::RelativeIllumination;
use crate::sensor::{Preset, SensorConfig};
use crate::{Error, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// Options of `psns heading`.
#[derive(Args)]
pub struct HeadingArgs {
    /// Raw PNG/TIFF mosaic (codes), or a psns frame stream (file, FIFO, or - for stdin).
    pub input: PathBuf,
    /// Sun position (--sun-zenith/--sun-azimuth or --time/--lat/--lon), intrinsics
    /// (--width/--height/--focal-length/--pixel-pitch) and the known tilt (--pitch/--roll, ENU).
    /// A stream gives the sun per frame and the intrinsics in its header (options override them);
    /// an image without the sun in the options, the scene.json beside it (as `psns render` wrote
    /// it). --frame solar reports the yaw from the sun's azimuth instead of from north.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Demosaic method (the whole frame). Default: bilinear; a frame of more than about 640 000
    /// pixels (the full 2448 x 2048 sensor) is instead read as every k-th 2 x 2 superpixel only
    /// (k even, about 40 000 samples: what the estimators read), the rest never demosaicked.
    #[arg(long, value_parser = parsed::<Method>)]
    pub demosaic: Option<Method>,
    /// Estimator: model-fit (Berry field fitted from the eigenvector answer; default, the most
    /// accurate), eigen (sun vector), hough (solar meridian).
    #[arg(long, default_value = "model-fit", value_parser = parsed::<HeadingMethod>)]
    pub method: HeadingMethod,
    /// Model fit: also fit the sun's elevation (one neutral-point distance), starting from the
    /// given or the stream's sun; for a sun position known only roughly.
    #[arg(long)]
    pub fit_sun_elevation: bool,
    /// Significant bits of the codes in a PNG/TIFF (saturation is the top code); a stream says.
    #[arg(long, value_parser = whole)]
    pub bits: Option<u64>,
    /// Stream input: only the frame with this index (`--frame` is the attitude frame of the
    /// scene options).
    #[arg(long, value_parser = whole, value_name = "N")]
    pub index: Option<u64>,
    /// Stream input: take each frame's pitch and roll (never its yaw) from the frame's attitude,
    /// as an IMU would supply them; otherwise --pitch/--roll (default level).
    #[arg(long, conflicts_with_all = ["pitch", "roll"])]
    pub imu_tilt: bool,
    /// Stream input, for a consumer slower than the camera: always estimate the newest complete
    /// frame. A reader thread keeps draining the stream (so a slow estimate never blocks the
    /// producer's writes) and keeps only the latest frame; frames replaced before the estimator
    /// took them are skipped, counted in the summary and missing from the rows (frame_index
    /// shows the gaps).
    #[arg(long)]
    pub latest: bool,
    /// Stream input, model fit: start each frame's neutral-point distances from the previous
    /// frame's fit (when its confidence was at least 0.5) and set the robust weights from the
    /// first residuals; the yaw still starts from the frame's own eigenvector answer.
    #[arg(long)]
    pub warm_start: bool,
    /// Image input: the sensor preset the frame was made with (camera, nfpi, gniipi, gniicpi), as
    /// in `psns render --raw`: its lens is the default of --lens and its relative illumination the
    /// flat-field law. A stream's header records both.
    #[arg(long, value_parser = parsed::<Preset>)]
    pub preset: Option<Preset>,
    /// Flat-field law of the intensity vote (the 180° decision with the sun within 8° of the
    /// horizon): the frames' relative illumination is cos^N of the field angle (0 = none).
    /// Default: an image's --preset (camera cos^1.5, gniipi/gniicpi cos^4, nfpi none); a
    /// stream's recorded optics (or its preset).
    #[arg(long, value_name = "N")]
    pub vignetting_cos_power: Option<f64>,
    /// Which pixels are sky. auto (default): found from each frame: pixels 8x darker or
    /// brighter than the frame's sky, unpolarized, or whose AoLP disagrees with the sky model
    /// at the estimated yaw (estimate, drop them, estimate again), and the regions where most
    /// do (a wall, foliage). none: every pixel polarized enough. FILE: a PNG/TIFF of the
    /// frame's size (the raw mosaic's), nonzero = sky, used as it is (nothing else found).
    #[arg(long, default_value = "auto", value_name = "auto|none|FILE", value_parser = parsed::<SkyMaskArg>)]
    pub mask: SkyMaskArg,
}

impl HeadingArgs {
    /// The relative illumination to flat-field S0 by: `--vignetting-cos-power`, else `default`.
    pub fn flat_field(&self, default: RelativeIllumination) -> Result<RelativeIllumination> {
        Ok(match self.vignetting_cos_power {
            Some(n) => {
                let ri = if n == 0.0 {
                    RelativeIllumination::None
                } else {
                    RelativeIllumination::CosPower { n }
                };
                ri.validate()
                    .map_err(|_| Error::range("vignetting-cos-power", n, "0..8"))?;
                ri
            }
            None => default,
        })
    }

    /// Whether yaws are reported in the solar frame (`--frame solar`: from the sun's azimuth,
    /// as `psns render --frame solar` takes them) instead of the ENU frame (from north).
    pub fn solar_frame(&self) -> bool {
        matches!(self.scene.frame, Some(AttitudeFrame::Solar))
    }

    /// An ENU yaw (degrees) in the frame of `--frame`: itself, or minus the sun's azimuth
    /// (ψ_a = ψ_n − A_s), in [0, 360).
    pub fn reported_yaw(&self, enu_yaw_deg: f64, sun_azimuth_deg: f64) -> f64 {
        if self.solar_frame() {
            (enu_yaw_deg - sun_azimuth_deg).rem_euclid(360.0)
        } else {
            enu_yaw_deg
        }
    }

    /// Options that need a particular `--method`.
    pub fn check_method_options(&self) -> Result<()> {
        if self.fit_sun_elevation && self.method != HeadingMethod::ModelFit {
            return Err(Error::Invalid(format!(
                "--fit-sun-elevation applies to --method model-fit, not {}",
                self.method
            )));
        }
        if self.warm_start && self.method != HeadingMethod::ModelFit {
            return Err(Error::Invalid(format!(
                "--warm-start applies to --method model-fit, not {}",
                self.method
            )));
        }
        Ok(())
    }

    /// The option checks of one image (not a stream).
    pub fn check_image_options(&self) -> Result<()> {
        self.check_method_options()?;
        for (name, given) in [
            ("imu-tilt", self.imu_tilt),
            ("latest", self.latest),
            ("warm-start", self.warm_start),
        ] {
            if given {
                return Err(Error::Invalid(format!(
                    "--{name} applies to stream input only"
                )));
            }
        }
        Ok(())
    }

    /// The tilt given as --pitch/--roll (ENU Euler attitude), refusing a yaw or a quaternion.
    pub fn given_tilt(&self) -> Result<(f64, f64)> {
        self.tilt_of(&self.scene.scene()?)
    }

    /// The tilt of a scene's attitude (its pitch and roll; never its yaw), refusing `--yaw` and
    /// `--quaternion` options. A scene file's quaternion gives its tilt.
    fn tilt_of(&self, cfg: &SceneConfig) -> Result<(f64, f64)> {
        if self.scene.yaw.is_some() || self.scene.quaternion.is_some() {
            return Err(Error::Invalid(
                "psns heading estimates the yaw: give only the tilt (--pitch, --roll)".into(),
            ));
        }
        Ok(match cfg.camera.attitude {
            Attitude::Euler {
                pitch_deg,
                roll_deg,
                ..
            } => (pitch_deg, roll_deg),
            // the tilt is the same in the solar and the ENU frame (they differ by a yaw)
            Attitude::Quaternion { wxyz, .. } => attitude_tilt_deg(wxyz),
        })
    }

    /// Whether the options give the sun: `--time`, or a zenith (or altitude) and an azimuth.
    fn options_give_sun(&self) -> bool {
        let s = &self.scene;
        s.time.is_some()
            || ((s.sun_zenith.is_some() || s.sun_altitude.is_some()) && s.sun_azimuth.is_some())
    }

    /// The scene of one image: the options applied onto `--config`, or, when neither gives the
    /// sun, onto the `scene.json` beside `image` (the file `psns render` writes with the frame:
    /// sun, intrinsics, lens, tilt and sensor). Returns the scene and the scene file read in
    /// place of `--config`, if any. With no sun anywhere it refuses, naming the options that
    /// give one: there is no default sun for a picture of someone's sky. `image` is `None` for
    /// an array (Python), which has no file beside it.
    pub fn image_scene(&self, image: Option<&Path>) -> Result<(SceneConfig, Option<PathBuf>)> {
        let mut args = self.scene.clone();
        let mut beside = None;
        if args.config.is_none() && !self.options_give_sun() {
            if let Some(p) = image
                .and_then(|i| i.parent())
                .map(|d| d.join("scene.json"))
                .filter(|p| p.is_file())
            {
                args.config = Some(p.clone());
                beside = Some(p);
            }
        }
        let cfg = args.scene()?;
        let sun = &cfg.sun;
        let complete = sun.time.is_some()
            || ((sun.zenith_deg.is_some() || sun.altitude_deg.is_some())
                && sun.azimuth_deg.is_some());
        if !complete {
            let what = match image {
                Some(i) => format!("{} (no scene.json beside it)", i.display()),
                None => "the array".to_string(),
            };
            let given = match &args.config {
                Some(c) => format!(" nor in {}", c.display()),
                None => String::new(),
            };
            return Err(Error::Invalid(format!(
                "no sun position for {what}: give --sun-zenith (or --sun-altitude) and \
                 --sun-azimuth, or --time with --lat and --lon, or --config SCENE (the \
                 scene.json psns render wrote); none is in the options{given}"
            )));
        }
        Ok((cfg, beside))
    }

    /// The estimator's setup for one image from [`image_scene`](Self::image_scene): its sun
    /// (up), intrinsics and tilt, the sensor preset's falloff; and the scene file read beside the
    /// image, if any.
    pub fn image_setup(&self, image: Option<&Path>) -> Result<(HeadingSetup, Option<PathBuf>)> {
        let (mut cfg, beside) = self.image_scene(image)?;
        let (pitch, roll) = self.tilt_of(&cfg)?;
        if let Some(p) = self.preset {
            if p != cfg.raw.preset {
                // the preset named, not the scene file's sensor
                cfg.raw.sensor = None;
            }
            cfg.raw.preset = p;
        }
        let sun = cfg.sun.resolve()?;
        cfg.sun.check_up(sun)?;
        // lens: --lens, or the camera preset's (as psns render)
        let mut setup = HeadingSetup::new(cfg.intrinsics(), sun);
        setup.pitch_deg = pitch;
        setup.roll_deg = roll;
        setup.fit_elevation = self.fit_sun_elevation;
        setup.find_mask = self.mask == SkyMaskArg::Auto;
        // the falloff of the preset's (or the configured) sensor, as psns render makes it
        let sensor = cfg
            .raw
            .sensor
            .clone()
            .unwrap_or_else(|| SensorConfig::preset(cfg.raw.preset));
        setup.relative_illumination = self.flat_field(sensor.effective_ri())?;
        Ok((setup, beside))
    }

    /// The estimate from one mosaic (not a stream) with the [`image_setup`](Self::image_setup)
    /// of the options; `name` names the input in messages.
    pub fn estimate_image(
        &self,
        setup: &HeadingSetup,
        raw: &LoadedRaw,
        name: &str,
    ) -> Result<CodesEstimate> {
        let mask = self.given_mask()?;
        let mask = mask.as_ref();
        let i = setup.intrinsics;
        if (raw.codes.width, raw.codes.height) != (i.width, i.height) {
            return Err(Error::Invalid(format!(
                "{name} is {} x {} pixels but the intrinsics say {} x {}: give --width/--height (and --pixel-pitch, --focal-length) of the camera",
                raw.codes.width,
                raw.codes.height,
                i.width,
                i.height
            )));
        }
        let bits = match self.bits {
            Some(b) if (8..=16).contains(&b) => b as u8,
            Some(b) => return Err(Error::range("bits", b as f64, "8..16")),
            None if raw.bits == 8 => 8,
            None => 12, // the IMX250MZR's deepest mode, in a 16-bit file
        };
        estimate_codes(
            &raw.codes,
            raw.black_level,
            raw.layout,
            bits,
            self.demosaic,
            self.method,
            setup,
            mask,
        )
    }

    /// The sky mask of `--mask FILE` (nonzero = sky), `None` for `auto` and `none`.
    pub fn given_mask(&self) -> Result<Option<Image<u8>>> {
        match &self.mask {
            SkyMaskArg::File(p) => load_mask(p).map(Some),
            _ => Ok(None),
        }
    }
}

/// What `--mask` says: find the sky mask from each frame, use none, or read one from a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum SkyMaskArg {
    /// Found from each frame ([`crate::heading::find_sky_mask`]).
    #[default]
    Auto,
    /// No mask: every pixel with a usable DoLP.
    None,
    /// A PNG/TIFF of the frame's size, nonzero = sky.
    File(PathBuf),
}

impl std::str::FromStr for SkyMaskArg {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "auto" => SkyMaskArg::Auto,
            "none" => SkyMaskArg::None,
            "" => return Err(Error::Invalid("--mask: give auto, none or a file".into())),
            f => SkyMaskArg::File(PathBuf::from(f)),
        })
    }
}

/// A sky mask from a PNG or TIFF (any bit depth or colour): 1 where a pixel is nonzero, else 0.
pub fn load_mask(path: &Path) -> Result<Image<u8>> {
    let img = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| Error::input(path, e))?
        .decode()
        .map_err(|e| {
            Error::Format(format!(
                "{}: not a readable PNG or TIFF mask ({e})",
                path.display()
            ))
        })?
        .into_luma16();
    let (w, h) = img.dimensions();
    let data = img.into_raw().into_iter().map(|v| (v != 0) as u8).collect();
    Ok(Image::from_vec(w as usize, h as usize, data))
}
