//! Progress on stderr (`src/cli/progress.rs`) through the binary: a short job prints only what it
//! printed before; a job forced long (`PSNS_PROGRESS_PERIOD_S=0`) prints plain periodic lines when
//! stderr is a pipe.

use std::process::{Command, Output};

fn stream(dir: &std::path::Path, extra: &[&str], env: &[(&str, &str)]) -> Output {
    // a new path each run: replacing an earlier stream says so on stderr
    let out = dir.join("s.psns");
    let _ = std::fs::remove_file(&out);
    let mut c = Command::new(env!("CARGO_BIN_EXE_psns"));
    c.args([
        "stream",
        "--width",
        "64",
        "--height",
        "48",
        "--pixel-pitch",
        "3.45",
    ])
    .args(["--out", out.to_str().unwrap()])
    .args(extra)
    .env_remove("PSNS_PROGRESS")
    .env_remove("PSNS_PROGRESS_PERIOD_S");
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.output().expect("run psns");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

fn lines(o: &Output) -> Vec<String> {
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn short_stream_prints_only_its_summary() {
    let d = tempfile::tempdir().unwrap();
    let l = lines(&stream(d.path(), &["--frames", "2"], &[]));
    assert_eq!(l.len(), 1, "{l:?}");
    assert!(l[0].starts_with("streamed 2 frames in "), "{l:?}");
    assert!(l[0].ends_with(" fps)"), "{l:?}");
}

#[test]
fn forced_long_stream_prints_plain_lines_on_a_pipe() {
    let d = tempfile::tempdir().unwrap();
    let l = lines(&stream(
        d.path(),
        &["--frames", "3"],
        &[("PSNS_PROGRESS_PERIOD_S", "0")],
    ));
    // one line per frame (period 0), then the summary
    assert_eq!(l.len(), 4, "{l:?}");
    for (k, line) in l[..3].iter().enumerate() {
        let head = format!("psns stream: {}/3 frames, ", k + 1);
        assert!(line.starts_with(&head), "{line}");
        assert!(line.contains(" fps"), "{line}");
    }
    assert!(l[0].contains(", eta ") && l[0].ends_with(" s"), "{}", l[0]);
    assert!(l[2].ends_with(" s elapsed"), "{}", l[2]);
    assert!(l[3].starts_with("streamed 3 frames in "), "{l:?}");

    // unknown total (a trajectory file, no --frames): a count without eta
    let t = d.path().join("t.csv");
    std::fs::write(&t, "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.05,1,0,0\n").unwrap();
    let l = lines(&stream(
        d.path(),
        &["--trajectory", t.to_str().unwrap()],
        &[("PSNS_PROGRESS_PERIOD_S", "0")],
    ));
    assert_eq!(l.len(), 3, "{l:?}");
    assert!(l[0].starts_with("psns stream: 1 frames, "), "{l:?}");
    assert!(l[1].starts_with("psns stream: 2 frames, "), "{l:?}");
    assert!(!l[1].contains("eta"), "{l:?}");

    // PSNS_PROGRESS=off wins
    let l = lines(&stream(
        d.path(),
        &["--frames", "3"],
        &[("PSNS_PROGRESS_PERIOD_S", "0"), ("PSNS_PROGRESS", "off")],
    ));
    assert_eq!(l.len(), 1, "{l:?}");
}

/// `psns render` counts its steps (the frame, then each file): nothing extra for a short run,
/// plain lines when forced long on a pipe.
#[test]
fn render_reports_its_steps_when_long() {
    let d = tempfile::tempdir().unwrap();
    let run = |name: &str, env: &[(&str, &str)]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_psns"));
        c.args([
            "render", "--raw", "--width", "64", "--height", "48", "--out",
        ])
        .arg(d.path().join(name))
        .env_remove("PSNS_PROGRESS")
        .env_remove("PSNS_PROGRESS_PERIOD_S");
        for (k, v) in env {
            c.env(k, v);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        lines(&o)
    };
    let short = run("a", &[]);
    assert_eq!(short.len(), 1, "{short:?}");
    assert!(short[0].starts_with("raw frame 64x48"), "{short:?}");
    let long = run("b", &[("PSNS_PROGRESS_PERIOD_S", "0")]);
    assert!(
        long.iter()
            .any(|l| l.starts_with("psns render: 26/26 steps")),
        "{long:?}"
    );
}
