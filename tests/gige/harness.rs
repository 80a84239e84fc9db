//! The harness of the device tests: running `psns gige` on its own loopback address, the
//! Aravis tools and Python client under a time limit, and the stream frames to compare with.

use psns::stream::{Event, StreamReader};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::io::{BufRead, BufReader};
use std::net::Ipv4Addr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub(super) const BIN: &str = env!("CARGO_BIN_EXE_psns");

pub(super) fn python() -> String {
    std::env::var("PSNS_SYSTEM_PYTHON").unwrap_or_else(|_| "/usr/bin/python3".into())
}

pub(super) fn client_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gige/aravis.py")
}

/// The tools these tests drive; a missing one fails the test with what to install.
pub(super) fn require_tools() {
    for (tool, pkg) in [
        ("arv-tool-0.8", "aravis-tools-cli"),
        ("arv-camera-test-0.8", "aravis-tools"),
        ("arv-test-0.8", "aravis-tools"),
        ("xmllint", "libxml2-utils"),
        ("gresource", "libglib2.0-bin"),
    ] {
        let ok = Command::new("sh")
            .args(["-c", &format!("command -v {tool}")])
            .output()
            .is_ok_and(|o| o.status.success());
        assert!(
            ok,
            "{tool} is missing: apt-get install {pkg} (tools/test installs it)"
        );
    }
    let gi = Command::new(python())
        .args([
            "-c",
            "import gi; gi.require_version('Aravis', '0.8'); from gi.repository import Aravis",
        ])
        .output()
        .expect("running the system python3");
    assert!(
        gi.status.success(),
        "{} cannot import gi's Aravis: apt-get install python3-gi gir1.2-aravis-0.8 (tools/test installs them)\n{}",
        python(),
        String::from_utf8_lossy(&gi.stderr)
    );
}

/// Runs `prog args` for at most `secs` seconds.
pub(super) fn bounded(secs: u32, prog: &str, args: &[&str]) -> Output {
    Command::new("timeout")
        .args(["-k", "5", &secs.to_string(), prog])
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("running {prog}: {e}"))
}

pub(super) fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs the Python client; its JSON lines.
pub(super) fn client(secs: u32, args: &[&str]) -> Vec<Value> {
    let script = client_script();
    let mut a = vec![script.to_str().unwrap()];
    a.extend_from_slice(args);
    let o = bounded(secs, &python(), &a);
    assert!(o.status.success(), "client {args:?} failed:\n{}", text(&o));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

/// A loopback address no other device of this run uses: 127.P.Q.N with P, Q from the process
/// id and N counting.
pub(super) fn unique_addr() -> Ipv4Addr {
    static NEXT: AtomicU32 = AtomicU32::new(2);
    let pid = std::process::id();
    let n = NEXT.fetch_add(1, Ordering::SeqCst);
    Ipv4Addr::new(
        127,
        (100 + pid % 100) as u8,
        ((pid / 100) % 250) as u8 + 1,
        (n % 250) as u8 + 2,
    )
}

/// A running `psns gige`, stopped (and waited for) when dropped.
pub(super) struct Server {
    child: Child,
    pub(super) addr: Ipv4Addr,
    log: Arc<Mutex<String>>,
    /// One device streams at a time: a device that outlives its client keeps sending to the
    /// client's port (as a camera does until its heartbeat expires), and the system may give
    /// that port to another test's client.
    _one_at_a_time: std::sync::MutexGuard<'static, ()>,
}

static ONE_DEVICE: Mutex<()> = Mutex::new(());

impl Server {
    /// Starts `psns gige ARGS` on a fresh loopback address and waits until it listens.
    pub(super) fn start(args: &[&str]) -> Server {
        for _ in 0..5 {
            if let Some(s) = Server::start_at(unique_addr(), args) {
                return s;
            }
        }
        panic!("psns gige did not start on any of 5 addresses");
    }

    /// `None` when the address is taken (the server exits saying so).
    pub(super) fn start_at(addr: Ipv4Addr, args: &[&str]) -> Option<Server> {
        // a test that failed while holding it does not stop the others
        let guard = ONE_DEVICE.lock().unwrap_or_else(|e| e.into_inner());
        let mut child = Command::new(BIN)
            .arg("gige")
            .args(["--address", &addr.to_string()])
            .args(args)
            .env("PSNS_PROGRESS", "off")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starting psns gige");
        let log = Arc::new(Mutex::new(String::new()));
        let (tx, rx) = std::sync::mpsc::channel();
        {
            let log = log.clone();
            let err = child.stderr.take().unwrap();
            std::thread::spawn(move || {
                for line in BufReader::new(err).lines().map_while(Result::ok) {
                    if line.contains("listening on") {
                        let _ = tx.send(());
                    }
                    let mut l = log.lock().unwrap();
                    l.push_str(&line);
                    l.push('\n');
                }
            });
        }
        let t0 = Instant::now();
        loop {
            if rx.recv_timeout(Duration::from_millis(100)).is_ok() {
                return Some(Server {
                    child,
                    addr,
                    log,
                    _one_at_a_time: guard,
                });
            }
            if let Ok(Some(st)) = child.try_wait() {
                std::thread::sleep(Duration::from_millis(100));
                let l = log.lock().unwrap().clone();
                if l.contains("in use") {
                    return None;
                }
                panic!("psns gige exited ({st}) before listening:\n{l}");
            }
            if t0.elapsed() > Duration::from_secs(120) {
                let _ = child.kill();
                panic!("psns gige did not listen within 120 s");
            }
        }
    }

    pub(super) fn ip(&self) -> String {
        self.addr.to_string()
    }

    pub(super) fn log(&self) -> String {
        self.log.lock().unwrap().clone()
    }

    /// Sends `signal` and waits (at most 20 s) for the exit; its status and log.
    pub(super) fn stop_with(mut self, signal: i32) -> (ExitStatus, String) {
        // SAFETY: kill(2) on the pid of a child this test spawned and has not waited for
        unsafe {
            libc::kill(self.child.id() as i32, signal);
        }
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.child.try_wait().unwrap() {
                std::thread::sleep(Duration::from_millis(100));
                return (st, self.log());
            }
            if t0.elapsed() > Duration::from_secs(20) {
                let _ = self.child.kill();
                panic!(
                    "psns gige did not end within 20 s of signal {signal}:\n{}",
                    self.log()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub(super) fn stop(self) -> String {
        let (st, log) = self.stop_with(libc::SIGTERM);
        assert!(st.success(), "psns gige exited with {st}:\n{log}");
        log
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// sha256 of each frame of `psns stream OPTS EXTRA --frames n`, by frame index.
pub(super) fn stream_hashes(opts: &[&str], extra: &[&str], n: u64) -> Vec<String> {
    let mut h = Vec::new();
    each_stream_frame(opts, extra, n, |p| h.push(hex(&Sha256::digest(p))));
    h
}

/// The payload of each frame of `psns stream OPTS EXTRA --frames n`, read from its stdout.
pub(super) fn each_stream_frame(opts: &[&str], extra: &[&str], n: u64, mut f: impl FnMut(&[u8])) {
    let mut child = Command::new(BIN)
        .arg("stream")
        .args(opts)
        .args(extra)
        .args(["--frames", &n.to_string(), "--out", "-"])
        .env("PSNS_PROGRESS", "off")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut r = StreamReader::new(child.stdout.take().unwrap()).unwrap();
    let mut k = 0;
    while let Some(ev) = r.next_event().unwrap() {
        if let Event::Frame(fr) = ev {
            assert!(fr.payload_crc_ok);
            assert_eq!(fr.meta.index, k);
            f(&fr.payload);
            k += 1;
        }
    }
    assert!(child.wait().unwrap().success());
    assert_eq!(k, n);
}

pub(super) fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

pub(super) fn buffers(lines: &[Value]) -> Vec<&Value> {
    lines.iter().filter(|l| l.get("block").is_some()).collect()
}

pub(super) fn stats(lines: &[Value]) -> &Value {
    &lines.last().expect("output")["stats"]
}

pub(super) fn tmpdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}
