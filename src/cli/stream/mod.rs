//! Hardware-in-the-loop streaming (`psns stream`): poses in, raw frames out, as a camera would
//! deliver them.
//!
//! A trajectory (CSV read line by line from a file or stdin, or the built-in turning camera) gives
//! timed ENU attitudes and optionally a place. Each pose goes through the full chain of
//! [`RawPipeline`] (sky model → pinhole camera → IMX250MZR raw mosaic) and becomes one record of a
//! stream in format v1 (`docs/stream-format.md`) written to a file, a FIFO or stdout.
//!
//! Time: every timestamp comes from the trajectory's clock, `start_time + t_s`, never from the
//! host, so the same options and seed give the same bytes (run to run, file or FIFO) — except the
//! frame count a regular file gets patched into its header on close, and the host monotonic clock
//! if `--stamp-host-time` asks for it.
//!
//! Sun: given directly by the scene (`cfg.sun.time` unset, no place in the trajectory) it stays
//! fixed; with a place (scene `sun.place` + `sun.time`, or the trajectory's lat/lon columns) it is
//! NREL SPA at mid-exposure `start_time + t_s + exposure/2` (the configured fixed exposure; with
//! auto-exposure the exposure is not known before rendering, so at exposure start). A sun below the
//! horizon gives a dark frame flagged `SKY_INVALID`.
//!
//! Concurrency: a render thread turns pose k+1 into a packed payload while the calling thread
//! writes frame k (`sync_channel(1)`); the order and bytes do not depend on the timing.

use super::poses::{open_trajectory, Trajectory, TrajectoryArgs};
use super::progress::{Progress, Unit};
use super::signals::{self, die_by, signal_name};
use psns::config::SceneConfig;
use psns::error::{Error, Result};
use psns::options::{finite, whole, RawArgs, SceneArgs, WorldArgs};
use psns::pipeline::{FrameResult, RawPipeline, SceneClock};
use psns::sensor::packing;
use psns::sensor::Exposure;
use psns::stream::{CameraConstants, FileHeader, FrameMeta, FLAG_LAST, JSON_MAX};

mod frames;
pub(crate) mod output;
mod place;
mod splice;
use frames::{write_loop, End, Frames, Next};
pub(crate) use output::grow_pipe;
use output::{FrameKind, OutputSpec, Pixels};
use psns::trajectory::Pose;
use std::path::{Path, PathBuf};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Options of `psns stream`.
#[derive(clap::Args)]
pub struct StreamArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    raw: RawArgs,
    #[command(flatten)]
    world: WorldArgs,
    #[command(flatten)]
    trajectory: TrajectoryArgs,
    /// Output file, FIFO, or - for stdout.
    #[arg(long, default_value = "-", value_name = "PATH|-")]
    out: PathBuf,
    /// Stop after N frames.
    #[arg(long, value_name = "N", value_parser = whole)]
    frames: Option<u64>,
    /// Pace output in real time at FPS against the trajectory clock (default: unpaced).
    #[arg(long, value_parser = finite, value_name = "FPS")]
    rate: Option<f64>,
    /// Stamp the host monotonic clock into frame headers (output no longer byte-identical).
    #[arg(long)]
    stamp_host_time: bool,
    /// Let the scheduler place the render threads (default: worker k of the render pool runs on
    /// the k-th CPU this process may use; frames are the same either way).
    #[arg(long)]
    no_pin: bool,
    #[command(flatten)]
    bag: super::bag::BagArgs,
    /// ROS 2 bag: also the ground-truth DoLP and AoLP (degrees) as 32FC1 images on
    /// /psns/truth/dolp and /psns/truth/aolp.
    #[arg(long)]
    truth_images: bool,
}

/// The refusal to write binary frames to a terminal: `Some(message)` when the output is stdout
/// (`-`, the default) and stdout is a terminal.
fn refuse_terminal(out: &Path, stdout_is_terminal: bool) -> Option<Error> {
    (out.as_os_str() == "-" && stdout_is_terminal).then(|| {
        Error::Invalid(
            "refusing to write binary frames to a terminal: choose --out FILE, or --out - piped \
             into a program (e.g. psns stream --out - | python3 tools/nav_reader.py -)"
                .into(),
        )
    })
}

/// Runs `psns stream`.
pub fn run(a: StreamArgs) -> anyhow::Result<()> {
    use std::io::IsTerminal;
    let bag = a.bag.options(a.truth_images)?;
    if bag.is_some() && a.stamp_host_time {
        return Err(
            Error::Invalid("--stamp-host-time applies to the psns format only".into()).into(),
        );
    }
    if let Some(e) = refuse_terminal(&a.out, bag.is_none() && std::io::stdout().is_terminal()) {
        return Err(e.into());
    }
    let mut cfg = a.scene.scene()?;
    a.raw.apply(&mut cfg)?;
    a.world.apply(&mut cfg)?;
    let opts = StreamOptions {
        trajectory: a.trajectory.trajectory,
        frames: a.frames,
        rate_fps: a.rate,
        start_time: a.trajectory.start_time,
        yaw_rate_deg_s: a.trajectory.yaw_rate,
        frame_interval_ms: a.trajectory.frame_interval_ms,
        stamp_host_time: a.stamp_host_time,
    };
    if let Some(r) = opts.rate_fps {
        psns::error::check_range("rate", r, 1e-6, 1e6)?;
    }
    let out = OutputSpec::check(&a.out, bag)?;
    if !a.no_pin {
        pin_workers();
    }
    signals::catch(&[libc::SIGINT, libc::SIGTERM, libc::SIGHUP]);
    let s = run_stream(&cfg, &opts, out)?;
    eprintln!(
        "streamed {} frames in {:.2} s ({:.2} fps){}{}{}",
        s.frames,
        s.seconds,
        s.frames as f64 / s.seconds.max(1e-9),
        if s.late_frames > 0 {
            format!(", {} late", s.late_frames)
        } else {
            String::new()
        },
        if s.reader_closed {
            ", reader closed the stream"
        } else {
            ""
        },
        s.signal.map_or(String::new(), |sig| format!(
            ", stopped by {}",
            signal_name(sig)
        ))
    );
    match s.signal {
        Some(sig) if s.aborted => die_by(sig),
        _ => Ok(()),
    }
}

/// A frame counts as late under `--rate` when it is ready this long after its due time.
pub const LATE_TOLERANCE: Duration = Duration::from_millis(1);

/// Options of `psns stream` besides the scene and sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamOptions {
    /// Trajectory CSV path, `-` for stdin; `None` = built-in turning generator.
    pub trajectory: Option<PathBuf>,
    /// Stop after this many frames.
    pub frames: Option<u64>,
    /// Pace output in real time at this rate; `None` = unpaced. Frame k is due at
    /// `t0 + k / rate`, t0 = when frame 0 is ready (after the camera set-up and the first render).
    pub rate_fps: Option<f64>,
    /// Trajectory time zero, ISO 8601 UTC; `None` = the scene's `sun.time`, else
    /// [`psns::pipeline::DEFAULT_START_TIME`].
    pub start_time: Option<String>,
    /// Built-in generator: yaw rate, degrees per second.
    pub yaw_rate_deg_s: f64,
    /// Built-in generator: frame interval, ms.
    pub frame_interval_ms: f64,
    /// Stamp host CLOCK_MONOTONIC into frame headers (breaks byte-identical output).
    pub stamp_host_time: bool,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            trajectory: None,
            frames: None,
            rate_fps: None,
            start_time: None,
            yaw_rate_deg_s: 10.0,
            frame_interval_ms: 50.0,
            stamp_host_time: false,
        }
    }
}

/// What a stream run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamSummary {
    /// Frames written.
    pub frames: u64,
    /// Frames that were late against `--rate`.
    pub late_frames: u64,
    /// Wall-clock seconds from the start of frame 0's render to the stream closed.
    pub seconds: f64,
    /// True when the reader closed the output early.
    pub reader_closed: bool,
    /// The signal (SIGINT, SIGTERM, SIGHUP) that stopped the stream.
    pub signal: Option<i32>,
    /// The output was marked aborted (a run with `--frames` stopped early, or SIGHUP) rather
    /// than finished after its last whole frame.
    pub aborted: bool,
}

/// One rendered frame, ready to write.
struct Rendered {
    meta: FrameMeta,
    payload: Payload,
    /// The payload's CRC-32 when it was made with the payload (while the bytes were in cache);
    /// `None`: the writer computes it.
    crc: Option<u32>,
    /// Ground-truth DoLP and AoLP (degrees) for a bag's `--truth-images`.
    truth: Option<(Vec<f32>, Vec<f32>)>,
}

/// A frame's payload: packed bytes, or (little-endian Mono16) the codes themselves, or a bag's
/// Mono16 image message: room for its CDR prefix (`.1` elements), then the codes.
enum Payload {
    Bytes(Vec<u8>),
    Codes(Vec<u16>),
    Message(Vec<u16>, usize),
}

impl Payload {
    /// The pixels for the output.
    fn pixels(&mut self) -> Pixels<'_> {
        match self {
            Payload::Bytes(b) => Pixels::Bytes(b),
            Payload::Codes(c) => Pixels::Bytes(bytemuck::cast_slice(c)),
            Payload::Message(m, lead) => Pixels::Message(bytemuck::cast_slice_mut(m), *lead * 2),
        }
    }
}

/// Everything the render thread needs besides the pipeline.
struct FrameMaker {
    pipe: RawPipeline,
    /// Pose time to stream time, and the sun of each frame.
    clock: SceneClock,
    /// The sensor's exposure (the sun is taken at mid-exposure).
    exposure: Exposure,
    /// What the output takes.
    kind: FrameKind,
    bits_valid: u8,
    /// The last frame's code buffer, reused.
    codes: Vec<u16>,
    /// Payload buffers handed back by the writer, reused (no page faults on fresh memory).
    spare: Option<Receiver<Payload>>,
    /// Payload buffers made so far, and how many may be: [`PAYLOAD_BUFFERS`], and those a
    /// pipe holds on to ([`OutputSpec::retains`]).
    made: usize,
    buffers: usize,
}

/// Payload buffers in circulation: one being rendered, one queued, one being written. When all
/// are out the render thread waits for the writer to hand one back instead of allocating (a
/// fresh 10 MB buffer costs its page faults and zeroing every frame).
const PAYLOAD_BUFFERS: usize = 3;

impl FrameMaker {
    /// A payload buffer back from the writer; `None` = make a new one (the first
    /// `buffers` frames, or the writer is gone).
    fn spare_payload(&mut self) -> Option<Payload> {
        let rx = self.spare.as_ref()?;
        if let Ok(p) = rx.try_recv() {
            return Some(p);
        }
        if self.made < self.buffers {
            self.made += 1;
            return None;
        }
        rx.recv().ok()
    }

    fn render(&mut self, index: u64, pose: &Pose, last: bool) -> Result<Rendered> {
        // buffers the writer has finished with come back: codes (Mono16) or packed bytes
        let mut bytes = Vec::new();
        if let Some(p) = self.spare_payload() {
            match p {
                Payload::Codes(c) | Payload::Message(c, _) => self.codes = c,
                Payload::Bytes(b) => bytes = b,
            }
        }
        let codes = std::mem::take(&mut self.codes);
        // the payload and its CRC come with the frame (the fast path takes the Mono16 CRC band
        // by band, packing takes it chunk by chunk); a bag's image has the codes behind room
        // for the message's CDR prefix
        let (lead, fmt) = (self.kind.lead, self.kind.format);
        let mut req = self
            .clock
            .request(index, pose, &self.exposure)?
            .into_codes(codes, lead)
            .with_payload(fmt, bytes);
        req.truth = self.kind.truth;
        let FrameResult {
            mut frame,
            record,
            payload_crc: crc,
            bytes,
            ..
        } = self.pipe.render(req)?;
        // little-endian Mono16 is the code buffer itself: no packing pass
        let payload = match frame.lead_buffer.take() {
            Some(m) => Payload::Message(m, lead),
            None if packing::codes_are_payload(fmt) => {
                Payload::Codes(std::mem::take(&mut frame.codes.data))
            }
            None => Payload::Bytes(bytes),
        };
        let mut meta = FrameMeta::of_record(&record, self.bits_valid);
        if last {
            meta.flags |= FLAG_LAST;
        }
        let truth = self.kind.truth.then(|| {
            let (dolp, aolp) = frame.truth_dolp_aolp();
            (dolp.data, aolp.data)
        });
        self.codes = frame.codes.data;
        Ok(Rendered {
            meta,
            payload,
            crc,
            truth,
        })
    }
}

/// The file header for a scene: sensor description, camera constants, seed and the scene as JSON.
pub fn stream_header(
    cfg: &SceneConfig,
    pipe: &RawPipeline,
    json_extra: serde_json::Value,
) -> Result<FileHeader> {
    let sc = pipe.sensor_config();
    let intr = cfg.camera.intrinsics;
    let fmt = cfg.raw.pixel_format;
    let (pc, pr) = intr.principal();
    let mut h = FileHeader {
        width: u32::try_from(intr.width)
            .map_err(|_| Error::range("width", intr.width as f64, "1..65535"))?,
        height: u32::try_from(intr.height)
            .map_err(|_| Error::range("height", intr.height as f64, "1..65535"))?,
        pixel_format: fmt,
        bits_valid: packing::bits_valid(fmt, sc.bit_depth),
        msb_aligned: false,
        layout: sc.layout,
        angle_sense: 1,
        frame_count: 0,
        aborted: false,
        seed: cfg.raw.seed,
        camera: CameraConstants {
            pixel_pitch_um: intr.pixel_pitch_um,
            focal_length_mm: intr.focal_length_mm,
            f_number: sc.f_number,
            wavelength_nm: sc.filter_center_nm,
            bandwidth_nm: sc.filter_width_nm,
            full_well_e: sc.full_well_e,
            k0_dn_per_e: sc.k0,
            read_noise_e: sc.read_noise_e,
            principal_col: pc,
            principal_row: pr,
        },
        preset: cfg.raw.preset.to_string(),
        ..FileHeader::default()
    };
    h.json = header_json(cfg, pipe, json_extra);
    h.validate()?;
    Ok(h)
}

/// Compact JSON of the scene (with the sensor in force) and the stream settings, shortened to fit
/// the header: first without the full sensor configuration, then the stream settings alone. The
/// projection and lens the frames were rendered with are always there, as
/// `"optics": {"projection": "rectilinear", "lens": "ideal", "relative_illumination":
/// {"kind": "cospower", "n": 1.5}}` (`psns heading` reads them: the falloff is its flat-field).
fn header_json(cfg: &SceneConfig, pipe: &RawPipeline, extra: serde_json::Value) -> String {
    let mut scene = cfg.clone();
    scene.derived = None;
    // the lens in force (the preset's unless one was set), recorded in the scene and on its own
    let intr = pipe.config().camera.intrinsics;
    scene.camera.intrinsics = intr;
    let optics = serde_json::json!({
        "projection": intr.projection,
        "lens": intr.lens(),
        "relative_illumination": pipe.sensor_config().effective_ri(),
    });
    let with_sensor = {
        let mut s = scene.clone();
        s.raw.sensor = Some(pipe.sensor_config().clone());
        s
    };
    let doc = |s: Option<&SceneConfig>| {
        let mut m = serde_json::Map::new();
        if let Some(s) = s {
            m.insert(
                "scene".into(),
                serde_json::to_value(s).unwrap_or(serde_json::Value::Null),
            );
        }
        m.insert("stream".into(), extra.clone());
        m.insert("optics".into(), optics.clone());
        serde_json::to_string(&serde_json::Value::Object(m)).unwrap_or_default()
    };
    [doc(Some(&with_sensor)), doc(Some(&scene)), doc(None)]
        .into_iter()
        .find(|j| j.len() <= JSON_MAX && !j.contains('\0'))
        .unwrap_or_default()
}

/// Host CLOCK_MONOTONIC in ns (Unix); 0 elsewhere.
fn host_monotonic_ns() -> i64 {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one timespec through a valid pointer to a live local
        if unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) } == 0 {
            // time_t and c_long are i64 on 64-bit Linux, narrower elsewhere
            #[allow(clippy::unnecessary_cast)]
            return (ts.tv_sec as i64)
                .saturating_mul(1_000_000_000)
                .saturating_add(ts.tv_nsec as i64);
        }
        0
    }
    #[cfg(not(unix))]
    {
        0
    }
}

/// The CPUs this process may run on (its affinity mask; Slurm and cgroups narrow it), in order;
/// empty where that is unknown.
fn allowed_cpus() -> Vec<usize> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: a zeroed cpu_set_t is the empty set; sched_getaffinity writes at most its size
        // into it, and CPU_ISSET reads it within CPU_SETSIZE
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
                return Vec::new();
            }
            (0..libc::CPU_SETSIZE as usize)
                .filter(|&c| libc::CPU_ISSET(c, &set))
                .collect()
        }
    }
    #[cfg(not(target_os = "linux"))]
    Vec::new()
}

/// Builds the global rayon pool (its size as rayon chooses: `RAYON_NUM_THREADS` or one per CPU)
/// with worker k pinned to the k-th allowed CPU, round robin; nothing with fewer than two CPUs
/// or where the pool already exists. Why: with the writer, a pipe's reader and the render thread
/// beside two workers on two cores, the scheduler often stacked both workers on one core and left
/// the other idle (`perf sched timehist`, docs/performance.md); pinned, a worker that a reader
/// preempts resumes as soon as the reader sleeps. Frames do not depend on it.
fn pin_workers() {
    let cpus = allowed_cpus();
    if cpus.len() < 2 {
        return;
    }
    let _ = rayon::ThreadPoolBuilder::new()
        .start_handler(move |k| {
            #[cfg(target_os = "linux")]
            // SAFETY: a zeroed cpu_set_t is the empty set; CPU_SET adds one CPU below
            // CPU_SETSIZE (it came from CPU_ISSET's range); sched_setaffinity reads the set for
            // this thread and fails harmlessly (the thread stays where it may run)
            unsafe {
                let mut one: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(cpus[k % cpus.len()], &mut one);
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &one);
            }
            #[cfg(not(target_os = "linux"))]
            let _ = k;
        })
        .build_global();
}

/// Runs `psns stream` into `out` (checked, opened once frame 0 is made).
///
/// Everything is validated (scene, sensor, options, trajectory header) before the output is
/// opened. A malformed trajectory line or an I/O error ends the output marked aborted after the
/// frames before it (a bag is left unfinished) and returns the error. A stop signal ends a run
/// without `--frames` cleanly after the frames already being made, the last flagged LAST
/// (`Ok` with `signal`); with `--frames`, or for SIGHUP, the output is marked aborted (`Ok` with
/// `signal` and `aborted`). A closed reader returns `Ok` with `reader_closed`.
pub fn run_stream(
    cfg: &SceneConfig,
    opts: &StreamOptions,
    out: OutputSpec,
) -> Result<StreamSummary> {
    let start = SceneClock::start_time(cfg, opts.start_time.as_deref())?;
    if out.is_bag() {
        // start_time has checked that the start fits i64 nanoseconds
        psns::ros2::Time::from_unix_ns(start.timestamp_nanos_opt().unwrap_or_default())?;
    }
    let pipe = RawPipeline::new(cfg)?;
    let sc = pipe.sensor_config().clone();
    let Trajectory {
        poses,
        lookahead,
        has_place,
    } = open_trajectory(
        opts.trajectory.as_deref(),
        cfg.camera.attitude,
        opts.yaw_rate_deg_s,
        opts.frame_interval_ms,
    )?;
    let clock = SceneClock::new(cfg, start, has_place)?;
    let traj_kind = match &opts.trajectory {
        None => serde_json::json!({
            "turning": {"yaw_rate_deg_s": opts.yaw_rate_deg_s, "frame_interval_ms": opts.frame_interval_ms}
        }),
        Some(_) => serde_json::json!("csv"),
    };
    let extra = serde_json::json!({
        "start_time": start.to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true),
        "trajectory": traj_kind,
        "attitude_frame": "enu",
    });
    // a fixed sun is recorded as resolved (the default's zenith and azimuth written out, as
    // scene.json has them); a timed one as given, its time and place
    let mut recorded = cfg.clone();
    if !has_place {
        recorded.sun = cfg.sun.filled();
    }
    let header = stream_header(&recorded, &pipe, extra)?;
    let kind = out.frames(&header)?;
    let retains = out.retains();
    let maker = FrameMaker {
        clock,
        exposure: sc.exposure,
        kind,
        bits_valid: packing::bits_valid(kind.format, sc.bit_depth),
        codes: Vec::new(),
        spare: None,
        made: 0,
        buffers: PAYLOAD_BUFFERS + retains,
        pipe,
    };
    let frames = Frames::start(maker, poses, lookahead, opts.frames)?;
    let t_open = Instant::now();
    // the output is opened only once frame 0 is made: bad input in the first pose (a missing
    // column, a time that does not fit the clock) writes nothing at all
    let first = match frames.next() {
        Next::Frame(r) => Some((*r)?),
        Next::End => None,
        Next::Stopped(sig) => die_by(sig),
    };
    if let Some(f) = &first {
        let pixels = header.width as u64 * header.height as u64;
        let saturated = f.meta.saturated.iter().map(|&n| n as u64).sum();
        if let Some(w) = psns::sensor::saturation_warning(saturated, pixels) {
            eprintln!("psns: warning: frame {}: {w}", f.meta.index);
        }
    }
    let mut out = match out.open(&header) {
        Ok(o) => o,
        Err(e) if e.is_broken_pipe() => {
            return Ok(StreamSummary {
                reader_closed: true,
                ..Default::default()
            });
        }
        Err(e) => return Err(e),
    };
    // frames/s and ETA on stderr: a bar on a terminal, plain lines for long jobs otherwise
    let mut progress = Progress::new("psns stream", Unit::Frames, opts.frames, false);
    let mut summary = StreamSummary::default();
    let retain = match retains {
        0 => 0,
        _ => out.splice_payloads(),
    };
    let end = write_loop(
        &mut out,
        first,
        &frames,
        retain,
        opts,
        &mut progress,
        &mut summary,
    );
    drop(progress);
    summary.seconds = t_open.elapsed().as_secs_f64();
    let fin = match end {
        Err(e) if e.is_broken_pipe() => {
            // reader gone; the render thread may be waiting for a trajectory line: leave it
            summary.reader_closed = true;
            return Ok(summary);
        }
        Err(e) => {
            // a failed stream is marked aborted so that no reader takes it for finished
            if let Err(m) = out.abort(&e.to_string()) {
                eprintln!("psns: could not mark the stream aborted in full: {m}");
            }
            return Err(e);
        }
        Ok(End::Done) => {
            frames.join();
            out.finish()
        }
        Ok(End::Finished(sig)) => {
            summary.signal = Some(sig);
            out.finish()
        }
        Ok(End::Stopped(sig)) => {
            summary.signal = Some(sig);
            summary.aborted = true;
            let reason = format!("stopped by {}", signal_name(sig));
            if let Err(m) = out.abort(&reason) {
                eprintln!("psns: could not mark the stream aborted in full: {m}");
            }
            Ok(())
        }
    };
    summary.seconds = t_open.elapsed().as_secs_f64();
    match fin {
        Err(e) if e.is_broken_pipe() => {
            summary.reader_closed = true;
            Ok(summary)
        }
        Err(e) => Err(e),
        Ok(()) => Ok(summary),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn terminal_stdout_is_refused_files_and_pipes_are_not() {
        let e = refuse_terminal(Path::new("-"), true).expect("refused");
        assert!(e.is_usage());
        let m = e.to_string();
        assert!(
            m.contains("terminal") && m.contains("--out FILE") && m.contains("--out -"),
            "{m}"
        );
        assert!(refuse_terminal(Path::new("-"), false).is_none());
        assert!(refuse_terminal(Path::new("run.psns"), true).is_none());
    }

    #[test]
    fn header_json_fits() {
        let mut cfg = SceneConfig::default();
        cfg.camera.intrinsics.width = 64;
        cfg.camera.intrinsics.height = 48;
        let pipe = RawPipeline::new(&cfg).unwrap();
        let h = stream_header(&cfg, &pipe, serde_json::json!({"start_time": "x"})).unwrap();
        assert!(h.json.contains("\"stream\""), "{}", h.json);
        assert!(h.json.contains("\"scene\""), "{}", h.json);
        assert!(h.json.len() <= JSON_MAX);
        assert_eq!(h.width, 64);
        assert_eq!(h.bits_valid, 12);
    }
}
