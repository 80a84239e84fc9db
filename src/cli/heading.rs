//! `psns heading`: the camera's yaw from raw frames, as a user with a real camera would call it:
//! pixels, sun position, intrinsics and the IMU's tilt, nothing else.
//!
//! Two inputs: one raw PNG/TIFF mosaic (one CSV row), or a psns frame stream (a file, a FIFO, or
//! `-` for stdin; recognised by its magic), one row per frame with the true yaw from the frame
//! metadata and the error, then summary statistics on stderr. The estimate never reads the true
//! attitude: from a stream it takes the sun (azimuth, elevation) and, with `--imu-tilt`, the pitch
//! and roll, as an IMU would supply them.

use super::args::SceneArgs;
use super::demosaic::{demosaic_codes, load_raw, LoadedRaw};
use clap::Args;
use psns::camera::{Attitude, Intrinsics, Lens, Projection};
use psns::demosaic::superpixel::superpixel_sampled;
use psns::demosaic::Method;
use psns::heading::{
    attitude_tilt_deg, attitude_yaw_deg, error_stats, estimate_heading_info, mask_saturated,
    mask_saturated_sampled, sampled_intrinsics, superpixel_step, wrap180, HeadingEstimate,
    HeadingMethod, HeadingSetup, ModelFitInfo, PolarView,
};
use psns::image::Image;
use psns::sensor::mosaic::MosaicLayout;
use psns::sensor::optics::RelativeIllumination;
use psns::sensor::{Preset, SensorConfig};
use psns::stream::{Event, StreamReader};
use psns::sun::SunPosition;
use psns::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `psns heading`.
#[derive(Args)]
pub struct HeadingArgs {
    /// Raw PNG/TIFF mosaic (codes), or a psns frame stream (file, FIFO, or - for stdin).
    pub(crate) input: PathBuf,
    /// Sun position (--sun-zenith/--sun-azimuth or --time/--lat/--lon), intrinsics
    /// (--width/--height/--focal-length/--pixel-pitch) and the known tilt (--pitch/--roll, ENU).
    /// A stream gives the sun per frame and the intrinsics in its header (options override them).
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// Demosaic method (the whole frame). Default: bilinear; a frame of more than about 640 000
    /// pixels (the full 2448 x 2048 sensor) is instead read as every k-th 2 x 2 superpixel only
    /// (k even, about 40 000 samples: what the estimators read), the rest never demosaicked.
    #[arg(long, value_parser = |s: &str| s.parse::<Method>().map_err(|e| e.to_string()))]
    pub(crate) demosaic: Option<Method>,
    /// Estimator: model-fit (Berry field fitted from the eigenvector answer; default, the most
    /// accurate), eigen (sun vector), hough (solar meridian).
    #[arg(long, default_value = "model-fit", value_parser = |s: &str| s.parse::<HeadingMethod>().map_err(|e| e.to_string()))]
    pub(crate) method: HeadingMethod,
    /// Model fit: also fit the sun's elevation (one neutral-point distance), starting from the
    /// given or the stream's sun; for a sun position known only roughly.
    #[arg(long)]
    pub(crate) fit_sun_elevation: bool,
    /// Significant bits of the codes in a PNG/TIFF (saturation is the top code); a stream says.
    #[arg(long, value_parser = super::args::whole)]
    pub(crate) bits: Option<u64>,
    /// Stream input: only the frame with this index (`--frame` is the attitude frame of the
    /// scene options).
    #[arg(long, value_parser = super::args::whole, value_name = "N")]
    pub(crate) index: Option<u64>,
    /// Stream input: take each frame's pitch and roll (never its yaw) from the frame's attitude,
    /// as an IMU would supply them; otherwise --pitch/--roll (default level).
    #[arg(long, conflicts_with_all = ["pitch", "roll"])]
    pub(crate) imu_tilt: bool,
    /// Stream input, for a consumer slower than the camera: always estimate the newest complete
    /// frame. A reader thread keeps draining the stream (so a slow estimate never blocks the
    /// producer's writes) and keeps only the latest frame; frames replaced before the estimator
    /// took them are skipped, counted in the summary and missing from the rows (frame_index
    /// shows the gaps).
    #[arg(long)]
    pub(crate) latest: bool,
    /// Stream input, model fit: start each frame's neutral-point distances from the previous
    /// frame's fit (when its confidence was at least 0.5) and set the robust weights from the
    /// first residuals; the yaw still starts from the frame's own eigenvector answer.
    #[arg(long)]
    pub(crate) warm_start: bool,
    /// Image input: the sensor preset the frame was made with (camera, nfpi, gniipi, gniicpi), as
    /// in `psns render --raw`: its lens is the default of --lens and its relative illumination the
    /// flat-field law. A stream's header records both.
    #[arg(long, value_parser = super::args::parse_preset)]
    pub(crate) preset: Option<Preset>,
    /// Flat-field law of the intensity vote (the 180° decision with the sun within 8° of the
    /// horizon): the frames' relative illumination is cos^N of the field angle (0 = none).
    /// Default: an image's --preset (camera cos^1.5, gniipi/gniicpi cos^4, nfpi none); a
    /// stream's recorded optics (or its preset).
    #[arg(long, value_name = "N")]
    pub(crate) vignetting_cos_power: Option<f64>,
}

/// The relative illumination to flat-field S0 by: `--vignetting-cos-power`, else `default`.
fn flat_field(a: &HeadingArgs, default: RelativeIllumination) -> Result<RelativeIllumination> {
    Ok(match a.vignetting_cos_power {
        Some(n) => {
            let ri = if n == 0.0 {
                RelativeIllumination::None
            } else {
                RelativeIllumination::CosPower { n }
            };
            ri.validate()
                .map_err(|_| Error::range("vignetting-cos-power", n, "0..8"))?;
            ri
        }
        None => default,
    })
}

/// Runs `psns heading`: one row `yaw_deg,confidence,pixels,saturated_pixels` for an image, or a
/// row per frame of a stream (see [`STREAM_HEADER`]) and a summary on stderr.
pub fn run(a: HeadingArgs) -> anyhow::Result<()> {
    check_method_options(&a)?;
    if is_stream(&a.input)? {
        return Ok(run_stream(&a)?);
    }
    check_image_options(&a)?;
    let row = heading_row(&a)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "yaw_deg,confidence,pixels,saturated_pixels\n{row}")?;
    Ok(())
}

/// Options that need a particular `--method`.
fn check_method_options(a: &HeadingArgs) -> Result<()> {
    if a.fit_sun_elevation && a.method != HeadingMethod::ModelFit {
        return Err(Error::Invalid(format!(
            "--fit-sun-elevation applies to --method model-fit, not {}",
            a.method
        )));
    }
    if a.warm_start && a.method != HeadingMethod::ModelFit {
        return Err(Error::Invalid(format!(
            "--warm-start applies to --method model-fit, not {}",
            a.method
        )));
    }
    Ok(())
}

/// The option checks of one image (not a stream), shared with `psns.heading` in Python.
pub(crate) fn check_image_options(a: &HeadingArgs) -> Result<()> {
    check_method_options(a)?;
    for (name, given) in [
        ("imu-tilt", a.imu_tilt),
        ("latest", a.latest),
        ("warm-start", a.warm_start),
    ] {
        if given {
            return Err(Error::Invalid(format!(
                "--{name} applies to stream input only"
            )));
        }
    }
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

/// The tilt given as --pitch/--roll (ENU Euler attitude), refusing a yaw or a quaternion.
fn given_tilt(a: &HeadingArgs) -> Result<(f64, f64)> {
    if a.scene.yaw.is_some() || a.scene.quaternion.is_some() {
        return Err(Error::Invalid(
            "psns heading estimates the yaw: give only the tilt (--pitch, --roll)".into(),
        ));
    }
    match a.scene.scene()?.camera.attitude {
        Attitude::Euler {
            pitch_deg,
            roll_deg,
            ..
        } => Ok((pitch_deg, roll_deg)),
        Attitude::Quaternion { .. } => Err(Error::Invalid(
            "psns heading takes the tilt as --pitch/--roll, not a quaternion".into(),
        )),
    }
}

/// Demosaics one mosaic (codes minus the black level) and masks the pixels next to a code at
/// full scale of `bits` (DoLP = NaN); returns the images and the number of masked pixels.
pub fn polar_from_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Method,
) -> Result<(psns::demosaic::PolarImages, usize)> {
    psns::demosaic::check_raw(codes)?;
    let full = ((1u32 << bits) - 1).min(65535) as u16;
    let mut p = demosaic_codes(codes, black_level, layout, demosaic)?;
    let saturated = mask_saturated(&mut p.dolp, codes, full);
    Ok((p, saturated))
}

/// [`polar_from_codes`] for what the estimators read: with no `--demosaic` and a frame large
/// enough ([`superpixel_step`]), every k-th superpixel only, with the intrinsics of that sampled
/// view ([`sampled_intrinsics`]) in the returned setup; otherwise the whole frame.
fn polar_for_estimate(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Option<Method>,
    setup: &HeadingSetup,
) -> Result<(psns::demosaic::PolarImages, usize, HeadingSetup)> {
    let k = superpixel_step(codes.width, codes.height);
    match (demosaic, k) {
        (None, Some(k)) => {
            let full = ((1u32 << bits) - 1).min(65535) as u16;
            let mut p = superpixel_sampled(codes, layout, k, black_level as f32)?;
            let saturated = mask_saturated_sampled(&mut p.dolp, codes, full, k);
            let mut s = *setup;
            s.intrinsics = sampled_intrinsics(&setup.intrinsics, k);
            s.step = 1;
            Ok((p, saturated, s))
        }
        (d, _) => {
            let (p, saturated) = polar_from_codes(
                codes,
                black_level,
                layout,
                bits,
                d.unwrap_or(Method::Bilinear),
            )?;
            Ok((p, saturated, *setup))
        }
    }
}

/// The estimate from one mosaic: demosaic, mask clipped pixels, estimate. `Ok(None)` when too few
/// pixels are usable (the reason on stderr); also returns the number of masked pixels.
fn estimate_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Option<Method>,
    method: HeadingMethod,
    setup: &HeadingSetup,
) -> Result<(Option<HeadingEstimate>, usize, Option<ModelFitInfo>)> {
    let (p, saturated, setup) =
        polar_for_estimate(codes, black_level, layout, bits, demosaic, setup)?;
    let view = PolarView {
        aolp_deg: &p.aolp_deg,
        dolp: &p.dolp,
        s0: Some(&p.stokes.s0),
    };
    match estimate_heading_info(method, &view, &setup) {
        Ok((e, info)) => Ok((Some(e), saturated, info)),
        // too few usable pixels (saturated, unpolarized): no heading, zero confidence
        Err(Error::Invalid(m)) if m.starts_with("heading: only") => {
            eprintln!("psns: {m}");
            Ok((None, saturated, None))
        }
        Err(e) => Err(e),
    }
}

fn heading_row(a: &HeadingArgs) -> Result<String> {
    let setup = image_setup(a)?; // option problems before reading the file
    let raw = load_raw(&a.input, MosaicLayout::default(), a.index)?;
    let (e, saturated) = estimate_loaded(a, &setup, &raw, &a.input.display().to_string())?;
    Ok(match e {
        Some(e) => format!(
            "{:.4},{:.4},{},{saturated}",
            e.yaw_deg, e.confidence, e.pixels
        ),
        None => format!("nan,0,0,{saturated}"),
    })
}

/// The estimator's setup for one image: the options' sun (up), intrinsics and tilt.
pub(crate) fn image_setup(a: &HeadingArgs) -> Result<HeadingSetup> {
    let (pitch, roll) = given_tilt(a)?;
    let mut cfg = a.scene.scene()?;
    if let Some(p) = a.preset {
        cfg.raw.preset = p;
    }
    let sun = cfg.sun.resolve()?;
    cfg.sun.check_up(sun)?;
    // lens: --lens, or the camera preset's (as psns render)
    let mut setup = HeadingSetup::new(cfg.intrinsics(), sun);
    setup.pitch_deg = pitch;
    setup.roll_deg = roll;
    setup.fit_elevation = a.fit_sun_elevation;
    // the falloff of the preset's (or the configured) sensor, as psns render makes it
    let sensor = cfg
        .raw
        .sensor
        .clone()
        .unwrap_or_else(|| SensorConfig::preset(cfg.raw.preset));
    setup.relative_illumination = flat_field(a, sensor.effective_ri())?;
    Ok(setup)
}

/// The estimate from one mosaic (not a stream) with the [`image_setup`] of the options, and the
/// number of masked pixels; `name` names the input in messages. The image path of
/// `psns heading`, and `psns.heading` in Python.
pub(crate) fn estimate_loaded(
    a: &HeadingArgs,
    setup: &HeadingSetup,
    raw: &LoadedRaw,
    name: &str,
) -> Result<(Option<HeadingEstimate>, usize)> {
    let i = setup.intrinsics;
    if (raw.codes.width, raw.codes.height) != (i.width, i.height) {
        return Err(Error::Invalid(format!(
            "{name} is {} x {} pixels but the intrinsics say {} x {}: give --width/--height (and --pixel-pitch, --focal-length) of the camera",
            raw.codes.width,
            raw.codes.height,
            i.width,
            i.height
        )));
    }
    let bits = match a.bits {
        Some(b) if (8..=16).contains(&b) => b as u8,
        Some(b) => return Err(Error::range("bits", b as f64, "8..16")),
        None if raw.bits == 8 => 8,
        None => 12, // the IMX250MZR's deepest mode, in a 16-bit file
    };
    estimate_codes(
        &raw.codes,
        raw.black_level,
        raw.layout,
        bits,
        a.demosaic,
        a.method,
        setup,
    )
    .map(|(e, sat, _)| (e, sat))
}

/// Columns of the per-frame CSV of a stream.
pub const STREAM_HEADER: &str =
    "frame_index,yaw_deg,confidence,pixels,true_yaw_deg,error_deg,saturated_pixels,ms";

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
    // the pinhole (psns before the lens option)
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
    let ri = flat_field(a, recorded_ri.or_else(sensor_ri).unwrap_or_else(preset_ri))?;
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

fn run_stream(a: &HeadingArgs) -> Result<()> {
    let s = &a.scene;
    if let Some(name) = super::args::first_given(&[
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
    let (pitch, roll) = given_tilt(a)?;
    keep_heap();
    let reader = StreamReader::new(super::open_input(&a.input)?)?;
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
            estimate_codes(
                &codes,
                black,
                h.layout,
                h.bits_valid,
                a.demosaic,
                a.method,
                &setup,
            )?
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        codes_buf = codes.data;
        source.recycle(f.payload);
        total_s += ms / 1e3;
        frames += 1;
        // the truth is read only here, after the estimate, for the error column
        let truth = attitude_yaw_deg(m.attitude_wxyz);
        // the next frame starts from this one's neutral points, if this one was trustworthy
        warm = match (&est.0, &est.2) {
            (Some(e), Some(i)) if e.confidence >= 0.5 => Some((i.babinet_deg, i.brewster_deg)),
            _ => None,
        };
        let line = match (est.0, est.1) {
            (Some(e), sat) => {
                let err = wrap180(e.yaw_deg - truth);
                errors.push(err);
                format!(
                    "{},{:.4},{:.4},{},{truth:.4},{err:.4},{sat},{ms:.1}",
                    m.index, e.yaw_deg, e.confidence, e.pixels
                )
            }
            (None, sat) => {
                none += 1;
                format!("{},nan,0,0,{truth:.4},nan,{sat},{ms:.1}", m.index)
            }
        };
        w(&mut out, &line)?;
    }
    let (damaged, skipped) = source.finish()?;
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
    Ok(())
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
            eprintln!("psns: damaged record (frame {index:?}): {reason}");
            None
        }
        Event::Truncated { index, .. } => {
            *damaged += 1;
            eprintln!("psns: stream ends inside a record (frame {index:?})");
            None
        }
        Event::Skipped { .. } => None,
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
            let result = (|| -> Result<()> {
                while let Some(ev) = reader.next_event()? {
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

    /// (damaged records, frames skipped for newer ones); the reader thread's error, if any.
    fn finish(&mut self) -> Result<(usize, usize)> {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let mut m = self.shared.0.lock().unwrap_or_else(|p| p.into_inner());
        match m.error.take() {
            Some(e) => Err(e),
            None => Ok((m.damaged, m.skipped)),
        }
    }
}
