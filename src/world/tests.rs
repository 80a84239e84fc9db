use super::optics::{fresnel, glass, Light};
use super::*;
use glam::DVec3;

fn dir(az_deg: f64, el_deg: f64) -> DVec3 {
    let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
    DVec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
}

fn world(cfg: &WorldConfig) -> World {
    World::new(cfg, 1, 0.0, None).unwrap()
}

/// A box of height h whose near face is a distance d away hides, straight ahead of it, the
/// elevations below atan(h/d) and none above, and nothing outside its azimuth span.
#[test]
fn a_box_hides_the_elevations_below_its_roof_edge() {
    let (d, h) = (20.0, 8.0);
    let cfg = WorldConfig {
        buildings: vec![Building {
            east_m: 0.0,
            north_m: d + 5.0,
            width_m: 10.0,
            depth_m: 10.0,
            height_m: h,
            rotation_deg: 0.0,
            surface: Surface::Diffuse,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        ..Default::default()
    };
    let w = world(&cfg);
    let edge = (h / d).atan().to_degrees();
    assert!(w.trace(dir(0.0, edge - 0.01)).is_obstruction());
    assert_eq!(w.trace(dir(0.0, edge + 0.01)), Hit::Sky);
    // the near face's normal points back at the observer
    let Hit::Diffuse { normal, .. } = w.trace(dir(0.0, 5.0)) else {
        panic!("not a wall")
    };
    assert!((normal - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
    // the azimuth span: atan(5 / 20) either side
    let half = (5.0f64 / d).atan().to_degrees();
    assert!(w.trace(dir(half - 0.05, 1.0)).is_obstruction());
    assert_eq!(w.trace(dir(half + 0.05, 1.0)), Hit::Sky);
    // rays into the ground stop there first (the camera at ground level)
    assert_eq!(w.trace(dir(0.0, -1.0)), Hit::Ground);
}

/// A canyon's walls hide elevations below atan(h / (w/2 / |sin(az − axis)|)), exactly.
#[test]
fn a_canyon_hides_what_its_walls_hide() {
    let cfg = WorldConfig {
        canyon: Some(Canyon::new(20.0, 6.0, 30.0)),
        camera_height_m: 1.5,
        ..Default::default()
    };
    let w = world(&cfg);
    for az in [40.0, 75.0, 120.0, 200.0, 290.0, 350.0] {
        let rel = (az - 30.0f64).to_radians().sin().abs();
        let edge = ((6.0 - 1.5) / (10.0 / rel)).atan().to_degrees();
        assert!(w.trace(dir(az, edge - 1e-3)).is_obstruction(), "{az}");
        assert_eq!(w.trace(dir(az, edge + 1e-3)), Hit::Sky, "{az}");
    }
    // along the street the sky reaches down to the horizon
    assert_eq!(w.trace(dir(30.0, 0.5)), Hit::Sky);
    // a camera above the ground sees the foot of the walls below the horizon
    let foot = (1.5f64 / 10.0).atan().to_degrees();
    assert!(w.trace(dir(120.0, -foot + 0.5)).is_obstruction());
    assert_eq!(w.trace(dir(120.0, -foot - 0.5)), Hit::Ground);
}

/// The skyline is interpolated linearly in azimuth and wraps round from the last point to
/// the first.
#[test]
fn the_skyline_wraps_and_interpolates() {
    let s = Skyline::new(&[[10.0, 5.0], [100.0, 20.0], [350.0, 2.0]]).unwrap();
    assert!((s.elevation_deg(55.0) - 12.5).abs() < 1e-12);
    // 350 → 370 = 10: from 2 to 5 over 20°
    assert!((s.elevation_deg(0.0) - 3.5).abs() < 1e-12);
    assert!((s.elevation_deg(360.0) - 3.5).abs() < 1e-12);
    assert!((s.elevation_deg(-5.0) - (2.0 + 3.0 * 5.0 / 20.0)).abs() < 1e-12);
}

#[test]
fn bad_skylines_name_the_value_and_the_range() {
    let e = Skyline::new(&[[10.0, 5.0], [10.0, 6.0]])
        .unwrap_err()
        .to_string();
    assert!(e.contains("does not increase") && e.contains("10"), "{e}");
    let e = Skyline::new(&[[10.0, 95.0]]).unwrap_err().to_string();
    assert!(e.contains("95") && e.contains("-90..90"), "{e}");
    let e = Skyline::new(&[[f64::NAN, 5.0]]).unwrap_err().to_string();
    assert!(e.contains("NaN") && e.contains("0..360"), "{e}");
    let e = Skyline::new(&[[360.0, 5.0]]).unwrap_err().to_string();
    assert!(e.contains("360"), "{e}");
    let e = Skyline::parse_csv("azimuth_deg,elevation_deg\n0,1\nx,2\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3") && e.contains("'x'"), "{e}");
}

#[test]
fn a_box_around_the_observer_is_refused() {
    let cfg = WorldConfig {
        buildings: vec![Building {
            east_m: 1.0,
            north_m: 1.0,
            width_m: 10.0,
            depth_m: 10.0,
            height_m: 5.0,
            rotation_deg: 20.0,
            surface: Surface::Diffuse,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        ..Default::default()
    };
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("around the observer"), "{e}");
    let mut cfg = cfg;
    cfg.buildings[0].east_m = 30.0;
    cfg.validate().unwrap();
    cfg.buildings[0].height_m = f64::NAN;
    let e = cfg.validate().unwrap_err().to_string();
    assert!(
        e.contains("building 1 height_m") && e.contains("NaN"),
        "{e}"
    );
}

/// Unpolarized light off glass comes back with Fresnel's degree (R_s − R_p)/(R_s + R_p), 1 at
/// Brewster's angle, with its E-vector across the plane of incidence whatever the sky's.
#[test]
fn glass_reflects_with_fresnel_s_degree_and_the_facade_s_angle() {
    let n = DVec3::new(0.0, -1.0, 0.0); // a facade to the north, facing the observer
    for inc_deg in [10.0, 30.0, 56.66, 70.0, 85.0] {
        let i = f64::to_radians(inc_deg);
        // a view ray rising toward the facade at incidence i, in the vertical plane
        let d = DVec3::new(0.0, i.cos(), i.sin());
        let d = DVec3::new(0.0, d.y, d.z).normalize();
        let cos_i = -d.dot(n);
        let (rs, rp) = fresnel(cos_i, 1.52);
        let want = (rs * rs - rp * rp) / (rs * rs + rp * rp);
        let sky = Light {
            radiance: 1.0,
            dop: 0.0,
            e: DVec3::X,
        };
        let out = glass(d, n, 1.52, sky);
        assert!(
            (out.dop - want).abs() < 1e-12,
            "{inc_deg}: {} vs {want}",
            out.dop
        );
        assert!((out.radiance - 0.5 * (rs * rs + rp * rp)).abs() < 1e-12);
        // the plane of incidence is the vertical north plane: the E-vector is east-west
        assert!(out.e.x.abs() > 1.0 - 1e-9, "{inc_deg}: {:?}", out.e);
        assert!(out.e.dot(d).abs() < 1e-12);
    }
    let brewster = 1.52f64.atan();
    let d = DVec3::new(0.0, brewster.cos(), brewster.sin());
    let out = glass(
        d,
        n,
        1.52,
        Light {
            radiance: 1.0,
            dop: 0.0,
            e: DVec3::X,
        },
    );
    assert!((out.dop - 1.0).abs() < 1e-12, "{}", out.dop);
}

/// A mirror (index → ∞) keeps a fully polarized sky fully polarized.
#[test]
fn a_near_perfect_mirror_keeps_polarization() {
    let n = DVec3::new(-1.0, 0.0, 0.0);
    let d = DVec3::new(0.8, 0.3, 0.52).normalize();
    let r = optics::mirror(d, n);
    let e = r.cross(DVec3::Z).normalize();
    let out = glass(
        d,
        n,
        1e6,
        Light {
            radiance: 2.0,
            dop: 1.0,
            e,
        },
    );
    assert!((out.dop - 1.0).abs() < 1e-5 && (out.radiance - 2.0).abs() < 1e-4);
    // a mirror reflects the E-vector: tangential part reversed, normal part kept
    let want = (-e + 2.0 * e.dot(n) * n).normalize();
    assert!(
        out.e.dot(want).abs() > 1.0 - 1e-5,
        "{:?} vs {want:?}",
        out.e
    );
}

/// Clouds drift by the wind's speed times the scene time, along the wind's azimuth at the
/// zenith.
#[test]
fn clouds_drift_by_wind_times_time() {
    let c = Cloud {
        azimuth_deg: 0.0,
        elevation_deg: 90.0,
        radius_deg: 5.0,
        opacity: 1.0,
        softness: 0.1,
    };
    let wind = Wind {
        speed_deg_s: 0.5,
        azimuth_deg: 90.0,
    };
    for t in [0.0, 4.0, 30.0] {
        let f = CloudField::new(&[c], Some(wind), t);
        let moved = f
            .centre(0)
            .dot(DVec3::Z)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!((moved - 0.5 * t).abs() < 1e-9, "{t}: {moved}");
        if t > 0.0 {
            assert!(f.centre(0).x > 0.0, "toward the east");
        }
    }
}

/// Cloud opacity: the cloud's inside its inner radius, 0 outside its rim, a smooth step
/// between; the seeded cover reaches the asked fraction and depends only on the seed.
#[test]
fn cloud_opacity_and_cover() {
    let c = Cloud {
        azimuth_deg: 90.0,
        elevation_deg: 45.0,
        radius_deg: 10.0,
        opacity: 0.8,
        softness: 0.2,
    };
    let f = CloudField::new(&[c], None, 0.0);
    assert!((f.opacity(dir(90.0, 45.0)) - 0.8).abs() < 1e-12);
    assert!((f.opacity(dir(90.0, 45.0 + 7.9)) - 0.8).abs() < 1e-12);
    assert_eq!(f.opacity(dir(90.0, 45.0 + 10.01)), 0.0);
    // a smooth step in cos: half way in cos is half the opacity
    let (ci, co) = (8f64.to_radians().cos(), 10f64.to_radians().cos());
    let mid = f.opacity(dir(90.0, 45.0 + (0.5 * (ci + co)).acos().to_degrees()));
    assert!((mid - 0.4).abs() < 1e-9, "{mid}");
    let mut last = 1.0;
    for k in 0..=40 {
        let a = f.opacity(dir(90.0, 45.0 + 7.9 + 0.05 * k as f64));
        assert!(a <= last, "falls monotonically across the rim");
        last = a;
    }
    for cover in [0.1, 0.5] {
        let a = clouds::draw_cover(cover, 7);
        assert_eq!(a, clouds::draw_cover(cover, 7));
        assert_ne!(a, clouds::draw_cover(cover, 8));
        // measured on an independent set of directions
        let f = CloudField::new(&a, None, 0.0);
        let n = 20_000;
        let covered = (0..n)
            .filter(|k| {
                let z = (*k as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let az = 2.399_963 * *k as f64 + 0.3;
                f.opacity(DVec3::new(r * az.cos(), r * az.sin(), z)) >= 0.5
            })
            .count() as f64
            / n as f64;
        assert!((covered - cover).abs() < 0.04, "{cover}: {covered}");
    }
}

/// The index answers as a scan of every cloud would.
#[test]
fn the_cloud_index_misses_nothing() {
    let clouds = clouds::draw_cover(0.4, 3);
    let f = CloudField::new(&clouds, None, 0.0);
    let one_by_one: Vec<CloudField> = clouds
        .iter()
        .map(|c| CloudField::new(&[*c], None, 0.0))
        .collect();
    for k in 0..5000 {
        let z = 2.0 * (k as f64 + 0.5) / 5000.0 - 1.0;
        let r = (1.0 - z * z).sqrt();
        let az = 2.399_963 * k as f64;
        let d = DVec3::new(r * az.cos(), r * az.sin(), z);
        let want = 1.0 - one_by_one.iter().fold(1.0, |a, f| a * (1.0 - f.opacity(d)));
        assert!((f.opacity(d) - want).abs() < 1e-12, "{k}");
    }
}

/// Trees: foliage where the canopy is not a gap, the gaps fixed to the world (the same ray,
/// the same answer) and about as frequent as asked; the trunk below.
#[test]
fn trees_have_foliage_gaps_and_a_trunk() {
    let tree = Tree {
        east_m: 0.0,
        north_m: 10.0,
        canopy_height_m: 6.0,
        radii_m: [3.0, 3.0, 2.5],
        trunk_radius_m: 0.3,
        gap_fraction: 0.3,
    };
    let cfg = WorldConfig {
        trees: vec![tree],
        camera_height_m: 1.5,
        ..Default::default()
    };
    let w = world(&cfg);
    // the trunk, straight ahead at eye level
    assert!(matches!(w.trace(dir(0.0, 0.0)), Hit::Diffuse { .. }));
    let (mut foliage, mut through) = (0, 0);
    for i in 0..40 {
        for j in 0..40 {
            let d = (DVec3::new(-1.5 + 0.075 * i as f64, 10.0, 4.5 + 0.075 * j as f64 - 1.5)
                - DVec3::new(0.0, 0.0, 1.5))
            .normalize();
            let h = w.trace(d);
            assert_eq!(h, w.trace(d));
            match h {
                Hit::Foliage => foliage += 1,
                Hit::Sky => through += 1,
                _ => {}
            }
        }
    }
    let gap = through as f64 / (foliage + through) as f64;
    assert!((0.2..0.4).contains(&gap), "{foliage} {through}");
    // another seed, another pattern
    let w2 = World::new(&cfg, 2, 0.0, None).unwrap();
    let differ = (0..200)
        .filter(|k| {
            let d = (DVec3::new(-1.0 + 0.01 * *k as f64, 10.0, 3.0)).normalize();
            w.trace(d) != w2.trace(d)
        })
        .count();
    assert!(differ > 10, "{differ}");
}

/// `clear` never says clear where a thing's edge is within the margin: against brute force
/// on rays around random directions.
#[test]
fn clear_is_conservative() {
    let cfg = WorldConfig {
        canyon: Some(Canyon::new(16.0, 9.0, 10.0)),
        buildings: vec![Building {
            east_m: -12.0,
            north_m: 25.0,
            width_m: 8.0,
            depth_m: 6.0,
            height_m: 30.0,
            rotation_deg: 35.0,
            surface: Surface::Glass,
            albedo: 0.3,
            refractive_index: 1.52,
        }],
        skyline: vec![[0.0, 8.0], [60.0, 14.0], [61.0, 2.0], [200.0, 12.0]],
        trees: vec![Tree {
            east_m: 5.0,
            north_m: -6.0,
            canopy_height_m: 5.0,
            radii_m: [2.0, 2.0, 2.0],
            trunk_radius_m: 0.2,
            gap_fraction: 0.2,
        }],
        ..Default::default()
    };
    let w = world(&cfg);
    let margin = 1.5f64.to_radians();
    // the terrain's normal turns with the ray (it faces the observer): one surface
    let kind = |h: Hit, d: DVec3| match h {
        Hit::Sky => 0,
        Hit::Ground => 1,
        Hit::Diffuse { normal, .. }
            if normal.dot(-DVec3::new(d.x, d.y, 0.0).normalize()) > 1.0 - 1e-12 =>
        {
            2
        }
        Hit::Diffuse { normal, .. } => 3 + (100.0 * (normal.x + 3.0 * normal.y)).round() as i64,
        Hit::Glass { normal, .. } => 1000 + (100.0 * (normal.x + 3.0 * normal.y)).round() as i64,
        Hit::Foliage => 5000,
    };
    let mut checked = 0;
    for k in 0..3000 {
        let z = (k as f64 + 0.5) / 3000.0 * 0.9 + 0.05;
        let r = (1.0 - z * z).sqrt();
        let az = 2.399_963 * k as f64;
        let d = DVec3::new(r * az.cos(), r * az.sin(), z);
        if !w.clear(d, margin, true) {
            continue;
        }
        checked += 1;
        let want = kind(w.trace(d), d);
        let (u, v) = (
            d.any_orthonormal_vector(),
            d.cross(d.any_orthonormal_vector()),
        );
        for i in 0..24 {
            let a = i as f64 * std::f64::consts::TAU / 24.0;
            for f in [0.3, 0.7, 0.99] {
                let t = margin * f;
                let q = (d * t.cos() + (u * a.cos() + v * a.sin()) * t.sin()).normalize();
                assert_eq!(kind(w.trace(q), q), want, "{k} {i} {f}");
            }
        }
    }
    assert!(checked > 1000, "{checked}");
}
