//! Named test scenes for the demosaic benchmark (`psns bench demosaic`), each built from the
//! real sky renderer and the IMX250MZR emulator through [`RawPipeline`], all seeded.
//!
//! | name | what | stresses |
//! |---|---|---|
//! | `clear-sky` | default sky (sun zenith 50°, azimuth 200°), zenith view, camera preset | baseline |
//! | `occluder-edge` | clear sky plus a dark unpolarized tree-line and buildings along the bottom, 1-px wires and a 3-px mast | IFOV error at edges (spec `demosaic.md` §3) |
//! | `sun-in-view` | camera pitched so the sun sits 20° from the optical axis; exposure set on the 90th percentile so the disc and circumsolar sky clip | saturation |
//! | `clouds` | clear sky plus soft unpolarized clouds ([`apply_soft_clouds`](psns::sky::clouds::apply_soft_clouds)) | DoLP → 0 patches, soft edges |
//! | `low-light` | clear sky with the exposure set so the median sky pixel collects 300 e⁻ | shot noise (§4) |
//! | `turbid` | turbidity 10 (hazy, low DoLP) | weak polarization |
//!
//! The occluders are drawn into the sensor-frame Stokes radiance at each pixel's own position
//! (S0 small, S1 = S2 = 0 inside), so the emulator's ground truth ([`RawFrame::truth`]) contains
//! them exactly and every demosaic error at the edges is the method's own. Every sky scene except
//! `low-light` uses auto-exposure (99th percentile at 70 % of full well, `sensor.md` §5).
//! Geometry is given as fractions of the frame, so a small `--quick` frame (same horizontal field
//! of view, shorter focal length) shows the same scene.

use psns::camera::{Attitude, Intrinsics};
use psns::config::SceneConfig;
use psns::error::{Error, Result};
use psns::image::StokesImage;
use psns::pipeline::{FrameRequest, RawPipeline, SceneInfo};
use psns::sensor::{Exposure, RawFrame, SensorConfig};
use psns::sky::clouds::SoftClouds;
use std::fmt;
use std::str::FromStr;

/// A named benchmark scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scene {
    /// Default clear sky, zenith view.
    ClearSky,
    /// Clear sky with a dark tree-line/building silhouette, 1-px wires and a mast.
    OccluderEdge,
    /// Sun 20° off the optical axis, saturated disc and circumsolar region.
    SunInView,
    /// Soft unpolarized clouds.
    Clouds,
    /// Median sky pixel at about 300 e⁻.
    LowLight,
    /// Turbidity 10, low DoLP.
    Turbid,
}

/// Full IMX250MZR frame width.
pub const FULL_WIDTH: usize = 2448;
/// Full IMX250MZR frame height.
pub const FULL_HEIGHT: usize = 2048;
/// Median electrons per pixel of the `low-light` scene.
pub const LOW_LIGHT_ELECTRONS: f64 = 300.0;

impl Scene {
    /// Every scene, in table order.
    pub const ALL: [Scene; 6] = [
        Scene::ClearSky,
        Scene::OccluderEdge,
        Scene::SunInView,
        Scene::Clouds,
        Scene::LowLight,
        Scene::Turbid,
    ];

    /// The scene's name as parsed by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            Scene::ClearSky => "clear-sky",
            Scene::OccluderEdge => "occluder-edge",
            Scene::SunInView => "sun-in-view",
            Scene::Clouds => "clouds",
            Scene::LowLight => "low-light",
            Scene::Turbid => "turbid",
        }
    }
}

impl fmt::Display for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Scene {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim().to_ascii_lowercase();
        Scene::ALL
            .iter()
            .copied()
            .find(|m| m.name() == t)
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "unknown scene '{s}' (allowed: {})",
                    Scene::ALL.map(Scene::name).join(", ")
                ))
            })
    }
}

/// One rendered scene: its configuration (with the sensor in force), the raw frame with ground
/// truth, and what the renderer reported.
#[derive(Clone, Debug)]
#[allow(dead_code)] // a complete record of the render; the benchmark reads only some fields
pub struct SceneFrame {
    /// Which scene.
    pub scene: Scene,
    /// Full configuration; `raw.sensor` holds the sensor actually used.
    pub config: SceneConfig,
    /// Raw codes and ground truth.
    pub frame: RawFrame,
    /// Sun, sun-disc and ground pixel counts.
    pub info: SceneInfo,
}

/// Intrinsics of a `width` x `height` frame with the horizontal field of view of the full
/// 2448-column IMX250MZR frame behind the default 4 mm lens.
pub fn intrinsics(width: usize, height: usize) -> Intrinsics {
    let d = Intrinsics::default();
    Intrinsics {
        width,
        height,
        focal_length_mm: d.focal_length_mm * width as f64 / FULL_WIDTH as f64,
        ..d
    }
}

/// The scene's configuration (before any exposure adjustment) at the given size and bit depth.
pub fn config(scene: Scene, width: usize, height: usize, bit_depth: u8) -> SceneConfig {
    let mut cfg = SceneConfig::default();
    cfg.camera.intrinsics = intrinsics(width, height);
    let mut sensor = SensorConfig {
        bit_depth,
        exposure: Exposure::auto(),
        ..SensorConfig::default()
    };
    cfg.raw.seed = 1 + Scene::ALL.iter().position(|&s| s == scene).unwrap_or(0) as u64;
    match scene {
        Scene::ClearSky | Scene::OccluderEdge | Scene::LowLight => {}
        Scene::SunInView => {
            let sun = psns::config::DEFAULT_SUN;
            cfg.camera.attitude = Attitude::enu(sun.azimuth_deg, -(sun.zenith_deg - 20.0), 0.0);
            // expose for the 90th percentile: the disc and the circumsolar sky clip
            sensor.exposure = Exposure::Auto {
                percentile: 90.0,
                fraction: 0.9,
            };
        }
        Scene::Clouds => cfg.raw.soft_clouds = Some(SoftClouds::default()),
        Scene::Turbid => cfg.sky.turbidity = 10.0,
    }
    cfg.raw.sensor = Some(sensor);
    cfg
}

/// Renders `scene` at `width` x `height` (multiples of 4) and `bit_depth` (8, 10 or 12).
pub fn render(scene: Scene, width: usize, height: usize, bit_depth: u8) -> Result<SceneFrame> {
    let mut cfg = config(scene, width, height, bit_depth);
    let sun = cfg.sun.resolve()?;
    let mut pipe = RawPipeline::new(&cfg)?;
    let (mut st, info) = pipe.stokes(sun, &cfg.camera.attitude)?;
    if scene == Scene::OccluderEdge {
        draw_occluders(&mut st);
    }
    if scene == Scene::LowLight {
        // fixed exposure putting the median sky pixel at LOW_LIGHT_ELECTRONS
        let rate = pipe.sensor().electron_rate(&st)?;
        let mut sky: Vec<f64> = rate
            .iter()
            .zip(&st.s0.data)
            .filter(|(_, &s0)| s0 > 0.0)
            .map(|(&r, _)| r)
            .collect();
        if sky.is_empty() {
            return Err(Error::Invalid("low-light scene has no sky pixels".into()));
        }
        let mid = sky.len() / 2;
        let median = *sky.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        let us = (1e6 * LOW_LIGHT_ELECTRONS / median)
            .clamp(psns::sensor::MIN_EXPOSURE_US, psns::sensor::MAX_EXPOSURE_US);
        let mut s = pipe.sensor_config().clone();
        s.exposure = Exposure::Fixed { us };
        cfg.raw.sensor = Some(s);
        pipe = RawPipeline::new(&cfg)?;
    }
    let frame = pipe
        .render(
            FrameRequest::planes(cfg.raw.frame_index, &st)
                .exact()
                .with_truth(),
        )?
        .frame;
    cfg.raw.sensor = Some(pipe.sensor_config().clone());
    Ok(SceneFrame {
        scene,
        config: cfg,
        frame,
        info,
    })
}

/// Draws the `occluder-edge` silhouette into a sensor-frame Stokes radiance: a tree-line with
/// two flat-roofed buildings along the bottom (S0 = 3 % of the median sky), two 1-pixel wires
/// (a straight one and a sagging one) and a 3-pixel mast (S0 = 10 %), all unpolarized.
pub fn draw_occluders(st: &mut StokesImage) {
    let (w, h) = (st.width(), st.height());
    let mut sky: Vec<f32> = st.s0.data.iter().copied().filter(|&v| v > 0.0).collect();
    let median = if sky.is_empty() {
        1.0
    } else {
        let mid = sky.len() / 2;
        *sky.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
    };
    let (wf, hf) = (w as f64, h as f64);
    let mast_c = (0.62 * wf) as usize;
    let mast_top = (0.22 * hf) as usize;
    for r in 0..h {
        for c in 0..w {
            let (x, y) = (c as f64 / wf, r as f64);
            // tree-line: wavy crowns; buildings: flat roofs standing above it
            let trees = hf * (0.80 + 0.025 * (x * 47.0).sin() + 0.015 * (x * 131.0).sin());
            let building = if (0.18..0.30).contains(&x) {
                hf * 0.66
            } else if (0.71..0.79).contains(&x) {
                hf * 0.70
            } else {
                hf
            };
            let top = trees.min(building);
            let wire1 = (0.30 * hf).round();
            let wire2 = (hf * (0.14 + 0.35 * (x - 0.5) * (x - 0.5))).round();
            let k = r * w + c;
            let (v, occluded) = if y >= top {
                (0.03 * median, true)
            } else if y == wire1 || y == wire2 || (c.abs_diff(mast_c) <= 1 && r >= mast_top) {
                (0.10 * median, true)
            } else {
                (0.0, false)
            };
            if occluded {
                st.s0.data[k] = v;
                st.s1.data[k] = 0.0;
                st.s2.data[k] = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for s in Scene::ALL {
            assert_eq!(s.name().parse::<Scene>().unwrap(), s);
        }
        assert!("fog".parse::<Scene>().is_err());
    }

    #[test]
    fn occluders_are_dark_and_unpolarized() {
        let mut st = StokesImage::zeros(64, 48);
        st.s0.data.iter_mut().for_each(|v| *v = 100.0);
        st.s1.data.iter_mut().for_each(|v| *v = 30.0);
        draw_occluders(&mut st);
        let bottom = 47 * 64 + 10;
        assert_eq!((st.s0.data[bottom], st.s1.data[bottom]), (3.0, 0.0));
        let wire = (0.30f64 * 48.0).round() as usize * 64 + 5;
        assert_eq!((st.s0.data[wire], st.s1.data[wire]), (10.0, 0.0));
        assert_eq!(st.s1.data[4 * 64 + 5], 30.0); // open sky untouched
    }

    #[test]
    fn low_light_median_near_target() {
        let sf = render(Scene::LowLight, 128, 96, 12).unwrap();
        let f = &sf.frame;
        let mut e: Vec<f64> = f
            .codes
            .data
            .iter()
            .map(|&c| (c as f64 - f.black_level_dn) / f.dn_per_electron)
            .collect();
        let mid = e.len() / 2;
        let m = *e.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        assert!((200.0..450.0).contains(&m), "median {m} e-");
    }
}
