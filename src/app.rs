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
    let t0 = Instant::now();
    let ideal = render::render_ideal(&sky, &cam);
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
    let mut out = cfg.clone();
    let mut derived = Derived {
        sun: Some(sky.sun()),
        ..Default::default()
    };
    derived.extra.insert("kappa_8bit".into(), kappa8.into());
    derived.extra.insert("sky_pixels".into(), valid.into());
    derived.extra.insert(
        "ground_pixels".into(),
        (ideal.valid.data.len() - valid).into(),
    );
    out.derived = Some(derived);
    let json = out.to_json();
    io::write_atomic(&put("scene.json"), |w| {
        w.write_all(json.as_bytes())
            .map_err(|e| Error::io("writing scene.json", e))
    })?;
    Ok(RenderSummary {
        render_s,
        kappa8,
        files,
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
    io::write_png_rgb8(&p, &sky_sweep(&params, &zen, 200)?)?;
    files.push(p.display().to_string());
    let az: Vec<SunPosition> = [0.0, 90.0, 200.0, 270.0]
        .iter()
        .map(|&a| SunPosition::new(50.0, a))
        .collect();
    let p = dir.join("sky_azimuth_sweep.png");
    io::write_png_rgb8(&p, &sky_sweep(&params, &az, 200)?)?;
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
