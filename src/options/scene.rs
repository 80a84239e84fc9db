//! The scene options (`--config`, sun, sky, attitude, intrinsics) and SPA settings, applied onto
//! a [`SceneConfig`].

use super::{finite, finite_list, first_given, integer, parsed};
use crate::camera::{Attitude, AttitudeFrame, Lens, Projection};
use crate::config::SceneConfig;
use crate::sky::cie::Radiance;
use crate::sky::{DopModel, DopNorm, PolarizationModel};
use crate::sun::{Place, Refraction};
use clap::Args;
use std::path::PathBuf;

/// Scene options shared by `render`, `sky` (and later commands). Every option overrides the
/// value from `--config`.
#[derive(Args, Clone)]
pub struct SceneArgs {
    /// Scene file (TOML or JSON, e.g. a previous run's scene.json).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Sun zenith angle, degrees (0..90 for a render).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub sun_zenith: Option<f64>,
    /// Sun altitude (elevation), degrees; alternative to --sun-zenith.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "sun_zenith")]
    pub sun_altitude: Option<f64>,
    /// Sun compass azimuth, degrees from north, clockwise.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub sun_azimuth: Option<f64>,
    /// UTC time (ISO 8601, e.g. 2003-10-17T19:30:30Z): sun from SPA with --lat/--lon.
    #[arg(long, conflicts_with_all = ["sun_zenith", "sun_altitude", "sun_azimuth"])]
    pub time: Option<String>,
    /// Observer latitude, degrees north.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub lat: Option<f64>,
    /// Observer longitude, degrees east.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub lon: Option<f64>,
    /// Observer height above the ellipsoid, metres (for --time).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "M")]
    pub observer_height: Option<f64>,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub spa: SpaArgs,
    /// Polarization model: wang (default; Berry AOP, PSNS/Wang DOP), rayleigh,
    /// depolarized-rayleigh (Wu 2014), berry (DOP = |w|), pan (Pan 2023's neutral points),
    /// queen (Pan's points, DOP = |w|/(2-|w|)), asymmetric (four independent neutral points);
    /// docs/sky.md.
    #[arg(long, value_enum)]
    pub model: Option<PolarizationModel>,
    /// Sky radiance: hosek (Hosek-Wilkie, default) or cie:N (CIE S 011 standard sky N = 1..15,
    /// scaled to the Hosek-Wilkie zenith; 1-5 overcast, without the sun's disc).
    #[arg(long, value_parser = parsed::<Radiance>, value_name = "hosek|cie:N")]
    pub radiance: Option<Radiance>,
    /// Molecular depolarization ratio of --model depolarized-rayleigh, 0..0.5 (default 0.0279).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "D")]
    pub depolarization_ratio: Option<f64>,
    /// --model asymmetric: Arago point's distance above the anti-sun, degrees 0..90 (default:
    /// the Brewster distance).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub arago: Option<f64>,
    /// --model asymmetric: fourth point's distance below the anti-sun, degrees 0..90 (default:
    /// the Brewster distance).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub fourth: Option<f64>,
    /// Turbidity, 1.7..10 (1..10 with --dop-model wang-paper or --model rayleigh).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "T")]
    pub turbidity: Option<f64>,
    /// Wavelength, nm, 320..720.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    pub wavelength: Option<f64>,
    /// Ground albedo, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "A")]
    pub albedo: Option<f64>,
    /// Distance of both neutral points from the sun (Babinet and Brewster), degrees 0..60
    /// (default 25; --model asymmetric: Pan's law unless given).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub neutral_distance: Option<f64>,
    /// Babinet point distance above the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    pub babinet: Option<f64>,
    /// Brewster point distance below the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    pub brewster: Option<f64>,
    /// Maximum DOP, 0..1, of every model but wang (default 1, as in the models' papers).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    pub dop_max: Option<f64>,
    /// Uniform unpolarized radiance of ground pixels, W m^-2 sr^-1 nm^-1 (default 0).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "L")]
    pub ground_radiance: Option<f64>,
    /// DOP normalisation of the Wang model (clamp: none; wilkie: 2/π).
    #[arg(long, value_enum)]
    pub dop_norm: Option<DopNorm>,
    /// Form of the Wang DOP: wang-bounded (default; stable for turbidity 1.7..10, the paper's
    /// values at the default scene) or wang-paper (eq. (5) as published, turbidity 1..10).
    #[arg(long, value_enum)]
    pub dop_model: Option<DopModel>,
    /// Camera yaw, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub yaw: Option<f64>,
    /// Camera pitch, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub pitch: Option<f64>,
    /// Camera roll, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pub roll: Option<f64>,
    /// Reference frame of yaw/pitch/roll (or of --quaternion): enu (yaw from north, the compass
    /// heading `psns heading` reports; the default) or solar (yaw from the sun's azimuth, as PSNS).
    #[arg(long, value_enum)]
    pub frame: Option<AttitudeFrame>,
    /// Attitude quaternion W,X,Y,Z (Hamilton, scalar first) rotating camera vectors into the frame.
    #[arg(long, value_parser = finite_list::<4>, allow_negative_numbers = true,
          conflicts_with_all = ["yaw", "pitch", "roll"], value_name = "W,X,Y,Z")]
    pub quaternion: Option<[f64; 4]>,
    /// Focal length, mm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "MM")]
    pub focal_length: Option<f64>,
    /// Pixel pitch, µm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "UM")]
    pub pixel_pitch: Option<f64>,
    /// Image width (columns), pixels.
    #[arg(long, value_name = "PX", value_parser = integer, allow_negative_numbers = true)]
    pub width: Option<i64>,
    /// Image height (rows), pixels.
    #[arg(long, value_name = "PX", value_parser = integer, allow_negative_numbers = true)]
    pub height: Option<i64>,
    /// Principal point X,Y: 0-based column and row of the optical axis.
    #[arg(long, value_parser = finite_list::<2>, allow_negative_numbers = true, value_name = "X,Y")]
    pub principal_point: Option<[f64; 2]>,
    /// Projection: rectilinear (default), or a 180-degree fisheye (equidistant, equisolid,
    /// stereographic, orthographic) with the image circle masked (docs/camera.md).
    #[arg(long, value_parser = parsed::<Projection>, value_name = "NAME")]
    pub projection: Option<Projection>,
    /// Polarization transport of the lens: ideal (meridional and sagittal components along the
    /// image's radial and tangential directions; the camera preset's default) or pinhole (the E-vector
    /// projected on the focal plane, PSNS eqs. 19-20; the PSNS presets' default).
    #[arg(long, value_parser = parsed::<Lens>, value_name = "NAME")]
    pub lens: Option<Lens>,
}

/// An image dimension, 1..65536 pixels.
fn size(name: &str, v: i64) -> crate::Result<usize> {
    if v <= 0 || v > 65_536 {
        return Err(crate::Error::range(name, v as f64, "1..65536"));
    }
    Ok(v as usize)
}

impl SceneArgs {
    /// The first option given that places the observer (used only with a time).
    pub fn place_given(&self) -> Option<&'static str> {
        first_given(&[
            ("lat", self.lat.is_some()),
            ("lon", self.lon.is_some()),
            ("observer-height", self.observer_height.is_some()),
            ("delta-t", self.spa.delta_t.is_some()),
            ("refraction", self.spa.refraction),
        ])
    }

    /// Scene from --config (or defaults) with every given option applied.
    pub fn scene(&self) -> crate::Result<SceneConfig> {
        let mut c = match &self.config {
            Some(p) => SceneConfig::load(p)?,
            None => SceneConfig::default(),
        };
        let s = &mut c.sun;
        if self.sun_zenith.is_some() || self.sun_altitude.is_some() || self.sun_azimuth.is_some() {
            if s.time.is_some() && self.sun_zenith.is_none() && self.sun_altitude.is_none() {
                return Err(crate::Error::Invalid(
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
                return Err(crate::Error::Invalid("give both --lat and --lon".into()));
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
            k.model = m;
        }
        if let Some(r) = self.radiance {
            k.radiance = r;
        }
        k.turbidity = self.turbidity.unwrap_or(k.turbidity);
        k.wavelength_nm = self.wavelength.unwrap_or(k.wavelength_nm);
        k.albedo = self.albedo.unwrap_or(k.albedo);
        k.fix_neutral_points(self.neutral_distance, self.babinet, self.brewster, |o| {
            format!("--{}", o.replace('_', "-"))
        })?;
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
            k.dop_norm = n;
        }
        if let Some(m) = self.dop_model {
            k.dop_model = m;
        }
        let cam = &mut c.camera;
        let frame_given = self.frame;
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
                        return Err(crate::Error::Invalid(
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

/// SPA settings shared by every command that takes --time.
#[derive(Args, Clone)]
pub struct SpaArgs {
    /// ΔT = TT − UT in seconds (default: the crate's estimate for the date).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "S")]
    pub delta_t: Option<f64>,
    /// Apply atmospheric refraction (default: geometric position).
    #[arg(long)]
    pub refraction: bool,
    /// Pressure for --refraction, hPa (default 1010).
    #[arg(long, value_parser = finite, value_name = "HPA", requires = "refraction")]
    pub pressure: Option<f64>,
    /// Temperature for --refraction, °C (default 10).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "C", requires = "refraction")]
    pub temperature: Option<f64>,
}

impl SpaArgs {
    /// The refraction these options ask for, if any.
    pub fn refraction(&self) -> Option<Refraction> {
        self.refraction.then_some(Refraction {
            pressure_hpa: self.pressure.unwrap_or(1010.0),
            temperature_c: self.temperature.unwrap_or(10.0),
        })
    }
}
