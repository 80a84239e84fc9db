//! `psns sky`: sky values (radiance, DOP, AOP) for directions read as CSV on stdin.

use super::args::SceneArgs;
use clap::Args;
use psns::config::SceneConfig;
use psns::sky::{aop_chart_deg, aop_meridian_deg, direction};
use psns::{Error, Result};
use std::io::{BufRead, Write};

/// Options of `psns sky`.
#[derive(Args)]
pub struct SkyArgs {
    #[command(flatten)]
    scene: SceneArgs,
}

/// Runs `psns sky`.
pub fn run(a: SkyArgs) -> anyhow::Result<()> {
    let cfg = a.scene.scene()?;
    let stdin = std::io::stdin().lock();
    let stdout = std::io::stdout().lock();
    sky_csv(&cfg, stdin, std::io::BufWriter::new(stdout))?;
    Ok(())
}

/// `psns sky`: CSV directions in, CSV sky values out (`zenith_deg,azimuth_deg` →
/// `zenith_deg,azimuth_deg,gamma_deg,radiance,dop,aop_meridian_deg,aop_north_deg`).
///
/// Directions at or below the horizon (zenith ≥ 90°) get radiance 0, DOP 0 and AOP 0 (ground).
pub fn sky_csv(cfg: &SceneConfig, input: impl BufRead, mut output: impl Write) -> Result<usize> {
    let sun = cfg.sun.resolve()?;
    let sky = psns::sky::Sky::new(sun, &cfg.sky)?;
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
