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
        check_range("wind speed (deg/s)", self.speed_deg_s, -10.0, 10.0)?;
        check_range("wind azimuth", self.azimuth_deg, -360.0, 720.0)?;
        Ok(())
    }
}

/// A cloud placed at a scene time: unit centre, cos of the inner (opaque) and outer radii.
#[derive(Clone, Copy, Debug)]
struct Placed {
    c: DVec3,
    opacity: f64,
    inner: f64,
    outer: f64,
    cos_outer: f64,
}

/// The clouds at one scene time, indexed by direction: cells of the sphere, equal in
/// z = sin(elevation) and in azimuth, each listing the clouds whose rim (grown by
/// [`INDEX_MARGIN_RAD`]) reaches into it.
#[derive(Clone, Debug, Default)]
pub struct CloudField {
    clouds: Vec<Placed>,
    cells: Vec<Vec<u32>>,
}

/// Rows (in z) and columns (in azimuth) of the cloud index.
const INDEX_Z: usize = 32;
const INDEX_AZ: usize = 64;
/// The widest margin [`CloudField::clear`] answers from the index (radians, 3°); wider ones
/// look at every cloud.
pub const INDEX_MARGIN_RAD: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// The index cell of the unit vector `d`.
#[inline]
fn cell_of(d: DVec3) -> usize {
    let zi = (((d.z + 1.0) * 0.5 * INDEX_Z as f64) as usize).min(INDEX_Z - 1);
    let a = d.x.atan2(d.y); // -π..π
    let ai = (((a / std::f64::consts::TAU + 0.5) * INDEX_AZ as f64) as usize).min(INDEX_AZ - 1);
    zi * INDEX_AZ + ai
}

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
        let clouds = clouds
            .iter()
            .map(|c| {
                let mut v = unit(c.azimuth_deg, c.elevation_deg);
                if let Some(q) = turn {
                    v = (q * v).normalize();
                }
                let r = c.radius_deg.to_radians();
                Placed {
                    c: v,
                    opacity: c.opacity,
                    inner: r * (1.0 - c.softness),
                    outer: r,
                    cos_outer: r.cos(),
                }
            })
            .collect();
        let mut f = CloudField {
            clouds,
            cells: Vec::new(),
        };
        f.index();
        f
    }

    /// Lists each cloud in the cells its grown rim can reach: a cell is bounded by the cap
    /// around its centre through its farthest corner.
    fn index(&mut self) {
        if self.clouds.is_empty() {
            return;
        }
        let mut cells = vec![Vec::new(); INDEX_Z * INDEX_AZ];
        let dir = |z: f64, a: f64| {
            let r = (1.0 - z * z).max(0.0).sqrt();
            DVec3::new(r * a.sin(), r * a.cos(), z)
        };
        for zi in 0..INDEX_Z {
            let (z0, z1) = (
                zi as f64 * 2.0 / INDEX_Z as f64 - 1.0,
                (zi + 1) as f64 * 2.0 / INDEX_Z as f64 - 1.0,
            );
            for ai in 0..INDEX_AZ {
                let step = std::f64::consts::TAU / INDEX_AZ as f64;
                let (a0, a1) = (
                    -std::f64::consts::PI + ai as f64 * step,
                    -std::f64::consts::PI + (ai + 1) as f64 * step,
                );
                let centre = dir(0.5 * (z0 + z1), 0.5 * (a0 + a1));
                // the cap through the corners and the edges' midpoints bounds the cell
                let mut reach: f64 = 0.0;
                for z in [z0, 0.5 * (z0 + z1), z1] {
                    for a in [a0, 0.5 * (a0 + a1), a1] {
                        reach = reach.max(centre.dot(dir(z, a)).clamp(-1.0, 1.0).acos());
                    }
                }
                // the azimuth bulge between the sampled points, with room to spare
                let reach = reach * 1.1 + 1e-3;
                let list = &mut cells[zi * INDEX_AZ + ai];
                for (k, p) in self.clouds.iter().enumerate() {
                    let ang = centre.dot(p.c).clamp(-1.0, 1.0).acos();
                    if ang <= p.outer + INDEX_MARGIN_RAD + reach {
                        list.push(k as u32);
                    }
                }
            }
        }
        self.cells = cells;
    }

    /// The clouds that may lie within [`INDEX_MARGIN_RAD`] of `d`.
    #[inline]
    fn near(&self, d: DVec3) -> impl Iterator<Item = &Placed> {
        let list: &[u32] = if self.cells.is_empty() {
            &[]
        } else {
            &self.cells[cell_of(d)]
        };
        list.iter().map(|&k| &self.clouds[k as usize])
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
    /// inner radius falling as a smooth step to 0 at its rim.
    #[inline]
    pub fn opacity(&self, d: DVec3) -> f64 {
        let mut clear = 1.0;
        for p in self.near(d) {
            let c = d.dot(p.c);
            if c <= p.cos_outer {
                continue;
            }
            let ang = c.clamp(-1.0, 1.0).acos();
            let a = if ang <= p.inner {
                p.opacity
            } else {
                let x = ((p.outer - ang) / (p.outer - p.inner)).clamp(0.0, 1.0);
                p.opacity * x * x * (3.0 - 2.0 * x)
            };
            clear *= 1.0 - a;
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
        let f = CloudField::new(&[c], None, 0.0);
        covered = 0;
        for (k, d) in dirs.iter().enumerate() {
            clear[k] *= 1.0 - f.opacity(*d);
            covered += (clear[k] <= 0.5) as usize;
        }
        out.push(c);
    }
    out
}
