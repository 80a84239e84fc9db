//! The project's own test command, `tools/test`, run with stand-ins for cargo, the venv's Python
//! and dpkg-query that log their calls: every stage runs even when one fails, the failures are
//! listed at the end, and Ctrl-C ends the run at once.

use std::path::Path;
use std::process::Command;

/// Writes an executable shell script.
fn script(path: &Path, body: &str) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::write(path, format!("#!/bin/sh\n{body}")).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// Runs tools/test with a cargo whose subcommand `fails` exits with `code`; returns the exit
/// code, the log of calls and stderr.
fn tools_test(fails: &[(&str, i32)]) -> (Option<i32>, String, String) {
    let d = tempfile::tempdir().unwrap();
    let bin = d.path().join("bin");
    let venv = d.path().join("venv");
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(venv.join("bin")).unwrap();
    let log = d.path().join("log");
    let cases: String = fails
        .iter()
        .map(|(sub, code)| format!("  {sub}) exit {code};;\n"))
        .collect();
    script(
        &bin.join("cargo"),
        &format!("echo \"cargo $*\" >> \"$LOG\"\ncase \"$1\" in\n{cases}esac\nexit 0\n"),
    );
    script(&bin.join("dpkg-query"), "echo 'install ok installed'\n");
    script(&venv.join("bin/python"), "echo \"python $*\" >> \"$LOG\"\n");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let o = Command::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tools/test"))
        .env("PATH", path)
        .env("PSNS_VENV", &venv)
        .env("LOG", &log)
        .output()
        .unwrap();
    let calls = std::fs::read_to_string(&log).unwrap_or_default();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    (o.status.code(), calls, err)
}

#[test]
fn every_stage_runs_and_the_failures_are_listed_at_the_end() {
    let (code, calls, err) = tools_test(&[("fmt", 1), ("test", 101)]);
    assert_eq!(code, Some(1), "{calls}{err}");
    for want in [
        "cargo fmt --all --check",
        "cargo clippy --release --workspace --all-targets",
        "cargo test --release --no-fail-fast",
        "python -m pytest -q python/tests",
    ] {
        assert!(calls.contains(want), "{want} did not run:\n{calls}\n{err}");
    }
    // the install steps are kept: the requirements go into the venv first
    assert!(
        calls.starts_with("python -m pip install")
            && calls.contains("-r tools/requirements-test.txt"),
        "{calls}"
    );
    let tail = &err[err.find("stage(s) failed").expect(&err)..];
    assert!(
        tail.contains("fmt (exit 1)") && tail.contains("cargo test (exit 101)"),
        "{err}"
    );
    assert!(
        !tail.contains("clippy") && !tail.contains("pytest"),
        "{err}"
    );
    let (code, _, err) = tools_test(&[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("every stage passed"), "{err}");
}

#[test]
fn ctrl_c_in_a_stage_ends_the_run() {
    let (code, calls, err) = tools_test(&[("test", 130)]);
    assert_eq!(code, Some(130), "{calls}{err}");
    assert!(!calls.contains("pytest"), "{calls}");
    assert!(err.contains("interrupted during cargo test"), "{err}");
}
