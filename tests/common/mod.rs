//! Helpers shared by the command-line integration tests.
#![allow(dead_code)] // each test binary uses a subset

use std::io::Write;
use std::process::{Command, Output, Stdio};

/// Runs the `psns` binary with `args`.
pub fn psns(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(args)
        .output()
        .expect("run psns")
}

/// Runs the `psns` binary with `input` on stdin.
pub fn psns_stdin(args: &[&str], input: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    child.wait_with_output().unwrap()
}

/// The process's stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
