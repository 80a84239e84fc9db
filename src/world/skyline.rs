//! The far skyline: the elevation of hills or a street's rooftops by compass azimuth, measured
//! (with a phone, a theodolite) or drawn, interpolated linearly and wrapping round.

use super::shapes::Arc;
use super::{Hit, DEFAULT_ALBEDO};
use crate::error::{check_range, Error, Result};
use glam::DVec3;

/// A skyline: points (azimuth, elevation), degrees, azimuths strictly increasing within
/// [0, 360); the last point joins the first across north.
///
/// ```
/// use psns::world::Skyline;
/// let s = Skyline::new(&[[0.0, 10.0], [180.0, 30.0]]).unwrap();
/// assert_eq!(s.elevation_deg(90.0), 20.0);
/// assert_eq!(s.elevation_deg(270.0), 20.0); // from 180 back round to 360 = 0
/// assert!(Skyline::new(&[[10.0, 5.0], [5.0, 5.0]]).is_err());
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Skyline {
    az: Vec<f64>,
    el: Vec<f64>,
}

impl Skyline {
    /// Checks and keeps the points.
    pub fn new(points: &[[f64; 2]]) -> Result<Skyline> {
        if points.is_empty() {
            return Err(Error::Invalid(
                "a skyline needs at least one point (azimuth_deg,elevation_deg)".into(),
            ));
        }
        let mut prev = f64::NEG_INFINITY;
        for (k, &[a, e]) in points.iter().enumerate() {
            let name = format!("skyline point {} azimuth_deg", k + 1);
            if !a.is_finite() || !(0.0..360.0).contains(&a) {
                return Err(Error::OutOfRange {
                    name,
                    value: crate::error::num(a),
                    allowed: "0..360 (360 excluded)".into(),
                });
            }
            if a <= prev {
                return Err(Error::Invalid(format!(
                    "{name} = {} does not increase (the previous point is at {}; allowed {}..360, azimuths strictly increasing)",
                    crate::error::num(a),
                    crate::error::num(prev),
                    crate::error::num(prev),
                )));
            }
            prev = a;
            check_range(
                &format!("skyline point {} elevation_deg", k + 1),
                e,
                -90.0,
                90.0,
            )?;
        }
        Ok(Skyline {
            az: points.iter().map(|p| p[0]).collect(),
            el: points.iter().map(|p| p[1]).collect(),
        })
    }

    /// Reads `azimuth_deg,elevation_deg` CSV text (a header line, then one point per line).
    pub fn parse_csv(text: &str) -> Result<Vec<[f64; 2]>> {
        let mut rd = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let mut points = Vec::new();
        let mut header = true;
        for rec in rd.records() {
            let rec = rec.map_err(|e| Error::Invalid(format!("skyline: {e}")))?;
            let line = rec.position().map_or(0, |p| p.line());
            if rec.iter().all(str::is_empty) {
                continue;
            }
            if header {
                header = false;
                let h: Vec<&str> = rec.iter().collect();
                if h != ["azimuth_deg", "elevation_deg"] {
                    return Err(Error::Invalid(format!(
                        "skyline line {line}: expected the header 'azimuth_deg,elevation_deg', found '{}'",
                        h.join(",")
                    )));
                }
                continue;
            }
            if rec.len() != 2 {
                return Err(Error::Invalid(format!(
                    "skyline line {line}: expected 2 columns (azimuth_deg,elevation_deg), found {}",
                    rec.len()
                )));
            }
            let num = |s: &str, name: &str| -> Result<f64> {
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "skyline line {line}: {name} '{s}' is not a finite number"
                        ))
                    })
            };
            points.push([num(&rec[0], "azimuth_deg")?, num(&rec[1], "elevation_deg")?]);
        }
        if header {
            return Err(Error::Invalid(
                "skyline: empty input, expected the header 'azimuth_deg,elevation_deg'".into(),
            ));
        }
        Skyline::new(&points)?;
        Ok(points)
    }

    /// The segment [az[i], az[i+1]] (wrapping) holding `a` in [0, 360): (i, j, fraction).
    fn segment(&self, a: f64) -> (usize, usize, f64) {
        let n = self.az.len();
        if n == 1 {
            return (0, 0, 0.0);
        }
        let k = self.az.partition_point(|&x| x <= a);
        let (i, j) = if k == 0 || k == n {
            (n - 1, 0)
        } else {
            (k - 1, k)
        };
        let (a0, mut a1, mut x) = (self.az[i], self.az[j], a);
        if j == 0 {
            a1 += 360.0;
            if x < a0 {
                x += 360.0;
            }
        }
        (i, j, (x - a0) / (a1 - a0))
    }

    /// Elevation of the skyline at compass azimuth `az_deg` (any value, wrapped), degrees.
    pub fn elevation_deg(&self, az_deg: f64) -> f64 {
        let a = az_deg.rem_euclid(360.0);
        let (i, j, f) = self.segment(a);
        self.el[i] + (self.el[j] - self.el[i]) * f
    }

    /// The terrain when the unit ray `d` is below the skyline (it faces the observer).
    pub(super) fn hit(&self, d: DVec3) -> Option<Hit> {
        let az = d.x.atan2(d.y).to_degrees();
        let el = d.z.clamp(-1.0, 1.0).asin().to_degrees();
        if el >= self.elevation_deg(az) {
            return None;
        }
        let h = DVec3::new(-d.x, -d.y, 0.0);
        let normal = if h.length_squared() > 0.0 {
            h.normalize()
        } else {
            DVec3::Z
        };
        Some(Hit::Diffuse {
            normal,
            albedo: DEFAULT_ALBEDO,
        })
    }

    /// The skyline as arcs of at most 1° of azimuth: a line linear in azimuth and elevation is
    /// within 0.01° of the great-circle arcs between its points there (the margin the fast path
    /// adds, `World::clear`).
    pub(super) fn edges(&self, out: &mut Vec<Arc>) {
        let dir = |az: f64, el: f64| {
            let (a, e) = (az.to_radians(), el.to_radians());
            DVec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
        };
        let n = self.az.len();
        for i in 0..n {
            let (a0, e0) = (self.az[i], self.el[i]);
            let (mut a1, e1) = (self.az[(i + 1) % n], self.el[(i + 1) % n]);
            if i + 1 == n {
                a1 += 360.0;
            }
            let steps = ((a1 - a0).ceil() as usize).max(1);
            for s in 0..steps {
                let (f0, f1) = (s as f64 / steps as f64, (s + 1) as f64 / steps as f64);
                let p = dir(a0 + (a1 - a0) * f0, e0 + (e1 - e0) * f0);
                let q = dir(a0 + (a1 - a0) * f1, e0 + (e1 - e0) * f1);
                out.push(Arc::new(p, q).widened(SKYLINE_SLACK_RAD));
            }
        }
    }
}

/// What the arcs of [`Skyline::edges`] add to their distance test, radians (0.02°).
const SKYLINE_SLACK_RAD: f64 = 0.02 * std::f64::consts::PI / 180.0;
