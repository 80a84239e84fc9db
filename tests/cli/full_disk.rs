//! Every writing command on a full file system: exit 1 (an I/O failure, not bad input), a message
//! naming the file and the reason, and the previous output left as it was. The file systems are
//! small tmpfs mounts (the tests run as root, as CI does).

use crate::common;
use common::{psns, stderr, Tmpfs};
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `args` with the file system at `mnt` full but for `keep` bytes; asserts exit 1 with
/// ENOSPC named, and nothing but the filler left behind.
fn assert_full_disk_exit_1(mnt: &Tmpfs, keep: u64, args: &[&str]) {
    mnt.fill(keep);
    let o = psns(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "psns {args:?}: {e}");
    assert!(e.contains("No space left"), "psns {args:?}: {e}");
    assert!(e.lines().last().unwrap_or("").len() < 300, "{e}");
    let left: Vec<String> = std::fs::read_dir(mnt.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "filler")
        .collect();
    // an output directory may stay (empty or holding what was there before), never a temporary
    assert!(
        left.iter().all(|n| !n.contains(".tmp-")),
        "psns {args:?} left {left:?}"
    );
    std::fs::remove_file(mnt.path().join("filler")).unwrap();
}

/// A two-frame stream of 256 x 256 Mono16 frames (128 KiB each) outside the small file system.
fn stream_file(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("s.psns");
    let o = psns(&[
        "stream",
        "--frames",
        "2",
        "--width",
        "256",
        "--height",
        "256",
        "--out",
        s(&p),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

#[test]
fn render_on_a_full_disk_exits_1() {
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("r");
    assert_full_disk_exit_1(
        &mnt,
        64 << 10,
        &[
            "render",
            "--width",
            "256",
            "--height",
            "256",
            "--out",
            s(&out),
        ],
    );
}

#[test]
fn extract_on_a_full_disk_exits_1() {
    let d = tempfile::tempdir().unwrap();
    let run = stream_file(d.path());
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("x");
    std::fs::create_dir(&out).unwrap();
    // room for nothing: the PNG fails first
    assert_full_disk_exit_1(
        &mnt,
        0,
        &["extract", s(&run), "--frame", "0", "--out", s(&out)],
    );
    // room for the PNG (~128 KiB of 16-bit codes compress little), not the TIFF
    assert_full_disk_exit_1(
        &mnt,
        160 << 10,
        &["extract", s(&run), "--frame", "0", "--out", s(&out)],
    );
}

#[test]
fn demosaic_on_a_full_disk_exits_1() {
    let d = tempfile::tempdir().unwrap();
    let run = stream_file(d.path());
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("d");
    assert_full_disk_exit_1(
        &mnt,
        64 << 10,
        &["demosaic", s(&run), "--frame", "0", "--out", s(&out)],
    );
}

#[test]
fn dataset_build_on_a_full_disk_exits_1() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("d.toml");
    std::fs::write(&cfg, "width = 256\nheight = 256\n[splits]\nNFPI = 20\n").unwrap();
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("ds");
    assert_full_disk_exit_1(
        &mnt,
        256 << 10,
        &[
            "dataset",
            "build",
            "--config",
            s(&cfg),
            "--out",
            s(&out),
            "--jobs",
            "1",
        ],
    );
}

#[test]
fn convert_on_a_full_disk_exits_1() {
    let d = tempfile::tempdir().unwrap();
    let run = stream_file(d.path());
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("b");
    assert_full_disk_exit_1(
        &mnt,
        64 << 10,
        &["convert", s(&run), "--format", "rosbag2", "--out", s(&out)],
    );
}

#[test]
fn figures_on_a_full_disk_exit_1() {
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("f");
    assert_full_disk_exit_1(&mnt, 0, &["figures", "--only", "lens", "--out", s(&out)]);
}

#[test]
fn single_files_onto_dev_full_exit_1() {
    // a stream onto /dev/full: the header cannot be written
    let o = psns(&[
        "stream",
        "--frames",
        "1",
        "--width",
        "64",
        "--height",
        "64",
        "--out",
        "/dev/full",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("No space left"), "{}", stderr(&o));
}

#[test]
fn dataset_preview_on_a_full_disk_exits_1() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("d.toml");
    std::fs::write(&cfg, "width = 128\nheight = 96\n[splits]\nNFPI = 2\n").unwrap();
    let ds = d.path().join("ds");
    let o = psns(&["dataset", "build", "--config", s(&cfg), "--out", s(&ds)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mnt = Tmpfs::new(1024);
    let out = mnt.path().join("p.png");
    assert_full_disk_exit_1(&mnt, 0, &["dataset", "preview", s(&ds), "--out", s(&out)]);
}

/// A recording that replaces an earlier one and runs out of room leaves the earlier one as it
/// was (exit 1, no temporary left).
#[test]
fn a_replacement_that_does_not_fit_keeps_the_earlier_recording() {
    let mnt = Tmpfs::new(1024);
    for (fmt, name) in [
        ("psns", "run.psns"),
        ("mcap", "run.mcap"),
        ("rosbag2", "run"),
    ] {
        let out = mnt.path().join(name);
        // 256 x 256 Mono16: 3 frames fit in 1 MiB, 20 do not
        let args = |frames: &'static str, seed: &'static str| {
            vec![
                "stream", "--frames", frames, "--seed", seed, "--width", "256", "--height", "256",
                "--format", fmt,
            ]
        };
        let o = psns(&[&args("3", "1")[..], &["--out", s(&out)]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let file = if fmt == "rosbag2" {
            out.join("run_0.mcap")
        } else {
            out.clone()
        };
        let before = std::fs::read(&file).unwrap();
        let o = psns(&[&args("20", "2")[..], &["--out", s(&out)]].concat());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{fmt}: {e}");
        assert!(
            e.contains("No space left") && e.contains("kept as it was"),
            "{e}"
        );
        assert_eq!(std::fs::read(&file).unwrap(), before, "{fmt}");
        let left: Vec<String> = std::fs::read_dir(mnt.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(left.iter().all(|n| !n.contains(".tmp-")), "{fmt}: {left:?}");
        if fmt == "rosbag2" {
            std::fs::remove_dir_all(&out).unwrap();
        } else {
            std::fs::remove_file(&out).unwrap();
        }
    }
}
