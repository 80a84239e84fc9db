//! Ideal images in the sensor frame (the PSNS paper's Fig. 10 a–g): LI, DOP and AOP per pixel, the
//! sensor-frame Stokes planes, and the four polarizer-direction images of eq. (24).
//!
//! Each pixel samples the sky along its own ray (`sky.md` §7): d_n = (C_n^c)ᵀ d_c/|d_c|; the
//! E-vector is rotated into the camera frame and projected on the focal plane,
//! AOP_s = atan2(e_c,y, e_c,x) mod 180° (from +x = columns toward +y = rows, down). Pixels that look
//! at or below the horizon are invalid: LI = DOP = AOP = 0 and mask 0 (never NaN).

use crate::camera::Camera;
use crate::image::{Image, StokesImage};
use crate::sky::hosek::{HosekWilkie, SUN_RADIUS_RAD};
use crate::sky::Sky;
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
        if self.cos2 == 0.0 && self.sin2 == 0.0 {
            0.0
        } else {
            crate::angle::SensorAngle::from_deg(0.5 * self.sin2.atan2(self.cos2).to_degrees()).deg()
        }
    }
    /// Sensor-frame Stokes (S0, S1, S2) in radiance units.
    pub fn stokes(&self) -> [f64; 3] {
        let p = self.li * self.dop;
        [self.li, p * self.cos2, p * self.sin2]
    }
}

/// Samples the sky for the ray through the 0-based sub-pixel position (col, row).
#[inline]
pub fn pixel_sky(sky: &Sky, cam: &Camera, col: f64, row: f64) -> PixelSky {
    let d = cam.pixel_direction(col, row);
    let s = sky.sample(d);
    if !s.valid {
        // ground: zero, or the configured uniform unpolarized ground radiance (sky.md §8)
        return PixelSky {
            li: sky.params().ground_radiance.unwrap_or(0.0),
            ..PixelSky::default()
        };
    }
    let e = cam.enu_to_camera * s.e;
    let n2 = e.x * e.x + e.y * e.y;
    let (cos2, sin2) = if s.dop > 0.0 && n2 > 0.0 {
        ((e.x * e.x - e.y * e.y) / n2, 2.0 * e.x * e.y / n2)
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
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let mut out = IdealImages {
        li: Image::new(w, h),
        dop: Image::new(w, h),
        aop_deg: Image::new(w, h),
        valid: Image::new(w, h),
    };
    out.li
        .data
        .par_chunks_mut(w)
        .zip(out.dop.data.par_chunks_mut(w))
        .zip(out.aop_deg.data.par_chunks_mut(w))
        .zip(out.valid.data.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (((li, dop), aop), valid))| {
            for c in 0..w {
                let p = pixel_sky(sky, cam, c as f64, r as f64);
                li[c] = p.li as f32;
                dop[c] = p.dop as f32;
                aop[c] = p.aop_deg() as f32;
                valid[c] = p.valid as u8;
            }
        });
    out
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
    out.s0
        .data
        .par_chunks_mut(w)
        .zip(out.s1.data.par_chunks_mut(w))
        .zip(out.s2.data.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, ((s0, s1), s2))| {
            for c in 0..w {
                let [a, b, d] = pixel_sky(sky, cam, c as f64, r as f64).stokes();
                s0[c] = a as f32;
                s1[c] = b as f32;
                s2[c] = d as f32;
            }
        });
    let n_sun = if opts.sun_disc {
        add_sun_disc(sky, cam, &mut out)
    } else {
        0
    };
    (out, n_sun)
}

/// Adds the solar disc to S0 where it is in view; returns the number of pixels touched.
fn add_sun_disc(sky: &Sky, cam: &Camera, st: &mut StokesImage) -> usize {
    let p = sky.params();
    let Ok(hw) = HosekWilkie::new(
        p.turbidity,
        p.albedo,
        sky.sun().elevation_deg().to_radians(),
        p.wavelength_nm,
    ) else {
        return 0;
    };
    let s_enu = sky.sun().vector();
    let s_c = cam.enu_to_camera * s_enu;
    let Some((sc, sr)) = cam.intrinsics.project(s_c) else {
        return 0;
    };
    // A pixel subtends less angle off axis (radially by cos²ϕ), so the disc spans more pixels:
    // radial extent of r_sun + 2 IFOV is (r_sun f + 2) / cos²ϕ pixels, plus one for rounding.
    let f = cam.intrinsics.focal_px();
    let cos_phi = s_c.normalize().z;
    let reach = (SUN_RADIUS_RAD * f + 2.0) / (cos_phi * cos_phi) + 1.0;
    let (w, h) = (st.width() as f64, st.height() as f64);
    let c0 = (sc - reach).floor().max(0.0);
    let c1 = (sc + reach).ceil().min(w - 1.0);
    let r0 = (sr - reach).floor().max(0.0);
    let r1 = (sr + reach).ceil().min(h - 1.0);
    if c0 > c1 || r0 > r1 {
        return 0;
    }
    let mut touched = 0;
    for r in r0 as usize..=r1 as usize {
        for c in c0 as usize..=c1 as usize {
            let mut acc = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let d: DVec3 = cam.pixel_direction(
                        c as f64 - 0.375 + 0.25 * sx as f64,
                        r as f64 - 0.375 + 0.25 * sy as f64,
                    );
                    let g = d.dot(s_enu).clamp(-1.0, 1.0).acos();
                    acc += hw.sun_radiance(g);
                }
            }
            if acc > 0.0 {
                let i = r * st.width() + c;
                st.s0.data[i] += (acc / 16.0) as f32;
                touched += 1;
            }
        }
    }
    touched
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
    let max = imgs
        .iter()
        .flat_map(|i| i.data.iter())
        .fold(0.0f32, |m, &v| m.max(v)) as f64;
    let kappa = if max > 0.0 { full_scale / max } else { 0.0 };
    let q = std::array::from_fn(|k| {
        let i = &imgs[k];
        Image::from_vec(
            i.width,
            i.height,
            i.data
                .iter()
                .map(|&v| (v as f64 * kappa).round().clamp(0.0, full_scale) as u16)
                .collect(),
        )
    });
    (kappa, q)
}

/// Sensor-frame Stokes planes evaluated exactly on a grid of nodes every `step` pixels and
/// interpolated bilinearly in between — the sky is smooth on the scale of a few pixels, so this cuts
/// the cost of the sky model by ~step². Cells whose corners straddle the horizon, or whose S0
/// varies by more than 2 % across the cell (the circumsolar peak), are evaluated exactly at
/// every pixel. `step = 1` is the exact render. The sun disc is added exactly as in
/// [`render_stokes`]. See `docs/sky.md` for the measured accuracy cost.
pub fn render_stokes_grid(
    sky: &Sky,
    cam: &Camera,
    opts: StokesOptions,
    step: usize,
) -> (StokesImage, usize) {
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    if step <= 1 || w < 2 || h < 2 {
        return render_stokes(sky, cam, opts);
    }
    // node coordinates: 0, step, 2 step, ..., and always the last pixel
    let nodes = |n: usize| -> Vec<usize> {
        let mut v: Vec<usize> = (0..n).step_by(step).collect();
        if *v.last().unwrap() != n - 1 {
            v.push(n - 1);
        }
        v
    };
    let (nc, nr) = (nodes(w), nodes(h));
    let grid: Vec<[f64; 4]> = nr
        .par_iter()
        .flat_map_iter(|&r| {
            nc.iter().map(move |&c| {
                let p = pixel_sky(sky, cam, c as f64, r as f64);
                let [a, b, d] = p.stokes();
                [a, b, d, p.valid as u8 as f64]
            })
        })
        .collect();
    let gw = nc.len();
    let mut out = StokesImage::zeros(w, h);
    let rows: Vec<(usize, usize)> = (0..nr.len() - 1).map(|j| (nr[j], nr[j + 1])).collect();
    // each band of rows between two node rows is independent: split the three planes into the
    // bands' row ranges and fill them in place
    let mut slices: Vec<(&mut [f32], &mut [f32], &mut [f32])> = Vec::with_capacity(rows.len());
    {
        let (mut a, mut b, mut d) = (
            &mut out.s0.data[..],
            &mut out.s1.data[..],
            &mut out.s2.data[..],
        );
        for (j, &(r0, r1)) in rows.iter().enumerate() {
            let r_end = if j + 2 == nr.len() { r1 + 1 } else { r1 };
            let n = (r_end - r0) * w;
            let (a0, a1) = std::mem::take(&mut a).split_at_mut(n);
            let (b0, b1) = std::mem::take(&mut b).split_at_mut(n);
            let (d0, d1) = std::mem::take(&mut d).split_at_mut(n);
            slices.push((a0, b0, d0));
            (a, b, d) = (a1, b1, d1);
        }
    }
    slices
        .into_par_iter()
        .enumerate()
        .for_each(|(j, (p0, p1, p2))| {
            let (r0, r1) = rows[j];
            let last_band = j + 2 == nr.len();
            let r_end = if last_band { r1 + 1 } else { r1 };
            let mut fxs: Vec<f64> = Vec::with_capacity(step + 1);
            for i in 0..gw - 1 {
                let (c0, c1) = (nc[i], nc[i + 1]);
                let q = [
                    grid[j * gw + i],
                    grid[j * gw + i + 1],
                    grid[(j + 1) * gw + i],
                    grid[(j + 1) * gw + i + 1],
                ];
                let all_valid = q.iter().all(|v| v[3] > 0.0);
                let (mn, mx) = q
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v[0]), b.max(v[0])));
                let exact = !all_valid || mx > 1.02 * mn;
                let last_col = i + 2 == gw;
                let c_end = if last_col { c1 + 1 } else { c1 };
                // column weights of this cell, the same values for every row
                fxs.clear();
                fxs.extend((c0..c_end).map(|c| (c - c0) as f64 / (c1 - c0) as f64));
                for r in r0..r_end {
                    let fy = (r - r0) as f64 / (r1 - r0) as f64;
                    for c in c0..c_end {
                        let s = if exact {
                            pixel_sky(sky, cam, c as f64, r as f64).stokes()
                        } else {
                            let fx = fxs[c - c0];
                            std::array::from_fn(|k| {
                                let top = q[0][k] * (1.0 - fx) + q[1][k] * fx;
                                let bot = q[2][k] * (1.0 - fx) + q[3][k] * fx;
                                top * (1.0 - fy) + bot * fy
                            })
                        };
                        let k = (r - r0) * w + c;
                        p0[k] = s[0] as f32;
                        p1[k] = s[1] as f32;
                        p2[k] = s[2] as f32;
                    }
                }
            }
        });
    let n_sun = if opts.sun_disc {
        add_sun_disc(sky, cam, &mut out)
    } else {
        0
    };
    (out, n_sun)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Attitude, Intrinsics};
    use crate::sky::{SkyParams, SunPosition};

    /// Solar flux collected by the disc pixels of a 64 × 64 window centred on the sun, for a camera
    /// whose optical axis is `off_axis_deg` from the sun: Σ ΔS0 · Ω_pixel.
    fn disc_flux(off_axis_deg: f64) -> (f64, usize) {
        let sun = SunPosition::new(50.0, 200.0);
        let sky = Sky::new(sun, &SkyParams::default()).unwrap();
        // look toward the sun's azimuth, tilted so the sun is off_axis_deg from the axis
        let att = Attitude::enu(200.0, -(50.0 - off_axis_deg), 0.0);
        let big = Intrinsics::default();
        let probe = Camera::new(big, &att, 200.0).unwrap();
        let (sc, sr) = big.project(probe.enu_to_camera * sun.vector()).unwrap();
        let (pc, pr) = big.principal();
        let win = Intrinsics {
            width: 64,
            height: 64,
            principal_point: Some([pc - (sc - 32.0).round(), pr - (sr - 32.0).round()]),
            ..big
        };
        let cam = Camera::new(win, &att, 200.0).unwrap();
        let (with, n) = render_stokes(&sky, &cam, StokesOptions { sun_disc: true });
        let (without, _) = render_stokes(&sky, &cam, StokesOptions { sun_disc: false });
        let f = win.focal_px();
        let mut flux = 0.0;
        for r in 0..64 {
            for c in 0..64 {
                let d = win.ray(c as f64, r as f64);
                let cos_phi = d.z / d.length();
                let omega = cos_phi.powi(3) / (f * f); // solid angle of one pixel
                let k = r * 64 + c;
                flux += (with.s0.data[k] - without.s0.data[k]) as f64 * omega;
            }
        }
        (flux, n)
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
