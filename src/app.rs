//! Command bodies behind the `psns` binary. `main.rs` parses arguments into these plain structs;
//! everything here is ordinary library code returning [`crate::Result`], so the commands can be
//! tested without spawning a process.

use crate::config::{Derived, SceneConfig};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::render;
use crate::sky::{aop_chart_deg, aop_meridian_deg, direction};
use crate::{io, vis};
use std::io::{BufRead, Write};
use std::path::Path;
use std::time::Instant;

/// What `render` wrote and measured.
#[derive(Clone, Debug)]
pub struct RenderSummary {
    /// Seconds spent rendering the ideal images (without file output).
    pub render_s: f64,
    /// κ of eq. (24) for 8-bit output.
    pub kappa8: f64,
    /// Files written.
    pub files: Vec<String>,
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(format!("creating {}", dir.display()), e))
}

/// `psns render`: ideal images of a scene into `dir`.
pub fn render_ideal_to_dir(cfg: &SceneConfig, dir: &Path) -> Result<RenderSummary> {
    let (sky, cam) = cfg.build()?; // validates everything before anything is written
    create_dir(dir)?;
    let (summary, extra) = write_ideal(&sky, &cam, dir)?;
    let derived = Derived {
        sun: Some(sky.sun()),
        extra,
    };
    let mut out = cfg.clone();
    out.derived = Some(derived);
    write_scene_json(dir, &out)?;
    let mut summary = summary;
    summary.files.push("scene.json".into());
    Ok(summary)
}

/// Renders and writes the ideal images (everything of `psns render` but `scene.json`); returns
/// what was written and the values `scene.json` records.
fn write_ideal(
    sky: &crate::sky::Sky,
    cam: &crate::camera::Camera,
    dir: &Path,
) -> Result<(RenderSummary, serde_json::Map<String, serde_json::Value>)> {
    let t0 = Instant::now();
    let ideal = render::render_ideal(sky, cam);
    let render_s = t0.elapsed().as_secs_f64();
    let mut files = Vec::new();
    let mut put = |name: &str| {
        files.push(name.to_string());
        dir.join(name)
    };
    io::write_npy(&put("li.npy"), &ideal.li)?;
    io::write_npy(&put("dop.npy"), &ideal.dop)?;
    io::write_npy(&put("aop.npy"), &ideal.aop_deg)?;
    let pol = render::polarizer_images(&ideal);
    let (kappa8, q8) = render::quantize_polarizer_images(&pol, 255.0);
    let (_, q16) = render::quantize_polarizer_images(&pol, 65535.0);
    for (k, a) in [0, 45, 90, 135].iter().enumerate() {
        let g8 = Image::from_vec(
            q8[k].width,
            q8[k].height,
            q8[k].data.iter().map(|&v| v as u8).collect(),
        );
        io::write_png_gray8(&put(&format!("i{a}.png")), &g8)?;
        io::write_png_gray16(&put(&format!("i{a}_16bit.png")), &q16[k])?;
    }
    let white = vis::quantile(&ideal.li, 0.999);
    io::write_png_gray8(&put("li.png"), &vis::gray8(&ideal.li, white))?;
    io::write_png_rgb8(
        &put("dop.png"),
        &vis::dop_rgb(&ideal.dop, Some(&ideal.valid)),
    )?;
    io::write_png_rgb8(
        &put("aop.png"),
        &vis::aop_rgb(&ideal.aop_deg, Some(&ideal.valid)),
    )?;
    let valid = ideal.valid.data.iter().filter(|&&v| v != 0).count();
    let mut extra = serde_json::Map::new();
    extra.insert("kappa_8bit".into(), kappa8.into());
    extra.insert("sky_pixels".into(), valid.into());
    extra.insert(
        "ground_pixels".into(),
        (ideal.valid.data.len() - valid).into(),
    );
    Ok((
        RenderSummary {
            render_s,
            kappa8,
            files,
        },
        extra,
    ))
}

/// Writes `scene.json` (atomically).
fn write_scene_json(dir: &Path, scene: &SceneConfig) -> Result<()> {
    let json = scene.to_json();
    io::write_atomic(&dir.join("scene.json"), |w| {
        w.write_all(json.as_bytes())
            .map_err(|e| Error::io("writing scene.json", e))
    })
}

/// `psns sky`: CSV directions in, CSV sky values out (`zenith_deg,azimuth_deg` →
/// `zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg`).
///
/// Directions at or below the horizon (zenith ≥ 90°) get radiance 0, DOP 0 and AOP 0 (ground).
pub fn sky_csv(cfg: &SceneConfig, input: impl BufRead, mut output: impl Write) -> Result<usize> {
    let sun = cfg.sun.resolve()?;
    let sky = crate::sky::Sky::new(sun, &cfg.sky)?;
    let werr = |e| Error::io("writing to stdout", e);
    let mut lines = input.lines().enumerate();
    match lines.next() {
        Some((_, Ok(h))) if h.trim().replace(' ', "") == "zenith_deg,azimuth_deg" => {}
        Some((_, Ok(h))) => {
            return Err(Error::Invalid(format!(
                "line 1: expected the header 'zenith_deg,azimuth_deg', found '{h}'"
            )))
        }
        Some((_, Err(e))) => return Err(Error::io("reading stdin", e)),
        None => {
            return Err(Error::Invalid(
                "empty input: expected a CSV header line".into(),
            ))
        }
    }
    writeln!(
        output,
        "zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg"
    )
    .map_err(werr)?;
    let mut n = 0;
    for (i, line) in lines {
        let line = line.map_err(|e| Error::io("reading stdin", e))?;
        if line.trim().is_empty() {
            continue;
        }
        let ln = i + 1;
        let cols: Vec<&str> = line.split(',').collect();
        if cols.len() != 2 {
            return Err(Error::Invalid(format!(
                "line {ln}: expected 2 columns (zenith_deg,azimuth_deg), found {}",
                cols.len()
            )));
        }
        let num = |s: &str, name: &str| -> Result<f64> {
            let v: f64 = s.trim().parse().map_err(|_| {
                Error::Invalid(format!("line {ln}: {name} '{}' is not a number", s.trim()))
            })?;
            if !v.is_finite() {
                return Err(Error::Invalid(format!(
                    "line {ln}: {name} '{}' is not finite",
                    s.trim()
                )));
            }
            Ok(v)
        };
        let z = num(cols[0], "zenith_deg")?;
        let a = num(cols[1], "azimuth_deg")?;
        if !(0.0..=180.0).contains(&z) {
            return Err(Error::Invalid(format!(
                "line {ln}: zenith_deg = {z} is out of range (allowed 0..180)"
            )));
        }
        let v = direction(z, a);
        let s = sky.sample(v);
        let (am, an) = if s.valid && s.dop > 0.0 {
            (aop_meridian_deg(v, s.e), aop_chart_deg(v, s.e))
        } else {
            (0.0, 0.0)
        };
        writeln!(
            output,
            "{z},{a},{:.9},{:.9e},{:.9},{:.6},{:.6}",
            v.dot(sun.vector()).clamp(-1.0, 1.0).acos().to_degrees(),
            s.radiance,
            s.dop,
            am,
            an
        )
        .map_err(werr)?;
        n += 1;
    }
    output.flush().map_err(werr)?;
    Ok(n)
}

/// `psns figures`: the sky and camera pictures of `docs/img` (small PNGs).
pub fn sky_figures(dir: &Path) -> Result<Vec<String>> {
    use crate::figures::sky_sweep;
    use crate::sky::SkyParams;
    use crate::sun::SunPosition;
    create_dir(dir)?;
    let mut files = Vec::new();
    let params = SkyParams::default();
    let zen: Vec<SunPosition> = [10.0, 30.0, 50.0, 70.0, 85.0]
        .iter()
        .map(|&z| SunPosition::new(z, 200.0))
        .collect();
    let p = dir.join("sky_zenith_sweep.png");
    io::write_png_rgb8(&p, &sky_sweep(&params, &zen, 160)?)?;
    files.push(p.display().to_string());
    let az: Vec<SunPosition> = [0.0, 90.0, 200.0, 270.0]
        .iter()
        .map(|&a| SunPosition::new(50.0, a))
        .collect();
    let p = dir.join("sky_azimuth_sweep.png");
    io::write_png_rgb8(&p, &sky_sweep(&params, &az, 160)?)?;
    files.push(p.display().to_string());
    let rayleigh = SkyParams {
        model: crate::sky::PolarizationModel::Rayleigh,
        ..SkyParams::default()
    };
    let p = dir.join("sky_rayleigh_vs_wang.png");
    let a = sky_sweep(&params, &[SunPosition::new(50.0, 200.0)], 200)?;
    let b = sky_sweep(&rayleigh, &[SunPosition::new(50.0, 200.0)], 200)?;
    io::write_png_rgb8(&p, &vis::vstack(&[&a, &b], 4))?;
    files.push(p.display().to_string());
    // the default camera frame, 8x smaller
    let cfg = SceneConfig::default();
    let (sky, cam) = cfg.build()?;
    let ideal = render::render_ideal(&sky, &cam);
    let li = vis::downsample(&ideal.li, 8);
    let white = vis::quantile(&li, 0.999);
    let li = vis::gray_rgb(&vis::gray8(&li, white));
    let dop = vis::dop_rgb(&vis::decimate(&ideal.dop, 8), None);
    let aop = vis::aop_rgb(&vis::decimate(&ideal.aop_deg, 8), None);
    let p = dir.join("default_camera_li_dop_aop.png");
    io::write_png_rgb8(&p, &vis::hstack(&[&li, &dop, &aop], 4))?;
    files.push(p.display().to_string());
    Ok(files)
}

/// Opens a file, or stdin for `-`.
pub fn open_input(path: &Path) -> Result<Box<dyn std::io::Read>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(std::io::stdin().lock()))
    } else {
        let f = std::fs::File::open(path)
            .map_err(|e| Error::io(format!("opening {}", path.display()), e))?;
        Ok(Box::new(std::io::BufReader::with_capacity(1 << 20, f)))
    }
}

/// `psns extract`: one frame of a stream as `frame_N.png` (8- or 16-bit grey holding the values),
/// `frame_N.tiff` (16-bit) and `frame_N.json` (file header and frame metadata).
pub fn extract_to_dir(input: &Path, frame: u64, dir: &Path) -> Result<Vec<String>> {
    let ex = crate::stream::extract_frame(open_input(input)?, frame)?;
    create_dir(dir)?;
    let (w, h) = (ex.header.width as usize, ex.header.height as usize);
    let img = Image::from_vec(w, h, ex.codes.clone());
    let mut files = Vec::new();
    let png = dir.join(format!("frame_{frame}.png"));
    if ex.header.bits_valid <= 8 && !ex.header.msb_aligned {
        let g = Image::from_vec(w, h, ex.codes.iter().map(|&v| v as u8).collect());
        io::write_png_gray8(&png, &g)?;
    } else {
        io::write_png_gray16(&png, &img)?;
    }
    files.push(png.display().to_string());
    let tiff = dir.join(format!("frame_{frame}.tiff"));
    io::write_tiff_u16(&tiff, &img)?;
    files.push(tiff.display().to_string());
    let json = dir.join(format!("frame_{frame}.json"));
    let text = serde_json::to_string_pretty(&ex).expect("metadata serializes");
    io::write_atomic(&json, |wr| {
        wr.write_all(text.as_bytes())
            .map_err(|e| Error::io("writing frame json", e))
    })?;
    files.push(json.display().to_string());
    Ok(files)
}

/// One row of the sky grid benchmark.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GridBenchRow {
    /// Grid step in pixels (1 = exact).
    pub step: usize,
    /// Median wall time per full Stokes render, ms.
    pub ms_per_frame: f64,
    /// Max |ΔS0|/S0 over sky pixels.
    pub max_rel_s0: f64,
    /// Max |ΔDOP|.
    pub max_dop: f64,
    /// Max AOP error, degrees, over pixels with DOP > 0.02.
    pub max_aop_deg: f64,
    /// 99th percentile AOP error, degrees, same pixels.
    pub p99_aop_deg: f64,
}

/// Error of an approximate Stokes render against the exact one.
pub fn stokes_errors(
    exact: &crate::image::StokesImage,
    approx: &crate::image::StokesImage,
) -> (f64, f64, f64, f64) {
    let (mut rel, mut dop, mut aop) = (0.0f64, 0.0f64, Vec::new());
    for i in 0..exact.s0.data.len() {
        let (a0, a1, a2) = (
            exact.s0.data[i] as f64,
            exact.s1.data[i] as f64,
            exact.s2.data[i] as f64,
        );
        let (b0, b1, b2) = (
            approx.s0.data[i] as f64,
            approx.s1.data[i] as f64,
            approx.s2.data[i] as f64,
        );
        if a0 <= 0.0 {
            continue;
        }
        rel = rel.max((b0 - a0).abs() / a0);
        let (pa, pb) = (
            a1.hypot(a2) / a0,
            if b0 > 0.0 { b1.hypot(b2) / b0 } else { 0.0 },
        );
        dop = dop.max((pa - pb).abs());
        if pa > 0.02 {
            let da = crate::angle::SensorAngle::from_stokes(a1, a2)
                .diff(crate::angle::SensorAngle::from_stokes(b1, b2));
            aop.push(da);
        }
    }
    aop.sort_by(|a, b| a.total_cmp(b));
    let max = aop.last().copied().unwrap_or(0.0);
    let p99 = aop
        .get(((aop.len() as f64 - 1.0) * 0.99) as usize)
        .copied()
        .unwrap_or(0.0);
    (rel, dop, max, p99)
}

/// `psns bench sky`: exact vs coarse-grid Stokes rendering of a scene, time and accuracy.
pub fn bench_sky_grid(
    cfg: &SceneConfig,
    steps: &[usize],
    runs: usize,
) -> Result<Vec<GridBenchRow>> {
    let (sky, cam) = cfg.build()?;
    let opts = render::StokesOptions { sun_disc: false };
    let (exact, _) = render::render_stokes(&sky, &cam, opts);
    let mut rows = Vec::new();
    for &step in steps {
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..runs.max(1) {
            let t0 = Instant::now();
            let (st, _) = render::render_stokes_grid(&sky, &cam, opts, step);
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            last = Some(st);
        }
        times.sort_by(|a, b| a.total_cmp(b));
        let (max_rel_s0, max_dop, max_aop_deg, p99_aop_deg) = stokes_errors(&exact, &last.unwrap());
        rows.push(GridBenchRow {
            step,
            ms_per_frame: times[times.len() / 2],
            max_rel_s0,
            max_dop,
            max_aop_deg,
            p99_aop_deg,
        });
    }
    Ok(rows)
}

/// What `render --raw` measured.
#[derive(Clone, Debug)]
pub struct RawSummary {
    /// Seconds for the scene (sky Stokes) of the frame.
    pub scene_s: f64,
    /// Seconds for the sensor emulation of the frame.
    pub sensor_s: f64,
    /// Seconds to build the camera (fixed-pattern maps; once per camera).
    pub setup_s: f64,
    /// Files written.
    pub files: Vec<String>,
}

/// `psns render --raw`: the raw frame, its ground truth and (for a sky scene) the ideal images.
pub fn render_raw_to_dir(cfg: &SceneConfig, dir: &Path) -> Result<RawSummary> {
    use crate::config::SceneKind;
    use crate::pipeline::RawPipeline;
    let t0 = Instant::now();
    let pipe = RawPipeline::new(cfg)?; // validates everything before anything is written
    let setup_s = t0.elapsed().as_secs_f64();
    // the ideal images need the sky and camera too: build (and so check) them before writing
    let ideal_scene = match cfg.raw.scene {
        SceneKind::Sky => Some(cfg.build()?),
        SceneKind::Flat => None,
    };
    let t1 = Instant::now();
    let (frame, info, scene_s) = pipe.render_configured_timed()?;
    let sensor_s = t1.elapsed().as_secs_f64() - scene_s;
    create_dir(dir)?;
    let (mut files, mut extra) = match &ideal_scene {
        Some((sky, cam)) => {
            let (s, x) = write_ideal(sky, cam, dir)?;
            (s.files, x)
        }
        None => (Vec::new(), serde_json::Map::new()),
    };
    let mut put = |name: &str| {
        files.push(name.to_string());
        dir.join(name)
    };
    let codes = &frame.codes;
    if frame.bit_depth <= 8 {
        let g = Image::from_vec(
            codes.width,
            codes.height,
            codes.data.iter().map(|&v| v as u8).collect(),
        );
        io::write_png_gray8(&put("raw.png"), &g)?;
    } else {
        io::write_png_gray16(&put("raw.png"), codes)?;
    }
    io::write_tiff_u16(&put("raw.tiff"), codes)?;
    let mut packed = Vec::new();
    crate::sensor::packing::pack(
        &codes.data,
        frame.bit_depth,
        cfg.raw.pixel_format,
        false,
        &mut packed,
    )?;
    io::write_atomic(&put("raw.bin"), |w| {
        w.write_all(&packed)
            .map_err(|e| Error::io("writing raw.bin", e))
    })?;
    let full = ((1u32 << frame.bit_depth) - 1) as f64;
    let view = Image::from_vec(
        codes.width,
        codes.height,
        codes
            .data
            .iter()
            .map(|&v| (v as f64 / full * 255.0).round() as u8)
            .collect(),
    );
    io::write_png_gray8(&put("raw_view.png"), &view)?;
    io::write_npy(&put("truth_s0.npy"), &frame.truth.s0)?;
    io::write_npy(&put("truth_s1.npy"), &frame.truth.s1)?;
    io::write_npy(&put("truth_s2.npy"), &frame.truth.s2)?;
    let (dolp, aolp) = frame.truth_dolp_aolp();
    io::write_npy(&put("truth_dolp.npy"), &dolp)?;
    io::write_npy(&put("truth_aolp.npy"), &aolp)?;
    // scene.json: the whole configuration plus what this frame measured
    let mut out = cfg.clone();
    out.raw.sensor = Some(pipe.sensor_config().clone());
    let x = &mut extra;
    let layout = pipe.sensor_config().layout;
    let sat: serde_json::Map<String, serde_json::Value> = (0..4)
        .map(|k| {
            let (r, c) = (k / 2, k % 2);
            (
                format!("({r},{c}) {}deg", layout.angle_deg(r, c)),
                frame.saturated[k].into(),
            )
        })
        .collect();
    x.insert("saturated_pixels".into(), sat.into());
    x.insert("exposure_us".into(), frame.exposure_us.into());
    x.insert("auto_exposed".into(), frame.auto_exposed.into());
    x.insert("exposure_clipped".into(), frame.exposure_clipped.into());
    x.insert("gain_db".into(), frame.gain_db.into());
    x.insert("bit_depth".into(), frame.bit_depth.into());
    x.insert("black_level_dn".into(), frame.black_level_dn.into());
    x.insert("dn_per_electron".into(), frame.dn_per_electron.into());
    x.insert("sun_disc_pixels".into(), info.sun_pixels.into());
    // the ideal render counts ground exactly per pixel; keep its count when there is one
    x.entry("ground_pixels")
        .or_insert(info.ground_pixels.into());
    x.insert("scene_seconds".into(), scene_s.into());
    x.insert("sensor_seconds".into(), sensor_s.into());
    out.derived = Some(Derived {
        sun: info.sun,
        extra,
    });
    write_scene_json(dir, &out)?;
    files.push("scene.json".into());
    Ok(RawSummary {
        scene_s,
        sensor_s,
        setup_s,
        files,
    })
}

/// `psns bench sky`: grid-step sweep for three views (zenith, tilted to the horizon, sun in view)
/// written as `sky_grid.csv` (and printed).
pub fn bench_sky_to_dir(cfg: &SceneConfig, dir: &Path, runs: usize) -> Result<Vec<String>> {
    use crate::camera::Attitude;
    cfg.build()?;
    create_dir(dir)?;
    let sun = cfg.sun.resolve()?;
    let views = [
        ("zenith", cfg.camera.attitude),
        ("horizon", Attitude::enu(sun.azimuth_deg + 90.0, 60.0, 0.0)),
        (
            "sun-in-view",
            Attitude::enu(sun.azimuth_deg, -(sun.zenith_deg - 20.0), 0.0),
        ),
    ];
    let mut csv = String::from(
        "view,step,ms_per_frame,max_rel_s0,max_dop_err,max_aop_err_deg,p99_aop_err_deg\n",
    );
    for (name, att) in views {
        let mut c = cfg.clone();
        c.camera.attitude = att;
        for r in bench_sky_grid(&c, &[1, 2, 4, 8, 16], runs)? {
            let line = format!(
                "{name},{},{:.1},{:.3e},{:.3e},{:.3e},{:.3e}\n",
                r.step, r.ms_per_frame, r.max_rel_s0, r.max_dop, r.max_aop_deg, r.p99_aop_deg
            );
            eprint!("{line}");
            csv.push_str(&line);
        }
    }
    let p = dir.join("sky_grid.csv");
    io::write_atomic(&p, |w| {
        w.write_all(csv.as_bytes())
            .map_err(|e| Error::io("writing sky_grid.csv", e))
    })?;
    Ok(vec![p.display().to_string()])
}
