//! Sensor pictures for `docs/sensor.md`: the raw frame, zooms on the mosaic and on the saturated
//! sun, the four channel sub-images, the PSNS presets side by side, the EMVA 1288 photon transfer
//! curve of the emulator and the DoLP of a plain superpixel estimate against the ground truth.
//!
//! Everything is produced by running the emulator ([`RawPipeline`], [`Sensor`]); nothing is drawn
//! by hand. Full frames are box-downsampled for the page; zooms are enlarged with nearest neighbour
//! so single pixels stay visible. The photon-transfer numbers are written next to the pictures as
//! `sensor_numbers.json` so the documentation quotes measured values.

use crate::cli::progress::Progress;
use crate::cli::vis;
use psns::camera::{Attitude, Camera};
use psns::config::SceneConfig;
use psns::error::{Error, Result};
use psns::image::Image;
use psns::io;
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::sensor::emva::{pair_stats, photon_transfer, PairStats, PhotonTransfer};
use psns::sensor::mosaic::MosaicLayout;
use psns::sensor::{
    flat_field, Exposure, FrameOptions, Preset, Radiance, RawFrame, Sensor, SensorConfig,
};
use std::path::Path;

/// One exposure level of the photon-transfer measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PtcLevel {
    /// Exposure time, µs.
    pub exposure_us: f64,
    /// Pair statistics (averaged over the pairs of the level), DN.
    pub stats: PairStats,
}

/// Flat-field photon-transfer data of the emulated camera and its EMVA 1288 evaluation.
#[derive(Clone, Debug)]
#[allow(dead_code)] // a complete record of the measurement; the chart reads only some fields
pub struct PtcData {
    /// Sensor configuration measured (exposure replaced per level).
    pub config: SensorConfig,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Flat-field radiance, W m⁻² sr⁻¹ nm⁻¹ (unpolarized).
    pub radiance: f64,
    /// Frame pairs averaged per level.
    pub pairs: u64,
    /// Mean noise-free electron rate over the frame, e⁻/s.
    pub electron_rate: f64,
    /// Dark pair (no light, shortest exposure).
    pub dark: PairStats,
    /// Illuminated levels, increasing exposure.
    pub levels: Vec<PtcLevel>,
    /// EMVA 1288 evaluation (K, dark noise, saturation).
    pub fit: PhotonTransfer,
}

/// The camera preset prepared for EMVA 1288: black level 16 DN so dark pixels do not clip, and
/// no relative illumination so the field is uniform.
pub fn ptc_sensor_config() -> SensorConfig {
    let mut cfg = SensorConfig {
        black_level_dn: 16.0,
        ..Default::default()
    };
    cfg.stages.ri = false;
    cfg
}

/// Exposure levels as fractions of the exposure that fills the full well: 5 low levels (0.1 % to
/// 2 %, the read-noise-limited part of the SNR curve), 20 evenly spaced up to 90 %, 8 fine steps
/// (1.5 %) from 92 % to 102.5 % to locate the variance maximum, and two levels past saturation
/// where the variance collapses.
pub fn ptc_fractions() -> Vec<f64> {
    let mut f = vec![0.001, 0.002, 0.005, 0.01, 0.02];
    f.extend((1..=20).map(|i| 0.9 * i as f64 / 20.0));
    f.extend((0..8).map(|i| 0.92 + 0.015 * i as f64));
    f.extend([1.1, 1.25]);
    f
}

/// Photon-transfer measurement of camera `seed` with sensor `cfg` on a `width` × `height`
/// unpolarized flat field of radiance 0.01 (full well in about 25 ms with the default optics, so
/// the shortest level stays above the 20 µs minimum exposure): a dark pair at 20 µs and one level per
/// [`ptc_fractions`] entry, each the average of `pairs` independent frame pairs; evaluated with
/// [`photon_transfer`]. Pure: same inputs, same result (no dependence on the thread count).
pub fn photon_transfer_data(
    cfg: &SensorConfig,
    width: usize,
    height: usize,
    seed: u64,
    pairs: u64,
) -> Result<PtcData> {
    if pairs == 0 {
        return Err(Error::range("pairs", 0.0, "1 or more"));
    }
    let intr = psns::camera::Intrinsics {
        width,
        height,
        ..Default::default()
    };
    cfg.validate(width, height)?;
    let radiance = 0.01;
    let light = flat_field(width, height, radiance, 0.0, 0.0)?;
    let dark = flat_field(width, height, 0.0, 0.0, 0.0)?;
    let probe = Sensor::new(cfg, &intr, seed)?;
    let rates = probe.electron_rate(&light)?;
    let electron_rate = rates.iter().sum::<f64>() / rates.len() as f64;
    if electron_rate <= 0.0 {
        return Err(Error::Invalid(
            "photon transfer: the flat field gives no signal".into(),
        ));
    }
    let t_sat_us = 1e6 * cfg.full_well_e / electron_rate;
    let measure = |scene: &psns::image::StokesImage, t_us: f64, block: u64| -> Result<PairStats> {
        let mut c = cfg.clone();
        c.exposure = Exposure::Fixed {
            us: t_us.clamp(psns::sensor::MIN_EXPOSURE_US, psns::sensor::MAX_EXPOSURE_US),
        };
        let s = Sensor::new(&c, &intr, seed)?;
        let (mut mean, mut var) = (0.0, 0.0);
        for j in 0..pairs {
            // every frame of the measurement has its own index: independent temporal noise
            let a = s.frame(
                Radiance::Planes(scene),
                2 * pairs * block + 2 * j,
                FrameOptions::exact(),
            )?;
            let b = s.frame(
                Radiance::Planes(scene),
                2 * pairs * block + 2 * j + 1,
                FrameOptions::exact(),
            )?;
            let p = pair_stats(&a.codes.data, &b.codes.data)?;
            mean += p.mean / pairs as f64;
            var += p.var / pairs as f64;
        }
        Ok(PairStats { mean, var })
    };
    let fractions = ptc_fractions();
    let dark_stats = measure(&dark, psns::sensor::MIN_EXPOSURE_US, fractions.len() as u64)?;
    let levels = fractions
        .iter()
        .enumerate()
        .map(|(i, &f)| {
            let t = (f * t_sat_us).max(psns::sensor::MIN_EXPOSURE_US);
            Ok(PtcLevel {
                exposure_us: t,
                stats: measure(&light, t, i as u64)?,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let stats: Vec<PairStats> = levels.iter().map(|l| l.stats).collect();
    let fit = photon_transfer(dark_stats, &stats)?;
    Ok(PtcData {
        config: cfg.clone(),
        width,
        height,
        radiance,
        pairs,
        electron_rate,
        dark: dark_stats,
        levels,
        fit,
    })
}

fn plot_err(e: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("drawing the photon transfer chart: {e}"))
}

/// SVG (1200 × 420) of the photon transfer data: variance vs mean with the fitted line of slope K,
/// SNR vs mean (log–log) with the EMVA model, and mean vs exposure time.
pub fn photon_transfer_svg(d: &PtcData) -> Result<String> {
    let mut svg = String::new();
    draw_ptc(d, &mut svg).map_err(plot_err)?;
    Ok(svg)
}

fn draw_ptc(d: &PtcData, svg: &mut String) -> std::result::Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let k = d.fit.k;
    let sat_x = d.fit.saturation_mean_dn - d.dark.mean;
    let lin_x = 0.7 * sat_x;
    // (x = mean above dark, variance, exposure µs)
    let pts: Vec<(f64, f64, f64)> = d
        .levels
        .iter()
        .map(|l| (l.stats.mean - d.dark.mean, l.stats.var, l.exposure_us))
        .collect();
    let font = ("sans-serif", 15);
    let root = SVGBackend::with_string(svg, (1200, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, 3));

    // 1. photon transfer: σ²_y vs μ_y − μ_y.dark
    let xmax = pts.iter().map(|p| p.0).fold(0.0, f64::max) * 1.05;
    let ymax = pts.iter().map(|p| p.1).fold(0.0, f64::max) * 1.15;
    let mut ch = ChartBuilder::on(&panels[0])
        .caption(format!("photon transfer, K = {k:.4} DN/e-"), font)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..xmax, 0f64..ymax)?;
    ch.configure_mesh()
        .x_desc("mean above dark (DN)")
        .y_desc("temporal variance (DN²)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", 12))
        .draw()?;
    ch.draw_series(
        pts.iter()
            .filter(|p| p.0 <= lin_x)
            .map(|p| Circle::new((p.0, p.1), 3, BLUE.filled())),
    )?
    .label("pairs in the fit (≤ 70 % sat.)")
    .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
    ch.draw_series(
        pts.iter()
            .filter(|p| p.0 > lin_x)
            .map(|p| Circle::new((p.0, p.1), 3, BLUE.stroke_width(1))),
    )?
    .label("other pairs")
    .legend(|(x, y)| Circle::new((x, y), 3, BLUE.stroke_width(1)));
    ch.draw_series(LineSeries::new(
        [(0.0, d.dark.var), (sat_x, d.dark.var + k * sat_x)],
        RED.stroke_width(2),
    ))?
    .label("σ²dark + K·mean")
    .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], RED.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        [(sat_x, 0.0), (sat_x, ymax)],
        BLACK.mix(0.4),
    ))?
    .label("saturation (max variance)")
    .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], BLACK.mix(0.4)));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font(("sans-serif", 12))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()?;

    // 2. SNR vs mean, log–log, up to saturation
    let snr: Vec<(f64, f64)> = pts
        .iter()
        .filter(|p| p.0 > 0.0 && p.0 <= sat_x * 1.0001)
        .map(|p| (p.0, p.0 / p.1.sqrt()))
        .collect();
    let x0 = snr.iter().map(|p| p.0).fold(f64::INFINITY, f64::min) * 0.5;
    let x1 = sat_x * 1.5;
    let y0 = snr.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) * 0.5;
    let y1 = (sat_x / k).sqrt() * 1.5;
    let mut ch = ChartBuilder::on(&panels[1])
        .caption("signal-to-noise ratio", font)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    ch.configure_mesh()
        .x_desc("mean above dark (DN)")
        .y_desc("SNR = mean / σ")
        .x_labels(5)
        .y_labels(5)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", 12))
        .draw()?;
    let xs: Vec<f64> = (0..=100)
        .map(|i| x0 * (sat_x / x0).powf(i as f64 / 100.0))
        .collect();
    ch.draw_series(LineSeries::new(
        xs.iter().map(|&x| (x, x / (d.dark.var + k * x).sqrt())),
        RED.stroke_width(2),
    ))?
    .label("EMVA model with measured K, σ²dark")
    .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], RED.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        xs.iter().map(|&x| (x, (x / k).sqrt())),
        BLACK.mix(0.5),
    ))?
    .label("ideal: shot noise only")
    .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], BLACK.mix(0.5)));
    ch.draw_series(
        snr.iter()
            .map(|&(x, y)| Circle::new((x, y), 3, BLUE.filled())),
    )?
    .label("measured pairs")
    .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font(("sans-serif", 12))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()?;

    // 3. linearity: mean vs exposure, with the configured noise-free prediction
    let tmax = pts.iter().map(|p| p.2).fold(0.0, f64::max) * 1.05 / 1000.0;
    let kcfg = psns::sensor::adc::system_gain(d.config.k0, d.config.gain_db)
        * psns::sensor::adc::output_scale(d.config.bit_depth);
    let ymax = xmax;
    let mut ch = ChartBuilder::on(&panels[2])
        .caption("linearity", font)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..tmax, 0f64..ymax)?;
    ch.configure_mesh()
        .x_desc("exposure time (ms)")
        .y_desc("mean above dark (DN)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", 12))
        .draw()?;
    let ts: Vec<f64> = (0..=200).map(|i| tmax * i as f64 / 200.0).collect();
    ch.draw_series(LineSeries::new(
        ts.iter().map(|&t| {
            let e = (d.electron_rate * t * 1e-3).min(d.config.full_well_e);
            (t, kcfg * e)
        }),
        RED.stroke_width(2),
    ))?
    .label("configured: K0·min(rate·t, full well)")
    .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], RED.stroke_width(2)));
    ch.draw_series(
        pts.iter()
            .map(|p| Circle::new((p.2 / 1000.0, p.0), 3, BLUE.filled())),
    )?
    .label("measured pairs")
    .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font(("sans-serif", 12))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()?;
    root.present()?;
    Ok(())
}

/// A `h` × `w` crop with top-left corner (r0, c0), clamped to the image.
pub fn crop<T: Copy>(img: &Image<T>, r0: usize, c0: usize, h: usize, w: usize) -> Image<T> {
    let r0 = r0.min(img.height.saturating_sub(h));
    let c0 = c0.min(img.width.saturating_sub(w));
    let (h, w) = (h.min(img.height), w.min(img.width));
    let mut data = Vec::with_capacity(w * h);
    for r in r0..r0 + h {
        data.extend_from_slice(&img.row(r)[c0..c0 + w]);
    }
    Image::from_vec(w, h, data)
}

/// Nearest-neighbour enlargement by an integer factor.
pub fn enlarge<T: Copy>(img: &Image<T>, k: usize) -> Image<T> {
    let (w, h) = (img.width * k, img.height * k);
    let data = (0..w * h).map(|i| *img.get(i / w / k, i % w / k)).collect();
    Image::from_vec(w, h, data)
}

/// The sub-image of one mosaic position (row phase `r0`, column phase `c0`): every second pixel.
pub fn sub_lattice(img: &Image<u16>, r0: usize, c0: usize) -> Image<u16> {
    let (w, h) = (img.width / 2, img.height / 2);
    let data = (0..w * h)
        .map(|i| *img.get(2 * (i / w) + r0, 2 * (i % w) + c0))
        .collect();
    Image::from_vec(w, h, data)
}

/// Codes as 8-bit grey, full scale (2^bits − 1) → 255.
fn codes_gray(codes: &Image<u16>, bit_depth: u8) -> Image<u8> {
    let full = ((1u32 << bit_depth) - 1) as f64;
    let f = Image::from_vec(
        codes.width,
        codes.height,
        codes.data.iter().map(|&v| v as f32).collect(),
    );
    vis::gray8(&f, full)
}

/// Grey RGB, pixels at the maximum code red.
fn codes_rgb_saturation(codes: &Image<u16>, white: f64, max: u16) -> Image<[u8; 3]> {
    let k = if white > 0.0 { 255.0 / white } else { 0.0 };
    Image::from_vec(
        codes.width,
        codes.height,
        codes
            .data
            .iter()
            .map(|&v| {
                if v >= max {
                    [230, 30, 30]
                } else {
                    let g = psns::image::round_clamp(v as f64 * k, 255.0) as u8;
                    [g, g, g]
                }
            })
            .collect(),
    )
}

/// Box-downsampled grey view (`white` → 255) with every block that holds a pixel at the maximum
/// code painted red.
fn saturation_overview(codes: &Image<u16>, factor: usize, white: f64, max: u16) -> Image<[u8; 3]> {
    let g = vis::gray8(&vis::downsample(codes, factor), white);
    let (w, h) = (g.width, g.height);
    let data = (0..w * h)
        .map(|i| {
            let (r, c) = (i / w, i % w);
            let sat = (0..factor).any(|dr| {
                codes.row(r * factor + dr)[c * factor..(c + 1) * factor]
                    .iter()
                    .any(|&v| v >= max)
            });
            if sat {
                [230, 30, 30]
            } else {
                let v = g.data[i];
                [v, v, v]
            }
        })
        .collect();
    Image::from_vec(w, h, data)
}

/// First channel of an RGB image (for grey pictures assembled with the RGB stacking helpers).
fn rgb_to_gray(img: &Image<[u8; 3]>) -> Image<u8> {
    Image::from_vec(
        img.width,
        img.height,
        img.data.iter().map(|p| p[0]).collect(),
    )
}

/// Superpixel Stokes estimate (black level removed) of a raw frame: DoLP per 2 × 2 superpixel,
/// and the DoLP of the mean ground truth over the same superpixel.
fn superpixel_dolp(
    frame: &RawFrame,
    layout: &psns::sensor::mosaic::MosaicLayout,
) -> [Image<f32>; 2] {
    let (w, h) = (frame.codes.width / 2, frame.codes.height / 2);
    let pos: Vec<(usize, usize)> = (0..4).map(|c| layout.position_of(c)).collect();
    let mut est = Image::new(w, h);
    let mut tru = Image::new(w, h);
    let b = frame.black_level_dn;
    for r in 0..h {
        for c in 0..w {
            let i = |ch: usize| {
                let (dr, dc) = pos[ch];
                *frame.codes.get(2 * r + dr, 2 * c + dc) as f64 - b
            };
            let (i0, i45, i90, i135) = (i(0), i(1), i(2), i(3));
            let s0 = 0.5 * (i0 + i45 + i90 + i135);
            let (s1, s2) = (i0 - i90, i45 - i135);
            *est.get_mut(r, c) = if s0 > 0.0 {
                (s1.hypot(s2) / s0) as f32
            } else {
                0.0
            };
            let (mut t0, mut t1, mut t2) = (0.0, 0.0, 0.0);
            for dr in 0..2 {
                for dc in 0..2 {
                    t0 += *frame.truth.s0.get(2 * r + dr, 2 * c + dc) as f64;
                    t1 += *frame.truth.s1.get(2 * r + dr, 2 * c + dc) as f64;
                    t2 += *frame.truth.s2.get(2 * r + dr, 2 * c + dc) as f64;
                }
            }
            *tru.get_mut(r, c) = if t0 > 0.0 {
                (t1.hypot(t2) / t0) as f32
            } else {
                0.0
            };
        }
    }
    [est, tru]
}

/// Noise-free electron rate (e⁻/s) of the brightest of the four channels of every 2 × 2
/// superpixel, row-major over superpixels: the quantity `sensor.md` §5 sizes the default exposure
/// by (PRNU, orientation error, ER and RI included, as the sensor configures them).
pub fn brightest_channel_rates(sensor: &Sensor, st: &psns::image::StokesImage) -> Result<Vec<f64>> {
    let rate = sensor.electron_rate(st)?;
    let (w, h) = (st.width(), st.height());
    let mut out = Vec::with_capacity(w * h / 4);
    for r in (0..h - 1).step_by(2) {
        for c in (0..w - 1).step_by(2) {
            let k = r * w + c;
            out.push(
                rate[k]
                    .max(rate[k + 1])
                    .max(rate[k + w])
                    .max(rate[k + w + 1]),
            );
        }
    }
    Ok(out)
}

/// Nearest-rank percentile p (0..100] of `v` (the rule auto-exposure uses).
fn percentile(mut v: Vec<f64>, p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let n = v.len();
    let i = ((p / 100.0 * n as f64).ceil() as usize).clamp(1, n) - 1;
    *v.select_nth_unstable_by(i, |a, b| a.total_cmp(b)).1
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let n = v.len() / 2;
    *v.select_nth_unstable_by(n, |a, b| a.total_cmp(b)).1
}

/// Steps of [`sensor_figures`] counted by its progress.
pub const SENSOR_FIGURE_STEPS: u64 = 6;

/// Where the sensor figures go: the files written and the numbers of `sensor_numbers.json`.
struct Figures<'a> {
    dir: &'a Path,
    files: Vec<String>,
    numbers: serde_json::Map<String, serde_json::Value>,
}

impl Figures<'_> {
    /// The path of figure `name`, listed among the files written.
    fn put(&mut self, name: &str) -> std::path::PathBuf {
        let p = self.dir.join(name);
        self.files.push(p.display().to_string());
        p
    }
}

/// Writes the sensor figures into `dir`; returns the files written. Counts
/// [`SENSOR_FIGURE_STEPS`] steps on `progress`.
pub fn sensor_figures(dir: &Path, progress: &mut Progress) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    let mut out = Figures {
        dir,
        files: Vec::new(),
        numbers: serde_json::Map::new(),
    };
    progress.set_message("sensor: raw frame");
    // 1. the default camera frame of the default sky, on the exact (reference) path the pipeline
    // section describes: every pixel's sky evaluated, the reference noise (the pictures then do
    // not move when the fast path is tuned)
    let mut cfg = super::figure_scene();
    cfg.raw.exact = true;
    let pipe = RawPipeline::new(&cfg)?;
    let layout = pipe.sensor_config().layout;
    let frame = default_frame(&cfg, &pipe, &mut out)?;
    progress.inc(1);
    progress.set_message("sensor: mosaic zoom, sun frame");
    mosaic_zoom_and_sun(&cfg, &pipe, &frame, &mut out)?;
    progress.inc(1);
    progress.set_message("sensor: channels");
    channels(&frame, &layout, &mut out)?;
    progress.inc(1);
    progress.set_message("sensor: presets");
    presets(&cfg, &frame, &mut out)?;
    progress.inc(1);
    progress.set_message("sensor: photon transfer");
    photon_transfer_figure(&mut out)?;
    progress.inc(1);
    progress.set_message("sensor: DoLP truth vs superpixel");
    dolp_truth_vs_superpixel(&frame, &layout, &mut out)?;
    let numbers = std::mem::take(&mut out.numbers);
    let json = serde_json::to_string_pretty(&serde_json::Value::Object(numbers))
        .expect("numbers serialize");
    io::write_atomic(&out.put("sensor_numbers.json"), |w| {
        std::io::Write::write_all(w, json.as_bytes())
            .map_err(|e| Error::io("writing sensor_numbers.json", e))
    })?;
    progress.inc(1);
    Ok(out.files)
}

/// Figure 1: the default camera frame (`raw_frame.png`) and the brightest channel's electron
/// rate.
fn default_frame(cfg: &SceneConfig, pipe: &RawPipeline, out: &mut Figures) -> Result<RawFrame> {
    let frame = pipe.render(pipe.configured_request()?)?.frame;
    let bits = frame.bit_depth;
    let gray = codes_gray(&frame.codes, bits);
    let small = vis::downsample(&gray, 4);
    io::write_png_gray8(&out.put("raw_frame.png"), &vis::gray8(&small, 255.0))?;
    out.numbers.insert(
        "default_frame".into(),
        serde_json::json!({
            "exposure_us": frame.exposure_us,
            "median_code": median(frame.codes.data.iter().map(|&v| v as f64).collect()),
            "max_code": frame.codes.data.iter().copied().max().unwrap_or(0),
            "saturated_pixels": frame.saturated,
        }),
    );
    // brightest-channel electron rate of the default sky (sensor.md §5 sizes the 1 ms exposure by it)
    let sun = cfg.sun.resolve()?;
    let (st, _) = pipe.stokes(sun, &cfg.camera.attitude)?;
    let bright = brightest_channel_rates(pipe.sensor(), &st)?;
    let radiance: Vec<f64> = st.s0.data.iter().map(|&v| v as f64).collect();
    out.numbers.insert(
        "brightest_channel_rate".into(),
        serde_json::json!({
            "superpixels": bright.len(),
            "median_e_per_ms": median(bright.clone()) * 1e-3,
            "p99_e_per_ms": percentile(bright, 99.0) * 1e-3,
            "radiance_min": percentile(radiance.clone(), 0.0),
            "radiance_median": median(radiance.clone()),
            "radiance_max": percentile(radiance, 100.0),
        }),
    );
    Ok(frame)
}

/// Figure 2: the mosaic where the truth DoLP is highest, and the sun in view at two exposures
/// (`raw_mosaic_zoom.png`, `raw_sun_frame.png`).
fn mosaic_zoom_and_sun(
    cfg: &SceneConfig,
    pipe: &RawPipeline,
    frame: &RawFrame,
    out: &mut Figures,
) -> Result<()> {
    let max = psns::sensor::adc::max_code(frame.bit_depth);
    // 2a. 24 × 24 crop where the truth DoLP is highest, ×12
    let (dolp, _) = frame.truth_dolp_aolp();
    let block = 24;
    let coarse = vis::downsample(&dolp, block);
    let (mut best, mut at) = (-1.0f32, (0, 0));
    for r in 0..coarse.height {
        for c in 0..coarse.width {
            let v = *coarse.get(r, c);
            if v > best {
                best = v;
                at = (r * block, c * block);
            }
        }
    }
    let zoom = crop(&frame.codes, at.0, at.1, block, block);
    let zmax = zoom.data.iter().copied().max().unwrap_or(1).max(1) as f64;
    let zoom_rgb = enlarge(&codes_rgb_saturation(&zoom, zmax, max), 12);
    // 2b. the sun in view: ENU yaw = sun azimuth, pitched so the sun is inside the frame
    let sun = cfg.sun.resolve()?;
    let mut sun_view = None;
    for pitch in [-30.0, 30.0] {
        let att = Attitude::enu(sun.azimuth_deg, pitch, 0.0);
        let cam = Camera::new(cfg.intrinsics(), &att, sun.azimuth_deg)?;
        if let Some((x, y)) = cfg
            .camera
            .intrinsics
            .project(cam.enu_to_camera * sun.vector())
        {
            let i = cfg.camera.intrinsics;
            if x > 32.0 && y > 32.0 && x < i.width as f64 - 32.0 && y < i.height as f64 - 32.0 {
                sun_view = Some((att, pitch, x, y));
                break;
            }
        }
    }
    let (att, pitch, sx, sy) =
        sun_view.ok_or_else(|| Error::Invalid("sun figure: the sun is not in view".into()))?;
    let (st, info) = pipe.stokes(sun, &att)?;
    let sun_frame = pipe
        .render(FrameRequest::planes(0, &st).exact().with_truth())?
        .frame; // default exposure 1 ms
                // the same camera (seed) at a short exposure: only the disc and its rim saturate
    let short_us = 50.0;
    let mut short_cfg = cfg.clone();
    let mut s = SensorConfig::preset(Preset::Camera);
    s.exposure = Exposure::Fixed { us: short_us };
    short_cfg.raw.sensor = Some(s);
    let short = RawPipeline::new(&short_cfg)?
        .render(FrameRequest::planes(0, &st).exact().with_truth())?
        .frame;
    let n = 32;
    let (r0, c0) = (
        ((sy.round() as usize).saturating_sub(n / 2)) & !1,
        ((sx.round() as usize).saturating_sub(n / 2)) & !1,
    );
    let sun_crop = crop(&short.codes, r0, c0, n, n);
    // display white: the brightest sky pixel of the crop (codes far below full scale), so the
    // aureole shows; brighter pixels clip to white, pixels at the maximum code are red
    let sun_white = sun_crop
        .data
        .iter()
        .copied()
        .filter(|&v| (v as f64) < 0.5 * max as f64)
        .max()
        .unwrap_or(max)
        .max(1) as f64;
    let sun_rgb = enlarge(&codes_rgb_saturation(&sun_crop, sun_white, max), 9);
    io::write_png_rgb8(
        &out.put("raw_mosaic_zoom.png"),
        &vis::hstack(&[&zoom_rgb, &sun_rgb], 8),
    )?;
    let long_view = saturation_overview(&sun_frame.codes, 8, max as f64, max);
    let short_view = saturation_overview(&short.codes, 8, max as f64 / 16.0, max);
    io::write_png_rgb8(
        &out.put("raw_sun_frame.png"),
        &vis::hstack(&[&long_view, &short_view], 4),
    )?;
    out.numbers.insert(
        "mosaic_zoom".into(),
        serde_json::json!({
            "row": at.0, "col": at.1, "size": block, "mean_truth_dolp": best,
            "display_white_code": zmax,
        }),
    );
    out.numbers.insert(
        "sun_view".into(),
        serde_json::json!({
            "attitude_enu_yaw_deg": sun.azimuth_deg, "pitch_deg": pitch,
            "sun_col": sx, "sun_row": sy, "crop_row": r0, "crop_col": c0, "crop_size": n,
            "sun_disc_pixels": info.sun_pixels,
            "saturated_pixels_1ms": sun_frame.saturated,
            "short_exposure_us": short_us,
            "saturated_pixels_short": short.saturated,
            "saturated_in_crop_short": sun_crop.data.iter().filter(|&&v| v >= max).count(),
            "above_half_scale_in_crop_short": sun_crop.data.iter().filter(|&&v| v as f64 >= 0.5 * max as f64).count(),
            "min_code_above_half_scale_in_crop_short": sun_crop.data.iter().copied().filter(|&v| v as f64 >= 0.5 * max as f64).min(),
            "crop_display_white_code": sun_white,
        }),
    );
    Ok(())
}

/// Figure 3: the four channel sub-images and their ratios to the mean (`raw_channels.png`).
fn channels(frame: &RawFrame, layout: &MosaicLayout, out: &mut Figures) -> Result<()> {
    // 3. the four channel sub-images, common scale; second row: I_k / mean of the four
    let subs: Vec<Image<u16>> = (0..4)
        .map(|ch| {
            let (r, c) = layout.position_of(ch);
            sub_lattice(&frame.codes, r, c)
        })
        .collect();
    let ch_white = frame.codes.data.iter().copied().max().unwrap_or(1).max(1) as f64;
    let row1: Vec<Image<[u8; 3]>> = subs
        .iter()
        .map(|s| vis::gray_rgb(&vis::gray8(&vis::downsample(s, 4), ch_white)))
        .collect();
    let mean4: Vec<f64> = (0..subs[0].data.len())
        .map(|i| subs.iter().map(|s| s.data[i] as f64).sum::<f64>() / 4.0)
        .collect();
    let row2: Vec<Image<[u8; 3]>> = subs
        .iter()
        .map(|s| {
            // ratio 0.5..1.5 → 0..255
            let ratio = Image::from_vec(
                s.width,
                s.height,
                s.data
                    .iter()
                    .zip(&mean4)
                    .map(|(&v, &m)| {
                        if m > 0.0 {
                            (v as f64 / m - 0.5) as f32
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            );
            vis::gray_rgb(&vis::gray8(&vis::downsample(&ratio, 4), 1.0))
        })
        .collect();
    let r1: Vec<&Image<[u8; 3]>> = row1.iter().collect();
    let r2: Vec<&Image<[u8; 3]>> = row2.iter().collect();
    let (a, b) = (vis::hstack(&r1, 4), vis::hstack(&r2, 4));
    io::write_png_gray8(
        &out.put("raw_channels.png"),
        &rgb_to_gray(&vis::vstack(&[&a, &b], 4)),
    )?;
    out.numbers.insert(
        "channels".into(),
        serde_json::json!({ "display_white_code": ch_white }),
    );
    Ok(())
}

/// Figure 4: the PSNS presets beside the camera, same sky (`psns_presets.png`).
fn presets(cfg: &SceneConfig, frame: &RawFrame, out: &mut Figures) -> Result<()> {
    // 4. PSNS presets and the camera, same sky: full frames /8 and a 152 × 128 corner crop ×2
    let mut top = Vec::new();
    let mut bottom = Vec::new();
    let mut preset_numbers = serde_json::Map::new();
    for p in [
        Preset::Nfpi,
        Preset::Gniipi,
        Preset::Gniicpi,
        Preset::Camera,
    ] {
        let f = if p == Preset::Camera {
            frame.clone()
        } else {
            let mut c = cfg.clone();
            c.raw.preset = p;
            {
                let pipe = RawPipeline::new(&c)?;
                pipe.render(pipe.configured_request()?)?.frame
            }
        };
        let fmax = psns::sensor::adc::max_code(f.bit_depth);
        preset_numbers.insert(
            p.to_string(),
            serde_json::json!({
                "max_code": f.codes.data.iter().copied().max().unwrap_or(0),
                "full_scale": fmax,
                "pixels_at_full_scale": f.codes.data.iter().filter(|&&v| v == fmax).count(),
                "median_code": median(f.codes.data.iter().map(|&v| v as f64).collect()),
            }),
        );
        let g = codes_gray(&f.codes, f.bit_depth);
        top.push(vis::gray_rgb(&vis::gray8(&vis::downsample(&g, 8), 255.0)));
        bottom.push(vis::gray_rgb(&enlarge(&crop(&g, 0, 0, 128, 152), 2)));
    }
    let t: Vec<&Image<[u8; 3]>> = top.iter().collect();
    let bt: Vec<&Image<[u8; 3]>> = bottom.iter().collect();
    let (a, b) = (vis::hstack(&t, 6), vis::hstack(&bt, 8));
    io::write_png_gray8(
        &out.put("psns_presets.png"),
        &rgb_to_gray(&vis::vstack(&[&a, &b], 6)),
    )?;
    out.numbers
        .insert("presets".into(), serde_json::Value::Object(preset_numbers));
    Ok(())
}

/// Figure 5: the photon transfer curve (`photon_transfer.svg`).
fn photon_transfer_figure(out: &mut Figures) -> Result<()> {
    // 5. photon transfer
    let ptc = photon_transfer_data(&ptc_sensor_config(), 256, 256, 2024, 2)?;
    let svg = photon_transfer_svg(&ptc)?;
    io::write_atomic(&out.put("photon_transfer.svg"), |w| {
        std::io::Write::write_all(w, svg.as_bytes())
            .map_err(|e| Error::io("writing photon_transfer.svg", e))
    })?;
    let c = &ptc.config;
    out.numbers.insert(
        "photon_transfer".into(),
        serde_json::json!({
            "frame": [ptc.width, ptc.height], "seed": 2024, "pairs_per_level": ptc.pairs,
            "levels": ptc.levels.len(), "black_level_dn": c.black_level_dn,
            "k_dn_per_e": ptc.fit.k, "k_configured": c.k0,
            "dark_noise_e": ptc.fit.dark_noise_e, "read_noise_configured_e": c.read_noise_e,
            "saturation_e": ptc.fit.saturation_e, "full_well_configured_e": c.full_well_e,
            "saturation_mean_dn": ptc.fit.saturation_mean_dn, "fit_points": ptc.fit.fit_points,
            "dark_mean_dn": ptc.dark.mean, "dark_var_dn2": ptc.dark.var,
            "points": ptc.levels.iter().map(|l| [l.exposure_us, l.stats.mean, l.stats.var]).collect::<Vec<_>>(),
        }),
    );
    Ok(())
}

/// Figure 6: the truth DoLP against a plain superpixel estimate
/// (`dolp_truth_vs_superpixel.png`).
fn dolp_truth_vs_superpixel(
    frame: &RawFrame,
    layout: &MosaicLayout,
    out: &mut Figures,
) -> Result<()> {
    // 6. DoLP: ground truth vs a plain superpixel estimate from the raw codes
    let [est, tru] = superpixel_dolp(frame, layout);
    let diff = Image::from_vec(
        est.width,
        est.height,
        est.data
            .iter()
            .zip(&tru.data)
            .map(|(&e, &t)| (e - t) / 0.1 + 0.5)
            .collect(),
    );
    let a = vis::dop_rgb(&vis::downsample(&tru, 6), None);
    let b = vis::dop_rgb(&vis::downsample(&est, 6), None);
    let c = vis::gray_rgb(&vis::gray8(&vis::downsample(&diff, 6), 1.0));
    io::write_png_rgb8(
        &out.put("dolp_truth_vs_superpixel.png"),
        &vis::hstack(&[&a, &b, &c], 4),
    )?;
    let d: Vec<f64> = est
        .data
        .iter()
        .zip(&tru.data)
        .filter(|(_, &t)| t > 0.1)
        .map(|(&e, &t)| (e / t) as f64)
        .collect();
    out.numbers.insert(
        "superpixel_dolp".into(),
        serde_json::json!({
            "median_ratio_estimate_over_truth": median(d),
            "truth_dolp_max": tru.data.iter().copied().fold(0.0f32, f32::max),
        }),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photon_transfer_recovers_k_on_a_small_frame() {
        let cfg = ptc_sensor_config();
        let d = photon_transfer_data(&cfg, 128, 128, 7, 1).unwrap();
        assert_eq!(d.levels.len(), ptc_fractions().len());
        println!(
            "128x128, 1 pair/level: K = {:.5} DN/e- (configured {:.5}), dark noise {:.3} e-, saturation {:.0} e-, {} fit points",
            d.fit.k, cfg.k0, d.fit.dark_noise_e, d.fit.saturation_e, d.fit.fit_points
        );
        assert!(
            (d.fit.k / cfg.k0 - 1.0).abs() < 0.02,
            "K {} vs {}",
            d.fit.k,
            cfg.k0
        );
        // means increase with exposure up to saturation
        assert!(d.levels[0].stats.mean < d.levels[10].stats.mean);
        // the pure function is deterministic
        let again = photon_transfer_data(&cfg, 128, 128, 7, 1).unwrap();
        assert_eq!(again.fit, d.fit);
        let svg = photon_transfer_svg(&d).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("mean above dark"));
    }

    #[test]
    fn brightest_channel_is_the_superpixel_maximum() {
        let cfg = SensorConfig {
            stages: psns::sensor::Stages::none(),
            ..Default::default()
        };
        let intr = psns::camera::Intrinsics::with_size(8, 4);
        let s = Sensor::new(&cfg, &intr, 1).unwrap();
        // fully polarized at 45°: the 45° pixel (0,1) of every superpixel is the brightest
        let st = flat_field(8, 4, 0.1, 1.0, 45.0).unwrap();
        let rate = s.electron_rate(&st).unwrap();
        let b = brightest_channel_rates(&s, &st).unwrap();
        assert_eq!(b.len(), 8);
        assert!(b.iter().all(|&v| v == rate[1]), "{b:?} vs {}", rate[1]);
        assert!(rate[1] > rate[0] && rate[1] > rate[8] && rate[1] > rate[9]);
        assert_eq!(percentile(vec![3.0, 1.0, 2.0, 4.0], 50.0), 2.0);
        assert_eq!(percentile(vec![3.0, 1.0, 2.0, 4.0], 99.0), 4.0);
    }

    #[test]
    fn crop_enlarge_lattice() {
        let img = Image::from_vec(4, 4, (0u16..16).collect());
        assert_eq!(crop(&img, 1, 2, 2, 2).data, vec![6, 7, 10, 11]);
        let e = enlarge(&crop(&img, 0, 0, 1, 2), 2);
        assert_eq!(e.data, vec![0, 0, 1, 1, 0, 0, 1, 1]);
        assert_eq!(sub_lattice(&img, 1, 0).data, vec![4, 6, 12, 14]);
    }
}
