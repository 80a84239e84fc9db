//! Saturation is said: render, a stream's first frame and heading warn on stderr when more than
//! 1 % of the pixels are saturated, and render's scene.json records the share.

use crate::common;
use common::{psns, stderr};
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The sensor's field of view at 16x its pixel area: auto-exposure places the sky below full scale.
const SMALL: [&str; 6] = ["--width", "612", "--height", "512", "--pixel-pitch", "13.8"];

/// `derived.saturated_fraction` of a render's scene.json.
fn fraction(dir: &Path) -> f64 {
    let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["derived"]["saturated_fraction"]
        .as_f64()
        .unwrap_or_else(|| panic!("no saturated_fraction: {text}"))
}

fn saturated_lines(text: &str) -> usize {
    text.lines().filter(|l| l.contains("saturated")).count()
}

#[test]
fn overexposed_frames_are_called_saturated() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut a = vec!["render", "--raw", "--out", s(&out)];
        a.extend(SMALL);
        a.extend(extra);
        let o = psns(&a);
        assert!(o.status.success(), "{}", stderr(&o));
        (out, stderr(&o))
    };
    let (over, err) = run("over", &["--exposure-us", "5000000"]);
    assert_eq!(saturated_lines(&err), 1, "{err}");
    assert!(err.contains("% of the pixels are saturated"), "{err}");
    let f = fraction(&over);
    assert!(f > 0.9, "{f}");
    let (fine, err) = run("fine", &["--auto-exposure"]);
    assert_eq!(saturated_lines(&err), 0, "{err}");
    assert!(fraction(&fine) < 0.01, "{}", fraction(&fine));

    // heading gives saturation as the reason for no estimate
    let o = psns(&["heading", s(&over.join("raw.png"))]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.lines().nth(1).unwrap().starts_with("nan,0,0,"),
        "{text}"
    );
    assert!(err.contains("saturated"), "{err}");
    let o = psns(&["heading", s(&fine.join("raw.png"))]);
    assert!(!stderr(&o).contains("saturated"), "{}", stderr(&o));

    // a stream: one warning, for its first frame
    let stream = d.join("s.psns");
    let mut a = vec!["stream", "--frames", "3", "--exposure-us", "5000000"];
    a.extend(SMALL);
    a.extend(["--out", s(&stream)]);
    let o = psns(&a);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(saturated_lines(&err), 1, "{err}");
    assert!(err.contains("frame 0"), "{err}");
    let mut a = vec!["stream", "--frames", "2", "--auto-exposure"];
    a.extend(SMALL);
    let second = d.join("t.psns");
    a.extend(["--out", s(&second)]);
    let o = psns(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(saturated_lines(&stderr(&o)), 0, "{}", stderr(&o));
}
