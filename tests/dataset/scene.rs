//! The dataset speaks the scene's language: `model`, `radiance`, `dop_model` and the neutral
//! points are keys of the description, named and parsed as `psns render` takes them, with
//! distributions; `labels.csv` records what each sample used, and those values re-render each
//! image through `psns render` byte for byte. Every sky model goes through a build.

use crate::build::{build, label_render_args, label_rows, ok, write_config};
use crate::common::{psns, stderr};
use psns::sky::PolarizationModel;
use std::collections::BTreeSet;
use std::path::Path;

/// Builds `description` into `dir/name`; its labels.csv.
fn built(dir: &Path, name: &str, description: &str) -> String {
    let cfg = dir.join(format!("{name}.toml"));
    std::fs::write(&cfg, description).unwrap();
    let out = dir.join(name);
    ok(&build(&out, &cfg, &["--jobs", "1"]));
    std::fs::read_to_string(out.join("labels.csv")).unwrap()
}

/// Renders every row of `labels` again with `psns render` and its label values (the sky's among
/// them) and compares the image with the dataset's.
fn renders_again(dir: &Path, name: &str, labels: &str) {
    for (i, r) in label_rows(labels).iter().enumerate() {
        let out = dir.join(format!("again-{name}-{i}"));
        let mut args: Vec<String> = ["render", "--raw", "--bit-depth", "8"]
            .into_iter()
            .chain(label_render_args(r))
            .map(String::from)
            .collect();
        args.extend(["--out".into(), out.to_str().unwrap().into()]);
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        let o = psns(&a);
        assert!(o.status.success(), "{a:?}: {}", stderr(&o));
        let file = dir.join(name).join(r["file"]);
        assert!(
            std::fs::read(out.join("raw.png")).unwrap() == std::fs::read(&file).unwrap(),
            "{} differs from psns render {a:?}",
            file.display()
        );
    }
}

const BASE: &str = "seed = 3\nwidth = 64\nheight = 48\nsun_altitude_deg = { min = 20, max = 60 }\n";

/// Every sky model through a build: the labels name it, and the images re-render.
#[test]
fn every_sky_model_through_the_dataset() {
    let d = tempfile::tempdir().unwrap();
    for m in PolarizationModel::ALL {
        let description = format!("{BASE}model = \"{m}\"\n[splits]\nNFPI = 1\nGNIIPI = 1\n");
        let labels = built(d.path(), m.name(), &description);
        let rows = label_rows(&labels);
        assert_eq!(rows.len(), 2, "{m}");
        for r in &rows {
            assert_eq!(r["model"], m.name(), "{m}");
            assert_eq!((r["radiance"], r["dop_model"]), ("hosek", "wang-bounded"));
            let points = match m {
                PolarizationModel::Rayleigh | PolarizationModel::DepolarizedRayleigh => "",
                PolarizationModel::Pan
                | PolarizationModel::Queen
                | PolarizationModel::Asymmetric => "pan",
                PolarizationModel::Wang | PolarizationModel::Berry => "25",
            };
            assert_eq!((r["babinet"], r["brewster"]), (points, points), "{m}");
        }
        renders_again(d.path(), m.name(), &labels);
    }
}

/// Distributions of the sky's named values and of the neutral points: each sample draws its
/// own, the labels say which, and the images re-render with them; dataset.toml keeps the keys.
#[test]
fn sky_keys_take_distributions_and_label_what_each_sample_used() {
    let d = tempfile::tempdir().unwrap();
    let description = format!(
        "{BASE}model = {{ values = [\"wang\", \"asymmetric\", \"berry\"] }}\nradiance = {{ values = [\"hosek\", \"cie:12\"] }}\ndop_model = {{ values = [\"wang-bounded\", \"wang-paper\"] }}\nbabinet = {{ min = 10, max = 30, step = 0.5 }}\nbrewster = 18\n[splits]\nNFPI = 6\nGNIICPI = 6\n"
    );
    let labels = built(d.path(), "mixed", &description);
    let rows = label_rows(&labels);
    assert_eq!(rows.len(), 12);
    let set = |col: &str| rows.iter().map(|r| r[col]).collect::<BTreeSet<&str>>();
    assert_eq!(set("model").len(), 3, "{labels}");
    assert_eq!(
        set("radiance"),
        BTreeSet::from(["hosek", "cie:12"]),
        "{labels}"
    );
    assert_eq!(set("dop_model").len(), 2, "{labels}");
    assert!(set("babinet").len() > 2, "{labels}");
    assert_eq!(set("brewster"), BTreeSet::from(["18"]), "{labels}");
    renders_again(d.path(), "mixed", &labels);
    // the description in force keeps the keys, and builds the same labels again
    let written = std::fs::read_to_string(d.path().join("mixed/dataset.toml")).unwrap();
    assert!(
        written.contains("cie:12") && written.contains("wang-paper"),
        "{written}"
    );
    assert_eq!(built(d.path(), "again", &written), labels);
}

/// Bad sky keys are bad input with the CLI's names and lists, and write nothing.
#[test]
fn bad_sky_keys_name_the_key_and_the_allowed_values() {
    let d = tempfile::tempdir().unwrap();
    for (key, want) in [
        (
            "model = \"mie\"",
            format!("model = mie is out of range (allowed {})", PolarizationModel::names()),
        ),
        ("model = { values = [] }", "values is empty".into()),
        (
            "radiance = \"cie:16\"",
            "radiance = cie:16 is out of range (allowed hosek or cie:N".into(),
        ),
        (
            "dop_model = \"paper\"",
            "dop-model = paper is out of range (allowed wang-bounded, wang-paper)".into(),
        ),
        ("babinet = 70", "babinet = 70 is out of range (allowed 0..60)".into()),
        (
            "neutral_distance = 20\nbabinet = 10",
            "by neutral_distance or by babinet and brewster, not both".into(),
        ),
        (
            "model = { values = [\"wang\", \"queen\"] }\nbabinet = 20",
            "model queen places both neutral points by Pan's law: to fix them give both babinet and brewster, or neutral_distance".into(),
        ),
        (
            "model = { values = [\"berry\", \"pan\"] }\nneutral_distance = 20",
            "--model pan places its neutral points by Pan's law".into(),
        ),
    ] {
        let cfg = write_config(d.path(), &format!("{BASE}{key}\n[splits]\nNFPI = 1\n"));
        let out = d.path().join("bad");
        let o = build(&out, &cfg, &[]);
        assert_eq!(o.status.code(), Some(2), "{key}: {}", stderr(&o));
        assert!(stderr(&o).contains(&want), "{key}: {}", stderr(&o));
        assert!(!out.exists(), "{key}");
    }
}
