//! Recordings are not lost: `--out` never overwrites a file that is not an earlier psns output of
//! the same kind and replaces one only when the new output is complete; a second run into a
//! file being written is refused; Ctrl-C ends an open-ended stream cleanly; `psns recover`
//! finishes what `kill -9` leaves; `psns verify` tells a cut-off end from damage.

use crate::common;
use common::{psns, psns_stdin, stderr, wait_deadline};
use psns::stream::{verify, FileHeader, VerifyStatus};
use std::io::Cursor;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SMALL: [&str; 4] = ["--width", "64", "--height", "48"];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `psns stream` of `SMALL` frames with `args`, asserting success.
fn stream(args: &[&str]) {
    let o = psns(&[&["stream"], &SMALL[..], args].concat());
    assert!(o.status.success(), "psns stream {args:?}: {}", stderr(&o));
}

/// A producer in the background, killed if the test fails before it ends.
struct Running(Option<Child>);

impl Running {
    fn id(&self) -> u32 {
        self.0.as_ref().map_or(0, Child::id)
    }
    /// The child, to wait for.
    fn take(mut self) -> Child {
        self.0.take().unwrap()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        if let Some(c) = &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// `psns stream` with `args` in the background.
fn spawn_stream(args: &[&str]) -> Running {
    let c = Command::new(env!("CARGO_BIN_EXE_psns"))
        .arg("stream")
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    Running(Some(c))
}

/// Waits until `p` holds `bytes`.
fn wait_for(p: &Path, bytes: u64) {
    let t = Instant::now();
    while std::fs::metadata(p).map_or(0, |m| m.len()) < bytes {
        assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn signal(c: &Running, sig: &str) {
    let st = Command::new("kill")
        .args([sig, &c.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
}

#[test]
fn out_never_overwrites_a_file_psns_did_not_write() {
    let d = tempfile::tempdir().unwrap();
    let notes = d.path().join("notes.txt");
    let junk = d.path().join("junk.mcap");
    let readme = d.path().join("readme.md");
    for p in [&notes, &junk, &readme] {
        std::fs::write(p, "the user's own words\n").unwrap();
    }
    let run = d.path().join("run.psns");
    stream(&["--frames", "3", "--out", s(&run)]);
    let cases: Vec<(Vec<&str>, &Path)> = vec![
        (vec!["stream", "--frames", "2", "--out", s(&notes)], &notes),
        (
            vec![
                "stream",
                "--frames",
                "2",
                "--format",
                "mcap",
                "--out",
                s(&junk),
            ],
            &junk,
        ),
        (
            vec!["convert", s(&run), "--format", "mcap", "--out", s(&readme)],
            &readme,
        ),
        (vec!["recover", s(&run), "--out", s(&notes)], &notes),
        // a psns stream is not the MCAP file --format mcap would replace, nor the reverse
        (
            vec![
                "stream",
                "--frames",
                "2",
                "--format",
                "mcap",
                "--out",
                s(&run),
            ],
            &run,
        ),
    ];
    for (args, file) in cases {
        let before = std::fs::read(file).unwrap();
        let small: &[&str] = if args[0] == "stream" { &SMALL } else { &[] };
        let o = psns(&[&args[..], small].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("exists and is not"), "{}", stderr(&o));
        assert_eq!(std::fs::read(file).unwrap(), before, "{args:?} touched it");
    }
    // a rosbag2 directory holding the user's file
    let dir = d.path().join("dir");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    let o = psns(&["convert", s(&run), "--format", "rosbag2", "--out", s(&dir)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    // special files are written as they always were
    let o = psns(
        &[
            &["stream", "--frames", "2", "--out", "/dev/null"],
            &SMALL[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let names: Vec<String> = std::fs::read_dir(d.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
}

#[test]
fn an_earlier_output_is_replaced_only_by_a_complete_one() {
    let d = tempfile::tempdir().unwrap();
    let run = d.path().join("run.psns");
    stream(&["--frames", "3", "--out", s(&run)]);
    let first = std::fs::read(&run).unwrap();
    // a run that fails (a bad trajectory line after two frames) leaves it as it was
    let bad = "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.1,10,0,0\n0.05,20,0,0\n";
    let o = psns_stdin(
        &[
            &["stream", "--trajectory", "-", "--out", s(&run)],
            &SMALL[..],
        ]
        .concat(),
        bad,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("kept as it was"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&run).unwrap(), first);
    // a complete one replaces it, and is the same file a new path gets
    stream(&["--frames", "2", "--seed", "9", "--out", s(&run)]);
    let fresh = d.path().join("fresh.psns");
    stream(&["--frames", "2", "--seed", "9", "--out", s(&fresh)]);
    assert_eq!(std::fs::read(&run).unwrap(), std::fs::read(&fresh).unwrap());
    // the same for an MCAP file and a bag directory psns wrote: the replacement is the bag a
    // new path of that name gets (the name is in the bag's metadata)
    let again = d.path().join("again");
    std::fs::create_dir(&again).unwrap();
    for (fmt, name) in [("mcap", "b.mcap"), ("rosbag2", "b")] {
        let out = d.path().join(name);
        let same = again.join(name);
        stream(&["--frames", "2", "--format", fmt, "--out", s(&out)]);
        stream(&[
            "--frames",
            "3",
            "--format",
            fmt,
            "--seed",
            "4",
            "--out",
            s(&out),
        ]);
        stream(&[
            "--frames",
            "3",
            "--format",
            fmt,
            "--seed",
            "4",
            "--out",
            s(&same),
        ]);
        for f in ["", "b_0.mcap", "metadata.yaml"] {
            let (a, b) = match (fmt, f) {
                ("mcap", "") => (out.clone(), same.clone()),
                ("rosbag2", f) if !f.is_empty() => (out.join(f), same.join(f)),
                _ => continue,
            };
            let same_bytes = std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap();
            assert!(same_bytes, "{} differs from {}", a.display(), b.display());
        }
    }
    let names: Vec<String> = std::fs::read_dir(d.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
}

#[test]
fn a_second_run_into_a_recording_in_progress_is_refused() {
    let d = tempfile::tempdir().unwrap();
    for existed in [false, true] {
        let out = d.path().join(format!("live-{existed}.psns"));
        if existed {
            stream(&["--frames", "1", "--out", s(&out)]);
        }
        let first = spawn_stream(&[&SMALL[..], &["--rate", "50", "--out", s(&out)]].concat());
        if existed {
            // the first run writes beside the earlier stream until it completes
            std::thread::sleep(Duration::from_millis(600));
        } else {
            wait_for(&out, 4096 + 2 * 8192);
        }
        for args in [
            vec!["stream", "--frames", "2", "--width", "64", "--out", s(&out)],
            vec!["recover", s(&out), "--out", s(&out)],
        ] {
            let o = psns(&args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            let e = stderr(&o);
            assert!(
                e.contains("another psns run") || e.contains("still writing"),
                "{e}"
            );
        }
        signal(&first, "-INT");
        let o = wait_deadline(first.take(), 30);
        assert!(o.status.success(), "{}", stderr(&o));
        let rep = verify(Cursor::new(std::fs::read(&out).unwrap())).unwrap();
        assert_eq!(rep.status, VerifyStatus::Clean, "{rep}");
        assert!(rep.frames > 2, "{rep}");
    }
}

/// SIGINT and SIGTERM end a run without `--frames` after its last whole frame: exit 0, a stream
/// that verifies clean, to a file and through a pipe. With `--frames`, or SIGHUP, the run is
/// cut short: aborted, and psns dies by the signal.
#[test]
fn ctrl_c_finishes_an_open_ended_stream_cleanly() {
    use std::os::unix::process::ExitStatusExt;
    let d = tempfile::tempdir().unwrap();
    for sig in ["-INT", "-TERM"] {
        let out = d.path().join(format!("{sig}.psns"));
        let c = spawn_stream(&[&SMALL[..], &["--rate", "50", "--out", s(&out)]].concat());
        wait_for(&out, 4096 + 3 * 8192);
        signal(&c, sig);
        let o = wait_deadline(c.take(), 30);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stderr(&o).contains("stopped by SIG"), "{}", stderr(&o));
        let v = psns(&["verify", s(&out)]);
        assert_eq!(v.status.code(), Some(0), "{}", stdout(&v));
        assert!(stdout(&v).ends_with("clean\n"), "{}", stdout(&v));
        // the count is patched and the last frame carries LAST
        let b = std::fs::read(&out).unwrap();
        let h = FileHeader::decode(&b).unwrap();
        assert!(h.frame_count >= 3 && !h.aborted, "{h:?}");
    }
    // through a pipe, where only LAST can mark the end
    let mut c = Running(Some(
        Command::new(env!("CARGO_BIN_EXE_psns"))
            .arg("stream")
            .args(SMALL)
            .args(["--rate", "50", "--out", "-"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    ));
    let mut pipe = c.0.as_mut().unwrap().stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut b = Vec::new();
        std::io::Read::read_to_end(&mut pipe, &mut b).unwrap();
        b
    });
    std::thread::sleep(Duration::from_millis(300));
    signal(&c, "-INT");
    let o = wait_deadline(c.take(), 30);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let b = reader.join().unwrap();
    let rep = verify(Cursor::new(&b)).unwrap();
    assert_eq!(rep.status, VerifyStatus::Clean, "{rep}");
    // a run of N frames stopped early, and SIGHUP: aborted, ended by the signal
    for (sig, n, extra) in [("-INT", 2, vec!["--frames", "100000"]), ("-HUP", 1, vec![])] {
        let out = d.path().join(format!("cut{sig}.psns"));
        let c =
            spawn_stream(&[&SMALL[..], &["--rate", "50", "--out", s(&out)], &extra[..]].concat());
        wait_for(&out, 4096 + 2 * 8192);
        signal(&c, sig);
        let o = wait_deadline(c.take(), 30);
        assert_eq!(o.status.signal(), Some(n), "{}", stderr(&o));
        let rep = verify(Cursor::new(std::fs::read(&out).unwrap())).unwrap();
        assert_eq!(rep.status, VerifyStatus::Aborted, "{rep}");
    }
}

/// A stream killed while writing a record: verify says unfinished (3), not damaged, and names
/// the record cut short; `psns recover` makes of it the stream `psns stream --frames N` writes.
#[test]
fn a_killed_stream_is_unfinished_and_recover_finishes_it() {
    let d = tempfile::tempdir().unwrap();
    let k = d.path().join("k.psns");
    let opts = ["--width", "256", "--height", "128", "--seed", "3"];
    let c = spawn_stream(&[&opts[..], &["--out", s(&k)]].concat());
    // 256 x 128 Mono16: 65 792-byte records of 17 pages
    let stride = 69_632usize;
    wait_for(&k, 4096 + 5 * stride as u64);
    drop(c); // SIGKILL: nothing patched, nothing flagged
             // the kill landed between writes or inside one; cut the last whole record short, as a kill
             // inside its write leaves it
    let b = std::fs::read(&k).unwrap();
    let whole = (b.len() - 4096) / stride;
    let cut = &b[..4096 + (whole - 1) * stride + stride / 3];
    std::fs::write(&k, cut).unwrap();
    let o = psns(&["verify", s(&k)]);
    assert_eq!(o.status.code(), Some(3), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("UNFINISHED") && out.contains("truncated: 0"),
        "{out}"
    );
    assert!(
        out.contains(&format!("cut short: the last record, frame {}", whole - 1)),
        "{out}"
    );
    let rep = verify(Cursor::new(cut)).unwrap();
    assert_eq!(
        (rep.status, rep.frames),
        (VerifyStatus::Unfinished, whole as u64 - 1)
    );
    assert!(rep.intact() && rep.cut_short.is_some() && rep.truncated.is_empty());
    // damage is what lies between intact frames: the same cut with a whole record after it, or
    // a cut end of a stream whose header counts its frames, is damaged (1)
    let mut mid = b[..4096 + (whole - 2) * stride + stride / 3].to_vec();
    mid.extend_from_slice(&b[4096 + (whole - 1) * stride..4096 + whole * stride]);
    let mut counted = cut.to_vec();
    let mut h = FileHeader::decode(&counted).unwrap();
    h.frame_count = whole as u64;
    counted[..4096].copy_from_slice(&h.encode().unwrap());
    for (name, bytes) in [("mid", &mid), ("counted", &counted)] {
        let p = d.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let o = psns(&["verify", s(&p)]);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stdout(&o));
    }
    // recover: the intact frames, finished, byte for byte what --frames N writes
    let rec = d.path().join("rec.psns");
    let o = psns(&["recover", s(&k), "--out", s(&rec)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains(&format!("recovered {} intact frames", whole - 1)),
        "{e}"
    );
    assert!(
        e.contains(&format!("frame {}", whole - 1)) && e.contains("cut short"),
        "{e}"
    );
    let n = (whole - 1).to_string();
    let direct = d.path().join("direct.psns");
    let o = psns(
        &[
            &["stream"],
            &opts[..],
            &["--frames", &n, "--out", s(&direct)],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&rec).unwrap(),
        std::fs::read(&direct).unwrap()
    );
    assert_eq!(psns(&["verify", s(&rec)]).status.code(), Some(0));
    // an aborted stream is recovered the same way; stdin too
    let piped = psns(&[&["stream"], &opts[..], &["--frames", &n, "--out", "-"]].concat());
    let mut c = Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(["recover", "-", "--out", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = c.stdin.take().unwrap();
    let bytes = cut.to_vec();
    let feed = std::thread::spawn(move || std::io::Write::write_all(&mut input, &bytes).is_ok());
    let o = c.wait_with_output().unwrap();
    assert!(feed.join().unwrap());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(o.stdout, piped.stdout, "recovered through pipes");
    // nothing intact, or not a recording: nothing written
    let empty = d.path().join("e.psns");
    std::fs::write(&empty, &b[..4096 + 100]).unwrap();
    for input in [&empty, &d.path().join("nope")] {
        let out = d.path().join("x.psns");
        let o = psns(&["recover", s(input), "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(!out.exists());
    }
}
