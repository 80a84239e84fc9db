//! The solid things of the world: a street canyon, boxes, trees; each traced exactly, and their
//! edges as arcs on the unit sphere around the eye.

use super::{Hit, DEFAULT_ALBEDO, DEFAULT_GLASS_INDEX};
use crate::error::{check_range, Error, Result};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// What a wall or a box is made of.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Surface {
    /// Lambertian, unpolarized, with its albedo.
    #[default]
    Diffuse,
    /// Glass: reflects the sky specularly (Fresnel).
    Glass,
}

/// Two infinitely long walls of `height_m` either side of a street `width_m` wide whose axis
/// runs along compass `azimuth_deg`, the observer on its centre line.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Canyon {
    /// Street width between the walls, metres.
    pub width_m: f64,
    /// Wall height, metres.
    pub height_m: f64,
    /// Compass azimuth of the street's axis, degrees.
    pub azimuth_deg: f64,
    /// The walls' surface.
    #[serde(default)]
    pub surface: Surface,
    /// Albedo of diffuse walls.
    #[serde(default = "default_albedo")]
    pub albedo: f64,
    /// Refractive index of glass walls.
    #[serde(default = "default_index")]
    pub refractive_index: f64,
}

fn default_albedo() -> f64 {
    DEFAULT_ALBEDO
}
fn default_index() -> f64 {
    DEFAULT_GLASS_INDEX
}

/// The (east, north) unit vector of compass azimuth `deg`.
fn compass(deg: f64) -> DVec2 {
    let a = deg.to_radians();
    DVec2::new(a.sin(), a.cos())
}

fn material_hit(surface: Surface, albedo: f64, index: f64, normal: DVec3) -> Hit {
    match surface {
        Surface::Diffuse => Hit::Diffuse { normal, albedo },
        Surface::Glass => Hit::Glass { normal, index },
    }
}

fn check_material(what: &str, albedo: f64, index: f64) -> Result<()> {
    check_range(&format!("{what} albedo"), albedo, 0.0, 1.0)?;
    check_range(&format!("{what} refractive_index"), index, 1.0, 3.0)?;
    Ok(())
}

impl Canyon {
    /// A diffuse canyon.
    pub fn new(width_m: f64, height_m: f64, azimuth_deg: f64) -> Self {
        Canyon {
            width_m,
            height_m,
            azimuth_deg,
            surface: Surface::Diffuse,
            albedo: DEFAULT_ALBEDO,
            refractive_index: DEFAULT_GLASS_INDEX,
        }
    }

    pub(super) fn validate(&self, camera_height_m: f64) -> Result<()> {
        use super::limits::{AZIMUTH_DEG, CANYON_HEIGHT_M, CANYON_WIDTH_M};
        check_range(
            "canyon width",
            self.width_m,
            CANYON_WIDTH_M.0,
            CANYON_WIDTH_M.1,
        )?;
        check_range(
            "canyon height",
            self.height_m,
            CANYON_HEIGHT_M.0,
            CANYON_HEIGHT_M.1,
        )?;
        check_range(
            "canyon azimuth",
            self.azimuth_deg,
            AZIMUTH_DEG.0,
            AZIMUTH_DEG.1,
        )?;
        check_material("canyon", self.albedo, self.refractive_index)?;
        let _ = camera_height_m;
        Ok(())
    }

    /// The horizontal unit vector across the street (to the right of its axis).
    fn across(&self) -> DVec3 {
        let a = compass(self.azimuth_deg);
        DVec3::new(a.y, -a.x, 0.0)
    }

    pub(super) fn hit(&self, eye: DVec3, d: DVec3) -> Option<(f64, Hit)> {
        let p = self.across();
        let dp = d.dot(p);
        if dp == 0.0 || dp.is_nan() {
            return None;
        }
        let t = 0.5 * self.width_m / dp.abs();
        let z = eye.z + t * d.z;
        if !(0.0..=self.height_m).contains(&z) {
            return None;
        }
        let normal = -dp.signum() * p;
        Some((
            t,
            material_hit(self.surface, self.albedo, self.refractive_index, normal),
        ))
    }

    pub(super) fn edges(&self, eye: DVec3, out: &mut Vec<Arc>) {
        let p = self.across();
        let a = compass(self.azimuth_deg);
        let axis = DVec3::new(a.x, a.y, 0.0);
        for side in [-1.0, 1.0] {
            for z in [self.height_m, 0.0] {
                let p0 = side * 0.5 * self.width_m * p + DVec3::new(0.0, 0.0, z) - eye;
                if z == 0.0 && eye.z == 0.0 {
                    continue; // the foot of the wall is the horizon, tested on its own
                }
                out.push(Arc::great_circle(p0.cross(axis)));
            }
        }
    }
}

/// A box on the ground: footprint centred `east_m`, `north_m` from the observer, `width_m`
/// along the compass direction `rotation_deg` + 90 (east when 0), `depth_m` along
/// `rotation_deg` (north when 0), and `height_m` tall.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Building {
    /// Centre of the footprint, metres east of the observer.
    pub east_m: f64,
    /// Centre of the footprint, metres north of the observer.
    pub north_m: f64,
    /// Footprint width, metres.
    pub width_m: f64,
    /// Footprint depth, metres.
    pub depth_m: f64,
    /// Height, metres.
    pub height_m: f64,
    /// Compass azimuth of the depth axis, degrees (0: the depth runs north).
    #[serde(default)]
    pub rotation_deg: f64,
    /// The walls' surface.
    #[serde(default)]
    pub surface: Surface,
    /// Albedo of diffuse walls.
    #[serde(default = "default_albedo")]
    pub albedo: f64,
    /// Refractive index of glass walls.
    #[serde(default = "default_index")]
    pub refractive_index: f64,
}

impl Building {
    pub(super) fn validate(&self, k: usize) -> Result<()> {
        let n = |s: &str| format!("building {} {s}", k + 1);
        check_range(&n("east_m"), self.east_m, -1e5, 1e5)?;
        check_range(&n("north_m"), self.north_m, -1e5, 1e5)?;
        check_range(&n("width_m"), self.width_m, 0.01, 1e5)?;
        check_range(&n("depth_m"), self.depth_m, 0.01, 1e5)?;
        check_range(&n("height_m"), self.height_m, 0.01, 1e4)?;
        check_range(&n("rotation_deg"), self.rotation_deg, -360.0, 720.0)?;
        check_material(
            &format!("building {}", k + 1),
            self.albedo,
            self.refractive_index,
        )?;
        let b = PreparedBox::new(self);
        let (u, v) = b.local(DVec3::ZERO);
        if u.abs() <= 0.5 * self.width_m && v.abs() <= 0.5 * self.depth_m {
            return Err(Error::Invalid(format!(
                "building {} stands around the observer (its footprint {} m x {} m centred {} m east, {} m north holds the origin); a building must stand apart from the camera",
                k + 1,
                crate::error::num(self.width_m),
                crate::error::num(self.depth_m),
                crate::error::num(self.east_m),
                crate::error::num(self.north_m),
            )));
        }
        Ok(())
    }
}

/// A [`Building`] with its axes.
#[derive(Clone, Copy, Debug)]
pub(super) struct PreparedBox {
    b: Building,
    /// Unit vectors of the width and depth axes (horizontal).
    u: DVec3,
    v: DVec3,
}

impl PreparedBox {
    pub(super) fn new(b: &Building) -> Self {
        let v = compass(b.rotation_deg);
        let u = compass(b.rotation_deg + 90.0);
        PreparedBox {
            b: *b,
            u: DVec3::new(u.x, u.y, 0.0),
            v: DVec3::new(v.x, v.y, 0.0),
        }
    }

    /// Footprint coordinates of the ground point under `p` (relative to the box's centre).
    fn local(&self, p: DVec3) -> (f64, f64) {
        let q = p - DVec3::new(self.b.east_m, self.b.north_m, 0.0);
        (q.dot(self.u), q.dot(self.v))
    }

    /// Slab test: the entry distance and the face's normal.
    pub(super) fn hit(&self, eye: DVec3, d: DVec3) -> Option<(f64, Hit)> {
        let (ou, ov) = self.local(eye);
        let (du, dv) = (d.dot(self.u), d.dot(self.v));
        let half = [0.5 * self.b.width_m, 0.5 * self.b.depth_m];
        let axes = [
            (ou, du, self.u),
            (ov, dv, self.v),
            (eye.z - 0.5 * self.b.height_m, d.z, DVec3::Z),
        ];
        let halves = [half[0], half[1], 0.5 * self.b.height_m];
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        let mut normal = DVec3::ZERO;
        for ((o, dd, ax), h) in axes.into_iter().zip(halves) {
            if dd == 0.0 {
                if o.abs() > h {
                    return None;
                }
                continue;
            }
            let (a, b) = ((-h - o) / dd, (h - o) / dd);
            let (near, far) = if a < b { (a, b) } else { (b, a) };
            if near > t0 {
                t0 = near;
                normal = -dd.signum() * ax;
            }
            t1 = t1.min(far);
            if t0 > t1 {
                return None;
            }
        }
        if normal == DVec3::ZERO {
            return None; // the eye is inside (refused by validation)
        }
        Some((
            t0,
            material_hit(
                self.b.surface,
                self.b.albedo,
                self.b.refractive_index,
                normal,
            ),
        ))
    }

    pub(super) fn edges(&self, eye: DVec3, out: &mut Vec<Arc>) {
        let c = DVec3::new(self.b.east_m, self.b.north_m, 0.0);
        let (hu, hv) = (0.5 * self.b.width_m * self.u, 0.5 * self.b.depth_m * self.v);
        let corners = [c - hu - hv, c + hu - hv, c + hu + hv, c - hu + hv];
        let top = DVec3::new(0.0, 0.0, self.b.height_m);
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            out.push(Arc::new(a + top - eye, b + top - eye));
            out.push(Arc::new(a - eye, b - eye));
            out.push(Arc::new(a - eye, a + top - eye));
        }
    }
}

/// A tree: a canopy of foliage (an ellipsoid with axes along east, north and up) on a trunk
/// (a vertical cylinder from the ground to the canopy's centre). A ray meeting the canopy
/// passes through a gap with probability `gap_fraction`, in a pattern fixed to the world
/// (cells of [`GAP_CELL_M`] where it enters, drawn from the world's seed).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tree {
    /// Canopy centre, metres east of the observer.
    pub east_m: f64,
    /// Canopy centre, metres north of the observer.
    pub north_m: f64,
    /// Height of the canopy's centre above the ground, metres.
    pub canopy_height_m: f64,
    /// Canopy semi-axes (east, north, up), metres.
    pub radii_m: [f64; 3],
    /// Trunk radius, metres (0: none).
    #[serde(default = "default_trunk")]
    pub trunk_radius_m: f64,
    /// Fraction of the canopy that lets the sky through, 0..1.
    #[serde(default = "default_gap")]
    pub gap_fraction: f64,
}

fn default_trunk() -> f64 {
    0.2
}
fn default_gap() -> f64 {
    0.2
}

/// Size of the cells of a canopy's gap pattern, metres (a leaf cluster).
pub const GAP_CELL_M: f64 = 0.15;

/// Albedo of foliage (green leaves in the visible, 0.05-0.15).
pub const FOLIAGE_ALBEDO: f64 = 0.1;

impl Tree {
    pub(super) fn validate(&self, k: usize, camera_height_m: f64) -> Result<()> {
        let n = |s: &str| format!("tree {} {s}", k + 1);
        check_range(&n("east_m"), self.east_m, -1e5, 1e5)?;
        check_range(&n("north_m"), self.north_m, -1e5, 1e5)?;
        use super::limits::{CANOPY_HEIGHT_M, CANOPY_RADIUS_M, GAP_FRACTION};
        let (lo, hi) = CANOPY_HEIGHT_M;
        check_range(&n("canopy_height_m"), self.canopy_height_m, lo, hi)?;
        for r in self.radii_m {
            check_range(&n("radii_m"), r, CANOPY_RADIUS_M.0, CANOPY_RADIUS_M.1)?;
        }
        check_range(&n("trunk_radius_m"), self.trunk_radius_m, 0.0, 100.0)?;
        let (lo, hi) = GAP_FRACTION;
        check_range(&n("gap_fraction"), self.gap_fraction, lo, hi)?;
        let eye = DVec3::new(0.0, 0.0, camera_height_m);
        let q = (eye - self.centre()) / DVec3::from(self.radii_m);
        let h = DVec2::new(self.east_m, self.north_m).length();
        if q.length_squared() <= 1.0
            || (h <= self.trunk_radius_m && camera_height_m <= self.canopy_height_m)
        {
            return Err(Error::Invalid(format!(
                "tree {} stands around the observer (canopy centred {} m east, {} m north); a tree must stand apart from the camera",
                k + 1,
                crate::error::num(self.east_m),
                crate::error::num(self.north_m),
            )));
        }
        Ok(())
    }

    fn centre(&self) -> DVec3 {
        DVec3::new(self.east_m, self.north_m, self.canopy_height_m)
    }

    pub(super) fn hit(&self, eye: DVec3, d: DVec3, seed: u64, k: u64) -> Option<(f64, Hit)> {
        let mut best: Option<(f64, Hit)> = None;
        // canopy: the unit sphere after scaling
        let r = DVec3::from(self.radii_m);
        let (o, dd) = ((eye - self.centre()) / r, d / r);
        let a = dd.length_squared();
        let b = o.dot(dd);
        let c = o.length_squared() - 1.0;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let t = (-b - disc.sqrt()) / a;
            if t >= 0.0 {
                let p = eye + t * d;
                if !gap(p, seed, k, self.gap_fraction) {
                    best = Some((t, Hit::Foliage));
                }
            }
        }
        // trunk: a vertical cylinder from the ground to the canopy's centre
        if self.trunk_radius_m > 0.0 {
            let o = DVec2::new(eye.x - self.east_m, eye.y - self.north_m);
            let dh = DVec2::new(d.x, d.y);
            let a = dh.length_squared();
            if a > 0.0 {
                let b = o.dot(dh);
                let c = o.length_squared() - self.trunk_radius_m * self.trunk_radius_m;
                let disc = b * b - a * c;
                if disc >= 0.0 {
                    let t = (-b - disc.sqrt()) / a;
                    let z = eye.z + t * d.z;
                    if t >= 0.0
                        && (0.0..=self.canopy_height_m).contains(&z)
                        && best.is_none_or(|(bt, _)| t < bt)
                    {
                        let p = o + t * dh;
                        let n = (p / self.trunk_radius_m).extend(0.0);
                        best = Some((
                            t,
                            Hit::Diffuse {
                                normal: n,
                                albedo: DEFAULT_ALBEDO,
                            },
                        ));
                    }
                }
            }
        }
        best
    }

    /// Bounding cones of the canopy and the trunk seen from `eye`: (unit axis, angular radius).
    pub(super) fn cones(&self, eye: DVec3, out: &mut Vec<(DVec3, f64)>) {
        let c = self.centre() - eye;
        let rmax = self.radii_m.iter().fold(0f64, |m, &r| m.max(r));
        let dist = c.length();
        out.push((c / dist, (rmax / dist).min(1.0).asin()));
        if self.trunk_radius_m > 0.0 {
            // the trunk inside the cone of its bounding sphere
            let half = 0.5 * self.canopy_height_m;
            let m = DVec3::new(self.east_m, self.north_m, half) - eye;
            let r = (half * half + self.trunk_radius_m * self.trunk_radius_m).sqrt();
            let dist = m.length();
            let ang = if r >= dist {
                std::f64::consts::PI
            } else {
                (r / dist).asin()
            };
            out.push((m / dist, ang));
        }
    }
}

/// Whether the canopy point `p` of tree `k` is a gap: a hash of its cell, the seed and the tree
/// (splitmix64), uniform in [0, 1), below the gap fraction.
fn gap(p: DVec3, seed: u64, k: u64, fraction: f64) -> bool {
    let c = (p / GAP_CELL_M).floor();
    let mut h = seed ^ k.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    for v in [c.x, c.y, c.z] {
        h = splitmix(h ^ (v as i64 as u64));
    }
    ((h >> 11) as f64) * (1.0 / (1u64 << 53) as f64) < fraction
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// An arc of a great circle on the unit sphere (the image of a straight edge seen from the
/// eye), or a whole great circle.
#[derive(Clone, Copy, Debug)]
pub(super) struct Arc {
    a: DVec3,
    b: DVec3,
    /// Unit normal of the circle's plane.
    n: DVec3,
    whole: bool,
    /// Subtracted from every distance (radians): a curve the arc approximates.
    slack: f64,
}

impl Arc {
    /// The shorter arc between the directions of `a` and `b` (not zero).
    pub(super) fn new(a: DVec3, b: DVec3) -> Self {
        let (a, b) = (a.normalize(), b.normalize());
        let n = a.cross(b);
        let n = if n.length_squared() > 1e-24 {
            n.normalize()
        } else {
            DVec3::ZERO
        };
        Arc {
            a,
            b,
            n,
            whole: false,
            slack: 0.0,
        }
    }

    /// The arc with `slack` radians taken off every distance.
    pub(super) fn widened(mut self, slack: f64) -> Self {
        self.slack = slack;
        self
    }

    /// The whole great circle of the plane with normal `n`.
    pub(super) fn great_circle(n: DVec3) -> Self {
        Arc {
            a: DVec3::ZERO,
            b: DVec3::ZERO,
            n: n.normalize(),
            whole: true,
            slack: 0.0,
        }
    }

    /// Whether this is a whole great circle.
    pub(super) fn is_whole(&self) -> bool {
        self.whole
    }

    /// A cap holding the arc: (unit centre, angular radius).
    pub(super) fn cap(&self) -> (DVec3, f64) {
        let m = self.a + self.b;
        if m.length_squared() < 1e-20 {
            return (self.a, std::f64::consts::PI);
        }
        let half = 0.5 * self.a.dot(self.b).clamp(-1.0, 1.0).acos();
        (m.normalize(), half + 1e-9)
    }

    /// Angle (radians) from the unit vector `d` to the nearest point of the arc.
    pub(super) fn distance(&self, d: DVec3) -> f64 {
        self.exact_distance(d) - self.slack
    }

    fn exact_distance(&self, d: DVec3) -> f64 {
        let s = d.dot(self.n).clamp(-1.0, 1.0);
        if self.whole {
            return s.abs().asin();
        }
        let ang = |v: DVec3| d.dot(v).clamp(-1.0, 1.0).acos();
        if self.n == DVec3::ZERO {
            return ang(self.a);
        }
        // the foot of d on the circle lies within the arc when it is on a's far side from -b
        let q = d - s * self.n;
        if self.a.cross(q).dot(self.n) >= 0.0 && q.cross(self.b).dot(self.n) >= 0.0 {
            s.abs().asin()
        } else {
            ang(self.a).min(ang(self.b))
        }
    }
}
