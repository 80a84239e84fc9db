//! `psns render`: ideal images of a scene (LI/DOP/AOP, polarizer images, visualisations) and,
//! with `--raw`, the IMX250MZR raw frame with its ground truth, written into a directory.

use super::output::{OutDir, RENDER_FILES};
use super::progress::{Progress, Unit};
use super::vis;
use psns::config::{Derived, SceneConfig, SceneKind};
use psns::image::Image;
use psns::memory::{check_memory, memory_available, memory_need};
use psns::options::RenderArgs;
use psns::{io, render, Error, Result};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Runs `psns render`.
pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    let (cfg, raw) = a.config()?;
    let out = a.out;
    if raw {
        let s = render_raw_to_dir(&cfg, &out)?;
        eprintln!(
            "raw frame {}x{}: scene {:.3} s + sensor {:.3} s (camera setup {:.3} s); wrote {} files to {}",
            cfg.camera.intrinsics.width,
            cfg.camera.intrinsics.height,
            s.scene_s,
            s.sensor_s,
            s.setup_s,
            s.files.len(),
            out.display()
        );
        return Ok(());
    }
    let s = render_ideal_to_dir(&cfg, &out)?;
    eprintln!(
        "rendered {}x{} in {:.3} s; wrote {} files to {}",
        cfg.camera.intrinsics.width,
        cfg.camera.intrinsics.height,
        s.render_s,
        s.files.len(),
        out.display()
    );
    Ok(())
}

#[derive(Clone, Debug)]
pub struct RenderSummary {
    /// Seconds spent rendering the ideal images (without file output).
    pub render_s: f64,
    /// Files written.
    pub files: Vec<String>,
}

/// `psns render`: ideal images of a scene into `dir`.
pub fn render_ideal_to_dir(cfg: &SceneConfig, target: &Path) -> Result<RenderSummary> {
    let (sky, cam) = cfg.build()?; // validates everything before anything is written
    check_size(cfg, IDEAL_BYTES_PER_PIXEL)?;
    let out = OutDir::begin(target, RENDER_FILES)?;
    let dir = out.path();
    let mut progress = Progress::new("psns render", Unit::Steps, Some(IDEAL_STEPS), false);
    progress.set_message("ideal images");
    let d = render_ideal(&sky, &cam, cfg.raw.sun_disc_on());
    progress.inc(1);
    let mut files = Vec::new();
    write_files(dir, ideal_jobs(&d), &mut progress, &mut files)?;
    let derived = Derived {
        sun: Some(sky.sun()),
        extra: d.extra.clone(),
    };
    let mut scene = cfg.clone();
    scene.derived = Some(derived);
    write_scene_json(dir, &scene)?;
    out.commit()?;
    files.push("scene.json".into());
    Ok(RenderSummary {
        render_s: d.render_s,
        files,
    })
}

/// Peak resident bytes per pixel of `psns render` and `render --raw` (measured at 1000² and
/// 3000² pixels: 53 and 87 B; rounded up).
const IDEAL_BYTES_PER_PIXEL: u64 = 56;
/// Progress steps: the ideal images and their 15 files; the raw frame and its 9 files.
const IDEAL_STEPS: u64 = 16;
const RAW_STEPS: u64 = 10;
const RAW_BYTES_PER_PIXEL: u64 = 90;

/// Refuses a frame too large for the memory this process may use.
fn check_size(cfg: &SceneConfig, bytes_per_pixel: u64) -> Result<()> {
    let i = &cfg.camera.intrinsics;
    i.validate()?; // sizes first: a frame over the pixel cap gets that message
    check_memory(
        &format!("a {} x {} render", i.width, i.height),
        memory_need(i.width * i.height, bytes_per_pixel),
        memory_available(),
    )
}

/// A file to write: its name in the run's directory and the function that writes it.
type FileJob<'a> = (String, Box<dyn FnOnce(&Path) -> Result<()> + Send + 'a>);

fn job<'a>(name: &str, f: impl FnOnce(&Path) -> Result<()> + Send + 'a) -> FileJob<'a> {
    (name.to_string(), Box::new(f))
}

/// Writes the files side by side (each PNG or npy encoder runs on one core, so one after the
/// other they left a core idle), counting each on `progress`; appends their names to `files` in
/// the order given. On an error the run's directory is never committed (nothing is written).
fn write_files(
    dir: &Path,
    jobs: Vec<FileJob>,
    progress: &mut Progress,
    files: &mut Vec<String>,
) -> Result<()> {
    use rayon::prelude::*;
    let progress = std::sync::Mutex::new(progress);
    let names = jobs
        .into_par_iter()
        .map(|(name, write)| {
            write(&dir.join(&name))?;
            let mut p = progress.lock().unwrap();
            p.set_message(name.as_str());
            p.inc(1);
            Ok(name)
        })
        .collect::<Result<Vec<_>>>()?;
    files.extend(names);
    Ok(())
}

/// The ideal images of a sky (everything of `psns render` but `scene.json`).
struct Ideal {
    ideal: render::IdealImages,
    q8: [Image<u16>; 4],
    q16: [Image<u16>; 4],
    /// What each pixel sees (`render::Class` codes).
    class: Image<u8>,
    render_s: f64,
    extra: serde_json::Map<String, serde_json::Value>,
}

/// Renders the ideal images (exact per pixel), the class image and the values `scene.json`
/// records.
fn render_ideal(sky: &psns::sky::Sky, cam: &psns::camera::Camera, sun_disc: bool) -> Ideal {
    let t0 = Instant::now();
    let (ideal, pol) = render::render_ideal_polarizers(sky, cam);
    let render_s = t0.elapsed().as_secs_f64();
    let class = render::class_image(sky, cam, sun_disc);
    let (kappa8, q8) = render::quantize_polarizer_images(&pol, 255.0);
    let (_, q16) = render::quantize_polarizer_images(&pol, 65535.0);
    let valid = ideal.valid.data.iter().filter(|&&v| v != 0).count();
    let mut extra = serde_json::Map::new();
    extra.insert("kappa_8bit".into(), kappa8.into());
    extra.insert("sky_pixels".into(), valid.into());
    extra.insert(
        "ground_pixels".into(),
        (ideal.valid.data.len() - valid).into(),
    );
    let f = render::fractions(&class);
    let fractions: serde_json::Map<String, serde_json::Value> = psns::world::Class::ALL
        .iter()
        .map(|c| (c.name().to_string(), f[*c as usize].into()))
        .collect();
    extra.insert("class_fractions".into(), fractions.into());
    Ideal {
        ideal,
        q8,
        q16,
        class,
        render_s,
        extra,
    }
}

/// The files of the ideal images, in `psns render`'s order.
fn ideal_jobs(d: &Ideal) -> Vec<FileJob<'_>> {
    let ideal = &d.ideal;
    let mut jobs = vec![
        job("li.npy", |p| io::write_npy(p, &ideal.li)),
        job("dop.npy", |p| io::write_npy(p, &ideal.dop)),
        job("aop.npy", |p| io::write_npy(p, &ideal.aop_deg)),
        job("class.npy", |p| io::write_npy(p, &d.class)),
    ];
    for (k, a) in [0, 45, 90, 135].iter().enumerate() {
        let (q8, q16) = (&d.q8[k], &d.q16[k]);
        jobs.push(job(&format!("i{a}.png"), move |p| {
            let g8 = Image::from_vec(
                q8.width,
                q8.height,
                q8.data.iter().map(|&v| v as u8).collect(),
            );
            io::write_png_gray8(p, &g8)
        }));
        jobs.push(job(&format!("i{a}_16bit.png"), move |p| {
            io::write_png_gray16(p, q16)
        }));
    }
    jobs.push(job("li.png", |p| {
        let white = vis::quantile(&ideal.li, 0.999);
        io::write_png_gray8(p, &vis::gray8(&ideal.li, white))
    }));
    jobs.push(job("dop.png", |p| {
        io::write_png_rgb8(p, &vis::dop_rgb(&ideal.dop, Some(&ideal.valid)))
    }));
    jobs.push(job("aop.png", |p| {
        io::write_png_rgb8(p, &vis::aop_rgb(&ideal.aop_deg, Some(&ideal.valid)))
    }));
    jobs
}

/// Writes `scene.json` (atomically), with the sun written out.
fn write_scene_json(dir: &Path, scene: &SceneConfig) -> Result<()> {
    let mut scene = scene.clone();
    scene.sun = scene.sun.filled();
    let json = scene.to_json();
    io::write_atomic(&dir.join("scene.json"), |w| {
        w.write_all(json.as_bytes())
            .map_err(|e| Error::io("writing scene.json", e))
    })
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
pub fn render_raw_to_dir(cfg: &SceneConfig, target: &Path) -> Result<RawSummary> {
    use psns::pipeline::{FrameResult, RawPipeline};
    check_size(cfg, RAW_BYTES_PER_PIXEL)?;
    let t0 = Instant::now();
    let pipe = RawPipeline::new(cfg)?; // validates everything before anything is written
    let setup_s = t0.elapsed().as_secs_f64();
    // the ideal images need the sky and camera too: build (and so check) them before writing
    let ideal_scene = match cfg.raw.scene {
        SceneKind::Sky => Some(cfg.build()?),
        SceneKind::Flat => None,
    };
    let t1 = Instant::now();
    let total = RAW_STEPS
        + if ideal_scene.is_some() {
            IDEAL_STEPS
        } else {
            0
        };
    let mut progress = Progress::new("psns render", Unit::Steps, Some(total), false);
    progress.set_message("raw frame and ideal images");
    // the raw frame and the ideal images side by side (each alone leaves a core idle at times)
    let (raw, ideal) = rayon::join(
        || {
            let r = pipe.configured_request().and_then(|req| pipe.render(req));
            (r, t1.elapsed().as_secs_f64())
        },
        || {
            ideal_scene
                .as_ref()
                .map(|(sky, cam)| render_ideal(sky, cam, cfg.raw.sun_disc_on()))
        },
    );
    let (
        FrameResult {
            frame,
            record,
            scene_seconds: scene_s,
            ..
        },
        raw_s,
    ) = (raw.0?, raw.1);
    progress.inc(if ideal.is_some() { 2 } else { 1 });
    let sensor_s = raw_s - scene_s;
    let outdir = OutDir::begin(target, RENDER_FILES)?;
    let dir = outdir.path();
    let mut files = Vec::new();
    let (mut jobs, mut extra) = match &ideal {
        Some(d) => (ideal_jobs(d), d.extra.clone()),
        None => (Vec::new(), serde_json::Map::new()),
    };
    let codes = &frame.codes;
    let bits = frame.bit_depth;
    jobs.push(job("raw.png", move |p| {
        if bits <= 8 {
            let g = Image::from_vec(
                codes.width,
                codes.height,
                codes.data.iter().map(|&v| v as u8).collect(),
            );
            io::write_png_gray8(p, &g)
        } else {
            io::write_png_gray16(p, codes)
        }
    }));
    jobs.push(job("raw.tiff", move |p| io::write_tiff_u16(p, codes)));
    let format = cfg.raw.pixel_format;
    jobs.push(job("raw.bin", move |p| {
        let mut packed = Vec::new();
        psns::sensor::packing::pack(&codes.data, bits, format, false, &mut packed)?;
        io::write_atomic(p, |w| {
            w.write_all(&packed)
                .map_err(|e| Error::io("writing raw.bin", e))
        })
    }));
    jobs.push(job("raw_view.png", move |p| {
        let full = ((1u32 << bits) - 1) as f64;
        let view = Image::from_vec(
            codes.width,
            codes.height,
            codes
                .data
                .iter()
                .map(|&v| psns::image::round_clamp(v as f64 / full * 255.0, 255.0) as u8)
                .collect(),
        );
        io::write_png_gray8(p, &view)
    }));
    let truth = &frame.truth;
    jobs.push(job("truth_s0.npy", |p| io::write_npy(p, &truth.s0)));
    jobs.push(job("truth_s1.npy", |p| io::write_npy(p, &truth.s1)));
    jobs.push(job("truth_s2.npy", |p| io::write_npy(p, &truth.s2)));
    let (dolp, aolp) = frame.truth_dolp_aolp();
    jobs.push(job("truth_dolp.npy", move |p| io::write_npy(p, &dolp)));
    jobs.push(job("truth_aolp.npy", move |p| io::write_npy(p, &aolp)));
    write_files(dir, jobs, &mut progress, &mut files)?;
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
    let pixels = (codes.width * codes.height) as u64;
    let saturated = frame.saturated_pixels();
    x.insert(
        "saturated_fraction".into(),
        psns::sensor::saturated_fraction(saturated, pixels).into(),
    );
    // the frame's record; the ideal render counts ground and classes exactly per pixel, and
    // its counts are kept where there are some
    let rec = serde_json::to_value(record).map_err(|e| Error::Invalid(e.to_string()))?;
    if let serde_json::Value::Object(rec) = rec {
        for (k, v) in rec {
            x.entry(k).or_insert(v);
        }
    }
    x.insert("scene_seconds".into(), scene_s.into());
    x.insert("sensor_seconds".into(), sensor_s.into());
    out.derived = Some(Derived {
        sun: (cfg.raw.scene == SceneKind::Sky).then_some(psns::sun::SunPosition {
            zenith_deg: record.sun_zenith_deg,
            azimuth_deg: record.sun_azimuth_deg,
        }),
        extra,
    });
    write_scene_json(dir, &out)?;
    outdir.commit()?;
    files.push("scene.json".into());
    if let Some(w) = psns::sensor::saturation_warning(saturated, pixels) {
        eprintln!("psns: warning: {w}");
    }
    Ok(RawSummary {
        scene_s,
        sensor_s,
        setup_s,
        files,
    })
}
