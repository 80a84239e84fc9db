//! `psns dataset build`'s plan: printed first by every build, and all of a `--dry-run`; plans
//! too big to hold are refused before allocating, and big ones are walked in bounded memory.

use crate::build::{bin, build, ok, write_config, TINY};
use crate::common::{psns, stderr};
use std::process::Command;

/// Every build prints its plan first (samples, bytes, estimated time); `--dry-run` prints it
/// and creates nothing, not even the output directory, also for the default description.
#[test]
fn every_build_prints_its_plan_and_dry_run_creates_nothing() {
    let d = tempfile::tempdir().unwrap();
    let cfg = write_config(d.path(), TINY);
    let out = d.path().join("tiny");
    let o = build(&out, &cfg, &["--jobs", "2"]);
    ok(&o);
    let e = stderr(&o);
    let first = e.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("psns dataset: plan: 6 samples of 64 x 48, 6 files, about ")
            && first.contains(" with 2 at once"),
        "{e}"
    );
    // the default description: planned, nothing created
    let big = d.path().join("psns");
    let o = psns(&[
        "dataset",
        "build",
        "--out",
        big.to_str().unwrap(),
        "--dry-run",
        "--jobs",
        "2",
    ]);
    ok(&o);
    let e = stderr(&o);
    assert!(
        e.contains("plan: 138000 samples of 2448 x 2048, 138000 files, about 458.")
            && e.contains(" GB, about 1."),
        "{e}"
    );
    assert!(!big.exists(), "--dry-run created {}", big.display());
    assert!(!e.contains("built"), "{e}");
    // a shard's plan counts its own samples; a dry run of a bad --out is refused as the build is
    let o = build(&out, &cfg, &["--dry-run", "--shard", "2/4"]);
    ok(&o);
    assert!(
        stderr(&o).contains("plan: 2 samples of 64 x 48 (shard 2/4 of 6 samples)"),
        "{}",
        stderr(&o)
    );
    std::fs::write(d.path().join("file"), "x").unwrap();
    let o = build(&d.path().join("file"), &cfg, &["--dry-run"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// Split sizes over the cap are refused in one short line (exit 2, nothing written) before
/// anything is allocated, under a 2 GB address-space limit.
#[test]
fn oversized_descriptions_are_refused_before_allocating() {
    let d = tempfile::tempdir().unwrap();
    for (text, want) in [
        (
            "[splits]\nNFPI = 999999999\n",
            "splits.NFPI = 999999999 is out of range (allowed 1..10000000)",
        ),
        (
            "width = 64\nheight = 48\n[splits]\nGNIIPI = 10000001\n",
            "splits.GNIIPI = 10000001 is out of range",
        ),
    ] {
        let cfg = write_config(d.path(), text);
        let out = d.path().join("out");
        let o = Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 2000000 && exec \"$0\" \"$@\"")
            .arg(bin())
            .args(["dataset", "build", "--out"])
            .arg(&out)
            .arg("--config")
            .arg(&cfg)
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(want), "{e}");
        assert_eq!(e.trim_end().lines().count(), 1, "{e}");
        assert!(e.len() < 250, "{e}");
        assert!(!out.exists());
    }
}

/// `merge` and `verify` walk every sample of a 1,500,000-sample description under a 350 MB
/// address-space limit: samples are drawn from their position as they are needed, a chunk at a
/// time. A plan holding every sample (about 850 bytes each, 1.3 GB here) does not fit.
#[test]
fn a_big_plan_is_walked_in_bounded_memory() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path().join("big");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(
        dir.join("dataset.toml"),
        "width = 64\nheight = 48\n[splits]\nNFPI = 1500000\n",
    )
    .unwrap();
    std::fs::write(dir.join("labels.csv"), "").unwrap();
    let run = |cmd: &str| {
        Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 350000 && exec \"$0\" \"$@\"")
            .arg(bin())
            .args(["dataset", cmd])
            .arg(&dir)
            .output()
            .unwrap()
    };
    let o = run("merge");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("1500000 of 1500000 samples are not built yet (first: NFPI/N1_"),
        "{e}"
    );
    assert!(!dir.join("manifest.csv").exists());
    let o = run("verify");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert_eq!(
        String::from_utf8_lossy(&o.stdout).trim_end(),
        format!(
            "manifest.csv: missing (an unfinished build, or shards not merged: psns dataset merge {})",
            dir.display()
        )
    );
    // nothing but the two files given: no temporary left behind
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
}
