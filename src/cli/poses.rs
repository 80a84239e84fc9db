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
