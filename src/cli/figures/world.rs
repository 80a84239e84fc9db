//! The pictures of `docs/world.md`: a zenith-looking equidistant fisheye in a street canyon,
//! under a tree, and under clouds drifting with a wind, each as intensity, DoLP, AoLP and the
//! class image.

use super::super::progress::Progress;
use super::super::vis;
use psns::config::SceneConfig;
use psns::image::Image;
use psns::io::create_dir;
use psns::world::{Cloud, Tree, Wind};
use psns::{io, render, Result};
use std::path::Path;

/// Steps of [`world_figures`].
pub const WORLD_FIGURE_STEPS: u64 = 3;

/// Colours of the classes (outside, sky, cloud, obstruction, ground, sun).
const PALETTE: [[u8; 3]; 6] = [
    [0, 0, 0],
    [90, 150, 255],
    [230, 230, 230],
    [150, 95, 60],
    [70, 120, 45],
    [255, 220, 0],
];

/// One row of panels: LI, DoLP, AoLP, class.
fn panels(cfg: &SceneConfig, t_s: f64) -> Result<Image<[u8; 3]>> {
    let (sky, cam) = cfg.build_at(t_s)?;
    let ideal = render::render_ideal(&sky, &cam);
    let white = vis::quantile(&ideal.li, 0.999);
    let li = vis::gray_rgb(&vis::gray8(&ideal.li, white));
    let dop = vis::dop_rgb(&ideal.dop, Some(&ideal.valid));
    let aop = vis::aop_rgb(&ideal.aop_deg, Some(&ideal.valid));
    let class = render::class_image(&sky, &cam, cfg.raw.sun_disc_on());
    let class = Image::from_vec(
        class.width,
        class.height,
        class.data.iter().map(|&k| PALETTE[k as usize]).collect(),
    );
    Ok(vis::hstack(&[&li, &dop, &aop, &class], 4))
}

/// Writes `world_canyon.png`, `world_tree.png` and `world_clouds.png` (the clouds at 0 and
/// 60 s of scene time, one row each) into `dir`.
pub fn world_figures(dir: &Path, progress: &mut Progress) -> Result<Vec<String>> {
    create_dir(dir)?;
    let mut files = Vec::new();
    let mut write = |name: &str, img: &Image<[u8; 3]>, progress: &mut Progress| -> Result<()> {
        let p = dir.join(name);
        io::write_png_rgb8(&p, img)?;
        files.push(p.display().to_string());
        progress.inc(1);
        Ok(())
    };
    progress.set_message("world: canyon");
    let mut cfg = super::fisheye_scene();
    cfg.world.canyon = Some(psns::world::Canyon::new(20.0, 6.0, 0.0));
    write("world_canyon.png", &panels(&cfg, 0.0)?, progress)?;

    progress.set_message("world: tree");
    let mut cfg = super::fisheye_scene();
    cfg.world.camera_height_m = 1.5;
    cfg.world.trees = vec![Tree {
        east_m: 4.0,
        north_m: 3.0,
        canopy_height_m: 7.0,
        radii_m: [4.0, 4.0, 3.0],
        trunk_radius_m: 0.3,
        gap_fraction: 0.25,
    }];
    write("world_tree.png", &panels(&cfg, 0.0)?, progress)?;

    progress.set_message("world: clouds");
    let mut cfg = super::fisheye_scene();
    cfg.world.clouds = vec![
        Cloud {
            azimuth_deg: 300.0,
            elevation_deg: 55.0,
            radius_deg: 14.0,
            opacity: 1.0,
            softness: 0.2,
        },
        Cloud {
            azimuth_deg: 60.0,
            elevation_deg: 70.0,
            radius_deg: 9.0,
            opacity: 0.35,
            softness: 0.3,
        },
    ];
    cfg.world.wind = Some(Wind {
        speed_deg_s: 0.5,
        azimuth_deg: 90.0,
    });
    let a = panels(&cfg, 0.0)?;
    let b = panels(&cfg, 60.0)?;
    write("world_clouds.png", &vis::vstack(&[&a, &b], 4), progress)?;
    Ok(files)
}
