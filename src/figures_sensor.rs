//! Sensor pictures for `docs/`: raw frame, mosaic zoom, channels, PSNS presets, photon transfer.
//! (Being implemented.)

use crate::error::Result;
use std::path::Path;

/// Writes the sensor figures into `dir`; returns the files written.
pub fn sensor_figures(dir: &Path) -> Result<Vec<String>> {
    let _ = dir;
    Ok(Vec::new())
}
