//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test binary uses a subset

use std::io::Write;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

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

/// The Python interpreter for tests that run the readers in `tools/`: `$PSNS_PYTHON` (set by
/// `tools/test` to the project's virtual environment), else `python3`.
pub fn python_cmd() -> Command {
    Command::new(std::env::var_os("PSNS_PYTHON").unwrap_or_else(|| "python3".into()))
}

/// Sets how the child of `cmd` takes SIGINT: `libc::SIG_DFL` gives a child Ctrl-C's default
/// back when the test run was started with SIGINT ignored (`nohup`, a background job, some CI
/// runners), which every child would inherit (and Python then ignores Ctrl-C); `libc::SIG_IGN`
/// makes such a run.
pub fn sigint_disposition(cmd: &mut Command, disposition: libc::sighandler_t) -> &mut Command {
    use std::os::unix::process::CommandExt;
    // SAFETY: signal(2) is async-signal-safe, as pre_exec requires; it only sets the
    // disposition of SIGINT in the forked child, which exec keeps
    unsafe {
        cmd.pre_exec(move || {
            libc::signal(libc::SIGINT, disposition);
            Ok(())
        })
    }
}

/// Panics (the test fails, it never passes silently) when the interpreter lacks numpy.
pub fn require_numpy() {
    let ok = python_cmd()
        .args(["-c", "import numpy"])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        ok,
        "this test runs the numpy stream reader: run the suite with tools/test (it makes .venv with \
         numpy), or point PSNS_PYTHON at a Python that has numpy"
    );
}

/// Makes a FIFO at `p` with mkfifo(1).
pub fn mkfifo(p: &Path) {
    let st = Command::new("mkfifo").arg(p).status().expect("mkfifo");
    assert!(st.success());
}

/// Waits for a child with a deadline (kills it and fails on timeout).
pub fn wait_deadline(mut c: Child, secs: u64) -> Output {
    let t = Instant::now();
    loop {
        if c.try_wait().unwrap().is_some() {
            return c.wait_with_output().unwrap();
        }
        if t.elapsed() > Duration::from_secs(secs) {
            let _ = c.kill();
            let o = c.wait_with_output().unwrap();
            panic!("psns did not end within {secs} s: {}", stderr(&o));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Frame `frame_index` of camera `seed` by the exact path, with its ground truth.
pub fn simulate(
    st: &psns::image::StokesImage,
    i: &psns::camera::Intrinsics,
    cfg: &psns::sensor::SensorConfig,
    seed: u64,
    frame_index: u64,
) -> psns::Result<psns::sensor::RawFrame> {
    use psns::sensor::{FrameOptions, Radiance, Sensor};
    let opts = FrameOptions::exact().with_truth();
    Sensor::new(cfg, i, seed)?.frame(Radiance::Planes(st), frame_index, opts)
}

/// The float image of the ideal model ([`psns::sensor::Sensor::float_image`]) of the camera
/// model of `cfg` (a PSNS preset's model is left out).
pub fn simulate_float(
    st: &psns::image::StokesImage,
    i: &psns::camera::Intrinsics,
    cfg: &psns::sensor::SensorConfig,
) -> psns::Result<psns::image::Image<f32>> {
    let mut c = cfg.clone();
    c.psns = None;
    psns::sensor::Sensor::new(&c, i, 0)?.float_image(st)
}

/// Builds the C stream reader (tools/psns_stream.c) into `dir` and returns its path.
pub fn c_stream_reader(dir: &Path) -> std::path::PathBuf {
    let exe = dir.join("psns_stream_c");
    let st = Command::new("cc")
        .args(["-std=c99", "-O2", "-Wall", "-Werror", "-o"])
        .arg(&exe)
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tools/psns_stream.c"))
        .status()
        .expect("a C compiler (cc) is required");
    assert!(st.success());
    exe
}

/// A small tmpfs mounted for a test (a full file system on demand), unmounted on drop. Mounting
/// needs root, which the test machines and CI have; anywhere else the test fails and says why.
pub struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    /// Mounts a tmpfs of `kib` KiB (rounded up to pages by the kernel).
    pub fn new(kib: u64) -> Tmpfs {
        let dir = tempfile::tempdir().unwrap();
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={kib}k"), "psns-test"])
            .arg(dir.path())
            .output()
            .expect("mount(8)");
        assert!(
            o.status.success(),
            "mounting a {kib} KiB tmpfs for a full-disk test failed (it needs root, as on the test \
             machines and CI): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        Tmpfs { dir }
    }

    /// The mount point.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// Fills the file system up to the last `keep` bytes with a file named `filler`.
    pub fn fill(&self, keep: u64) {
        let st = free_bytes(self.path());
        let free = st.saturating_sub(keep);
        std::fs::write(self.path().join("filler"), vec![0u8; free as usize]).unwrap();
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

/// Free bytes of the file system at `p` (df).
fn free_bytes(p: &Path) -> u64 {
    let o = Command::new("df")
        .args(["--output=avail", "-B1"])
        .arg(p)
        .output()
        .expect("df");
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .nth(1)
        .and_then(|l| l.trim().parse().ok())
        .expect("df --output=avail")
}

/// A test's tool or data is missing: under `.ci/run` (which sets `PSNS_REQUIRE_ALL`, and where
/// everything is installed) the test fails; elsewhere it says SKIPPED past the harness's capture,
/// so the skip is seen. The caller returns after it.
pub fn missing(test: &str, what: &str) {
    if std::env::var_os("PSNS_REQUIRE_ALL").is_some() {
        panic!("{test}: {what}; .ci/run requires it (PSNS_REQUIRE_ALL is set)");
    }
    let _ = writeln!(std::io::stderr().lock(), "SKIPPED {test}: {what}");
}
