//! `psns heading`: the camera's yaw from raw frames, as a user with a real camera would call it:
//! pixels, sun position, intrinsics and the IMU's tilt, nothing else.
//!
//! Two inputs: one raw PNG/TIFF mosaic (one CSV row), or a psns frame stream (a file, a FIFO, or
//! `-` for stdin; recognised by its magic), one row per frame with the true yaw from the frame
//! metadata and the error, then summary statistics on stderr. The estimate never reads the true
//! attitude: from a stream it takes the sun (azimuth, elevation) and, with `--imu-tilt`, the pitch
//! and roll, as an IMU would supply them.

use psns::camera::{Intrinsics, Lens, Projection};
use psns::heading::{
    attitude_tilt_deg, attitude_yaw_deg, error_stats, estimate_codes, wrap180, HeadingSetup,
};
use psns::image::Image;
use psns::io::{load_raw, open_input};
use psns::options::{first_given, HeadingArgs, SkyMaskArg};
use psns::sensor::mosaic::MosaicLayout;
use psns::sensor::optics::RelativeIllumination;
use psns::sensor::{Preset, SensorConfig};
use psns::stream::{Event, StreamReader, VerifyReport, VerifyStatus, VerifyTally};
use psns::sun::SunPosition;
use psns::{Error, Result};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Runs `psns heading`: one row of [`IMAGE_HEADER`] for an image, or a row per frame of a stream
/// (see [`STREAM_HEADER`]) and a summary on stderr.
pub fn run(a: HeadingArgs) -> anyhow::Result<()> {
    a.check_method_options()?;
    if is_stream(&a.input)? {
        return match run_stream(&a)? {
            None => Ok(()),
            Some(rep) => {
                eprintln!(
                    "psns: the stream is damaged ({} corrupt, {} truncated, {} dropped frames, {} \
                     streams{}); the rows are its intact frames' (psns verify reports the damage)",
                    rep.corrupt.len(),
                    rep.truncated.len(),
                    rep.dropped,
                    rep.restarts + 1,
                    match rep.count_mismatch {
                        Some((d, n)) => format!("; header declares {d} frames, found {n}"),
                        None => String::new(),
                    }
                );
                Err(anyhow::Error::new(super::NotClean))
            }
        };
    }
    a.check_image_options()?;
    let row = heading_row(&a)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{IMAGE_HEADER}\n{row}")?;
    Ok(())
}

/// `-` (stdin, always read as a stream) or a file that starts with the stream's magic.
fn is_stream(input: &Path) -> Result<bool> {
    if input.as_os_str() == "-" {
        return Ok(true);
    }
    use std::io::Read;
    let meta = std::fs::metadata(input).map_err(|e| Error::input(input, e))?;
    if meta.is_dir() {
        return Err(Error::Invalid(format!(
            "{} is a directory",
            input.display()
        )));
    }
    // A FIFO is read once, and not even opened here: opening lets its writer start, and closing
    // it again before the stream's own open broke the writer's pipe. Only a regular file is
    // peeked at and reopened.
    if !meta.is_file() {
        return Ok(true);
    }
    let mut f = std::fs::File::open(input).map_err(|e| Error::input(input, e))?;
    let mut head = [0u8; 8];
    let n = f.read(&mut head).map_err(|e| Error::input(input, e))?;
    Ok(n == 8 && head == psns::stream::FILE_MAGIC)
}

/// Columns of the CSV row of an image.
pub const IMAGE_HEADER: &str =
    "yaw_deg,confidence,pixels,saturated_pixels,residual_deg,sky_fraction";

fn heading_row(a: &HeadingArgs) -> Result<String> {
    let (setup, beside) = a.image_setup(Some(&a.input))?; // option problems before reading the file
    if let Some(p) = beside {
        let sun = setup.sun;
        eprintln!(
            "psns: the sun (zenith {} deg, azimuth {} deg), camera and sensor from {}",
            sun.zenith_deg,
            sun.azimuth_deg,
            p.display()
        );
    }
    let raw = load_raw(&a.input, MosaicLayout::default(), a.index)?;
    let r = a.estimate_image(&setup, &raw, &a.input.display().to_string())?;
    if let Some(m) = &r.reason {
        eprintln!("psns: {m}");
    }
    let saturated = r.saturated;
    Ok(match r.estimate {
        Some(e) => format!(
            "{:.4},{:.4},{},{saturated},{:.4},{:.4}",
            a.reported_yaw(e.yaw_deg, setup.sun.azimuth_deg),
            e.confidence,
            e.pixels,
            e.residual_deg,
            e.sky_fraction
        ),
        None => format!("nan,0,0,{saturated},nan,0"),
    })
}

/// Columns of the per-frame CSV of a stream.
pub const STREAM_HEADER: &str = "frame_index,yaw_deg,confidence,pixels,true_yaw_deg,error_deg,\
                                 saturated_pixels,ms,residual_deg,sky_fraction";

/// Intrinsics of a stream, its header's, each overridden by an option given; and the relative
/// illumination of its frames: `--vignetting-cos-power`, else the header's `optics` record, else
/// its sensor configuration, else its preset's.
fn stream_optics(
    a: &HeadingArgs,
    h: &psns::stream::FileHeader,
) -> Result<(Intrinsics, RelativeIllumination)> {
    let s = &a.scene;
    let c = &h.camera;
    // the stream's record of its optics; a stream without one was rendered rectilinear through
    // the pinhole
    let doc: Option<serde_json::Value> = serde_json::from_str(&h.json).ok();
    let optics: Option<serde_json::Value> = doc.as_ref().and_then(|v| v.get("optics").cloned());
    let recorded_ri = optics
        .as_ref()
        .and_then(|o| o.get("relative_illumination"))
        .and_then(|v| serde_json::from_value::<RelativeIllumination>(v.clone()).ok());
    let sensor_ri = || {
        doc.as_ref()
            .and_then(|v| v.pointer("/scene/raw/sensor"))
            .and_then(|v| serde_json::from_value::<SensorConfig>(v.clone()).ok())
            .map(|sc| sc.effective_ri())
    };
    let preset_ri = || {
        h.preset
            .parse::<Preset>()
            .map(|p| SensorConfig::preset(p).effective_ri())
            .unwrap_or_default()
    };
    let ri = a.flat_field(recorded_ri.or_else(sensor_ri).unwrap_or_else(preset_ri))?;
    let recorded = |key: &str| -> Option<String> {
        optics
            .as_ref()
            .and_then(|o| o.get(key))
            .and_then(|v| v.as_str())
            .map(str::to_string)
    };
    let projection = match (s.projection, recorded("projection")) {
        (Some(p), _) => p,
        (None, Some(p)) => p.parse()?,
        (None, None) => Projection::Rectilinear,
    };
    let lens = match (s.lens, recorded("lens")) {
        (Some(l), _) => l,
        (None, Some(l)) => l.parse()?,
        (None, None) => Lens::Pinhole,
    };
    let i = Intrinsics {
        width: h.width as usize,
        height: h.height as usize,
        focal_length_mm: s.focal_length.unwrap_or(c.focal_length_mm),
        pixel_pitch_um: s.pixel_pitch.unwrap_or(c.pixel_pitch_um),
        principal_point: Some(
            s.principal_point
                .unwrap_or([c.principal_col, c.principal_row]),
        ),
        projection,
        lens: Some(lens),
    };
    for (name, v, have) in [("width", s.width, i.width), ("height", s.height, i.height)] {
        if let Some(v) = v {
            if v != have as i64 {
                return Err(Error::Invalid(format!(
                    "--{name} {v} disagrees with the stream's frames ({} x {})",
                    h.width, h.height
                )));
            }
        }
    }
    i.validate()?;
    Ok((i, ri))
}

/// Estimates every frame of a stream, printing a row each and the summary; returns the stream's
/// verify report when it is damaged (`psns verify` would exit 1: the rows are those of its intact
/// frames).
fn run_stream(a: &HeadingArgs) -> Result<Option<VerifyReport>> {
    let s = &a.scene;
    if let Some(name) = first_given(&[
        ("sun-zenith", s.sun_zenith.is_some()),
        ("sun-altitude", s.sun_altitude.is_some()),
        ("sun-azimuth", s.sun_azimuth.is_some()),
        ("time", s.time.is_some()),
    ]) {
        return Err(Error::Invalid(format!(
            "--{name}: a stream's frames carry the sun position; give no sun options"
        )));
    }
    if a.bits.is_some() {
        return Err(Error::Invalid(
            "--bits: a stream's header gives the bit depth".into(),
        ));
    }
    if a.preset.is_some() {
        return Err(Error::Invalid(
            "--preset: a stream's header records its preset and optics (--lens, --projection and --vignetting-cos-power override them)".into(),
        ));
    }
    let (pitch, roll) = a.given_tilt()?;
    let mask = a.given_mask()?;
    keep_heap();
    let reader = StreamReader::new(open_input(&a.input)?)?;
    let (mut intr, mut ri) = stream_optics(a, reader.header())?;
    let mut out = std::io::stdout().lock();
    let w = |out: &mut std::io::StdoutLock, line: &str| -> Result<()> {
        writeln!(out, "{line}")
            .and_then(|_| out.flush())
            .map_err(|e| Error::io("writing stdout", e))
    };
    w(&mut out, STREAM_HEADER)?;
    let (mut errors, mut frames, mut none) = (Vec::new(), 0usize, 0usize);
    let mut total_s = 0.0;
    let mut source = FrameSource::start(reader, a.index, a.latest);
    let mut generation = 0u64;
    let mut warm: Option<(f64, f64)> = None;
    let mut codes_buf: Vec<u16> = Vec::new();
    while let Some((gen, h, f)) = source.next()? {
        if gen != generation {
            // the stream restarted with a new header
            generation = gen;
            (intr, ri) = stream_optics(a, &h)?;
            warm = None;
        }
        let t0 = Instant::now();
        let h = &h;
        // the codes and (below) the payload buffers go round frame after frame: no fresh pages
        f.codes_into(h, &mut codes_buf)?;
        let codes = Image::from_vec(
            h.width as usize,
            h.height as usize,
            std::mem::take(&mut codes_buf),
        );
        let black = if h.msb_aligned {
            f.meta.black_level / 2f64.powi(16 - h.bits_valid as i32)
        } else {
            f.meta.black_level
        };
        let m = &f.meta;
        let sun = SunPosition::new(90.0 - m.sun_elevation_deg, m.sun_azimuth_deg);
        let (p, r) = if a.imu_tilt {
            attitude_tilt_deg(m.attitude_wxyz)
        } else {
            (pitch, roll)
        };
        let mut setup = HeadingSetup::new(intr, sun);
        setup.pitch_deg = p;
        setup.roll_deg = r;
        setup.fit_elevation = a.fit_sun_elevation;
        setup.relative_illumination = ri;
        setup.find_mask = a.mask == SkyMaskArg::Auto;
        if a.warm_start {
            setup.warm_start = warm;
        }
        let est = if sun.check_up().is_err() {
            eprintln!(
                "psns: frame {}: sun elevation {} deg, below the horizon",
                m.index, m.sun_elevation_deg
            );
            (None, 0, None)
        } else {
            let r = estimate_codes(
                &codes,
                black,
                h.layout,
                h.bits_valid,
                a.demosaic,
                a.method,
                &setup,
                mask.as_ref(),
            )?;
            if let Some(m) = &r.reason {
                eprintln!("psns: {m}");
            }
            (r.estimate, r.saturated, r.info)
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        codes_buf = codes.data;
        source.recycle(f.payload);
        total_s += ms / 1e3;
        frames += 1;
        // the truth is read only here, after the estimate, for the error column
        let truth = a.reported_yaw(attitude_yaw_deg(m.attitude_wxyz), m.sun_azimuth_deg);
        // the next frame starts from this one's neutral points, if this one was trustworthy
        warm = match (&est.0, &est.2) {
            (Some(e), Some(i)) if e.confidence >= 0.5 => Some((i.babinet_deg, i.brewster_deg)),
            _ => None,
        };
        let line = match (est.0, est.1) {
            (Some(e), sat) => {
                let yaw = a.reported_yaw(e.yaw_deg, m.sun_azimuth_deg);
                let err = wrap180(yaw - truth);
                errors.push(err);
                format!(
                    "{},{yaw:.4},{:.4},{},{truth:.4},{err:.4},{sat},{ms:.1},{:.4},{:.4}",
                    m.index, e.confidence, e.pixels, e.residual_deg, e.sky_fraction
                )
            }
            (None, sat) => {
                none += 1;
                format!("{},nan,0,0,{truth:.4},nan,{sat},{ms:.1},nan,0", m.index)
            }
        };
        w(&mut out, &line)?;
    }
    let (damaged, skipped, report) = source.finish()?;
    let st = error_stats(&errors);
    let skipped = if a.latest {
        format!(", {skipped} skipped for newer frames")
    } else {
        String::new()
    };
    eprintln!(
        "psns heading: {frames} frames ({none} without an estimate, {damaged} damaged{skipped}); error RMS {:.4} deg, p95 {:.4}, max {:.4}; {:.1} ms per frame",
        st.rms,
        st.p95,
        st.max,
        if frames > 0 { total_s * 1e3 / frames as f64 } else { f64::NAN }
    );
    Ok(report.filter(|r| r.status == VerifyStatus::Damaged))
}

/// Keeps freed memory in the heap for reuse: glibc serves allocations from 128 KiB up (the
/// model fit's per-frame vectors, the sampled Stokes images) with fresh mmaps, and raises that
/// threshold only past the size freed, so same-size allocations frame after frame fault in and
/// zero new pages every frame (≈ 10 % of a full-size frame's CPU). A stream consumer's working
/// set is a few tens of MB, so it is kept.
fn keep_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; it fails harmlessly (returns 0)
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

type Reader = StreamReader<Box<dyn std::io::Read + Send + Sync>>;

/// Where `psns heading` takes a stream's frames from: a reader thread that reads ahead of the
/// estimator, so reading the next frame overlaps estimating this one. In order, it holds up to
/// [`READ_AHEAD`] frames and then waits (the FIFO then fills and the producer's writes block, as
/// with no thread); with `--latest` it holds only the newest complete frame, replacing older
/// ones. Yields (header generation, header, frame).
struct FrameSource {
    shared: std::sync::Arc<(std::sync::Mutex<Mailbox>, std::sync::Condvar)>,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// Frames the in-order reader thread holds ready for the estimator.
const READ_AHEAD: usize = 2;

/// The frames between the reader thread and the estimator.
#[derive(Default)]
struct Mailbox {
    queue: std::collections::VecDeque<(u64, psns::stream::FileHeader, psns::stream::Frame)>,
    done: bool,
    error: Option<Error>,
    damaged: usize,
    skipped: usize,
    /// Payload buffers the estimator is done with, for the reader thread to read into.
    returned: Vec<Vec<u8>>,
    /// The stream as `psns verify` reports it, once read to its end.
    report: Option<VerifyReport>,
}

/// A frame event of a stream as `psns heading` treats it: `Some` for a good frame (of the
/// `--index` wanted), `None` for anything else (reported on stderr; `damaged` counts damage).
fn usable_frame(
    ev: Event,
    index: Option<u64>,
    damaged: &mut usize,
    generation: &mut u64,
) -> Option<psns::stream::Frame> {
    match ev {
        Event::Frame(f) => {
            if index.is_some_and(|n| n != f.meta.index) {
                return None;
            }
            if !f.payload_crc_ok {
                *damaged += 1;
                eprintln!(
                    "psns: frame {}: payload CRC mismatch, skipped",
                    f.meta.index
                );
                return None;
            }
            Some(f)
        }
        Event::Restart(_) => {
            *generation += 1;
            None
        }
        Event::Gap { from, to } => {
            eprintln!("psns: frames {from}..{to} missing (dropped)");
            None
        }
        Event::Corrupt { index, reason, .. } => {
            *damaged += 1;
            eprintln!("psns: damaged record ({}): {reason}", frame_name(index));
            None
        }
        Event::Truncated {
            index, have, need, ..
        } => {
            *damaged += 1;
            eprintln!(
                "psns: stream ends inside a record ({}: {have} of {need} bytes)",
                frame_name(index)
            );
            None
        }
        Event::Skipped { .. } => None,
        Event::Aborted { reason, .. } => {
            eprintln!("psns: the stream was aborted by its producer: {reason}");
            None
        }
    }
}

/// "frame N", or "frame index unreadable" for a record whose index is unknown.
fn frame_name(index: Option<u64>) -> String {
    match index {
        Some(i) => format!("frame {i}"),
        None => "frame index unreadable".to_string(),
    }
}

impl FrameSource {
    /// Starts the reader thread. In order (`latest` false) it waits while [`READ_AHEAD`] frames
    /// are queued; with `latest` it keeps only the newest good frame, counting the ones it
    /// replaces before the estimator took them.
    fn start(mut reader: Reader, index: Option<u64>, latest: bool) -> FrameSource {
        use std::sync::{Arc, Condvar, Mutex};
        let shared = Arc::new((Mutex::new(Mailbox::default()), Condvar::new()));
        let sh = shared.clone();
        let thread = std::thread::spawn(move || {
            let (lock, cv) = &*sh;
            let (mut generation, mut damaged) = (0u64, 0usize);
            // the stream's state as psns verify reports it, for the exit code
            let mut tally = VerifyTally::new(reader.header().clone(), None);
            let result = (|| -> Result<()> {
                while let Some(ev) = reader.next_event()? {
                    tally.record(&ev);
                    let Some(f) = usable_frame(ev, index, &mut damaged, &mut generation) else {
                        continue;
                    };
                    let h = reader.header().clone();
                    let mut m = lock.lock().unwrap_or_else(|p| p.into_inner());
                    if latest {
                        if let Some(old) = m.queue.pop_front() {
                            m.skipped += 1;
                            reader.recycle(old.2.payload);
                        }
                    } else {
                        while m.queue.len() >= READ_AHEAD {
                            m = cv.wait(m).unwrap_or_else(|p| p.into_inner());
                        }
                    }
                    m.queue.push_back((generation, h, f));
                    for b in m.returned.drain(..) {
                        reader.recycle(b);
                    }
                    cv.notify_all();
                }
                Ok(())
            })();
            let mut m = lock.lock().unwrap_or_else(|p| p.into_inner());
            m.done = true;
            m.damaged = damaged;
            m.report = Some(tally.finish(reader.restart_offsets()));
            m.error = result.err();
            cv.notify_all();
        });
        FrameSource {
            shared,
            thread: Some(thread),
        }
    }

    fn next(&mut self) -> Result<Option<(u64, psns::stream::FileHeader, psns::stream::Frame)>> {
        let (lock, cv) = &*self.shared;
        let mut m = lock.lock().unwrap_or_else(|p| p.into_inner());
        loop {
            if let Some(x) = m.queue.pop_front() {
                cv.notify_all(); // a place in the queue for the reader
                return Ok(Some(x));
            }
            if m.done {
                return Ok(None);
            }
            m = cv.wait(m).unwrap_or_else(|p| p.into_inner());
        }
    }

    /// Gives a frame's payload buffer back to the reader, for a later frame.
    fn recycle(&mut self, payload: Vec<u8>) {
        let mut m = self.shared.0.lock().unwrap_or_else(|p| p.into_inner());
        if m.returned.len() < READ_AHEAD + 1 {
            m.returned.push(payload);
        }
    }

    /// (damaged records, frames skipped for newer ones, the stream's verify report); the reader
    /// thread's error, if any.
    fn finish(&mut self) -> Result<(usize, usize, Option<VerifyReport>)> {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let mut m = self.shared.0.lock().unwrap_or_else(|p| p.into_inner());
        match m.error.take() {
            Some(e) => Err(e),
            None => Ok((m.damaged, m.skipped, m.report.take())),
        }
    }
}
