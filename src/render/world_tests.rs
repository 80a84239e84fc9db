//! The world seen through the camera: the class image against hand projections, the fast
//! path's grid against the exact render, clouds fixed in the sky.

use super::*;
use crate::camera::{Attitude, Intrinsics, Projection};
use crate::sky::SkyParams;
use crate::sun::SunPosition;
use crate::world::{Building, Canyon, Class, Cloud, Surface, Tree, World, WorldConfig};

fn sky_with(cfg: &WorldConfig, sun: SunPosition) -> Sky {
    let w = World::new(cfg, 5, 0.0, None).unwrap();
    Sky::new(sun, &SkyParams::default()).unwrap().with_world(w)
}

fn zenith_fisheye(size: usize) -> Camera {
    let intr = Intrinsics {
        projection: Projection::Equidistant,
        focal_length_mm: 1.0,
        pixel_pitch_um: 3.45,
        ..Intrinsics::with_size(size, size)
    };
    Camera::new(intr, &Attitude::enu(0.0, 0.0, 0.0), 200.0).unwrap()
}

/// A flat skyline at e degrees is, in a zenith equidistant fisheye, the circle of radius
/// f (90° − e) in radians: every pixel more than a pixel inside it is sky, every pixel more
/// than a pixel outside it (within the image circle) is obstruction.
#[test]
fn a_flat_skyline_is_a_circle_in_an_equidistant_fisheye() {
    let cam = zenith_fisheye(400);
    let f = cam.intrinsics.focal_px();
    let (c0, r0) = cam.intrinsics.principal();
    for e in [5.0, 20.0, 45.0] {
        let cfg = WorldConfig {
            skyline: vec![[0.0, e], [120.0, e], [240.0, e]],
            ..Default::default()
        };
        let sky = sky_with(&cfg, SunPosition::new(30.0, 100.0));
        let class = class_image(&sky, &cam, false);
        let radius = f * (90.0f64 - e).to_radians();
        let mut checked = 0;
        for r in 0..400 {
            for c in 0..400 {
                let rho = (c as f64 - c0).hypot(r as f64 - r0);
                let k = class.data[r * 400 + c];
                if rho < radius - 1.0 {
                    assert_eq!(k, Class::Sky as u8, "{e}: ({c},{r}) rho {rho}");
                    checked += 1;
                } else if rho > radius + 1.0 && k != Class::Outside as u8 {
                    assert_eq!(k, Class::Obstruction as u8, "{e}: ({c},{r}) rho {rho}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }
}

/// A box of height h whose near face stands d metres north: in the zenith fisheye the class
/// image hides, straight north, the zenith angles beyond 90° − atan(h/d), to a pixel.
#[test]
fn a_box_in_the_class_image_is_its_hand_projection() {
    let cam = zenith_fisheye(400);
    let f = cam.intrinsics.focal_px();
    let (d, h) = (12.0, 9.0);
    let cfg = WorldConfig {
        buildings: vec![Building {
            east_m: 0.0,
            north_m: d + 4.0,
            width_m: 30.0,
            depth_m: 8.0,
            height_m: h,
            rotation_deg: 0.0,
            surface: Surface::Diffuse,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        ..Default::default()
    };
    let sky = sky_with(&cfg, SunPosition::new(30.0, 100.0));
    let class = class_image(&sky, &cam, false);
    // north in the image: the pixel of the ENU direction north at the horizon
    let north = cam
        .intrinsics
        .project(cam.enu_to_camera * glam::DVec3::Y)
        .unwrap();
    let (c0, r0) = cam.intrinsics.principal();
    let (ux, uy) = ((north.0 - c0) / f, (north.1 - r0) / f);
    let (ux, uy) = (ux / ux.hypot(uy), uy / ux.hypot(uy));
    let edge = f * (std::f64::consts::FRAC_PI_2 - (h / d).atan());
    for step in 0..200 {
        let rho = step as f64;
        let (c, r) = (c0 + ux * rho, r0 + uy * rho);
        let k = class.data[r.round() as usize * 400 + c.round() as usize];
        if rho < edge - 1.0 {
            assert_eq!(k, Class::Sky as u8, "rho {rho} edge {edge}");
        } else if rho > edge + 1.0 && rho < 0.99 * f * std::f64::consts::FRAC_PI_2 {
            assert_eq!(k, Class::Obstruction as u8, "rho {rho} edge {edge}");
        }
    }
}

/// The fast path's grid gives the exact render's values in a world of every kind (canyon,
/// glass box, tree, skyline, clouds): exactly at the pixels it evaluates, within its
/// interpolation tolerance elsewhere, and nowhere a pixel of the wrong thing.
#[test]
fn the_grid_sees_the_world_the_exact_render_sees() {
    let cfg = WorldConfig {
        canyon: Some(Canyon::new(24.0, 7.0, 15.0)),
        buildings: vec![Building {
            east_m: -14.0,
            north_m: 40.0,
            width_m: 10.0,
            depth_m: 10.0,
            height_m: 40.0,
            rotation_deg: 20.0,
            surface: Surface::Glass,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        trees: vec![Tree {
            east_m: 3.0,
            north_m: 8.0,
            canopy_height_m: 6.0,
            radii_m: [2.5, 2.5, 2.0],
            trunk_radius_m: 0.25,
            gap_fraction: 0.2,
        }],
        skyline: vec![[0.0, 3.0], [90.0, 10.0], [180.0, 4.0], [270.0, 12.0]],
        clouds: vec![Cloud {
            azimuth_deg: 250.0,
            elevation_deg: 60.0,
            radius_deg: 8.0,
            opacity: 0.7,
            softness: 0.3,
        }],
        camera_height_m: 1.6,
        ..Default::default()
    };
    let mut solid = cfg.clone();
    solid.clouds.clear();
    // without clouds the edges are exact and the rest within the tolerance; the clouds'
    // opacity is interpolated (every 4 pixels across a rim): within a tenth there, and the
    // image as a whole within the tolerance at its median
    for (cfg, worst_allowed) in [(solid, 20.0 * 2.4e-4), (cfg, 0.1)] {
        let sky = sky_with(&cfg, SunPosition::new(40.0, 150.0));
        for (intr, att) in [
            (zenith_fisheye(300).intrinsics, Attitude::enu(0.0, 0.0, 0.0)),
            (
                Intrinsics {
                    pixel_pitch_um: 3.45 * 6.0,
                    ..Intrinsics::with_size(320, 240)
                },
                Attitude::enu(10.0, 60.0, 0.0),
            ),
        ] {
            let cam = Camera::new(intr, &att, 150.0).unwrap();
            let opts = StokesOptions { sun_disc: true };
            let tol = 2.4e-4;
            let (exact, _) = render_stokes(&sky, &cam, opts);
            let (grid, _) = render_stokes_grid(&sky, &cam, opts, 16, tol);
            let mut worst = 0f64;
            let mut errs = Vec::new();
            for i in 0..exact.s0.data.len() {
                let s0 = exact.s0.data[i] as f64;
                let err = [
                    (grid.s0.data[i] - exact.s0.data[i]) as f64,
                    (grid.s1.data[i] - exact.s1.data[i]) as f64,
                    (grid.s2.data[i] - exact.s2.data[i]) as f64,
                ]
                .iter()
                .map(|e| e.abs())
                .sum::<f64>();
                let rel = if s0 > 0.0 { err / s0 } else { err };
                worst = worst.max(rel);
                errs.push(rel);
            }
            errs.sort_by(f64::total_cmp);
            let median = errs[errs.len() / 2];
            assert!(
                worst < worst_allowed,
                "{:?}: worst {worst}",
                intr.projection
            );
            assert!(median < tol, "{:?}: median {median}", intr.projection);
        }
    }
}

/// A cloud fixed in the sky sits, in frame k of a turning camera, where the camera's rotation
/// puts its centre; and the sun behind a building draws no disc.
#[test]
fn a_world_fixed_cloud_stays_in_the_sky_as_the_camera_turns() {
    let cloud = Cloud {
        azimuth_deg: 40.0,
        elevation_deg: 70.0,
        radius_deg: 6.0,
        opacity: 1.0,
        softness: 0.1,
    };
    let cfg = WorldConfig {
        clouds: vec![cloud],
        ..Default::default()
    };
    let sky = sky_with(&cfg, SunPosition::new(50.0, 200.0));
    let intr = Intrinsics {
        pixel_pitch_um: 3.45 * 8.0,
        ..Intrinsics::with_size(300, 250)
    };
    let a = (40.0f64.to_radians(), 70.0f64.to_radians());
    let centre = glam::DVec3::new(a.1.cos() * a.0.sin(), a.1.cos() * a.0.cos(), a.1.sin());
    for k in 0..3 {
        let cam = Camera::new(intr, &Attitude::enu(15.0 * k as f64, 0.0, 0.0), 200.0).unwrap();
        let class = class_image(&sky, &cam, false);
        let (mut sc, mut sr, mut n) = (0.0, 0.0, 0.0);
        for (i, &v) in class.data.iter().enumerate() {
            if v == Class::Cloud as u8 {
                sc += (i % 300) as f64;
                sr += (i / 300) as f64;
                n += 1.0;
            }
        }
        let (pc, pr) = cam.intrinsics.project(cam.enu_to_camera * centre).unwrap();
        // the centroid of a projected disc is within a pixel or two of its centre's image
        assert!(n > 500.0, "frame {k}: {n} cloud pixels");
        assert!(
            (sc / n - pc).abs() < 2.0 && (sr / n - pr).abs() < 2.0,
            "frame {k}"
        );
    }
    // the sun behind a tall box to its azimuth
    let box_cfg = WorldConfig {
        buildings: vec![Building {
            east_m: -20.0 * 200f64.to_radians().sin().abs(),
            north_m: -20.0 * 200f64.to_radians().cos().abs(),
            width_m: 30.0,
            depth_m: 6.0,
            height_m: 60.0,
            rotation_deg: 200.0,
            surface: Surface::Diffuse,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        ..Default::default()
    };
    let mut fish = zenith_fisheye(300);
    fish.intrinsics.pixel_pitch_um *= 3.0;
    let open = sky_with(&WorldConfig::default(), SunPosition::new(50.0, 200.0));
    let hidden = sky_with(&box_cfg, SunPosition::new(50.0, 200.0));
    assert!(!sun_disc_pixels(&open, &fish).is_empty());
    assert!(sun_disc_pixels(&hidden, &fish).is_empty());
}

/// The class image on every `s`-th pixel is the full class image's pixels at those columns
/// and rows (the sun's disc too), and its fractions are the counts of its classes.
#[test]
fn the_strided_class_image_is_the_full_one_subsampled() {
    let intr = Intrinsics {
        projection: Projection::Equidistant,
        focal_length_mm: 0.25,
        pixel_pitch_um: 3.45,
        ..Intrinsics::with_size(120, 120)
    };
    let cam = Camera::new(intr, &Attitude::enu(0.0, 0.0, 0.0), 200.0).unwrap();
    let cfg = WorldConfig {
        canyon: Some(Canyon::new(20.0, 20.0, 30.0)),
        cloud_cover: Some(0.3),
        ..Default::default()
    };
    let sky = sky_with(&cfg, SunPosition::new(10.0, 100.0));
    let full = class_image(&sky, &cam, true);
    assert!(full.data.contains(&(Class::Sun as u8)));
    for s in [1, 3, 7] {
        let part = class_image_every(&sky, &cam, true, s);
        assert_eq!(
            (part.width, part.height),
            (120usize.div_ceil(s), 120usize.div_ceil(s))
        );
        for r in 0..part.height {
            for c in 0..part.width {
                assert_eq!(
                    part.data[r * part.width + c],
                    full.data[r * s * 120 + c * s]
                );
            }
        }
    }
    let f = fractions(&full);
    for k in Class::ALL {
        let n = full.data.iter().filter(|&&v| v == k as u8).count();
        assert_eq!(f[k as usize], n as f64 / (120.0 * 120.0));
    }
    assert!(f[Class::Obstruction as usize] > 0.2 && f[Class::Cloud as usize] > 0.0);
}
