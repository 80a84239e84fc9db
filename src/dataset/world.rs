//! The world around each sample's camera (`docs/dataset.md`, "The world"): distributions of a
//! street canyon, the camera's height, seeded clouds, their wind and trees standing around the
//! observer, drawn per sample into the library's [`WorldConfig`] (checked by its own
//! validation); the world presets `urban` and `canopy`; the world's label columns.

use super::*;
use crate::world::{limits, Canyon, Tree, Wind, WorldConfig};

/// A set of defaults for the world keys, named by the description's `world` key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WorldPreset {
    /// Street canyons of varied width, height and direction, and some clouds.
    Urban,
    /// Trees standing around the observer, their canopies overhead, and some clouds.
    Canopy,
}

impl WorldPreset {
    /// Every preset.
    pub const ALL: [WorldPreset; 2] = [WorldPreset::Urban, WorldPreset::Canopy];

    /// Its name in a description.
    pub fn name(self) -> &'static str {
        match self {
            WorldPreset::Urban => "urban",
            WorldPreset::Canopy => "canopy",
        }
    }

    /// Sets every world key of `cfg` that is not given to the preset's value.
    pub fn fill(self, cfg: &mut DatasetConfig) {
        let grid = |min, max, step| uniform(min, max, step);
        cfg.camera_height_m.get_or_insert(Dist::Fixed(1.5));
        match self {
            WorldPreset::Urban => {
                cfg.canyon.get_or_insert(CanyonDist {
                    width_m: grid(10.0, 50.0, 0.5),
                    height_m: grid(4.0, 30.0, 0.5),
                    azimuth_deg: grid(0.0, 179.9, 0.1),
                });
                cfg.cloud_cover.get_or_insert(grid(0.0, 0.4, 0.01));
            }
            WorldPreset::Canopy => {
                cfg.trees.get_or_insert(TreesDist {
                    count: grid(2.0, 6.0, 1.0),
                    distance_m: grid(1.0, 10.0, 0.1),
                    canopy_height_m: grid(6.0, 10.0, 0.1),
                    radius_m: grid(2.0, 4.0, 0.1),
                    gap_fraction: grid(0.1, 0.4, 0.01),
                });
                cfg.cloud_cover.get_or_insert(grid(0.0, 0.3, 0.01));
            }
        }
    }
}

impl fmt::Display for WorldPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for WorldPreset {
    type Err = Error;
    fn from_str(s: &str) -> Result<WorldPreset> {
        WorldPreset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| Error::OutOfRange {
                name: "world".into(),
                value: s.into(),
                allowed: WorldPreset::ALL.map(WorldPreset::name).join(", "),
            })
    }
}

impl Serialize for WorldPreset {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for WorldPreset {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(de::Error::custom)
    }
}

/// A street canyon (`psns render --canyon WIDTH_M,HEIGHT_M,AZIMUTH_DEG`), each number drawn.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanyonDist {
    /// Street width between the walls, metres.
    pub width_m: Dist,
    /// Wall height, metres.
    pub height_m: Dist,
    /// Compass azimuth of the street's axis, degrees.
    pub azimuth_deg: Dist,
}

/// The clouds' drift (`psns render --wind DEG_PER_S,AZIMUTH_DEG`), each number drawn.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindDist {
    /// Angular speed, degrees per second.
    pub speed_deg_s: Dist,
    /// Compass azimuth the clouds move toward, degrees.
    pub azimuth_deg: Dist,
}

/// Trees standing around the observer: `count` of them, each at a compass azimuth drawn
/// uniformly (0.1 degree grid) and a horizontal distance `distance_m` from the observer, a
/// spherical canopy of radius `radius_m` centred `canopy_height_m` above the ground, the
/// library's trunk (0.2 m) and a gap fraction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreesDist {
    /// Number of trees (whole numbers, 0..[`MAX_TREES`]).
    pub count: Dist,
    /// Horizontal distance of a trunk from the observer, metres.
    pub distance_m: Dist,
    /// Height of a canopy's centre above the ground, metres.
    pub canopy_height_m: Dist,
    /// Radius of a canopy, metres.
    pub radius_m: Dist,
    /// Fraction of a canopy that lets the sky through.
    #[serde(default = "default_gap")]
    pub gap_fraction: Dist,
}

fn default_gap() -> Dist {
    Dist::Fixed(0.2)
}

/// Most trees around one sample.
pub const MAX_TREES: f64 = 64.0;
/// Nearest and farthest a trunk may stand from the observer, metres (beyond the trunk's
/// radius).
pub const TREE_DISTANCE_M: (f64, f64) = (0.5, 1000.0);

/// Random streams of the world's draws ([`crate::rng::dataset_rng`]).
mod stream {
    pub const CANYON_WIDTH: u32 = 22;
    pub const CANYON_HEIGHT: u32 = 23;
    pub const CANYON_AZIMUTH: u32 = 24;
    pub const CAMERA_HEIGHT: u32 = 25;
    pub const CLOUD_COVER: u32 = 26;
    pub const WIND_SPEED: u32 = 27;
    pub const WIND_AZIMUTH: u32 = 28;
    pub const TREE_COUNT: u32 = 29;
    pub const TREE_AZIMUTH: u32 = 30;
    pub const TREE_DISTANCE: u32 = 31;
    pub const TREE_HEIGHT: u32 = 32;
    pub const TREE_RADIUS: u32 = 33;
    pub const TREE_GAP: u32 = 34;
}

impl Dist {
    /// The smallest and largest value it can draw.
    pub(super) fn bounds(&self) -> (f64, f64) {
        match self {
            Dist::Fixed(v) => (*v, *v),
            Dist::Uniform { min, max, .. } => (*min, *max),
            Dist::Choice(v) => v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                }),
        }
    }

    /// Checks that every value it can draw is a whole number (steps too).
    fn check_whole(&self, name: &str) -> Result<()> {
        let whole = |k: &str, v: f64| {
            if v.fract() == 0.0 {
                Ok(())
            } else {
                Err(Error::range(k, v, "whole numbers"))
            }
        };
        match self {
            Dist::Fixed(v) => whole(name, *v),
            Dist::Uniform { min, max, step } => {
                whole(&format!("{name}.min"), *min)?;
                whole(&format!("{name}.max"), *max)?;
                match step {
                    Some(s) if *s < 1.0 || s.fract() != 0.0 => Err(Error::range(
                        &format!("{name}.step"),
                        *s,
                        "whole numbers from 1",
                    )),
                    _ => Ok(()),
                }
            }
            Dist::Choice(v) => v
                .iter()
                .try_for_each(|x| whole(&format!("{name}.values"), *x)),
        }
    }
}

impl DatasetConfig {
    /// Whether the description sets any world key (then every sample has a world, and its
    /// label row the world's columns and class fractions).
    pub fn has_world(&self) -> bool {
        self.canyon.is_some()
            || self.camera_height_m.is_some()
            || self.cloud_cover.is_some()
            || self.wind.is_some()
            || self.trees.is_some()
    }

    /// Whether the world draws from the camera's seed (seeded clouds, the trees' gaps): every
    /// sample then has a camera seed of its own.
    pub(super) fn world_seeded(&self) -> bool {
        self.cloud_cover.is_some() || self.trees.is_some()
    }

    /// Checks the world keys against the library's ranges ([`limits`]).
    pub(super) fn validate_world(&self) -> Result<()> {
        let check = |d: &Dist, k: &str, (lo, hi): (f64, f64)| d.validate(k, lo, hi);
        if let Some(c) = &self.canyon {
            check(&c.width_m, "canyon.width_m", limits::CANYON_WIDTH_M)?;
            check(&c.height_m, "canyon.height_m", limits::CANYON_HEIGHT_M)?;
            check(&c.azimuth_deg, "canyon.azimuth_deg", limits::AZIMUTH_DEG)?;
        }
        if let Some(d) = &self.camera_height_m {
            check(d, "camera_height_m", limits::CAMERA_HEIGHT_M)?;
        }
        if let Some(d) = &self.cloud_cover {
            check(d, "cloud_cover", limits::CLOUD_COVER)?;
        }
        if let Some(w) = &self.wind {
            check(&w.speed_deg_s, "wind.speed_deg_s", limits::WIND_SPEED_DEG_S)?;
            check(&w.azimuth_deg, "wind.azimuth_deg", limits::AZIMUTH_DEG)?;
        }
        if let Some(t) = &self.trees {
            check(&t.count, "trees.count", (0.0, MAX_TREES))?;
            t.count.check_whole("trees.count")?;
            check(&t.distance_m, "trees.distance_m", TREE_DISTANCE_M)?;
            check(
                &t.canopy_height_m,
                "trees.canopy_height_m",
                limits::CANOPY_HEIGHT_M,
            )?;
            check(&t.radius_m, "trees.radius_m", limits::CANOPY_RADIUS_M)?;
            check(&t.gap_fraction, "trees.gap_fraction", limits::GAP_FRACTION)?;
            // every canopy above the camera, so that no draw puts the camera inside one
            let low = t.canopy_height_m.bounds().0 - t.radius_m.bounds().1;
            let eye = self.camera_height_m.as_ref().map_or(0.0, |d| d.bounds().1);
            if low <= eye {
                return Err(Error::Invalid(format!(
                    "trees: a canopy may reach down to the camera (canopy_height_m from {} minus radius_m up to {} is not above camera_height_m up to {}); raise the canopies or shrink them",
                    num(t.canopy_height_m.bounds().0),
                    num(t.radius_m.bounds().1),
                    num(eye)
                )));
            }
        }
        Ok(())
    }

    /// The world of the sample at `frame_index`, each number from its own stream; `None`
    /// without world keys. Checked by the library's validation.
    pub(super) fn draw_world(&self, frame_index: u64) -> Result<Option<WorldConfig>> {
        if !self.has_world() {
            return Ok(None);
        }
        let draw = |d: &Dist, id: u32, step: f64| {
            d.draw(
                &mut crate::rng::dataset_rng(self.seed, frame_index, id),
                step,
            )
        };
        let mut w = WorldConfig::default();
        if let Some(d) = &self.camera_height_m {
            w.camera_height_m = draw(d, stream::CAMERA_HEIGHT, 0.01);
        }
        if let Some(c) = &self.canyon {
            w.canyon = Some(Canyon::new(
                draw(&c.width_m, stream::CANYON_WIDTH, 0.1),
                draw(&c.height_m, stream::CANYON_HEIGHT, 0.1),
                draw(&c.azimuth_deg, stream::CANYON_AZIMUTH, 0.1),
            ));
        }
        if let Some(d) = &self.cloud_cover {
            w.cloud_cover = Some(draw(d, stream::CLOUD_COVER, 0.01));
        }
        if let Some(d) = &self.wind {
            w.wind = Some(Wind {
                speed_deg_s: draw(&d.speed_deg_s, stream::WIND_SPEED, 0.01),
                azimuth_deg: draw(&d.azimuth_deg, stream::WIND_AZIMUTH, 0.1),
            });
        }
        if let Some(t) = &self.trees {
            let n = draw(&t.count, stream::TREE_COUNT, 1.0) as usize;
            let rng = |id| crate::rng::dataset_rng(self.seed, frame_index, id);
            let (mut ra, mut rd, mut rh, mut rr, mut rg) = (
                rng(stream::TREE_AZIMUTH),
                rng(stream::TREE_DISTANCE),
                rng(stream::TREE_HEIGHT),
                rng(stream::TREE_RADIUS),
                rng(stream::TREE_GAP),
            );
            let azimuth = uniform(0.0, 359.9, 0.1);
            for _ in 0..n {
                let a = azimuth.draw(&mut ra, 0.1).to_radians();
                let d = t.distance_m.draw(&mut rd, 0.1);
                let r = t.radius_m.draw(&mut rr, 0.1);
                w.trees.push(Tree {
                    east_m: d * a.sin(),
                    north_m: d * a.cos(),
                    canopy_height_m: t.canopy_height_m.draw(&mut rh, 0.1),
                    radii_m: [r; 3],
                    trunk_radius_m: 0.2,
                    gap_fraction: t.gap_fraction.draw(&mut rg, 0.01),
                });
            }
        }
        w.validate()?;
        Ok(Some(w))
    }
}

/// The world's columns of `labels.csv`, after the others.
macro_rules! world_label_header {
    () => {
        "canyon_width_m,canyon_height_m,canyon_azimuth_deg,camera_height_m,cloud_cover,wind_speed_deg_s,wind_azimuth_deg,trees,outside_fraction,sky_fraction,cloud_fraction,obstruction_fraction,ground_fraction,sun_fraction"
    };
}
pub(super) use world_label_header;

/// Header of the world's columns of `labels.csv`, the last of [`LABEL_HEADER`].
pub const WORLD_LABEL_HEADER: &str = world_label_header!();

impl Sample {
    /// The fraction of the sample's frame (its split's preset) in each class
    /// ([`crate::world::Class::ALL`] order), from the class image of `psns render` on every
    /// [`crate::render::class_stride`]-th pixel, as the frame's record counts them; at stride 1
    /// `psns render`'s `derived.class_fractions`.
    pub fn class_fractions(&self) -> Result<[f64; 6]> {
        let scene = self.scene(self.split.preset());
        let i = scene.intrinsics();
        let stride = crate::render::class_stride(i.width, i.height);
        let class = if scene.raw.sun_disc_on() {
            let (sky, cam) = scene.build()?;
            crate::render::class_image_every(&sky, &cam, true, stride)
        } else {
            // the PSNS presets draw no sun disc: the world and the camera are all it takes
            let sun = scene.sun.resolve()?;
            let cam = crate::camera::Camera::new(i, &scene.camera.attitude, sun.azimuth_deg)?;
            let world = scene.world_at(0.0)?;
            crate::render::class_image_in(Some(&world), &cam, stride)
        };
        Ok(crate::render::fractions(&class))
    }

    /// The world's columns ([`WORLD_LABEL_HEADER`]): all empty without a world; with one, the
    /// canyon's, cloud cover's and wind's empty when not set, the camera height (0: at ground
    /// level) and the number of trees always.
    pub(super) fn world_labels(&self) -> Result<String> {
        let Some(w) = &self.world else {
            return Ok(",".repeat(WORLD_LABEL_HEADER.matches(',').count()));
        };
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        let c = w.canyon;
        let f = self.class_fractions()?;
        let fractions: Vec<String> = f.iter().map(|v| v.to_string()).collect();
        Ok(format!(
            "{},{},{},{},{},{},{},{},{}",
            opt(c.map(|c| c.width_m)),
            opt(c.map(|c| c.height_m)),
            opt(c.map(|c| c.azimuth_deg)),
            w.camera_height_m,
            opt(w.cloud_cover),
            opt(w.wind.map(|w| w.speed_deg_s)),
            opt(w.wind.map(|w| w.azimuth_deg)),
            w.trees.len(),
            fractions.join(",")
        ))
    }
}
