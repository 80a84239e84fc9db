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
        let imgs: [Image<f32>; 4] = std::array::from_fn(|_| Image::from_vec(a.len(), 1, a.clone()));
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
use crate::sky::SkyParams;
use crate::sun::SunPosition;

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

/// A cell `beyond_rim` calls dark has no pixel inside the image circle, for every fisheye; and
/// the test does skip cells (the frame's corners).
#[test]
fn cells_beyond_the_rim_receive_no_light() {
    use crate::camera::Projection;
    for p in [
        Projection::Equidistant,
        Projection::Equisolid,
        Projection::Stereographic,
        Projection::Orthographic,
    ] {
        let intr = Intrinsics {
            projection: p,
            focal_length_mm: 1.2,
            pixel_pitch_um: 3.45 * 8.0,
            ..Intrinsics::with_size(306, 256)
        };
        let cam = Camera::new(intr, &Attitude::enu(0.0, 0.0, 0.0), 200.0).unwrap();
        let mut dark = 0;
        for r0 in (0..240).step_by(16) {
            for c0 in (0..290).step_by(16) {
                if !grid::beyond_rim(&cam, c0, c0 + 16, r0, r0 + 16) {
                    continue;
                }
                dark += 1;
                for r in r0..=r0 + 16 {
                    for c in c0..=c0 + 16 {
                        assert!(intr.ray(c as f64, r as f64).is_none(), "{p:?} ({c},{r})");
                    }
                }
            }
        }
        assert!(dark > 4, "{p:?}: {dark}");
    }
}
