//! The world around the camera: what cuts the sky (a skyline, buildings, a street canyon,
//! trees, a camera-fixed mask) and clouds fixed in the sky, in ENU metres with the observer's
//! feet at the origin and the camera `camera_height_m` above them (`docs/world.md`).
//!
//! [`WorldConfig`] is the description (the scene file's `[world]` table and the command-line
//! options); [`World`] is it prepared: [`World::trace`] says what a ray from the camera meets
//! first, exactly (ray against box, wall, ellipsoid and cylinder; the skyline interpolated
//! linearly in azimuth), and [`World::clear`] whether every ray within an angle of it meets the
//! same thing, which lets the fast path interpolate away from edges. The light those surfaces
//! send back (diffuse, glass, foliage) is [`optics`]; the sky's part of it is the renderer's.

use crate::error::{check_range, Error, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};

pub mod clouds;
mod index;
pub mod optics;
mod shapes;
pub mod skyline;
#[cfg(test)]
mod tests;

pub use clouds::{Cloud, CloudField, Wind};
pub use shapes::{Building, Canyon, Surface, Tree, FOLIAGE_ALBEDO, GAP_CELL_M};
pub use skyline::Skyline;

/// Allowed ranges (inclusive) of the world's numbers, as the options, scene files and dataset
/// descriptions take them.
pub mod limits {
    /// Camera height above the ground, metres.
    pub const CAMERA_HEIGHT_M: (f64, f64) = (0.0, 10_000.0);
    /// Fraction of the sky covered by seeded clouds.
    pub const CLOUD_COVER: (f64, f64) = (0.0, 1.0);
    /// Street width of a canyon, metres.
    pub const CANYON_WIDTH_M: (f64, f64) = (0.01, 1e5);
    /// Wall height of a canyon, metres.
    pub const CANYON_HEIGHT_M: (f64, f64) = (0.0, 1e4);
    /// Compass azimuths (a canyon's axis, the wind's direction), degrees.
    pub const AZIMUTH_DEG: (f64, f64) = (-360.0, 720.0);
    /// The clouds' angular speed, degrees per second.
    pub const WIND_SPEED_DEG_S: (f64, f64) = (-10.0, 10.0);
    /// Height of a tree's canopy centre above the ground, metres.
    pub const CANOPY_HEIGHT_M: (f64, f64) = (0.0, 1e3);
    /// Semi-axes of a tree's canopy, metres.
    pub const CANOPY_RADIUS_M: (f64, f64) = (0.01, 1e3);
    /// Fraction of a canopy that lets the sky through.
    pub const GAP_FRACTION: (f64, f64) = (0.0, 1.0);
}

/// Albedo of a diffuse surface that sets none (weathered concrete and brick, 0.2-0.4).
pub const DEFAULT_ALBEDO: f64 = 0.3;
/// Refractive index of facade glass that sets none (soda-lime glass).
pub const DEFAULT_GLASS_INDEX: f64 = 1.52;

/// The world as a scene file or the options describe it (all empty: the open sky of the
/// sky models, meeting a flat ground at the horizon).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorldConfig {
    /// Height of the camera above the ground, metres (0: at ground level).
    #[serde(skip_serializing_if = "is_zero")]
    pub camera_height_m: f64,
    /// The far skyline: (compass azimuth, elevation) in degrees, azimuths increasing in
    /// [0, 360), interpolated linearly and wrapping round.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub skyline: Vec<[f64; 2]>,
    /// A street canyon: two infinitely long walls either side of the observer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub canyon: Option<Canyon>,
    /// Buildings (boxes on the ground).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub buildings: Vec<Building>,
    /// Trees.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub trees: Vec<Tree>,
    /// Clouds given one by one.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub clouds: Vec<Cloud>,
    /// Fraction of the sky covered by seeded clouds (0..1), drawn from `seed`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cloud_cover: Option<f64>,
    /// The clouds' drift over a stream's scene time.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wind: Option<Wind>,
    /// Seed of the seeded clouds and of the trees' gaps (a scene takes the camera's seed
    /// unless this is set).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// A PNG the size of the image, fixed to the camera: black (0) pixels are blocked (a mast,
    /// a lens hood), any other value lets the world through.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_mask: Option<std::path::PathBuf>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl WorldConfig {
    /// Whether nothing is set: the plain sky.
    pub fn is_empty(&self) -> bool {
        *self == WorldConfig::default()
    }

    /// Checks every value (finite, in range, nothing around the observer).
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = limits::CAMERA_HEIGHT_M;
        check_range("camera-height", self.camera_height_m, lo, hi)?;
        if !self.skyline.is_empty() {
            Skyline::new(&self.skyline)?;
        }
        if let Some(c) = &self.canyon {
            c.validate(self.camera_height_m)?;
        }
        for (k, b) in self.buildings.iter().enumerate() {
            b.validate(k)?;
        }
        for (k, t) in self.trees.iter().enumerate() {
            t.validate(k, self.camera_height_m)?;
        }
        for (k, c) in self.clouds.iter().enumerate() {
            c.validate(k)?;
        }
        if let Some(f) = self.cloud_cover {
            let (lo, hi) = limits::CLOUD_COVER;
            check_range("cloud-cover", f, lo, hi)?;
        }
        if let Some(w) = &self.wind {
            w.validate()?;
        }
        Ok(())
    }
}

/// What a ray from the camera meets first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hit {
    /// Nothing: the sky (through the clouds).
    Sky,
    /// The flat ground.
    Ground,
    /// A diffuse (Lambertian, unpolarized) surface with this outward normal and albedo.
    Diffuse {
        /// Outward unit normal (ENU).
        normal: DVec3,
        /// Albedo, 0..1.
        albedo: f64,
    },
    /// Glass: a specular reflector with this outward normal and refractive index.
    Glass {
        /// Outward unit normal (ENU).
        normal: DVec3,
        /// Refractive index.
        index: f64,
    },
    /// A tree's foliage.
    Foliage,
}

impl Hit {
    /// Whether the ray meets something that hides the sky above the ground (class 3).
    pub fn is_obstruction(&self) -> bool {
        matches!(self, Hit::Diffuse { .. } | Hit::Glass { .. } | Hit::Foliage)
    }
}

/// Per-pixel classes of the class image (`class.npy`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Class {
    /// Outside a fisheye's image circle.
    Outside = 0,
    /// Clear sky.
    Sky = 1,
    /// A cloud of opacity 0.5 or more.
    Cloud = 2,
    /// Something that hides the sky: a building, a wall, a tree, the skyline, the camera mask.
    Obstruction = 3,
    /// The ground.
    Ground = 4,
    /// The sun's disc.
    Sun = 5,
}

impl Class {
    /// Every class, in the order of their codes.
    pub const ALL: [Class; 6] = [
        Class::Outside,
        Class::Sky,
        Class::Cloud,
        Class::Obstruction,
        Class::Ground,
        Class::Sun,
    ];
    /// The name in the per-frame metadata and labels.
    pub fn name(self) -> &'static str {
        match self {
            Class::Outside => "outside",
            Class::Sky => "sky",
            Class::Cloud => "cloud",
            Class::Obstruction => "obstruction",
            Class::Ground => "ground",
            Class::Sun => "sun",
        }
    }
}

/// A world ready to trace rays, its clouds placed at one scene time.
#[derive(Clone, Debug)]
pub struct World {
    eye: DVec3,
    skyline: Option<Skyline>,
    canyon: Option<Canyon>,
    buildings: Vec<shapes::PreparedBox>,
    trees: Vec<Tree>,
    clouds: CloudField,
    /// The clouds at scene time 0 and their wind.
    cloud_list: Vec<Cloud>,
    wind: Option<Wind>,
    seed: u64,
    /// The camera-fixed mask: width, height and one byte per pixel (0 blocked).
    mask: Option<(usize, usize, std::sync::Arc<Vec<u8>>)>,
    /// The edges of everything solid, as arcs on the unit sphere seen from the eye: the whole
    /// great circles, tested always, and the arcs, by the index of their bounding caps.
    circles: Vec<shapes::Arc>,
    edges: Vec<shapes::Arc>,
    edge_index: index::SphereIndex,
    /// Bounding cones (axis, angular radius) of the trees, whose foliage has no edge to test.
    cones: Vec<(DVec3, f64)>,
}

impl World {
    /// Prepares `cfg` (validated here) with `seed` (the camera's, unless the world sets one),
    /// its clouds where they are `t_s` seconds into the scene. `mask` is the camera mask's
    /// pixels when the description names one (the caller reads the file).
    pub fn new(
        cfg: &WorldConfig,
        seed: u64,
        t_s: f64,
        mask: Option<(usize, usize, Vec<u8>)>,
    ) -> Result<World> {
        let mask = mask.map(|(w, h, m)| (w, h, std::sync::Arc::new(m)));
        cfg.validate()?;
        if !t_s.is_finite() {
            return Err(Error::Invalid(format!(
                "scene time {} s is not finite",
                crate::error::num(t_s)
            )));
        }
        let seed = cfg.seed.unwrap_or(seed);
        let eye = DVec3::new(0.0, 0.0, cfg.camera_height_m);
        let skyline = if cfg.skyline.is_empty() {
            None
        } else {
            Some(Skyline::new(&cfg.skyline)?)
        };
        let buildings: Vec<shapes::PreparedBox> =
            cfg.buildings.iter().map(shapes::PreparedBox::new).collect();
        let mut edges = Vec::new();
        if let Some(c) = &cfg.canyon {
            c.edges(eye, &mut edges);
        }
        for b in &buildings {
            b.edges(eye, &mut edges);
        }
        if let Some(s) = &skyline {
            s.edges(&mut edges);
        }
        let (circles, edges): (Vec<shapes::Arc>, Vec<shapes::Arc>) =
            edges.into_iter().partition(|a| a.is_whole());
        let caps: Vec<(DVec3, f64)> = edges.iter().map(|a| a.cap()).collect();
        let edge_index = index::SphereIndex::new(&caps);
        let mut cones = Vec::new();
        for t in &cfg.trees {
            t.cones(eye, &mut cones);
        }
        let mut clouds = cfg.clouds.clone();
        if let Some(f) = cfg.cloud_cover {
            clouds.extend(clouds::draw_cover(f, seed));
        }
        let cloud_list = clouds;
        let clouds = CloudField::new(&cloud_list, cfg.wind, t_s);
        Ok(World {
            eye,
            skyline,
            canyon: cfg.canyon,
            buildings,
            trees: cfg.trees.clone(),
            clouds,
            cloud_list,
            wind: cfg.wind,
            seed,
            mask,
            circles,
            edges,
            edge_index,
            cones,
        })
    }

    /// This world with its clouds `t_s` seconds into the scene.
    pub fn at(&self, t_s: f64) -> World {
        let mut w = self.clone();
        w.clouds = CloudField::new(&self.cloud_list, self.wind, t_s);
        w
    }

    /// Whether the clouds move with scene time.
    pub fn drifts(&self) -> bool {
        self.wind.is_some_and(|w| w.speed_deg_s != 0.0) && !self.cloud_list.is_empty()
    }

    /// The clouds, placed.
    pub fn clouds(&self) -> &CloudField {
        &self.clouds
    }

    /// What the unit ENU ray `d` from the camera meets first.
    pub fn trace(&self, d: DVec3) -> Hit {
        let mut best = f64::INFINITY;
        let mut hit = Hit::Sky;
        if d.z < 0.0 {
            best = self.eye.z / -d.z;
            hit = Hit::Ground;
        }
        if let Some(c) = &self.canyon {
            if let Some((t, h)) = c.hit(self.eye, d) {
                if t < best {
                    (best, hit) = (t, h);
                }
            }
        }
        for b in &self.buildings {
            if let Some((t, h)) = b.hit(self.eye, d) {
                if t < best {
                    (best, hit) = (t, h);
                }
            }
        }
        for (k, tr) in self.trees.iter().enumerate() {
            if let Some((t, h)) = tr.hit(self.eye, d, self.seed, k as u64) {
                if t < best {
                    (best, hit) = (t, h);
                }
            }
        }
        if hit == Hit::Sky {
            if let Some(s) = &self.skyline {
                if let Some(h) = s.hit(d) {
                    hit = h;
                }
            }
        }
        hit
    }

    /// Whether every ray within `margin` radians of the unit ray `d` meets the same surface
    /// as `d` (no edge of a building, wall or skyline within the margin, no tree's foliage, no
    /// cloud's rim), judged conservatively. Clouds are included when `clouds`.
    pub fn clear(&self, d: DVec3, margin: f64, clouds: bool) -> bool {
        if self.circles.iter().any(|a| a.distance(d) <= margin) {
            return false;
        }
        let near = |a: &shapes::Arc| a.distance(d) <= margin;
        let edge_near = if margin > index::MARGIN_RAD {
            self.edges.iter().any(near)
        } else {
            self.edge_index
                .near(d)
                .iter()
                .any(|&k| near(&self.edges[k as usize]))
        };
        if edge_near {
            return false;
        }
        if self
            .cones
            .iter()
            .any(|&(axis, r)| d.dot(axis).clamp(-1.0, 1.0).acos() <= r + margin)
        {
            return false;
        }
        !clouds || self.clouds.clear(d, margin)
    }

    /// Whether the camera mask lets pixel (col, row) see the world (no mask: every pixel).
    #[inline]
    pub fn open(&self, col: usize, row: usize) -> bool {
        match &self.mask {
            None => true,
            Some((w, _, m)) => m[row * w + col] != 0,
        }
    }

    /// Row `row` of the camera mask (0: blocked), when there is one.
    pub fn mask_row(&self, row: usize) -> Option<&[u8]> {
        self.mask
            .as_ref()
            .map(|(w, _, m)| &m[row * w..(row + 1) * w])
    }

    /// The camera mask's size, when there is one.
    pub fn mask_size(&self) -> Option<(usize, usize)> {
        self.mask.as_ref().map(|(w, h, _)| (*w, *h))
    }

    /// Whether the world hides part of the sky or adds clouds (the plain sky otherwise).
    pub fn is_empty(&self) -> bool {
        self.skyline.is_none()
            && self.canyon.is_none()
            && self.buildings.is_empty()
            && self.trees.is_empty()
            && self.clouds.is_empty()
            && self.mask.is_none()
    }
}
