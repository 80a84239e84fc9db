//! `psns dataset build`'s plan: printed first by every build, and all of a `--dry-run`.

use crate::build::{build, ok, write_config, TINY};
use crate::common::{psns, stderr};

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
