//! `psns` command line: argument parsing only; the work is in the library (`psns::app`).

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};
use psns::camera::{Attitude, AttitudeFrame};
use psns::config::{SceneConfig, SceneKind};
use psns::sensor::packing::PixelFormat;
use psns::sensor::{Exposure, Preset, SensorConfig};
use psns::sky::{DopNorm, PolarizationModel};
use psns::sun::{Place, Refraction};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "psns",
    version,
    about = "Polarized skylight + IMX250MZR polarization camera emulator"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a scene: ideal LI/DOP/AOP images, polarizer images and visualisations.
    Render {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        raw: RawArgs,
        /// Also emulate the sensor: raw.png, raw.tiff, raw.bin, truth_*.npy.
        #[arg(long = "raw")]
        raw_frame: bool,
        /// Output directory (created if missing; files of the same names are replaced).
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Sky values for directions read as CSV on stdin (header `zenith_deg,azimuth_deg`).
    Sky {
        #[command(flatten)]
        scene: SceneArgs,
    },
    /// Sun position (SPA) for a UTC time and place, as CSV `zenith_deg,azimuth_deg`.
    Sun(SunArgs),
    /// Stream raw frames driven by a trajectory to a file, FIFO or stdout (hardware in the loop).
    Stream {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        raw: RawArgs,
        /// Trajectory CSV (t_s, yaw_deg,pitch_deg,roll_deg or qw,qx,qy,qz [, lat_deg,lon_deg,height_m]); - for stdin. Default: built-in turning camera.
        #[arg(long, value_name = "PATH|-")]
        trajectory: Option<PathBuf>,
        /// Output file, FIFO, or - for stdout.
        #[arg(long, default_value = "-", value_name = "PATH|-")]
        out: PathBuf,
        /// Stop after N frames.
        #[arg(long, value_name = "N")]
        frames: Option<u64>,
        /// Pace output in real time at FPS against the trajectory clock (default: unpaced).
        #[arg(long, value_parser = finite, value_name = "FPS")]
        rate: Option<f64>,
        /// Time zero of the trajectory, ISO 8601 UTC.
        #[arg(long, value_name = "TIME")]
        start_time: Option<String>,
        /// Built-in trajectory: yaw rate, degrees per second.
        #[arg(long, value_parser = finite, allow_negative_numbers = true, default_value_t = 10.0)]
        yaw_rate: f64,
        /// Built-in trajectory: frame interval, ms.
        #[arg(long, value_parser = finite, default_value_t = 50.0)]
        frame_interval_ms: f64,
        /// Stamp the host monotonic clock into frame headers (output no longer byte-identical).
        #[arg(long)]
        stamp_host_time: bool,
    },
    /// Check a frame stream: frame count, drops, corrupt and truncated frames. Exit 0 only if clean.
    Verify {
        /// Stream file, FIFO, or - for stdin.
        file: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Write one frame of a stream as PNG and TIFF plus its metadata as JSON.
    Extract {
        /// Stream file, FIFO, or - for stdin.
        file: PathBuf,
        /// Frame index.
        #[arg(long)]
        frame: u64,
        /// Output directory.
        #[arg(long, default_value = ".")]
        out: PathBuf,
    },
    /// Demosaic a raw mosaic (PNG/TIFF) or a stream frame into S0, S1, S2, DoLP, AoLP.
    Demosaic {
        /// Raw PNG/TIFF or psns stream file.
        input: PathBuf,
        /// Method: superpixel, bilinear, bicubic, ppid, newton, eari.
        #[arg(long, default_value = "bilinear", value_parser = parse_method)]
        method: psns::demosaic::Method,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Frame index (stream input).
        #[arg(long)]
        frame: Option<u64>,
        /// Mosaic layout of a PNG/TIFF input, e.g. "90,45/135,0".
        #[arg(long, default_value = "90,45/135,0", value_parser = parse_layout)]
        layout: psns::sensor::mosaic::MosaicLayout,
        /// Also write dolp_debiased.npy, corrected for the Rice bias with this noise σ of S1/S2 (DN).
        #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "SIGMA_DN")]
        dolp_debias: Option<f64>,
    },
    /// Benchmarks that chart speed against accuracy.
    Bench {
        #[command(subcommand)]
        what: BenchCmd,
    },
    /// Regenerate the pictures in docs/ (sky sweeps, default camera views).
    Figures {
        /// Output directory.
        #[arg(long, default_value = "docs/img")]
        out: PathBuf,
    },
}

fn parse_method(s: &str) -> Result<psns::demosaic::Method, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

fn parse_layout(s: &str) -> Result<psns::sensor::mosaic::MosaicLayout, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

#[derive(Subcommand)]
enum BenchCmd {
    /// Time every demosaic method on full-size frames and score it on the named scenes; writes
    /// demosaic.csv, the speed-vs-accuracy chart and stability maps.
    Demosaic {
        /// Output directory.
        #[arg(long, default_value = "docs/bench")]
        out: PathBuf,
        /// Timed runs per method (median reported).
        #[arg(long, default_value_t = 7)]
        runs: usize,
        /// Small frames and few runs (a quick look; not for the docs).
        #[arg(long)]
        quick: bool,
    },
    /// Exact vs coarse-grid sky evaluation: time per full frame and error (writes sky_grid.csv).
    Sky {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output directory.
        #[arg(long, default_value = "docs/bench")]
        out: PathBuf,
        /// Timed runs per setting (median reported).
        #[arg(long, default_value_t = 5)]
        runs: usize,
    },
}

/// Parses a finite f64 (rejects NaN and infinities with a clear message).
fn finite(s: &str) -> Result<f64, String> {
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

/// Parses `a,b,...` with exactly N finite numbers.
fn finite_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s.split(',').map(finite).collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("expected {N} comma-separated numbers, found {}", v.len()))
}

#[derive(Clone, Copy, ValueEnum)]
enum ModelArg {
    Wang,
    Rayleigh,
}

#[derive(Clone, Copy, ValueEnum)]
enum NormArg {
    Clamp,
    Wilkie,
}

#[derive(Clone, Copy, ValueEnum)]
enum FrameArg {
    Solar,
    Enu,
}

/// Scene options shared by `render`, `sky` (and later commands). Every option overrides the
/// value from `--config`.
#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene file (TOML or JSON, e.g. a previous run's scene.json).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Sun zenith angle, degrees (0..90 for a render).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    sun_zenith: Option<f64>,
    /// Sun altitude (elevation), degrees; alternative to --sun-zenith.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "sun_zenith")]
    sun_altitude: Option<f64>,
    /// Sun compass azimuth, degrees from north, clockwise.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    sun_azimuth: Option<f64>,
    /// UTC time (ISO 8601, e.g. 2003-10-17T19:30:30Z): sun from SPA with --lat/--lon.
    #[arg(long, conflicts_with_all = ["sun_zenith", "sun_altitude", "sun_azimuth"])]
    time: Option<String>,
    /// Observer latitude, degrees north.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lat: Option<f64>,
    /// Observer longitude, degrees east.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lon: Option<f64>,
    /// Observer height above the ellipsoid, metres (for --time).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "M")]
    observer_height: Option<f64>,
    #[command(flatten)]
    spa: SpaArgs,
    /// Polarization model.
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// Turbidity, 1..10.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "T")]
    turbidity: Option<f64>,
    /// Wavelength, nm, 320..720.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    wavelength: Option<f64>,
    /// Ground albedo, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "A")]
    albedo: Option<f64>,
    /// Distance of both neutral points from the sun (Babinet and Brewster), degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    neutral_distance: Option<f64>,
    /// Babinet point distance above the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    babinet: Option<f64>,
    /// Brewster point distance below the sun, degrees 0..60.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG", conflicts_with = "neutral_distance")]
    brewster: Option<f64>,
    /// Maximum DOP of the Rayleigh model, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    dop_max: Option<f64>,
    /// Uniform unpolarized radiance of ground pixels, W m^-2 sr^-1 nm^-1 (default 0).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "L")]
    ground_radiance: Option<f64>,
    /// DOP normalisation of the Wang model (clamp: none; wilkie: 2/π).
    #[arg(long, value_enum)]
    dop_norm: Option<NormArg>,
    /// Camera yaw, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    yaw: Option<f64>,
    /// Camera pitch, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    pitch: Option<f64>,
    /// Camera roll, degrees.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    roll: Option<f64>,
    /// Reference frame of yaw/pitch/roll (or of --quaternion).
    #[arg(long, value_enum)]
    frame: Option<FrameArg>,
    /// Attitude quaternion W,X,Y,Z (Hamilton, scalar first) rotating camera vectors into the frame.
    #[arg(long, value_parser = finite_list::<4>, allow_negative_numbers = true,
          conflicts_with_all = ["yaw", "pitch", "roll"], value_name = "W,X,Y,Z")]
    quaternion: Option<[f64; 4]>,
    /// Focal length, mm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "MM")]
    focal_length: Option<f64>,
    /// Pixel pitch, µm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "UM")]
    pixel_pitch: Option<f64>,
    /// Image width (columns), pixels.
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    width: Option<i64>,
    /// Image height (rows), pixels.
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    height: Option<i64>,
    /// Principal point X,Y: 0-based column and row of the optical axis.
    #[arg(long, value_parser = finite_list::<2>, allow_negative_numbers = true, value_name = "X,Y")]
    principal_point: Option<[f64; 2]>,
}

fn size(name: &str, v: i64) -> psns::Result<usize> {
    if v <= 0 || v > 65_536 {
        return Err(psns::Error::range(name, v as f64, "1..65536"));
    }
    Ok(v as usize)
}

impl SceneArgs {
    /// Scene from --config (or defaults) with every given option applied.
    fn scene(&self) -> psns::Result<SceneConfig> {
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
            };
        }
        k.turbidity = self.turbidity.unwrap_or(k.turbidity);
        k.wavelength_nm = self.wavelength.unwrap_or(k.wavelength_nm);
        k.albedo = self.albedo.unwrap_or(k.albedo);
        if let Some(d) = self.neutral_distance {
            k.babinet_deg = d;
            k.brewster_deg = d;
        }
        k.babinet_deg = self.babinet.unwrap_or(k.babinet_deg);
        k.brewster_deg = self.brewster.unwrap_or(k.brewster_deg);
        k.dop_max = self.dop_max.unwrap_or(k.dop_max);
        if self.ground_radiance.is_some() {
            k.ground_radiance = self.ground_radiance;
        }
        if let Some(n) = self.dop_norm {
            k.dop_norm = match n {
                NormArg::Clamp => DopNorm::Clamp,
                NormArg::Wilkie => DopNorm::Wilkie,
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
                cam.attitude = Attitude::Quaternion {
                    frame: frame_given.unwrap_or(frame),
                    wxyz: q,
                };
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
        Ok(c)
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum SceneKindArg {
    Sky,
    Flat,
}

#[derive(Clone, Copy, ValueEnum)]
enum OnOff {
    On,
    Off,
}

/// Sensor and raw-frame options (`render --raw`, `stream`, `bench`).
#[derive(Args, Clone, Default)]
struct RawArgs {
    /// Sensor preset: camera (realistic IMX250MZR), nfpi, gniipi, gniicpi (PSNS dataset variants).
    #[arg(long, value_parser = parse_preset)]
    preset: Option<Preset>,
    /// Scene for raw frames: the sky or a uniform flat field.
    #[arg(long, value_enum)]
    scene: Option<SceneKindArg>,
    /// Flat-field radiance, W m^-2 sr^-1 nm^-1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "R")]
    flat_radiance: Option<f64>,
    /// Flat-field degree of linear polarization, 0..1.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "D")]
    flat_dolp: Option<f64>,
    /// Flat-field angle of linear polarization, degrees (sensor frame).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DEG")]
    flat_aolp: Option<f64>,
    /// Exposure time, µs (20..10,000,000).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "US", conflicts_with = "auto_exposure")]
    exposure_us: Option<f64>,
    /// Auto-exposure: 99th percentile of the sky at 70 % of full well.
    #[arg(long)]
    auto_exposure: bool,
    /// Analog gain, dB (0..48).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DB")]
    gain_db: Option<f64>,
    /// Black level, DN at 12 bit (0..200).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "DN")]
    black_level: Option<f64>,
    /// Output bit depth: 8, 10 or 12.
    #[arg(long, allow_negative_numbers = true, value_name = "BITS")]
    bit_depth: Option<i64>,
    /// Packed pixel format of raw.bin / the stream payload: mono8, mono12p, mono12packed, mono16.
    #[arg(long, value_parser = parse_pixel_format)]
    pixel_format: Option<PixelFormat>,
    /// Camera seed (fixed patterns and noise).
    #[arg(long)]
    seed: Option<u64>,
    /// Frame index of that camera (temporal noise).
    #[arg(long)]
    frame_index: Option<u64>,
    /// Draw the solar disc (default: on for the camera preset, off for PSNS presets).
    #[arg(long, value_enum)]
    sun_disc: Option<OnOff>,
    /// Add soft unpolarized clouds to the scene.
    #[arg(long)]
    clouds: bool,
    /// Evaluate the sky every N pixels and interpolate (1 = exact; default 4).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    sky_grid: Option<i64>,
    /// Lens f-number.
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    f_number: Option<f64>,
    /// Read (dark) noise, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    read_noise: Option<f64>,
    /// Full-well capacity, e-.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "E")]
    full_well: Option<f64>,
    /// Sensor temperature, °C (dark current).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "C")]
    sensor_temperature: Option<f64>,
    /// Pixel crosstalk fraction (0..0.03).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    crosstalk: Option<f64>,
    /// Band-pass filter width, nm.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "NM")]
    filter_width: Option<f64>,
    /// Switch stages off: any of ri, polarizer_er, polarizer_orientation, prnu, crosstalk, dark,
    /// shot, fwc_clip, dsnu, read, quantize (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "STAGE")]
    off: Vec<String>,
    /// Set any sensor field: KEY=VALUE with VALUE in JSON (e.g. prnu=0.01, ri={"kind":"cospower","n":4}).
    #[arg(long = "sensor-set", value_name = "KEY=VALUE")]
    sensor_set: Vec<String>,
}

fn parse_preset(s: &str) -> Result<Preset, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

fn parse_pixel_format(s: &str) -> Result<PixelFormat, String> {
    s.parse().map_err(|e: psns::Error| e.to_string())
}

impl RawArgs {
    /// Applies the raw options to a scene.
    fn apply(&self, c: &mut SceneConfig) -> psns::Result<()> {
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
struct SpaArgs {
    /// ΔT = TT − UT in seconds (default: the crate's estimate for the date).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "S")]
    delta_t: Option<f64>,
    /// Apply atmospheric refraction (default: geometric position).
    #[arg(long)]
    refraction: bool,
    /// Pressure for --refraction, hPa.
    #[arg(long, value_parser = finite, default_value_t = 1010.0, value_name = "HPA")]
    pressure: f64,
    /// Temperature for --refraction, °C.
    #[arg(long, value_parser = finite, default_value_t = 10.0, allow_negative_numbers = true, value_name = "C")]
    temperature: f64,
}

impl SpaArgs {
    fn refraction(&self) -> Option<Refraction> {
        self.refraction.then_some(Refraction {
            pressure_hpa: self.pressure,
            temperature_c: self.temperature,
        })
    }
}

#[derive(Args)]
struct SunArgs {
    /// UTC time, ISO 8601 (e.g. 2003-10-17T19:30:30Z).
    #[arg(long)]
    time: String,
    /// Latitude, degrees north (−90..90).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lat: f64,
    /// Longitude, degrees east (−180..180).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lon: f64,
    /// Height above the ellipsoid, metres.
    #[arg(long, value_parser = finite, default_value_t = 0.0, allow_negative_numbers = true)]
    height: f64,
    #[command(flatten)]
    spa: SpaArgs,
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.cmd {
        Cmd::Render {
            scene,
            raw,
            raw_frame,
            out,
        } => {
            let mut cfg = scene.scene()?;
            raw.apply(&mut cfg)?;
            if raw_frame || cfg.raw.scene == SceneKind::Flat {
                let s = psns::app::render_raw_to_dir(&cfg, &out)?;
                eprintln!(
                    "raw frame {}x{}: scene {:.3} s + sensor {:.3} s (camera setup {:.3} s); wrote {} files to {}",
                    cfg.camera.intrinsics.width,
                    cfg.camera.intrinsics.height,
                    s.scene_s,
                    s.sensor_s,
                    s.setup_s,
                    s.files.len(),
                    out.display()
                );
                return Ok(());
            }
            let s = psns::app::render_ideal_to_dir(&cfg, &out)?;
            eprintln!(
                "rendered {}x{} in {:.3} s; wrote {} files to {}",
                cfg.camera.intrinsics.width,
                cfg.camera.intrinsics.height,
                s.render_s,
                s.files.len(),
                out.display()
            );
        }
        Cmd::Sky { scene } => {
            let cfg = scene.scene()?;
            let stdin = std::io::stdin().lock();
            let stdout = std::io::stdout().lock();
            psns::app::sky_csv(&cfg, stdin, std::io::BufWriter::new(stdout))?;
        }
        Cmd::Stream {
            scene,
            raw,
            trajectory,
            out,
            frames,
            rate,
            start_time,
            yaw_rate,
            frame_interval_ms,
            stamp_host_time,
        } => {
            let mut cfg = scene.scene()?;
            raw.apply(&mut cfg)?;
            let opts = psns::hil::StreamOptions {
                trajectory,
                out,
                frames,
                rate_fps: rate,
                start_time,
                yaw_rate_deg_s: yaw_rate,
                frame_interval_ms,
                stamp_host_time,
            };
            let s = psns::hil::run_stream(&cfg, &opts)?;
            eprintln!(
                "streamed {} frames in {:.2} s ({:.2} fps){}{}",
                s.frames,
                s.seconds,
                s.frames as f64 / s.seconds.max(1e-9),
                if s.late_frames > 0 {
                    format!(", {} late", s.late_frames)
                } else {
                    String::new()
                },
                if s.reader_closed {
                    ", reader closed the stream"
                } else {
                    ""
                }
            );
        }
        Cmd::Verify { file, json } => {
            let rep = psns::stream::verify(psns::app::open_input(&file)?)?;
            let mut out = std::io::stdout().lock();
            if json {
                writeln!(out, "{}", serde_json::to_string_pretty(&rep)?)?;
            } else {
                write!(out, "{rep}")?;
            }
            if !rep.clean() {
                return Err(anyhow::Error::new(NotClean));
            }
        }
        Cmd::Extract { file, frame, out } => {
            for f in psns::app::extract_to_dir(&file, frame, &out)? {
                eprintln!("wrote {f}");
            }
        }
        Cmd::Demosaic {
            input,
            method,
            out,
            frame,
            layout,
            dolp_debias,
        } => {
            let opts = psns::bench::DemosaicOptions {
                input,
                method,
                out,
                frame,
                layout,
                debias_sigma: dolp_debias,
            };
            for f in psns::bench::demosaic_to_dir(&opts)? {
                eprintln!("wrote {f}");
            }
        }
        Cmd::Bench { what } => match what {
            BenchCmd::Demosaic { out, runs, quick } => {
                let opts = psns::bench::BenchOptions { out, runs, quick };
                for f in psns::bench::bench_demosaic(&opts)? {
                    eprintln!("wrote {f}");
                }
            }
            BenchCmd::Sky { scene, out, runs } => {
                let cfg = scene.scene()?;
                for f in psns::app::bench_sky_to_dir(&cfg, &out, runs)? {
                    eprintln!("wrote {f}");
                }
            }
        },
        Cmd::Figures { out } => {
            for f in psns::app::sky_figures(&out)? {
                eprintln!("wrote {f}");
            }
            for f in psns::figures_sensor::sensor_figures(&out)? {
                eprintln!("wrote {f}");
            }
        }
        Cmd::Sun(a) => {
            let t = psns::sun::parse_time(&a.time)?;
            let place = Place {
                lat_deg: a.lat,
                lon_deg: a.lon,
                height_m: a.height,
            };
            let s = psns::sun::spa(&t, &place, a.spa.delta_t, a.spa.refraction())?;
            let mut out = std::io::stdout().lock();
            writeln!(
                out,
                "zenith_deg,azimuth_deg\n{:.9},{:.9}",
                s.zenith_deg, s.azimuth_deg
            )
            .context("writing to stdout")?;
        }
    }
    Ok(())
}

/// `psns verify` found damage: exit code 1 with the report already printed.
#[derive(Debug)]
struct NotClean;
impl std::fmt::Display for NotClean {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stream is not clean")
    }
}
impl std::error::Error for NotClean {}

fn main() -> ExitCode {
    let cli = Cli::parse(); // usage errors exit with code 2
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let lib = e.downcast_ref::<psns::Error>();
            let io_pipe = e
                .downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe);
            if lib.is_some_and(|l| l.is_broken_pipe()) || io_pipe {
                return ExitCode::SUCCESS; // reader went away: end quietly
            }
            match lib {
                Some(l) => eprintln!("psns: error: {l}"),
                None => eprintln!("psns: error: {e:#}"),
            }
            if lib.is_some_and(|l| l.is_usage()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}
