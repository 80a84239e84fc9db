//! Trajectories that drive `psns stream`: timed poses read line by line from CSV, or generated.
//!
//! CSV: a header line, then one pose per line. Columns: `t_s` (seconds since the stream's start
//! time), then either `yaw_deg,pitch_deg,roll_deg` (ENU frame, as `psns render --frame enu`) or
//! `qw,qx,qy,qz` (Hamilton, camera → ENU), and optionally `lat_deg,lon_deg,height_m`. Lines are
//! read as they arrive and their fields parsed by the `csv` crate, so a trajectory can be piped
//! in from a running simulator.

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

/// A value from the input as an error message quotes it: at most [`QUOTE_MAX`] characters, so a
/// 10 MB line does not end up whole on stderr.
///
/// ```
/// use psns::trajectory::quote;
/// assert_eq!(quote("0.5x"), "'0.5x'");
/// assert_eq!(quote(&"9".repeat(100)), format!("'{}...' (100 bytes)", "9".repeat(32)));
/// ```
pub fn quote(s: &str) -> String {
    match s.char_indices().nth(QUOTE_MAX) {
        None => format!("'{s}'"),
        Some((i, _)) => format!("'{}...' ({} bytes)", &s[..i], s.len()),
    }
}

/// Latest pose time, seconds (about 31.7 years: far inside the stream clock's i64 nanoseconds).
pub const MAX_T_S: f64 = 1e9;

/// Most characters of an input value quoted in a message ([`quote`]).
pub const QUOTE_MAX: usize = 32;

/// Reads poses from CSV, one line at a time as lines arrive (each line's fields split, unquoted
/// and trimmed by the `csv` crate); errors name the line number and quote at most
/// [`QUOTE_MAX`] characters of the input.
pub struct CsvTrajectory<R: BufRead> {
    src: R,
    line: Vec<u8>,
    rec: csv::ByteRecord,
    line_no: u64,
    att: AttCols,
    has_place: bool,
    last_t: f64,
    complete_lines: bool,
}

impl<R: BufRead> CsvTrajectory<R> {
    /// Reads and checks the header line. A last line without its newline is accepted (a file
    /// saved without one); see [`require_complete_lines`](Self::require_complete_lines).
    pub fn new(reader: R) -> Result<Self> {
        Self::open(reader, false)
    }

    /// Like [`new`](Self::new), but a last line without its newline is refused: read from a pipe,
    /// it is a line the producer was cut off in the middle of (`0.1,12` for `0.1,12.5`).
    pub fn require_complete_lines(reader: R) -> Result<Self> {
        Self::open(reader, true)
    }

    fn open(reader: R, complete_lines: bool) -> Result<Self> {
        let mut t = CsvTrajectory {
            src: reader,
            line: Vec::new(),
            rec: csv::ByteRecord::new(),
            line_no: 0,
            att: AttCols::Euler,
            has_place: false,
            last_t: f64::NEG_INFINITY,
            complete_lines,
        };
        if !t.read_record()? {
            return Err(Error::Invalid(
                "trajectory line 1: empty input, expected a header".into(),
            ));
        }
        let ln = t.line_no;
        let cols = t.fields()?;
        let c: Vec<&str> = cols.iter().map(|s| s.as_str()).collect();
        let (att, rest) = match c.as_slice() {
            ["t_s", "yaw_deg", "pitch_deg", "roll_deg", rest @ ..] => (AttCols::Euler, rest),
            ["t_s", "qw", "qx", "qy", "qz", rest @ ..] => (AttCols::Quat, rest),
            _ => {
                return Err(Error::Invalid(format!(
                    "trajectory line {ln}: header {} must start with t_s,yaw_deg,pitch_deg,roll_deg or t_s,qw,qx,qy,qz",
                    quote(&c.join(","))
                )))
            }
        };
        t.has_place = match rest {
            [] => false,
            ["lat_deg", "lon_deg", "height_m"] => true,
            _ => {
                return Err(Error::Invalid(format!(
                    "trajectory line {ln}: after the attitude columns only lat_deg,lon_deg,height_m may follow, found {}",
                    quote(&rest.join(","))
                )))
            }
        };
        t.att = att;
        Ok(t)
    }

    /// Reads the next line that is not blank into `rec`; false at the end of the input.
    fn read_record(&mut self) -> Result<bool> {
        loop {
            self.line.clear();
            let n = self
                .src
                .read_until(b'\n', &mut self.line)
                .map_err(|e| Error::io("reading trajectory", e))?;
            if n == 0 {
                return Ok(false);
            }
            self.line_no += 1;
            let mut rd = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .trim(csv::Trim::All)
                .from_reader(&self.line[..]);
            let more = rd.read_byte_record(&mut self.rec).map_err(|e| {
                let what = e.to_string();
                match e.into_kind() {
                    csv::ErrorKind::Io(io) => Error::io("reading trajectory", io),
                    _ => Error::Invalid(format!("trajectory line {}: {what}", self.line_no)),
                }
            })?;
            if !more || self.rec.iter().all(|f| f.is_empty()) {
                continue; // a blank line
            }
            if self.complete_lines && self.line.last() != Some(&b'\n') {
                let fields: Vec<_> = self.rec.iter().map(String::from_utf8_lossy).collect();
                return Err(Error::Invalid(format!(
                    "trajectory line {}: the input ended inside this line ({} has no newline): \
                     a line cut off by its producer is refused",
                    self.line_no,
                    quote(&fields.join(","))
                )));
            }
            return Ok(true);
        }
    }

    /// The current record's fields as text.
    fn fields(&self) -> Result<Vec<String>> {
        self.rec
            .iter()
            .enumerate()
            .map(|(k, f)| {
                std::str::from_utf8(f).map(str::to_string).map_err(|_| {
                    Error::Invalid(format!(
                        "trajectory line {}: column {} is not UTF-8 text",
                        self.line_no,
                        k + 1
                    ))
                })
            })
            .collect()
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

    fn parse(&mut self) -> Result<Pose> {
        let ln = self.line_no;
        let f = self.fields()?;
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
                    "trajectory line {ln}: {} is not a finite number",
                    quote(s)
                ))),
            })
            .collect::<Result<_>>()?;
        let t = v[0];
        crate::error::check_range("t_s", t, 0.0, MAX_T_S)
            .map_err(|e| Error::Invalid(format!("trajectory line {ln}: {e}")))?;
        if t <= self.last_t {
            return Err(Error::Invalid(format!(
                "trajectory line {ln}: time goes backwards or repeats (t_s = {} after {})",
                crate::error::num(t),
                crate::error::num(self.last_t)
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
        match self.read_record() {
            Ok(true) => Some(self.parse()),
            Ok(false) => None,
            Err(e) => Some(Err(e)),
        }
    }
}

/// The built-in trajectory: the camera at `start` (yaw, pitch and roll in its frame; zenith-looking
/// by default) turning in yaw at a constant rate, one pose every `interval_s`; infinite. A
/// quaternion start is refused.
pub fn turning(
    start: Attitude,
    yaw_rate_deg_s: f64,
    interval_s: f64,
) -> Result<impl Iterator<Item = Result<Pose>>> {
    let Attitude::Euler {
        frame,
        yaw_deg,
        pitch_deg,
        roll_deg,
    } = start
    else {
        return Err(Error::Invalid(
            "the turning camera starts from --yaw, --pitch and --roll: give a --trajectory for \
             a --quaternion attitude"
                .into(),
        ));
    };
    Ok((0u64..).map(move |i| {
        let t = i as f64 * interval_s;
        Ok(Pose {
            t_s: t,
            attitude: Attitude::Euler {
                frame,
                yaw_deg: (yaw_deg + yaw_rate_deg_s * t).rem_euclid(360.0),
                pitch_deg,
                roll_deg,
            },
            place: None,
        })
    }))
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
    fn a_huge_value_is_quoted_short_and_bad_bytes_name_their_line() {
        let line = format!("0.05,{},0,0\n", "9".repeat(10 << 20));
        let e = read(&format!("t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n{line}")).unwrap_err();
        let m = e.to_string();
        assert!(
            m.len() < 120 && m.contains("line 3") && m.contains("10485760 bytes"),
            "{m}"
        );
        let mut b = b"t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n\n0.1,".to_vec();
        b.extend_from_slice(b"\xff\xfe,0,0\n");
        let e = CsvTrajectory::new(&b[..])
            .unwrap()
            .nth(1)
            .unwrap()
            .unwrap_err();
        assert!(e.is_usage(), "{e:?}");
        assert!(
            e.to_string().contains("line 4") && e.to_string().contains("UTF-8"),
            "{e}"
        );
        let e = read(&format!("{},yaw\n", "t".repeat(1000))).unwrap_err();
        assert!(e.to_string().len() < 200, "{e}");
        let e = read("t_s,yaw_deg,pitch_deg,roll_deg\n1e308,0,0,0\n").unwrap_err();
        assert!(e.to_string().contains("line 2: t_s = 1e308"), "{e}");
    }

    #[test]
    fn a_last_line_without_newline_is_refused_where_asked() {
        // the whole line would be 0.1,12,0,0.25: cut inside the last number, it still parses
        let cut = "t_s,yaw_deg,pitch_deg,roll_deg\n0,1,2,3\n0.1,12,0,0.2";
        // a file saved without a final newline: fine
        let p = read(cut).unwrap();
        assert_eq!(p[1].attitude, Attitude::enu(12.0, 0.0, 0.2));
        // from a pipe: the producer was cut off inside the number
        let mut t = CsvTrajectory::require_complete_lines(cut.as_bytes()).unwrap();
        assert!(t.next().unwrap().is_ok());
        let e = t.next().unwrap().unwrap_err();
        assert!(e.is_usage(), "{e:?}");
        assert!(
            e.to_string().contains("line 3") && e.to_string().contains("'0.1,12,0,0.2'"),
            "{e}"
        );
        for whole in [
            format!("{cut}5\n"),
            format!("{cut}5\r\n"),
            format!("{cut}5\n  \n"),
        ] {
            let t = CsvTrajectory::require_complete_lines(whole.as_bytes()).unwrap();
            let poses: Vec<Pose> = t.collect::<Result<_>>().unwrap();
            assert_eq!(poses.len(), 2, "{whole:?}");
        }
        let Err(e) = CsvTrajectory::require_complete_lines("t_s,yaw_deg".as_bytes()) else {
            panic!("a header without its newline from a pipe was accepted")
        };
        assert!(e.to_string().contains("line 1"), "{e}");
    }

    /// Bytes arriving in pieces, as from a simulator's pipe.
    struct Pieces(std::sync::mpsc::Receiver<Vec<u8>>, Vec<u8>);
    impl std::io::Read for Pieces {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.1.is_empty() {
                match self.0.recv() {
                    Ok(b) => self.1 = b,
                    Err(_) => return Ok(0),
                }
            }
            let n = self.1.len().min(buf.len());
            buf[..n].copy_from_slice(&self.1[..n]);
            self.1.drain(..n);
            Ok(n)
        }
    }

    #[test]
    fn each_pose_is_delivered_when_its_line_arrives() {
        let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
        let (ptx, prx) = std::sync::mpsc::channel();
        tx.send(b"t_s,yaw_deg,pitch_deg,roll_deg\n".to_vec())
            .unwrap();
        std::thread::spawn(move || {
            let src = std::io::BufReader::new(Pieces(rx, Vec::new()));
            let t = CsvTrajectory::require_complete_lines(src).unwrap();
            for p in t {
                let _ = ptx.send(p);
            }
        });
        for k in 0..3 {
            // half a line: no pose yet
            tx.send(format!("{k}.5,{k}").into_bytes()).unwrap();
            let wait = std::time::Duration::from_millis(200);
            assert!(
                prx.recv_timeout(wait).is_err(),
                "pose {k} before its line ended"
            );
            tx.send(b",0,0\n".to_vec()).unwrap();
            let p = prx
                .recv_timeout(std::time::Duration::from_secs(10))
                .expect("the pose of a whole line")
                .unwrap();
            assert_eq!(p.t_s, k as f64 + 0.5);
        }
    }

    #[test]
    fn turning_generator() {
        let p: Vec<Pose> = turning(Attitude::default(), 10.0, 0.05)
            .unwrap()
            .take(3)
            .map(|p| p.unwrap())
            .collect();
        assert_eq!(p[2].t_s, 0.1);
        assert_eq!(p[2].attitude, Attitude::enu(1.0, 0.0, 0.0));
        // from a given attitude: yaw turns, pitch and roll stay
        let p: Vec<Pose> = turning(Attitude::enu(355.0, 20.0, -5.0), 100.0, 0.1)
            .unwrap()
            .take(2)
            .map(|p| p.unwrap())
            .collect();
        assert_eq!(p[0].attitude, Attitude::enu(355.0, 20.0, -5.0));
        assert_eq!(p[1].attitude, Attitude::enu(5.0, 20.0, -5.0));
        let q = Attitude::Quaternion {
            frame: AttitudeFrame::Enu,
            wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        assert!(matches!(turning(q, 1.0, 1.0), Err(Error::Invalid(_))));
    }
}
