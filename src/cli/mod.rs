//! The front-end of the `psns` binary: one module per command (its options and its body), the
//! options several commands share ([`args`]), and the file, terminal and chart code around the
//! library. Nothing here is physics: every formula is in the `psns` library.

pub mod args;
pub mod bench;
pub mod dataset;
pub mod demosaic;
pub mod figures;
pub mod gige;
pub mod heading;
pub mod output;
pub mod poses;
pub mod progress;
pub mod render;
pub mod sky;
pub mod stream;
pub mod sun;
pub mod verify;
pub mod vis;

use psns::{Error, Result};
use std::path::Path;
use std::process::ExitCode;

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

/// Creates a directory and its parents.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(format!("creating {}", dir.display()), e))
}

/// Opens a file, or stdin for `-`.
/// Send + Sync, so a reader kept across calls (the Python package's stream iterator) can hold
/// it; stdin is locked per read, which its large buffered reads make negligible.
pub fn open_input(path: &Path) -> Result<Box<dyn std::io::Read + Send + Sync>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(std::io::stdin()))
    } else {
        let f = std::fs::File::open(path).map_err(|e| Error::input(path, e))?;
        if f.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(Error::Invalid(format!("{} is a directory", path.display())));
        }
        Ok(Box::new(std::io::BufReader::with_capacity(1 << 20, f)))
    }
}

/// `psns verify` found damage: exit code 1 with the report already printed.
#[derive(Debug)]
pub struct NotClean;
impl std::fmt::Display for NotClean {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stream is not clean")
    }
}
impl std::error::Error for NotClean {}

/// `psns verify` found an intact but unfinished stream: exit code 3 with the report printed.
#[derive(Debug)]
pub struct Unfinished;
impl std::fmt::Display for Unfinished {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stream is intact but unfinished")
    }
}
impl std::error::Error for Unfinished {}

/// Maps a command's result to the process exit code: 0 on success or when the reader closed the
/// pipe (a closed pipe ends quietly), 2 for bad input (the library's usage errors), 1 otherwise.
pub fn exit_code(r: anyhow::Result<()>) -> ExitCode {
    let e = match r {
        Ok(()) => return ExitCode::SUCCESS,
        Err(e) => e,
    };
    let lib = e.downcast_ref::<Error>();
    let io_pipe = e
        .downcast_ref::<std::io::Error>()
        .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe);
    if lib.is_some_and(|l| l.is_broken_pipe()) || io_pipe {
        return ExitCode::SUCCESS;
    }
    if e.downcast_ref::<Unfinished>().is_some() {
        eprintln!("psns: {e}");
        return ExitCode::from(3);
    }
    match lib {
        Some(l) => eprintln!("psns: error: {l}"),
        None => eprintln!("psns: error: {e:#}"),
    }
    if lib.is_some_and(|l| l.is_usage()) {
        ExitCode::from(2)
    } else {
        ExitCode::from(1)
    }
}

/// Writes a text file atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    use std::io::Write;
    psns::io::write_atomic(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| Error::io(format!("writing {}", path.display()), e))
    })
}
