//! `psns figures`: regenerates the pictures of the docs (sky sweeps, default camera views, the
//! sensor figures).

pub mod sensor;
pub mod sky;
pub mod world;

use super::progress::{Progress, Unit};
use super::vis;
use clap::Args;
use psns::config::SceneConfig;
use psns::io::create_dir;
use psns::{io, render, Result};
use std::path::{Path, PathBuf};

/// Options of `psns figures`.
#[derive(Args)]
pub struct FiguresArgs {
    /// Output directory (regenerate the docs' pictures with `--out docs/img`).
    #[arg(long, default_value = "out-figures")]
    out: PathBuf,
    /// Only this group of pictures: sky, sensor, lens or world (default: all).
    #[arg(long, value_enum, value_name = "GROUP")]
    only: Option<Group>,
}

/// A group of pictures.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Group {
    /// Sky sweeps and the default camera frame.
    Sky,
    /// The sensor figures of docs/sensor.md.
    Sensor,
    /// The lens and projection figures of docs/camera.md.
    Lens,
    /// The world around the camera of docs/world.md.
    World,
}

/// The scene of the docs' pictures: the default scene with the camera's image +y axis toward the
/// sun's azimuth (yaw 0 in the solar frame, ENU yaw 200°), the view the pictures and their numbers
/// in docs/ describe.
pub(crate) fn figure_scene() -> SceneConfig {
    let mut c = SceneConfig::default();
    c.camera.attitude = psns::camera::Attitude::solar(0.0, 0.0, 0.0);
    c
}

/// [`figure_scene`] through a 1.8 mm equidistant fisheye looking at the zenith, at 8 x 8
/// binning of the full sensor (306 x 256).
pub(crate) fn fisheye_scene() -> SceneConfig {
    let mut c = figure_scene();
    let i = &mut c.camera.intrinsics;
    i.projection = psns::camera::Projection::Equidistant;
    i.focal_length_mm = 1.8;
    i.width = 306;
    i.height = 256;
    i.pixel_pitch_um = 3.45 * 8.0;
    c
}

/// Runs `psns figures`.
pub fn run(a: FiguresArgs) -> anyhow::Result<()> {
    let want = |g: Group| a.only.is_none_or(|o| o == g);
    let steps = [
        (Group::Sky, SKY_FIGURE_STEPS),
        (Group::Sensor, sensor::SENSOR_FIGURE_STEPS),
        (Group::Lens, LENS_FIGURE_STEPS),
        (Group::World, world::WORLD_FIGURE_STEPS),
    ]
    .iter()
    .filter(|(g, _)| want(*g))
    .map(|(_, n)| n)
    .sum();
    let mut progress = Progress::new("psns figures", Unit::Steps, Some(steps), false);
    let mut files = Vec::new();
    if want(Group::Sky) {
        files.extend(sky_figures(&a.out, &mut progress)?);
    }
    if want(Group::Sensor) {
        files.extend(sensor::sensor_figures(&a.out, &mut progress)?);
    }
    if want(Group::Lens) {
        files.extend(lens_figures(&a.out, &mut progress)?);
    }
    if want(Group::World) {
        files.extend(world::world_figures(&a.out, &mut progress)?);
    }
    for f in files {
        progress.println(format!("wrote {f}"));
    }
    Ok(())
}

/// Steps of [`lens_figures`].
pub const LENS_FIGURE_STEPS: u64 = 2;

/// The pictures of `docs/camera.md`: the whole sky through a 1.8 mm equidistant fisheye (LI,
/// DOP, AOP; the default scene and camera preset, looking at the zenith, the full sensor's field
/// at 8x8 binning), and the default frame's AOP through the pinhole and the ideal lens with their
/// difference (8x smaller), whose statistics at full size go to `lens_numbers.json`.
pub fn lens_figures(dir: &Path, progress: &mut Progress) -> Result<Vec<String>> {
    use psns::camera::Lens;
    create_dir(dir)?;
    let mut files = Vec::new();
    progress.set_message("lens: fisheye");
    let cfg = fisheye_scene();
    let (sky, cam) = cfg.build()?;
    let ideal = render::render_ideal(&sky, &cam);
    let white = vis::quantile(&ideal.li, 0.999);
    let li = vis::gray_rgb(&vis::gray8(&ideal.li, white));
    let dop = vis::dop_rgb(&ideal.dop, Some(&ideal.valid));
    let aop = vis::aop_rgb(&ideal.aop_deg, Some(&ideal.valid));
    let p = dir.join("fisheye_equidistant_1.8mm.png");
    io::write_png_rgb8(&p, &vis::hstack(&[&li, &dop, &aop], 4))?;
    files.push(p.display().to_string());
    progress.inc(1);

    progress.set_message("lens: pinhole vs ideal");
    let aop_of = |lens: Lens| -> Result<psns::image::Image<f32>> {
        let mut c = figure_scene();
        c.camera.intrinsics.lens = Some(lens);
        let (sky, cam) = c.build()?;
        Ok(render::render_ideal(&sky, &cam).aop_deg)
    };
    let (a, b) = (aop_of(Lens::Pinhole)?, aop_of(Lens::Ideal)?);
    let diff = psns::image::Image::from_vec(
        a.width,
        a.height,
        a.data
            .iter()
            .zip(&b.data)
            .map(|(&x, &y)| {
                let d = (x - y).rem_euclid(180.0);
                d.min(180.0 - d)
            })
            .collect(),
    );
    let mut sorted = diff.data.clone();
    sorted.sort_by(f32::total_cmp);
    let q = |f: f64| sorted[((sorted.len() - 1) as f64 * f).round() as usize] as f64;
    let numbers = serde_json::json!({
        "what": "|AOP ideal - AOP pinhole|, degrees, default scene and camera (2448 x 2048)",
        "median_deg": q(0.5),
        "p99_deg": q(0.99),
        "max_deg": q(1.0),
        "pixel_0_0_deg": diff.data[0],
    });
    let scaled = psns::image::Image::from_vec(
        diff.width,
        diff.height,
        diff.data.iter().map(|&d| d / 15.0).collect(),
    );
    let panels = [
        vis::aop_rgb(&vis::decimate(&a, 8), None),
        vis::aop_rgb(&vis::decimate(&b, 8), None),
        vis::dop_rgb(&vis::decimate(&scaled, 8), None),
    ];
    let p = dir.join("lens_pinhole_ideal_aop.png");
    io::write_png_rgb8(&p, &vis::hstack(&[&panels[0], &panels[1], &panels[2]], 4))?;
    files.push(p.display().to_string());
    let p = dir.join("lens_numbers.json");
    let text = serde_json::to_string_pretty(&numbers).expect("json") + "\n";
    std::fs::write(&p, text).map_err(|e| psns::Error::io(format!("writing {}", p.display()), e))?;
    files.push(p.display().to_string());
    progress.inc(1);
    Ok(files)
}

/// Steps of [`sky_figures`] counted by its progress (one per picture).
pub const SKY_FIGURE_STEPS: u64 = 5;

/// The command of the README's first picture, [`README_FIGURE`]: what it renders is that
/// picture, 8x smaller.
pub const README_COMMAND: [&str; 3] = ["render", "--out", "out"];

/// The README's first picture: LI, DOP and AOP of [`README_COMMAND`] (the default scene, yaw 0:
/// the image's +y axis points north).
pub const README_FIGURE: &str = "readme_render_li_dop_aop.png";

/// The scene `psns render` renders with [`README_COMMAND`]'s options, as it parses them.
pub(crate) fn readme_scene() -> Result<SceneConfig> {
    use clap::{Args, Command, FromArgMatches};
    let words = std::iter::once("psns").chain(README_COMMAND.iter().skip(1).copied());
    let cmd = psns::options::RenderArgs::augment_args(Command::new("render"));
    let m = cmd
        .try_get_matches_from(words)
        .map_err(|e| psns::Error::Invalid(e.to_string()))?;
    let a = psns::options::RenderArgs::from_arg_matches(&m)
        .map_err(|e| psns::Error::Invalid(e.to_string()))?;
    Ok(a.config()?.0)
}

/// LI, DOP and AOP of a scene's ideal images side by side, 8x smaller.
fn li_dop_aop(cfg: &SceneConfig) -> Result<psns::image::Image<[u8; 3]>> {
    let (sky, cam) = cfg.build()?;
    let ideal = render::render_ideal(&sky, &cam);
    let li = vis::downsample(&ideal.li, 8);
    let white = vis::quantile(&li, 0.999);
    let li = vis::gray_rgb(&vis::gray8(&li, white));
    let dop = vis::dop_rgb(&vis::decimate(&ideal.dop, 8), None);
    let aop = vis::aop_rgb(&vis::decimate(&ideal.aop_deg, 8), None);
    Ok(vis::hstack(&[&li, &dop, &aop], 4))
}

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
    // the default camera frame facing the sun's azimuth, 8x smaller
    let p = dir.join("default_camera_li_dop_aop.png");
    io::write_png_rgb8(&p, &li_dop_aop(&figure_scene())?)?;
    files.push(p.display().to_string());
    progress.inc(1);
    progress.set_message("sky: the README's render");
    let p = dir.join(README_FIGURE);
    io::write_png_rgb8(&p, &li_dop_aop(&readme_scene()?)?)?;
    files.push(p.display().to_string());
    progress.inc(1);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use psns::camera::{Attitude, AttitudeFrame};

    #[test]
    fn readme_picture_is_the_default_render_at_yaw_0() {
        let c = readme_scene().unwrap();
        assert_eq!(
            c.camera.attitude,
            Attitude::Euler {
                frame: AttitudeFrame::Enu,
                yaw_deg: 0.0,
                pitch_deg: 0.0,
                roll_deg: 0.0
            }
        );
        let mut d = SceneConfig::default();
        d.camera.intrinsics = d.intrinsics();
        assert_eq!(c.camera, d.camera);
        assert_eq!(c.sun, d.sun);
        assert_ne!(c.camera, figure_scene().camera);
    }
}
