//! Ideal images in the sensor frame (the PSNS paper's Fig. 10 a–g): LI, DOP and AOP per pixel, the
//! sensor-frame Stokes planes, and the four polarizer-direction images of eq. (24).
//!
//! Each pixel samples the sky along its own ray (`sky.md` §7, `camera.md`): d_n = (C_n^c)ᵀ d_c/|d_c|
//! with d_c from the projection; the E-vector is rotated into the camera frame and delivered to the
//! sensor by the lens ([`crate::camera::Lens`]: projected on the focal plane for the pinhole,
//! AOP_s = atan2(e_c,y, e_c,x) mod 180°, from +x = columns toward +y = rows, down). Pixels that
//! look at or below the horizon, or lie outside a fisheye's image circle, are invalid:
//! LI = DOP = AOP = 0 (ground: the ground radiance) and mask 0 (never NaN).
//!
//! [`pixel_sky`] is one pixel; [`pixel_sky_cols`] (the row evaluator) gives the same bits for a
//! row's pixels a chunk at a time, in loops that vectorise, and is what the renders and the
//! fast path's [`SkyGrid`] use.

use crate::camera::{Camera, Lens, Projection};
use crate::image::{Image, StokesImage, StokesRows};
use crate::sky::hosek::{HosekWilkie, SUN_RADIUS_RAD};
use crate::sky::{Lane, Sky, SkyLanes, Surroundings, LANES};
use glam::DVec3;
use rayon::prelude::*;

mod class;
mod grid;
mod ideal;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod world_tests;

pub use class::*;
pub use grid::*;
pub use ideal::*;

/// The sky as seen by one pixel, in the sensor frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSky {
    /// Radiance LI, W m⁻² sr⁻¹ nm⁻¹.
    pub li: f64,
    /// Degree of polarization, [0, 1].
    pub dop: f64,
    /// cos 2·AOP_s and sin 2·AOP_s (both 0 where DOP = 0 or invalid).
    pub cos2: f64,
    /// See `cos2`.
    pub sin2: f64,
    /// False for ground pixels.
    pub valid: bool,
}

impl PixelSky {
    /// AOP_s in degrees, [0, 180) (0 where undefined).
    pub fn aop_deg(&self) -> f64 {
        self.aop_deg_from(crate::vmath::atan2(self.sin2, self.cos2))
    }

    /// [`Self::aop_deg`] given `a` = atan2(sin2, cos2) (the ideal render computes a row of
    /// them in one loop).
    #[inline]
    fn aop_deg_from(&self, a: f64) -> f64 {
        if self.cos2 == 0.0 && self.sin2 == 0.0 {
            0.0
        } else {
            crate::angle::SensorAngle::from_deg(0.5 * a.to_degrees()).deg()
        }
    }
    /// Sensor-frame Stokes (S0, S1, S2) in radiance units.
    pub fn stokes(&self) -> [f64; 3] {
        let p = self.li * self.dop;
        [self.li, p * self.cos2, p * self.sin2]
    }
}

/// Samples the sky for the ray through the 0-based sub-pixel position (col, row). Outside a
/// fisheye's image circle no light arrives: all zero and invalid.
#[inline]
pub fn pixel_sky(sky: &Sky, cam: &Camera, col: f64, row: f64) -> PixelSky {
    if sky.surroundings().is_some() {
        // the world's lanes, one of them
        let mut l = ChunkLanes::new();
        l.col[0] = col;
        let mut out = [PixelSky::default()];
        sky_chunk(sky, cam, row, &mut l, &mut out);
        return out[0];
    }
    let Some(ray) = cam.intrinsics.ray(col, row) else {
        return PixelSky::default();
    };
    let d = (cam.enu_to_camera.transpose() * ray).normalize();
    let s = sky.sample(d);
    if !s.valid {
        // ground: zero, or the configured uniform unpolarized ground radiance (sky.md §8)
        return PixelSky {
            li: sky.params().ground_radiance.unwrap_or(0.0),
            ..PixelSky::default()
        };
    }
    let e = cam.enu_to_camera * s.e;
    let (ex, ey) = match cam.intrinsics.lens() {
        crate::camera::Lens::Pinhole => (e.x, e.y),
        l => l.sensor_vector(ray.normalize(), e),
    };
    let n2 = ex * ex + ey * ey;
    let (cos2, sin2) = if s.dop > 0.0 && n2 > 0.0 {
        ((ex * ex - ey * ey) / n2, 2.0 * ex * ey / n2)
    } else {
        (0.0, 0.0)
    };
    PixelSky {
        li: s.radiance,
        dop: s.dop,
        cos2,
        sin2,
        valid: true,
    }
}

/// [`pixel_sky`] for the pixels (col0 + k, row), k = 0..out.len(), into `out[k]`: the same
/// values bit for bit, by [`pixel_sky_cols`].
pub fn pixel_sky_row(sky: &Sky, cam: &Camera, row: usize, col0: usize, out: &mut [PixelSky]) {
    let cols: Vec<usize> = (col0..col0 + out.len()).collect();
    pixel_sky_cols(sky, cam, row, &cols, out);
}

/// [`pixel_sky`] for the pixels (cols[k], row) into `out[k]` (same length), the same values bit
/// for bit. Works on chunks of [`LANES`] pixels in structure-of-arrays form: camera geometry
/// and the lens in loops over the chunk, ground and dark pixels set aside before the sky
/// ([`Sky::sample_lanes`]), every transcendental ([`crate::vmath`]) one loop over the chunk, and
/// branches as selects; built for the CPU's instruction set (`simd_dispatch!`), the same bits in
/// each.
pub fn pixel_sky_cols(sky: &Sky, cam: &Camera, row: usize, cols: &[usize], out: &mut [PixelSky]) {
    assert_eq!(cols.len(), out.len());
    // (the fast path asks every row for its exact pixels; most have none)
    if !cols.is_empty() {
        sky_cols(sky, cam, row, cols, out);
    }
}

crate::simd::simd_dispatch! {
    /// [`sky_cols_body`] built for the best instruction set the CPU has.
    fn sky_cols = sky_cols_body(sky: &Sky, cam: &Camera, row: usize, cols: &[usize], out: &mut [PixelSky])
}

/// The arrays of one chunk of [`pixel_sky_cols`], made (zeroed) once per call.
struct ChunkLanes {
    /// Column of each lane.
    col: Lane,
    /// Camera-frame rays, as `Intrinsics::ray`.
    ray: [Lane; 3],
    /// Unit ENU view vectors.
    d: [Lane; 3],
    /// False outside a fisheye's image circle.
    lit: [bool; LANES],
    /// The sky's lanes (the pixels that see the sky, packed) ...
    sky: SkyLanes,
    /// ... their index in the chunk, their rays ...
    idx: [usize; LANES],
    ray_sky: [Lane; 3],
    /// ... the unit rays and camera-frame E-vectors (ideal lens) ...
    u: [Lane; 3],
    ec: [Lane; 3],
    /// ... √(u_x² + u_y²) (ideal lens) and the sensor-plane E-vector.
    h: Lane,
    ex: Lane,
    ey: Lane,
    /// With a world: the directions the sky is sampled in, and each lane's index among them.
    look: SkyLanes,
    look_idx: [usize; LANES],
}

impl ChunkLanes {
    fn new() -> Self {
        let z = [0.0; LANES];
        ChunkLanes {
            col: z,
            ray: [z; 3],
            d: [z; 3],
            lit: [true; LANES],
            sky: SkyLanes::default(),
            idx: [0; LANES],
            ray_sky: [z; 3],
            u: [z; 3],
            ec: [z; 3],
            h: z,
            ex: z,
            ey: z,
            look: SkyLanes::default(),
            look_idx: [0; LANES],
        }
    }
}

/// [`pixel_sky_cols`], a chunk of [`LANES`] pixels at a time.
#[inline(always)]
fn sky_cols_body(sky: &Sky, cam: &Camera, row: usize, cols: &[usize], out: &mut [PixelSky]) {
    thread_local! {
        /// One per thread: zeroing its ~25 kB per call cost more than the refined cells'
        /// short rows it evaluates.
        static LANES_BUF: std::cell::RefCell<Option<Box<ChunkLanes>>> =
            const { std::cell::RefCell::new(None) };
    }
    // taken out of the thread-local and put back: the loop stays in this function, built for
    // the caller's instruction set (a closure passed to `with` would be built for the baseline)
    let held = LANES_BUF.with(|cell| cell.try_borrow_mut().ok().and_then(|mut c| c.take()));
    let mut l = held.unwrap_or_else(|| Box::new(ChunkLanes::new()));
    // the fisheyes set this per lane; a pinhole's lanes are all lit
    l.lit = [true; LANES];
    for (cs, o) in cols.chunks(LANES).zip(out.chunks_mut(LANES)) {
        for (x, &c) in l.col.iter_mut().zip(cs) {
            *x = c as f64;
        }
        sky_chunk(sky, cam, row as f64, &mut l, o);
    }
    LANES_BUF.with(|cell| {
        if let Ok(mut c) = cell.try_borrow_mut() {
            *c = Some(l);
        }
    });
}

/// [`pixel_sky`] for the pixels (l.col[k], row), k = 0..out.len() ≤ [`LANES`].
#[inline(always)]
fn sky_chunk(sky: &Sky, cam: &Camera, row: f64, l: &mut ChunkLanes, out: &mut [PixelSky]) {
    let n = out.len();
    assert!(n <= LANES);
    let intr = &cam.intrinsics;
    let (m, mt) = (cam.enu_to_camera, cam.enu_to_camera.transpose());
    let (cols, ray, lit) = (&l.col, &mut l.ray, &mut l.lit);
    if intr.projection == Projection::Rectilinear {
        let (c0, r0) = intr.principal();
        let f = intr.focal_px();
        for j in 0..n {
            (ray[0][j], ray[1][j], ray[2][j]) = (cols[j] - c0, row - r0, f);
        }
    } else {
        // fisheyes: the projection's trigonometry stays scalar (libm)
        for j in 0..n {
            let r = intr.ray(cols[j], row);
            lit[j] = r.is_some();
            let r = r.unwrap_or(DVec3::Z);
            (ray[0][j], ray[1][j], ray[2][j]) = (r.x, r.y, r.z);
        }
    }
    let d = &mut l.d;
    for j in 0..n {
        let v = (mt * DVec3::new(ray[0][j], ray[1][j], ray[2][j])).normalize();
        (d[0][j], d[1][j], d[2][j]) = (v.x, v.y, v.z);
    }
    let (k, all_sky) = match sky.surroundings() {
        Some(w) => (world_lanes(sky, w, row, l, n), false),
        None => plain_lanes(sky, l, n),
    };
    let s = &l.sky;
    let pray = &l.ray_sky;
    // the E-vector into the camera frame and through the lens onto the sensor
    let (ex, ey) = (&mut l.ex, &mut l.ey);
    match intr.lens() {
        Lens::Pinhole => {
            for i in 0..k {
                let e = m * DVec3::new(s.e[0][i], s.e[1][i], s.e[2][i]);
                (ex[i], ey[i]) = (e.x, e.y);
            }
        }
        Lens::Ideal => {
            let (u, ec, h) = (&mut l.u, &mut l.ec, &mut l.h);
            for i in 0..k {
                let ui = DVec3::new(pray[0][i], pray[1][i], pray[2][i]).normalize();
                let e = m * DVec3::new(s.e[0][i], s.e[1][i], s.e[2][i]);
                (u[0][i], u[1][i], u[2][i]) = (ui.x, ui.y, ui.z);
                (ec[0][i], ec[1][i], ec[2][i]) = (e.x, e.y, e.z);
            }
            for i in 0..k {
                h[i] = crate::vmath::hypot(u[0][i], u[1][i]);
            }
            for i in 0..k {
                let ui = DVec3::new(u[0][i], u[1][i], u[2][i]);
                let e = DVec3::new(ec[0][i], ec[1][i], ec[2][i]);
                (ex[i], ey[i]) = Lens::ideal_sensor_vector(ui, e, h[i]);
            }
        }
    }
    // cos 2·AOP_s and sin 2·AOP_s in place of the sensor vector, one loop over the lanes
    for i in 0..k {
        let (x, y) = (ex[i], ey[i]);
        let n2 = x * x + y * y;
        (ex[i], ey[i]) = if s.dop[i] > 0.0 && n2 > 0.0 {
            ((x * x - y * y) / n2, 2.0 * x * y / n2)
        } else {
            (0.0, 0.0)
        };
    }
    let px = |i: usize| PixelSky {
        li: s.radiance[i],
        dop: s.dop[i],
        cos2: ex[i],
        sin2: ey[i],
        valid: true,
    };
    if all_sky {
        for (i, o) in out.iter_mut().enumerate() {
            *o = px(i);
        }
        return;
    }
    // ground (lit, below the horizon) and dark pixels, then the sky's
    let ground = PixelSky {
        li: sky.params().ground_radiance.unwrap_or(0.0),
        ..PixelSky::default()
    };
    for (o, &lit) in out.iter_mut().zip(l.lit.iter()) {
        *o = if lit { ground } else { PixelSky::default() };
    }
    for i in 0..k {
        out[l.idx[i]] = px(i);
    }
}

/// Packs the lanes of `l` that see the sky (as Sky::sample: v.z > 0, not NaN) with their rays
/// and samples the sky there: (lanes packed, whether all `n` are sky). A chunk that is all sky
/// (the usual case) is copied as it is.
#[inline(always)]
fn plain_lanes(sky: &Sky, l: &mut ChunkLanes, n: usize) -> (usize, bool) {
    let (d, ray, lit) = (&l.d, &l.ray, &l.lit);
    let (v, idx, pray) = (&mut l.sky.v, &mut l.idx, &mut l.ray_sky);
    let all_sky = (0..n).fold(true, |a, j| a & lit[j] & (d[2][j] > 0.0));
    let k = if all_sky {
        for a in 0..3 {
            v[a][..n].copy_from_slice(&d[a][..n]);
            pray[a][..n].copy_from_slice(&ray[a][..n]);
        }
        n
    } else {
        let mut k = 0;
        for j in 0..n {
            for a in 0..3 {
                v[a][k] = d[a][j];
                pray[a][k] = ray[a][j];
            }
            idx[k] = j;
            k += (lit[j] && d[2][j] > 0.0) as usize;
        }
        k
    };
    l.sky.n = k;
    sky.sample_lanes(&mut l.sky);
    (k, all_sky)
}

/// [`plain_lanes`] with a world around the camera: each lit lane's ray is traced
/// ([`Surroundings::look`]), the sky sampled where it is seen (along the ray, or mirrored by
/// glass), and the lanes that see anything but the ground packed with their light. Pixels the
/// camera mask blocks are black.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // the lanes of several arrays side by side
fn world_lanes(sky: &Sky, w: &Surroundings, row: f64, l: &mut ChunkLanes, n: usize) -> usize {
    let mut looks: [Option<crate::sky::surroundings::Look>; LANES] = [None; LANES];
    let mut m = 0;
    for j in 0..n {
        if !l.lit[j] {
            continue;
        }
        let dj = DVec3::new(l.d[0][j], l.d[1][j], l.d[2][j]);
        if dj.is_nan() {
            continue;
        }
        let lk = w.look(dj);
        if let Some(v) = lk.sample {
            (l.look.v[0][m], l.look.v[1][m], l.look.v[2][m]) = (v.x, v.y, v.z);
            l.look_idx[j] = m;
            m += 1;
        }
        looks[j] = Some(lk);
    }
    l.look.n = m;
    sky.sample_lanes(&mut l.look);
    let ground = sky.params().ground_radiance.unwrap_or(0.0);
    let (wd, hd) = w.world().mask_size().unwrap_or((1, 1));
    let r = (row.round().max(0.0) as usize).min(hd - 1);
    let mut k = 0;
    for j in 0..n {
        let Some(lk) = looks[j] else {
            continue;
        };
        let dj = DVec3::new(l.d[0][j], l.d[1][j], l.d[2][j]);
        let c = (l.col[j].round().max(0.0) as usize).min(wd - 1);
        let light = if !w.world().open(c, r) {
            Some(crate::world::optics::Light {
                radiance: 0.0,
                dop: 0.0,
                e: crate::world::optics::horizontal_across(dj),
            })
        } else {
            let s = match lk.sample {
                Some(_) => {
                    let i = l.look_idx[j];
                    crate::sky::SkySample {
                        valid: true,
                        gamma_rad: 0.0,
                        radiance: l.look.radiance[i],
                        dop: l.look.dop[i],
                        e: DVec3::new(l.look.e[0][i], l.look.e[1][i], l.look.e[2][i]),
                    }
                }
                None => crate::sky::SkySample::GROUND,
            };
            w.shade(dj, &lk, &s, ground)
        };
        if let Some(li) = light {
            l.sky.radiance[k] = li.radiance;
            l.sky.dop[k] = li.dop;
            (l.sky.e[0][k], l.sky.e[1][k], l.sky.e[2][k]) = (li.e.x, li.e.y, li.e.z);
            for a in 0..3 {
                l.ray_sky[a][k] = l.ray[a][j];
            }
            l.idx[k] = j;
            k += 1;
        }
    }
    k
}
