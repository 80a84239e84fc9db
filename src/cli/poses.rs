//! Opening a trajectory for the commands that render frames from poses (`psns stream`,
//! `psns gige`): a CSV file, stdin, or the built-in turning camera.

use psns::error::{Error, Result};
use psns::trajectory::{turning, CsvTrajectory, Pose};
use std::io::BufReader;
use std::path::Path;

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

/// Opens `path` (a CSV file, `-` for stdin), or with no path the built-in turning camera at
/// `yaw_rate_deg_s`, one pose every `frame_interval_ms`.
pub fn open_trajectory(
    path: Option<&Path>,
    yaw_rate_deg_s: f64,
    frame_interval_ms: f64,
) -> Result<Trajectory> {
    match path {
        None => {
            psns::error::check_range("frame-interval-ms", frame_interval_ms, 1e-3, 3.6e6)?;
            psns::error::check_range("yaw-rate", yaw_rate_deg_s, -1e6, 1e6)?;
            Ok(Trajectory {
                poses: Box::new(turning(yaw_rate_deg_s, frame_interval_ms * 1e-3)),
                lookahead: false,
                has_place: false,
            })
        }
        Some(p) if p.as_os_str() == "-" => {
            let t = CsvTrajectory::new(BufReader::new(std::io::stdin()))?;
            Ok(Trajectory {
                has_place: t.has_place(),
                poses: Box::new(t),
                lookahead: false,
            })
        }
        Some(p) => {
            let f = std::fs::File::open(p)
                .map_err(|e| Error::io(format!("opening trajectory {}", p.display()), e))?;
            let regular = f.metadata().map(|m| m.is_file()).unwrap_or(false);
            let t = CsvTrajectory::new(BufReader::new(f))?;
            Ok(Trajectory {
                has_place: t.has_place(),
                poses: Box::new(t),
                lookahead: regular,
            })
        }
    }
}
