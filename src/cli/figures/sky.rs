//! Figures for `docs/`: all-sky maps (LI, DOP, AOP) for sweeps of the sun position, in the spirit
//! of the PSNS paper's Figs. 5–9, and small views of the default camera frame.
//!
//! All-sky maps use the stereographic chart of `sky.md` §1 drawn as a map seen from above: north up,
//! east right, zenith at the centre, the horizon on the circle. The AOP panel shows the chart AOP χ
//! (angle of the E-vector from north toward east) as a cyclic hue.

use crate::cli::vis;
use psns::angle::direction;
use psns::image::Image;
use psns::sky::{aop_chart_deg, Sky, SkyParams};
use psns::sun::SunPosition;
use rayon::prelude::*;

/// LI (grey, scaled to its 99.5th percentile), DOP (viridis 0..1) and AOP χ (hue) all-sky maps of
/// `size` × `size` pixels, side by side.
pub fn sky_dome_panels(sky: &Sky, size: usize) -> Image<[u8; 3]> {
    let n = size as f64;
    let px: Vec<(f32, f32, f32, u8)> = (0..size * size)
        .into_par_iter()
        .map(|i| {
            let (r, c) = (i / size, i % size);
            let x = (c as f64 + 0.5) / n * 2.0 - 1.0; // east
            let y = 1.0 - (r as f64 + 0.5) / n * 2.0; // north
            let rho = x.hypot(y);
            if rho >= 1.0 {
                return (0.0, 0.0, 0.0, 0);
            }
            let theta = 2.0 * rho.atan();
            let a = x.atan2(y);
            let v = direction(theta.to_degrees(), a.to_degrees());
            let s = sky.sample(v);
            if !s.valid {
                return (0.0, 0.0, 0.0, 0);
            }
            let chi = if s.dop > 0.0 {
                aop_chart_deg(v, s.e)
            } else {
                0.0
            };
            (s.radiance as f32, s.dop as f32, chi as f32, 1)
        })
        .collect();
    let img = |k: usize| {
        Image::from_vec(
            size,
            size,
            px.iter()
                .map(|p| match k {
                    0 => p.0,
                    1 => p.1,
                    _ => p.2,
                })
                .collect(),
        )
    };
    let mask = Image::from_vec(size, size, px.iter().map(|p| p.3).collect());
    // AOP is undefined where DOP = 0 (neutral points, clamped regions): black
    let pol_mask = Image::from_vec(
        size,
        size,
        px.iter().map(|p| (p.3 != 0 && p.1 > 0.0) as u8).collect(),
    );
    let li = img(0);
    let white = vis::quantile(&li, 0.995);
    let li_rgb = vis::gray_rgb(&vis::gray8(&li, white));
    let dop_rgb = vis::dop_rgb(&img(1), Some(&mask));
    let aop_rgb = vis::aop_rgb(&img(2), Some(&pol_mask));
    vis::hstack(&[&li_rgb, &dop_rgb, &aop_rgb], 4)
}

/// Rows of all-sky panels, one row per sun position.
pub fn sky_sweep(
    params: &SkyParams,
    suns: &[SunPosition],
    size: usize,
) -> psns::Result<Image<[u8; 3]>> {
    let rows: Vec<Image<[u8; 3]>> = suns
        .iter()
        .map(|&s| Ok(sky_dome_panels(&Sky::new(s, params)?, size)))
        .collect::<psns::Result<_>>()?;
    let refs: Vec<&Image<[u8; 3]>> = rows.iter().collect();
    Ok(vis::vstack(&refs, 4))
}
