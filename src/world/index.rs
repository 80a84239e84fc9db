//! Directions indexed on the sphere: an octahedral map cut into cells, each listing the items
//! (caps: a centre and an angular radius) that reach within a margin of it, so a ray tests the
//! few things near it instead of all of them.

use glam::DVec3;

/// Cells per side of the octahedral map.
const N: usize = 48;

/// The widest margin (radians, 3°) the index answers for; wider ones must look at every item.
pub const MARGIN_RAD: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// The octahedral map of the unit vector `d` into [0, 1)²: no trigonometry per ray.
#[inline]
fn octahedral(d: DVec3) -> (f64, f64) {
    let n = d.x.abs() + d.y.abs() + d.z.abs();
    let (mut x, mut y) = (d.x / n, d.y / n);
    if d.z < 0.0 {
        let (ax, ay) = (x.abs(), y.abs());
        x = (1.0 - ay) * x.signum();
        y = (1.0 - ax) * y.signum();
    }
    (0.5 * (x + 1.0), 0.5 * (y + 1.0))
}

/// The unit vector of the octahedral map's point (u, v) in [0, 1]².
fn from_octahedral(u: f64, v: f64) -> DVec3 {
    let (x, y) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum())
    } else {
        (x, y)
    };
    DVec3::new(x, y, z).normalize()
}

/// The bounding cap (centre, angular radius) of every cell, row by row: the cap around the
/// cell's centre through the farthest of a 5 × 5 lattice of its points, grown by a tenth for the
/// curvature between them. The same for every index, so computed once.
fn cell_caps() -> &'static [(DVec3, f64)] {
    static CAPS: std::sync::OnceLock<Vec<(DVec3, f64)>> = std::sync::OnceLock::new();
    CAPS.get_or_init(|| {
        let n = N as f64;
        let mut out = Vec::with_capacity(N * N);
        for j in 0..N {
            for i in 0..N {
                let (u0, v0) = (i as f64 / n, j as f64 / n);
                let centre = from_octahedral(u0 + 0.5 / n, v0 + 0.5 / n);
                let mut reach: f64 = 0.0;
                for a in 0..5 {
                    for b in 0..5 {
                        let p =
                            from_octahedral(u0 + a as f64 / (4.0 * n), v0 + b as f64 / (4.0 * n));
                        reach = reach.max(centre.dot(p).clamp(-1.0, 1.0).acos());
                    }
                }
                out.push((centre, reach * 1.1 + 1e-3));
            }
        }
        out
    })
}

/// Caps on the sphere, indexed by cell.
#[derive(Clone, Debug, Default)]
pub(super) struct SphereIndex {
    cells: Vec<Vec<u32>>,
}

impl SphereIndex {
    /// Indexes `caps` (unit centre, angular radius): each is listed in every cell it reaches
    /// within [`MARGIN_RAD`], a cell bounded by its cap ([`cell_caps`]).
    pub(super) fn new(caps: &[(DVec3, f64)]) -> Self {
        if caps.is_empty() {
            return SphereIndex::default();
        }
        let cells = cell_caps()
            .iter()
            .map(|&(centre, reach)| {
                let mut list = Vec::new();
                for (k, &(c, r)) in caps.iter().enumerate() {
                    if centre.dot(c).clamp(-1.0, 1.0).acos() <= r + MARGIN_RAD + reach {
                        list.push(k as u32);
                    }
                }
                list
            })
            .collect();
        SphereIndex { cells }
    }

    /// The items that may lie within [`MARGIN_RAD`] of the unit vector `d`.
    #[inline]
    pub(super) fn near(&self, d: DVec3) -> &[u32] {
        if self.cells.is_empty() {
            return &[];
        }
        let (u, v) = octahedral(d);
        let (i, j) = (
            ((u * N as f64) as usize).min(N - 1),
            ((v * N as f64) as usize).min(N - 1),
        );
        &self.cells[j * N + i]
    }
}
