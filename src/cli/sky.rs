//! `psns sky`: sky values (radiance, DOP, AOP) for directions read as CSV on stdin; with
//! `--stability`, the stability map of the DOP models (and the other models' rows) instead.

use super::progress::{Progress, Unit};
use psns::config::SceneConfig;
use psns::error::check_range;
use psns::options::{first_given, SkyArgs};
use psns::sky::stability::{stability_map, Grid, MapCell, MAX_AOP_SHIFT_DEG, MAX_JUMP};
use psns::sky::{DopModel, PolarizationModel, SkyParams};
use psns::{Error, Result};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Runs `psns sky`.
pub fn run(a: SkyArgs) -> anyhow::Result<()> {
    let cfg = a.scene.scene()?;
    if a.stability {
        let sc = &a.scene;
        let swept = first_given(&[
            ("sun-zenith", sc.sun_zenith.is_some()),
            ("sun-altitude", sc.sun_altitude.is_some()),
            ("sun-azimuth", sc.sun_azimuth.is_some()),
            ("time", sc.time.is_some()),
            ("turbidity", sc.turbidity.is_some()),
            ("wavelength", sc.wavelength.is_some()),
            ("model", sc.model.is_some()),
            ("dop-model", sc.dop_model.is_some()),
        ]);
        if let Some(n) = swept {
            return Err(Error::Invalid(format!(
                "--{n} would be ignored: --stability sweeps the sun, turbidity and wavelength for every model"
            ))
            .into());
        }
        let dir = a.out.unwrap_or_else(|| PathBuf::from("out-stability"));
        for f in write_stability(&cfg.sky, &dir)? {
            eprintln!("psns sky: wrote {f}");
        }
        return Ok(());
    }
    let stdin = std::io::stdin().lock();
    let stdout = std::io::stdout().lock();
    sky_csv(&cfg, stdin, std::io::BufWriter::new(stdout))?;
    Ok(())
}

/// `psns sky`: CSV directions in, CSV sky values out (`zenith_deg,azimuth_deg` →
/// `zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg`).
///
/// Directions at or below the horizon (zenith ≥ 90°) get radiance 0, DOP 0 and AOP 0 (ground).
/// Every field is range-checked as the options are: zenith 0..180, azimuth -360..720.
pub fn sky_csv(cfg: &SceneConfig, input: impl Read, mut output: impl Write) -> Result<usize> {
    let sun = cfg.sun.resolve()?;
    let sky = psns::sky::Sky::new(sun, &cfg.sky)?;
    let werr = |e| Error::io("writing to stdout", e);
    let mut rd = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(input);
    let mut rec = csv::StringRecord::new();
    let read = |rd: &mut csv::Reader<_>, rec: &mut csv::StringRecord| -> Result<bool> {
        rd.read_record(rec).map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            let what = e.to_string();
            match e.into_kind() {
                csv::ErrorKind::Io(io) => Error::io("reading stdin", io),
                csv::ErrorKind::Utf8 { .. } => {
                    Error::Invalid(format!("line {line}: not UTF-8 text"))
                }
                _ => Error::Invalid(format!("line {line}: {what}")),
            }
        })
    };
    if !read(&mut rd, &mut rec)? {
        return Err(Error::Invalid(
            "empty input: expected a CSV header line".into(),
        ));
    }
    if rec.iter().collect::<Vec<_>>() != ["zenith_deg", "azimuth_deg"] {
        let found = rec.iter().collect::<Vec<_>>().join(",");
        return Err(Error::Invalid(format!(
            "line 1: expected the header 'zenith_deg,azimuth_deg', found '{}'",
            quote(&found)
        )));
    }
    writeln!(
        output,
        "zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg"
    )
    .map_err(werr)?;
    let mut n = 0;
    while read(&mut rd, &mut rec)? {
        let ln = rec.position().map_or(0, |p| p.line());
        if rec.iter().all(str::is_empty) {
            continue;
        }
        if rec.len() != 2 {
            return Err(Error::Invalid(format!(
                "line {ln}: expected 2 columns (zenith_deg,azimuth_deg), found {}",
                rec.len()
            )));
        }
        let num = |s: &str, name: &str| -> Result<f64> {
            let v: f64 = s.parse().map_err(|_| {
                Error::Invalid(format!("line {ln}: {name} '{}' is not a number", quote(s)))
            })?;
            if !v.is_finite() {
                return Err(Error::Invalid(format!(
                    "line {ln}: {name} '{}' is not finite",
                    quote(s)
                )));
            }
            Ok(v)
        };
        // the ranges of the options: a zenith as --sun-zenith, an azimuth as --sun-azimuth
        let field = |i: usize, name: &str, lo: f64, hi: f64| -> Result<f64> {
            check_range(&format!("line {ln}: {name}"), num(&rec[i], name)?, lo, hi)
        };
        let z = field(0, "zenith_deg", 0.0, 180.0)?;
        let a = field(1, "azimuth_deg", -360.0, 720.0)?;
        let v = sky.values(z, a);
        writeln!(
            output,
            "{z},{a},{:.9},{:.9e},{:.9},{:.6},{:.6}",
            v.gamma_deg, v.radiance, v.dop, v.aop_meridian_deg, v.aop_north_deg
        )
        .map_err(werr)?;
        n += 1;
    }
    output.flush().map_err(werr)?;
    Ok(n)
}

/// At most the first 40 characters of a field for a message (a long line is not echoed whole).
fn quote(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

/// Turbidities of the stability map: 1..10 every 0.5, plus 1.7 (the bounded model's lowest).
pub fn map_turbidities() -> Vec<f64> {
    let mut t: Vec<f64> = (0..=18).map(|i| 1.0 + 0.5 * i as f64).collect();
    t.push(1.7);
    t.sort_by(f64::total_cmp);
    t
}

/// Sun zeniths of the stability map: 0..90 every 2°.
pub fn map_sun_zeniths() -> Vec<f64> {
    (0..=45).map(|i| 2.0 * i as f64).collect()
}

/// Wavelengths of the stability map, nm.
pub const MAP_WAVELENGTHS: [f64; 5] = [380.0, 450.0, 550.0, 650.0, 720.0];

/// One model's map: per turbidity, the cells (sun zenith × wavelength) or the refusal.
type ModelMap = Vec<(f64, std::result::Result<Vec<MapCell>, String>)>;

/// A model's rows of the map (name, DOP form): the two forms of the Wang DOP; one row for each
/// model whose polarization depends on neither turbidity nor wavelength (evaluated once per sun
/// zenith, at T = 4 and 450 nm, and drawn across every turbidity); none for `rayleigh`, which is
/// `depolarized-rayleigh` with the depolarization ratio 0 (the same field and DOP law, so its
/// row would repeat that one's at a slightly higher peak).
fn map_rows(model: PolarizationModel) -> &'static [(&'static str, DopModel)] {
    match model {
        PolarizationModel::Wang => &[
            ("wang-paper", DopModel::WangPaper),
            ("wang-bounded", DopModel::WangBounded),
        ],
        PolarizationModel::Rayleigh => &[],
        PolarizationModel::DepolarizedRayleigh => {
            &[("depolarized-rayleigh", DopModel::WangBounded)]
        }
        PolarizationModel::Berry => &[("berry", DopModel::WangBounded)],
        PolarizationModel::Pan => &[("pan", DopModel::WangBounded)],
        PolarizationModel::Queen => &[("queen", DopModel::WangBounded)],
        PolarizationModel::Asymmetric => &[("asymmetric", DopModel::WangBounded)],
    }
}

/// The rows of the map, top to bottom: every model's [`map_rows`] in the order of
/// [`PolarizationModel::ALL`].
fn all_map_rows() -> Vec<(&'static str, PolarizationModel, DopModel)> {
    PolarizationModel::ALL
        .into_iter()
        .flat_map(|m| map_rows(m).iter().map(move |&(n, d)| (n, m, d)))
        .collect()
}

/// Writes `dop_stability.csv`, `.svg` and `.png` into `dir` (created if missing; other
/// files are left alone). Returns the files written.
pub fn write_stability(base: &SkyParams, dir: &Path) -> Result<Vec<String>> {
    let ts = map_turbidities();
    let zs = map_sun_zeniths();
    let rows = all_map_rows();
    let steps: usize = rows
        .iter()
        .map(|r| {
            if r.1 == PolarizationModel::Wang {
                ts.len()
            } else {
                1
            }
        })
        .sum();
    let mut progress = Progress::new(
        "psns sky --stability",
        Unit::Steps,
        Some(steps as u64),
        false,
    );
    let mut maps: Vec<(&str, bool, ModelMap)> = Vec::new();
    for (name, model, m) in rows {
        let asym = model == PolarizationModel::Asymmetric;
        let p = SkyParams {
            model,
            dop_model: m,
            neutral_law: None,
            arago_deg: base.arago_deg.filter(|_| asym),
            fourth_deg: base.fourth_deg.filter(|_| asym),
            ..base.clone()
        };
        let mut rows = Vec::new();
        if model == PolarizationModel::Wang {
            for &t in &ts {
                progress.set_message(format!("{name} T = {t}"));
                let r = stability_map(&p, &[t], &zs, &MAP_WAVELENGTHS, Grid::default())
                    .map_err(|e| e.to_string());
                rows.push((t, r));
                progress.inc(1);
            }
        } else {
            progress.set_message(name.to_string());
            let r = stability_map(&p, &[4.0], &zs, &[450.0], Grid::default())
                .map_err(|e| e.to_string());
            rows = ts.iter().map(|&t| (t, r.clone())).collect();
            progress.inc(1);
        }
        maps.push((name, model == PolarizationModel::Wang, rows));
    }
    psns::io::create_dir(dir)?;
    let mut csv = String::from(
        "model,turbidity,sun_zenith_deg,wavelength_nm,status,directions,mid_directions,pinned_low,pinned_high,max_jump,jumps,max_dop,median_aop_shift_deg\n",
    );
    for (name, per_t, rows) in &maps {
        // the turbidity- and wavelength-free models: one row per sun zenith
        let rows = if *per_t { &rows[..] } else { &rows[..1] };
        for (t, r) in rows {
            match r {
                Ok(cells) => {
                    for c in cells {
                        let s = &c.stats;
                        let (tt, ll) = if *per_t {
                            (c.turbidity.to_string(), c.wavelength_nm.to_string())
                        } else {
                            ("any".to_string(), "any".to_string())
                        };
                        csv += &format!(
                            "{name},{tt},{},{ll},{},{},{},{},{},{:.6},{},{:.6},{:.4}\n",
                            c.sun_zenith_deg,
                            if s.is_stable() && !s.aop_flips() {
                                "stable"
                            } else {
                                "unstable"
                            },
                            s.directions,
                            s.mid_directions,
                            s.pinned_low,
                            s.pinned_high,
                            s.max_jump,
                            s.jumps,
                            s.max_dop,
                            s.median_aop_shift_deg
                        );
                    }
                }
                Err(_) => {
                    for z in &zs {
                        for l in MAP_WAVELENGTHS {
                            csv += &format!("{name},{t},{z},{l},refused,,,,,,,,\n");
                        }
                    }
                }
            }
        }
    }
    let pcsv = dir.join("dop_stability.csv");
    write(&pcsv, csv.as_bytes())?;
    let maps: Vec<(&str, ModelMap)> = maps.into_iter().map(|(n, _, r)| (n, r)).collect();
    let psvg = dir.join("dop_stability.svg");
    let mut svg = String::new();
    draw_map(&maps, &ts, &zs, &mut svg)
        .map_err(|e| Error::Invalid(format!("drawing the stability map: {e}")))?;
    write(&psvg, svg.as_bytes())?;
    let ppng = dir.join("dop_stability.png");
    psns::io::write_png_rgb8(&ppng, &map_png(&maps, &zs))?;
    Ok(vec![
        pcsv.display().to_string(),
        psvg.display().to_string(),
        ppng.display().to_string(),
    ])
}

fn write(p: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(p, bytes).map_err(|e| Error::io(format!("writing {}", p.display()), e))
}

/// Per map cell (turbidity, sun zenith) the worst over the wavelengths of: fraction pinned low,
/// fraction pinned high, largest jump, median AOP shift (degrees).
fn worst(cells: &[MapCell], z: f64) -> [f64; 4] {
    let mut w = [0.0f64; 4];
    for c in cells.iter().filter(|c| c.sun_zenith_deg == z) {
        w[0] = w[0].max(c.stats.low_fraction());
        w[1] = w[1].max(c.stats.high_fraction());
        w[2] = w[2].max(c.stats.max_jump);
        w[3] = w[3].max(c.stats.median_aop_shift_deg);
    }
    w
}

/// Colour of one map cell for metric `k` (0 pinned low, 1 pinned high, 2 jump, 3 AOP shift):
/// grey where the model refuses the turbidity, pale green for none pinned, white → red with the
/// fraction pinned; jumps blue up to 0.15, red above; AOP shifts blue up to 10°, red above (a
/// flip: 90°).
fn cell_color(r: &std::result::Result<Vec<MapCell>, String>, z: f64, k: usize) -> [u8; 3] {
    let cells = match r {
        Err(_) => return [190, 190, 190],
        Ok(c) => c,
    };
    let v = worst(cells, z)[k];
    if k == 3 {
        if v > MAX_AOP_SHIFT_DEG {
            [255, 60, 60]
        } else {
            let g = (255.0 - 120.0 * (v / MAX_AOP_SHIFT_DEG).clamp(0.0, 1.0)) as u8;
            [g, g, 255]
        }
    } else if k == 2 {
        if v > MAX_JUMP {
            let f = ((v - MAX_JUMP) / (1.0 - MAX_JUMP)).clamp(0.0, 1.0);
            let g = (140.0 * (1.0 - f)) as u8;
            [255, g, g]
        } else {
            let g = (255.0 - 120.0 * (v / MAX_JUMP).clamp(0.0, 1.0)) as u8;
            [g, g, 255]
        }
    } else if v > 0.0 {
        let g = (200.0 * (1.0 - v.clamp(0.0, 1.0).sqrt())) as u8;
        [255, g, g]
    } else {
        [235, 245, 235]
    }
}

/// The map as a small PNG without text: rows as [`all_map_rows`]; columns pinned low, pinned high,
/// jump, AOP shift; in each panel turbidity grows to the right (one 8-px column per value of
/// [`map_turbidities`]) and sun zenith downwards (4 px per 2°).
fn map_png(maps: &[(&str, ModelMap)], zs: &[f64]) -> psns::image::Image<[u8; 3]> {
    let mut rows = Vec::new();
    for (_, rows_m) in maps {
        let mut panels = Vec::new();
        for k in 0..4 {
            let (w, h) = (rows_m.len() * 8, zs.len() * 4);
            let mut data = vec![[255u8; 3]; w * h];
            for (i, (_, r)) in rows_m.iter().enumerate() {
                for (j, &z) in zs.iter().enumerate() {
                    let c = cell_color(r, z, k);
                    for y in j * 4..j * 4 + 4 {
                        for x in i * 8..i * 8 + 8 {
                            data[y * w + x] = c;
                        }
                    }
                }
            }
            panels.push(psns::image::Image::from_vec(w, h, data));
        }
        rows.push(super::vis::hstack(&panels.iter().collect::<Vec<_>>(), 6));
    }
    super::vis::vstack(&rows.iter().collect::<Vec<_>>(), 6)
}

fn draw_map(
    maps: &[(&str, ModelMap)],
    ts: &[f64],
    zs: &[f64],
    svg: &mut String,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let root =
        SVGBackend::with_string(svg, (1600, 260 * maps.len() as u32 + 40)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(40);
    title.draw(&Text::new(
        "DOP stability and AOP continuity, worst of 380/450/550/650/720 nm for wang (4050 directions per cell; grey: refused)",
        (20, 12),
        ("sans-serif", 17),
    ))?;
    let rows = body.split_evenly((maps.len(), 4));
    // cell edges: turbidity steps are 0.5 except around 1.7
    let edges: Vec<f64> = {
        let mut e = vec![ts[0] - 0.25];
        for w in ts.windows(2) {
            e.push(0.5 * (w[0] + w[1]));
        }
        e.push(ts[ts.len() - 1] + 0.25);
        e
    };
    let metrics = [
        "pinned DOP <= 0.001 (40..140 deg from sun)",
        "pinned DOP >= 0.95",
        "max jump over 2 deg (red: > 0.15)",
        "median AOP shift, sun 0.5 deg (red: > 10 deg)",
    ];
    for (mi, (m, rows_m)) in maps.iter().enumerate() {
        let unstable: usize = rows_m
            .iter()
            .filter_map(|(_, r)| r.as_ref().ok())
            .flat_map(|c| c.iter())
            .filter(|c| !c.stats.is_stable() || c.stats.aop_flips())
            .count();
        let total: usize = rows_m
            .iter()
            .filter_map(|(_, r)| r.as_ref().ok())
            .map(|c| c.len())
            .sum();
        for (k, name) in metrics.iter().enumerate() {
            let area = &rows[mi * 4 + k];
            let cap = if k == 0 {
                format!("{m}: {name} ({unstable}/{total} unstable)")
            } else {
                format!("{m}: {name}")
            };
            let mut ch = ChartBuilder::on(area)
                .caption(cap, ("sans-serif", 13))
                .margin(8)
                .x_label_area_size(32)
                .y_label_area_size(44)
                .build_cartesian_2d(edges[0]..edges[edges.len() - 1], -1f64..91f64)?;
            ch.configure_mesh()
                .disable_mesh()
                .x_desc("turbidity")
                .y_desc("sun zenith (deg)")
                .label_style(("sans-serif", 11))
                .draw()?;
            for (i, (_, r)) in rows_m.iter().enumerate() {
                let (x0, x1) = (edges[i], edges[i + 1]);
                // one rectangle per run of equal colours down the column (keeps the SVG small)
                let colors: Vec<[u8; 3]> = zs.iter().map(|&z| cell_color(r, z, k)).collect();
                let mut j = 0;
                while j < zs.len() {
                    let mut e = j;
                    while e + 1 < zs.len() && colors[e + 1] == colors[j] {
                        e += 1;
                    }
                    let [cr, cg, cb] = colors[j];
                    ch.draw_series(std::iter::once(Rectangle::new(
                        [(x0, zs[j] - 1.0), (x1, zs[e] + 1.0)],
                        RGBColor(cr, cg, cb).filled(),
                    )))?;
                    j = e + 1;
                }
            }
        }
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model has its rows on the map but `rayleigh` (see [`map_rows`]), in the order of
    /// the docs' map.
    #[test]
    fn every_model_but_rayleigh_has_map_rows() {
        for m in PolarizationModel::ALL {
            let rows = map_rows(m);
            assert_eq!(rows.is_empty(), m == PolarizationModel::Rayleigh, "{m}");
            for (name, _) in rows {
                assert!(name.starts_with(m.name()), "{name} is a row of {m}");
            }
        }
        let names: Vec<&str> = all_map_rows().iter().map(|r| r.0).collect();
        assert_eq!(
            names,
            [
                "wang-paper",
                "wang-bounded",
                "depolarized-rayleigh",
                "berry",
                "pan",
                "queen",
                "asymmetric"
            ]
        );
    }
}
