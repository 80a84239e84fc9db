//! Clouds fixed in the sky (ENU), not in the image: each a soft disc of the sky at a direction,
//! with an angular radius and an opacity, seeded or listed, drifting with a wind.
//!
//! Optics (`docs/world.md`): a cloud of opacity α in front of the clear sky gives
//! L = (1 − α) L_sky + α L_cloud, and only the sky's part stays polarized: the degree falls to
//! (1 − α) L_sky DoP / L and the angle is the clear sky's (as Pomozi et al. 2001 measured
//! under thin clouds); a thick cloud (α = 1) is unpolarized.

use crate::error::{check_range, Result};
use glam::DVec3;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// One cloud: a soft disc of the sky.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cloud {
    /// Compass azimuth of its centre, degrees.
    pub azimuth_deg: f64,
    /// Elevation of its centre, degrees.
    pub elevation_deg: f64,
    /// Angular radius, degrees.
    pub radius_deg: f64,
    /// Opacity at the centre, 0..1 (1: thick, nothing of the sky through).
    #[serde(default = "one")]
    pub opacity: f64,
    /// Width of the soft rim as a fraction of the radius, 0..1.
    #[serde(default = "default_softness")]
    pub softness: f64,
}

fn one() -> f64 {
    1.0
}
fn default_softness() -> f64 {
    0.1
}

/// Radiance of a thick cloud as a multiple of the clear sky's zenith radiance (a bright
/// cumulus in sunlight; the image-space soft clouds take 2.5 times the median sky).
pub const CLOUD_BRIGHTNESS: f64 = 2.5;

impl Cloud {
    pub(super) fn validate(&self, k: usize) -> Result<()> {
        let n = |s: &str| format!("cloud {} {s}", k + 1);
        check_range(&n("azimuth_deg"), self.azimuth_deg, -360.0, 720.0)?;
        check_range(&n("elevation_deg"), self.elevation_deg, -90.0, 90.0)?;
        check_range(&n("radius_deg"), self.radius_deg, 0.01, 90.0)?;
        check_range(&n("opacity"), self.opacity, 0.0, 1.0)?;
        check_range(&n("softness"), self.softness, 0.0, 1.0)?;
        Ok(())
    }
}

/// Clouds moving across the sky at `speed_deg_s` toward compass `azimuth_deg` (at the zenith;
/// the whole field turns about the horizontal axis across the wind).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wind {
    /// Angular speed, degrees per second.
    pub speed_deg_s: f64,
    /// Compass azimuth the clouds move toward, degrees.
    pub azimuth_deg: f64,
}

impl Wind {
    pub(super) fn validate(&self) -> Result<()> {
        use super::limits::{AZIMUTH_DEG, WIND_SPEED_DEG_S};
        let (lo, hi) = WIND_SPEED_DEG_S;
        check_range("wind speed (deg/s)", self.speed_deg_s, lo, hi)?;
        check_range(
            "wind azimuth",
            self.azimuth_deg,
            AZIMUTH_DEG.0,
            AZIMUTH_DEG.1,
        )?;
        Ok(())
    }
}

/// A cloud placed at a scene time: unit centre, cos of the inner (opaque) and outer radii.
#[derive(Clone, Copy, Debug)]
struct Placed {
    c: DVec3,
    opacity: f64,
    outer: f64,
    cos_outer: f64,
    cos_inner: f64,
}

impl Placed {
    /// `c` at scene time 0.
    fn new(c: &Cloud) -> Self {
        let r = c.radius_deg.to_radians();
        Placed {
            c: unit(c.azimuth_deg, c.elevation_deg),
            opacity: c.opacity,
            outer: r,
            cos_outer: r.cos(),
            cos_inner: (r * (1.0 - c.softness)).cos(),
        }
    }

    /// The opacity where the cosine of the angle from the centre is `c` (0 at and beyond the
    /// rim).
    #[inline]
    fn opacity_at(&self, c: f64) -> f64 {
        if c <= self.cos_outer {
            0.0
        } else if c >= self.cos_inner {
            self.opacity
        } else {
            // a smooth step in cos(angle): no arccosine per ray
            let x = ((c - self.cos_outer) / (self.cos_inner - self.cos_outer)).clamp(0.0, 1.0);
            self.opacity * x * x * (3.0 - 2.0 * x)
        }
    }
}

/// The clouds at one scene time, indexed by direction: cells of the sphere, equal in
/// z = sin(elevation) and in azimuth, each listing the clouds whose rim (grown by
/// [`INDEX_MARGIN_RAD`]) reaches into it.
#[derive(Clone, Debug, Default)]
pub struct CloudField {
    clouds: Vec<Placed>,
    index: SphereIndex,
}

use super::index::SphereIndex;
pub use super::index::MARGIN_RAD as INDEX_MARGIN_RAD;

fn unit(az_deg: f64, el_deg: f64) -> DVec3 {
    let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
    DVec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
}

impl CloudField {
    /// `clouds` drifted by `wind` for `t_s` seconds.
    pub fn new(clouds: &[Cloud], wind: Option<Wind>, t_s: f64) -> Self {
        let turn = wind.map(|w| {
            let a = w.azimuth_deg.to_radians();
            let axis = DVec3::Z.cross(DVec3::new(a.sin(), a.cos(), 0.0));
            glam::DQuat::from_axis_angle(axis, (w.speed_deg_s * t_s).to_radians())
        });
        let clouds: Vec<Placed> = clouds
            .iter()
            .map(|c| {
                let mut p = Placed::new(c);
                if let Some(q) = turn {
                    p.c = (q * p.c).normalize();
                }
                p
            })
            .collect();
        let caps: Vec<(DVec3, f64)> = clouds.iter().map(|p: &Placed| (p.c, p.outer)).collect();
        CloudField {
            clouds,
            index: SphereIndex::new(&caps),
        }
    }

    /// The clouds that may lie within [`INDEX_MARGIN_RAD`] of `d`.
    #[inline]
    fn near(&self, d: DVec3) -> impl Iterator<Item = &Placed> {
        self.index.near(d).iter().map(|&k| &self.clouds[k as usize])
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.clouds.is_empty()
    }

    /// Number of clouds.
    pub fn len(&self) -> usize {
        self.clouds.len()
    }

    /// The unit centre of cloud `k`.
    pub fn centre(&self, k: usize) -> DVec3 {
        self.clouds[k].c
    }

    /// Opacity along the unit ray `d`: 1 − Π (1 − α_k), α_k the cloud's opacity inside its
    /// inner radius falling to 0 at its rim as a smooth step 3x² − 2x³ in
    /// x = (cos θ − cos r_out)/(cos r_in − cos r_out), θ the angle from its centre.
    #[inline]
    pub fn opacity(&self, d: DVec3) -> f64 {
        let mut clear = 1.0;
        for p in self.near(d) {
            let c = d.dot(p.c);
            if c > p.cos_outer {
                clear *= 1.0 - p.opacity_at(c);
            }
        }
        1.0 - clear
    }

    /// Whether no cloud that could hide between nodes `margin` radians apart lies within
    /// `margin` of `d`: a cloud less than four margins across. The rims of larger ones are
    /// smooth (a smooth step), and the grid's curvature test refines them as it does the sky.
    pub(super) fn clear(&self, d: DVec3, margin: f64) -> bool {
        let small = |p: &Placed| {
            p.outer < 2.0 * margin && d.dot(p.c).clamp(-1.0, 1.0).acos() <= p.outer + margin
        };
        if margin > INDEX_MARGIN_RAD {
            !self.clouds.iter().any(small)
        } else {
            !self.near(d).any(small)
        }
    }
}

/// Seeded clouds covering about `cover` of the sky above the horizon (the fraction of
/// directions, uniform in solid angle, with opacity ≥ 0.5): centres uniform over the sky,
/// radii 4-15°, opacities 0.5-1, added until the cover is reached (judged on 4096 directions).
pub fn draw_cover(cover: f64, seed: u64) -> Vec<Cloud> {
    let mut rng = crate::rng::scene_rng(seed, 0x7765_6c64);
    // a Fibonacci lattice of the hemisphere, uniform in solid angle
    const N: usize = 4096;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let dirs: Vec<DVec3> = (0..N)
        .map(|k| {
            let z = (k as f64 + 0.5) / N as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * k as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect();
    let mut clear = vec![1.0f64; N];
    let mut covered = 0usize;
    let mut out = Vec::new();
    while (covered as f64) < cover * N as f64 && out.len() < 2000 {
        let c = Cloud {
            azimuth_deg: rng.random_range(0.0..360.0),
            elevation_deg: rng.random_range(0.0f64..1.0).asin().to_degrees(),
            radius_deg: rng.random_range(4.0..15.0),
            opacity: rng.random_range(0.5..1.0),
            softness: 0.1,
        };
        // the one cloud alone: no index to build per draw
        let p = Placed::new(&c);
        covered = 0;
        for (k, d) in dirs.iter().enumerate() {
            clear[k] *= 1.0 - p.opacity_at(d.dot(p.c));
            covered += (clear[k] <= 0.5) as usize;
        }
        out.push(c);
    }
    out
}
