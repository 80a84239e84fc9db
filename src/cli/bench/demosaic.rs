//! `psns demosaic` and `psns bench demosaic`: demosaic files and streams, score every method on
//! the named scenes of [`crate::cli::bench::scenes`] against the emulator's ground truth, chart speed against
//! accuracy, and map where each method fails.
//!
//! Scoring (spec `demosaic.md` §2): the estimate is the demosaic of (codes − black level); the
//! truth is [`RawFrame::truth`] (ideal polarizer, no noise, output DN above black). S0 PSNR uses
//! peak = 2^bits − 1; DoLP RMSE and bias are over every pixel; AoLP RMSE (axial, mod 180°) is over
//! pixels with true DoLP > [`DOLP_THRESHOLD`]; an 8-pixel border is excluded. Pixels within
//! [`SAT_RADIUS`] of a saturated code (≥ [`saturation_threshold`]: the top code or a full well,
//! which reads 4091–4094 at 12 bit after read noise and DSNU) are excluded from the main scores (the truth is not clipped,
//! so no demosaicker can be right there); `aolp_rmse_all_deg` keeps them.
//!
//! Timing: the median of `runs` calls of [`full_chain_into`] with output buffers reused across
//! runs (raw u16 mosaic in memory → S0, S1, S2, DoLP, AoLP f32 in memory), and, as a second
//! column, [`full_chain`] with fresh output allocation; both on the full clear-sky frame.
//!
//! Noise laws (spec §4): [`noise_sweep`] renders uniform flat fields through the emulator with
//! shot and read noise only and measures the mean DoLP at p = 0 (theory 0.886/√N) and the AoLP
//! spread at p > 0 (theory 20.3°/(p√N)).

use crate::cli::bench::error_maps::*;
use crate::cli::bench::scenes::{self, Scene, SceneFrame};
use crate::cli::progress::{Progress, Unit};
use psns::angle::SensorAngle;
use psns::demosaic::demosaic_codes;
use psns::demosaic::{full_chain, full_chain_into, Method, PolarImages, RawPixel};
use psns::error::{Error, Result};
use psns::image::{Image, StokesImage};
use psns::io::{create_dir, write_text};
use psns::sensor::mosaic::MosaicLayout;
use psns::sensor::{self, Exposure, RawFrame, Sensor, SensorConfig, Stages};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// AoLP is scored where the true DoLP exceeds this.
pub const DOLP_THRESHOLD: f64 = 0.05;
/// Border excluded from the scores, pixels.
pub const BORDER: usize = 8;
/// Pixels closer than this (Chebyshev distance) to a clipped code are excluded from the main
/// scores: the widest kernel (EARI, Keys) reaches 3 pixels.
pub const SAT_RADIUS: usize = 3;
/// Largest file the benchmark may write into docs/, bytes.
pub const MAX_FILE_BYTES: usize = 300_000;

/// Lowest code counted as saturated at `bit_depth`: the top code minus 4 DN at 12 bit, scaled
/// to the depth and rounded (8 bit: the top code only; 16 bit: top − 64). The sensor counts a
/// pixel whose well is full as saturated although read noise and DSNU make it read a few DN
/// below the top code ([`RawFrame::saturated`]); `RawFrame` has no per-pixel map, so the
/// benchmark seeds its mask from this threshold.
pub fn saturation_threshold(bit_depth: u8) -> u16 {
    let max = psns::sensor::adc::max_code(bit_depth);
    let margin = (4.0 * max as f64 / 4095.0).round() as u16;
    max - margin.min(max)
}

/// Pixels within `radius` (Chebyshev) of a code ≥ `max` (separable dilation).
pub fn saturation_mask(codes: &Image<u16>, max: u16, radius: usize) -> Vec<bool> {
    let (w, h) = (codes.width, codes.height);
    let mut rows = vec![false; w * h];
    rows.par_chunks_mut(w).enumerate().for_each(|(r, out)| {
        let src = codes.row(r);
        for (c, &v) in src.iter().enumerate() {
            if v >= max {
                let lo = c.saturating_sub(radius);
                let hi = (c + radius).min(w - 1);
                out[lo..=hi].iter_mut().for_each(|x| *x = true);
            }
        }
    });
    let mut out = vec![false; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(r, o)| {
        let lo = r.saturating_sub(radius);
        let hi = (r + radius).min(h - 1);
        for rr in lo..=hi {
            for (x, &s) in o.iter_mut().zip(&rows[rr * w..(rr + 1) * w]) {
                *x |= s;
            }
        }
    });
    out
}

/// Scores like [`psns::stokes::score`], skipping pixels where `exclude` is true (every score,
/// including the S0 PSNR and the pixel counts), with the estimated DoLP clipped to ≤ 1: where a
/// kernel rings to S0 ≈ 0 in a dark region the raw ratio reaches 10³ and a handful of pixels
/// would own the RMSE (they are counted separately by [`score_scene`]).
pub fn score_masked(
    est: &StokesImage,
    truth: &StokesImage,
    peak: f64,
    dolp_threshold: f64,
    border: usize,
    exclude: Option<&[bool]>,
) -> Result<psns::stokes::Scores> {
    psns::stokes::score_with(est, truth, peak, dolp_threshold, border, exclude, true)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Median ms per full chain (raw → S0, S1, S2, DoLP, AoLP) over `runs` runs after one warm-up:
/// (with output buffers reused across runs, with fresh output allocation each run).
pub fn time_full_chain<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
    runs: usize,
) -> Result<(f64, f64)> {
    let runs = runs.max(1);
    let (w, h) = (raw.width, raw.height);
    let mut out = PolarImages {
        stokes: StokesImage::zeros(w, h),
        dolp: Image::new(w, h),
        aolp_deg: Image::new(w, h),
    };
    full_chain_into(raw, layout, method, &mut out)?;
    let mut reused = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t0 = Instant::now();
        full_chain_into(raw, layout, method, &mut out)?;
        reused.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    drop(out);
    let mut fresh = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t0 = Instant::now();
        let p = full_chain(raw, layout, method)?;
        fresh.push(t0.elapsed().as_secs_f64() * 1e3);
        drop(p); // freeing is not part of the timed chain
    }
    Ok((median(&mut reused), median(&mut fresh)))
}

/// Options of `psns bench demosaic`.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Output directory (CSV, chart, stability maps).
    pub out: PathBuf,
    /// Timed runs per method (median reported).
    pub runs: usize,
    /// Smaller frames and fewer runs, for a quick look / tests.
    pub quick: bool,
}

/// One row of `demosaic.csv`: one method on one scene.
#[derive(Clone, Debug)]
pub struct BenchRow {
    /// Method.
    pub method: Method,
    /// Scene.
    pub scene: Scene,
    /// Output bit depth of the scene's frame.
    pub bits: u8,
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Median ms per full chain, buffers reused (timed on the clear-sky frame).
    pub ms_per_frame: f64,
    /// Median ms per full chain with fresh output allocation.
    pub ms_per_frame_fresh: f64,
    /// Scores with saturated neighbourhoods excluded.
    pub scores: psns::stokes::Scores,
    /// AoLP RMSE over every pixel with true DoLP above the threshold, saturated ones included.
    pub aolp_rmse_all_deg: f64,
    /// Pixels excluded as saturated (inside the border).
    pub n_saturated_excluded: usize,
    /// Scored pixels whose estimated DoLP exceeds 1 (clipped to 1 for the DoLP scores).
    pub n_dolp_above_1: usize,
}

/// The CSV header of `demosaic.csv`.
pub const CSV_HEADER: &str = "method,scene,bits,width,height,ms_per_frame,ms_per_frame_fresh,s0_psnr_db,dolp_rmse,dolp_bias,aolp_rmse_deg,aolp_mae_deg,aolp_rmse_all_deg,n_aolp_px,n_sat_excluded_px,n_dolp_above_1_px";

impl BenchRow {
    fn csv(&self) -> String {
        let s = &self.scores;
        format!(
            "{},{},{},{},{},{:.2},{:.2},{:.2},{:.5},{:.5},{:.3},{:.3},{:.3},{},{},{}",
            self.method,
            self.scene,
            self.bits,
            self.width,
            self.height,
            self.ms_per_frame,
            self.ms_per_frame_fresh,
            s.s0_psnr_db,
            s.dolp_rmse,
            s.dolp_bias,
            s.aolp_rmse_deg,
            s.aolp_mean_abs_deg,
            self.aolp_rmse_all_deg,
            s.n_aolp_pixels,
            self.n_saturated_excluded,
            self.n_dolp_above_1
        )
    }
}

/// What [`score_scene`] measured.
#[derive(Clone, Debug)]
pub struct SceneScore {
    /// Scores with saturated neighbourhoods excluded.
    pub scores: psns::stokes::Scores,
    /// AoLP RMSE with them.
    pub aolp_rmse_all_deg: f64,
    /// Pixels excluded as saturated (inside the border).
    pub n_saturated_excluded: usize,
    /// Scored pixels with estimated DoLP > 1.
    pub n_dolp_above_1: usize,
    /// The demosaiced images.
    pub images: PolarImages,
}

/// Scores one method on one rendered scene; `sat` marks the pixels to exclude.
pub fn score_scene(sf: &SceneFrame, method: Method, sat: &[bool]) -> Result<SceneScore> {
    let f = &sf.frame;
    let layout = sf
        .config
        .raw
        .sensor
        .as_ref()
        .map_or(MosaicLayout::IMX250MZR, |s| s.layout);
    let p = demosaic_codes(&f.codes, f.black_level_dn, layout, method)?;
    let peak = ((1u32 << f.bit_depth) - 1) as f64;
    let s = score_masked(&p.stokes, &f.truth, peak, DOLP_THRESHOLD, BORDER, Some(sat))?;
    let all = score_masked(&p.stokes, &f.truth, peak, DOLP_THRESHOLD, BORDER, None)?;
    let (w, h) = (f.codes.width, f.codes.height);
    let n_dolp_above_1 = (BORDER..h - BORDER)
        .map(|r| {
            (BORDER..w - BORDER)
                .filter(|&c| !sat[r * w + c] && p.dolp.data[r * w + c] > 1.0)
                .count()
        })
        .sum();
    Ok(SceneScore {
        scores: s,
        aolp_rmse_all_deg: all.aolp_rmse_deg,
        n_saturated_excluded: all.n_pixels - s.n_pixels,
        n_dolp_above_1,
        images: p,
    })
}

fn sat_mask_of(f: &RawFrame) -> Vec<bool> {
    saturation_mask(&f.codes, saturation_threshold(f.bit_depth), SAT_RADIUS)
}

/// One row of the noise-law sweep.
#[derive(Clone, Copy, Debug)]
pub struct SweepRow {
    /// Method.
    pub method: Method,
    /// Mean electrons per pixel N.
    pub electrons: f64,
    /// True DoLP of the flat field.
    pub dolp: f64,
    /// Mean estimated DoLP.
    pub mean_dolp: f64,
    /// RMS axial AoLP error, degrees.
    pub aolp_sigma_deg: f64,
    /// 0.886/√N (the p = 0 bias law).
    pub theory_bias: f64,
    /// 20.3°/(p√N), capped at 90°/√3 (uniform AoLP), NaN at p = 0.
    pub theory_sigma_deg: f64,
}

/// True AoLP of the sweep's flat fields, degrees.
pub const SWEEP_AOLP_DEG: f64 = 30.0;

/// The sweep's sensor: the camera with shot and read noise (2.5 e⁻) only, ideal polarizer, no RI,
/// no fixed patterns, no rounding or full-well clip, 1 DN per electron.
pub fn sweep_sensor() -> SensorConfig {
    SensorConfig {
        stages: Stages {
            shot: true,
            read: true,
            ..Stages::none()
        },
        k0: 1.0,
        full_well_e: 1e6,
        exposure: Exposure::Fixed { us: 1000.0 },
        ..SensorConfig::default()
    }
}

/// Exposure sweep on uniform flat fields (`size` x `size`, DoLP `dolp`, AoLP 30°): for each mean
/// electron count N and method, the mean DoLP and the RMS AoLP error over the frame minus the
/// border. Seeded; one frame per N.
pub fn noise_sweep(
    size: usize,
    electrons: &[f64],
    dolp: f64,
    methods: &[Method],
    seed: u64,
) -> Result<Vec<SweepRow>> {
    let intr = scenes::intrinsics(size, size);
    let cfg = sweep_sensor();
    let sensor = Sensor::new(&cfg, &intr, seed)?;
    let unit = sensor::flat_field(size, size, 1.0, 0.0, 0.0)?;
    let rate = sensor.electron_rate(&unit)?;
    let per_radiance = rate[0] * 1e-3; // electrons per pixel per unit radiance at 1000 µs
    let mut rows = Vec::new();
    for (k, &n) in electrons.iter().enumerate() {
        psns::error::check_range("electrons", n, 1.0, 1e5)?;
        let st = sensor::flat_field(size, size, n / per_radiance, dolp, SWEEP_AOLP_DEG)?;
        let opts = sensor::FrameOptions::exact().with_truth();
        let fr = sensor.frame(sensor::Radiance::Planes(&st), k as u64, opts)?;
        let analog = fr
            .analog
            .ok_or_else(|| Error::Invalid("sweep sensor must keep analog values".into()))?;
        let truth = fr.truth;
        for &m in methods {
            let p = full_chain(&analog, cfg.layout, m)?;
            let (mut sd, mut se, mut cnt) = (0f64, 0f64, 0f64);
            let t = SensorAngle::from_stokes(truth.s1.data[0] as f64, truth.s2.data[0] as f64);
            for r in BORDER..size - BORDER {
                for c in BORDER..size - BORDER {
                    let i = r * size + c;
                    let (s0, s1, s2) = (
                        p.stokes.s0.data[i] as f64,
                        p.stokes.s1.data[i] as f64,
                        p.stokes.s2.data[i] as f64,
                    );
                    sd += if s0 > 0.0 { s1.hypot(s2) / s0 } else { 0.0 };
                    let e = if dolp > 0.0 {
                        SensorAngle::from_stokes(s1, s2).diff(t)
                    } else {
                        // p = 0: spread about the (arbitrary) configured angle
                        SensorAngle::from_stokes(s1, s2).diff(SensorAngle::from_deg(SWEEP_AOLP_DEG))
                    };
                    se += e * e;
                    cnt += 1.0;
                }
            }
            let uniform = 90.0 / 3f64.sqrt();
            rows.push(SweepRow {
                method: m,
                electrons: n,
                dolp,
                mean_dolp: sd / cnt,
                aolp_sigma_deg: (se / cnt).sqrt(),
                theory_bias: 0.886 / n.sqrt(),
                theory_sigma_deg: if dolp > 0.0 {
                    (20.3 / (dolp * n.sqrt())).min(uniform)
                } else {
                    f64::NAN
                },
            });
        }
    }
    Ok(rows)
}

type PlotErr<E> = plotters::drawing::DrawingAreaErrorKind<E>;
pub(crate) fn perr<E: std::error::Error + Send + Sync>(e: PlotErr<E>) -> Error {
    Error::Invalid(format!("plotting: {e}"))
}

const PALETTE: [(u8, u8, u8); 8] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (90, 90, 90),
];

/// Speed-vs-accuracy chart: ms per full frame (log) against AoLP RMSE (log), one point per
/// method and scene, colour = scene, method names along the top.
pub fn speed_chart_svg(rows: &[BenchRow], title: &str) -> Result<String> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let xs: Vec<f64> = rows
            .iter()
            .map(|r| r.ms_per_frame)
            .filter(|v| *v > 0.0)
            .collect();
        let ys: Vec<f64> = rows
            .iter()
            .map(|r| r.scores.aolp_rmse_deg)
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let (x0, x1) = (
            xs.iter().copied().fold(f64::MAX, f64::min) / 1.6,
            xs.iter().copied().fold(0.0, f64::max) * 1.6,
        );
        let (y0, y1) = (
            ys.iter().copied().fold(f64::MAX, f64::min) / 1.5,
            ys.iter().copied().fold(0.0, f64::max) * 2.5,
        );
        if xs.is_empty() || ys.is_empty() {
            return Err(Error::Invalid("nothing to chart".into()));
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("ms per full frame (raw -> S0, S1, S2, DoLP, AoLP; median, buffers reused)")
            .y_desc("AoLP RMSE, degrees (true DoLP > 0.05)")
            .light_line_style(RGBColor(238, 238, 238))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for r in rows {
            let key = if r.bits == 12 {
                r.scene.name().to_string()
            } else {
                format!("{} {}-bit", r.scene, r.bits)
            };
            let y = r.scores.aolp_rmse_deg;
            if !(y.is_finite() && y > 0.0) {
                continue;
            }
            match series.iter_mut().find(|s| s.0 == key) {
                Some(s) => s.1.push((r.ms_per_frame, y)),
                None => series.push((key, vec![(r.ms_per_frame, y)])),
            }
        }
        for (k, (name, pts)) in series.iter().enumerate() {
            let (r, g, b) = PALETTE[k % PALETTE.len()];
            let col = RGBColor(r, g, b);
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 5, col.filled())))
                .map_err(perr)?
                .label(name.as_str())
                .legend(move |(x, y)| Circle::new((x, y), 5, col.filled()));
        }
        let mut methods: Vec<(Method, f64)> = Vec::new();
        for r in rows {
            if !methods.iter().any(|m| m.0 == r.method) {
                methods.push((r.method, r.ms_per_frame));
            }
        }
        methods.sort_by(|a, b| a.1.total_cmp(&b.1));
        // stagger the names so neighbours in time do not overlap
        chart
            .draw_series(methods.iter().enumerate().map(|(k, &(m, x))| {
                Text::new(
                    m.name().to_string(),
                    (x, y1 / 1.15 / 1.35f64.powi((k % 3) as i32)),
                    ("sans-serif", 13).into_font().color(&BLACK),
                )
            }))
            .map_err(perr)?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::Coordinate(250, 330))
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

/// Noise-law chart: mean DoLP at p = 0 and σ_AoLP at p > 0 against N, with the theory lines.
pub fn sweep_chart_svg(bias: &[SweepRow], sigma: &[SweepRow]) -> Result<String> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1000, 460)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let panels = root.split_evenly((1, 2));
        let p_sigma = sigma.first().map_or(0.1, |r| r.dolp);
        for (pi, (area, rows)) in panels.iter().zip([bias, sigma]).enumerate() {
            let val = |r: &SweepRow| {
                if pi == 0 {
                    r.mean_dolp
                } else {
                    r.aolp_sigma_deg
                }
            };
            let theory = |n: f64| {
                if pi == 0 {
                    0.886 / n.sqrt()
                } else {
                    20.3 / (p_sigma * n.sqrt())
                }
            };
            let ns: Vec<f64> = rows.iter().map(|r| r.electrons).collect();
            let (n0, n1) = (
                ns.iter().copied().fold(f64::MAX, f64::min) / 1.3,
                ns.iter().copied().fold(0.0, f64::max) * 1.3,
            );
            let vs: Vec<f64> = rows
                .iter()
                .map(val)
                .chain([theory(n0), theory(n1)])
                .filter(|v| *v > 0.0)
                .collect();
            let (v0, v1) = (
                vs.iter().copied().fold(f64::MAX, f64::min) / 1.5,
                vs.iter().copied().fold(0.0, f64::max) * 1.5,
            );
            let cap = if pi == 0 {
                "Mean DoLP at true DoLP 0 (Rice bias)".to_string()
            } else {
                format!("AoLP spread at true DoLP {p_sigma}")
            };
            let mut chart = ChartBuilder::on(area)
                .caption(cap, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(55)
                .build_cartesian_2d((n0..n1).log_scale(), (v0..v1).log_scale())
                .map_err(perr)?;
            chart
                .configure_mesh()
                .x_desc("N, mean electrons per pixel")
                .y_desc(if pi == 0 {
                    "mean DoLP"
                } else {
                    "RMS AoLP error, deg"
                })
                .label_style(("sans-serif", 12))
                .draw()
                .map_err(perr)?;
            let line: Vec<(f64, f64)> = (0..=40)
                .map(|i| {
                    let n = n0 * (n1 / n0).powf(i as f64 / 40.0);
                    (n, theory(n))
                })
                .collect();
            let tlabel = if pi == 0 {
                "theory 0.886/sqrt(N)".to_string()
            } else {
                format!("theory 20.3 deg/({p_sigma} sqrt(N))")
            };
            chart
                .draw_series(LineSeries::new(line, BLACK.stroke_width(2)))
                .map_err(perr)?
                .label(tlabel)
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2))
                });
            let mut methods: Vec<Method> = Vec::new();
            for r in rows.iter() {
                if !methods.contains(&r.method) {
                    methods.push(r.method);
                }
            }
            for (k, m) in methods.iter().enumerate() {
                let (r, g, b) = PALETTE[k % PALETTE.len()];
                let col = RGBColor(r, g, b);
                let pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| r.method == *m)
                    .map(|r| (r.electrons, val(r)))
                    .filter(|p| p.1 > 0.0)
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), col.stroke_width(1)))
                    .map_err(perr)?;
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))
                    .map_err(perr)?
                    .label(m.name())
                    .legend(move |(x, y)| Circle::new((x, y), 4, col.filled()));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .border_style(BLACK)
                .background_style(WHITE.mix(0.85))
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(perr)?;
        }
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

fn check_size(path: &Path) -> Result<()> {
    let n = std::fs::metadata(path)
        .map_err(|e| Error::io(format!("reading {}", path.display()), e))?
        .len() as usize;
    if n > MAX_FILE_BYTES {
        eprintln!(
            "warning: {} is {} KB (> {} KB)",
            path.display(),
            n / 1000,
            MAX_FILE_BYTES / 1000
        );
    }
    Ok(())
}

/// True when `out` lies inside the project's tracked `docs/`: the path as given has a `docs`
/// component (`docs/bench`, `./docs`, `../psns/docs/x`), or, made absolute against the current
/// directory and with `.`/`..` resolved, it passes through a `docs` directory that sits beside a
/// `Cargo.toml` (e.g. `--out bench` run from inside `docs/`).
pub fn inside_docs(out: &Path) -> bool {
    use std::path::Component;
    let is_docs = |c: &Component| c.as_os_str() == "docs";
    if out.components().any(|c| is_docs(&c)) {
        return true;
    }
    let Ok(cwd) = std::env::current_dir() else {
        return false;
    };
    let mut abs = PathBuf::new();
    for c in cwd.join(out).components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                abs.pop();
            }
            c => {
                abs.push(c);
                if is_docs(&c) && abs.parent().is_some_and(|p| p.join("Cargo.toml").is_file()) {
                    return true;
                }
            }
        }
    }
    false
}

/// `--quick` with an output directory inside `docs/` is bad input: quick numbers never land in
/// the docs (the tracked files are regenerated only by a full run with an explicit `--out`).
fn check_quick_out(quick: bool, out: &Path) -> Result<()> {
    if quick && inside_docs(out) {
        return Err(Error::Invalid(format!(
            "--quick with --out {}: quick numbers never land in docs; drop --quick, or write \
             elsewhere (default out-bench)",
            out.display()
        )));
    }
    Ok(())
}

/// A bench's output directory and the files written into it, in order.
pub struct BenchFiles<'a> {
    dir: &'a Path,
    written: Vec<String>,
}

impl<'a> BenchFiles<'a> {
    /// Refuses a quick run into docs/ ([`check_quick_out`]), then creates `out`.
    pub fn create(quick: bool, out: &'a Path) -> Result<Self> {
        check_quick_out(quick, out)?;
        create_dir(out)?;
        Ok(BenchFiles {
            dir: out,
            written: Vec::new(),
        })
    }

    /// Writes `text` into the file `name` of the directory.
    pub fn put(&mut self, name: &str, text: &str) -> Result<()> {
        let p = self.dir.join(name);
        write_text(&p, text)?;
        self.written.push(p.display().to_string());
        Ok(())
    }

    /// The files written, in order.
    pub fn into_written(self) -> Vec<String> {
        self.written
    }
}

/// `psns bench demosaic`; returns the files written.
///
/// Writes `demosaic.csv` (one row per method and scene, plus clear-sky at 8 bit),
/// `demosaic_speed_accuracy.svg`, `demosaic_aolp_error_<scene>.png` for `occluder-edge` and
/// `sun-in-view` (methods left to right in [`Method::ALL`] order, top: whole frame max-pooled;
/// bottom: a native-resolution crop), `demosaic_noise.csv` and `demosaic_noise.svg`.
pub fn bench_demosaic(opts: &BenchOptions) -> Result<Vec<String>> {
    check_quick_out(opts.quick, &opts.out)?;
    let (w, h, runs, sweep_size) = if opts.quick {
        (512, 512, opts.runs.clamp(1, 2), 64)
    } else {
        (
            scenes::FULL_WIDTH,
            scenes::FULL_HEIGHT,
            opts.runs.max(1),
            256,
        )
    };
    create_dir(&opts.out)?;
    let mut files = Vec::new();
    let methods = Method::ALL;
    let mut scenes_todo: Vec<(Scene, u8)> = Scene::ALL.iter().map(|&s| (s, 12)).collect();
    scenes_todo.push((Scene::ClearSky, 8));
    // steps: one timing per method, one score per method and scene, the two noise sweeps; a full
    // run takes minutes, so it counts as long from the start
    let steps = methods.len() * (1 + scenes_todo.len()) + 2;
    let mut progress = Progress::new(
        "psns bench demosaic",
        Unit::Steps,
        Some(steps as u64),
        !opts.quick,
    );

    // timing on the clear-sky frame
    let t_render = Instant::now();
    progress.set_message("rendering clear-sky");
    let clear = scenes::render(Scene::ClearSky, w, h, 12)?;
    progress.println(format!(
        "clear-sky {w} x {h} rendered in {:.1} s",
        t_render.elapsed().as_secs_f64()
    ));
    let layout = MosaicLayout::IMX250MZR;
    let mut timing = Vec::new();
    for &m in &methods {
        progress.set_message(format!("timing {m}"));
        let (reused, fresh) = time_full_chain(&clear.frame.codes, layout, m, runs)?;
        progress.println(format!(
            "{m:>10}: {reused:8.1} ms/frame (buffers reused), {fresh:8.1} ms (fresh)"
        ));
        timing.push((m, reused, fresh));
        progress.inc(1);
    }

    let mut rows: Vec<BenchRow> = Vec::new();
    for &(scene, bits) in &scenes_todo {
        progress.set_message(format!("scoring {scene} {bits} bit"));
        let sf = if scene == Scene::ClearSky && bits == 12 {
            clear.clone()
        } else {
            scenes::render(scene, w, h, bits)?
        };
        let sat = sat_mask_of(&sf.frame);
        let maps = bits == 12 && matches!(scene, Scene::OccluderEdge | Scene::SunInView);
        let factor = (w / 256).max(1);
        let detail = (w / 10).clamp(64, 200);
        let (dr, dc) = detail_origin(scene, w, h, detail, &sat);
        let mut pooled = Vec::new();
        let mut crops = Vec::new();
        for &(m, reused, fresh) in &timing {
            let sc = score_scene(&sf, m, &sat)?;
            let (s, all, p) = (sc.scores, sc.aolp_rmse_all_deg, &sc.images);
            progress.println(format!(
                "{m:>10} {scene:>14} {bits:>2} bit: S0 {:6.2} dB, DoLP RMSE {:.4} bias {:+.4}, AoLP RMSE {:7.3} deg (all {:7.3})",
                s.s0_psnr_db, s.dolp_rmse, s.dolp_bias, s.aolp_rmse_deg, all
            ));
            progress.inc(1);
            if maps {
                let e = aolp_error_map(&p.stokes, &sf.frame.truth);
                pooled.push(index_map(&max_pool(&e, factor)));
                crops.push(index_map(&crop(&e, dr, dc, detail)));
            }
            rows.push(BenchRow {
                method: m,
                scene,
                bits,
                width: w,
                height: h,
                ms_per_frame: reused,
                ms_per_frame_fresh: fresh,
                scores: s,
                aolp_rmse_all_deg: all,
                n_saturated_excluded: sc.n_saturated_excluded,
                n_dolp_above_1: sc.n_dolp_above_1,
            });
        }
        if maps {
            let top = hstack_idx(&pooled, 4, 7);
            let bottom = hstack_idx(&crops, 4, 7);
            let img = vstack_idx(&[top, bottom], 6, 7);
            let p = opts.out.join(format!("demosaic_aolp_error_{scene}.png"));
            write_png_indexed(&p, &img, &error_palette())?;
            check_size(&p)?;
            files.push(p.display().to_string());
        }
    }
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for r in &rows {
        csv.push_str(&r.csv());
        csv.push('\n');
    }
    let p = opts.out.join("demosaic.csv");
    write_text(&p, &csv)?;
    files.push(p.display().to_string());

    let title = format!(
        "Demosaic speed vs AoLP error, {w} x {h}, {} run median{}",
        runs,
        if opts.quick { " (quick)" } else { "" }
    );
    let p = opts.out.join("demosaic_speed_accuracy.svg");
    write_text(&p, &speed_chart_svg(&rows, &title)?)?;
    check_size(&p)?;
    files.push(p.display().to_string());

    // noise laws
    let ns: Vec<f64> = if opts.quick {
        vec![30.0, 300.0, 3000.0]
    } else {
        vec![30.0, 100.0, 300.0, 1000.0, 3000.0, 10000.0]
    };
    progress.set_message("noise sweep, DoLP 0");
    let bias = noise_sweep(sweep_size, &ns, 0.0, &methods, 11)?;
    progress.inc(1);
    progress.set_message("noise sweep, DoLP 0.1");
    let sigma = noise_sweep(sweep_size, &ns, 0.1, &methods, 12)?;
    progress.inc(1);
    let mut csv = String::from(
        "method,electrons,dolp,mean_dolp,aolp_rms_err_deg,theory_bias,theory_sigma_deg\n",
    );
    for r in bias.iter().chain(&sigma) {
        csv.push_str(&format!(
            "{},{},{},{:.5},{:.3},{:.5},{:.3}\n",
            r.method,
            r.electrons,
            r.dolp,
            r.mean_dolp,
            r.aolp_sigma_deg,
            r.theory_bias,
            r.theory_sigma_deg
        ));
    }
    let p = opts.out.join("demosaic_noise.csv");
    write_text(&p, &csv)?;
    files.push(p.display().to_string());
    let p = opts.out.join("demosaic_noise.svg");
    write_text(&p, &sweep_chart_svg(&bias, &sigma)?)?;
    check_size(&p)?;
    files.push(p.display().to_string());
    Ok(files)
}
