//! `psns bench heading`: the whole chain sky → sensor → demosaic → Stokes → heading measured
//! against the truth, one factor at a time around a baseline, for every estimator; per-cell RMS,
//! 95th percentile and maximum error, mean confidence, confident-wrong frames and time per frame,
//! as CSV and SVG charts.

use super::demosaic::BenchFiles;
use psns::camera::{Attitude, Intrinsics};
use psns::config::SceneConfig;
use psns::demosaic::Method;
use psns::heading::{
    error_stats, estimate_heading, polar_from_codes, wrap180, HeadingMethod, HeadingSetup,
    PolarView,
};
use psns::image::StokesImage;
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::sensor::{Exposure, SensorConfig};
use psns::sky::clouds::SoftClouds;
use psns::sky::PolarizationModel;
use psns::sun::SunPosition;
use psns::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

/// Options of `psns bench heading`.
#[derive(Clone, Debug)]
pub struct HeadingBenchOptions {
    /// Output directory.
    pub out: PathBuf,
    /// Small frames, two yaws, fewer values per factor (refused with an --out inside docs/).
    pub quick: bool,
}

/// Exposure of a cell: auto, or a fraction of the auto-exposure time (low light).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expo {
    Auto,
    Fraction(f64),
}

/// One cell's scene, sensor and processing.
#[derive(Clone, Debug)]
struct Case {
    sun_elevation: f64,
    turbidity: f64,
    exposure: Expo,
    clouds: usize,
    demosaic: Method,
    bits: u8,
    tilt: (f64, f64),
    /// Rayleigh sky with this maximum DOP (the low-DoLP factor); `None` = default sky.
    rayleigh_dop: Option<f64>,
}

const BASE: Case = Case {
    sun_elevation: 40.0,
    turbidity: 4.0,
    exposure: Expo::Auto,
    clouds: 0,
    demosaic: Method::Bilinear,
    bits: 12,
    tilt: (0.0, 0.0),
    rayleigh_dop: None,
};

/// Sun azimuth of every cell (compass degrees).
const SUN_AZIMUTH: f64 = 200.0;
/// A frame counts as confidently wrong with an error above this (degrees) at a confidence of at
/// least [`CONFIDENT`].
pub const WRONG_DEG: f64 = 2.0;
/// See [`WRONG_DEG`].
pub const CONFIDENT: f64 = 0.5;

/// The factors and their values: (factor, [(label, case)]).
fn factors(quick: bool) -> Vec<(&'static str, Vec<(String, Case)>)> {
    let pick = |v: Vec<(String, Case)>| -> Vec<(String, Case)> {
        if quick && v.len() > 2 {
            vec![v[0].clone(), v[v.len() - 1].clone()]
        } else {
            v
        }
    };
    let with = |f: &dyn Fn(&mut Case)| {
        let mut c = BASE.clone();
        f(&mut c);
        c
    };
    let mut out = Vec::new();
    out.push((
        "sun elevation (deg)",
        pick(
            [
                5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0, 89.0,
            ]
            .iter()
            .map(|&e| (format!("{e}"), with(&|c| c.sun_elevation = e)))
            .collect(),
        ),
    ));
    out.push((
        "turbidity",
        pick(
            [2.0, 3.0, 4.0, 6.0, 8.0]
                .iter()
                .map(|&t| (format!("{t}"), with(&|c| c.turbidity = t)))
                .collect(),
        ),
    ));
    out.push((
        "exposure (x auto)",
        pick(
            [1.0, 0.3, 0.1, 0.03, 0.01, 0.003]
                .iter()
                .map(|&f| {
                    let label = if f == 1.0 {
                        "auto".to_string()
                    } else {
                        format!("{f}")
                    };
                    let e = if f == 1.0 {
                        Expo::Auto
                    } else {
                        Expo::Fraction(f)
                    };
                    (label, with(&|c| c.exposure = e))
                })
                .collect(),
        ),
    ));
    out.push((
        "cloud patches",
        pick(
            [0usize, 4, 10, 20, 40]
                .iter()
                .map(|&n| (format!("{n}"), with(&|c| c.clouds = n)))
                .collect(),
        ),
    ));
    out.push((
        "demosaic",
        pick(
            Method::ALL
                .iter()
                .map(|&m| (m.name().to_string(), with(&|c| c.demosaic = m)))
                .collect(),
        ),
    ));
    out.push((
        "bit depth",
        pick(
            [8u8, 10, 12]
                .iter()
                .map(|&b| (format!("{b}"), with(&|c| c.bits = b)))
                .collect(),
        ),
    ));
    out.push((
        "tilt pitch/roll (deg)",
        pick(
            [
                (0.0, 0.0),
                (2.0, -2.0),
                (5.0, 5.0),
                (-5.0, 3.0),
                (10.0, -10.0),
            ]
            .iter()
            .map(|&t| (format!("{}/{}", t.0, t.1), with(&|c| c.tilt = t)))
            .collect(),
        ),
    ));
    // the target cells: sun 10..70° with both tilts at 5° (compensated), clear and cloudy
    let mut combined = Vec::new();
    for clouds in [0usize, 20] {
        for e in [10.0, 40.0, 70.0] {
            combined.push((
                format!("{e}/t5/c{clouds}"),
                with(&|c| {
                    c.sun_elevation = e;
                    c.tilt = (5.0, -5.0);
                    c.clouds = clouds;
                }),
            ));
        }
    }
    // label: sun elevation / tilt 5° (pitch 5, roll −5) / cloud patches
    out.push(("combined: sun/tilt/clouds", pick(combined)));
    out.push((
        "max DoLP (rayleigh sky)",
        pick(
            [1.0, 0.3, 0.1, 0.05, 0.02]
                .iter()
                .map(|&d| (format!("{d}"), with(&|c| c.rayleigh_dop = Some(d))))
                .collect(),
        ),
    ));
    out
}

/// One frame's result for one method.
#[derive(Clone, Debug)]
pub struct FrameRow {
    /// Factor swept.
    pub factor: String,
    /// Value of the factor.
    pub value: String,
    /// True yaw, degrees.
    pub yaw: f64,
    /// Estimator.
    pub method: HeadingMethod,
    /// Signed error, degrees (NaN: no estimate).
    pub error: f64,
    /// Confidence (0 without an estimate).
    pub confidence: f64,
    /// Demosaic + estimator time, ms.
    pub ms: f64,
}

/// One cell (factor value × method).
#[derive(Clone, Debug)]
pub struct CellRow {
    /// Factor swept.
    pub factor: String,
    /// Value of the factor.
    pub value: String,
    /// Estimator.
    pub method: HeadingMethod,
    /// Frames.
    pub frames: usize,
    /// Frames without an estimate.
    pub no_estimate: usize,
    /// RMS error, degrees.
    pub rms: f64,
    /// 95th percentile |error|.
    pub p95: f64,
    /// Largest |error|.
    pub max: f64,
    /// Mean confidence.
    pub confidence: f64,
    /// Frames with |error| > [`WRONG_DEG`] at confidence ≥ [`CONFIDENT`].
    pub confident_wrong: usize,
    /// Median time per frame (demosaic + estimator), ms.
    pub ms: f64,
    /// Cloud cover of the cell's frames (mean opacity), 0..1.
    pub cloud_cover: f64,
}

fn scene(case: &Case, intr: Intrinsics, exposure: Exposure) -> SceneConfig {
    let mut cfg = SceneConfig::default();
    cfg.camera.intrinsics = intr;
    cfg.sun.zenith_deg = Some(90.0 - case.sun_elevation);
    cfg.sun.altitude_deg = None;
    cfg.sun.azimuth_deg = Some(SUN_AZIMUTH);
    cfg.sun.time = None;
    cfg.sky.turbidity = case.turbidity;
    if let Some(d) = case.rayleigh_dop {
        cfg.sky.model = PolarizationModel::Rayleigh;
        cfg.sky.dop_max = d;
    }
    let mut s = SensorConfig::preset(cfg.raw.preset);
    s.exposure = exposure;
    s.bit_depth = case.bits;
    cfg.raw.sensor = Some(s);
    if case.clouds > 0 {
        cfg.raw.soft_clouds = Some(SoftClouds {
            count: case.clouds,
            ..SoftClouds::default()
        });
    }
    cfg
}

/// Mean opacity of the clouds the pipeline draws for `cfg` (the same seed as
/// `RawPipeline::stokes`), 0 without clouds.
fn cloud_cover(cfg: &SceneConfig) -> Result<f64> {
    let Some(c) = &cfg.raw.soft_clouds else {
        return Ok(0.0);
    };
    let i = cfg.intrinsics();
    let mut st = StokesImage::zeros(i.width, i.height);
    st.s0.data.fill(1.0); // clouds are drawn only over sky (S0 > 0)
    let op = psns::sky::clouds::apply_soft_clouds(&mut st, c, cfg.raw.seed ^ 0x636c_6f75_6473)?;
    Ok(op.iter().map(|&v| v as f64).sum::<f64>() / op.len().max(1) as f64)
}

/// Runs the sweep; `progress` sees each finished cell.
pub fn run_sweep(
    opts: &HeadingBenchOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<FrameRow>, Vec<CellRow>)> {
    // the full sensor's field of view at a quarter (quick: an eighth) of its pixels
    let (w, h, k, yaws): (usize, usize, f64, Vec<f64>) = if opts.quick {
        (304, 256, 8.0, vec![17.0, 197.0])
    } else {
        (
            612,
            512,
            4.0,
            (0..8).map(|j| 17.0 + 45.0 * j as f64).collect(),
        )
    };
    let intr = Intrinsics {
        pixel_pitch_um: 3.45 * k,
        ..Intrinsics::with_size(w, h)
    };
    let (mut frames, mut cells) = (Vec::new(), Vec::new());
    for (factor, values) in factors(opts.quick) {
        for (label, case) in values {
            let (exposure, light) = match case.exposure {
                Expo::Auto => (Exposure::auto(), 1.0),
                Expo::Fraction(f) => {
                    // the auto-exposure time of this scene, scaled; below the shortest exposure
                    // (20 µs) the lens transmission takes the rest, so the light is f × auto
                    let pipe = RawPipeline::new(&scene(&case, intr, Exposure::auto()))?;
                    let frame = pipe.render(pipe.configured_request()?)?.frame;
                    let want = frame.exposure_us * f;
                    (
                        Exposure::Fixed { us: want.max(20.0) },
                        want / want.max(20.0),
                    )
                }
            };
            let mut cfg = scene(&case, intr, exposure);
            if let Some(s) = cfg.raw.sensor.as_mut() {
                s.lens_transmission *= light;
            }
            let cover = cloud_cover(&cfg)?;
            let pipe = RawPipeline::new(&cfg)?;
            let sun = SunPosition::new(90.0 - case.sun_elevation, SUN_AZIMUTH);
            let mut cell: Vec<FrameRow> = Vec::new();
            for (j, &yaw) in yaws.iter().enumerate() {
                let att = Attitude::enu(yaw, case.tilt.0, case.tilt.1);
                let (st, _) = pipe.stokes(sun, &att)?;
                let frame = pipe
                    .render(FrameRequest::planes(j as u64, &st).exact())?
                    .frame;
                let t0 = Instant::now();
                let (p, _) = polar_from_codes(
                    &frame.codes,
                    frame.black_level_dn,
                    pipe.sensor_config().layout,
                    frame.bit_depth,
                    case.demosaic,
                )?;
                let demosaic_ms = t0.elapsed().as_secs_f64() * 1e3;
                let view = PolarView {
                    aolp_deg: &p.aolp_deg,
                    dolp: &p.dolp,
                    s0: Some(&p.stokes.s0),
                    mask: None,
                };
                let mut setup = HeadingSetup::new(pipe.config().camera.intrinsics, sun);
                setup.pitch_deg = case.tilt.0;
                setup.roll_deg = case.tilt.1;
                for m in HeadingMethod::ALL {
                    let t1 = Instant::now();
                    let e = estimate_heading(m, &view, &setup);
                    let ms = demosaic_ms + t1.elapsed().as_secs_f64() * 1e3;
                    let (error, confidence) = match e {
                        Ok(e) => (wrap180(e.yaw_deg - yaw), e.confidence),
                        Err(Error::TooFewPixels(_) | Error::Undetermined(_)) => (f64::NAN, 0.0),
                        Err(e) => return Err(e),
                    };
                    cell.push(FrameRow {
                        factor: factor.to_string(),
                        value: label.clone(),
                        yaw,
                        method: m,
                        error,
                        confidence,
                        ms,
                    });
                }
            }
            for m in HeadingMethod::ALL {
                let rows: Vec<&FrameRow> = cell.iter().filter(|r| r.method == m).collect();
                let errs: Vec<f64> = rows.iter().map(|r| r.error).collect();
                let st = error_stats(&errs);
                let mut ms: Vec<f64> = rows.iter().map(|r| r.ms).collect();
                ms.sort_by(f64::total_cmp);
                cells.push(CellRow {
                    factor: factor.to_string(),
                    value: label.clone(),
                    method: m,
                    frames: rows.len(),
                    no_estimate: rows.len() - st.count,
                    rms: st.rms,
                    p95: st.p95,
                    max: st.max,
                    confidence: rows.iter().map(|r| r.confidence).sum::<f64>()
                        / rows.len().max(1) as f64,
                    confident_wrong: rows
                        .iter()
                        .filter(|r| r.confidence >= CONFIDENT && r.error.abs() > WRONG_DEG)
                        .count(),
                    ms: ms[ms.len() / 2],
                    cloud_cover: cover,
                });
            }
            progress(&format!("{factor} = {label}"));
            frames.extend(cell);
        }
    }
    // the yaw factor: the baseline frames (the exposure factor's first cell, auto) by yaw
    for m in HeadingMethod::ALL {
        for &yaw in &yaws {
            let rows: Vec<&FrameRow> = frames
                .iter()
                .filter(|r| {
                    r.factor == "exposure (x auto)"
                        && r.value == "auto"
                        && r.method == m
                        && r.yaw == yaw
                })
                .collect();
            if rows.is_empty() {
                continue;
            }
            let errs: Vec<f64> = rows.iter().map(|r| r.error).collect();
            let st = error_stats(&errs);
            cells.push(CellRow {
                factor: "yaw (deg)".into(),
                value: format!("{yaw}"),
                method: m,
                frames: rows.len(),
                no_estimate: rows.len() - st.count,
                rms: st.rms,
                p95: st.p95,
                max: st.max,
                confidence: rows[0].confidence,
                confident_wrong: 0,
                ms: rows[0].ms,
                cloud_cover: 0.0,
            });
        }
    }
    Ok((frames, cells))
}

/// Order of the factors in the charts.
pub const FACTOR_ORDER: [&str; 10] = [
    "sun elevation (deg)",
    "yaw (deg)",
    "turbidity",
    "exposure (x auto)",
    "cloud patches",
    "demosaic",
    "bit depth",
    "tilt pitch/roll (deg)",
    "max DoLP (rayleigh sky)",
    "combined: sun/tilt/clouds",
];

type PlotErr<E> = plotters::drawing::DrawingAreaErrorKind<E>;
fn perr<E: std::error::Error + Send + Sync>(e: PlotErr<E>) -> Error {
    Error::Invalid(format!("plotting: {e}"))
}

const COLOURS: [(u8, u8, u8); 3] = [(31, 119, 180), (214, 39, 40), (44, 160, 44)];

fn colour(m: HeadingMethod) -> plotters::style::RGBColor {
    let k = HeadingMethod::ALL.iter().position(|&x| x == m).unwrap_or(0);
    let (r, g, b) = COLOURS[k];
    plotters::style::RGBColor(r, g, b)
}

/// Error to chart: NaN (no estimate) and 0 are drawn at the axis limits.
fn clamp_err(v: f64) -> f64 {
    if v.is_finite() {
        v.clamp(1e-4, 180.0)
    } else {
        180.0
    }
}

/// RMS (lines) and p95 (crosses) error against each factor, one panel per factor, log scale.
pub fn factors_svg(cells: &[CellRow]) -> Result<String> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1500, 1280)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let (title, body) = root.split_vertically(40);
        title
            .draw(&Text::new(
                "psns bench heading: RMS (line) and p95 (x) heading error per factor; no estimate drawn at 180",
                (20, 12),
                ("sans-serif", 18).into_font(),
            ))
            .map_err(perr)?;
        let panels = body.split_evenly((4, 3));
        for (area, &factor) in panels.iter().zip(FACTOR_ORDER.iter()) {
            let mut labels: Vec<String> = Vec::new();
            for c in cells.iter().filter(|c| c.factor == factor) {
                if !labels.contains(&c.value) {
                    labels.push(c.value.clone());
                }
            }
            if labels.is_empty() {
                continue;
            }
            let n = labels.len();
            let lab = labels.clone();
            let mut chart = ChartBuilder::on(area)
                .caption(factor, ("sans-serif", 15))
                .margin(8)
                .x_label_area_size(32)
                .y_label_area_size(50)
                .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), (1e-4f64..200.0).log_scale())
                .map_err(perr)?;
            chart
                .configure_mesh()
                .x_labels(n)
                .x_label_formatter(&move |x| {
                    let k = x.round();
                    if (x - k).abs() < 0.01 && k >= 0.0 && (k as usize) < lab.len() {
                        lab[k as usize].clone()
                    } else {
                        String::new()
                    }
                })
                .y_desc("error, deg")
                .disable_x_mesh()
                .max_light_lines(0)
                .bold_line_style(RGBColor(230, 230, 230))
                .label_style(("sans-serif", 11))
                .draw()
                .map_err(perr)?;
            for m in HeadingMethod::ALL {
                let col = colour(m);
                let pts: Vec<(f64, f64, f64)> = labels
                    .iter()
                    .enumerate()
                    .filter_map(|(k, l)| {
                        cells
                            .iter()
                            .find(|c| c.factor == factor && &c.value == l && c.method == m)
                            .map(|c| (k as f64, clamp_err(c.rms), clamp_err(c.p95)))
                    })
                    .collect();
                chart
                    .draw_series(LineSeries::new(
                        pts.iter().map(|p| (p.0, p.1)),
                        col.stroke_width(2),
                    ))
                    .map_err(perr)?
                    .label(m.name())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 3, col.filled())))
                    .map_err(perr)?;
                chart
                    .draw_series(pts.iter().map(|p| Cross::new((p.0, p.2), 4, col)))
                    .map_err(perr)?;
            }
            if factor == FACTOR_ORDER[0] {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperLeft)
                    .border_style(BLACK)
                    .background_style(WHITE.mix(0.85))
                    .label_font(("sans-serif", 12))
                    .draw()
                    .map_err(perr)?;
            }
        }
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

/// RMS error against median time per frame, one point per cell and method.
pub fn time_svg(cells: &[CellRow]) -> Result<String> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let xs: Vec<f64> = cells.iter().map(|c| c.ms).filter(|v| *v > 0.0).collect();
        if xs.is_empty() {
            return Err(Error::Invalid("nothing to chart".into()));
        }
        let x0 = xs.iter().copied().fold(f64::MAX, f64::min) / 1.5;
        let x1 = xs.iter().copied().fold(0.0, f64::max) * 1.5;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "psns bench heading: RMS error against time per frame (demosaic + estimator)",
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (1e-4f64..200.0).log_scale())
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("ms per frame (median of the cell)")
            .y_desc("RMS heading error, deg (no estimate at 180)")
            .max_light_lines(0)
            .bold_line_style(RGBColor(230, 230, 230))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        for m in HeadingMethod::ALL {
            let col = colour(m);
            chart
                .draw_series(
                    cells
                        .iter()
                        .filter(|c| c.method == m && c.factor != "yaw (deg)")
                        .map(|c| Circle::new((c.ms, clamp_err(c.rms)), 4, col.mix(0.7).filled())),
                )
                .map_err(perr)?
                .label(m.name())
                .legend(move |(x, y)| Circle::new((x, y), 4, col.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

/// A CSV field, quoted when it holds a comma or a quote.
pub(super) fn csv_field(s: &str) -> String {
    if s.contains(',') || s.contains('"') {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `psns bench heading`; returns the files written.
pub fn bench_heading(opts: &HeadingBenchOptions) -> Result<Vec<String>> {
    let mut files = BenchFiles::create(opts.quick, &opts.out)?;
    let t0 = Instant::now();
    let (frames, cells) = run_sweep(opts, &mut |s| {
        eprintln!(
            "psns bench heading: {s} ({:.0} s)",
            t0.elapsed().as_secs_f64()
        )
    })?;
    let mut c = String::from(
        "factor,value,method,frames,no_estimate,rms_deg,p95_deg,max_deg,mean_confidence,confident_wrong,ms_per_frame,cloud_cover\n",
    );
    for r in &cells {
        c += &format!(
            "{},{},{},{},{},{:.4},{:.4},{:.4},{:.3},{},{:.1},{:.3}\n",
            csv_field(&r.factor),
            csv_field(&r.value),
            r.method,
            r.frames,
            r.no_estimate,
            r.rms,
            r.p95,
            r.max,
            r.confidence,
            r.confident_wrong,
            r.ms,
            r.cloud_cover
        );
    }
    files.put("heading.csv", &c)?;
    let mut f = String::from("factor,value,yaw_deg,method,error_deg,confidence,ms\n");
    for r in &frames {
        f += &format!(
            "{},{},{},{},{:.4},{:.3},{:.1}\n",
            csv_field(&r.factor),
            csv_field(&r.value),
            r.yaw,
            r.method,
            r.error,
            r.confidence,
            r.ms
        );
    }
    files.put("heading_frames.csv", &f)?;
    files.put("heading_factors.svg", &factors_svg(&cells)?)?;
    files.put("heading_time.svg", &time_svg(&cells)?)?;
    Ok(files.into_written())
}
