//! Progress of long library work (a dataset build). The library tells a [`Reporter`] what it
//! does and never draws, prints or reads a clock for it; the front-end shows it (an indicatif bar
//! on a terminal, periodic plain lines in a log) or ignores it ([`Quiet`]).
//!
//! The rules of the plain lines are pure functions of an elapsed time ([`Schedule::due`],
//! [`mode`], [`plain_line`]), shared by every front-end and tested without a clock or a terminal:
//! at most one line per period (10 s) plus one per 10 % of a known total, none while a job not
//! marked long is younger than the grace time (5 s); `PSNS_PROGRESS=off` turns progress off and
//! `PSNS_PROGRESS_PERIOD_S=S` sets the period.

use std::time::Duration;

/// One piece of work in progress.
pub trait Progress: Send {
    /// The current step, shown beside the count.
    fn set_message(&mut self, msg: &str);
    /// `n` more done.
    fn inc(&mut self, n: u64);
    /// A line for the user that must not be torn by the progress display.
    fn println(&mut self, line: &str);
}

/// Starts the [`Progress`] of a piece of work: `prefix` names it (`psns dataset`), `total` is
/// the count when known, and `long` marks work that shows progress from its start.
pub trait Reporter: Sync {
    /// A new piece of work.
    fn start(&self, prefix: &str, unit: Unit, total: Option<u64>, long: bool) -> Box<dyn Progress>;
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet;

impl Progress for Quiet {
    fn set_message(&mut self, _: &str) {}
    fn inc(&mut self, _: u64) {}
    fn println(&mut self, _: &str) {}
}

impl Reporter for Quiet {
    fn start(&self, _: &str, _: Unit, _: Option<u64>, _: bool) -> Box<dyn Progress> {
        Box::new(Quiet)
    }
}

/// Plain lines: at most one per this period (besides the 10 % steps).
pub const DEFAULT_PERIOD: Duration = Duration::from_secs(10);
/// Plain lines: none while a job not marked long is younger than this.
pub const GRACE: Duration = Duration::from_secs(5);
/// Environment variable: `off` disables progress output.
pub const ENV_MODE: &str = "PSNS_PROGRESS";
/// Environment variable: period of the plain lines, seconds (≥ 0).
pub const ENV_PERIOD: &str = "PSNS_PROGRESS_PERIOD_S";

/// What is counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// Frames of a stream (rate in fps).
    Frames,
    /// Steps of a batch job (rate in steps/s).
    Steps,
    /// Images of a dataset (rate in images/s).
    Images,
}

impl Unit {
    /// What is counted, plural.
    pub fn name(self) -> &'static str {
        match self {
            Unit::Frames => "frames",
            Unit::Steps => "steps",
            Unit::Images => "images",
        }
    }
    /// The rate's unit.
    pub fn rate(self) -> &'static str {
        match self {
            Unit::Frames => "fps",
            Unit::Steps => "steps/s",
            Unit::Images => "images/s",
        }
    }
}

/// How progress is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Nothing.
    Off,
    /// An indicatif bar (stderr is a terminal).
    Bar,
    /// Periodic plain lines (stderr is a pipe or a file).
    Plain,
}

/// The mode for a stderr that is (or is not) a terminal and the value of `PSNS_PROGRESS`.
pub fn mode(stderr_is_terminal: bool, env_mode: Option<&str>) -> Mode {
    match env_mode.map(str::trim) {
        Some(m) if m.eq_ignore_ascii_case("off") || m == "0" => Mode::Off,
        _ if stderr_is_terminal => Mode::Bar,
        _ => Mode::Plain,
    }
}

/// The period of the plain lines from the value of `PSNS_PROGRESS_PERIOD_S`: `Err(message)` for a
/// value that is not a finite number of seconds in 0..=86400.
pub fn period(env_period: Option<&str>) -> Result<Duration, String> {
    let Some(v) = env_period else {
        return Ok(DEFAULT_PERIOD);
    };
    match v.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && (0.0..=86400.0).contains(&s) => Ok(Duration::from_secs_f64(s)),
        _ => Err(format!(
            "ignoring {ENV_PERIOD}={v}: seconds 0..86400 expected; using {} s",
            DEFAULT_PERIOD.as_secs()
        )),
    }
}

/// When the plain lines are due: the pure decision logic, driven by the elapsed time.
#[derive(Clone, Debug)]
pub struct Schedule {
    period: Duration,
    grace: Duration,
    long: bool,
    last: Option<Duration>,
    last_decile: u64,
}

impl Schedule {
    /// Lines at most every `period` (plus one per 10 % of a known total), none before the grace
    /// time `min(GRACE, period)` unless `long`.
    pub fn new(period: Duration, long: bool) -> Self {
        Schedule {
            period,
            grace: GRACE.min(period),
            long,
            last: None,
            last_decile: 0,
        }
    }

    /// Whether a line is due at `elapsed` after the start with `done` of `total` done; a `true`
    /// counts as printed.
    pub fn due(&mut self, elapsed: Duration, done: u64, total: Option<u64>) -> bool {
        if !self.long && elapsed < self.grace {
            return false;
        }
        let decile = match total {
            Some(t) if t > 0 => (done.min(t) * 10 / t).min(10),
            _ => 0,
        };
        let due = match self.last {
            None => true,
            Some(last) => elapsed.saturating_sub(last) >= self.period || decile > self.last_decile,
        };
        if due {
            self.last = Some(elapsed);
            self.last_decile = decile;
        }
        due
    }
}

/// One plain progress line, e.g. `psns stream: 1200/3000 frames, 98.1 fps, eta 18 s`, or without a
/// total `psns stream: 1200 frames, 98.1 fps`; `msg` (the current step) goes in parentheses.
pub fn plain_line(
    prefix: &str,
    unit: Unit,
    done: u64,
    total: Option<u64>,
    elapsed: Duration,
    msg: &str,
) -> String {
    let secs = elapsed.as_secs_f64();
    let rate = if secs > 0.0 { done as f64 / secs } else { 0.0 };
    let mut s = match total {
        Some(t) => format!("{prefix}: {done}/{t} {}", unit.name()),
        None => format!("{prefix}: {done} {}", unit.name()),
    };
    if rate >= 10.0 {
        s.push_str(&format!(", {rate:.1} {}", unit.rate()));
    } else {
        s.push_str(&format!(", {rate:.2} {}", unit.rate()));
    }
    match total {
        Some(t) if done > 0 && done < t && rate > 0.0 => {
            let eta = (t - done) as f64 / rate;
            s.push_str(&format!(", eta {:.0} s", eta.ceil()));
        }
        _ => s.push_str(&format!(", {secs:.0} s elapsed")),
    }
    if !msg.is_empty() {
        s.push_str(&format!(" ({msg})"));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: f64) -> Duration {
        Duration::from_secs_f64(x)
    }

    #[test]
    fn terminal_gets_a_bar_pipes_plain_lines_env_turns_off() {
        assert_eq!(mode(true, None), Mode::Bar);
        assert_eq!(mode(false, None), Mode::Plain);
        assert_eq!(mode(true, Some("off")), Mode::Off);
        assert_eq!(mode(false, Some("OFF")), Mode::Off);
        assert_eq!(mode(false, Some("0")), Mode::Off);
        assert_eq!(mode(false, Some("auto")), Mode::Plain);
    }

    #[test]
    fn period_from_the_environment() {
        assert_eq!(period(None), Ok(DEFAULT_PERIOD));
        assert_eq!(period(Some("0")), Ok(Duration::ZERO));
        assert_eq!(period(Some(" 2.5 ")), Ok(s(2.5)));
        for bad in ["-1", "nan", "inf", "x", "", "1e9"] {
            let e = period(Some(bad)).unwrap_err();
            assert!(e.contains(ENV_PERIOD) && e.contains("0..86400"), "{e}");
        }
    }

    #[test]
    fn short_jobs_print_nothing() {
        // 4.9 s of updates, 1000 frames of 1000: never a line (grace 5 s)
        let mut sc = Schedule::new(DEFAULT_PERIOD, false);
        for k in 0..=1000u64 {
            assert!(!sc.due(s(k as f64 * 0.0049), k, Some(1000)), "at {k}");
        }
        // unknown total too
        let mut sc = Schedule::new(DEFAULT_PERIOD, false);
        assert!(!sc.due(s(4.99), 500, None));
    }

    #[test]
    fn long_jobs_print_every_period_and_every_ten_percent() {
        // unknown total: first update after the grace time, then one per period
        let mut sc = Schedule::new(s(10.0), false);
        let printed: Vec<u64> = (0..=300u64)
            .filter(|&t| sc.due(s(t as f64 * 0.1), t, None))
            .collect();
        assert_eq!(printed, vec![50, 150, 250]);
        // known total, slow job (1000 updates over 100 s): each 10 % step (10 s here) and the
        // period coincide; first line at the grace time
        let mut sc = Schedule::new(s(10.0), false);
        let printed: Vec<u64> = (0..=1000u64)
            .filter(|&k| sc.due(s(k as f64 * 0.1), k, Some(1000)))
            .collect();
        assert_eq!(
            printed,
            vec![50, 100, 200, 300, 400, 500, 600, 700, 800, 900, 1000]
        );
        // known total with a long period: the 10 % steps alone
        let mut sc = Schedule::new(s(1000.0), false);
        let printed: Vec<u64> = (0..=100u64)
            .filter(|&k| sc.due(s(k as f64), k, Some(100)))
            .collect();
        assert_eq!(printed, vec![5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]);
    }

    #[test]
    fn marked_long_starts_at_once_and_period_zero_prints_every_update() {
        let mut sc = Schedule::new(s(10.0), true);
        assert!(sc.due(s(0.01), 1, Some(3000)));
        assert!(!sc.due(s(0.02), 2, Some(3000)));
        assert!(sc.due(s(10.01), 1000, Some(3000)));
        let mut sc = Schedule::new(Duration::ZERO, false);
        assert!((1..=5).all(|k| sc.due(s(k as f64 * 1e-3), k, None)));
    }

    #[test]
    fn plain_line_format() {
        assert_eq!(
            plain_line(
                "psns stream",
                Unit::Frames,
                1200,
                Some(3000),
                s(1200.0 / 98.1),
                ""
            ),
            "psns stream: 1200/3000 frames, 98.1 fps, eta 19 s"
        );
        assert_eq!(
            plain_line("psns stream", Unit::Frames, 1200, None, s(12.0), ""),
            "psns stream: 1200 frames, 100.0 fps, 12 s elapsed"
        );
        assert_eq!(
            plain_line(
                "psns figures",
                Unit::Steps,
                3,
                Some(12),
                s(6.0),
                "photon transfer"
            ),
            "psns figures: 3/12 steps, 0.50 steps/s, eta 18 s (photon transfer)"
        );
        assert_eq!(
            plain_line("psns figures", Unit::Steps, 0, Some(12), Duration::ZERO, ""),
            "psns figures: 0/12 steps, 0.00 steps/s, 0 s elapsed"
        );
    }
}
