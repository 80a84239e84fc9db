//! `psns bench stream --cpu`: CPU time per frame (user + system, every thread) of the stream's
//! stages and of whole `psns stream` runs, at each instruction-set level, side by side with a
//! baseline binary, runs alternated so that both see the same machine.

use psns::config::SceneConfig;
use psns::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// CPU seconds (user + system) used so far by this process (`children`: by its waited-for
/// children).
pub fn cpu_seconds(children: bool) -> f64 {
    let who = if children {
        libc::RUSAGE_CHILDREN
    } else {
        libc::RUSAGE_SELF
    };
    // SAFETY: an all-zero rusage is a valid value, and getrusage only writes into it
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: as above
    if unsafe { libc::getrusage(who, &mut ru) } != 0 {
        return f64::NAN;
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(ru.ru_utime) + t(ru.ru_stime)
}

/// An instruction-set level as `PSNS_SIMD` caps it: `None` for the best the CPU has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Level {
    Best,
    Avx2,
}

impl Level {
    fn name(self) -> &'static str {
        match self {
            Level::Best => "best",
            Level::Avx2 => "avx2",
        }
    }
    /// `cmd` at this level: `PSNS_SIMD` set or removed.
    fn apply(self, cmd: &mut Command) {
        match self {
            Level::Best => cmd.env_remove("PSNS_SIMD"),
            Level::Avx2 => cmd.env("PSNS_SIMD", "avx2"),
        };
    }
}

/// One end-to-end run: `exe stream --frames n --out /dev/null` at `level`; (CPU ms per frame,
/// frames/s).
fn stream_run(exe: &Path, level: Level, n: usize) -> Result<(f64, f64)> {
    let mut cmd = Command::new(exe);
    cmd.args(["stream", "--frames", &n.to_string(), "--out", "/dev/null"])
        .env("PSNS_PROGRESS", "off")
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    level.apply(&mut cmd);
    let (c0, t0) = (cpu_seconds(true), Instant::now());
    let st = cmd
        .status()
        .map_err(|e| Error::io(exe.display().to_string(), e))?;
    let (c1, t1) = (cpu_seconds(true), t0.elapsed().as_secs_f64());
    if !st.success() {
        return Err(Error::Invalid(format!(
            "`{} stream` failed: {st}",
            exe.display()
        )));
    }
    Ok((1e3 * (c1 - c0) / n as f64, n as f64 / t1))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The stage rows of this binary at `level`, from a child process (the level is fixed once per
/// process): `psns bench stream --stages-child`.
fn stage_rows(exe: &Path, level: Level, frames: usize) -> Result<Vec<String>> {
    let mut cmd = Command::new(exe);
    cmd.args([
        "bench",
        "stream",
        "--stages-child",
        "--frames",
        &frames.to_string(),
    ])
    .env("PSNS_PROGRESS", "off")
    .stderr(Stdio::null());
    level.apply(&mut cmd);
    let out = cmd
        .output()
        .map_err(|e| Error::io(exe.display().to_string(), e))?;
    if !out.status.success() {
        return Err(Error::Invalid(format!(
            "the stage run at {} failed",
            level.name()
        )));
    }
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| format!("{},{l}", level.name()))
        .collect())
}

/// Header of the stage rows `--stages-child` prints (CPU ms per frame, median over the frames).
pub const STAGE_CPU_HEADER: &str = "sky_cpu_ms,sensor_cpu_ms,pack_cpu_ms,total_cpu_ms";

/// Options of `psns bench stream --cpu`.
pub struct CpuOptions {
    pub out: PathBuf,
    /// Frames per stage measurement.
    pub frames: usize,
    /// Frames per end-to-end run.
    pub e2e_frames: usize,
    /// Alternated runs per binary and level.
    pub runs: usize,
    /// The binary to compare with (e.g. an earlier commit's `target/release/psns`).
    pub baseline: Option<PathBuf>,
}

/// `psns bench stream --cpu`: prints and writes `stream_cpu_stages.csv` and `stream_cpu.csv`.
pub fn bench_cpu(_cfg: &SceneConfig, o: &CpuOptions) -> Result<Vec<String>> {
    psns::io::create_dir(&o.out)?;
    let exe = std::env::current_exe().map_err(|e| Error::io("finding the psns binary", e))?;
    let levels = [Level::Avx2, Level::Best];
    let mut files = Vec::new();
    // stages, this binary
    let mut rows = Vec::new();
    eprintln!("level,{STAGE_CPU_HEADER}");
    for l in levels {
        for r in stage_rows(&exe, l, o.frames)? {
            eprintln!("{r}");
            rows.push(r);
        }
    }
    let p = o.out.join("stream_cpu_stages.csv");
    let text = format!("level,{STAGE_CPU_HEADER}\n{}\n", rows.join("\n"));
    std::fs::write(&p, text).map_err(|e| Error::io(p.display().to_string(), e))?;
    files.push(p.display().to_string());
    // end to end, alternated: this binary and the baseline at each level, run after run
    let mut bins = vec![("psns", exe.clone())];
    if let Some(b) = &o.baseline {
        bins.push(("baseline", b.clone()));
    }
    let mut cpu = vec![vec![Vec::new(); levels.len()]; bins.len()];
    let mut fps = vec![vec![Vec::new(); levels.len()]; bins.len()];
    for run in 0..o.runs {
        for (li, &l) in levels.iter().enumerate() {
            for (bi, (name, path)) in bins.iter().enumerate() {
                let (c, f) = stream_run(path, l, o.e2e_frames)?;
                eprintln!(
                    "run {run} {name} {}: {c:.2} CPU ms per frame, {f:.1} frames/s",
                    l.name()
                );
                cpu[bi][li].push(c);
                fps[bi][li].push(f);
            }
        }
    }
    let mut lines = vec!["binary,level,cpu_ms_per_frame,fps,runs,ratio_to_baseline".to_string()];
    for (li, &l) in levels.iter().enumerate() {
        let base = (bins.len() > 1).then(|| median(cpu[1][li].clone()));
        for (bi, (name, path)) in bins.iter().enumerate() {
            let c = median(cpu[bi][li].clone());
            let ratio = base.map_or(String::new(), |b| format!("{:.3}", c / b));
            lines.push(format!(
                "\"{name} ({})\",{},{c:.2},{:.1},{},{ratio}",
                path.display(),
                l.name(),
                median(fps[bi][li].clone()),
                cpu[bi][li].len()
            ));
        }
    }
    for l in &lines {
        eprintln!("{l}");
    }
    let p = o.out.join("stream_cpu.csv");
    std::fs::write(&p, lines.join("\n") + "\n")
        .map_err(|e| Error::io(p.display().to_string(), e))?;
    files.push(p.display().to_string());
    Ok(files)
}
