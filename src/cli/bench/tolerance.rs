//! `psns bench heading --tolerance`: how far each input of `psns heading` can be wrong before
//! the confidence falls below 0.5, on a rectilinear frame and on each fisheye.

use super::demosaic::BenchFiles;
use super::heading::{csv_field, CONFIDENT};
use psns::camera::{Attitude, Intrinsics, Lens, Projection};
use psns::config::SceneConfig;
use psns::demosaic::Method;
use psns::heading::{
    estimate_codes, estimate_heading, polar_for_estimate, sampled_intrinsics, superpixel_step,
    wrap180, HeadingMethod, HeadingSetup, PolarView,
};
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::sensor::optics::RelativeIllumination;
use psns::sensor::{Exposure, SensorConfig};
use psns::sun::SunPosition;
use psns::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

/// Sun azimuth of the scan's scenes, degrees.
const SUN_AZIMUTH: f64 = 200.0;

/// Options of `psns bench heading --tolerance`.
#[derive(Clone, Debug)]
pub struct ToleranceOptions {
    /// Output directory.
    pub out: PathBuf,
    /// 304 x 256 frames, one yaw, coarser steps (refused with an --out inside docs/).
    pub quick: bool,
}

/// An input of `psns heading` that a user can get wrong by a continuous amount: its name, unit,
/// scan step, scan limit each way, and how an error of `offset` changes the setup.
struct WrongInput {
    name: &'static str,
    step: f64,
    limit: f64,
    apply: fn(&mut HeadingSetup, f64),
}

fn wrong_inputs() -> Vec<WrongInput> {
    vec![
        WrongInput {
            name: "pitch (deg)",
            step: 0.5,
            limit: 45.0,
            apply: |s, o| s.pitch_deg += o,
        },
        WrongInput {
            name: "roll (deg)",
            step: 0.5,
            limit: 45.0,
            apply: |s, o| s.roll_deg += o,
        },
        WrongInput {
            name: "sun elevation (deg)",
            step: 0.5,
            limit: 50.0,
            apply: |s, o| s.sun = SunPosition::new(s.sun.zenith_deg - o, s.sun.azimuth_deg),
        },
        WrongInput {
            name: "sun azimuth (deg)",
            step: 0.5,
            limit: 20.0,
            apply: |s, o| s.sun = SunPosition::new(s.sun.zenith_deg, s.sun.azimuth_deg + o),
        },
        WrongInput {
            name: "focal length (%)",
            step: 1.0,
            limit: 50.0,
            apply: |s, o| s.intrinsics.focal_length_mm *= 1.0 + o / 100.0,
        },
        WrongInput {
            name: "principal point column (px)",
            step: 2.0,
            limit: 200.0,
            apply: |s, o| {
                let (c, r) = s.intrinsics.principal();
                s.intrinsics.principal_point = Some([c + o, r]);
            },
        },
        WrongInput {
            name: "principal point row (px)",
            step: 2.0,
            limit: 200.0,
            apply: |s, o| {
                let (c, r) = s.intrinsics.principal();
                s.intrinsics.principal_point = Some([c, r + o]);
            },
        },
    ]
}

/// One estimate of the tolerance scan.
#[derive(Clone, Debug)]
struct ScanRow {
    /// The projection of the frames (and of the right inputs).
    projection: Projection,
    input: String,
    offset: f64,
    yaw: f64,
    method: HeadingMethod,
    /// |yaw error|, degrees; NaN without an estimate.
    error: f64,
    confidence: f64,
    residual: f64,
}

/// The scene of the tolerance scan: the default scene (sun zenith 50°, azimuth 200°, default
/// sky, camera preset and its ideal lens, 12 bit) with auto-exposure, level. Rectilinear: the
/// full field of view in 612 x 512 (quick: 304 x 256) pixels; a fisheye: the whole sky through
/// a 1 mm lens on 1024 x 1024 pixels of 3.45 µm (read as sampled superpixels, as `psns heading`
/// reads a frame of that size; quick: 512 x 512 of 6.9 µm, demosaicked whole).
fn tolerance_scene(quick: bool, projection: Projection) -> SceneConfig {
    let fisheye = projection != Projection::Rectilinear;
    let (w, h, k) = match (quick, fisheye) {
        (true, false) => (304, 256, 8.0),
        (false, false) => (612, 512, 4.0),
        (true, true) => (512, 512, 2.0),
        (false, true) => (1024, 1024, 1.0),
    };
    let mut cfg = SceneConfig::default();
    cfg.camera.intrinsics = Intrinsics {
        pixel_pitch_um: 3.45 * k,
        projection,
        ..Intrinsics::with_size(w, h)
    };
    if fisheye {
        cfg.camera.intrinsics.focal_length_mm = 1.0;
    }
    cfg.sun.zenith_deg = Some(50.0);
    cfg.sun.altitude_deg = None;
    cfg.sun.azimuth_deg = Some(SUN_AZIMUTH);
    cfg.sun.time = None;
    let mut s = SensorConfig::preset(cfg.raw.preset);
    s.exposure = Exposure::auto();
    cfg.raw.sensor = Some(s);
    cfg
}

/// Scans each input of `psns heading` away from its right value, one at a time, until the
/// confidence falls below [`CONFIDENT`]; returns every estimate.
fn tolerance_scan(opts: &ToleranceOptions, progress: &mut dyn FnMut(&str)) -> Result<Vec<ScanRow>> {
    let mut rows = Vec::new();
    for projection in Projection::ALL {
        scan_projection(opts, projection, &mut rows, progress)?;
    }
    Ok(rows)
}

/// [`tolerance_scan`] of the frames of one projection, appended to `rows`.
fn scan_projection(
    opts: &ToleranceOptions,
    projection: Projection,
    rows: &mut Vec<ScanRow>,
    progress: &mut dyn FnMut(&str),
) -> Result<()> {
    let cfg = tolerance_scene(opts.quick, projection);
    let pipe = RawPipeline::new(&cfg)?;
    let sun = cfg.sun.resolve()?;
    let yaws: Vec<f64> = if opts.quick {
        vec![17.0]
    } else {
        (0..4).map(|j| 17.0 + 90.0 * j as f64).collect()
    };
    let coarse = if opts.quick { 4.0 } else { 1.0 };
    // the inputs as psns heading takes them (the preset's falloff for the flat field)
    let mut right = HeadingSetup::new(cfg.intrinsics(), sun);
    right.relative_illumination = pipe.sensor_config().effective_ri();
    // a large frame is read as sampled superpixels, flat-fielded (`polar_for_estimate`): the
    // estimators then take the sampled view's intrinsics, made from the (wrong) inputs given
    let i = cfg.intrinsics();
    let sampled = superpixel_step(i.width, i.height);
    let view_setup = |s: HeadingSetup| match sampled {
        Some(k) => HeadingSetup {
            intrinsics: sampled_intrinsics(&s.intrinsics, k),
            step: 1,
            relative_illumination: RelativeIllumination::None,
            ..s
        },
        None => s,
    };
    let estimate = |m: HeadingMethod, view: &PolarView, s: HeadingSetup| {
        s.intrinsics
            .validate()
            .and_then(|_| estimate_heading(m, view, &view_setup(s)))
    };
    for (j, &yaw) in yaws.iter().enumerate() {
        let (st, _) = pipe.stokes(sun, &Attitude::enu(yaw, 0.0, 0.0))?;
        let frame = pipe
            .render(FrameRequest::planes(j as u64, &st).exact())?
            .frame;
        let layout = pipe.sensor_config().layout;
        // the images psns heading reads: bilinear, or the flat-fielded sampled superpixels
        let (p, _, _) = polar_for_estimate(
            &frame.codes,
            frame.black_level_dn,
            layout,
            frame.bit_depth,
            None,
            &right,
        )?;
        let view = PolarView {
            aolp_deg: &p.aolp_deg,
            dolp: &p.dolp,
            s0: Some(&p.stokes.s0),
            mask: None,
        };
        let mut row = |input: &str, offset: f64, m: HeadingMethod, e: Result<_>| -> Result<f64> {
            let (error, confidence, residual) = match e {
                Ok(psns::heading::HeadingEstimate {
                    yaw_deg,
                    confidence,
                    residual_deg,
                    ..
                }) => (wrap180(yaw_deg - yaw).abs(), confidence, residual_deg),
                Err(Error::TooFewPixels(_) | Error::Undetermined(_)) => (f64::NAN, 0.0, f64::NAN),
                Err(e) => return Err(e),
            };
            rows.push(ScanRow {
                projection,
                input: input.to_string(),
                offset,
                yaw,
                method: m,
                error,
                confidence,
                residual,
            });
            Ok(confidence)
        };
        for m in HeadingMethod::ALL {
            row("right inputs", 0.0, m, estimate(m, &view, right))?;
            for w in wrong_inputs() {
                let step = w.step * coarse;
                for sign in [1.0, -1.0] {
                    let mut k = 1;
                    while k as f64 * step <= w.limit + 1e-9 {
                        let off = sign * k as f64 * step;
                        let mut s = right;
                        (w.apply)(&mut s, off);
                        if s.sun.check_up().is_err() {
                            break; // the sun below the horizon: refused before estimating
                        }
                        if row(w.name, off, m, estimate(m, &view, s))? < CONFIDENT {
                            break;
                        }
                        k += 1;
                    }
                }
            }
            // the discrete inputs: each wrong projection, the other lens
            for pr in Projection::ALL
                .into_iter()
                .filter(|&p| p != right.intrinsics.projection)
            {
                let mut s = right;
                s.intrinsics.projection = pr;
                row(
                    &format!("projection {}", pr.name()),
                    0.0,
                    m,
                    estimate(m, &view, s),
                )?;
            }
            let mut s = right;
            let other = if right.intrinsics.lens() == Lens::Ideal {
                Lens::Pinhole
            } else {
                Lens::Ideal
            };
            s.intrinsics.lens = Some(other);
            row(
                &format!("lens {}", other.name()),
                0.0,
                m,
                estimate(m, &view, s),
            )?;
            // the bit depth decides which codes count as clipped
            for bits in [10u8, 16] {
                let e = estimate_codes(
                    &frame.codes,
                    frame.black_level_dn,
                    layout,
                    bits,
                    if sampled.is_some() {
                        None
                    } else {
                        Some(Method::Bilinear)
                    },
                    m,
                    &right,
                    None,
                )
                .and_then(|c| {
                    c.estimate
                        .ok_or_else(|| Error::TooFewPixels(c.reason.unwrap_or_default()))
                });
                row(&format!("bits {bits}"), 0.0, m, e)?;
            }
        }
        progress(&format!("{} yaw {yaw}", projection.name()));
    }
    Ok(())
}

/// One line of the tolerance table: an input wrong one way, for one method, over the yaws of
/// one projection's frames.
struct ToleranceRow {
    projection: Projection,
    input: String,
    side: &'static str,
    method: HeadingMethod,
    /// Smallest and largest error of the input (over the yaws) at which the confidence first
    /// fell below [`CONFIDENT`]; `None` when it did not within the scan's limit.
    falls: Option<(f64, f64)>,
    /// Yaws whose confidence did not fall within the limit.
    held: usize,
    /// Largest |yaw error| at a confidence ≥ [`CONFIDENT`] on the way (degrees).
    confident_error: f64,
    /// Largest |yaw error| at the first error with confidence below [`CONFIDENT`] (degrees).
    error_at_fall: f64,
    /// Mean residual there (degrees).
    residual_at_fall: f64,
    /// The scan's limit.
    limit: f64,
}

fn tolerance_rows(scan: &[ScanRow]) -> Vec<ToleranceRow> {
    let mut out = Vec::new();
    for projection in Projection::ALL {
        out.extend(projection_rows(
            projection,
            &scan
                .iter()
                .filter(|r| r.projection == projection)
                .cloned()
                .collect::<Vec<_>>(),
        ));
    }
    out
}

/// [`tolerance_rows`] of the scan rows of one projection.
fn projection_rows(projection: Projection, scan: &[ScanRow]) -> Vec<ToleranceRow> {
    let mut out = Vec::new();
    for w in wrong_inputs() {
        for (side, sign) in [("+", 1.0), ("-", -1.0)] {
            for m in HeadingMethod::ALL {
                let pts: Vec<&ScanRow> = scan
                    .iter()
                    .filter(|r| r.input == w.name && r.method == m && r.offset * sign > 0.0)
                    .collect();
                let mut yaws: Vec<f64> = pts.iter().map(|r| r.yaw).collect();
                yaws.dedup();
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                let (mut held, mut ce, mut ef, mut rf, mut nf) = (0, 0.0f64, 0.0f64, 0.0, 0);
                for &y in &yaws {
                    let p: Vec<&&ScanRow> = pts.iter().filter(|r| r.yaw == y).collect();
                    for r in &p {
                        if r.confidence >= CONFIDENT && r.error.is_finite() {
                            ce = ce.max(r.error);
                        }
                    }
                    match p.iter().find(|r| r.confidence < CONFIDENT) {
                        Some(r) => {
                            lo = lo.min(r.offset.abs());
                            hi = hi.max(r.offset.abs());
                            ef = if r.error.is_finite() {
                                ef.max(r.error)
                            } else {
                                f64::NAN
                            };
                            if r.residual.is_finite() {
                                rf += r.residual;
                                nf += 1;
                            }
                        }
                        None => held += 1,
                    }
                }
                let falls = lo.is_finite().then_some((lo, hi));
                out.push(ToleranceRow {
                    projection,
                    input: w.name.to_string(),
                    side,
                    method: m,
                    falls,
                    held,
                    confident_error: ce,
                    error_at_fall: if falls.is_some() { ef } else { f64::NAN },
                    residual_at_fall: if nf > 0 { rf / nf as f64 } else { f64::NAN },
                    limit: w.limit,
                });
            }
        }
    }
    out
}

/// `psns bench heading --tolerance`: how far each input of `psns heading` can be wrong before
/// the confidence falls below 0.5, and the yaw error there; returns the files written.
pub fn bench_tolerance(opts: &ToleranceOptions) -> Result<Vec<String>> {
    let mut files = BenchFiles::create(opts.quick, &opts.out)?;
    let t0 = Instant::now();
    let scan = tolerance_scan(opts, &mut |s| {
        eprintln!(
            "psns bench heading --tolerance: {s} ({:.0} s)",
            t0.elapsed().as_secs_f64()
        )
    })?;
    let rows = tolerance_rows(&scan);
    let num = |v: f64| {
        if v.is_finite() {
            format!("{v:.4}")
        } else {
            "nan".into()
        }
    };
    let mut c = String::from(
        "input,side,method,falls_from,falls_to,yaws_held,limit,largest_confident_error_deg,error_at_fall_deg,residual_at_fall_deg,projection\n",
    );
    for r in &rows {
        let (a, b) = r
            .falls
            .map_or((String::new(), String::new()), |(a, b)| (num(a), num(b)));
        c += &format!(
            "{},{},{},{a},{b},{},{},{},{},{},{}\n",
            csv_field(&r.input),
            r.side,
            r.method,
            r.held,
            r.limit,
            num(r.confident_error),
            num(r.error_at_fall),
            num(r.residual_at_fall),
            r.projection.name()
        );
    }
    files.put("tolerance.csv", &c)?;
    let mut f = String::from(
        "input,offset,yaw_deg,method,abs_error_deg,confidence,residual_deg,projection\n",
    );
    for r in &scan {
        f += &format!(
            "{},{},{},{},{},{:.4},{},{}\n",
            csv_field(&r.input),
            r.offset,
            r.yaw,
            r.method,
            num(r.error),
            r.confidence,
            num(r.residual),
            r.projection.name()
        );
    }
    files.put("tolerance_scan.csv", &f)?;
    files.put("tolerance.md", &tolerance_markdown(&rows, &scan))?;
    Ok(files.into_written())
}

/// The tolerance tables as Markdown, the rectilinear frames' first, then each fisheye's under
/// its name.
fn tolerance_markdown(rows: &[ToleranceRow], scan: &[ScanRow]) -> String {
    let mut s = String::new();
    for projection in Projection::ALL {
        let r: Vec<&ToleranceRow> = rows.iter().filter(|r| r.projection == projection).collect();
        let sc: Vec<ScanRow> = scan
            .iter()
            .filter(|r| r.projection == projection)
            .cloned()
            .collect();
        if projection != Projection::Rectilinear {
            s += &format!(
                "\n### {} fisheye (the whole sky, 1 mm lens)\n\n",
                projection.name()
            );
        }
        s += &projection_markdown(&r, &sc);
    }
    s
}

/// The tables of one projection: per input and side, for each method, where the confidence
/// falls below 0.5 and the yaw error there; then the discrete inputs.
fn projection_markdown(rows: &[&ToleranceRow], scan: &[ScanRow]) -> String {
    let mut s = String::from(
        "| input wrong by | model fit: confidence < 0.5 from | yaw error there (largest before) | eigen | hough |\n|---|---|---|---|---|\n",
    );
    let cell = |r: &ToleranceRow| match r.falls {
        Some((a, b)) if a == b && r.held == 0 => format!("{a}"),
        Some((a, b)) if r.held == 0 => format!("{a}–{b}"),
        Some((a, b)) => format!("{a}–{b}, {} yaws not by {}", r.held, r.limit),
        None => format!("not by {}", r.limit),
    };
    let err = |r: &ToleranceRow| {
        if r.falls.is_some() {
            format!("{:.2}° ({:.2}°)", r.error_at_fall, r.confident_error)
        } else {
            format!("– ({:.2}°)", r.confident_error)
        }
    };
    for w in wrong_inputs() {
        for side in ["+", "-"] {
            let get = |m: HeadingMethod| {
                rows.iter()
                    .find(|r| r.input == w.name && r.side == side && r.method == m)
            };
            let (Some(f), Some(e), Some(h)) = (
                get(HeadingMethod::ModelFit),
                get(HeadingMethod::Eigen),
                get(HeadingMethod::Hough),
            ) else {
                continue;
            };
            s += &format!(
                "| {} {side} | {} | {} | {}; {} | {}; {} |\n",
                w.name,
                cell(f),
                err(f),
                cell(e),
                err(e),
                cell(h),
                err(h)
            );
        }
    }
    s += "\n| input | model fit: confidence, largest yaw error | eigen | hough |\n|---|---|---|---|\n";
    let mut inputs: Vec<&str> = Vec::new();
    for r in scan.iter().filter(|r| r.offset == 0.0) {
        if !inputs.contains(&r.input.as_str()) {
            inputs.push(&r.input);
        }
    }
    for i in inputs {
        let cell = |m: HeadingMethod| {
            let p: Vec<&ScanRow> = scan
                .iter()
                .filter(|r| r.input == i && r.method == m)
                .collect();
            let cmin = p.iter().map(|r| r.confidence).fold(f64::INFINITY, f64::min);
            let cmax = p.iter().map(|r| r.confidence).fold(0.0, f64::max);
            let e = p.iter().map(|r| r.error).fold(0.0, |a: f64, b| {
                if b.is_nan() || a.is_nan() {
                    f64::NAN
                } else {
                    a.max(b)
                }
            });
            let res = p.iter().map(|r| r.residual).sum::<f64>() / p.len().max(1) as f64;
            if cmax == 0.0 && e.is_nan() {
                "no estimate".to_string()
            } else {
                format!("{cmin:.2}–{cmax:.2}, {e:.2}° (residual {res:.1}°)")
            }
        };
        s += &format!(
            "| {i} | {} | {} | {} |\n",
            cell(HeadingMethod::ModelFit),
            cell(HeadingMethod::Eigen),
            cell(HeadingMethod::Hough)
        );
    }
    s
}
