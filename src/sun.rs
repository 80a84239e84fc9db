//! Sun position: from UTC time and place with NREL's SPA (crate `solar-positioning`), or given
//! directly.
//!
//! Output is the topocentric sun zenith angle θ_s (degrees, may exceed 90° when the sun is down)
//! and compass azimuth A_s (degrees from north, clockwise) — `sky.md` §2. The position is geometric
//! (no refraction) unless a [`Refraction`] is given; ΔT comes from the crate's estimator unless
//! set explicitly.

use crate::angle::CompassAzimuth;
use crate::error::{check_range, Error, Result};
use chrono::{DateTime, Datelike, Timelike, Utc};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use solar_positioning::{time::JulianDate, Location, RefractionCorrection, SolarPositions};

/// Where the sun is, seen from the observer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SunPosition {
    /// Zenith angle θ_s in degrees (0 = overhead, 90 = horizon, > 90 below it).
    pub zenith_deg: f64,
    /// Compass azimuth A_s in degrees from north, clockwise, in [0, 360).
    pub azimuth_deg: f64,
}

impl SunPosition {
    /// A sun given directly; the azimuth is wrapped to [0, 360).
    pub fn new(zenith_deg: f64, azimuth_deg: f64) -> Self {
        SunPosition {
            zenith_deg,
            azimuth_deg: CompassAzimuth::from_deg(azimuth_deg).deg(),
        }
    }

    /// Elevation above the horizon, 90° − θ_s.
    pub fn elevation_deg(&self) -> f64 {
        90.0 - self.zenith_deg
    }

    /// Checks that the sun is up, as a sky render needs (θ_s in 0..90).
    ///
    /// ```
    /// let e = psns::sun::SunPosition::new(95.0, 10.0).check_up().unwrap_err();
    /// assert_eq!(e.to_string(), "sun altitude -5 deg: the sun is below the horizon (a sky render needs altitude 0..90)");
    /// ```
    pub fn check_up(&self) -> Result<()> {
        let z = self.zenith_deg;
        if z.is_finite() && z > 90.0 {
            return Err(Error::Invalid(format!(
                "sun altitude {} deg: the sun is below the horizon (a sky render needs altitude 0..90)",
                crate::error::num(((90.0 - z) * 1e6).round() / 1e6)
            )));
        }
        check_range("sun-zenith", z, 0.0, 90.0).map(|_| ())
    }

    /// Unit vector toward the sun in ENU (x east, y north, z up).
    ///
    /// ```
    /// let s = psns::sun::SunPosition::new(90.0, 90.0).vector();
    /// assert!((s.x - 1.0).abs() < 1e-12 && s.z.abs() < 1e-12);
    /// ```
    pub fn vector(&self) -> DVec3 {
        crate::angle::direction(self.zenith_deg, self.azimuth_deg)
    }
}

/// Atmospheric refraction settings (SPA's formula).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Refraction {
    /// Pressure in hPa (mbar).
    pub pressure_hpa: f64,
    /// Temperature in °C.
    pub temperature_c: f64,
}

/// Observer place.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Place {
    /// Latitude in degrees, north positive, −90..90.
    pub lat_deg: f64,
    /// Longitude in degrees, east positive, −180..180.
    pub lon_deg: f64,
    /// Height above the ellipsoid in metres.
    #[serde(default)]
    pub height_m: f64,
}

impl Place {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        check_range("lat", self.lat_deg, -90.0, 90.0)?;
        check_range("lon", self.lon_deg, -180.0, 180.0)?;
        check_range("height", self.height_m, -1000.0, 100_000.0)?;
        Ok(())
    }
}

/// ΔT = TT − UT in seconds estimated for a UTC time (crate estimator, ≈69 s in 2025).
pub fn delta_t_estimate(time: &DateTime<Utc>) -> Result<f64> {
    solar_positioning::delta_t::estimate_from_date_like(time)
        .map_err(|e| Error::Invalid(format!("cannot estimate delta T for {time}: {e}")))
}

/// SPA sun position at a UTC time and place.
///
/// `delta_t_s`: ΔT in seconds, or `None` for the crate's estimate. `refraction`: `None` for the
/// geometric position (the project default).
pub fn spa(
    time: &DateTime<Utc>,
    place: &Place,
    delta_t_s: Option<f64>,
    refraction: Option<Refraction>,
) -> Result<SunPosition> {
    place.validate()?;
    let delta_t = match delta_t_s {
        Some(d) => check_range("delta-t", d, -10_000.0, 10_000.0)?,
        None => delta_t_estimate(time)?,
    };
    let sec = time.second() as f64 + time.nanosecond() as f64 * 1e-9;
    let jd = JulianDate::from_utc(
        time.year(),
        time.month(),
        time.day(),
        time.hour(),
        time.minute(),
        sec,
        delta_t,
    )
    .map_err(|e| Error::Invalid(format!("bad time {time}: {e}")))?;
    let refr = match refraction {
        Some(r) => {
            // the ranges SPA's refraction formula is meant for (sea level to high mountains)
            check_range("pressure", r.pressure_hpa, 1.0, 1100.0)?;
            check_range("temperature", r.temperature_c, -90.0, 60.0)?;
            Some(
                RefractionCorrection::new(r.pressure_hpa, r.temperature_c)
                    .map_err(|e| Error::Invalid(format!("refraction settings: {e}")))?,
            )
        }
        None => None,
    };
    let loc = Location {
        latitude: place.lat_deg,
        longitude: place.lon_deg,
    };
    let p = SolarPositions::new()
        .at_from_julian(jd, loc, place.height_m, refr)
        .map_err(|e| Error::Invalid(format!("SPA failed: {e}")))?;
    Ok(SunPosition::new(p.zenith_angle(), p.azimuth()))
}

/// Parses an ISO 8601 / RFC 3339 UTC time such as `2003-10-17T19:30:30Z`.
pub fn parse_time(s: &str) -> Result<DateTime<Utc>> {
    DateTime::parse_from_rfc3339(s.trim())
        .map(|t| t.with_timezone(&Utc))
        .map_err(|e| {
            Error::Invalid(format!(
                "time '{s}' is not an ISO 8601 time like 2003-10-17T19:30:30Z: {e}"
            ))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nrel() -> (DateTime<Utc>, Place) {
        (
            parse_time("2003-10-17T19:30:30Z").unwrap(),
            Place {
                lat_deg: 39.742476,
                lon_deg: -105.1786,
                height_m: 1830.14,
            },
        )
    }

    /// Reda & Andreas (2004) test case, refracted at 820 mbar, 11 °C, ΔT = 67 s (sky.md §9 #3).
    #[test]
    fn nrel_spa_reference_refracted() {
        let (t, p) = nrel();
        let r = Refraction {
            pressure_hpa: 820.0,
            temperature_c: 11.0,
        };
        let s = spa(&t, &p, Some(67.0), Some(r)).unwrap();
        assert!((s.zenith_deg - 50.111622).abs() < 1e-5, "{s:?}");
        assert!((s.azimuth_deg - 194.340241).abs() < 1e-5, "{s:?}");
    }

    #[test]
    fn nrel_spa_reference_geometric() {
        let (t, p) = nrel();
        let s = spa(&t, &p, Some(67.0), None).unwrap();
        assert!((s.zenith_deg - 50.127954).abs() < 1e-5, "{s:?}");
        // refraction lifts the sun by ~0.016° at θ_s = 50° (sky.md §2)
        assert!((s.zenith_deg - 50.111622 - 0.0163).abs() < 1e-3);
    }

    #[test]
    fn sun_below_horizon_is_reported() {
        let t = parse_time("2003-10-17T06:00:00Z").unwrap();
        let (_, p) = nrel();
        let s = spa(&t, &p, None, None).unwrap();
        assert!(s.zenith_deg > 90.0, "{s:?}");
        assert!((0.0..360.0).contains(&s.azimuth_deg));
    }

    #[test]
    fn delta_t_estimate_is_plausible() {
        let t = parse_time("2025-06-01T00:00:00Z").unwrap();
        let d = delta_t_estimate(&t).unwrap();
        assert!((60.0..80.0).contains(&d), "{d}");
    }
}
