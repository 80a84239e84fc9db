//! One attitude frame by default: a yaw given to `psns render` (or `psns.Camera`) is the compass
//! heading that `psns heading` reports, with every other option left at its default.

use crate::common;

/// (yaw_deg, confidence) from `psns heading`'s one CSV row.
fn heading_row(raw: &str, extra: &[&str]) -> (f64, f64) {
    let mut a = vec!["heading", raw];
    a.extend(extra);
    let o = common::psns(&a);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| -> f64 {
        let i = head.iter().position(|h| *h == n).unwrap();
        row[i].parse().unwrap()
    };
    (col("yaw_deg"), col("confidence"))
}

fn angle_gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

#[test]
fn render_then_heading_round_trips_with_defaults() {
    let dir = tempfile::tempdir().unwrap();
    // yaw None: the default attitude (yaw 0)
    for (yaw, tilt) in [
        (None, None),
        (Some("30"), None),
        (Some("233.5"), Some("-6")),
    ] {
        let out = dir.path().join(format!("r{}", yaw.unwrap_or("0")));
        let mut a = vec!["render", "--raw", "--out", out.to_str().unwrap()];
        if let Some(y) = yaw {
            a.extend(["--yaw", y]);
        }
        if let Some(r) = tilt {
            a.extend(["--roll", r]);
        }
        let o = common::psns(&a);
        assert!(o.status.success(), "{}", common::stderr(&o));
        let raw = out.join("raw.png");
        let extra: Vec<&str> = tilt.map(|r| vec!["--roll", r]).unwrap_or_default();
        let (got, conf) = heading_row(raw.to_str().unwrap(), &extra);
        let want: f64 = yaw.unwrap_or("0").parse().unwrap();
        assert!(
            angle_gap(got, want) < 0.5,
            "render --yaw {want} -> heading {got} (confidence {conf})"
        );
        assert!(conf > 0.5, "confidence {conf}");
        // the scene file the render wrote names its frame
        let scene = std::fs::read_to_string(out.join("scene.json")).unwrap();
        assert!(scene.contains("\"frame\": \"enu\""), "{scene}");
    }
}
