//! Options of `psns sky` (and `psns.sky` in Python).

use super::SceneArgs;
use clap::Args;
use std::path::PathBuf;

/// Options of `psns sky`.
#[derive(Args)]
pub struct SkyArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub scene: SceneArgs,
    /// Instead of reading directions: write the DOP stability map of both DOP models
    /// (dop_stability.csv, .svg and a small .png) over turbidity 1..10 x sun zenith 0..90 x
    /// wavelength 380..720 nm; the scene's other sky settings (albedo, neutral points, norm) apply.
    #[arg(long)]
    pub stability: bool,
    /// Output directory of --stability (regenerate the docs' map with `--out docs/img`).
    #[arg(long, requires = "stability", value_name = "DIR")]
    pub out: Option<PathBuf>,
}
