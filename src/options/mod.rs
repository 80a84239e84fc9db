//! The command-line options both front-ends parse: the `psns` binary's commands and the Python
//! package's keyword arguments (`sun_zenith=50` is `--sun-zenith 50`), so both accept the same
//! values and refuse the rest with the same message. Each option struct turns itself into the
//! library's configuration ([`SceneConfig`](crate::config::SceneConfig), a heading setup, ...);
//! what a command then does with files, terminals and charts stays in its front-end.
//!
//! The structs derive [`clap::Args`]; their doc comments are the `--help` text.

pub mod dataset;
pub mod demosaic;
pub mod heading;
pub mod raw;
pub mod render;
pub mod scene;
pub mod sky;
pub mod world;

pub use dataset::{BuildArgs, DatasetCmd, DirArgs, PreviewArgs};
pub use demosaic::DemosaicArgs;
pub use heading::{load_mask, HeadingArgs, SkyMaskArg};
pub use raw::RawArgs;
pub use render::RenderArgs;
pub use scene::{SceneArgs, SpaArgs};
pub use sky::SkyArgs;
pub use world::WorldArgs;

use std::str::FromStr;

/// Lets every option that takes a value accept a negative number, so `--frames -1` gets a
/// message about the value instead of clap's "unexpected argument '-1'".
pub fn negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if a.get_action().takes_values() && !a.is_positional() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_numbers)
}

/// Parses a value by its [`FromStr`] (the library's names: a preset, a method, a layout, ...),
/// with the library's message on failure.
pub fn parsed<T: FromStr<Err = crate::Error>>(s: &str) -> Result<T, String> {
    s.parse().map_err(|e: crate::Error| e.to_string())
}

/// Parses a finite f64 (rejects NaN and infinities with a clear message).
pub fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a finite number"))
    }
}

/// Parses a whole number 0..2^64-1 (a count, an index or a seed), with a range message for a
/// negative or fractional value.
pub fn whole(s: &str) -> Result<u64, String> {
    let t = s.trim();
    t.parse::<u64>().map_err(|_| match t.parse::<f64>() {
        Ok(v) => format!(
            "{} is out of range (allowed a whole number 0..{})",
            crate::error::num(v),
            u64::MAX
        ),
        Err(_) => format!("'{s}' is not a whole number"),
    })
}

/// Parses a whole number that may be negative (a size or a count checked later against its
/// range, which then names it), with a clear message for anything else: `640.0` is not an
/// integer, `1e30` is out of range.
///
/// ```
/// use psns::options::integer;
/// assert_eq!(integer("-3"), Ok(-3));
/// assert_eq!(integer("640.0").unwrap_err(), "'640.0' is not an integer");
/// assert!(integer("1e30").unwrap_err().contains("is out of range (allowed"));
/// ```
pub fn integer(s: &str) -> Result<i64, String> {
    let t = s.trim();
    t.parse::<i64>().map_err(|_| match t.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() >= 2f64.powi(63) => format!(
            "{} is out of range (allowed a whole number {}..{})",
            crate::error::num(v),
            i64::MIN,
            i64::MAX
        ),
        _ => format!("'{s}' is not an integer"),
    })
}

/// The first option of `options` (name, given) that was given.
pub fn first_given(options: &[(&'static str, bool)]) -> Option<&'static str> {
    options.iter().find_map(|&(n, g)| g.then_some(n))
}

/// Parses a repetition count, 1..1000.
pub fn runs(s: &str) -> Result<usize, String> {
    match whole(s)? {
        v @ 1..=1000 => Ok(v as usize),
        v => Err(format!("{v} is out of range (allowed 1..1000)")),
    }
}

/// Parses `a,b,...` with exactly N finite numbers.
pub fn finite_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s.split(',').map(finite).collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("expected {N} comma-separated numbers, found {}", v.len()))
}
