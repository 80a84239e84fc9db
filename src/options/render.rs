//! Options of `psns render` (and `psns.render`/`psns.render_raw` in Python).

use super::{RawArgs, SceneArgs, WorldArgs};
use crate::config::{SceneConfig, SceneKind};
use crate::{Error, Result};
use clap::Args;
use std::path::PathBuf;

/// Options of `psns render`.
#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub scene: SceneArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub raw: RawArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub world: WorldArgs,
    /// Also emulate the sensor: raw.png, raw.tiff, raw.bin, truth_*.npy.
    #[arg(long = "raw")]
    pub raw_frame: bool,
    /// Output directory: new, empty, or a previous psns run's (replaced whole when this run
    /// has written everything; a failed or killed run leaves it as it was).
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

impl RenderArgs {
    /// The scene these options describe, checked as `psns render` checks it, and whether a raw
    /// frame is asked for (`--raw`, or a flat-field scene).
    pub fn config(&self) -> Result<(SceneConfig, bool)> {
        let mut cfg = self.scene.scene()?;
        self.raw.apply(&mut cfg)?;
        self.world.apply(&mut cfg)?;
        // the lens in force (the preset's unless --lens), so scene.json records it
        cfg.camera.intrinsics = cfg.intrinsics();
        let raw = self.raw_frame || cfg.raw.scene == SceneKind::Flat;
        // a seeded world (clouds, trees' gaps) takes --seed without --raw too
        let first = match WorldArgs::seeded(&cfg) {
            true => self.raw.first_given_but("seed"),
            false => self.raw.first_given(),
        };
        if let (false, Some(opt)) = (raw, first) {
            return Err(Error::Invalid(format!(
                "--{opt} applies to the raw frame: add --raw (without it psns render writes the ideal images only)"
            )));
        }
        if cfg.sun.time.is_none() {
            if let Some(opt) = self.scene.place_given() {
                return Err(Error::Invalid(format!(
                    "--{opt} places the observer for --time; the sun is given directly here, so it would be ignored (add --time, or leave --{opt} out)"
                )));
            }
        }
        Ok((cfg, raw))
    }
}
