//! The scene clock of a trajectory: when each frame's exposure starts and where its sun is.

use super::FrameRequest;
use crate::config::SceneConfig;
use crate::error::Result;
use crate::sensor::Exposure;
use crate::sun::{self, Place, Refraction, SunPosition};
use crate::trajectory::Pose;
use chrono::{DateTime, Utc};

/// Trajectory start time when neither the caller nor the scene's `sun.time` gives one.
pub const DEFAULT_START_TIME: &str = "2025-06-21T10:00:00Z";

/// Seconds as whole nanoseconds (rounded), refused when they do not fit the stream clock.
pub fn seconds_to_ns(t_s: f64) -> Result<i64> {
    let ns = (t_s * 1e9).round();
    if !(ns.is_finite() && ns.abs() < 9.0e18) {
        return Err(crate::error::Error::Invalid(format!(
            "trajectory time {} s does not fit the stream clock",
            crate::error::num(t_s)
        )));
    }
    Ok(ns as i64)
}

/// Where a frame's sun comes from.
#[derive(Clone, Copy, Debug)]
enum SunSource {
    /// Given directly by the scene: fixed.
    Fixed(SunPosition),
    /// SPA at the frame's time, at the pose's place or else this one (None: the pose must carry
    /// one).
    Spa(Option<Place>),
}

/// The clock and the sun of frames driven by a trajectory (`psns stream`, `psns gige`): a pose
/// at `t_s` starts its exposure at `start + t_s`, never at a host time, so the same options give
/// the same frames. The sun is the scene's when the scene gives it directly; with a place (the
/// scene's `sun.place` and `sun.time`, or the pose's lat/lon) it is NREL SPA at the time the
/// caller asks for (mid-exposure).
#[derive(Clone, Debug)]
pub struct SceneClock {
    sun: SunSource,
    place: Option<Place>,
    start: DateTime<Utc>,
    start_ns: i64,
    delta_t_s: Option<f64>,
    refraction: Option<Refraction>,
}

impl SceneClock {
    /// Time zero of the trajectory: `start_time`, else the scene's `sun.time`, else
    /// [`DEFAULT_START_TIME`].
    pub fn start_time(cfg: &SceneConfig, start_time: Option<&str>) -> Result<DateTime<Utc>> {
        let s = start_time
            .map(str::to_string)
            .or_else(|| cfg.sun.time.clone())
            .unwrap_or_else(|| DEFAULT_START_TIME.to_string());
        let t = sun::parse_time(&s)?;
        t.timestamp_nanos_opt().ok_or_else(|| {
            crate::error::Error::Invalid(format!("start time {s} is out of range"))
        })?;
        Ok(t)
    }

    /// The clock of `cfg` from `start`; `trajectory_has_place` when every pose carries a place
    /// (the scene's time and place must then be consistent with one).
    pub fn new(
        cfg: &SceneConfig,
        start: DateTime<Utc>,
        trajectory_has_place: bool,
    ) -> Result<Self> {
        let start_ns = start.timestamp_nanos_opt().ok_or_else(|| {
            crate::error::Error::Invalid(format!("start time {start} is out of range"))
        })?;
        let sun = if cfg.sun.time.is_some() {
            // the scene's time and place must be consistent; the trajectory may bring the place
            let mut check = cfg.sun.clone();
            if trajectory_has_place && check.place.is_none() {
                check.place = Some(Place {
                    lat_deg: 0.0,
                    lon_deg: 0.0,
                    height_m: 0.0,
                });
            }
            check.resolve()?;
            SunSource::Spa(cfg.sun.place)
        } else {
            SunSource::Fixed(cfg.sun.resolve()?)
        };
        Ok(SceneClock {
            sun,
            place: cfg.sun.place,
            start,
            start_ns,
            delta_t_s: cfg.sun.delta_t_s,
            refraction: cfg.sun.refraction,
        })
    }

    /// Time zero.
    pub fn start(&self) -> DateTime<Utc> {
        self.start
    }

    /// When `pose`'s exposure starts, ns since the Unix epoch.
    pub fn exposure_start_ns(&self, pose: &Pose) -> Result<i64> {
        self.start_ns
            .checked_add(seconds_to_ns(pose.t_s)?)
            .ok_or_else(|| {
                crate::error::Error::Invalid(format!(
                    "trajectory time {} s does not fit the stream clock",
                    crate::error::num(pose.t_s)
                ))
            })
    }

    /// The request of frame `index` at `pose` taken with `exposure`: its exposure start on this
    /// clock, the sun at mid-exposure (at the start for auto-exposure, whose length the frame
    /// decides), the pose's place.
    pub fn request(
        &self,
        index: u64,
        pose: &Pose,
        exposure: &Exposure,
    ) -> Result<FrameRequest<'static>> {
        let half_ns = match exposure {
            Exposure::Fixed { us } => seconds_to_ns(us * 0.5e-6)?,
            Exposure::Auto { .. } => 0,
        };
        let t_ns = self.exposure_start_ns(pose)?;
        let sun = self.sun_at(pose, t_ns.saturating_add(half_ns))?;
        Ok(FrameRequest::sky(index, sun, pose.attitude).at(pose.t_s, t_ns, self.place(pose)))
    }

    /// The place of `pose`: its own, else the scene's.
    pub fn place(&self, pose: &Pose) -> Option<Place> {
        pose.place.or(self.place)
    }

    /// The sun for `pose` at `t_ns` (ns since the Unix epoch): the scene's fixed sun, or SPA
    /// at the pose's place (else the scene's).
    pub fn sun_at(&self, pose: &Pose, t_ns: i64) -> Result<SunPosition> {
        // a place in the trajectory always means SPA; otherwise the scene decides
        let place = match (pose.place, self.sun) {
            (Some(p), _) => Some(p),
            (None, SunSource::Fixed(s)) => return Ok(s),
            (None, SunSource::Spa(p)) => p,
        };
        let place = place.ok_or_else(|| {
            crate::error::Error::Invalid(
                "a moving sun needs a place: give --lat/--lon or lat_deg,lon_deg,height_m columns"
                    .into(),
            )
        })?;
        let t = self.start + chrono::Duration::nanoseconds(t_ns - self.start_ns);
        sun::spa(&t, &place, self.delta_t_s, self.refraction)
    }
}
