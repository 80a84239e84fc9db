//! Where a recording goes (the `--out` of `psns stream`, `psns convert` and `psns recover`), and
//! the rule that keeps the user's files:
//! - `-` is stdout (the psns format only); a FIFO, a character device (`/dev/null`) or another
//!   special file is opened and written as it is;
//! - a new path, an empty file or (rosbag2) an empty directory is written in place, so a reader
//!   can follow the recording as it grows and a killed run leaves its frames where the user
//!   looks (`psns recover` finishes them);
//! - a previous psns output of the same kind (a psns stream; an MCAP file psns wrote; a rosbag2
//!   directory holding one) is replaced only when the new one is complete: the run writes a
//!   hidden `.NAME.tmp-PID` beside it and renames it into place at the end, so a run that fails
//!   or is stopped leaves it as it was;
//! - anything else is refused before any work (exit 2, the file untouched).
//!
//! A run holds an exclusive lock (`flock`) on the file it writes and on the output it replaces,
//! so a second run into the same place is refused while the first one runs: two runs never
//! write one file, and a finished run never replaces a recording still in progress.

use super::super::bag::{BagFile, BagKind};
use super::super::output::{dead, temp_pid, OutDir};
use psns::error::{Error, Result};
use std::fs::{File, OpenOptions};
use std::io::Read;
use std::path::{Path, PathBuf};

/// MCAP's magic, the first 8 bytes of an MCAP file.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// An output path, checked before any work: what is there decides how it is written.
#[derive(Debug)]
pub(crate) struct Place {
    out: PathBuf,
    bag: Option<BagKind>,
    how: How,
}

#[derive(Debug)]
enum How {
    Stdout,
    /// A FIFO, a device or another special file.
    Special,
    /// A new path, an empty file or an empty directory.
    InPlace,
    /// A previous psns output of the same kind, locked (the file itself, or a bag's MCAP file).
    Replace(File),
}

/// The usage error for `--out`.
fn bad(out: &Path, m: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("--out {}: {m}", out.display()))
}

/// Takes the exclusive lock of a run on `f`; refused when another run holds it. A file system
/// without locks lets the run go on unlocked.
fn lock(f: &File, out: &Path) -> Result<()> {
    match f.try_lock() {
        Err(std::fs::TryLockError::WouldBlock) => Err(bad(
            out,
            "another psns run is writing it; wait for it to end, or give another path",
        )),
        _ => Ok(()),
    }
}

/// The first bytes of a file (at most 4 KiB).
fn head(f: &File, path: &Path) -> Result<Vec<u8>> {
    let mut b = Vec::new();
    f.take(4096)
        .read_to_end(&mut b)
        .map_err(|e| Error::input(path, e))?;
    Ok(b)
}

/// An MCAP file whose header names psns as the library that wrote it.
fn psns_mcap(b: &[u8]) -> bool {
    // magic, then the Header record: opcode 0x01, u64 length, profile and library strings
    let string = |at: usize| -> Option<(&[u8], usize)> {
        let n = u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?) as usize;
        Some((b.get(at + 4..at + 4 + n)?, at + 4 + n))
    };
    b.starts_with(MCAP_MAGIC)
        && b.get(8) == Some(&0x01)
        && string(17)
            .and_then(|(_, at)| string(at))
            .is_some_and(|(lib, _)| lib.starts_with(b"psns"))
}

impl Place {
    /// Checks `out` for a psns stream (`bag` `None`) or a bag; refuses what must not be written.
    pub(crate) fn check(out: &Path, bag: Option<&BagKind>) -> Result<Place> {
        let how = if out.as_os_str() == "-" {
            if bag.is_some() {
                return Err(Error::Invalid(
                    "a ROS 2 bag is written to a path, not stdout: give --out DIR (rosbag2) or \
                     --out FILE.mcap (mcap)"
                        .into(),
                ));
            }
            How::Stdout
        } else {
            match std::fs::metadata(out) {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => How::InPlace,
                Err(e) => return Err(Error::input(out, e)),
                Ok(m) if bag == Some(&BagKind::Rosbag2) => check_bag_dir(out, &m)?,
                Ok(m) if m.is_dir() => {
                    return Err(bad(
                        out,
                        match bag {
                            Some(_) => {
                                "is a directory (--format mcap writes one file; --format \
                                 rosbag2 writes a directory)"
                            }
                            None => "is a directory (a psns stream is one file)",
                        },
                    ))
                }
                Ok(m) if !m.is_file() => How::Special,
                Ok(_) => check_file(out, bag.is_some())?,
            }
        };
        if bag == Some(&BagKind::Rosbag2) {
            bag_name(out)?;
        }
        Ok(Place {
            out: out.to_path_buf(),
            bag: bag.cloned(),
            how,
        })
    }

    /// True when the output is a pipe or FIFO (stdout included).
    pub(crate) fn is_pipe(&self) -> bool {
        use std::os::unix::fs::FileTypeExt;
        match self.how {
            How::Stdout => {
                use std::os::fd::AsFd;
                let out = std::io::stdout().as_fd().try_clone_to_owned();
                out.is_ok_and(|fd| super::splice::is_pipe(&File::from(fd)))
            }
            How::Special => std::fs::metadata(&self.out).is_ok_and(|m| m.file_type().is_fifo()),
            _ => false,
        }
    }

    /// True when a previous output is replaced at the end of the run.
    pub(crate) fn replaces(&self) -> bool {
        matches!(self.how, How::Replace(_))
    }

    /// What a run that replaces an earlier output says when it starts writing.
    pub(crate) fn replacing_note(&self) -> Option<String> {
        let what = match self.bag {
            None => "psns stream",
            Some(BagKind::Mcap) => "MCAP file",
            Some(BagKind::Rosbag2) => "bag",
        };
        self.replaces().then(|| {
            format!(
                "{} holds an earlier {what}; it is replaced when this run completes",
                self.out.display()
            )
        })
    }

    /// Opens the file the run writes (`None` for stdout), and what puts it in place.
    pub(crate) fn open(self) -> Result<(Option<File>, Landing)> {
        let Place { out, bag, how } = self;
        let mut landing = Landing {
            out: out.clone(),
            path: out.clone(),
            dir: None,
            file_name: String::new(),
            state: State::Stdout,
        };
        let create = |p: &Path| -> Result<File> {
            let f = OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(p)
                .map_err(|e| match e.kind() {
                    std::io::ErrorKind::AlreadyExists => {
                        bad(p, "appeared while this run started; give another path")
                    }
                    _ => Error::io(format!("creating {}", p.display()), e),
                })?;
            lock(&f, p)?;
            Ok(f)
        };
        let file = match (how, &bag) {
            (How::Stdout, _) => return Ok((None, landing)),
            (How::Special, _) => {
                landing.state = State::Special;
                landing.file_name = file_name(&out);
                OpenOptions::new()
                    .write(true)
                    .open(&out)
                    .map_err(|e| Error::io(format!("opening {}", out.display()), e))?
            }
            (How::InPlace, Some(BagKind::Rosbag2)) => {
                let made_dir = !out.exists();
                psns::io::create_dir(&out)?;
                landing.state = State::InPlace { made_dir };
                landing.file_name = format!("{}_0.mcap", bag_name(&out)?);
                landing.path = out.join(&landing.file_name);
                landing.dir = Some(out.clone());
                create(&landing.path)?
            }
            (How::InPlace, _) => {
                landing.state = State::InPlace { made_dir: false };
                landing.file_name = file_name(&out);
                if out.exists() {
                    // an empty file: locked before it is emptied, so a run that just created
                    // it keeps its header
                    let f = OpenOptions::new()
                        .write(true)
                        .open(&out)
                        .map_err(|e| Error::io(format!("opening {}", out.display()), e))?;
                    lock(&f, &out)?;
                    f.set_len(0)
                        .map_err(|e| Error::io(format!("emptying {}", out.display()), e))?;
                    f
                } else {
                    create(&out)?
                }
            }
            (How::Replace(old), Some(BagKind::Rosbag2)) => {
                let names: Vec<String> = std::fs::read_dir(&out)
                    .map_err(|e| Error::input(&out, e))?
                    .flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect();
                let known: Vec<&str> = names.iter().map(String::as_str).collect();
                let dir = OutDir::begin(&out, &known)?;
                landing.file_name = format!("{}_0.mcap", bag_name(&out)?);
                landing.path = dir.path().join(&landing.file_name);
                landing.dir = Some(dir.path().to_path_buf());
                landing.state = State::ReplaceDir { dir, _old: old };
                create(&landing.path)?
            }
            (How::Replace(old), _) => {
                let name = file_name(&out);
                let parent = match out.parent() {
                    Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                    _ => PathBuf::from("."),
                };
                remove_stale_temps(&parent, &name);
                let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
                let _ = std::fs::remove_file(&tmp);
                landing.path = tmp.clone();
                landing.file_name = name;
                let f = create(&tmp)?;
                landing.state = State::ReplaceFile(TempFile {
                    path: tmp,
                    _old: old,
                });
                f
            }
        };
        Ok((Some(file), landing))
    }
}

/// Checks an existing regular file: empty, or a previous psns output of the same kind (locked
/// for the run), else refused.
fn check_file(out: &Path, mcap: bool) -> Result<How> {
    let f = File::open(out).map_err(|e| Error::input(out, e))?;
    lock(&f, out)?;
    let b = head(&f, out)?;
    if b.is_empty() {
        return Ok(How::InPlace);
    }
    let (ours, what) = if mcap {
        (psns_mcap(&b), "an MCAP file written by psns")
    } else {
        (b.starts_with(&psns::stream::FILE_MAGIC), "a psns stream")
    };
    if !ours {
        return Err(bad(
            out,
            format!(
                "exists and is not {what}; psns replaces only its own earlier output of the \
                 same kind (when the new one is complete): give a new path"
            ),
        ));
    }
    Ok(How::Replace(f))
}

/// Checks a rosbag2 `--out`: a new or empty directory, or one holding a bag psns wrote (its
/// `metadata.yaml` and one MCAP file psns wrote, or that file alone when the run was killed).
fn check_bag_dir(out: &Path, m: &std::fs::Metadata) -> Result<How> {
    const WHAT: &str = "a rosbag2 bag is a new or empty directory, or a bag psns wrote, which is \
                        replaced when the new one is complete";
    if !m.is_dir() {
        return Err(bad(out, format!("exists and is not a directory ({WHAT})")));
    }
    let mut mcaps = Vec::new();
    let mut others = Vec::new();
    let mut any = false;
    for e in std::fs::read_dir(out).map_err(|e| Error::input(out, e))? {
        let e = e.map_err(|e| Error::input(out, e))?;
        any = true;
        let name = e.file_name().to_string_lossy().into_owned();
        let file = e.file_type().is_ok_and(|t| t.is_file());
        let stale = name.starts_with('.') && name.contains(".tmp-");
        if file && name.ends_with(".mcap") {
            mcaps.push(e.path());
        } else if !(file && (name == "metadata.yaml" || stale)) {
            others.push(name);
        }
    }
    if !any {
        return Ok(How::InPlace);
    }
    let foreign = |what: String| {
        bad(
            out,
            format!("the directory is not empty: it holds {what}, which is not part of a bag psns wrote ({WHAT})"),
        )
    };
    if let Some(n) = others.first() {
        return Err(foreign(format!("'{n}'")));
    }
    let [mcap] = &mcaps[..] else {
        return Err(foreign(format!("{} MCAP files", mcaps.len())));
    };
    let f = File::open(mcap).map_err(|e| Error::input(mcap, e))?;
    lock(&f, out)?;
    let b = head(&f, mcap)?;
    if !b.is_empty() && !psns_mcap(&b) {
        let n = mcap.file_name().unwrap_or_default().to_string_lossy();
        return Err(foreign(format!("'{n}', an MCAP file psns did not write,")));
    }
    Ok(How::Replace(f))
}

/// The last component of a file path.
fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The bag's name: the directory's last component (rosbag2 names its file `<name>_0.mcap`).
pub(crate) fn bag_name(dir: &Path) -> Result<String> {
    let abs = std::path::absolute(dir).map_err(|e| Error::io("resolving --out", e))?;
    let name = abs
        .components()
        .filter_map(|c| match c {
            std::path::Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
            _ => None,
        })
        .next_back()
        .filter(|n| dir.file_name().is_some() && !n.is_empty());
    name.ok_or_else(|| bad(dir, "name the bag's directory (e.g. --out run1)"))
}

/// Removes the hidden `.NAME.tmp-PID` files that runs killed while replacing `NAME` left in
/// `parent` (checked by PID: the run is gone).
fn remove_stale_temps(parent: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if e.file_type().is_ok_and(|t| t.is_file()) && temp_pid(&n, name).is_some_and(dead) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// A hidden temporary file, removed unless it was put in place.
#[derive(Debug)]
struct TempFile {
    path: PathBuf,
    /// The lock on the output it replaces.
    _old: File,
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.path.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

#[derive(Debug)]
enum State {
    Stdout,
    Special,
    /// Written where the user looks; `made_dir`: this run made the bag's directory.
    InPlace {
        made_dir: bool,
    },
    ReplaceFile(TempFile),
    ReplaceDir {
        dir: OutDir,
        _old: File,
    },
}

/// Where an opened output is written and how it lands at `--out`.
#[derive(Debug)]
pub(crate) struct Landing {
    /// What the user named.
    out: PathBuf,
    /// The file written (the temporary when replacing).
    path: PathBuf,
    /// A rosbag2 bag: the directory written, where `metadata.yaml` goes.
    dir: Option<PathBuf>,
    /// The MCAP file's name in the finished bag (`<name>_0.mcap`, or the bare file's name).
    file_name: String,
    state: State,
}

impl Landing {
    /// The file as the finished output has it (a bag directory's MCAP file, or `--out`).
    pub(crate) fn final_path(&self) -> PathBuf {
        match &self.dir {
            Some(_) => self.out.join(&self.file_name),
            None => self.out.clone(),
        }
    }

    /// True when a previous output is replaced at the end.
    pub(crate) fn replaces(&self) -> bool {
        matches!(self.state, State::ReplaceFile(_) | State::ReplaceDir { .. })
    }

    /// The bag file to write: the open file, where it is, the directory of `metadata.yaml`.
    pub(crate) fn bag_file(&self, file: File) -> BagFile {
        BagFile {
            file,
            path: self.path.clone(),
            dir: self.dir.clone(),
            file_name: self.file_name.clone(),
        }
    }

    /// What a run that stops before it is complete leaves at `--out`.
    pub(crate) fn left(&self, bag: bool) -> String {
        match (&self.state, &self.dir) {
            (State::ReplaceFile(_) | State::ReplaceDir { .. }, _) => {
                format!("{} is kept as it was", self.out.display())
            }
            (_, Some(d)) => format!(
                "the bag {} is left unfinished: no metadata.yaml",
                d.display()
            ),
            (_, None) if bag => {
                format!("{} is left unfinished: no MCAP footer", self.out.display())
            }
            (_, None) => format!("{} is marked aborted", self.out.display()),
        }
    }

    /// Puts a complete output in place: a replacement's temporary is synced and renamed over
    /// the previous output (a directory exchanged with it, which is then removed).
    pub(crate) fn commit(self) -> Result<()> {
        match self.state {
            State::ReplaceFile(mut t) => {
                let ctx = || format!("putting {} in place", self.out.display());
                File::open(&t.path)
                    .and_then(|f| f.sync_all())
                    .and_then(|_| std::fs::rename(&t.path, &self.out))
                    .map_err(|e| Error::io(ctx(), e))?;
                t.path = PathBuf::new();
                Ok(())
            }
            State::ReplaceDir { dir, .. } => dir.commit(),
            _ => Ok(()),
        }
    }

    /// Removes what this run wrote: the output it started in place (the file, and the
    /// directory if the run made it), or a replacement's temporary.
    pub(crate) fn discard(self) {
        if let State::InPlace { made_dir } = self.state {
            let _ = std::fs::remove_file(&self.path);
            if let (Some(d), true) = (&self.dir, made_dir) {
                let _ = std::fs::remove_dir(d);
            }
        }
        // a replacement's temporary goes with it (Drop)
    }
}
