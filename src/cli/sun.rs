//! `psns sun`: the SPA sun position for a UTC time and place, as CSV `zenith_deg,azimuth_deg`.

use anyhow::Context;
use clap::Args;
use psns::options::{finite, SpaArgs};
use psns::sun::Place;
use std::io::Write;

/// Options of `psns sun`.
#[derive(Args)]
pub struct SunArgs {
    /// UTC time, ISO 8601 (e.g. 2003-10-17T19:30:30Z).
    #[arg(long)]
    time: String,
    /// Latitude, degrees north (−90..90).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lat: f64,
    /// Longitude, degrees east (−180..180).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    lon: f64,
    /// Height above the ellipsoid, metres.
    #[arg(long, value_parser = finite, default_value_t = 0.0, allow_negative_numbers = true)]
    height: f64,
    #[command(flatten)]
    spa: SpaArgs,
}

/// Runs `psns sun`.
pub fn run(a: SunArgs) -> anyhow::Result<()> {
    let t = psns::sun::parse_time(&a.time)?;
    let place = Place {
        lat_deg: a.lat,
        lon_deg: a.lon,
        height_m: a.height,
    };
    let s = psns::sun::spa(&t, &place, a.spa.delta_t, a.spa.refraction())?;
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "zenith_deg,azimuth_deg\n{:.9},{:.9}",
        s.zenith_deg, s.azimuth_deg
    )
    .context("writing to stdout")?;
    Ok(())
}
