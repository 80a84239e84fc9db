//! Messages are written for people: no Rust debug text (`Some(..)`, `None`) in what a failing
//! command prints, across the commands.

use crate::common;
use common::{psns, psns_stdin, stderr};
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Rust's debug rendering of options and results.
const DEBUG_TEXT: [&str; 4] = ["Some(", "None", "Ok(", "Err("];

#[test]
fn failing_commands_print_no_debug_text() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stream = d.join("s.psns");
    let o = psns(&[
        "stream",
        "--frames",
        "3",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        s(&stream),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&stream).unwrap();
    let cut = d.join("cut.psns");
    std::fs::write(&cut, &bytes[..bytes.len() - 1000]).unwrap();
    // a damaged record in the middle: frame 1's header bytes overwritten
    let mut bad = bytes.clone();
    let n = bad.len();
    for b in &mut bad[n / 2..n / 2 + 64] {
        *b ^= 0x5a;
    }
    let damaged = d.join("damaged.psns");
    std::fs::write(&damaged, &bad).unwrap();
    let traj = d.join("t.csv");
    std::fs::write(&traj, b"t_s,yaw_deg,pitch_deg,roll_deg\n0,\xff\xfe,0,0\n").unwrap();
    let (sc, dm, tr) = (s(&cut), s(&damaged), s(&traj));
    let mcap = d.join("x.mcap");
    let tstream = d.join("t.psns");
    let (missing, nothing) = (d.join("missing.png"), d.join("nothing"));
    let out = d.join("out");
    let runs: Vec<Vec<&str>> = vec![
        vec!["heading", sc],
        vec!["heading", dm],
        vec!["heading", dm, "--index", "1"],
        vec!["verify", sc],
        vec!["verify", dm],
        vec!["extract", sc, "--frame", "2", "--out", s(&out)],
        vec!["extract", dm, "--frame", "7", "--out", s(&out)],
        vec!["demosaic", sc, "--frame", "2", "--out", s(&out)],
        vec!["convert", dm, "--format", "mcap", "--out", s(&mcap)],
        vec![
            "stream",
            "--trajectory",
            tr,
            "--frames",
            "1",
            "--out",
            s(&tstream),
        ],
        vec!["render", "--sun-zenith", "95", "--out", s(&out)],
        vec!["heading", s(&missing)],
        vec!["dataset", "verify", s(&nothing)],
    ];
    for a in &runs {
        let o = psns(a);
        assert!(!o.status.success(), "{a:?} succeeded");
        let text = format!("{}{}", stderr(&o), String::from_utf8_lossy(&o.stdout));
        for t in DEBUG_TEXT {
            assert!(!text.contains(t), "{a:?} prints {t}: {text}");
        }
    }
    let o = psns_stdin(&["sky"], "zenith_deg,azimuth_deg\n10,20\n\"unclosed,3\n");
    let text = stderr(&o);
    for t in DEBUG_TEXT {
        assert!(!text.contains(t), "sky prints {t}: {text}");
    }
}
