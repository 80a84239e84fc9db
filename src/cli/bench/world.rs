//! `psns bench heading --world`: each estimator's yaw error where the sky is cut, with the mask
//! found from the frame and without one, against the obstructed fraction of the image circle
//! (street canyons, a skyline, trees) and against cloud cover.

use super::demosaic::BenchFiles;
use super::heading::csv_field;
use crate::cli::progress::{Progress, Unit};
use psns::camera::{Attitude, Projection};
use psns::config::SceneConfig;
use psns::heading::{estimate_codes, wrap180, HeadingMethod, HeadingSetup};
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::world::{Canyon, Class, Tree};
use psns::{render, Error, Result};
use std::path::PathBuf;

/// Options of `psns bench heading --world`.
#[derive(Clone, Debug)]
pub struct WorldOptions {
    /// Output directory.
    pub out: PathBuf,
    /// Three canyons, one world of each other kind, four yaws (refused with an --out inside
    /// docs/).
    pub quick: bool,
}

/// A world of the sweep: its family, its label and the scene.
struct Case {
    family: &'static str,
    label: String,
    cfg: SceneConfig,
}

/// The zenith-looking equidistant fisheye of the goal (1 mm, 6.9 µm pixels: the image circle
/// just inside a 512 x 512 frame), the default sun.
fn base() -> SceneConfig {
    let mut c = SceneConfig::default();
    let i = &mut c.camera.intrinsics;
    i.projection = Projection::Equidistant;
    i.focal_length_mm = 1.0;
    (i.width, i.height, i.pixel_pitch_um) = (512, 512, 6.9);
    c
}

fn cases(quick: bool) -> Vec<Case> {
    let mut out = Vec::new();
    let heights: &[f64] = if quick {
        &[0.0, 6.0]
    } else {
        &[0.0, 2.0, 4.0, 6.0, 9.0, 13.0, 20.0, 30.0]
    };
    for &h in heights {
        let mut cfg = base();
        if h > 0.0 {
            cfg.world.canyon = Some(Canyon::new(20.0, h, 0.0));
        }
        out.push(Case {
            family: "canyon",
            label: format!("canyon 20,{h},0"),
            cfg,
        });
    }
    let skylines: &[f64] = if quick { &[15.0] } else { &[10.0, 25.0, 40.0] };
    for &e in skylines {
        let mut cfg = base();
        cfg.world.skyline = vec![[0.0, e], [90.0, 0.3 * e], [180.0, e], [270.0, 0.3 * e]];
        out.push(Case {
            family: "skyline",
            label: format!("skyline up to {e} deg"),
            cfg,
        });
    }
    let trees: &[usize] = if quick { &[2] } else { &[1, 2, 4] };
    for &n in trees {
        let mut cfg = base();
        cfg.world.camera_height_m = 1.5;
        cfg.world.trees = (0..n)
            .map(|k| {
                let a = (35.0 + 90.0 * k as f64).to_radians();
                Tree {
                    east_m: 5.0 * a.sin(),
                    north_m: 5.0 * a.cos(),
                    canopy_height_m: 6.0,
                    radii_m: [3.0, 3.0, 2.5],
                    trunk_radius_m: 0.25,
                    gap_fraction: 0.2,
                }
            })
            .collect();
        out.push(Case {
            family: "trees",
            label: format!("{n} tree{}", if n == 1 { "" } else { "s" }),
            cfg,
        });
    }
    let covers: &[f64] = if quick { &[0.3] } else { &[0.1, 0.3, 0.5, 0.7] };
    for &f in covers {
        let mut cfg = base();
        cfg.world.cloud_cover = Some(f);
        out.push(Case {
            family: "clouds",
            label: format!("cloud cover {f}"),
            cfg,
        });
    }
    out
}

/// One estimate: the case, the yaw, the method, whether masked, and what came out.
struct Row {
    family: &'static str,
    label: String,
    hidden: f64,
    cloud: f64,
    yaw: f64,
    method: HeadingMethod,
    masked: bool,
    error: f64,
    confidence: f64,
    sky_fraction: f64,
}

/// `psns bench heading --world`: writes world.csv, world_summary.csv and world.svg.
pub fn bench_world(opts: &WorldOptions) -> Result<Vec<String>> {
    let mut files = BenchFiles::create(opts.quick, &opts.out)?;
    let cases = cases(opts.quick);
    let yaws: Vec<f64> = if opts.quick {
        (0..4).map(|k| 10.0 + 90.0 * k as f64).collect()
    } else {
        (0..12).map(|k| 10.0 + 30.0 * k as f64).collect()
    };
    let mut progress = Progress::new(
        "psns bench heading --world",
        Unit::Steps,
        Some((cases.len() * yaws.len()) as u64),
        !opts.quick,
    );
    let mut rows = Vec::new();
    for case in &cases {
        progress.set_message(case.label.as_str());
        let pipe = RawPipeline::new(&case.cfg)?;
        let sun = case.cfg.sun.resolve()?;
        for (k, &yaw) in yaws.iter().enumerate() {
            let att = Attitude::enu(yaw, 0.0, 0.0);
            let mut cfg = case.cfg.clone();
            cfg.camera.attitude = att;
            let (sky, cam) = cfg.build()?;
            let class = render::class_image(&sky, &cam, false);
            let circle = class
                .data
                .iter()
                .filter(|&&c| c != Class::Outside as u8)
                .count();
            let share = |c: Class| {
                class.data.iter().filter(|&&v| v == c as u8).count() as f64 / circle as f64
            };
            let (hidden, cloud) = (share(Class::Obstruction), share(Class::Cloud));
            let frame = pipe.render(FrameRequest::sky(k as u64, sun, att))?.frame;
            let layout = pipe.sensor_config().layout;
            for method in HeadingMethod::ALL {
                for masked in [false, true] {
                    let mut setup = HeadingSetup::new(cfg.intrinsics(), sun);
                    setup.relative_illumination = pipe.sensor_config().effective_ri();
                    setup.find_mask = masked;
                    let e = estimate_codes(
                        &frame.codes,
                        frame.black_level_dn,
                        layout,
                        frame.bit_depth,
                        None,
                        method,
                        &setup,
                        None,
                    )?;
                    let (error, confidence, sky_fraction) = match e.estimate {
                        Some(x) => (wrap180(x.yaw_deg - yaw).abs(), x.confidence, x.sky_fraction),
                        None => (f64::NAN, 0.0, 0.0),
                    };
                    rows.push(Row {
                        family: case.family,
                        label: case.label.clone(),
                        hidden,
                        cloud,
                        yaw,
                        method,
                        masked,
                        error,
                        confidence,
                        sky_fraction,
                    });
                }
            }
            progress.inc(1);
        }
    }
    let mut csv = String::from(
        "family,world,hidden_fraction,cloud_fraction,yaw_deg,method,mask,yaw_error_deg,confidence,sky_fraction\n",
    );
    for r in &rows {
        csv += &format!(
            "{},{},{:.4},{:.4},{},{},{},{:.4},{:.3},{:.4}\n",
            r.family,
            csv_field(&r.label),
            r.hidden,
            r.cloud,
            r.yaw,
            r.method.name(),
            if r.masked { "found" } else { "none" },
            r.error,
            r.confidence,
            r.sky_fraction
        );
    }
    files.put("world.csv", &csv)?;
    // per world, method and mask: RMS over the yaws (a missing estimate counts as failed)
    let mut summary = String::from(
        "family,world,hidden_fraction,cloud_fraction,method,mask,rms_yaw_error_deg,max_yaw_error_deg,failed,mean_confidence\n",
    );
    let mut points = Vec::new();
    for case in &cases {
        for method in HeadingMethod::ALL {
            for masked in [false, true] {
                let sel: Vec<&Row> = rows
                    .iter()
                    .filter(|r| r.label == case.label && r.method == method && r.masked == masked)
                    .collect();
                let ok: Vec<f64> = sel
                    .iter()
                    .map(|r| r.error)
                    .filter(|e| e.is_finite())
                    .collect();
                let rms = (ok.iter().map(|e| e * e).sum::<f64>() / ok.len().max(1) as f64).sqrt();
                let max = ok.iter().fold(0f64, |m, &e| m.max(e));
                let failed = sel.len() - ok.len();
                let conf = sel.iter().map(|r| r.confidence).sum::<f64>() / sel.len() as f64;
                let hidden = sel.iter().map(|r| r.hidden).sum::<f64>() / sel.len() as f64;
                let cloud = sel.iter().map(|r| r.cloud).sum::<f64>() / sel.len() as f64;
                summary += &format!(
                    "{},{},{hidden:.4},{cloud:.4},{},{},{rms:.4},{max:.4},{failed},{conf:.3}\n",
                    case.family,
                    csv_field(&case.label),
                    method.name(),
                    if masked { "found" } else { "none" },
                );
                points.push((case.family, hidden + cloud, method, masked, rms, failed));
            }
        }
    }
    files.put("world_summary.csv", &summary)?;
    files.put("world.svg", &chart(&points)?)?;
    Ok(files.into_written())
}

type Point = (&'static str, f64, HeadingMethod, bool, f64, usize);

/// RMS yaw error (log scale) against the hidden (obstructed or clouded) fraction of the image
/// circle, per estimator; solid lines with the found mask, dashed without; a failed estimate
/// drawn at the top.
fn chart(points: &[Point]) -> Result<String> {
    use plotters::prelude::*;
    let perr = |e: String| Error::Invalid(format!("chart: {e}"));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Yaw error where the sky is cut (zenith fisheye)",
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0f64..0.9f64, (0.001f64..30f64).log_scale())
            .map_err(|e| perr(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("hidden fraction of the image circle (obstruction + cloud)")
            .y_desc("RMS yaw error over yaws, deg")
            .draw()
            .map_err(|e| perr(e.to_string()))?;
        let colours = [RED, BLUE, GREEN];
        for (mi, method) in HeadingMethod::ALL.iter().enumerate() {
            for masked in [true, false] {
                for family in ["canyon", "skyline", "trees", "clouds"] {
                    let mut pts: Vec<(f64, f64)> = points
                        .iter()
                        .filter(|p| p.0 == family && p.2 == *method && p.3 == masked)
                        .map(|p| {
                            (
                                p.1,
                                if p.5 > 0 {
                                    30.0
                                } else {
                                    p.4.clamp(0.001, 30.0)
                                },
                            )
                        })
                        .collect();
                    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let colour = colours[mi % colours.len()];
                    let style = if masked {
                        colour.stroke_width(2)
                    } else {
                        colour.mix(0.45).stroke_width(1)
                    };
                    let s = chart
                        .draw_series(LineSeries::new(pts.clone(), style))
                        .map_err(|e| perr(e.to_string()))?;
                    if family == "canyon" {
                        let name = format!(
                            "{} {}",
                            method.name(),
                            if masked { "mask found" } else { "no mask" }
                        );
                        s.label(name).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], style)
                        });
                    }
                    chart
                        .draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 3, style)))
                        .map_err(|e| perr(e.to_string()))?;
                }
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| perr(e.to_string()))?;
        root.present().map_err(|e| perr(e.to_string()))?;
    }
    Ok(svg)
}
