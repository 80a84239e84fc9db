//! `psns` command line: argument parsing only; the work is in the library (`psns::app`).

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};
use psns::camera::{Attitude, AttitudeFrame};
use psns::config::SceneConfig;
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
    /// Regenerate the pictures in docs/ (sky sweeps, default camera views).
    Figures {
        /// Output directory.
        #[arg(long, default_value = "docs/img")]
        out: PathBuf,
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
#[derive(Args, Clone, Default)]
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
    /// ΔT = TT − UT in seconds (default: estimated).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "S")]
    delta_t: Option<f64>,
    /// Apply atmospheric refraction to the SPA position.
    #[arg(long)]
    refraction: bool,
    /// Pressure for --refraction, hPa.
    #[arg(long, value_parser = finite, default_value_t = 1010.0, value_name = "HPA")]
    pressure: f64,
    /// Temperature for --refraction, °C.
    #[arg(long, value_parser = finite, default_value_t = 10.0, allow_negative_numbers = true, value_name = "C")]
    temperature: f64,
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
        if self.delta_t.is_some() {
            s.delta_t_s = self.delta_t;
        }
        if self.refraction {
            s.refraction = Some(Refraction {
                pressure_hpa: self.pressure,
                temperature_c: self.temperature,
            });
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
        if let Some(q) = self.quaternion {
            cam.attitude = Attitude::Quaternion {
                frame: frame_given.unwrap_or_default(),
                wxyz: q,
            };
        } else if self.yaw.is_some()
            || self.pitch.is_some()
            || self.roll.is_some()
            || frame_given.is_some()
        {
            let (mut f, mut y, mut p, mut r) = match cam.attitude {
                Attitude::Euler {
                    frame,
                    yaw_deg,
                    pitch_deg,
                    roll_deg,
                } => (frame, yaw_deg, pitch_deg, roll_deg),
                Attitude::Quaternion { frame, .. } => (frame, 0.0, 0.0, 0.0),
            };
            f = frame_given.unwrap_or(f);
            y = self.yaw.unwrap_or(y);
            p = self.pitch.unwrap_or(p);
            r = self.roll.unwrap_or(r);
            cam.attitude = Attitude::Euler {
                frame: f,
                yaw_deg: y,
                pitch_deg: p,
                roll_deg: r,
            };
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

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.cmd {
        Cmd::Render { scene, out } => {
            let cfg = scene.scene()?;
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
        Cmd::Figures { out } => {
            for f in psns::app::sky_figures(&out)? {
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
            let r = a.refraction.then_some(Refraction {
                pressure_hpa: a.pressure,
                temperature_c: a.temperature,
            });
            let s = psns::sun::spa(&t, &place, a.delta_t, r)?;
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
            eprintln!("psns: error: {e:#}");
            if lib.is_some_and(|l| l.is_usage()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}
