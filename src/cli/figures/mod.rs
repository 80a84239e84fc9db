//! `psns figures`: regenerates the pictures of the docs (sky sweeps, default camera views, the
//! sensor figures).

pub mod sensor;
pub mod sky;

use super::progress::{Progress, Unit};
use super::{create_dir, vis};
use clap::Args;
use psns::config::SceneConfig;
use psns::{io, render, Result};
use std::path::{Path, PathBuf};

/// Options of `psns figures`.
#[derive(Args)]
pub struct FiguresArgs {
    /// Output directory (regenerate the docs' pictures with `--out docs/img`).
    #[arg(long, default_value = "out-figures")]
    out: PathBuf,
}

/// Runs `psns figures`.
pub fn run(a: FiguresArgs) -> anyhow::Result<()> {
    let mut progress = Progress::new(
        "psns figures",
        Unit::Steps,
        Some(SKY_FIGURE_STEPS + sensor::SENSOR_FIGURE_STEPS),
        false,
    );
    for f in sky_figures(&a.out, &mut progress)? {
        progress.println(format!("wrote {f}"));
    }
    for f in sensor::sensor_figures(&a.out, &mut progress)? {
        progress.println(format!("wrote {f}"));
    }
    Ok(())
}

/// Steps of [`sky_figures`] counted by its progress (one per picture).
pub const SKY_FIGURE_STEPS: u64 = 4;

/// `psns figures`: the sky and camera pictures of `docs/img` (small PNGs). Counts
/// [`SKY_FIGURE_STEPS`] steps on `progress`.
pub fn sky_figures(dir: &Path, progress: &mut Progress) -> Result<Vec<String>> {
    use crate::cli::figures::sky::sky_sweep;
    use psns::sky::SkyParams;
    use psns::sun::SunPosition;
    create_dir(dir)?;
    let mut files = Vec::new();
    let params = SkyParams::default();
    progress.set_message("sky: zenith sweep");
    let zen: Vec<SunPosition> = [10.0, 30.0, 50.0, 70.0, 85.0]
        .iter()
        .map(|&z| SunPosition::new(z, 200.0))
        .collect();
    let p = dir.join("sky_zenith_sweep.png");
    io::write_png_rgb8(&p, &sky_sweep(&params, &zen, 160)?)?;
    files.push(p.display().to_string());
    progress.inc(1);
    progress.set_message("sky: azimuth sweep");
    let az: Vec<SunPosition> = [0.0, 90.0, 200.0, 270.0]
        .iter()
        .map(|&a| SunPosition::new(50.0, a))
        .collect();
    let p = dir.join("sky_azimuth_sweep.png");
    io::write_png_rgb8(&p, &sky_sweep(&params, &az, 160)?)?;
    files.push(p.display().to_string());
    progress.inc(1);
    let rayleigh = SkyParams {
        model: psns::sky::PolarizationModel::Rayleigh,
        ..SkyParams::default()
    };
    progress.set_message("sky: Rayleigh vs Wang");
    let p = dir.join("sky_rayleigh_vs_wang.png");
    let a = sky_sweep(&params, &[SunPosition::new(50.0, 200.0)], 200)?;
    let b = sky_sweep(&rayleigh, &[SunPosition::new(50.0, 200.0)], 200)?;
    io::write_png_rgb8(&p, &vis::vstack(&[&a, &b], 4))?;
    files.push(p.display().to_string());
    progress.inc(1);
    progress.set_message("sky: default camera frame");
    // the default camera frame, 8x smaller
    let cfg = SceneConfig::default();
    let (sky, cam) = cfg.build()?;
    let ideal = render::render_ideal(&sky, &cam);
    let li = vis::downsample(&ideal.li, 8);
    let white = vis::quantile(&li, 0.999);
    let li = vis::gray_rgb(&vis::gray8(&li, white));
    let dop = vis::dop_rgb(&vis::decimate(&ideal.dop, 8), None);
    let aop = vis::aop_rgb(&vis::decimate(&ideal.aop_deg, 8), None);
    let p = dir.join("default_camera_li_dop_aop.png");
    io::write_png_rgb8(&p, &vis::hstack(&[&li, &dop, &aop], 4))?;
    files.push(p.display().to_string());
    progress.inc(1);
    Ok(files)
}
