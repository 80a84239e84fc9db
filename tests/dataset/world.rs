//! The world around each sample: world keys checked with the command line's ranges, a canyon
//! sample equal to `psns render --canyon` byte for byte and hiding what its geometry hides, and
//! the `urban` and `canopy` presets built the same whatever the jobs or shards.

use crate::build::{assert_same_tree, build, label_render_args, label_rows, ok, write_config};
use crate::common::{psns, stderr};
use std::path::Path;

/// A zenith-looking equidistant fisheye at 64 x 64: focal length 0.8 mm, pixels 40 um, so the
/// horizon is a circle of 0.8 * pi / 2 / 0.04 = 31.4 pixels.
const FISHEYE: &str = "width = 64\nheight = 64\npixel_pitch_um = 40\nprojection = \"equidistant\"\nfocal_length_mm = 0.8\n";

fn num(s: &str) -> f64 {
    s.parse()
        .unwrap_or_else(|_| panic!("'{s}' is not a number"))
}

/// Bad world keys exit 2 with the key, the value and the range `psns render` allows, and write
/// nothing.
#[test]
fn world_keys_are_checked_with_the_command_line_ranges() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("never");
    // the command line's message for the same value
    let o = psns(&[
        "render",
        "--canyon=-1,6,0",
        "--out",
        t.path().join("r").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("canyon width = -1 is out of range (allowed 0.01..100000)"),
        "{}",
        stderr(&o)
    );
    let cases: &[(&str, &str)] = &[
        (
            "[canyon]\nwidth_m = { min = -1, max = 20 }\nheight_m = 6\nazimuth_deg = 0\n",
            "canyon.width_m.min = -1 is out of range (allowed 0.01..100000)",
        ),
        (
            "[canyon]\nwidth_m = 20\nheight_m = { values = [6, 20000] }\nazimuth_deg = 0\n",
            "canyon.height_m.values = 20000 is out of range (allowed 0..10000)",
        ),
        (
            "[canyon]\nwidth_m = 20\nheight_m = 6\n",
            "missing field `azimuth_deg`",
        ),
        (
            "cloud_cover = { min = 0, max = 1.5 }\n",
            "cloud_cover.max = 1.5 is out of range (allowed 0..1)",
        ),
        (
            "camera_height = -2\n",
            "camera_height_m = -2 is out of range (allowed 0..10000)",
        ),
        (
            "[wind]\nspeed_deg_s = 20\nazimuth_deg = 90\n",
            "wind.speed_deg_s = 20 is out of range (allowed -10..10)",
        ),
        (
            "world = \"forest\"\n",
            "world = forest is out of range (allowed urban, canopy)",
        ),
        (
            "[trees]\ncount = 2.5\ndistance_m = 3\ncanopy_height_m = 8\nradius_m = 2\n",
            "trees.count = 2.5 is out of range (allowed whole numbers)",
        ),
        (
            "camera_height_m = 5\n[trees]\ncount = 2\ndistance_m = 3\ncanopy_height_m = 8\nradius_m = { min = 1, max = 4 }\n",
            "trees: a canopy may reach down to the camera (canopy_height_m from 8 minus radius_m up to 4 is not above camera_height_m up to 5)",
        ),
        (
            "world = \"canopy\"\n[trees]\ncount = 3\ndistance_m = 0.1\ncanopy_height_m = 8\nradius_m = 2\n",
            "trees.distance_m = 0.1 is out of range (allowed 0.5..1000)",
        ),
    ];
    for (text, want) in cases {
        let cfg = write_config(t.path(), &format!("{FISHEYE}{text}"));
        let o = build(&out, &cfg, &[]);
        assert_eq!(o.status.code(), Some(2), "{text}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{text}: {}", stderr(&o));
        assert!(!out.exists(), "{text} wrote {}", out.display());
    }
}

/// The fraction of a zenith equidistant fisheye's frame (f / pitch pixels per radian, `pixels`
/// in the frame) that canyon walls `height` tall either side of a street `width` wide hide from
/// a camera on the ground: at azimuth phi from the street's cross direction the wall's top is at
/// elevation atan(2 height |cos phi| / width), so the walls fill zenith angles theta0(phi) =
/// pi/2 - that elevation up to pi/2, the area f^2 / 2 (pi^2 / 4 - theta0^2) dphi.
fn canyon_fraction(width: f64, height: f64, f_px: f64, pixels: f64) -> f64 {
    let n = 100_000;
    let h = std::f64::consts::TAU / n as f64;
    let half_pi = std::f64::consts::FRAC_PI_2;
    let area: f64 = (0..n)
        .map(|k| {
            let phi = (k as f64 + 0.5) * h;
            let t0 = half_pi - (2.0 * height * phi.cos().abs() / width).atan();
            0.5 * (half_pi * half_pi - t0 * t0) * h
        })
        .sum();
    f_px * f_px * area / pixels
}

/// Every sample with a canyon (and one with seeded clouds, a wind and a camera above the ground)
/// is `psns render --raw --canyon W,H,AZ` with its label values, byte for byte, and its class
/// fractions are `psns render`'s; on the ground the walls hide the share of the fisheye's frame
/// their geometry predicts.
#[test]
fn a_canyon_sample_is_psns_render_with_its_canyon() {
    let t = tempfile::tempdir().unwrap();
    let text = format!(
        "{FISHEYE}seed = 9\n[splits]\nNFPI = 3\nGNIIPI = 2\n[canyon]\nwidth_m = {{ values = [20, 12] }}\nheight_m = {{ values = [6, 10] }}\nazimuth_deg = {{ min = 0, max = 179.9 }}\n"
    );
    let clouded = format!(
        "{FISHEYE}seed = 9\ncamera_height_m = 1.5\ncloud_cover = 0.3\nwind = {{ speed_deg_s = 0.5, azimuth_deg = 90 }}\n[splits]\nGNIIPI = 1\n[canyon]\nwidth_m = 20\nheight_m = 6\nazimuth_deg = 30\n"
    );
    let mut checked = 0;
    for (name, text) in [("ground", text), ("clouded", clouded)] {
        let dir = t.path().join(name);
        std::fs::create_dir(&dir).unwrap();
        let cfg = write_config(&dir, &text);
        let d = dir.join("d");
        ok(&build(&d, &cfg, &["--jobs", "1"]));
        let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
        for r in label_rows(&labels) {
            let out = dir.join(format!("again{}{}", r["split"], r["number"]));
            let canyon = format!(
                "{},{},{}",
                r["canyon_width_m"], r["canyon_height_m"], r["canyon_azimuth_deg"]
            );
            let mut args = vec![
                "render",
                "--raw",
                "--bit-depth",
                "8",
                "--projection",
                "equidistant",
                "--canyon",
                &canyon,
                "--camera-height",
                r["camera_height_m"],
            ];
            args.extend(label_render_args(&r));
            if !r["cloud_cover"].is_empty() {
                args.extend(["--cloud-cover", r["cloud_cover"]]);
            }
            let wind = format!("{},{}", r["wind_speed_deg_s"], r["wind_azimuth_deg"]);
            if wind != "," {
                args.extend(["--wind", &wind]);
            }
            let o = out.to_str().unwrap().to_string();
            args.extend(["--out", &o]);
            ok(&psns(&args));
            assert!(
                std::fs::read(out.join("raw.png")).unwrap()
                    == std::fs::read(d.join(r["file"])).unwrap(),
                "{} differs from psns render --canyon {canyon}",
                r["file"]
            );
            let scene: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap())
                    .unwrap();
            let f = &scene["derived"]["class_fractions"];
            for c in ["outside", "sky", "cloud", "obstruction", "ground", "sun"] {
                assert_eq!(
                    num(r[format!("{c}_fraction").as_str()]),
                    f[c].as_f64().unwrap(),
                    "{c} of {}",
                    r["file"]
                );
            }
            if name == "ground" {
                let want = canyon_fraction(
                    num(r["canyon_width_m"]),
                    num(r["canyon_height_m"]),
                    0.8 / 0.04,
                    64.0 * 64.0,
                );
                let got = num(r["obstruction_fraction"]);
                assert!(
                    (got - want).abs() < 0.005,
                    "{}: obstruction {got}, the walls' geometry {want}",
                    r["file"]
                );
                assert_eq!(num(r["cloud_fraction"]), 0.0);
            } else {
                assert!(num(r["cloud_fraction"]) > 0.0, "{r:?}");
                assert_eq!(r["cloud_cover"], "0.3");
                assert_eq!(wind, "0.5,90");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 6);
}

/// Builds `text` into `dir/name` with `extra` options (and shards when `shards` > 1).
fn built(dir: &Path, name: &str, cfg: &Path, extra: &[&str], shards: u64) -> std::path::PathBuf {
    let out = dir.join(name);
    if shards <= 1 {
        ok(&build(&out, cfg, extra));
    } else {
        for k in 1..=shards {
            let s = format!("{k}/{shards}");
            let mut a = extra.to_vec();
            a.extend(["--shard", &s]);
            ok(&build(&out, cfg, &a));
        }
    }
    out
}

/// The presets build small datasets the same with 1 and 2 jobs and as two shards; their labels
/// carry the world drawn (canyons, trees, clouds) and its class fractions.
#[test]
fn urban_and_canopy_presets_build_the_same_whatever_the_jobs_or_shards() {
    for preset in ["urban", "canopy"] {
        let t = tempfile::tempdir().unwrap();
        let cfg = write_config(
            t.path(),
            &format!("{FISHEYE}world = \"{preset}\"\nseed = 21\n[splits]\nNFPI = 3\nTGNIIPI = 2\n"),
        );
        let one = built(t.path(), "one", &cfg, &["--jobs", "1"], 1);
        let two = built(t.path(), "two", &cfg, &["--jobs", "2"], 1);
        let shards = built(t.path(), "shards", &cfg, &["--jobs", "1"], 2);
        assert_same_tree(&one, &two);
        assert_same_tree(&one, &shards);
        let toml = std::fs::read_to_string(one.join("dataset.toml")).unwrap();
        assert!(toml.contains(&format!("world = \"{preset}\"")), "{toml}");
        let labels = std::fs::read_to_string(one.join("labels.csv")).unwrap();
        let rows = label_rows(&labels);
        assert_eq!(rows.len(), 5);
        let mut seeds = std::collections::BTreeSet::new();
        for r in &rows {
            let sum: f64 = ["outside", "sky", "cloud", "obstruction", "ground", "sun"]
                .iter()
                .map(|c| num(r[format!("{c}_fraction").as_str()]))
                .sum();
            assert!((sum - 1.0).abs() < 1e-9, "{r:?}");
            assert!(num(r["obstruction_fraction"]) > 0.0, "{r:?}");
            assert_eq!(r["camera_height_m"], "1.5");
            let cover = num(r["cloud_cover"]);
            seeds.insert(r["seed"]);
            if preset == "urban" {
                assert!((0.0..=0.4).contains(&cover), "{r:?}");
                assert!((10.0..=50.0).contains(&num(r["canyon_width_m"])), "{r:?}");
                assert!((4.0..=30.0).contains(&num(r["canyon_height_m"])), "{r:?}");
                assert_eq!(r["trees"], "0");
            } else {
                assert!((0.0..=0.3).contains(&cover), "{r:?}");
                assert!((2.0..=6.0).contains(&num(r["trees"])), "{r:?}");
                assert_eq!(r["canyon_width_m"], "");
            }
        }
        // seeded clouds: a camera of its own per sample
        assert_eq!(seeds.len(), 5);
    }
}
