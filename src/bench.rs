//! `psns demosaic` and `psns bench demosaic`: demosaic files and streams, score every method on
//! named scenes against the emulator's ground truth, chart speed against accuracy.
//! (Being implemented.)

use crate::demosaic::Method;
use crate::error::{Error, Result};
use crate::sensor::mosaic::MosaicLayout;
use std::path::{Path, PathBuf};

/// Options of `psns demosaic`.
#[derive(Clone, Debug, PartialEq)]
pub struct DemosaicOptions {
    /// Raw PNG/TIFF (mosaic codes) or a psns frame stream.
    pub input: PathBuf,
    /// Method.
    pub method: Method,
    /// Output directory.
    pub out: PathBuf,
    /// Frame index when the input is a stream (default: the first intact frame).
    pub frame: Option<u64>,
    /// Mosaic layout of the input (default IMX250MZR `90,45/135,0`; a stream's header wins).
    pub layout: MosaicLayout,
}

/// `psns demosaic`: writes s0/s1/s2/dolp/aolp `.npy` plus visualisations; returns the files.
pub fn demosaic_to_dir(opts: &DemosaicOptions) -> Result<Vec<String>> {
    let _ = opts;
    Err(Error::Invalid(
        "psns demosaic is not implemented yet".into(),
    ))
}

/// Options of `psns bench demosaic`.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Output directory (CSV, chart, stability maps).
    pub out: PathBuf,
    /// Timed runs per method (median reported).
    pub runs: usize,
    /// Smaller frames and fewer runs, for a quick look / tests.
    pub quick: bool,
}

/// `psns bench demosaic`; returns the files written.
pub fn bench_demosaic(opts: &BenchOptions) -> Result<Vec<String>> {
    let _ = (opts, Path::new("."));
    Err(Error::Invalid(
        "psns bench demosaic is not implemented yet".into(),
    ))
}
