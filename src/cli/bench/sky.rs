//! `psns bench sky`: the exact per-pixel sky against the coarse-grid sky of raw frames, time per
//! full frame and error.

use crate::cli::progress::{Progress, Unit};
use psns::config::SceneConfig;
use psns::io::create_dir;
use psns::{io, render, Error, Result};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

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

/// Errors of pixel `i` of an approximate Stokes render against the exact one: |ΔS0|/S0, |ΔDoLP|
/// and, where the exact DoLP exceeds 0.02, |ΔAoLP| in degrees. `None` where the exact S0 ≤ 0.
pub fn pixel_errors(
    exact: &psns::image::StokesImage,
    approx: &psns::image::StokesImage,
    i: usize,
) -> Option<(f64, f64, Option<f64>)> {
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
        return None;
    }
    let (pa, pb) = (
        a1.hypot(a2) / a0,
        if b0 > 0.0 { b1.hypot(b2) / b0 } else { 0.0 },
    );
    let aop = (pa > 0.02).then(|| {
        psns::angle::SensorAngle::from_stokes(a1, a2)
            .diff(psns::angle::SensorAngle::from_stokes(b1, b2))
    });
    Some(((b0 - a0).abs() / a0, (pa - pb).abs(), aop))
}

/// Error of an approximate Stokes render against the exact one: max |ΔS0|/S0, max |ΔDoLP|, max and
/// p99 |ΔAoLP| (see [`pixel_errors`]).
pub fn stokes_errors(
    exact: &psns::image::StokesImage,
    approx: &psns::image::StokesImage,
) -> (f64, f64, f64, f64) {
    let (mut rel, mut dop, mut aop) = (0.0f64, 0.0f64, Vec::new());
    for i in 0..exact.s0.data.len() {
        let Some((r, d, a)) = pixel_errors(exact, approx, i) else {
            continue;
        };
        rel = rel.max(r);
        dop = dop.max(d);
        aop.extend(a);
    }
    aop.sort_by(|a, b| a.total_cmp(b));
    let max = aop.last().copied().unwrap_or(0.0);
    let p99 = aop
        .get(((aop.len() as f64 - 1.0) * 0.99) as usize)
        .copied()
        .unwrap_or(0.0);
    (rel, dop, max, p99)
}

/// `psns bench sky`: exact vs coarse-grid Stokes rendering of a scene, time and accuracy;
/// `on_row` sees each row as soon as it is measured.
pub fn bench_sky_grid(
    cfg: &SceneConfig,
    steps: &[usize],
    runs: usize,
    on_row: &mut dyn FnMut(&GridBenchRow),
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
            let (st, _) =
                render::render_stokes_grid(&sky, &cam, opts, step, render::GRID_TOLERANCE);
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            last = Some(st);
        }
        times.sort_by(|a, b| a.total_cmp(b));
        let (max_rel_s0, max_dop, max_aop_deg, p99_aop_deg) = stokes_errors(&exact, &last.unwrap());
        let row = GridBenchRow {
            step,
            ms_per_frame: times[times.len() / 2],
            max_rel_s0,
            max_dop,
            max_aop_deg,
            p99_aop_deg,
        };
        on_row(&row);
        rows.push(row);
    }
    Ok(rows)
}

/// `psns bench sky`: grid-step sweep for three views (zenith, tilted to the horizon, sun in view)
/// written as `sky_grid.csv` (and printed).
pub fn bench_sky_to_dir(cfg: &SceneConfig, dir: &Path, runs: usize) -> Result<Vec<String>> {
    use psns::camera::Attitude;
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
    let steps = [1, 2, 4, 8, 16];
    let mut progress = Progress::new(
        "psns bench sky",
        Unit::Steps,
        Some((views.len() * steps.len()) as u64),
        false,
    );
    for (name, att) in views {
        let mut c = cfg.clone();
        c.camera.attitude = att;
        progress.set_message(name);
        bench_sky_grid(&c, &steps, runs, &mut |r| {
            let line = format!(
                "{name},{},{:.1},{:.3e},{:.3e},{:.3e},{:.3e}",
                r.step, r.ms_per_frame, r.max_rel_s0, r.max_dop, r.max_aop_deg, r.p99_aop_deg
            );
            progress.println(&line);
            csv.push_str(&line);
            csv.push('\n');
            progress.inc(1);
        })?;
    }
    drop(progress);
    let p = dir.join("sky_grid.csv");
    io::write_atomic(&p, |w| {
        w.write_all(csv.as_bytes())
            .map_err(|e| Error::io("writing sky_grid.csv", e))
    })?;
    Ok(vec![p.display().to_string()])
}
