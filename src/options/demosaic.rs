//! Options of `psns demosaic` (and `psns.demosaic` in Python).

use super::{finite, parsed, whole};
use crate::demosaic::Method;
use crate::sensor::mosaic::MosaicLayout;
use clap::Args;
use std::path::PathBuf;

/// Options of `psns demosaic`.
#[derive(Args)]
pub struct DemosaicArgs {
    /// Raw PNG/TIFF or psns stream file.
    pub input: PathBuf,
    /// Method: superpixel, bilinear, bicubic, ppid, newton, eari.
    #[arg(long, default_value = "bilinear", value_parser = parsed::<Method>)]
    pub method: Method,
    /// Output directory: new, empty, or a previous psns run's (replaced whole when this run
    /// has written everything).
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Frame index (stream input).
    #[arg(long, value_parser = whole)]
    pub frame: Option<u64>,
    /// Mosaic layout of a PNG/TIFF input, e.g. "90,45/135,0".
    #[arg(long, default_value = "90,45/135,0", value_parser = parsed::<MosaicLayout>)]
    pub layout: MosaicLayout,
    /// Also write dolp_debiased.npy, corrected for the Rice bias with this noise σ of S1/S2 (DN).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "SIGMA_DN")]
    pub dolp_debias: Option<f64>,
}
