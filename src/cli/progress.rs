//! Progress of long commands on stderr (`psns stream`, `psns dataset build`, `psns bench demosaic`,
//! `psns bench sky`, `psns figures`); the library's work reports through [`Terminal`], its
//! [`psns::progress::Reporter`].
//!
//! * stderr is a terminal: an [`indicatif`] bar (position, rate, ETA; a spinner with a count when
//!   the total is unknown), cleared when the work ends, so only the command's own lines remain.
//! * stderr is not a terminal (a pipe, a file, a Slurm log): plain lines such as
//!   `psns stream: 1200/3000 frames, 98.1 fps, eta 18 s`, at most one per period (10 s) plus one
//!   per 10 % of a known total, and none at all while the job is younger than the grace time (5 s)
//!   unless the caller marked it long. Short jobs therefore print exactly what they printed
//!   before.
//! * `PSNS_PROGRESS=off` turns both off; `PSNS_PROGRESS_PERIOD_S=S` sets the period of the plain
//!   lines (the grace time is never longer than the period, so `0` prints a line per update).
//!
//! The decisions are the library's pure functions of an elapsed time ([`Schedule::due`],
//! [`mode`], [`plain_line`]).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
pub use psns::progress::Unit;
use psns::progress::{
    mode, period, plain_line, Mode, Schedule, DEFAULT_PERIOD, ENV_MODE, ENV_PERIOD,
};
use std::time::{Duration, Instant};

enum Inner {
    Off,
    Bar(ProgressBar),
    Plain { schedule: Schedule, start: Instant },
}

/// Progress of one command (see the module documentation).
pub struct Progress {
    prefix: String,
    unit: Unit,
    total: Option<u64>,
    done: u64,
    msg: String,
    inner: Inner,
}

impl Progress {
    /// Progress on this process's stderr, as its terminal status and the environment decide.
    /// `total` is the count to reach when known; `long` marks a job that is known to be long
    /// (plain lines start without the grace time).
    pub fn new(prefix: &str, unit: Unit, total: Option<u64>, long: bool) -> Self {
        use std::io::IsTerminal;
        let env_mode = std::env::var(ENV_MODE).ok();
        let m = mode(std::io::stderr().is_terminal(), env_mode.as_deref());
        let p = match period(std::env::var(ENV_PERIOD).ok().as_deref()) {
            Ok(p) => p,
            Err(msg) => {
                eprintln!("psns: {msg}");
                DEFAULT_PERIOD
            }
        };
        Self::with_mode(prefix, unit, total, long, m, p)
    }

    fn with_mode(
        prefix: &str,
        unit: Unit,
        total: Option<u64>,
        long: bool,
        mode: Mode,
        period: Duration,
    ) -> Self {
        let inner = match mode {
            Mode::Off => Inner::Off,
            Mode::Plain => Inner::Plain {
                schedule: Schedule::new(period, long),
                start: Instant::now(),
            },
            Mode::Bar => {
                let tpl = match total {
                    Some(_) => format!(
                        "{{prefix}}: [{{bar:30}}] {{pos}}/{{len}} {}, {{rate}}, eta {{eta}} {{wide_msg}}",
                        unit.name()
                    ),
                    None => format!(
                        "{{prefix}}: {{spinner}} {{pos}} {}, {{rate}}, {{elapsed}} {{wide_msg}}",
                        unit.name()
                    ),
                };
                let rate_unit = unit.rate();
                let style = ProgressStyle::with_template(&tpl)
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> ")
                    .with_key(
                        "rate",
                        move |st: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                            let r = st.per_sec();
                            let _ = if r >= 10.0 {
                                write!(w, "{r:.1} {rate_unit}")
                            } else {
                                write!(w, "{r:.2} {rate_unit}")
                            };
                        },
                    );
                let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::stderr());
                bar.set_style(style);
                bar.set_prefix(prefix.to_string());
                bar.enable_steady_tick(Duration::from_millis(200));
                Inner::Bar(bar)
            }
        };
        Progress {
            prefix: prefix.to_string(),
            unit,
            total,
            done: 0,
            msg: String::new(),
            inner,
        }
    }

    /// Sets the current step's description (shown after the numbers).
    pub fn set_message(&mut self, msg: impl Into<String>) {
        self.msg = msg.into();
        if let Inner::Bar(b) = &self.inner {
            b.set_message(self.msg.clone());
        }
    }

    /// Counts `n` more done; may print a plain line.
    pub fn inc(&mut self, n: u64) {
        self.done += n;
        match &mut self.inner {
            Inner::Off => {}
            Inner::Bar(b) => b.set_position(self.done),
            Inner::Plain { schedule, start } => {
                let elapsed = start.elapsed();
                if schedule.due(elapsed, self.done, self.total) {
                    eprintln!(
                        "{}",
                        plain_line(
                            &self.prefix,
                            self.unit,
                            self.done,
                            self.total,
                            elapsed,
                            &self.msg
                        )
                    );
                }
            }
        }
    }

    /// Prints a line of the command's own output on stderr without tearing the bar.
    pub fn println(&self, line: impl AsRef<str>) {
        match &self.inner {
            Inner::Bar(b) => b.suspend(|| eprintln!("{}", line.as_ref())),
            _ => eprintln!("{}", line.as_ref()),
        }
    }
}

/// The bar is cleared when the progress ends (also after an error).
impl Drop for Progress {
    fn drop(&mut self) {
        if let Inner::Bar(b) = &self.inner {
            b.finish_and_clear();
        }
    }
}

/// The library's progress on this process's stderr, as [`Progress`] shows it.
pub struct Terminal;

impl psns::progress::Reporter for Terminal {
    fn start(
        &self,
        prefix: &str,
        unit: Unit,
        total: Option<u64>,
        long: bool,
    ) -> Box<dyn psns::progress::Progress> {
        Box::new(Progress::new(prefix, unit, total, long))
    }
}

impl psns::progress::Progress for Progress {
    fn set_message(&mut self, msg: &str) {
        Progress::set_message(self, msg);
    }
    fn inc(&mut self, n: u64) {
        Progress::inc(self, n);
    }
    fn println(&mut self, line: &str) {
        Progress::println(self, line);
    }
}
