//! Options shared by several commands: the scene (`--config`, sun, sky, attitude, intrinsics),
//! the sensor and raw frame, and SPA settings; each applies itself onto a [`SceneConfig`].

use clap::{Args, ValueEnum};
use psns::camera::{Attitude, AttitudeFrame, Lens, Projection};
use psns::config::{SceneConfig, SceneKind};
use psns::sensor::packing::PixelFormat;
use psns::sensor::{Exposure, Preset, SensorConfig};
use psns::sky::{DopModel, DopNorm, NeutralLaw, PolarizationModel};
use psns::sun::{Place, Refraction};
use std::path::PathBuf;

/// Parses a finite f64 (rejects NaN and infinities with a clear message).
pub(crate) fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a finite number"))
    }
}

/// Parses a whole number 0..2^64-1 (a count, an index or a seed), with a range message for a
/// negative or fractional value.
pub(crate) fn whole(s: &str) -> Result<u64, String> {
    let t = s.trim();
    t.parse::<u64>().map_err(|_| match t.parse::<f64>() {
        Ok(v) => format!(
            "{} is out of range (allowed a whole number 0..{})",
            psns::error::num(v),
            u64::MAX
        ),
        Err(_) => format!("'{s}' is not a whole number"),
    })
}

/// The first option of `options` (name, given) that was given.
pub(crate) fn first_given(options: &[(&'static str, bool)]) -> Option<&'static str> {
    options.iter().find_map(|&(n, g)| g.then_some(n))
}

/// Parses a repetition count, 1..1000.
pub(crate) fn runs(s: &str) -> Result<usize, String> {
    match whole(s)? {
        v @ 1..=1000 => Ok(v as usize),
        v => Err(format!("{v} is out of range (allowed 1..1000)")),
    }
}

/// Parses `a,b,...` with exactly N finite numbers.
pub(crate) fn finite_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s.split(',').map(finite).collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("expected {N} comma-separated numbers, found {}", v.len()))
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum ModelArg {
    Wang,
    Rayleigh,
    DepolarizedRayleigh,
    Berry,
    Pan,
    Queen,
    Asymmetric,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum NormArg {
    Clamp,
    Wilkie,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum DopModelArg {
    WangBounded,
    WangPaper,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum FrameArg {
    Solar,
    Enu,
}

/// Scene options shared by `render`, `sky` (and later commands). Every option overrides the
/// value from `--config`.
#[derive(Args, Clone)]
pub(crate) struct SceneArgs {
    /// Scene file (TOML or JSON, e.g. a previous run's scene.json).
    #[arg(long, value_name = "FILE")]
    pub(crate) config: Option<PathBuf>,
    /// Sun zenith angle, degrees (0..90 for a render).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) sun_zenith: Option<f64>,
    /// Sun altitude (elevation), degrees; alternative to --sun-zenith.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "sun_zenith")]
    pub(crate) sun_altitude: Option<f64>,
    /// Sun compass azimuth, degrees from north, clockwise.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) sun_azimuth: Option<f64>,
    /// UTC time (ISO 8601, e.g. 2003-10-17T19:30:30Z): sun from SPA with --lat/--lon.
    #[arg(long, conflicts_with_all = ["sun_zenith", "sun_altitude", "sun_azimuth"])]
    pub(crate) time: Option<String>,
    /// Observer latitude, degrees north.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub(crate) lat: Option<f64>,
    /// Observer longitude, degrees east.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub(crate) lon: Option<f64>,
    /// Observer height above the ellipsoid, metres (for --time).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "M")]
    pub(crate) observer_height: Option<f64>,
    #[command(flatten)]
    pub(crate) spa: SpaArgs,
    /// Polarization model: wang (default; Berry AOP, PSNS/Wang DOP), rayleigh,
    /// depolarized-rayleigh (Wu 2014), berry (DOP = |w|), pan (Pan 2023's neutral points),
    /// queen (Pan's points, DOP = |w|/(2-|w|)), asymmetric (four independent neutral points);
    /// docs/sky.md.
    #[arg(long, value_enum)]
    pub(crate) model: Option<ModelArg>,
    /// Sky radiance: hosek (Hosek-Wilkie, default) or cie:N (CIE S 011 standard sky N = 1..15,
    /// scaled to the Hosek-Wilkie zenith; 1-5 overcast, without the sun's disc).
    #[arg(long, value_parser = parse_radiance, value_name = "hosek|cie:N")]
    pub(crate) radiance: Option<psns::sky::cie::Radiance>,
    /// Molecular depolarization ratio of --model depolarized-rayleigh, 0..0.5 (default 0.0279).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "D")]
    pub(crate) depolarization_ratio: Option<f64>,
    /// --model asymmetric: Arago point's distance above the anti-sun, degrees 0..90 (default:
    /// the Brewster distance).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) arago: Option<f64>,
    /// --model asymmetric: fourth point's distance below the anti-sun, degrees 0..90 (default:
    /// the Brewster distance).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) fourth: Option<f64>,
    /// Turbidity, 1.7..10 (1..10 with --dop-model wang-paper or --model rayleigh).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "T")]
    pub(crate) turbidity: Option<f64>,
    /// Wavelength, nm, 320..720.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    pub(crate) wavelength: Option<f64>,
    /// Ground albedo, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "A")]
    pub(crate) albedo: Option<f64>,
    /// Distance of both neutral points from the sun (Babinet and Brewster), degrees 0..60
    /// (default 25; --model asymmetric: Pan's law unless given).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) neutral_distance: Option<f64>,
    /// Babinet point distance above the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    pub(crate) babinet: Option<f64>,
    /// Brewster point distance below the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    pub(crate) brewster: Option<f64>,
    /// Maximum DOP, 0..1, of every model but wang (default 1, as in the models' papers).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub(crate) dop_max: Option<f64>,
    /// Uniform unpolarized radiance of ground pixels, W m^-2 sr^-1 nm^-1 (default 0).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "L")]
    pub(crate) ground_radiance: Option<f64>,
    /// DOP normalisation of the Wang model (clamp: none; wilkie: 2/π).
    #[arg(long, value_enum)]
    pub(crate) dop_norm: Option<NormArg>,
    /// Form of the Wang DOP: wang-bounded (default; stable for turbidity 1.7..10, the paper's
    /// values at the default scene) or wang-paper (eq. (5) as published, turbidity 1..10).
    #[arg(long, value_enum)]
    pub(crate) dop_model: Option<DopModelArg>,
    /// Camera yaw, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) yaw: Option<f64>,
    /// Camera pitch, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) pitch: Option<f64>,
    /// Camera roll, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) roll: Option<f64>,
    /// Reference frame of yaw/pitch/roll (or of --quaternion).
    #[arg(long, value_enum)]
    pub(crate) frame: Option<FrameArg>,
    /// Attitude quaternion W,X,Y,Z (Hamilton, scalar first) rotating camera vectors into the frame.
    #[arg(long, value_parser = finite_list::<4>, allow_negative_numbers = true,
          conflicts_with_all = ["yaw", "pitch", "roll"], value_name = "W,X,Y,Z")]
    pub(crate) quaternion: Option<[f64; 4]>,
    /// Focal length, mm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "MM")]
    pub(crate) focal_length: Option<f64>,
    /// Pixel pitch, µm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "UM")]
    pub(crate) pixel_pitch: Option<f64>,
    /// Image width (columns), pixels.
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    pub(crate) width: Option<i64>,
    /// Image height (rows), pixels.
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    pub(crate) height: Option<i64>,
    /// Principal point X,Y: 0-based column and row of the optical axis.
    #[arg(long, value_parser = finite_list::<2>, allow_negative_numbers = true, value_name = "X,Y")]
    pub(crate) principal_point: Option<[f64; 2]>,
    /// Projection: rectilinear (default), or a 180-degree fisheye (equidistant, equisolid,
    /// stereographic, orthographic) with the image circle masked (docs/camera.md).
    #[arg(long, value_parser = parse_projection, value_name = "NAME")]
    pub(crate) projection: Option<Projection>,
    /// Polarization transport of the lens: ideal (meridional and sagittal components along the
    /// image's radial and tangential directions; the camera preset's default) or pinhole (the E-vector
    /// projected on the focal plane, PSNS eqs. 19-20; the PSNS presets' default).
    #[arg(long, value_parser = parse_lens, value_name = "NAME")]
    pub(crate) lens: Option<Lens>,
}

pub(crate) fn parse_radiance(s: &str) -> Result<psns::sky::cie::Radiance, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

pub(crate) fn parse_projection(s: &str) -> Result<Projection, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

pub(crate) fn parse_lens(s: &str) -> Result<Lens, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

pub(crate) fn size(name: &str, v: i64) -> psns::Result<usize> {
    if v <= 0 || v > 65_536 {
        return Err(psns::Error::range(name, v as f64, "1..65536"));
    }
    Ok(v as usize)
}

impl SceneArgs {
    /// The first option given that places the observer (used only with a time).
    pub(crate) fn place_given(&self) -> Option<&'static str> {
        first_given(&[
            ("lat", self.lat.is_some()),
            ("lon", self.lon.is_some()),
            ("observer-height", self.observer_height.is_some()),
            ("delta-t", self.spa.delta_t.is_some()),
            ("refraction", self.spa.refraction),
        ])
    }

    /// Scene from --config (or defaults) with every given option applied.
    pub(crate) fn scene(&self) -> psns::Result<SceneConfig> {
        let mut c = match &self.config {
            Some(p) => SceneConfig::load(p)?,
            None => SceneConfig::default(),
        };
        let s = &mut c.sun;
        if self.sun_zenith.is_some() || self.sun_altitude.is_some() || self.sun_azimuth.is_some() {
            if s.time.is_some() && self.sun_zenith.is_none() && self.sun_altitude.is_none() {
                return Err(psns::Error::Invalid(
                    "the scene gives the sun by --time; to set it directly give --sun-zenith (or --sun-altitude) with --sun-azimuth".into(),
                ));
            }
            s.time = None;
            if self.sun_zenith.is_some() || self.sun_altitude.is_some() {
                s.zenith_deg = self.sun_zenith;
                s.altitude_deg = self.sun_altitude;
            }
            if self.sun_azimuth.is_some() {
                s.azimuth_deg = self.sun_azimuth;
            }
        }
        if let Some(t) = &self.time {
            s.time = Some(t.clone());
            s.zenith_deg = None;
            s.altitude_deg = None;
            s.azimuth_deg = None;
        }
        if self.lat.is_some() || self.lon.is_some() || self.observer_height.is_some() {
            let mut p = s.place.unwrap_or(Place {
                lat_deg: f64::NAN,
                lon_deg: f64::NAN,
                height_m: 0.0,
            });
            p.lat_deg = self.lat.unwrap_or(p.lat_deg);
            p.lon_deg = self.lon.unwrap_or(p.lon_deg);
            p.height_m = self.observer_height.unwrap_or(p.height_m);
            if !p.lat_deg.is_finite() || !p.lon_deg.is_finite() {
                return Err(psns::Error::Invalid("give both --lat and --lon".into()));
            }
            s.place = Some(p);
        }
        if self.spa.delta_t.is_some() {
            s.delta_t_s = self.spa.delta_t;
        }
        if let Some(r) = self.spa.refraction() {
            s.refraction = Some(r);
        }
        let k = &mut c.sky;
        if let Some(m) = self.model {
            k.model = match m {
                ModelArg::Wang => PolarizationModel::Wang,
                ModelArg::Rayleigh => PolarizationModel::Rayleigh,
                ModelArg::DepolarizedRayleigh => PolarizationModel::DepolarizedRayleigh,
                ModelArg::Berry => PolarizationModel::Berry,
                ModelArg::Pan => PolarizationModel::Pan,
                ModelArg::Queen => PolarizationModel::Queen,
                ModelArg::Asymmetric => PolarizationModel::Asymmetric,
            };
        }
        if let Some(r) = self.radiance {
            k.radiance = r;
        }
        k.turbidity = self.turbidity.unwrap_or(k.turbidity);
        k.wavelength_nm = self.wavelength.unwrap_or(k.wavelength_nm);
        k.albedo = self.albedo.unwrap_or(k.albedo);
        let one_point = self.babinet.is_some() != self.brewster.is_some();
        if self.neutral_distance.is_some() || self.babinet.is_some() || self.brewster.is_some() {
            if one_point && k.law() == NeutralLaw::Pan {
                return Err(psns::Error::Invalid(format!(
                    "--model {} places both neutral points by Pan's law: to fix them give both \
                     --babinet and --brewster, or --neutral-distance",
                    k.model
                )));
            }
            k.neutral_law = Some(NeutralLaw::Fixed);
        }
        if let Some(d) = self.neutral_distance {
            k.babinet_deg = d;
            k.brewster_deg = d;
        }
        k.babinet_deg = self.babinet.unwrap_or(k.babinet_deg);
        k.brewster_deg = self.brewster.unwrap_or(k.brewster_deg);
        k.dop_max = self.dop_max.unwrap_or(k.dop_max);
        k.depolarization_ratio = self.depolarization_ratio.unwrap_or(k.depolarization_ratio);
        if self.arago.is_some() {
            k.arago_deg = self.arago;
        }
        if self.fourth.is_some() {
            k.fourth_deg = self.fourth;
        }
        if self.ground_radiance.is_some() {
            k.ground_radiance = self.ground_radiance;
        }
        if let Some(n) = self.dop_norm {
            k.dop_norm = match n {
                NormArg::Clamp => DopNorm::Clamp,
                NormArg::Wilkie => DopNorm::Wilkie,
            };
        }
        if let Some(m) = self.dop_model {
            k.dop_model = match m {
                DopModelArg::WangBounded => DopModel::WangBounded,
                DopModelArg::WangPaper => DopModel::WangPaper,
            };
        }
        let cam = &mut c.camera;
        let frame_given = self.frame.map(|f| match f {
            FrameArg::Solar => AttitudeFrame::Solar,
            FrameArg::Enu => AttitudeFrame::Enu,
        });
        let euler_given = self.yaw.is_some() || self.pitch.is_some() || self.roll.is_some();
        match (self.quaternion, cam.attitude) {
            (Some(q), current) => {
                let frame = match current {
                    Attitude::Euler { frame, .. } | Attitude::Quaternion { frame, .. } => frame,
                };
                let a = Attitude::Quaternion {
                    frame: frame_given.unwrap_or(frame),
                    wxyz: q,
                };
                a.validate()?;
                let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                if (norm - 1.0).abs() > 1e-12 {
                    // typed quaternions are rounded: use the unit one, and record that in scene.json
                    eprintln!("psns: note: --quaternion normalised (its norm was {norm:.6})");
                }
                cam.attitude = a.normalized();
            }
            (None, Attitude::Quaternion { frame, wxyz }) => {
                if euler_given {
                    let all = self.yaw.is_some() && self.pitch.is_some() && self.roll.is_some();
                    if !all {
                        return Err(psns::Error::Invalid(
                            "the scene's attitude is a quaternion: give --quaternion, or all of --yaw, --pitch and --roll".into(),
                        ));
                    }
                    cam.attitude = Attitude::Euler {
                        frame: frame_given.unwrap_or(frame),
                        yaw_deg: self.yaw.unwrap_or(0.0),
                        pitch_deg: self.pitch.unwrap_or(0.0),
                        roll_deg: self.roll.unwrap_or(0.0),
                    };
                } else if let Some(f) = frame_given {
                    cam.attitude = Attitude::Quaternion { frame: f, wxyz };
                }
            }
            (
                None,
                Attitude::Euler {
                    frame,
                    yaw_deg,
                    pitch_deg,
                    roll_deg,
                },
            ) => {
                cam.attitude = Attitude::Euler {
                    frame: frame_given.unwrap_or(frame),
                    yaw_deg: self.yaw.unwrap_or(yaw_deg),
                    pitch_deg: self.pitch.unwrap_or(pitch_deg),
                    roll_deg: self.roll.unwrap_or(roll_deg),
                };
            }
        }
        let i = &mut cam.intrinsics;
        i.focal_length_mm = self.focal_length.unwrap_or(i.focal_length_mm);
        i.pixel_pitch_um = self.pixel_pitch.unwrap_or(i.pixel_pitch_um);
        if let Some(w) = self.width {
            i.width = size("width", w)?;
        }
        if let Some(h) = self.height {
            i.height = size("height", h)?;
        }
        if self.principal_point.is_some() {
            i.principal_point = self.principal_point;
        }
        if let Some(p) = self.projection {
            i.projection = p;
        }
        if self.lens.is_some() {
            i.lens = self.lens;
        }
        Ok(c)
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SceneKindArg {
    Sky,
    Flat,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum OnOff {
    On,
    Off,
}

/// Sensor and raw-frame options (`render --raw`, `stream`, `bench`).
#[derive(Args, Clone, Default)]
pub(crate) struct RawArgs {
    /// Sensor preset: camera (realistic IMX250MZR), nfpi, gniipi, gniicpi (PSNS dataset variants).
    #[arg(long, value_parser = parse_preset)]
    pub(crate) preset: Option<Preset>,
    /// Scene for raw frames: the sky or a uniform flat field.
    #[arg(long, value_enum)]
    pub(crate) scene: Option<SceneKindArg>,
    /// Flat-field radiance, W m^-2 sr^-1 nm^-1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "R")]
    pub(crate) flat_radiance: Option<f64>,
    /// Flat-field degree of linear polarization, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "D")]
    pub(crate) flat_dolp: Option<f64>,
    /// Flat-field angle of linear polarization, degrees (sensor frame).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub(crate) flat_aolp: Option<f64>,
    /// Exposure time, µs (20..10,000,000).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "US", conflicts_with = "auto_exposure")]
    pub(crate) exposure_us: Option<f64>,
    /// Auto-exposure: 99th percentile of the sky at 70 % of full well.
    #[arg(long)]
    pub(crate) auto_exposure: bool,
    /// Analog gain, dB (0..48).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DB")]
    pub(crate) gain_db: Option<f64>,
    /// Black level, DN at 12 bit (0..200).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DN")]
    pub(crate) black_level: Option<f64>,
    /// Output bit depth: 8, 10 or 12.
    #[arg(long, allow_negative_numbers = true, value_name = "BITS")]
    pub(crate) bit_depth: Option<i64>,
    /// Packed pixel format of raw.bin / the stream payload: mono8, mono12p, mono12packed, mono16.
    #[arg(long, value_parser = parse_pixel_format)]
    pub(crate) pixel_format: Option<PixelFormat>,
    /// Camera seed (fixed patterns and noise).
    #[arg(long, value_parser = whole)]
    pub(crate) seed: Option<u64>,
    /// Frame index of that camera (temporal noise).
    #[arg(long, value_parser = whole)]
    pub(crate) frame_index: Option<u64>,
    /// Draw the solar disc (default: on for the camera preset, off for PSNS presets).
    #[arg(long, value_enum)]
    pub(crate) sun_disc: Option<OnOff>,
    /// Add soft unpolarized clouds to the scene.
    #[arg(long)]
    pub(crate) clouds: bool,
    /// Sky nodes every N pixels of the fast path, refined where interpolation would be off by
    /// more than a fortieth of the shot noise (1 = every pixel; default 16).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub(crate) sky_grid: Option<i64>,
    /// Reference run: the sky model at every pixel, no caches, and the exact sensor path (exact
    /// Poisson sampling, per-row ChaCha8 streams), bit-identical to psns before the fast path.
    #[arg(long)]
    pub(crate) exact: bool,
    /// Lens f-number.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub(crate) f_number: Option<f64>,
    /// Read (dark) noise, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    pub(crate) read_noise: Option<f64>,
    /// Full-well capacity, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    pub(crate) full_well: Option<f64>,
    /// Sensor temperature, °C (dark current).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "C")]
    pub(crate) sensor_temperature: Option<f64>,
    /// Pixel crosstalk fraction (0..0.03).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub(crate) crosstalk: Option<f64>,
    /// Band-pass filter width, nm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    pub(crate) filter_width: Option<f64>,
    /// Switch stages off: any of ri, polarizer_er, polarizer_orientation, prnu, crosstalk, dark,
    /// shot, fwc_clip, dsnu, read, quantize (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "STAGE")]
    pub(crate) off: Vec<String>,
    /// Set any sensor field: KEY=VALUE with VALUE in JSON (e.g. prnu=0.01, ri={"kind":"cospower","n":4}).
    #[arg(long = "sensor-set", value_name = "KEY=VALUE")]
    pub(crate) sensor_set: Vec<String>,
}

pub(crate) fn parse_preset(s: &str) -> Result<Preset, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

pub(crate) fn parse_pixel_format(s: &str) -> Result<PixelFormat, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

impl RawArgs {
    /// The first raw-frame option given on the command line (they do nothing for ideal images).
    pub(crate) fn first_given(&self) -> Option<&'static str> {
        first_given(&[
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
        ])
    }

    /// Applies the raw options to a scene.
    pub(crate) fn apply(&self, c: &mut SceneConfig) -> psns::Result<()> {
        let r = &mut c.raw;
        if let Some(p) = self.preset {
            r.preset = p;
            r.sensor = None;
        }
        if let Some(k) = self.scene {
            r.scene = match k {
                SceneKindArg::Sky => SceneKind::Sky,
                SceneKindArg::Flat => SceneKind::Flat,
            };
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
                return Err(psns::Error::range("sky-grid", g as f64, "1..64"));
            }
            r.sky_grid = g as usize;
        }
        if self.exact {
            if self.sky_grid.is_some_and(|g| g != 1) {
                return Err(psns::Error::Invalid(
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
                return Err(psns::Error::range("bit-depth", b as f64, "8, 10 or 12"));
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
                        return Err(psns::Error::OutOfRange {
                            name: "off".into(),
                            value: st.into(),
                            allowed: "ri, polarizer_er, polarizer_orientation, prnu, crosstalk, dark, shot, fwc_clip, dsnu, read, quantize".into(),
                        })
                    }
                }
            }
            for kv in &self.sensor_set {
                let (k, val) = kv.split_once('=').ok_or_else(|| {
                    psns::Error::Invalid(format!("--sensor-set '{kv}' is not KEY=VALUE"))
                })?;
                let parsed: serde_json::Value = serde_json::from_str(val)
                    .unwrap_or_else(|_| serde_json::Value::String(val.to_string()));
                if v.get(k.trim()).is_none() {
                    return Err(psns::Error::Invalid(format!(
                        "--sensor-set: unknown sensor field '{k}'"
                    )));
                }
                v[k.trim()] = parsed;
            }
            s = serde_json::from_value(v)
                .map_err(|e| psns::Error::Invalid(format!("sensor settings: {e}")))?;
        }
        r.sensor = Some(s);
        Ok(())
    }
}

/// SPA settings shared by every command that takes --time.
#[derive(Args, Clone)]
pub(crate) struct SpaArgs {
    /// ΔT = TT − UT in seconds (default: the crate's estimate for the date).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "S")]
    pub(crate) delta_t: Option<f64>,
    /// Apply atmospheric refraction (default: geometric position).
    #[arg(long)]
    pub(crate) refraction: bool,
    /// Pressure for --refraction, hPa (default 1010).
    #[arg(long, value_parser = finite, value_name = "HPA", requires = "refraction")]
    pub(crate) pressure: Option<f64>,
    /// Temperature for --refraction, °C (default 10).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "C", requires = "refraction")]
    pub(crate) temperature: Option<f64>,
}

impl SpaArgs {
    pub(crate) fn refraction(&self) -> Option<Refraction> {
        self.refraction.then_some(Refraction {
            pressure_hpa: self.pressure.unwrap_or(1010.0),
            temperature_c: self.temperature.unwrap_or(10.0),
        })
    }
}
