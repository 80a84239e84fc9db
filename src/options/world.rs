//! Options of the world around the camera (`psns render`, `stream`, `gige` and Python): they
//! set the scene's `[world]` table (`docs/world.md`), which a scene file can also give in full
//! (buildings, trees, clouds one by one).

use super::{finite, finite_list};
use crate::config::SceneConfig;
use crate::world::{Canyon, Skyline, Wind};
use crate::{Error, Result};
use clap::Args;
use std::path::PathBuf;

/// What cuts the sky, and the clouds in it.
#[derive(Args, Clone, Debug, Default)]
pub struct WorldArgs {
    /// Skyline: CSV with the header azimuth_deg,elevation_deg (compass azimuths increasing in
    /// 0..360, interpolated linearly, the last point joining the first); rays below it see
    /// the terrain.
    #[arg(long, value_name = "FILE.csv")]
    pub skyline: Option<PathBuf>,
    /// Street canyon: two infinitely long walls WIDTH_M apart and HEIGHT_M tall, the street's
    /// axis along compass AZIMUTH_DEG, the camera on its centre line.
    #[arg(long, value_parser = finite_list::<3>, allow_negative_numbers = true, value_name = "WIDTH_M,HEIGHT_M,AZIMUTH_DEG")]
    pub canyon: Option<[f64; 3]>,
    /// Height of the camera above the ground, metres (default 0).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "M")]
    pub camera_height: Option<f64>,
    /// Camera-fixed mask: a greyscale PNG of the image's size whose black (0) pixels are
    /// blocked (a mast, a lens hood).
    #[arg(long, value_name = "PNG")]
    pub mask: Option<PathBuf>,
    /// Seeded clouds covering this fraction of the sky (0..1), drawn from --seed.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "F")]
    pub cloud_cover: Option<f64>,
    /// Clouds drift at DEG_PER_S toward compass AZIMUTH_DEG over a stream's scene time.
    #[arg(long, value_parser = finite_list::<2>, allow_negative_numbers = true, value_name = "DEG_PER_S,AZIMUTH_DEG")]
    pub wind: Option<[f64; 2]>,
}

impl WorldArgs {
    /// Applies the given options to the scene's world and checks it.
    pub fn apply(&self, c: &mut SceneConfig) -> Result<()> {
        let w = &mut c.world;
        if let Some(p) = &self.skyline {
            let text = std::fs::read_to_string(p).map_err(|e| Error::input(p, e))?;
            w.skyline = Skyline::parse_csv(&text)
                .map_err(|e| Error::Invalid(format!("{}: {e}", p.display())))?;
        }
        if let Some([width, height, az]) = self.canyon {
            w.canyon = Some(Canyon::new(width, height, az));
        }
        if let Some(h) = self.camera_height {
            w.camera_height_m = h;
        }
        if let Some(m) = &self.mask {
            w.camera_mask = Some(m.clone());
        }
        if let Some(f) = self.cloud_cover {
            w.cloud_cover = Some(f);
        }
        if let Some([speed, az]) = self.wind {
            w.wind = Some(Wind {
                speed_deg_s: speed,
                azimuth_deg: az,
            });
        }
        w.validate()
    }

    /// Whether the world these options and `c` describe draws anything from the seed.
    pub fn seeded(c: &SceneConfig) -> bool {
        c.world.cloud_cover.is_some() || !c.world.trees.is_empty()
    }
}
