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
