//! `psns heading`: the camera's yaw from one raw frame (PNG/TIFF mosaic), as a user with a real
//! camera would call it: pixels, sun position, intrinsics and the IMU's tilt, nothing else.

use super::args::SceneArgs;
use super::demosaic::{demosaic_codes, load_raw};
use clap::Args;
use psns::camera::Attitude;
use psns::demosaic::Method;
use psns::heading::{eigenvector_heading, mask_saturated, HeadingSetup};
use psns::sensor::mosaic::MosaicLayout;
use psns::{Error, Result};
use std::io::Write;
use std::path::PathBuf;

/// Options of `psns heading`.
#[derive(Args)]
pub struct HeadingArgs {
    /// Raw PNG/TIFF mosaic (codes), or a psns stream with --frame.
    input: PathBuf,
    /// Sun position (--sun-zenith/--sun-azimuth or --time/--lat/--lon), intrinsics
    /// (--width/--height/--focal-length/--pixel-pitch) and the known tilt (--pitch/--roll, ENU).
    #[command(flatten)]
    scene: SceneArgs,
    /// Demosaic method.
    #[arg(long, default_value = "bilinear", value_parser = |s: &str| s.parse::<Method>().map_err(|e| e.to_string()))]
    demosaic: Method,
    /// Significant bits of the codes in a PNG/TIFF (saturation is the top code); a stream says.
    #[arg(long, value_parser = super::args::whole)]
    bits: Option<u64>,
    /// Frame index of a stream input (`--frame` is the attitude frame of the scene options).
    #[arg(long, value_parser = super::args::whole, value_name = "N")]
    index: Option<u64>,
}

/// Runs `psns heading`: prints `yaw_deg,confidence,pixels,saturated_pixels`.
pub fn run(a: HeadingArgs) -> anyhow::Result<()> {
    let row = heading_row(&a)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "yaw_deg,confidence,pixels,saturated_pixels\n{row}")?;
    Ok(())
}

fn heading_row(a: &HeadingArgs) -> Result<String> {
    if a.scene.yaw.is_some() || a.scene.quaternion.is_some() {
        return Err(Error::Invalid(
            "psns heading estimates the yaw: give only the tilt (--pitch, --roll)".into(),
        ));
    }
    let cfg = a.scene.scene()?;
    let sun = cfg.sun.resolve()?;
    cfg.sun.check_up(sun)?;
    let (pitch, roll) = match cfg.camera.attitude {
        Attitude::Euler {
            pitch_deg,
            roll_deg,
            ..
        } => (pitch_deg, roll_deg),
        Attitude::Quaternion { .. } => {
            return Err(Error::Invalid(
                "psns heading takes the tilt as --pitch/--roll, not a quaternion".into(),
            ))
        }
    };
    let raw = load_raw(&a.input, MosaicLayout::default(), a.index)?;
    let i = cfg.camera.intrinsics;
    if (raw.codes.width, raw.codes.height) != (i.width, i.height) {
        return Err(Error::Invalid(format!(
            "{} is {} x {} pixels but the intrinsics say {} x {}: give --width/--height (and --pixel-pitch, --focal-length) of the camera",
            a.input.display(),
            raw.codes.width,
            raw.codes.height,
            i.width,
            i.height
        )));
    }
    psns::demosaic::check_raw(&raw.codes)?;
    let bits = match (a.bits, raw.frame) {
        (Some(b), _) if (8..=16).contains(&b) => b as u8,
        (Some(b), _) => return Err(Error::range("bits", b as f64, "8..16")),
        (None, Some(_)) => raw.bits,
        (None, None) if raw.bits == 8 => 8,
        (None, None) => 12, // the IMX250MZR's deepest mode, in a 16-bit file
    };
    let full = ((1u32 << bits) - 1).min(65535) as u16;
    let mut p = demosaic_codes(&raw.codes, raw.black_level, raw.layout, a.demosaic)?;
    let saturated = mask_saturated(&mut p.dolp, &raw.codes, full);
    let mut setup = HeadingSetup::new(i, sun);
    setup.pitch_deg = pitch;
    setup.roll_deg = roll;
    match eigenvector_heading(&p.aolp_deg, &p.dolp, &setup) {
        Ok(e) => Ok(format!(
            "{:.4},{:.4},{},{saturated}",
            e.yaw_deg, e.confidence, e.pixels
        )),
        // too few usable pixels (saturated, unpolarized): no heading, zero confidence
        Err(Error::Invalid(m)) if m.starts_with("heading: only") => {
            eprintln!("psns: {m}");
            Ok(format!("nan,0,0,{saturated}"))
        }
        Err(e) => Err(e),
    }
}
