//! Opening a trajectory for the commands that render frames from poses (`psns stream`,
//! `psns gige`): a CSV file, stdin, or the built-in turning camera.

use psns::camera::Attitude;
use psns::error::{Error, Result};
use psns::trajectory::{turning, CsvTrajectory, Pose};
use std::io::BufReader;
use std::path::{Path, PathBuf};

use psns::options::finite;

/// Poses in order.
pub type Poses = Box<dyn Iterator<Item = Result<Pose>> + Send>;

/// An opened trajectory.
pub struct Trajectory {
    /// The poses.
    pub poses: Poses,
    /// A regular file: reading one pose ahead costs no latency.
    pub lookahead: bool,
    /// Every pose carries a place.
    pub has_place: bool,
}

/// Where the poses come from: the trajectory options of `psns stream` and `psns gige`.
#[derive(clap::Args)]
pub struct TrajectoryArgs {
    /// Trajectory CSV (t_s, yaw_deg,pitch_deg,roll_deg or qw,qx,qy,qz [, lat_deg,lon_deg,height_m]); - for stdin. Default: built-in turning camera.
    #[arg(long, value_name = "PATH|-")]
    pub trajectory: Option<PathBuf>,
    /// Time zero of the trajectory, ISO 8601 UTC.
    #[arg(long, value_name = "TIME")]
    pub start_time: Option<String>,
    /// Built-in trajectory: yaw rate, degrees per second.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, default_value_t = 10.0)]
    pub yaw_rate: f64,
    /// Built-in trajectory: frame interval, ms.
    #[arg(long, value_parser = finite, default_value_t = 50.0)]
    pub frame_interval_ms: f64,
}

impl TrajectoryArgs {
    /// The trajectory these options name ([`open_trajectory`]), the turning camera starting at
    /// `start`.
    pub fn open(&self, start: Attitude) -> Result<Trajectory> {
        open_trajectory(
            self.trajectory.as_deref(),
            start,
            self.yaw_rate,
            self.frame_interval_ms,
        )
    }
}

/// Opens `path` (a CSV file, `-` for stdin), or with no path the built-in turning camera from
/// the attitude `start` (the scene's `--yaw`, `--pitch`, `--roll`) at `yaw_rate_deg_s`, one pose
/// every `frame_interval_ms`. A file's rows give the attitude: a `start` other than the default
/// is refused beside one, rather than ignored.
pub fn open_trajectory(
    path: Option<&Path>,
    start: Attitude,
    yaw_rate_deg_s: f64,
    frame_interval_ms: f64,
) -> Result<Trajectory> {
    if path.is_some() && start != Attitude::default() {
        return Err(Error::Invalid(
            "--yaw, --pitch, --roll, --quaternion and --frame do not apply with --trajectory, \
             whose rows give the attitude"
                .into(),
        ));
    }
    match path {
        None => {
            psns::error::check_range("frame-interval-ms", frame_interval_ms, 1e-3, 3.6e6)?;
            psns::error::check_range("yaw-rate", yaw_rate_deg_s, -1e6, 1e6)?;
            Ok(Trajectory {
                poses: Box::new(turning(start, yaw_rate_deg_s, frame_interval_ms * 1e-3)?),
                lookahead: false,
                has_place: false,
            })
        }
        // a pipe's last line must end in a newline (else its producer was cut off mid-line); a
        // file saved without a final newline is fine
        Some(p) if p.as_os_str() == "-" => {
            let t = CsvTrajectory::require_complete_lines(BufReader::new(std::io::stdin()))?;
            Ok(Trajectory {
                has_place: t.has_place(),
                poses: Box::new(t),
                lookahead: false,
            })
        }
        Some(p) => {
            let f = std::fs::File::open(p).map_err(|e| Error::input(p, e))?;
            let meta = f.metadata().map_err(|e| Error::input(p, e))?;
            if meta.is_dir() {
                return Err(Error::input(p, std::io::ErrorKind::IsADirectory.into()));
            }
            let regular = meta.is_file();
            let f = BufReader::new(f);
            let t = if regular {
                CsvTrajectory::new(f)?
            } else {
                CsvTrajectory::require_complete_lines(f)?
            };
            Ok(Trajectory {
                has_place: t.has_place(),
                poses: Box::new(t),
                lookahead: regular,
            })
        }
    }
}
