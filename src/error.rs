//! The library's one error type.
//!
//! Bad input names the value and the allowed range; the binary maps [`Error::is_usage`] errors to
//! exit code 2.

use std::fmt;

/// Everything the library can fail with.
#[derive(Debug)]
pub enum Error {
    /// A parameter outside its allowed range, e.g. `turbidity = 12 is out of range (allowed 1..10)`.
    OutOfRange {
        /// Parameter name as the user wrote it (CLI option or config key).
        name: String,
        /// The offending value, formatted.
        value: String,
        /// The allowed range or set, e.g. `1..10`.
        allowed: String,
    },
    /// Input that cannot be interpreted (malformed CSV line, bad quaternion, unknown name).
    Invalid(String),
    /// A damaged or unreadable data stream / file format.
    Format(String),
    /// A stream's first file header is damaged; its frames may still be readable in degraded
    /// mode (`StreamReader::new_recovering`). The message starts with
    /// `stream::HEADER_DAMAGED`.
    HeaderDamaged(String),
    /// Too few usable pixels (saturated, unpolarized, off the sky) for a heading estimate.
    TooFewPixels(String),
    /// The inputs cannot determine the answer, e.g. a heading with the sun at the zenith (its
    /// azimuth fixes no yaw).
    Undetermined(String),
    /// An input file the user named that is missing, not permitted or a directory (bad input;
    /// the Python package raises `FileNotFoundError`, `PermissionError`, `IsADirectoryError`).
    Input {
        /// The path as the user gave it.
        path: std::path::PathBuf,
        /// The underlying error (its kind says which).
        source: std::io::Error,
    },
    /// An I/O error, with what was being done.
    Io {
        /// What the library was doing, e.g. `writing out/li.npy`.
        context: String,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Result with the library's error.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An out-of-range error for a number.
    pub fn range(name: &str, value: f64, allowed: &str) -> Self {
        Error::OutOfRange {
            name: name.to_string(),
            value: num(value),
            allowed: allowed.to_string(),
        }
    }

    /// An error reading an input file the user named: a missing, unreadable or wrong kind of file
    /// (a directory, say) is bad input (exit code 2); other failures stay I/O errors.
    pub fn input(path: &std::path::Path, source: std::io::Error) -> Self {
        use std::io::ErrorKind as K;
        match source.kind() {
            K::NotFound | K::PermissionDenied | K::IsADirectory => Error::Input {
                path: path.to_path_buf(),
                source,
            },
            K::InvalidData | K::InvalidInput | K::UnexpectedEof => {
                Error::Invalid(format!("{}: {source}", path.display()))
            }
            _ => Error::io(format!("reading {}", path.display()), source),
        }
    }

    /// Wraps an I/O error with context.
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            context: context.into(),
            source,
        }
    }

    /// True for errors caused by the user's input, including an input file that is not what it
    /// should be (exit code 2 in the binary).
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            Error::OutOfRange { .. }
                | Error::Invalid(_)
                | Error::Format(_)
                | Error::HeaderDamaged(_)
                | Error::TooFewPixels(_)
                | Error::Undetermined(_)
                | Error::Input { .. }
        )
    }

    /// True when the error is a closed pipe downstream (the program should end quietly).
    pub fn is_broken_pipe(&self) -> bool {
        matches!(self, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::BrokenPipe)
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::OutOfRange {
                name,
                value,
                allowed,
            } => write!(f, "{name} = {value} is out of range (allowed {allowed})"),
            Error::Invalid(m) => write!(f, "{m}"),
            Error::Format(m)
            | Error::HeaderDamaged(m)
            | Error::TooFewPixels(m)
            | Error::Undetermined(m) => {
                write!(f, "{m}")
            }
            Error::Io { context, source } => write!(f, "{context}: {source}"),
            Error::Input { path, source } if source.kind() == std::io::ErrorKind::NotFound => {
                write!(f, "{} does not exist", path.display())
            }
            Error::Input { path, source } => write!(f, "{}: {source}", path.display()),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } | Error::Input { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Formats a number for a message: short and exact for ordinary values, in exponent form for
/// huge or tiny ones (a user's `1e308` is printed as `1e308`, not as 309 digits).
///
/// ```
/// use psns::error::num;
/// assert_eq!(num(12.5), "12.5");
/// assert_eq!(num(-90.0), "-90");
/// assert_eq!(num(1e308), "1e308");
/// assert_eq!(num(-2.5e-9), "-2.5e-9");
/// assert_eq!(num(f64::NAN), "NaN");
/// ```
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && v != 0.0 && !(1e-6..1e9).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Checks that `value` is finite and within `[lo, hi]`.
///
/// ```
/// assert!(psns::error::check_range("turbidity", 4.0, 1.0, 10.0).is_ok());
/// let e = psns::error::check_range("turbidity", 12.0, 1.0, 10.0).unwrap_err();
/// assert_eq!(e.to_string(), "turbidity = 12 is out of range (allowed 1..10)");
/// ```
pub fn check_range(name: &str, value: f64, lo: f64, hi: f64) -> Result<f64> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(Error::range(
            name,
            value,
            &format!("{}..{}", num(lo), num(hi)),
        ))
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn check_positive(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::range(name, value, "a finite number > 0"))
    }
}
