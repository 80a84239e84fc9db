//! Hardware-in-the-loop streaming (`psns stream`): poses in, raw frames out, as a camera would
//! deliver them. (Being implemented.)

use crate::config::SceneConfig;
use crate::error::{Error, Result};
use std::path::PathBuf;

/// Options of `psns stream` besides the scene and sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamOptions {
    /// Trajectory CSV path, `-` for stdin; `None` = built-in turning generator.
    pub trajectory: Option<PathBuf>,
    /// Output: a file, a FIFO, or `-` for stdout.
    pub out: PathBuf,
    /// Stop after this many frames.
    pub frames: Option<u64>,
    /// Pace output in real time at this rate against the trajectory clock; `None` = unpaced.
    pub rate_fps: Option<f64>,
    /// Trajectory time zero, ISO 8601 UTC; `None` = the scene's `sun.time`, else 2025-06-21T10:00:00Z.
    pub start_time: Option<String>,
    /// Built-in generator: yaw rate, degrees per second.
    pub yaw_rate_deg_s: f64,
    /// Built-in generator: frame interval, ms.
    pub frame_interval_ms: f64,
    /// Stamp host CLOCK_MONOTONIC into frame headers (breaks byte-identical output).
    pub stamp_host_time: bool,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            trajectory: None,
            out: PathBuf::from("-"),
            frames: None,
            rate_fps: None,
            start_time: None,
            yaw_rate_deg_s: 10.0,
            frame_interval_ms: 50.0,
            stamp_host_time: false,
        }
    }
}

/// What a stream run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamSummary {
    /// Frames written.
    pub frames: u64,
    /// Frames that were late against `--rate`.
    pub late_frames: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// True when the reader closed the output early.
    pub reader_closed: bool,
}

/// Runs `psns stream`.
pub fn run_stream(cfg: &SceneConfig, opts: &StreamOptions) -> Result<StreamSummary> {
    let _ = (cfg, opts);
    Err(Error::Invalid("psns stream is not implemented yet".into()))
}
