//! Every value of the library's name tables through the command line: each name in the help of
//! its option, each sky model through `psns render` (ideal and raw), each preset, pixel format,
//! projection and lens through `psns render --raw`, each demosaic method through `psns demosaic`
//! and each heading method through `psns heading`. A value one front-end forgets fails here.

use crate::common;
use common::{psns, stderr};
use psns::camera::{AttitudeFrame, Lens, Projection};
use psns::config::SceneKind;
use psns::demosaic::Method;
use psns::heading::HeadingMethod;
use psns::sensor::packing::{payload_size, PixelFormat};
use psns::sensor::{Preset, Stages};
use psns::sky::{DopModel, DopNorm, PolarizationModel};
use std::path::Path;

/// The help paragraph of `option` in `psns <cmd> --help`: its line to the next option's.
fn option_help(cmd: &[&str], option: &str) -> String {
    let mut args = cmd.to_vec();
    args.push("--help");
    let o = psns(&args);
    assert!(o.status.success(), "{cmd:?}: {}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let mut lines = text.lines().skip_while(|l| {
        !l.trim_start()
            .strip_prefix(option)
            .is_some_and(|r| r.starts_with(' ') || r.is_empty())
    });
    let mut out = lines.next().unwrap_or_default().to_string();
    for l in lines {
        if l.trim_start().starts_with('-') {
            break;
        }
        out.push('\n');
        out.push_str(l);
    }
    assert!(!out.is_empty(), "no {option} in psns {cmd:?} --help");
    out
}

/// Every name a word of the help paragraph (not part of a longer name).
fn help_lists(cmd: &[&str], option: &str, names: &[&str]) {
    let help = option_help(cmd, option);
    let words: Vec<&str> = help
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '-' || c == '_'))
        .collect();
    for n in names {
        assert!(
            words.contains(n),
            "psns {cmd:?} {option}: '{n}' is missing from its help:\n{help}"
        );
    }
}

#[test]
fn every_name_is_in_the_help_of_its_option() {
    let render = ["render"];
    help_lists(
        &render,
        "--model",
        &PolarizationModel::ALL.map(|v| v.name()),
    );
    help_lists(&render, "--dop-norm", &DopNorm::ALL.map(|v| v.name()));
    help_lists(&render, "--dop-model", &DopModel::ALL.map(|v| v.name()));
    help_lists(&render, "--frame", &AttitudeFrame::ALL.map(|v| v.name()));
    help_lists(&render, "--projection", &Projection::ALL.map(|v| v.name()));
    help_lists(&render, "--lens", &Lens::ALL.map(|v| v.name()));
    help_lists(&render, "--scene", &SceneKind::ALL.map(|v| v.name()));
    help_lists(&render, "--preset", &Preset::ALL.map(|v| v.name()));
    help_lists(
        &render,
        "--pixel-format",
        &PixelFormat::ALL.map(|v| v.name()),
    );
    help_lists(&render, "--off", &Stages::NAMES);
    help_lists(
        &["stream"],
        "--model",
        &PolarizationModel::ALL.map(|v| v.name()),
    );
    help_lists(
        &["stream"],
        "--pixel-format",
        &PixelFormat::ALL.map(|v| v.name()),
    );
    help_lists(
        &["verify"],
        "--pixel-format",
        &PixelFormat::ALL.map(|v| v.name()),
    );
    help_lists(&["demosaic"], "--method", &Method::ALL.map(|v| v.name()));
    help_lists(
        &["heading"],
        "--method",
        &HeadingMethod::ALL.map(|v| v.name()),
    );
    help_lists(&["heading"], "--preset", &Preset::ALL.map(|v| v.name()));
}

/// `psns render` of a 64 x 48 frame with `extra` into `out`; its scene.json.
fn render(out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "render",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = psns(&args);
    assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap()
}

/// Every sky model through `psns render --raw`: scene.json names it, and its DOP and raw frame
/// differ from every other model's.
#[test]
fn every_sky_model_through_render() {
    let d = tempfile::tempdir().unwrap();
    let mut seen: Vec<(PolarizationModel, Vec<u8>, Vec<u8>)> = Vec::new();
    for m in PolarizationModel::ALL {
        let out = d.path().join(m.name());
        let scene = render(&out, &["--raw", "--model", m.name()]);
        assert_eq!(scene["sky"]["model"], m.name(), "{m}");
        let dop = std::fs::read(out.join("dop.npy")).unwrap();
        let raw = std::fs::read(out.join("raw.bin")).unwrap();
        for (other, d, r) in &seen {
            assert_ne!(&dop, d, "{m} renders the DOP of {other}");
            assert_ne!(&raw, r, "{m} renders the raw frame of {other}");
        }
        seen.push((m, dop, raw));
    }
}

/// Every preset and every pixel format through `psns render --raw`: scene.json names them and
/// raw.bin has the format's size.
#[test]
fn every_preset_and_pixel_format_through_render_raw() {
    let d = tempfile::tempdir().unwrap();
    for p in Preset::ALL {
        let out = d.path().join(p.name());
        let scene = render(&out, &["--raw", "--preset", p.name()]);
        assert_eq!(scene["raw"]["preset"], p.name(), "{p}");
    }
    for f in PixelFormat::ALL {
        let out = d.path().join(f.name());
        let scene = render(&out, &["--raw", "--pixel-format", f.name()]);
        assert_eq!(scene["raw"]["pixel_format"], f.pfnc_name(), "{f}");
        let raw = std::fs::read(out.join("raw.bin")).unwrap();
        assert_eq!(raw.len(), payload_size(f, 64, 48), "{f}");
    }
}

/// Every projection and lens through `psns render`: scene.json names them.
#[test]
fn every_projection_and_lens_through_render() {
    let d = tempfile::tempdir().unwrap();
    for p in Projection::ALL {
        for l in Lens::ALL {
            let out = d.path().join(format!("{p}-{l}"));
            let scene = render(&out, &["--projection", p.name(), "--lens", l.name()]);
            let i = &scene["camera"]["intrinsics"];
            assert_eq!(i["projection"], p.name(), "{p} {l}");
            assert_eq!(i["lens"], l.name(), "{p} {l}");
        }
    }
}

/// Every demosaic method through `psns demosaic` (each its own DoLP) and every heading method
/// through `psns heading` (each its own answer), on one raw frame.
#[test]
fn every_demosaic_and_heading_method_through_the_cli() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("r");
    render(&out, &["--raw"]);
    let raw = out.join("raw.png");
    let mut dolps: Vec<(Method, Vec<u8>)> = Vec::new();
    for m in Method::ALL {
        let o = d.path().join(format!("d-{m}"));
        let r = psns(&[
            "demosaic",
            raw.to_str().unwrap(),
            "--method",
            m.name(),
            "--out",
            o.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{m}: {}", stderr(&r));
        let dolp = std::fs::read(o.join("dolp.npy")).unwrap();
        for (other, d) in &dolps {
            assert_ne!(&dolp, d, "{m} demosaics as {other}");
        }
        dolps.push((m, dolp));
    }
    // each estimator answers in its own way (at this size Hough finds no meridian)
    let mut seen: Vec<(HeadingMethod, Vec<u8>)> = Vec::new();
    for m in HeadingMethod::ALL {
        let r = psns(&["heading", raw.to_str().unwrap(), "--method", m.name()]);
        assert!(r.status.success(), "{m}: {}", stderr(&r));
        for (other, out) in &seen {
            assert_ne!(&r.stdout, out, "{m} answers as {other}");
        }
        seen.push((m, r.stdout));
    }
}
