//! `psns bench stream`: frames/s of the stream per stage (sky, sensor, packing, write) and end
//! to end, fast path against `--exact`, and the fast path's error for several sky grids.

use psns::camera::{Attitude, Camera};
use psns::config::SceneConfig;
use psns::io::create_dir;
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::render::{self, SkyGrid, StokesOptions};
use psns::sensor::{packing, FastSink, FrameOptions, Radiance};
use psns::sky::Sky;
use psns::stream::{FrameMeta, StreamWriter};
use psns::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

/// Median milliseconds per stage of one mode.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// "fast" or "exact" (with the grid step for fast).
    pub mode: String,
    /// Sky: node grid (fast) or every pixel (exact), ms.
    pub sky_ms: f64,
    /// Sensor, ms (fast: reading the sky rows from the grid included).
    pub sensor_ms: f64,
    /// Packing into the stream's pixel format with the payload's CRC, ms (as `psns stream`
    /// packs; a little-endian Mono16 stream sends the codes unpacked and skips it).
    pub pack_ms: f64,
    /// Writing the frame's record (header and payload) into a 1 MiB pipe that `cat > /dev/null`
    /// drains, as `psns stream --out - | cat > /dev/null` does, ms. The payload's CRC is taken
    /// where the stream takes it: in the sensor stage (the fast path's Mono16 codes, band by
    /// band) or the packing stage (packed formats), else within the write (`--exact` Mono16).
    /// Timed alone, with the payload warm in cache; in `psns stream` a writer
    /// thread does this while the next frame renders, on the same two cores.
    pub write_ms: f64,
    /// Frames timed per stage (the warm-up frame left out).
    pub frames: usize,
    /// Sum of the render's stage medians (sky, sensor, packing), ms; `fps` is its inverse.
    pub total_ms: f64,
    /// CPU time (user + system, every thread of the process) of the sky, sensor and packing
    /// stages, ms per frame (medians).
    pub cpu_ms: [f64; 3],
    /// Fast path: mean sky nodes, refined cells and pixels evaluated exactly per frame.
    pub nodes: f64,
    /// See `nodes`.
    pub refined_cells: f64,
    /// See `nodes`.
    pub exact_pixels: f64,
}

/// Header of `stream_stages.csv` (and of the lines printed while measuring).
const STAGES_HEADER: &str =
    "mode,sky_ms,sensor_ms,pack_ms,write_ms,total_ms,fps,nodes,refined_cells,exact_pixels";

impl StageTimes {
    /// One line of `stream_stages.csv`.
    fn csv_row(&self) -> String {
        format!(
            "\"{}\",{:.3},{:.3},{:.3},{:.3},{:.3},{:.2},{:.0},{:.0},{:.0}",
            self.mode,
            self.sky_ms,
            self.sensor_ms,
            self.pack_ms,
            self.write_ms,
            self.total_ms,
            1e3 / self.total_ms,
            self.nodes,
            self.refined_cells,
            self.exact_pixels
        )
    }
}

/// The attitude of frame `k` of a turning camera like `psns stream`'s built-in trajectory
/// (level, ENU yaw in steps of 3.6°).
fn attitude(k: usize) -> Attitude {
    Attitude::enu((3.6 * k as f64).rem_euclid(360.0), 0.0, 0.0)
}

/// Per-stage medians over `frames` frames of a turning camera, for the fast path with grid
/// `step` (None = `--exact`).
pub fn stage_times(cfg: &SceneConfig, step: Option<usize>, frames: usize) -> Result<StageTimes> {
    let mut c = cfg.clone();
    match step {
        Some(s) => c.raw.sky_grid = s,
        None => c.raw.exact = true,
    }
    let pipe = RawPipeline::new(&c)?;
    let sun = c.sun.resolve()?;
    let sky = Sky::new(sun, &c.sky)?;
    let opts = StokesOptions {
        sun_disc: c.raw.sun_disc_on(),
    };
    let tol = pipe.grid_tolerance();
    let fmt = c.raw.pixel_format;
    let bits = pipe.sensor_config().bit_depth;
    let (mut sky_t, mut sen_t, mut pack_t, mut write_t) = (vec![], vec![], vec![], vec![]);
    let mut cpu: [Vec<f64>; 3] = Default::default();
    let cpu_now = || super::stream_cpu::cpu_seconds(false);
    let mut refine = [0f64; 3];
    let mut codes = Vec::new();
    let mut payload = Vec::new();
    let mut drain = Drain::start(&c, &pipe)?;
    // one warm-up frame builds the fast path's per-pixel coefficients
    for k in 0..frames + 1 {
        let att = attitude(k);
        let cam = Camera::new(c.intrinsics(), &att, sun.azimuth_deg)?;
        let (t0, c0) = (Instant::now(), cpu_now());
        let frame = match step {
            Some(s) => {
                let grid = SkyGrid::new(&sky, &cam, opts, s, tol);
                let (t1, c1) = (Instant::now(), cpu_now());
                if k > 0 {
                    let (cells, _, px) = grid.refinement();
                    refine[0] += grid.node_count() as f64 / frames as f64;
                    refine[1] += cells as f64 / frames as f64;
                    refine[2] += px as f64 / frames as f64;
                }
                // as psns stream: a Mono16 payload's CRC taken band by band in the sensor pass
                let sink = if packing::codes_are_payload(fmt) {
                    FastSink::CodesCrc32
                } else {
                    FastSink::None
                };
                let opts = FrameOptions::fast()
                    .into_codes(std::mem::take(&mut codes))
                    .with_sink(sink);
                let f = pipe.sensor().frame(Radiance::Rows(&grid), k as u64, opts)?;
                let (t2, c2) = (Instant::now(), cpu_now());
                sky_t.push((t1 - t0).as_secs_f64());
                sen_t.push((t2 - t1).as_secs_f64());
                cpu[0].push(c1 - c0);
                cpu[1].push(c2 - c1);
                f
            }
            None => {
                let (st, _) = render::render_stokes(&sky, &cam, opts);
                let (t1, c1) = (Instant::now(), cpu_now());
                let f = pipe
                    .render(FrameRequest::planes(k as u64, &st).exact())?
                    .frame;
                let (t2, c2) = (Instant::now(), cpu_now());
                sky_t.push((t1 - t0).as_secs_f64());
                sen_t.push((t2 - t1).as_secs_f64());
                cpu[0].push(c1 - c0);
                cpu[1].push(c2 - c1);
                f
            }
        };
        let (t3, c3) = (Instant::now(), cpu_now());
        let packed_crc = packing::pack_crc32(&frame.codes.data, bits, fmt, false, &mut payload)?;
        pack_t.push(t3.elapsed().as_secs_f64());
        cpu[2].push(cpu_now() - c3);
        // the stream's payload and CRC, as `RawPipeline::render` gives them: the codes
        // themselves where they are its bytes (no packing), with the CRC the frame carries
        // (`None` on the exact path: the writer takes it), else the packed bytes and theirs
        let (bytes, crc): (&[u8], _) = if packing::codes_are_payload(fmt) {
            (bytemuck::cast_slice(&frame.codes.data), frame.codes_crc32)
        } else {
            (&payload, Some(packed_crc))
        };
        write_t.push(drain.write(k as u64, bytes, crc)?);
        codes = frame.codes.data;
        if k == 0 {
            sky_t.clear();
            sen_t.clear();
            pack_t.clear();
            write_t.clear();
            cpu.iter_mut().for_each(Vec::clear);
        }
    }
    drain.finish()?;
    let timed = write_t.len();
    debug_assert!([&sky_t, &sen_t, &pack_t].iter().all(|v| v.len() == timed));
    let (a, b, p, wr) = (
        1e3 * median(sky_t),
        1e3 * median(sen_t),
        1e3 * median(pack_t),
        1e3 * median(write_t),
    );
    Ok(StageTimes {
        mode: match step {
            Some(s) => format!("fast, sky grid {s}"),
            None => "exact".into(),
        },
        sky_ms: a,
        sensor_ms: b,
        pack_ms: p,
        write_ms: wr,
        frames: timed,
        total_ms: a + b + p,
        cpu_ms: cpu.map(|v| 1e3 * median(v)),
        nodes: refine[0],
        refined_cells: refine[1],
        exact_pixels: refine[2],
    })
}

/// The write stage's consumer: `cat > /dev/null` reading a pipe with psns stream's 1 MiB
/// buffer, fed by the stream's writer.
struct Drain {
    child: std::process::Child,
    w: Option<StreamWriter<std::process::ChildStdin>>,
}

impl Drain {
    fn start(cfg: &SceneConfig, pipe: &RawPipeline) -> Result<Self> {
        let child = Command::new("cat")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .map_err(|e| Error::io("starting `cat` (the write stage's reader)", e))?;
        // from here on Drop reaps `cat`, also when the header fails
        let mut d = Drain { child, w: None };
        let stdin = d.child.stdin.take().expect("stdin is piped");
        {
            use std::os::fd::AsRawFd;
            crate::cli::stream::grow_pipe(stdin.as_raw_fd());
        }
        let header = crate::cli::stream::stream_header(cfg, pipe, serde_json::json!({}))?;
        d.w = Some(StreamWriter::new(stdin, &header)?);
        Ok(d)
    }
    /// Writes frame `index`'s record, with its payload's CRC when it came with the payload
    /// (`None`: the writer takes it, within the timed write). Returns seconds.
    fn write(&mut self, index: u64, payload: &[u8], crc: Option<u32>) -> Result<f64> {
        let w = self.w.as_mut().expect("not finished");
        let meta = FrameMeta {
            index,
            ..FrameMeta::default()
        };
        let t = Instant::now();
        w.write_payload_crc(&meta, payload, crc)?;
        Ok(t.elapsed().as_secs_f64())
    }
    /// Closes the pipe and waits for `cat`.
    fn finish(mut self) -> Result<()> {
        drop(self.w.take().expect("not finished").finish()?);
        let st = self
            .child
            .wait()
            .map_err(|e| Error::io("waiting for `cat`", e))?;
        if st.success() {
            Ok(())
        } else {
            Err(Error::Invalid(format!(
                "`cat` (the write stage's reader) failed: {st}"
            )))
        }
    }
}

impl Drop for Drain {
    /// On an early return: close the pipe, so `cat` ends, and reap it.
    fn drop(&mut self) {
        drop(self.w.take());
        let _ = self.child.wait();
    }
}

/// One end-to-end run: `psns stream` as a child process, process start included.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EndToEnd {
    /// What was run (shell form; in `bench_stream`, `psns` for the binary and $TMP for its scratch).
    pub command: String,
    /// Frames streamed.
    pub frames: usize,
    /// Median wall seconds of the runs.
    pub seconds: f64,
    /// frames / seconds.
    pub fps: f64,
    /// frames/s of the slowest and the fastest run: on a shared machine the spread says as much
    /// as the median.
    pub fps_range: (f64, f64),
}

/// Runs `sh -c command` `runs` times and reports the median and the spread.
fn time_shell(command: &str, frames: usize, runs: usize) -> Result<EndToEnd> {
    let mut t = Vec::new();
    for _ in 0..runs {
        let t0 = Instant::now();
        let st = Command::new("sh")
            .arg("-c")
            .arg(command)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .map_err(|e| Error::io("running sh", e))?;
        if !st.success() {
            return Err(Error::Invalid(format!("`{command}` failed: {st}")));
        }
        t.push(t0.elapsed().as_secs_f64());
    }
    let (lo, hi) = t
        .iter()
        .fold((f64::INFINITY, 0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    let s = median(t);
    Ok(EndToEnd {
        command: command.to_string(),
        frames,
        seconds: s,
        fps: frames as f64 / s,
        fps_range: (frames as f64 / hi, frames as f64 / lo),
    })
}

/// Options of `psns bench stream`.
pub struct StreamBenchOptions {
    /// Output directory.
    pub out: PathBuf,
    /// Frames per stage measurement.
    pub frames: usize,
    /// Frames per end-to-end run (fast path; exact runs a third of them).
    pub e2e_frames: usize,
    /// End-to-end runs per command (median).
    pub runs: usize,
    /// Sky grids of the fast path to measure.
    pub steps: Vec<usize>,
}

/// `psns bench stream`: prints and writes `stream_e2e.csv`, `stream_targets.csv`,
/// `stream_stages.csv`, `stream_accuracy.csv` and the chart `stream_speed_accuracy.svg`.
pub fn bench_stream(cfg: &SceneConfig, o: &StreamBenchOptions) -> Result<Vec<String>> {
    create_dir(&o.out)?;
    let exe = std::env::current_exe().map_err(|e| Error::io("finding the psns binary", e))?;
    let exe = exe.display().to_string();
    let n = o.e2e_frames;
    let ne = (n / 3).max(10);
    // Scratch for the FIFO, the C reader and render's output; removed at the end.
    let tmp = std::env::temp_dir().join(format!("psns-bench-stream-{}", std::process::id()));
    create_dir(&tmp)?;
    let t = tmp.display();
    let mut commands = vec![(format!("{exe} stream --frames {n} --out /dev/null"), n)];
    for fmt in ["mono16", "mono8", "mono12p"] {
        commands.push((
            format!("{exe} stream --frames {n} --pixel-format {fmt} --out - | cat > /dev/null"),
            n,
        ));
    }
    match build_c_reader(&tmp) {
        Ok(reader) => {
            let r = reader.display();
            for fmt in ["mono16", "mono8", "mono12p"] {
                commands.push((
                    fifo_command(&exe, &t.to_string(), &r.to_string(), n, fmt),
                    n,
                ));
            }
        }
        Err(why) => eprintln!("skipped: the FIFO runs into the C reader ({why})"),
    }
    commands.push((
        format!("{exe} stream --exact --frames {ne} --out /dev/null"),
        ne,
    ));
    commands.push((format!("{exe} render --raw --out {t}/render"), 1));
    let mut e2e = Vec::new();
    let mut rss_mb = None;
    let runs = commands.into_iter().try_for_each(|(c, frames)| {
        let mut r = time_shell(&c, frames, o.runs)?;
        // shown and recorded as run by hand: `psns`, and $TMP for the scratch directory
        r.command = c.replace(&exe, "psns").replace(&t.to_string(), "$TMP");
        eprintln!("{:.1} frames/s ({:.2} s)  {}", r.fps, r.seconds, r.command);
        if e2e.is_empty() {
            // The /dev/null runs are the first children, spawned while this process is still
            // small: a spawned child's peak RSS counts its parent's pages until exec.
            rss_mb = children_max_rss_mb();
        }
        e2e.push(r);
        Ok::<_, Error>(())
    });
    // the scratch goes also when a run failed
    let removed = std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(t.to_string(), e));
    runs?;
    removed?;
    let targets = targets(&e2e, rss_mb);
    eprintln!("target,measured,met");
    for r in &targets {
        eprintln!("{r}");
    }
    let mut stages = Vec::new();
    eprintln!("{STAGES_HEADER}");
    for s in o
        .steps
        .iter()
        .map(|&s| Some(s))
        .chain(std::iter::once(None))
    {
        let n = if s.is_none() {
            o.frames.div_ceil(3).max(2)
        } else {
            o.frames
        };
        let t = stage_times(cfg, s, n)?;
        eprintln!("{}", t.csv_row());
        stages.push(t);
    }
    let acc = accuracy(cfg, &o.steps)?;
    eprintln!("step,max_sigma,p99_sigma,max_s0,p99_s0,max_dolp,p99_dolp,max_aolp_deg,p99_aolp_deg");
    let acc_rows: Vec<String> = acc
        .iter()
        .map(|a| {
            format!(
                "{},{:.4},{:.4},{:.2e},{:.2e},{:.2e},{:.2e},{:.2e},{:.2e}",
                a.step,
                a.max_sigma,
                a.p99_sigma,
                a.max_s0,
                a.p99_s0,
                a.max_dolp,
                a.p99_dolp,
                a.max_aolp_deg,
                a.p99_aolp_deg
            )
        })
        .collect();
    for r in &acc_rows {
        eprintln!("{r}");
    }
    let mut files = Vec::new();
    let p = o.out.join("stream_accuracy.csv");
    write_csv(
        &p,
        "step,max_sigma,p99_sigma,max_s0,p99_s0,max_dolp,p99_dolp,max_aolp_deg,p99_aolp_deg",
        acc_rows.into_iter(),
    )?;
    files.push(p.display().to_string());
    let p = o.out.join("stream_speed_accuracy.svg");
    let svg = chart_svg(&stages, &acc)?;
    std::fs::write(&p, svg).map_err(|e| Error::io(p.display().to_string(), e))?;
    files.push(p.display().to_string());
    let p = o.out.join("stream_stages.csv");
    write_csv(&p, STAGES_HEADER, stages.iter().map(StageTimes::csv_row))?;
    files.push(p.display().to_string());
    let p = o.out.join("stream_e2e.csv");
    write_csv(
        &p,
        "command,frames,seconds,fps,fps_slowest_run,fps_fastest_run",
        e2e.iter().map(|r| {
            format!(
                "\"{}\",{},{:.3},{:.2},{:.2},{:.2}",
                r.command, r.frames, r.seconds, r.fps, r.fps_range.0, r.fps_range.1
            )
        }),
    )?;
    files.push(p.display().to_string());
    let p = o.out.join("stream_targets.csv");
    write_csv(&p, "target,measured,met", targets.into_iter())?;
    files.push(p.display().to_string());
    Ok(files)
}

/// Builds the C reader `tools/psns_stream.c` with `cc -std=c99 -O2` into `dir`; the error says
/// why it could not (no source tree, no compiler).
fn build_c_reader(dir: &Path) -> std::result::Result<PathBuf, String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/psns_stream.c");
    if !src.is_file() {
        return Err(format!("{} not found", src.display()));
    }
    let exe = dir.join("psns_stream_c");
    match Command::new("cc")
        .args(["-std=c99", "-O2", "-o"])
        .arg(&exe)
        .arg(&src)
        .status()
    {
        Ok(s) if s.success() => Ok(exe),
        Ok(s) => Err(format!("cc failed: {s}")),
        Err(e) => Err(format!("no C compiler `cc`: {e}")),
    }
}

/// The largest resident set of any child process waited for so far, MB (Linux reports KiB).
fn children_max_rss_mb() -> Option<f64> {
    // SAFETY: an all-zero rusage is a valid value, and getrusage only writes into it
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: as above
    (unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut ru) } == 0)
        .then(|| ru.ru_maxrss as f64 / 1024.0)
}

/// The FIFO run of `fmt`: `exe stream` into a FIFO in `tmp`, read by the C reader `reader` as a
/// consumer uses it (`check`: every frame's CRCs checked and its values unpacked); fails unless
/// the reader read all `n` frames and reported no damage, and the stream succeeded.
fn fifo_command(exe: &str, tmp: &str, reader: &str, n: usize, fmt: &str) -> String {
    format!(
        "rm -f {tmp}/fifo && mkfifo {tmp}/fifo && {{ {exe} stream --frames {n} --pixel-format \
         {fmt} --out {tmp}/fifo & p=$!; {{ {reader} check {tmp}/fifo; echo status $?; }} | awk \
         '/^frame /{{k++}} /^status 0$/{{ok=1}} END{{exit !(k=={n} && ok)}}'; s=$?; wait $p && \
         [ $s -eq 0 ]; }}"
    )
}

/// A run's command as the targets name it: for the FIFO runs the stream and the reader, not
/// the shell plumbing.
fn target_name(cmd: &str) -> String {
    match cmd.split_once(" && { ") {
        Some((_, rest)) => rest
            .split(" | awk")
            .next()
            .unwrap_or(rest)
            .replace(" & p=$!; { ", " & ")
            .replace("; echo status $?; }", ""),
        None => cmd.to_string(),
    }
}

/// The median frames/s, and the slowest and fastest run when there were several (a CSV field
/// without commas).
fn fps_runs(r: &EndToEnd) -> String {
    let (lo, hi) = r.fps_range;
    if hi > lo {
        format!("{:.1} frames/s (runs {lo:.1} to {hi:.1})", r.fps)
    } else {
        format!("{:.1} frames/s", r.fps)
    }
}

fn targets(e2e: &[EndToEnd], rss_mb: Option<f64>) -> Vec<String> {
    let mut rows = Vec::new();
    let mut row = |what: String, measured: String, met: &str| {
        rows.push(format!("\"{what}\",{measured},{met}"));
    };
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    for r in e2e {
        let cmd = target_name(&r.command);
        if cmd.contains("render --raw") {
            row(
                format!("{cmd} < 1 s"),
                format!("{:.2} s", r.seconds),
                yes_no(r.seconds < 1.0),
            );
        } else if cmd.contains("--exact") {
            let met = yes_no(r.fps >= 10.0);
            row(format!("{cmd} >= 10 frames/s"), fps_runs(r), met);
        } else {
            let met = match r.fps {
                f if f >= 100.0 => "yes",
                f if f >= 75.0 => "floor only",
                _ => "no",
            };
            let what = format!("{cmd} >= 100 frames/s (floor 75)");
            row(what, fps_runs(r), met);
        }
    }
    match rss_mb {
        Some(m) => row(
            "psns stream memory < 300 MB".into(),
            format!("{m:.0} MB"),
            yes_no(m < 300.0),
        ),
        None => row(
            "psns stream memory < 300 MB".into(),
            "not measured".into(),
            "no",
        ),
    }
    rows
}

fn write_csv(path: &Path, header: &str, rows: impl Iterator<Item = String>) -> Result<()> {
    let mut s = String::from(header);
    s.push('\n');
    for r in rows {
        s.push_str(&r);
        s.push('\n');
    }
    let mut f =
        std::fs::File::create(path).map_err(|e| Error::io(path.display().to_string(), e))?;
    f.write_all(s.as_bytes())
        .map_err(|e| Error::io(path.display().to_string(), e))
}

/// Accuracy of the fast path's sky grid against the exact per-pixel sky, pixels outside the
/// solar disc and its 2 IFOV spread: max and 99th percentile.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Accuracy {
    /// Grid step, pixels.
    pub step: usize,
    /// |Δμ| / σ_shot of the mean electrons at the configured exposure.
    pub max_sigma: f64,
    /// See `max_sigma`.
    pub p99_sigma: f64,
    /// |ΔS0| / S0.
    pub max_s0: f64,
    /// See `max_s0`.
    pub p99_s0: f64,
    /// |ΔDoLP|.
    pub max_dolp: f64,
    /// See `max_dolp`.
    pub p99_dolp: f64,
    /// |ΔAoLP|, degrees, where the exact DoLP > 0.02.
    pub max_aolp_deg: f64,
    /// See `max_aolp_deg`.
    pub p99_aolp_deg: f64,
}

fn max_p99(v: &mut [f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let i = ((v.len() - 1) as f64 * 0.99) as usize;
    let p = *v.select_nth_unstable_by(i, |a, b| a.total_cmp(b)).1;
    (v.iter().copied().fold(0.0, f64::max), p)
}

/// The sweep's views: (sun zenith, yaw offset from the sun, pitch offset below it).
const VIEWS: [(f64, f64, f64); 6] = [
    (20.0, 0.0, 0.0),
    (20.0, 150.0, 20.0),
    (60.0, 0.0, 0.0),
    (60.0, 10.0, 8.0),
    (86.0, 0.0, 0.0),
    (86.0, 90.0, -30.0),
];

/// Fast-path accuracy for each grid step over [`VIEWS`] (the scene's sky, sensor and size).
pub fn accuracy(cfg: &SceneConfig, steps: &[usize]) -> Result<Vec<Accuracy>> {
    let pipe = RawPipeline::new(cfg)?;
    let sensor = pipe.sensor();
    let t = match pipe.sensor_config().exposure {
        psns::sensor::Exposure::Fixed { us } => us * 1e-6,
        psns::sensor::Exposure::Auto { .. } => 1e-3,
    };
    let tol = pipe.grid_tolerance();
    let intr = cfg.intrinsics();
    let mut acc: Vec<[Vec<f64>; 4]> = steps.iter().map(|_| Default::default()).collect();
    for &(zenith, dyaw, dpitch) in &VIEWS {
        let sun = psns::sun::SunPosition::new(zenith, 120.0);
        let sky = Sky::new(sun, &cfg.sky)?;
        let att = Attitude::enu(
            120.0 + dyaw,
            (90.0 - zenith - dpitch).clamp(-90.0, 90.0),
            0.0,
        );
        let cam = Camera::new(intr, &att, sun.azimuth_deg)?;
        let opts = StokesOptions { sun_disc: true };
        let (exact, _) = render::render_stokes(&sky, &cam, opts);
        let re = sensor.electron_rate(&exact)?;
        let sun_c = cam.enu_to_camera * sun.vector();
        let ifov = (intr.pixel_pitch_um * 1e-3 / intr.focal_length_mm).to_degrees();
        let keep: Vec<bool> = (0..intr.width * intr.height)
            .map(|i| {
                let Some(d) = intr.ray((i % intr.width) as f64, (i / intr.width) as f64) else {
                    return false;
                };
                d.normalize()
                    .dot(sun_c)
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
                    > 0.27 + 2.0 * ifov
                    && exact.s0.data[i] > 0.0
            })
            .collect();
        for (k, &step) in steps.iter().enumerate() {
            let grid = SkyGrid::new(&sky, &cam, opts, step, tol);
            let rf = sensor.electron_rate_fast(&grid)?;
            let approx = grid.to_image();
            for i in 0..keep.len() {
                if !keep[i] {
                    continue;
                }
                let (me, mf) = (re[i] * t, rf[i] * t);
                acc[k][0].push((mf - me).abs() / me.sqrt().max(1e-9));
                if let Some((rel, dop, aop)) = super::sky::pixel_errors(&exact, &approx, i) {
                    acc[k][1].push(rel);
                    acc[k][2].push(dop);
                    acc[k][3].extend(aop);
                }
            }
        }
    }
    Ok(steps
        .iter()
        .zip(acc.iter_mut())
        .map(|(&step, a)| {
            let (max_sigma, p99_sigma) = max_p99(&mut a[0]);
            let (max_s0, p99_s0) = max_p99(&mut a[1]);
            let (max_dolp, p99_dolp) = max_p99(&mut a[2]);
            let (max_aolp_deg, p99_aolp_deg) = max_p99(&mut a[3]);
            Accuracy {
                step,
                max_sigma,
                p99_sigma,
                max_s0,
                p99_s0,
                max_dolp,
                p99_dolp,
                max_aolp_deg,
                p99_aolp_deg,
            }
        })
        .collect())
}

/// Frames/s of the render path (sum of the stage medians) against the fast path's largest
/// error in shot-noise σ, one point per grid step, with the camera's 75 frames/s.
pub fn chart_svg(stages: &[StageTimes], acc: &[Accuracy]) -> Result<String> {
    use super::demosaic::perr;
    use plotters::prelude::*;
    let pts: Vec<(f64, f64, usize)> = acc
        .iter()
        .filter_map(|a| {
            let s = stages
                .iter()
                .find(|s| s.mode == format!("fast, sky grid {}", a.step))?;
            Some((a.max_sigma.max(1e-4), 1e3 / s.total_ms, a.step))
        })
        .collect();
    let exact_fps = stages
        .iter()
        .find(|s| s.mode == "exact")
        .map(|s| 1e3 / s.total_ms);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 460)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let ymax = pts.iter().map(|p| p.1).fold(120.0, f64::max) * 1.15;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "psns stream, full frame: speed against the fast path's error",
                ("sans-serif", 17),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(55)
            .build_cartesian_2d((1e-4f64..1.0f64).log_scale(), 0f64..ymax)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("largest |fast − exact| mean outside the solar disc, in shot-noise σ")
            .y_desc("frames/s (render path, stage medians)")
            .light_line_style(RGBColor(238, 238, 238))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        for (y, label, col) in [
            (75.0, "camera 75 frames/s", RED),
            (100.0, "target 100", BLUE),
        ] {
            chart
                .draw_series(LineSeries::new([(1e-4, y), (1.0, y)], col.stroke_width(1)))
                .map_err(perr)?
                .label(label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], col));
        }
        chart
            .draw_series(
                pts.iter()
                    .map(|&(x, y, _)| Circle::new((x, y), 5, BLACK.filled())),
            )
            .map_err(perr)?;
        chart
            .draw_series(pts.iter().map(|&(x, y, s)| {
                Text::new(
                    format!("grid {s}"),
                    (x * 1.15, y + 2.0),
                    ("sans-serif", 13).into_font(),
                )
            }))
            .map_err(perr)?;
        if let Some(f) = exact_fps {
            chart
                .draw_series([Text::new(
                    format!("--exact: {f:.1} frames/s, error 0"),
                    (1.2e-4, f + 3.0),
                    ("sans-serif", 13).into_font(),
                )])
                .map_err(perr)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stage is timed, the write stage through `cat` included (a small frame, fast and
    /// exact, Mono16 and a packed format), and a CSV row has the header's fields.
    #[test]
    fn stage_times_cover_every_stage() {
        for fmt in [packing::PixelFormat::Mono16, packing::PixelFormat::Mono12p] {
            let mut cfg = SceneConfig::default();
            cfg.camera.intrinsics = super::super::scenes::intrinsics(96, 64);
            cfg.raw.pixel_format = fmt;
            for step in [Some(16), None] {
                let t = stage_times(&cfg, step, 3).unwrap();
                for (name, v) in [
                    ("sky", t.sky_ms),
                    ("sensor", t.sensor_ms),
                    ("pack", t.pack_ms),
                    ("write", t.write_ms),
                ] {
                    assert!(v.is_finite() && v > 0.0, "{fmt:?} {step:?} {name}: {v}");
                }
                // three frames timed per stage: the warm-up frame left out
                assert_eq!(t.frames, 3);
                // the row read back by the header's names (the quoted mode, then numbers)
                let row = t.csv_row();
                let (mode, numbers) = row.split_once("\",").expect("quoted mode");
                assert_eq!(&mode[1..], t.mode);
                let names: Vec<&str> = STAGES_HEADER.split(',').skip(1).collect();
                let values: Vec<f64> = numbers.split(',').map(|v| v.parse().unwrap()).collect();
                assert_eq!(names.len(), values.len(), "{row}");
                let get = |n: &str| values[names.iter().position(|&m| m == n).unwrap()];
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b.abs().max(1.0);
                assert!(close(get("write_ms"), t.write_ms), "{row}");
                assert!(close(get("pack_ms"), t.pack_ms), "{row}");
                let total = t.sky_ms + t.sensor_ms + t.pack_ms;
                assert!(close(get("total_ms"), total), "{row}");
                assert!(close(get("fps"), 1e3 / total), "{row}");
            }
        }
    }

    /// The runs' spread: the slowest run's frames/s ≤ the median's ≤ the fastest's, and the
    /// targets show it; a single run shows the median alone.
    #[test]
    fn end_to_end_runs_report_their_spread() {
        let r = time_shell("sleep 0.01", 10, 3).unwrap();
        let (lo, hi) = r.fps_range;
        // three runs never take the very same nanoseconds
        assert!(
            lo < hi && lo <= r.fps && r.fps <= hi && lo > 0.0,
            "{lo} {} {hi}",
            r.fps
        );
        let r = EndToEnd {
            command: "psns stream --frames 300 --out /dev/null".into(),
            frames: 300,
            seconds: 3.0,
            fps: 100.0,
            fps_range: (90.0, 110.0),
        };
        assert_eq!(fps_runs(&r), "100.0 frames/s (runs 90.0 to 110.0)");
        let rows = targets(std::slice::from_ref(&r), Some(100.0));
        assert_eq!(
            rows[0],
            "\"psns stream --frames 300 --out /dev/null >= 100 frames/s (floor 75)\",\
             100.0 frames/s (runs 90.0 to 110.0),yes"
        );
        let one = EndToEnd {
            fps_range: (100.0, 100.0),
            ..r
        };
        assert_eq!(fps_runs(&one), "100.0 frames/s");
    }

    #[test]
    fn fifo_runs_are_named_by_stream_and_reader() {
        let c = fifo_command("psns", "$TMP", "$TMP/psns_stream_c", 300, "mono12p");
        assert_eq!(
            target_name(&c),
            "psns stream --frames 300 --pixel-format mono12p --out $TMP/fifo & \
             $TMP/psns_stream_c check $TMP/fifo"
        );
        let plain = "psns stream --frames 300 --out /dev/null";
        assert_eq!(target_name(plain), plain);
    }

    /// The FIFO command runs as written: with a stand-in reader that prints the frame lines
    /// and succeeds it passes; one frame short, or a reader exit status of 1, and it fails.
    #[test]
    fn fifo_command_checks_frames_and_status() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().display().to_string();
        // stands in for `psns stream`: writes the FIFO's frames; the "reader" reads them
        let exe = format!("{d}/stream.sh");
        std::fs::write(
            &exe,
            "#!/bin/sh\nprintf 'frame 0 1\\nframe 1 2\\n' > \"$7\"\n",
        )
        .unwrap();
        let ok = format!("{d}/ok.sh");
        std::fs::write(&ok, "#!/bin/sh\ncat \"$2\"\n").unwrap();
        let bad = format!("{d}/bad.sh");
        std::fs::write(&bad, "#!/bin/sh\ncat \"$2\"; exit 1\n").unwrap();
        for f in [&exe, &ok, &bad] {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(f, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
        let run = |reader: &str, n: usize| {
            let c = fifo_command(&exe, &d, reader, n, "mono16");
            std::process::Command::new("sh")
                .args(["-c", &c])
                .status()
                .unwrap()
                .success()
        };
        assert!(run(&ok, 2));
        assert!(!run(&ok, 3), "a frame short");
        assert!(!run(&bad, 2), "reader status 1");
    }
}
