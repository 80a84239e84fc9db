//! The ideal images of a scene: LI, DOP, AOP, the sensor-frame Stokes planes with the solar
//! disc, and the polarizer images of eq. (24).

use super::*;

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

pub(super) fn render_ideal_rows(
    sky: &Sky,
    cam: &Camera,
    pol: Option<&mut [Image<f32>; 4]>,
) -> IdealImages {
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
    pub(super) fn two_aop_row = two_aop_row_body(px: &[PixelSky], out: &mut [f64])
}

#[inline(always)]
pub(super) fn two_aop_row_body(px: &[PixelSky], out: &mut [f64]) {
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
pub(super) fn stokes_at(sky: &Sky, cam: &Camera, r: usize, cols: &[usize], s: [&mut [f32]; 3]) {
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
pub(super) fn stokes_row_body(px: &[PixelSky], s: [&mut [f32]; 3]) {
    let [s0, s1, s2] = s;
    for (((p, a), b), d) in px.iter().zip(s0).zip(s1).zip(s2) {
        let [x, y, z] = p.stokes();
        (*a, *b, *d) = (x as f32, y as f32, z as f32);
    }
}

crate::simd::simd_dispatch! {
    /// [`stokes_row_body`] built for the best instruction set the CPU has (the same values:
    /// two products and three conversions per pixel, none fused).
    pub(super) fn stokes_row = stokes_row_body(px: &[PixelSky], s: [&mut [f32]; 3])
}

/// Adds the solar disc to S0 where it is in view; returns the number of pixels touched.
pub(super) fn add_sun_disc(sky: &Sky, cam: &Camera, st: &mut StokesImage) -> usize {
    let px = sun_disc_pixels(sky, cam);
    for &(i, add) in &px {
        st.s0.data[i] += add;
    }
    px.len()
}

/// The solar disc's radiance per pixel it touches, (pixel index, radiance), sorted by index:
/// the limb-darkened Hosek–Wilkie solar radiance averaged over 4 × 4 sub-samples within
/// r_sun + 2 IFOV of the sun. None under an overcast CIE sky ([`Sky::sun_visible`]).
pub(super) fn sun_disc_pixels(sky: &Sky, cam: &Camera) -> Vec<(usize, f32)> {
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
                    let l = hw.sun_radiance(g);
                    // hidden by the world, dimmed by a cloud
                    acc += match sky.surroundings() {
                        Some(w) if l > 0.0 => l * w.sun_transmission(d),
                        _ => l,
                    };
                }
            }
            let open = sky.surroundings().is_none_or(|w| w.world().open(c, r));
            if acc > 0.0 && open {
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
    pub(super) fn quantize_row = quantize_row_body(src: &[f32], kappa: f64, hi: f64, out: &mut [u16])
}

/// [`crate::image::round_clamp`]`(v κ, hi)` of a row, clipped to u16 (`hi` is taken into
/// [0, 65 535] first), its operations through i32 (the same values in that range) so that the
/// loop vectorises: 8 images of 5 M pixels in `psns render`.
#[inline(always)]
pub(super) fn quantize_row_body(src: &[f32], kappa: f64, hi: f64, out: &mut [u16]) {
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
