//! Where the commands that regenerate the docs write by default: outside the tracked tree
//! (`out/...`), with `docs/...` only on an explicit `--out`; `--quick` never writes into docs/.

use crate::common;
use std::process::Command;

fn psns_in(cwd: &std::path::Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run psns")
}

/// The `[default: ...]` of `--out` in `psns ARGS --help`.
fn default_out(args: &[&str]) -> String {
    let mut a = args.to_vec();
    a.push("--help");
    let o = common::psns(&a);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let help = String::from_utf8_lossy(&o.stdout).into_owned();
    let i = help
        .find("--out")
        .unwrap_or_else(|| panic!("no --out in {args:?} --help:\n{help}"));
    let rest = &help[i..];
    let d = rest
        .find("[default: ")
        .unwrap_or_else(|| panic!("no default for --out in {args:?}:\n{rest}"));
    let v = &rest[d + "[default: ".len()..];
    v[..v.find(']').unwrap()].to_string()
}

#[test]
fn default_outputs_are_outside_docs() {
    for args in [
        &["bench", "demosaic"][..],
        &["bench", "sky"][..],
        &["bench", "heading"][..],
        &["figures"][..],
    ] {
        let d = default_out(args);
        assert!(
            !d.starts_with("docs") && !d.starts_with("./docs"),
            "psns {args:?}: default --out {d} is inside docs/"
        );
        // beside, not inside, render's out/: a render replaces its directory whole
        assert!(d.starts_with("out-"), "psns {args:?}: default --out {d}");
        // .gitignore keeps it untracked
        let gi =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/.gitignore")).unwrap();
        assert!(
            gi.lines().any(|l| l.trim() == format!("/{d}")),
            "{d} not ignored"
        );
    }
}

#[test]
fn quick_bench_into_docs_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for out in ["docs/bench", "./docs/bench", "docs"] {
        let o = psns_in(
            dir.path(),
            &["bench", "demosaic", "--quick", "--runs", "1", "--out", out],
        );
        let err = common::stderr(&o);
        assert_eq!(o.status.code(), Some(2), "--out {out}: {err}");
        assert!(err.contains("quick numbers never land in docs"), "{err}");
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "--out {out}: something was written"
        );
    }
}

/// The README's first picture is what its first command renders (`psns render --out out`, the
/// default scene at yaw 0), as `psns figures` regenerates it byte for byte, and stays small.
#[test]
fn readme_picture_is_its_command_s_render() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let cmd = readme
        .find("cargo run --release -- render --out out\n")
        .unwrap();
    let pic = readme.find("![").unwrap();
    assert!(
        cmd < pic,
        "the README's first picture comes before its command"
    );
    let link = &readme[readme[pic..].find("](").unwrap() + pic + 2..];
    let path = &link[..link.find(')').unwrap()];
    assert_eq!(path, "docs/img/readme_render_li_dop_aop.png");
    let dir = tempfile::tempdir().unwrap();
    let o = common::psns(&[
        "figures",
        "--only",
        "sky",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let made = std::fs::read(dir.path().join("readme_render_li_dop_aop.png")).unwrap();
    let committed = std::fs::read(root.join(path)).unwrap();
    assert!(
        made == committed,
        "{path} differs from psns figures --only sky's"
    );
    assert!(
        committed.len() < 200_000,
        "{path}: {} bytes",
        committed.len()
    );
}
