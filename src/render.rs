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
use crate::sky::{Lane, Sky, SkyLanes, LANES};
use glam::DVec3;
use rayon::prelude::*;

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
}

/// [`pixel_sky_cols`], a chunk of [`LANES`] pixels at a time.
#[inline(always)]
fn sky_cols_body(sky: &Sky, cam: &Camera, row: usize, cols: &[usize], out: &mut [PixelSky]) {
    let z = [0.0; LANES];
    let mut l = ChunkLanes {
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
    };
    for (cs, o) in cols.chunks(LANES).zip(out.chunks_mut(LANES)) {
        for (x, &c) in l.col.iter_mut().zip(cs) {
            *x = c as f64;
        }
        sky_chunk(sky, cam, row as f64, &mut l, o);
    }
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
    // pack the lanes that see the sky (as Sky::sample: v.z > 0, not NaN), with their rays; a
    // chunk that is all sky (the usual case) is copied as it is
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
    let s = &l.sky;
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
    for (o, &lit) in out.iter_mut().zip(lit.iter()) {
        *o = if lit { ground } else { PixelSky::default() };
    }
    for i in 0..k {
        out[idx[i]] = px(i);
    }
}

/// LI, DOP, AOP and validity images.
#[derive(Clone, Debug)]
pub struct IdealImages {
    /// Radiance, W m⁻² sr⁻¹ nm⁻¹.
    pub li: Image<f32>,
    /// DOP in [0, 1].
    pub dop: Image<f32>,
    /// AOP_s in degrees, [0, 180), from +x toward +y.
    pub aop_deg: Image<f32>,
    /// 1 = sky, 0 = ground.
    pub valid: Image<u8>,
}

/// Renders LI, DOP and AOP at every pixel centre.
pub fn render_ideal(sky: &Sky, cam: &Camera) -> IdealImages {
    render_ideal_rows(sky, cam, None)
}

/// [`render_ideal`] and the four polarizer images of [`polarizer_images`] in one pass. Here
/// eq. (24) is evaluated from the pixel's f64 Stokes vector, LI(α) = ½ (S0 + S1 cos 2α + S2 sin 2α)
/// with cos 2α, sin 2α ∈ {0, ±1} (the same value as ½ LI [1 + DOP cos 2(AOP − α)]), instead of
/// from the stored f32 images: no cosine per pixel, and no rounding of AOP to f32 degrees first
/// (the two agree to within a few f32 steps; tested).
pub fn render_ideal_polarizers(sky: &Sky, cam: &Camera) -> (IdealImages, [Image<f32>; 4]) {
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let mut pol: [Image<f32>; 4] = std::array::from_fn(|_| Image::new(w, h));
    let ideal = render_ideal_rows(sky, cam, Some(&mut pol));
    (ideal, pol)
}

fn render_ideal_rows(sky: &Sky, cam: &Camera, pol: Option<&mut [Image<f32>; 4]>) -> IdealImages {
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let mut out = IdealImages {
        li: Image::new(w, h),
        dop: Image::new(w, h),
        aop_deg: Image::new(w, h),
        valid: Image::new(w, h),
    };
    let with_pol = pol.is_some();
    // without polarizer images, four dummy rows of one value each stand in (never written)
    let mut none: [Vec<f32>; 4] = Default::default();
    let (pw, [p0, p45, p90, p135]) = match pol {
        Some([a, b, c, d]) => (w, [&mut a.data, &mut b.data, &mut c.data, &mut d.data]),
        None => {
            let [a, b, c, d] = &mut none;
            for v in [&mut *a, &mut *b, &mut *c, &mut *d] {
                v.resize(h, 0.0);
            }
            (1, [a, b, c, d])
        }
    };
    (
        out.li.data.par_chunks_mut(w),
        out.dop.data.par_chunks_mut(w),
        out.aop_deg.data.par_chunks_mut(w),
        out.valid.data.par_chunks_mut(w),
        p0.par_chunks_mut(pw),
        p45.par_chunks_mut(pw),
        p90.par_chunks_mut(pw),
        p135.par_chunks_mut(pw),
    )
        .into_par_iter()
        .enumerate()
        .for_each(|(r, (li, dop, aop, valid, i0, i45, i90, i135))| {
            let mut px = vec![PixelSky::default(); w];
            pixel_sky_row(sky, cam, r, 0, &mut px);
            let mut two_aop = vec![0.0; w];
            two_aop_row(&px, &mut two_aop);
            for (c, p) in px.iter().enumerate() {
                li[c] = p.li as f32;
                dop[c] = p.dop as f32;
                aop[c] = p.aop_deg_from(two_aop[c]) as f32;
                valid[c] = p.valid as u8;
                if with_pol {
                    let [s0, s1, s2] = p.stokes();
                    i0[c] = (0.5 * (s0 + s1)) as f32;
                    i45[c] = (0.5 * (s0 + s2)) as f32;
                    i90[c] = (0.5 * (s0 - s1)) as f32;
                    i135[c] = (0.5 * (s0 - s2)) as f32;
                }
            }
        });
    out
}

crate::simd::simd_dispatch! {
    /// atan2(sin2, cos2) = 2 AOP_s (radians) of every pixel, for the AOP image.
    fn two_aop_row = two_aop_row_body(px: &[PixelSky], out: &mut [f64])
}

#[inline(always)]
fn two_aop_row_body(px: &[PixelSky], out: &mut [f64]) {
    for (o, p) in out.iter_mut().zip(px) {
        *o = crate::vmath::atan2(p.sin2, p.cos2);
    }
}

/// Options for the Stokes render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StokesOptions {
    /// Add the unpolarized, limb-darkened solar disc (Hosek–Wilkie solar radiance), area-averaged
    /// with 4 × 4 sub-samples within r_sun + 2 IFOV of the sun (`sky.md` §8).
    pub sun_disc: bool,
}

/// Sensor-frame Stokes planes (radiance units) at every pixel centre, plus how many pixels see
/// part of the sun disc.
pub fn render_stokes(sky: &Sky, cam: &Camera, opts: StokesOptions) -> (StokesImage, usize) {
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let mut out = StokesImage::zeros(w, h);
    let cols: Vec<usize> = (0..w).collect();
    out.par_rows(|r, s0, s1, s2| stokes_at(sky, cam, r, &cols, [s0, s1, s2]));
    let n_sun = if opts.sun_disc {
        add_sun_disc(sky, cam, &mut out)
    } else {
        0
    };
    (out, n_sun)
}

/// The exact sky's S0, S1, S2 (f32) of the pixels (c, r), c in `cols`, into `s[p][c]`, by the
/// row evaluator ([`pixel_sky_cols`]). `cols` ascend; when they are the whole row the planes
/// are written in order (a loop without an index per pixel; the same values).
fn stokes_at(sky: &Sky, cam: &Camera, r: usize, cols: &[usize], s: [&mut [f32]; 3]) {
    thread_local! {
        /// The row's pixels: one buffer per thread, grown as needed, not a new one per row
        /// (`pixel_sky_cols` writes every element it is given).
        static PX: std::cell::RefCell<Vec<PixelSky>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    let [s0, s1, s2] = s;
    PX.with_borrow_mut(|buf| {
        if buf.len() < cols.len() {
            buf.resize(cols.len(), PixelSky::default());
        }
        let px = &mut buf[..cols.len()];
        pixel_sky_cols(sky, cam, r, cols, px);
        let w = s0.len();
        if cols.len() == w {
            // w ascending columns below w are 0..w: checked whole in debug builds, by the ends
            // in release
            assert!(cols.first() == Some(&0) && cols.last() == Some(&(w - 1)));
            debug_assert!(cols.iter().enumerate().all(|(i, &c)| i == c));
            stokes_row(px, [s0, s1, s2]);
        } else {
            for (&c, p) in cols.iter().zip(px.iter()) {
                let [a, b, d] = p.stokes();
                (s0[c], s1[c], s2[c]) = (a as f32, b as f32, d as f32);
            }
        }
    });
}

/// [`PixelSky::stokes`] of every pixel of a row into the planes, in order.
#[inline(always)]
fn stokes_row_body(px: &[PixelSky], s: [&mut [f32]; 3]) {
    let [s0, s1, s2] = s;
    for (((p, a), b), d) in px.iter().zip(s0).zip(s1).zip(s2) {
        let [x, y, z] = p.stokes();
        (*a, *b, *d) = (x as f32, y as f32, z as f32);
    }
}

crate::simd::simd_dispatch! {
    /// [`stokes_row_body`] built for the best instruction set the CPU has (the same values:
    /// two products and three conversions per pixel, none fused).
    fn stokes_row = stokes_row_body(px: &[PixelSky], s: [&mut [f32]; 3])
}

/// Adds the solar disc to S0 where it is in view; returns the number of pixels touched.
fn add_sun_disc(sky: &Sky, cam: &Camera, st: &mut StokesImage) -> usize {
    let px = sun_disc_pixels(sky, cam);
    for &(i, add) in &px {
        st.s0.data[i] += add;
    }
    px.len()
}

/// The solar disc's radiance per pixel it touches, (pixel index, radiance), sorted by index:
/// the limb-darkened Hosek–Wilkie solar radiance averaged over 4 × 4 sub-samples within
/// r_sun + 2 IFOV of the sun. None under an overcast CIE sky ([`Sky::sun_visible`]).
fn sun_disc_pixels(sky: &Sky, cam: &Camera) -> Vec<(usize, f32)> {
    if !sky.sun_visible() {
        return Vec::new();
    }
    let p = sky.params();
    let Ok(hw) = HosekWilkie::new(
        p.turbidity,
        p.albedo,
        sky.sun().elevation_deg().to_radians(),
        p.wavelength_nm,
    ) else {
        return Vec::new();
    };
    let s_enu = sky.sun().vector();
    let s_c = cam.enu_to_camera * s_enu;
    let Some((sc, sr)) = cam.intrinsics.project(s_c) else {
        return Vec::new();
    };
    // A pixel subtends less angle off axis (rectilinear: radially by cos²ϕ), so the disc spans
    // more pixels: radial extent of r_sun + 2 IFOV is (r_sun f + 2) / cos²ϕ pixels, plus one for
    // rounding; a fisheye's magnification is the larger of its radial and tangential scales.
    let f = cam.intrinsics.focal_px();
    let cos_phi = s_c.normalize().z;
    let proj = cam.intrinsics.projection;
    let reach = if proj == crate::camera::Projection::Rectilinear {
        (SUN_RADIUS_RAD * f + 2.0) / (cos_phi * cos_phi) + 1.0
    } else {
        let th = cos_phi.clamp(-1.0, 1.0).acos();
        let mag = proj
            .radial_scale(th)
            .max(proj.tangential_scale(th))
            .max(1.0);
        (SUN_RADIUS_RAD * f + 2.0) * mag + 1.0
    };
    let (wu, hu) = (cam.intrinsics.width, cam.intrinsics.height);
    let (w, h) = (wu as f64, hu as f64);
    let c0 = (sc - reach).floor().max(0.0);
    let c1 = (sc + reach).ceil().min(w - 1.0);
    let r0 = (sr - reach).floor().max(0.0);
    let r1 = (sr + reach).ceil().min(h - 1.0);
    let mut out = Vec::new();
    if c0 > c1 || r0 > r1 {
        return out;
    }
    for r in r0 as usize..=r1 as usize {
        for c in c0 as usize..=c1 as usize {
            let mut acc = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let Some(d): Option<DVec3> = cam.pixel_direction(
                        c as f64 - 0.375 + 0.25 * sx as f64,
                        r as f64 - 0.375 + 0.25 * sy as f64,
                    ) else {
                        continue; // outside a fisheye's image circle
                    };
                    let g = d.dot(s_enu).clamp(-1.0, 1.0).acos();
                    acc += hw.sun_radiance(g);
                }
            }
            if acc > 0.0 {
                out.push((r * wu + c, (acc / 16.0) as f32));
            }
        }
    }
    out
}

/// The four polarizer-direction images LI(α) = ½ LI [1 + DOP cos 2(AOP − α)] (PSNS eq. (24)
/// before κ), for α = 0°, 45°, 90°, 135°.
pub fn polarizer_images(ideal: &IdealImages) -> [Image<f32>; 4] {
    let (w, h) = (ideal.li.width, ideal.li.height);
    let mut out: [Image<f32>; 4] = std::array::from_fn(|_| Image::new(w, h));
    for (k, img) in out.iter_mut().enumerate() {
        let a = (45.0 * k as f64).to_radians();
        img.data.par_iter_mut().enumerate().for_each(|(i, v)| {
            let li = ideal.li.data[i] as f64;
            let dop = ideal.dop.data[i] as f64;
            let aop = (ideal.aop_deg.data[i] as f64).to_radians();
            *v = (0.5 * li * (1.0 + dop * (2.0 * (aop - a)).cos())) as f32;
        });
    }
    out
}

/// κ mapping the brightest value of the four polarizer images to `full_scale`, and the scaled,
/// rounded images (eq. (24)).
pub fn quantize_polarizer_images(
    imgs: &[Image<f32>; 4],
    full_scale: f64,
) -> (f64, [Image<u16>; 4]) {
    // f32::max ignores NaN; the maximum is exact in any order
    let max = imgs
        .iter()
        .map(|i| i.data.par_iter().copied().reduce(|| 0.0f32, f32::max))
        .fold(0.0f32, f32::max) as f64;
    let kappa = if max > 0.0 { full_scale / max } else { 0.0 };
    // round(v κ) clipped to [0, full scale] and to u16
    let q = std::array::from_fn(|k| {
        let i = &imgs[k];
        let mut data = vec![0u16; i.data.len()];
        data.par_chunks_mut(i.width.max(1))
            .zip(i.data.par_chunks(i.width.max(1)))
            .for_each(|(o, v)| quantize_row(v, kappa, full_scale, o));
        Image::from_vec(i.width, i.height, data)
    });
    (kappa, q)
}

crate::simd::simd_dispatch! {
    /// [`quantize_row_body`] built for the best instruction set the CPU has.
    fn quantize_row = quantize_row_body(src: &[f32], kappa: f64, hi: f64, out: &mut [u16])
}

/// [`crate::image::round_clamp`]`(v κ, hi)` of a row, clipped to u16 (`hi` is taken into
/// [0, 65 535] first), its operations through i32 (the same values in that range) so that the
/// loop vectorises: 8 images of 5 M pixels in `psns render`.
#[inline(always)]
fn quantize_row_body(src: &[f32], kappa: f64, hi: f64, out: &mut [u16]) {
    // round_clamp's bounds: a negative hi clips everything to 0, a NaN one does not clip (here:
    // to u16 only)
    let hi = if hi.is_nan() {
        65_535.0
    } else {
        hi.clamp(0.0, 65_535.0)
    };
    for (o, &v) in out.iter_mut().zip(src) {
        // max ignores NaN: NaN becomes 0
        let x = (v as f64 * kappa).max(0.0).min(hi);
        // SAFETY: x is in [0, 65 535], so the truncation fits i32 (and, unlike `as`, needs no
        // saturation code, which kept the loop from vectorising)
        let t = unsafe { x.to_int_unchecked::<i32>() };
        *o = (t + (x - t as f64 >= 0.5) as i32) as u16;
    }
}

/// Pixels whose ray points at or below the horizon (inside the image circle of a fisheye). In a
/// rectilinear camera the ray's ENU up component is linear along a row, so each row is counted
/// from where it changes sign; fisheyes are counted pixel by pixel.
pub fn ground_pixel_count(cam: &Camera) -> usize {
    let i = &cam.intrinsics;
    let (w, h) = (i.width, i.height);
    if i.projection != crate::camera::Projection::Rectilinear {
        return (0..h)
            .into_par_iter()
            .map(|r| {
                (0..w)
                    .filter(|&c| {
                        cam.pixel_direction(c as f64, r as f64)
                            .is_some_and(|d| d.z <= 0.0)
                    })
                    .count()
            })
            .sum();
    }
    // up component of the ENU direction of ray(c, r) = m · (c − c0, r − r0, f)
    let m = cam.enu_to_camera.transpose().row(2);
    let (c0, r0) = i.principal();
    let f = i.focal_px();
    (0..h)
        .map(|r| {
            let a = m.y * (r as f64 - r0) + m.z * f - m.x * c0; // z(c) = a + m.x c
            if m.x == 0.0 {
                if a <= 0.0 {
                    w
                } else {
                    0
                }
            } else {
                let cross = -a / m.x; // z(cross) = 0
                if m.x > 0.0 {
                    // z ≤ 0 for c ≤ cross
                    ((cross.floor() + 1.0).clamp(0.0, w as f64)) as usize
                } else {
                    // z ≤ 0 for c ≥ cross
                    w - (cross.ceil().clamp(0.0, w as f64)) as usize
                }
            }
        })
        .sum()
}

/// Relative interpolation tolerance of [`render_stokes_grid`]: estimated error at most this
/// fraction of S0 (a tenth of the shot noise of a full 10 500 e⁻ well is 1e-3).
pub const GRID_TOLERANCE: f64 = 2.5e-4;

/// Sensor-frame Stokes planes from a [`SkyGrid`] (`step` = 1: the exact render).
pub fn render_stokes_grid(
    sky: &Sky,
    cam: &Camera,
    opts: StokesOptions,
    step: usize,
) -> (StokesImage, usize) {
    if step <= 1 {
        return render_stokes(sky, cam, opts);
    }
    let g = SkyGrid::new(sky, cam, opts, step, GRID_TOLERANCE);
    (g.to_image(), g.sun_pixels())
}

/// A refined cell: nodes every `step` pixels (the last at the cell's far edge), and per sub-cell
/// whether it is evaluated exactly at every pixel.
#[derive(Clone, Debug)]
struct SubGrid {
    /// The coarse cell's column index (its row is the band holding it in `SkyGrid::band_subs`).
    cell: usize,
    /// Node spacing (the last interval of each axis may be shorter).
    step: usize,
    cols: Vec<usize>,
    rows: Vec<usize>,
    nodes: Vec<[f32; 3]>,
    exact: Vec<bool>,
}

/// The sky on a coarse grid of pixel nodes, refined where bilinear interpolation would be off by
/// more than `tol` · S0 and evaluated exactly where a cell straddles the horizon.
///
/// Nodes sit every `step` pixels (and on the last row and column). The interpolation error of a
/// cell is estimated from the second differences of the node values at its corners,
/// (|Δ²ₓ| + |Δ²ᵧ|)/8 summed over S0, S1, S2 (the bound for bilinear interpolation of a function
/// with those second derivatives). A cell above tolerance gets sub-nodes every `step`/4 pixels
/// and the same test per sub-cell; sub-cells still above it, and all sub-cells with a corner on
/// the ground, are evaluated at every pixel. In a pinhole camera the horizon is a straight line,
/// so a cell whose four corners see sky sees only sky. The solar disc is added exactly, as in
/// [`render_stokes`]. Rows are produced on demand ([`StokesRows`]); the measured cost and error
/// are in `docs/performance.md`.
pub struct SkyGrid<'a> {
    /// Node spacing (the last interval of each axis may be shorter).
    step: usize,
    sky: &'a Sky,
    cam: &'a Camera,
    width: usize,
    height: usize,
    cols: Vec<usize>,
    rows: Vec<usize>,
    nodes: Vec<[f32; 3]>,
    /// The refined cells, in row-major order of the coarse cells.
    subs: Vec<SubGrid>,
    /// The refined cells of band j (coarse cell row j) are `subs[band_subs[j]..band_subs[j + 1]]`.
    band_subs: Vec<usize>,
    /// Solar disc additions to S0: (pixel index, radiance), sorted by index.
    disc: Vec<(usize, f32)>,
    exact_pixels: usize,
}

/// Node positions 0, step, 2 step, … and always n − 1.
fn grid_nodes(start: usize, end: usize, step: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (start..=end).step_by(step.max(1)).collect();
    if *v.last().unwrap() != end {
        v.push(end);
    }
    v
}

/// Per node, the interpolation-error estimate (|Δ²ₓ| + |Δ²ᵧ|)/8 summed over the planes;
/// one-sided at the edges (the neighbour's second difference); infinite along an axis with fewer
/// than three nodes.
fn curvature(nodes: &[[f32; 3]], gw: usize, gh: usize) -> Vec<f32> {
    let at = |i: usize, j: usize| nodes[j * gw + i];
    let d2 = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| -> f32 {
        (0..3).map(|k| (a[k] - 2.0 * b[k] + c[k]).abs()).sum()
    };
    let mut out = vec![0f32; gw * gh];
    out.par_chunks_mut(gw.max(1))
        .enumerate()
        .for_each(|(j, row)| {
            for (i, o) in row.iter_mut().enumerate() {
                // with fewer than three nodes along an axis the curvature is unknown: infinite, so
                // the cell is refined rather than trusted
                let dx = if gw < 3 {
                    f32::INFINITY
                } else {
                    let m = i.clamp(1, gw - 2);
                    d2(at(m - 1, j), at(m, j), at(m + 1, j))
                };
                let dy = if gh < 3 {
                    f32::INFINITY
                } else {
                    let m = j.clamp(1, gh - 2);
                    d2(at(i, m - 1), at(i, m), at(i, m + 1))
                };
                *o = (dx + dy) / 8.0;
            }
        });
    out
}

/// Whether the sky seen within `span` pixels of (col, row) is certainly free of the horizon and of
/// a fisheye's image-circle rim, judged by angle: the pixel's angular distance from either must
/// exceed the angle `span` pixels can cover there (√2 span times the larger of the radial and
/// tangential angle per pixel, with a factor 1.5 for its change across the cell). Only for
/// fisheyes: in a rectilinear camera the horizon is a straight line and a cell whose corners see
/// sky sees only sky.
fn clear_of_edges(cam: &Camera, col: usize, row: usize, span: usize) -> bool {
    let i = &cam.intrinsics;
    let Some(ray) = i.ray(col as f64, row as f64) else {
        return false;
    };
    let theta = ray.x.hypot(ray.y).atan2(ray.z);
    let p = i.projection;
    let per_px = 1.0 / (i.focal_px() * p.radial_scale(theta).min(p.tangential_scale(theta)));
    let margin = 1.5 * std::f64::consts::SQRT_2 * span as f64 * per_px;
    let up = (cam.enu_to_camera.transpose() * ray)
        .z
        .clamp(-1.0, 1.0)
        .asin();
    std::f64::consts::FRAC_PI_2 - theta > margin && up > margin
}

/// Whether the cell (i, j) of a node grid needs more than bilinear interpolation.
fn cell_needs_more(
    nodes: &[[f32; 3]],
    valid: &[bool],
    curv: &[f32],
    gw: usize,
    i: usize,
    j: usize,
    tol: f32,
) -> bool {
    let k = [
        j * gw + i,
        j * gw + i + 1,
        (j + 1) * gw + i,
        (j + 1) * gw + i + 1,
    ];
    if !k.iter().all(|&k| valid[k]) {
        return true;
    }
    let s0min = k.iter().map(|&k| nodes[k][0]).fold(f32::MAX, f32::min);
    let err = k.iter().map(|&k| curv[k]).fold(0f32, f32::max);
    err.is_nan() || err > tol * s0min
}

impl<'a> SkyGrid<'a> {
    /// Evaluates the nodes and refines (see the type docs). `step` ≥ 2.
    pub fn new(sky: &'a Sky, cam: &'a Camera, opts: StokesOptions, step: usize, tol: f64) -> Self {
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let step = step.max(2);
        let (cols, rows) = (grid_nodes(0, w - 1, step), grid_nodes(0, h - 1, step));
        let (gw, gh) = (cols.len(), rows.len());
        let sub_step = (step / 4).max(1);
        // fisheyes: a node near the horizon or the image-circle rim counts as invalid, so the
        // cells around it are refined and evaluated exactly (`clear_of_edges`)
        let fisheye = cam.intrinsics.projection != crate::camera::Projection::Rectilinear;
        // the nodes (cols[k], r) of one row: Stokes and whether to trust them
        let eval_row = |r: usize, cols: &[usize], span: usize| -> Vec<([f32; 3], bool)> {
            let mut px = vec![PixelSky::default(); cols.len()];
            pixel_sky_cols(sky, cam, r, cols, &mut px);
            px.iter()
                .zip(cols)
                .map(|(p, &c)| {
                    let [a, b, d] = p.stokes();
                    let ok = p.valid && (!fisheye || clear_of_edges(cam, c, r, span));
                    ([a as f32, b as f32, d as f32], ok)
                })
                .collect()
        };
        // the solar disc (sequential) beside the nodes and their refinement
        let ((nodes, band_subs, subs, exact_pixels), disc) = rayon::join(
            || {
                let evaluated: Vec<([f32; 3], bool)> = rows
                    .par_iter()
                    // small tasks, for the same reason as the sensor pass's bands
                    .with_max_len(2)
                    .flat_map_iter(|&r| eval_row(r, &cols, step))
                    .collect();
                let nodes: Vec<[f32; 3]> = evaluated.iter().map(|e| e.0).collect();
                let valid: Vec<bool> = evaluated.iter().map(|e| e.1).collect();
                let curv = curvature(&nodes, gw, gh);
                let tol = tol as f32;
                let mut flagged = Vec::new();
                let bands = gh.max(2) - 1;
                if gw >= 2 && gh >= 2 {
                    // the test per cell in parallel, the numbering of the flagged ones in order
                    let mut more = vec![false; (gw - 1) * bands];
                    more.par_chunks_mut(gw - 1)
                        .enumerate()
                        .for_each(|(j, row)| {
                            for (i, m) in row.iter_mut().enumerate() {
                                *m = cell_needs_more(&nodes, &valid, &curv, gw, i, j, tol);
                            }
                        });
                    for (k, _) in more.iter().enumerate().filter(|(_, &m)| m) {
                        flagged.push((k % (gw - 1), k / (gw - 1)));
                    }
                }
                // flagged is in row-major order: each band's cells are one run
                let band_subs: Vec<usize> = (0..=bands)
                    .map(|j| flagged.partition_point(|&(_, fj)| fj < j))
                    .collect();
                let subs: Vec<SubGrid> = flagged
                    .par_iter()
                    .map(|&(i, j)| {
                        let sc = grid_nodes(cols[i], cols[i + 1], sub_step);
                        let sr = grid_nodes(rows[j], rows[j + 1], sub_step);
                        let (sw, sh) = (sc.len(), sr.len());
                        let ev: Vec<([f32; 3], bool)> = sr
                            .iter()
                            .flat_map(|&r| eval_row(r, &sc, sub_step))
                            .collect();
                        let sn: Vec<[f32; 3]> = ev.iter().map(|e| e.0).collect();
                        let sv: Vec<bool> = ev.iter().map(|e| e.1).collect();
                        let scurv = curvature(&sn, sw, sh);
                        let mut exact = vec![true; (sw - 1) * (sh - 1)];
                        if sub_step > 1 {
                            for jj in 0..sh - 1 {
                                for ii in 0..sw - 1 {
                                    exact[jj * (sw - 1) + ii] =
                                        cell_needs_more(&sn, &sv, &scurv, sw, ii, jj, tol);
                                }
                            }
                        }
                        SubGrid {
                            cell: i,
                            step: sub_step,
                            cols: sc,
                            rows: sr,
                            nodes: sn,
                            exact,
                        }
                    })
                    .collect();
                let exact_pixels = subs
                    .iter()
                    .map(|s| {
                        let sw = s.cols.len();
                        s.exact
                            .iter()
                            .enumerate()
                            .filter(|(_, &e)| e)
                            .map(|(k, _)| {
                                let (ii, jj) = (k % (sw - 1), k / (sw - 1));
                                (s.cols[ii + 1] - s.cols[ii]) * (s.rows[jj + 1] - s.rows[jj])
                            })
                            .sum::<usize>()
                    })
                    .sum();
                (nodes, band_subs, subs, exact_pixels)
            },
            || {
                if opts.sun_disc {
                    sun_disc_pixels(sky, cam)
                } else {
                    Vec::new()
                }
            },
        );
        SkyGrid {
            step,
            sky,
            cam,
            width: w,
            height: h,
            cols,
            rows,
            nodes,
            subs,
            band_subs,
            disc,
            exact_pixels,
        }
    }

    /// Pixels touched by the solar disc.
    pub fn sun_pixels(&self) -> usize {
        self.disc.len()
    }

    /// Coarse nodes evaluated.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Refined cells, sub-grid nodes evaluated, and pixels evaluated exactly (about: sub-cell
    /// edges shared by neighbours are counted once per cell).
    pub fn refinement(&self) -> (usize, usize, usize) {
        (
            self.subs.len(),
            self.subs.iter().map(|s| s.nodes.len()).sum(),
            self.exact_pixels,
        )
    }

    /// The whole image.
    pub fn to_image(&self) -> StokesImage {
        let mut out = StokesImage::zeros(self.width, self.height);
        out.par_rows(|r, a, b, c| self.fill_row(r, a, b, c));
        out
    }

    /// Index of the node interval holding `x` in `nodes` (the last interval holds the end).
    #[inline]
    fn interval(nodes: &[usize], step: usize, x: usize) -> usize {
        (x / step).min(nodes.len() - 2)
    }
}

/// Fills `out[k]` for columns c0..c_end of one row by linear interpolation between `left` (at c0)
/// and `right` (at c1).
#[inline(always)]
fn lerp_span(
    out: [&mut [f32]; 3],
    left: [f32; 3],
    right: [f32; 3],
    c0: usize,
    c1: usize,
    c_end: usize,
) {
    // x as f32 read from a table, so that the loop vectorises (the same values)
    const XS: [f32; 64] = {
        let mut t = [0f32; 64];
        let mut i = 0;
        while i < 64 {
            t[i] = i as f32;
            i += 1;
        }
        t
    };
    let inv = 1.0 / (c1 - c0) as f32;
    for (k, o) in out.into_iter().enumerate() {
        let (l, d) = (left[k], right[k] - left[k]);
        let o = &mut o[c0..c_end];
        if o.len() <= XS.len() {
            for (v, &x) in o.iter_mut().zip(&XS) {
                *v = l + d * (x * inv);
            }
        } else {
            for (x, v) in o.iter_mut().enumerate() {
                *v = l + d * (x as f32 * inv);
            }
        }
    }
}

/// The full-width cells 0..gw − 2 of row band `j` (columns 0..`full`): each plane bilinear
/// between the nodes of rows j and j + 1 (weight `fy`), `fx[x]` = x/step across a cell; the
/// same arithmetic as `lerp3` then `lerp_span`, one plane at a time.
#[allow(clippy::too_many_arguments)]
fn interp_cells(
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    nodes: &[[f32; 3]],
    gw: usize,
    j: usize,
    fy: f32,
    fx: &[f32],
    full: usize,
) {
    let (top, bottom) = (
        nodes[j * gw..(j + 1) * gw].as_flattened(),
        nodes[(j + 1) * gw..(j + 2) * gw].as_flattened(),
    );
    // the row's node values and their differences to the next node, all planes interleaved
    // (v[3i + p], d[3i + p]), in two loops over whole vectors: a cell then needs two broadcasts
    // (a per-thread buffer: neither an allocation nor zeroing per row)
    thread_local! {
        static NODE_ROW: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    NODE_ROW.with_borrow_mut(|buf| {
        let n = top.len();
        if buf.len() < 2 * n {
            buf.resize(2 * n, 0.0);
        }
        let (v, d) = buf.split_at_mut(n);
        let (v, d) = (&mut v[..n], &mut d[..n]);
        for k in 0..n {
            v[k] = top[k] + (bottom[k] - top[k]) * fy;
        }
        for k in 0..n - 3 {
            d[k] = v[k + 3] - v[k];
        }
        interp_planes([s0, s1, s2], v, d, fx, full);
    });
}

/// The planes of [`interp_cells`] from the node row `v` and its differences `d`.
fn interp_planes(s: [&mut [f32]; 3], v: &[f32], d: &[f32], fx: &[f32], full: usize) {
    for (p, out) in s.into_iter().enumerate() {
        let out = &mut out[..full];
        // the default grid's 16-pixel cells as whole vectors, written out: left to itself the
        // loop vectoriser spreads the cells over the lanes and scatters (slower than scalar)
        match <&[f32; 16]>::try_from(fx) {
            Ok(fx) => interp16(out, v, d, p, fx),
            Err(_) => interp_plane(out, v, d, p, fx),
        }
    }
}

crate::simd_dispatch! {
    /// [`interp_plane`] for 16-pixel cells.
    fn interp16 = {
        avx512: interp16_avx512,
        avx2: interp16_avx2,
        plain: interp16_plain,
    }(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16])
}

fn interp16_plain(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    interp_plane(out, v, d, p, fx);
}

/// One plane of [`interp_cells`], any cell width (`fx.len()`): cell i is v[3i + p] +
/// d[3i + p] · fx.
fn interp_plane(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32]) {
    for (i, chunk) in out.chunks_exact_mut(fx.len()).enumerate() {
        let (l, d) = (v[3 * i + p], d[3 * i + p]);
        for (o, &f) in chunk.iter_mut().zip(fx) {
            *o = l + d * f;
        }
    }
}

/// [`interp_plane`] for 16-pixel cells, one AVX-512 vector per cell (separate multiply and add,
/// as the scalar code: the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn interp16_avx512(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    use std::arch::x86_64::*;
    let cells = out.len() / 16;
    assert!(p < 3 && 3 * cells <= d.len() && d.len() <= v.len());
    // SAFETY: 16 floats read from `fx` and written to each of the `cells` 16-float chunks of
    // `out`; v and d read at 3i + p < 3 cells ≤ d.len() ≤ v.len() (asserted)
    unsafe {
        let f = _mm512_loadu_ps(fx.as_ptr());
        let (v, d, o) = (v.as_ptr().add(p), d.as_ptr().add(p), out.as_mut_ptr());
        for i in 0..cells {
            let l = _mm512_set1_ps(*v.add(3 * i));
            let dd = _mm512_set1_ps(*d.add(3 * i));
            _mm512_storeu_ps(o.add(16 * i), _mm512_add_ps(l, _mm512_mul_ps(dd, f)));
        }
    }
}

/// [`interp16_avx512`] with two AVX vectors per cell.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn interp16_avx2(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    use std::arch::x86_64::*;
    let cells = out.len() / 16;
    assert!(p < 3 && 3 * cells <= d.len() && d.len() <= v.len());
    // SAFETY: as in `interp16_avx512`
    unsafe {
        let (fa, fb) = (
            _mm256_loadu_ps(fx.as_ptr()),
            _mm256_loadu_ps(fx.as_ptr().add(8)),
        );
        let (v, d, o) = (v.as_ptr().add(p), d.as_ptr().add(p), out.as_mut_ptr());
        for i in 0..cells {
            let l = _mm256_set1_ps(*v.add(3 * i));
            let dd = _mm256_set1_ps(*d.add(3 * i));
            let o = o.add(16 * i);
            _mm256_storeu_ps(o, _mm256_add_ps(l, _mm256_mul_ps(dd, fa)));
            _mm256_storeu_ps(o.add(8), _mm256_add_ps(l, _mm256_mul_ps(dd, fb)));
        }
    }
}

#[inline(always)]
fn lerp3(a: [f32; 3], b: [f32; 3], f: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

impl StokesRows for SkyGrid<'_> {
    fn width(&self) -> usize {
        self.width
    }
    fn height(&self) -> usize {
        self.height
    }
    fn fill_row(&self, r: usize, s0: &mut [f32], s1: &mut [f32], s2: &mut [f32]) {
        let (w, gw) = (self.width, self.cols.len());
        let step = self.step;
        // columns evaluated exactly, gathered so that the row evaluator gets whole chunks
        let mut exact: Vec<usize> = Vec::new();
        if gw < 2 || self.rows.len() < 2 {
            exact.extend(0..w);
        } else {
            let j = Self::interval(&self.rows, step, r);
            let (r0, r1) = (self.rows[j], self.rows[j + 1]);
            let fy = (r - r0) as f32 / (r1 - r0) as f32;
            // every cell by interpolation first (the full-width cells in one tight loop per
            // plane, built for the CPU's vector units), then the refined cells overwritten
            let full = (gw - 2) * step; // cells 0..gw−2 are `step` wide, the last one narrower
            let (mut buf, mut heap) = ([0f32; 64], Vec::new());
            let fx: &mut [f32] = if step <= buf.len() {
                &mut buf[..step]
            } else {
                heap.resize(step, 0.0);
                &mut heap
            };
            for (x, f) in fx.iter_mut().enumerate() {
                *f = x as f32 / step as f32;
            }
            interp_cells(s0, s1, s2, &self.nodes, gw, j, fy, fx, full);
            let v = |i: usize| lerp3(self.nodes[j * gw + i], self.nodes[(j + 1) * gw + i], fy);
            lerp_span(
                [&mut *s0, &mut *s1, &mut *s2],
                v(gw - 2),
                v(gw - 1),
                self.cols[gw - 2],
                self.cols[gw - 1],
                w,
            );
            for sg in &self.subs[self.band_subs[j]..self.band_subs[j + 1]] {
                let i = sg.cell;
                let c_end = if i + 2 == gw {
                    self.cols[i + 1] + 1
                } else {
                    self.cols[i + 1]
                };
                let (sw, sh) = (sg.cols.len(), sg.rows.len());
                let jj = ((r - r0) / sg.step).min(sh - 2);
                let (sr0, sr1) = (sg.rows[jj], sg.rows[jj + 1]);
                let fy = (r - sr0) as f32 / (sr1 - sr0) as f32;
                for ii in 0..sw - 1 {
                    let (a0, a1) = (sg.cols[ii], sg.cols[ii + 1]);
                    let a_end = if ii + 2 == sw { c_end } else { a1 };
                    if sg.exact[jj * (sw - 1) + ii] {
                        exact.extend(a0..a_end);
                    } else {
                        let n = |x: usize, y: usize| sg.nodes[y * sw + x];
                        let left = lerp3(n(ii, jj), n(ii, jj + 1), fy);
                        let right = lerp3(n(ii + 1, jj), n(ii + 1, jj + 1), fy);
                        lerp_span([&mut *s0, &mut *s1, &mut *s2], left, right, a0, a1, a_end);
                    }
                }
            }
        }
        stokes_at(
            self.sky,
            self.cam,
            r,
            &exact,
            [&mut *s0, &mut *s1, &mut *s2],
        );
        // the solar disc, exactly as render_stokes adds it
        let lo = self.disc.partition_point(|&(k, _)| k < r * w);
        for &(k, add) in self.disc[lo..]
            .iter()
            .take_while(|&&(k, _)| k < (r + 1) * w)
        {
            s0[k - r * w] += add;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quantisation without libm's round equals `round().clamp()` + `as u16` at every
    /// awkward value: halves, just below halves, negatives, NaN, −∞, and above 65535 (saturated).
    /// The one-pass polarizer images (from the f64 Stokes vector) against eq. (24) applied to the
    /// stored f32 images: the same ideal images bit for bit, and polarizer images within the f32
    /// rounding of AOP (≤ 1e-6 of the brightest), on a fisheye (ground and outside-circle pixels)
    /// and a tilted pinhole frame with the horizon in view.
    #[test]
    fn one_pass_polarizer_images_are_eq_24() {
        use crate::camera::Projection;
        let sky = Sky::new(SunPosition::new(55.0, 130.0), &SkyParams::default()).unwrap();
        let fisheye = Intrinsics {
            projection: Projection::Equidistant,
            focal_length_mm: 1.8,
            pixel_pitch_um: 3.45 * 16.0,
            ..Intrinsics::with_size(153, 128)
        };
        let pinhole = Intrinsics {
            pixel_pitch_um: 3.45 * 16.0,
            ..Intrinsics::with_size(160, 120)
        };
        for (intr, att) in [
            (fisheye, Attitude::enu(30.0, 10.0, 0.0)),
            (pinhole, Attitude::enu(200.0, 80.0, 5.0)),
        ] {
            let cam = Camera::new(intr, &att, 130.0).unwrap();
            let (ideal, one_pass) = render_ideal_polarizers(&sky, &cam);
            assert_eq!(ideal.li, render_ideal(&sky, &cam).li);
            assert_eq!(ideal.aop_deg, render_ideal(&sky, &cam).aop_deg);
            let want = polarizer_images(&ideal);
            let top = want[0].data.iter().fold(0.0f32, |m, &v| m.max(v));
            let (mut ground, mut sky_px) = (0, 0);
            for k in 0..4 {
                for (i, (&a, &b)) in one_pass[k].data.iter().zip(&want[k].data).enumerate() {
                    assert!((a - b).abs() <= 1e-6 * top, "{k} px {i}: {a} vs {b}");
                }
            }
            for (i, &v) in ideal.valid.data.iter().enumerate() {
                if v == 0 {
                    ground += 1;
                    assert_eq!(one_pass[0].data[i], one_pass[2].data[i]);
                } else {
                    sky_px += 1;
                }
            }
            assert!(ground > 100 && sky_px > 1000, "{ground} {sky_px}");
        }
    }

    #[test]
    fn polarizer_quantisation_is_round_then_clamp() {
        let vals: Vec<f32> = [
            0.0,
            0.5,
            1.5,
            2.5,
            0.499_999_97,
            -0.5,
            -3.0,
            254.5,
            255.49,
            300.0,
            254.999_98,
            f32::NAN,
            f32::NEG_INFINITY,
            65_535.5,
            70_000.0,
            7.3,
            100.5,
        ]
        .into_iter()
        .chain((0..2000).map(|k| k as f32 * 0.25 + 0.125))
        .collect();
        for fs in [255.0, 65_535.0, 1e6] {
            // the brightest value is fs itself, so κ = 1 and v·κ = v: every awkward value is
            // met as it is (those above fs would change the maximum and are left out)
            let mut a: Vec<f32> = vals
                .iter()
                .copied()
                .filter(|v| v.partial_cmp(&(fs as f32)) != Some(std::cmp::Ordering::Greater))
                .collect();
            a.push(fs as f32);
            let imgs: [Image<f32>; 4] =
                std::array::from_fn(|_| Image::from_vec(a.len(), 1, a.clone()));
            let (kappa, q) = quantize_polarizer_images(&imgs, fs);
            assert_eq!(kappa, 1.0);
            for (k, &v) in a.iter().enumerate() {
                let want = (v as f64 * kappa).round().clamp(0.0, fs) as u16;
                assert_eq!(q[0].data[k], want, "v {v} full scale {fs}");
            }
        }
    }

    /// The row kernel at every instruction set (on this thread, where `with_simd` applies), for
    /// awkward values and full scales, a negative one included: round_clamp, clipped to u16.
    #[test]
    fn quantize_row_is_round_clamp_at_every_instruction_set() {
        let mut vals: Vec<f32> = vec![
            0.0,
            -0.0,
            0.5,
            1.5,
            2.5,
            0.499_999_97,
            -0.5,
            254.5,
            255.49,
            65_534.5,
            65_535.5,
            1e12,
            -1e12,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
        ];
        vals.extend((0..3000).map(|k| k as f32 * 0.37 - 20.0));
        for level in crate::simd::Simd::available() {
            for (kappa, hi) in [(1.0, 255.0), (0.7, 65_535.0), (3.0, 1e6), (1.0, -1.0)] {
                let mut out = vec![7u16; vals.len()];
                crate::simd::with_simd(level, || quantize_row(&vals, kappa, hi, &mut out));
                for (k, &v) in vals.iter().enumerate() {
                    let want = crate::image::round_clamp(v as f64 * kappa, hi).min(65_535) as u16;
                    assert_eq!(out[k], want, "{level:?}: v {v} kappa {kappa} hi {hi}");
                }
            }
        }
    }
    use crate::camera::{Attitude, Intrinsics};
    use crate::sky::{SkyParams, SunPosition};

    /// The row evaluator (pixel_sky_row, pixel_sky_cols) gives pixel_sky's bits in every
    /// instruction set the CPU has: skies from the zenith sun to 89°, turbidity 1.7 to 8, both
    /// DOP forms and normalisations, the Rayleigh model, one and two Hosek–Wilkie channels, a
    /// ground radiance; the ideal and pinhole lenses and a fisheye; looking at the sun, at the
    /// horizon (ground in view) and at the zenith; widths that leave partial chunks. Also the
    /// ideal render's AOP from a row of atan2 (`two_aop_row`).
    #[test]
    fn pixel_sky_row_is_pixel_sky_bit_for_bit() {
        use crate::camera::{Lens, Projection};
        use crate::sky::dop::DOP_KNEE;
        use crate::sky::{DopModel, DopNorm, PolarizationModel};
        let d = SkyParams::default();
        let skies = [
            (
                0.0,
                0.0,
                SkyParams {
                    turbidity: 2.0,
                    ..d.clone()
                },
            ),
            (40.0, 100.0, d.clone()),
            (
                89.0,
                250.0,
                SkyParams {
                    turbidity: 8.0,
                    ground_radiance: Some(0.05),
                    ..d.clone()
                },
            ),
            (
                60.0,
                30.0,
                SkyParams {
                    model: PolarizationModel::Rayleigh,
                    dop_max: 0.8,
                    ..d.clone()
                },
            ),
            (
                75.0,
                300.0,
                SkyParams {
                    dop_model: DopModel::WangPaper,
                    dop_norm: DopNorm::Wilkie,
                    turbidity: 6.0,
                    ..d.clone()
                },
            ),
            // Rayleigh limit of the Berry field, clear air: DOP above the soft ceiling's knee;
            // 600 nm is a Hosek–Wilkie channel (one channel, not two)
            (
                30.0,
                200.0,
                SkyParams {
                    turbidity: 1.7,
                    babinet_deg: 0.0,
                    brewster_deg: 0.0,
                    wavelength_nm: 600.0,
                    albedo: 0.5,
                    ..d.clone()
                },
            ),
            (
                85.0,
                10.0,
                SkyParams {
                    dop_model: DopModel::WangPaper,
                    turbidity: 1.2,
                    ..d.clone()
                },
            ),
        ];
        let rect = Intrinsics {
            pixel_pitch_um: 3.45 * 30.0,
            ..Intrinsics::with_size(151, 37)
        };
        let cams = [
            Intrinsics {
                lens: Some(Lens::Ideal),
                ..rect
            },
            Intrinsics {
                lens: Some(Lens::Pinhole),
                ..rect
            },
            Intrinsics {
                projection: Projection::Equidistant,
                focal_length_mm: 1.8,
                pixel_pitch_um: 3.45 * 20.0,
                lens: Some(Lens::Ideal),
                ..Intrinsics::with_size(130, 41)
            },
        ];
        let bits = |p: &PixelSky| [p.li, p.dop, p.cos2, p.sin2].map(f64::to_bits);
        let (mut above_knee, mut ground, mut dark) = (0, 0, 0);
        for (zen, az, params) in &skies {
            let sun = SunPosition::new(*zen, *az);
            let sky = Sky::new(sun, params).unwrap();
            for intr in cams {
                for att in [
                    Attitude::solar(0.0, -zen, 0.0),
                    Attitude::solar(90.0, -88.0, 10.0),
                    Attitude::solar(0.0, 0.0, 0.0),
                ] {
                    let cam = Camera::new(intr, &att, *az).unwrap();
                    let (w, h) = (intr.width, intr.height);
                    let cols: Vec<usize> = (0..w).step_by(7).chain([w - 1]).collect();
                    // render_stokes (on rayon's workers, at the detected level) gives each
                    // pixel's Stokes vector
                    let (st, _) = render_stokes(&sky, &cam, StokesOptions { sun_disc: false });
                    for r in 0..h {
                        for c in 0..w {
                            let (k, want) = (r * w + c, pixel_sky(&sky, &cam, c as f64, r as f64));
                            let got = [st.s0.data[k], st.s1.data[k], st.s2.data[k]];
                            let want = want.stokes().map(|v| (v as f32).to_bits());
                            assert_eq!(got.map(f32::to_bits), want, "render_stokes {c},{r}");
                        }
                    }
                    for level in crate::simd::Simd::available() {
                        crate::simd::with_simd(level, || {
                            let mut row = vec![PixelSky::default(); w];
                            let mut sel = vec![PixelSky::default(); cols.len()];
                            for r in 0..h {
                                pixel_sky_row(&sky, &cam, r, 0, &mut row);
                                pixel_sky_cols(&sky, &cam, r, &cols, &mut sel);
                                for (c, got) in row.iter().enumerate() {
                                    let want = pixel_sky(&sky, &cam, c as f64, r as f64);
                                    assert!(
                                        bits(got) == bits(&want) && got.valid == want.valid,
                                        "{level:?} sun {zen},{az} {intr:?} {att:?} px {c},{r}: \
                                         {got:?} vs {want:?}"
                                    );
                                    above_knee += (want.dop > DOP_KNEE) as usize;
                                    ground += (!want.valid && want.li > 0.0) as usize;
                                    dark += (!want.valid && want.li == 0.0) as usize;
                                }
                                for (k, &c) in cols.iter().enumerate() {
                                    assert_eq!(bits(&sel[k]), bits(&row[c]), "cols: {c},{r}");
                                }
                                // the ideal render's AOP: atan2 a row at a time
                                let mut two_aop = vec![0.0; w];
                                two_aop_row(&row, &mut two_aop);
                                for (p, &a) in row.iter().zip(&two_aop) {
                                    let (got, want) = (p.aop_deg_from(a), p.aop_deg());
                                    assert_eq!(got.to_bits(), want.to_bits(), "AOP row {r}");
                                }
                                // the exact render's planes, a whole row in order
                                let [mut a, mut b, mut d] = [0; 3].map(|_| vec![0f32; w]);
                                stokes_row(&row, [&mut a, &mut b, &mut d]);
                                for (c, p) in row.iter().enumerate() {
                                    let want = p.stokes().map(|v| (v as f32).to_bits());
                                    let got = [a[c], b[c], d[c]].map(f32::to_bits);
                                    assert_eq!(got, want, "Stokes {c},{r}");
                                }
                            }
                            // a part row starting mid-chunk
                            let mut part = vec![PixelSky::default(); w - 70];
                            pixel_sky_row(&sky, &cam, h / 2, 70, &mut part);
                            for (k, p) in part.iter().enumerate() {
                                let want = pixel_sky(&sky, &cam, (70 + k) as f64, (h / 2) as f64);
                                assert_eq!(bits(p), bits(&want));
                            }
                        });
                    }
                }
            }
        }
        assert!(
            above_knee > 100 && ground > 1000 && dark > 1000,
            "{above_knee} {ground} {dark}"
        );
    }

    /// A 64 × 64 window of camera `big` (attitude `att`, sun azimuth 200°) centred on the sun.
    fn window_on_sun(big: Intrinsics, att: &Attitude, sun: SunPosition) -> Intrinsics {
        let probe = Camera::new(big, att, 200.0).unwrap();
        let (sc, sr) = big.project(probe.enu_to_camera * sun.vector()).unwrap();
        let (pc, pr) = big.principal();
        Intrinsics {
            width: 64,
            height: 64,
            principal_point: Some([pc - (sc - 32.0).round(), pr - (sr - 32.0).round()]),
            ..big
        }
    }

    /// Solar flux collected by the disc pixels of a 64 × 64 window centred on the sun, for a camera
    /// whose optical axis is `off_axis_deg` from the sun: Σ ΔS0 · Ω_pixel.
    fn disc_flux(off_axis_deg: f64) -> (f64, usize) {
        let sun = SunPosition::new(50.0, 200.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        // look toward the sun's azimuth, tilted so the sun is off_axis_deg from the axis
        let att = Attitude::enu(200.0, -(50.0 - off_axis_deg), 0.0);
        let win = window_on_sun(Intrinsics::default(), &att, sun);
        let cam = Camera::new(win, &att, 200.0).unwrap();
        let (with, n) = render_stokes(&sky, &cam, StokesOptions { sun_disc: true });
        let (without, _) = render_stokes(&sky, &cam, StokesOptions { sun_disc: false });
        let f = win.focal_px();
        let mut flux = 0.0;
        for r in 0..64 {
            for c in 0..64 {
                let d = win.ray(c as f64, r as f64).unwrap();
                let cos_phi = d.z / d.length();
                let omega = cos_phi.powi(3) / (f * f); // solid angle of one pixel
                let k = r * 64 + c;
                flux += (with.s0.data[k] - without.s0.data[k]) as f64 * omega;
            }
        }
        (flux, n)
    }

    /// The grid on an awkward size (last cells 3 pixels wide, narrower than a sub-cell): fully refined (tolerance 0) it is the exact render; not
    /// refined at all it is exact at its nodes, and always finite and close.
    #[test]
    fn sky_grid_refines_to_the_exact_render() {
        let sun = SunPosition::new(40.0, 100.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        let intr = Intrinsics {
            pixel_pitch_um: 3.45 * 20.0,
            ..Intrinsics::with_size(116, 84)
        };
        let cam = Camera::new(intr, &Attitude::enu(90.0, 20.0, 0.0), 100.0).unwrap();
        let opts = StokesOptions { sun_disc: true };
        let (exact, n) = render_stokes(&sky, &cam, opts);
        for step in [5usize, 16, 50] {
            let all = SkyGrid::new(&sky, &cam, opts, step, 0.0).to_image();
            let differ = (0..exact.s0.data.len())
                .filter(|&k| {
                    all.s0.data[k] != exact.s0.data[k]
                        || all.s1.data[k] != exact.s1.data[k]
                        || all.s2.data[k] != exact.s2.data[k]
                })
                .count();
            assert_eq!(differ, 0, "step {step}, tolerance 0");
            assert_eq!(SkyGrid::new(&sky, &cam, opts, step, 0.0).sun_pixels(), n);
            let none = SkyGrid::new(&sky, &cam, opts, step, f64::INFINITY);
            let img = none.to_image();
            let nodes = |len: usize| -> Vec<usize> {
                let mut v: Vec<usize> = (0..len).step_by(step).collect();
                if *v.last().unwrap() != len - 1 {
                    v.push(len - 1);
                }
                v
            };
            for &r in &nodes(intr.height) {
                for &c in &nodes(intr.width) {
                    let k = r * intr.width + c;
                    assert_eq!(img.s0.data[k], exact.s0.data[k], "node {c},{r} step {step}");
                }
            }
            for k in 0..img.s0.data.len() {
                let (a, b) = (img.s0.data[k], exact.s0.data[k]);
                assert!(
                    a.is_finite() && (a - b).abs() <= 0.5 * b.abs().max(1e-3),
                    "{k}: {a} {b}"
                );
            }
        }
    }

    /// The grid's rows are the same bits in every instruction set the CPU has (16-pixel cells
    /// by explicit vectors, other widths by the plain loop), and match the row-by-row
    /// reference: bilinear by `lerp3` then `lerp_span` on every cell.
    #[test]
    fn sky_grid_rows_agree_across_simd() {
        use crate::simd::{with_simd, Simd};
        let sun = SunPosition::new(40.0, 100.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        let intr = Intrinsics {
            pixel_pitch_um: 3.45 * 10.0,
            ..Intrinsics::with_size(250, 70)
        };
        let cam = Camera::new(intr, &Attitude::enu(90.0, 20.0, 0.0), 100.0).unwrap();
        let opts = StokesOptions { sun_disc: true };
        let (w, h) = (intr.width, intr.height);
        // 90: cells wider than lerp_span's table (its last cell 69 pixels)
        for step in [16usize, 12, 90] {
            let g = SkyGrid::new(&sky, &cam, opts, step, f64::INFINITY);
            let rows = |l: Simd| -> Vec<u32> {
                with_simd(l, || {
                    let (mut a, mut b, mut c) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
                    let mut v = Vec::new();
                    for r in 0..h {
                        g.fill_row(r, &mut a, &mut b, &mut c);
                        v.extend(a.iter().chain(&b).chain(&c).map(|x| x.to_bits()));
                    }
                    v
                })
            };
            let plain = rows(Simd::Plain);
            for l in Simd::available().into_iter().skip(1) {
                assert!(rows(l) == plain, "step {step}: {l:?} differs from plain");
            }
            // the reference, as fill_row was first written: nodes by lerp3, full-width cells at
            // x/step, the last cell at x · (1/width)
            let gw = g.cols.len();
            for r in 0..h {
                let j = SkyGrid::interval(&g.rows, step, r);
                let fy = (r - g.rows[j]) as f32 / (g.rows[j + 1] - g.rows[j]) as f32;
                let v = |i: usize| lerp3(g.nodes[j * gw + i], g.nodes[(j + 1) * gw + i], fy);
                let (mut a, mut b, mut c) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
                for i in 0..gw - 2 {
                    for (p, o) in [&mut a, &mut b, &mut c].into_iter().enumerate() {
                        let (l, d) = (v(i)[p], v(i + 1)[p] - v(i)[p]);
                        for x in 0..step {
                            o[i * step + x] = l + d * (x as f32 / step as f32);
                        }
                    }
                }
                let (c0, c1) = (g.cols[gw - 2], g.cols[gw - 1]);
                for (p, o) in [&mut a, &mut b, &mut c].into_iter().enumerate() {
                    let (l, d) = (v(gw - 2)[p], v(gw - 1)[p] - v(gw - 2)[p]);
                    for (x, v) in o[c0..w].iter_mut().enumerate() {
                        *v = l + d * (x as f32 * (1.0 / (c1 - c0) as f32));
                    }
                }
                for (k, x) in a.iter().chain(&b).chain(&c).enumerate() {
                    let (p, col) = (k / w, k % w);
                    let got = plain[(r * 3 + p) * w + col];
                    // the solar disc is added on top of the interpolation
                    if p > 0 || !g.disc.iter().any(|&(q, _)| q == r * w + col) {
                        assert_eq!(got, x.to_bits(), "step {step} row {r} plane {p} col {col}");
                    }
                }
            }
        }
    }

    /// Off axis, by hand: a Rayleigh sky (E ∝ s × v) with the sun at zenith angle θs = 60° due
    /// east, seen by a zenith-looking camera (image +x east, +y north) at the pixel whose ray is
    /// θ = 40° off axis toward north, placed by each projection's own radius formula. With
    /// s = (sin θs, 0, cos θs) and v = (0, sin θ, cos θ), s × v has components −sin θs cos θ
    /// along north, −cos θs sin θ along east, and, resolved on the ray's meridional
    /// (north-down) and sagittal (−east) unit vectors, −sin θs and cos θs sin θ. So the pinhole
    /// (E on the focal plane) reads AOP = atan(tan θs cos θ / sin θ) = 64.152°, the ideal lens
    /// (meridional along the image's radial +y, sagittal along its tangential −x)
    /// atan(tan θs / sin θ) = 69.639°, whatever the projection.
    #[test]
    fn lens_aop_off_axis_by_hand() {
        use crate::camera::{Lens, Projection};
        use crate::sky::PolarizationModel;
        let (ts, t) = (60f64.to_radians(), 40f64.to_radians());
        let pinhole = (ts.tan() * t.cos() / t.sin()).atan().to_degrees();
        let ideal = (ts.tan() / t.sin()).atan().to_degrees();
        assert!((pinhole - 64.152).abs() < 1e-3 && (ideal - 69.639).abs() < 1e-3);
        let params = SkyParams {
            model: PolarizationModel::Rayleigh,
            ..SkyParams::default()
        };
        let sky = Sky::new(SunPosition::new(60.0, 90.0), &params).unwrap();
        for (p, rho) in [
            (Projection::Rectilinear, t.tan()),
            (Projection::Equidistant, t),
            (Projection::Equisolid, 2.0 * (t / 2.0).sin()),
            (Projection::Stereographic, 2.0 * (t / 2.0).tan()),
            (Projection::Orthographic, t.sin()),
        ] {
            for (lens, want) in [(Lens::Pinhole, pinhole), (Lens::Ideal, ideal)] {
                let intr = Intrinsics {
                    projection: p,
                    lens: Some(lens),
                    focal_length_mm: 1.8,
                    ..Intrinsics::with_size(64, 48)
                };
                let cam = Camera::new(intr, &Attitude::enu(0.0, 0.0, 0.0), 90.0).unwrap();
                let (c0, r0) = intr.principal();
                let px = pixel_sky(&sky, &cam, c0, r0 + intr.focal_px() * rho);
                assert!(px.valid && px.dop > 0.1, "{p} {lens}");
                let got = px.aop_deg();
                assert!(
                    (got - want).abs() < 1e-6,
                    "{p} {lens}: AOP {got}, by hand {want}"
                );
            }
        }
        // on the axis the two lenses agree
        let cams = Lens::ALL.map(|l| {
            let intr = Intrinsics {
                lens: Some(l),
                ..Intrinsics::with_size(64, 48)
            };
            Camera::new(intr, &Attitude::enu(0.0, 0.0, 0.0), 90.0).unwrap()
        });
        let (c0, r0) = cams[0].intrinsics.principal();
        let a = cams.map(|c| pixel_sky(&sky, &c, c0, r0).aop_deg());
        assert!((a[0] - a[1]).abs() < 1e-9, "{a:?}");
    }

    /// A whole-sky fisheye looking at the zenith: pixels outside the image circle are dark and
    /// invalid, those inside valid, and the grid (fast path) reproduces the mask exactly.
    #[test]
    fn fisheye_image_circle_is_masked_and_the_grid_keeps_it() {
        use crate::camera::Projection;
        let sun = SunPosition::new(40.0, 100.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        for p in [Projection::Equidistant, Projection::Orthographic] {
            let intr = Intrinsics {
                projection: p,
                focal_length_mm: 1.8,
                pixel_pitch_um: 3.45 * 16.0,
                ..Intrinsics::with_size(153, 128)
            };
            let cam = Camera::new(intr, &Attitude::enu(30.0, 10.0, 0.0), 100.0).unwrap();
            let ideal = render_ideal(&sky, &cam);
            let (c0, r0) = intr.principal();
            let rim = p.rim_radius().unwrap() * intr.focal_px();
            let mut inside = 0;
            for r in 0..intr.height {
                for c in 0..intr.width {
                    let k = r * intr.width + c;
                    let rr = (c as f64 - c0).hypot(r as f64 - r0);
                    if rr > rim {
                        assert_eq!(ideal.valid.data[k], 0, "{p} {c},{r}");
                        assert_eq!(ideal.li.data[k], 0.0);
                    } else {
                        inside += 1;
                    }
                }
            }
            assert!(inside > 1000, "{p}: {inside}");
            let opts = StokesOptions { sun_disc: true };
            let (exact, _) = render_stokes(&sky, &cam, opts);
            let grid = SkyGrid::new(&sky, &cam, opts, 16, GRID_TOLERANCE).to_image();
            for k in 0..exact.s0.data.len() {
                let (a, b) = (grid.s0.data[k], exact.s0.data[k]);
                assert_eq!(a == 0.0, b == 0.0, "{p}: pixel {k}: grid {a}, exact {b}");
                assert!(
                    (a - b).abs() <= 2e-3 * b.abs().max(1e-6),
                    "{p}: pixel {k}: {a} {b}"
                );
            }
        }
    }

    /// The solar disc through fisheyes, 50° off axis in a 64 × 64 window around it (1.8 mm lens,
    /// 1 µm pixels so the disc spans about 17 px across): the same flux as the rectilinear camera
    /// on axis, with each projection's pixel solid angle by hand, Ω = sin θ/(ρ ρ′ f²):
    /// sin θ/(θ f²) equidistant, cos⁴(θ/2)/f² stereographic, 1/f² equisolid.
    #[test]
    fn sun_disc_flux_through_fisheyes() {
        use crate::camera::Projection;
        let (on, _) = disc_flux(0.0);
        let sun = SunPosition::new(50.0, 200.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        let att = Attitude::enu(0.0, 0.0, 0.0);
        for p in [
            Projection::Equidistant,
            Projection::Stereographic,
            Projection::Equisolid,
        ] {
            let big = Intrinsics {
                projection: p,
                focal_length_mm: 1.8,
                pixel_pitch_um: 1.0,
                ..Intrinsics::default()
            };
            let win = window_on_sun(big, &att, sun);
            let cam = Camera::new(win, &att, 200.0).unwrap();
            let (with, n) = render_stokes(&sky, &cam, StokesOptions { sun_disc: true });
            let (without, _) = render_stokes(&sky, &cam, StokesOptions { sun_disc: false });
            let f = win.focal_px();
            let (c0, r0) = win.principal();
            let mut flux = 0.0;
            for r in 0..64 {
                for c in 0..64 {
                    let rho = (c as f64 - c0).hypot(r as f64 - r0) / f;
                    let omega = match p {
                        Projection::Equidistant => rho.sin() / rho,
                        Projection::Stereographic => {
                            let t = 2.0 * (rho / 2.0).atan();
                            (t / 2.0).cos().powi(4)
                        }
                        _ => 1.0,
                    } / (f * f);
                    let k = r * 64 + c;
                    flux += (with.s0.data[k] - without.s0.data[k]) as f64 * omega;
                }
            }
            assert!(n > 100, "{p}: {n} pixels");
            assert!(
                (flux / on - 1.0).abs() < 0.005,
                "{p}: flux {flux:e}, rectilinear on axis {on:e}"
            );
        }
    }

    #[test]
    fn sun_disc_flux_is_the_same_on_and_off_axis() {
        let (on, n_on) = disc_flux(0.0);
        let (off, n_off) = disc_flux(50.0);
        assert!(n_on > 50 && n_off > n_on, "{n_on} {n_off}");
        // the disc spans more pixels off axis (1/cos² radially), but carries the same flux
        // (a box of on-axis size cut the disc: −1.8 % at 40°, more beyond)
        assert!(
            (off / on - 1.0).abs() < 0.005,
            "flux on axis {on:e}, 50 deg off {off:e}"
        );
        // and the flux is the disc's: ∫ L dΩ ≈ L̄ π r² with L̄ between the limb and the centre
        let hw = crate::sky::hosek::HosekWilkie::new(4.0, 0.1, 40f64.to_radians(), 450.0).unwrap();
        let area = std::f64::consts::PI * SUN_RADIUS_RAD * SUN_RADIUS_RAD;
        assert!(on < hw.sun_radiance(0.0) * area && on > 0.5 * hw.sun_radiance(0.0) * area);
    }
}
