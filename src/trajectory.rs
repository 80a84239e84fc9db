//! Trajectories that drive `psns stream`: timed poses read line by line from CSV, or generated.
//!
//! CSV: a header line, then one pose per line. Columns: `t_s` (seconds since the stream's start
//! time), then either `yaw_deg,pitch_deg,roll_deg` (ENU frame, as `psns render --frame enu`) or
//! `qw,qx,qy,qz` (Hamilton, camera → ENU), and optionally `lat_deg,lon_deg,height_m`. Lines are
//! parsed as they arrive, so a trajectory can be piped in from a running simulator.

use crate::camera::{Attitude, AttitudeFrame};
use crate::error::{Error, Result};
use crate::sun::Place;
use std::io::BufRead;

/// One timed pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Seconds since the stream's start time.
    pub t_s: f64,
    /// Camera attitude (ENU frame).
    pub attitude: Attitude,
    /// Place, when the trajectory carries one.
    pub place: Option<Place>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum AttCols {
    Euler,
    Quat,
}

/// Reads poses from CSV, one line at a time; errors name the line number.
pub struct CsvTrajectory<R: BufRead> {
    lines: std::io::Lines<R>,
    line_no: usize,
    att: AttCols,
    has_place: bool,
    last_t: f64,
}

impl<R: BufRead> CsvTrajectory<R> {
    /// Reads and checks the header line.
    pub fn new(reader: R) -> Result<Self> {
        let mut lines = reader.lines();
        let header = match lines.next() {
            Some(Ok(h)) => h,
            Some(Err(e)) => return Err(Error::io("reading trajectory", e)),
            None => {
                return Err(Error::Invalid(
                    "trajectory line 1: empty input, expected a header".into(),
                ))
            }
        };
        let cols: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
        let c: Vec<&str> = cols.iter().map(|s| s.as_str()).collect();
        let (att, rest) = match c.as_slice() {
            ["t_s", "yaw_deg", "pitch_deg", "roll_deg", rest @ ..] => (AttCols::Euler, rest),
            ["t_s", "qw", "qx", "qy", "qz", rest @ ..] => (AttCols::Quat, rest),
            _ => {
                return Err(Error::Invalid(format!(
                    "trajectory line 1: header '{header}' must start with t_s,yaw_deg,pitch_deg,roll_deg or t_s,qw,qx,qy,qz"
                )))
            }
        };
        let has_place = match rest {
            [] => false,
            ["lat_deg", "lon_deg", "height_m"] => true,
            _ => {
                return Err(Error::Invalid(format!(
                    "trajectory line 1: after the attitude columns only lat_deg,lon_deg,height_m may follow, found '{}'",
                    rest.join(",")
                )))
            }
        };
        Ok(CsvTrajectory {
            lines,
            line_no: 1,
            att,
            has_place,
            last_t: f64::NEG_INFINITY,
        })
    }

    /// True when the header has the `lat_deg,lon_deg,height_m` columns.
    pub fn has_place(&self) -> bool {
        self.has_place
    }

    /// Number of columns per data line.
    fn ncols(&self) -> usize {
        1 + match self.att {
            AttCols::Euler => 3,
            AttCols::Quat => 4,
        } + if self.has_place { 3 } else { 0 }
    }

    fn parse(&mut self, line: &str) -> Result<Pose> {
        let ln = self.line_no;
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != self.ncols() {
            return Err(Error::Invalid(format!(
                "trajectory line {ln}: expected {} columns, found {}",
                self.ncols(),
                f.len()
            )));
        }
        let v: Vec<f64> = f
            .iter()
            .map(|s| match s.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(Error::Invalid(format!(
                    "trajectory line {ln}: '{s}' is not a finite number"
                ))),
            })
            .collect::<Result<_>>()?;
        let t = v[0];
        if t < 0.0 {
            return Err(Error::Invalid(format!(
                "trajectory line {ln}: t_s = {t} is negative"
            )));
        }
        if t <= self.last_t {
            return Err(Error::Invalid(format!(
                "trajectory line {ln}: time goes backwards or repeats (t_s = {t} after {})",
                self.last_t
            )));
        }
        let (attitude, k) = match self.att {
            AttCols::Euler => (Attitude::enu(v[1], v[2], v[3]), 4),
            AttCols::Quat => (
                Attitude::Quaternion {
                    frame: AttitudeFrame::Enu,
                    wxyz: [v[1], v[2], v[3], v[4]],
                },
                5,
            ),
        };
        attitude
            .validate()
            .map_err(|e| Error::Invalid(format!("trajectory line {ln}: {e}")))?;
        let place = if self.has_place {
            let p = Place {
                lat_deg: v[k],
                lon_deg: v[k + 1],
                height_m: v[k + 2],
            };
            p.validate()
                .map_err(|e| Error::Invalid(format!("trajectory line {ln}: {e}")))?;
            Some(p)
        } else {
            None
        };
        self.last_t = t;
        Ok(Pose {
            t_s: t,
            attitude,
            place,
        })
    }
}

impl<R: BufRead> Iterator for CsvTrajectory<R> {
    type Item = Result<Pose>;
    fn next(&mut self) -> Option<Result<Pose>> {
        loop {
            self.line_no += 1;
            let line = match self.lines.next()? {
                Ok(l) => l,
                Err(e) => return Some(Err(Error::io("reading trajectory", e))),
            };
            if line.trim().is_empty() {
                continue;
            }
            return Some(self.parse(&line));
        }
    }
}

/// The built-in trajectory: a zenith-looking camera turning in yaw (ENU) at a constant rate, one
/// pose every `interval_s`; infinite.
pub fn turning(yaw_rate_deg_s: f64, interval_s: f64) -> impl Iterator<Item = Result<Pose>> {
    (0u64..).map(move |i| {
        let t = i as f64 * interval_s;
        Ok(Pose {
            t_s: t,
            attitude: Attitude::enu((yaw_rate_deg_s * t).rem_euclid(360.0), 0.0, 0.0),
            place: None,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(s: &str) -> Result<Vec<Pose>> {
        CsvTrajectory::new(s.as_bytes())?.collect()
    }

    #[test]
    fn euler_quaternion_and_place() {
        let p = read("t_s,yaw_deg,pitch_deg,roll_deg\n0,10,0,0\n0.05,11,1,-1\n").unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[1].attitude, Attitude::enu(11.0, 1.0, -1.0));
        let p = read("t_s,qw,qx,qy,qz,lat_deg,lon_deg,height_m\n0,1,0,0,0,45,7,100\n").unwrap();
        assert_eq!(p[0].place.unwrap().lat_deg, 45.0);
    }

    #[test]
    fn errors_name_the_line() {
        let e = read("t_s,yaw_deg,pitch_deg,roll_deg\n0,1,2,3\n0.1,1,2\n").unwrap_err();
        assert!(
            e.to_string().contains("line 3") && e.to_string().contains("expected 4 columns"),
            "{e}"
        );
        let e = read("t_s,yaw_deg,pitch_deg,roll_deg\n0,1,2,3\n\n0.1,x,2,3\n").unwrap_err();
        assert!(
            e.to_string().contains("line 4") && e.to_string().contains("'x'"),
            "{e}"
        );
        let e = read("t_s,yaw_deg,pitch_deg,roll_deg\n1,1,2,3\n0.5,1,2,3\n").unwrap_err();
        assert!(
            e.to_string().contains("line 3") && e.to_string().contains("backwards"),
            "{e}"
        );
        let e = read("t_s,qw,qx,qy,qz\n0,1,1,0,0\n").unwrap_err();
        assert!(
            e.to_string().contains("line 2") && e.to_string().contains("unit quaternion"),
            "{e}"
        );
        assert!(read("time,yaw\n").is_err());
    }

    #[test]
    fn poses_before_an_error_are_delivered() {
        let mut t = CsvTrajectory::new("t_s,yaw_deg,pitch_deg,roll_deg\n0,1,2,3\nbad\n".as_bytes())
            .unwrap();
        assert!(t.next().unwrap().is_ok());
        assert!(t.next().unwrap().is_err());
    }

    #[test]
    fn turning_generator() {
        let p: Vec<Pose> = turning(10.0, 0.05).take(3).map(|p| p.unwrap()).collect();
        assert_eq!(p[2].t_s, 0.1);
        assert_eq!(p[2].attitude, Attitude::enu(1.0, 0.0, 0.0));
    }
}
