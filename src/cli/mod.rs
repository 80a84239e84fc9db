//! The front-end of the `psns` binary: one module per command, and the file, terminal and chart
//! code around the library. The options it parses are the library's ([`psns::options`], shared
//! with the Python package); nothing here is physics.

pub mod bag;
pub mod bench;
pub mod convert;
pub mod dataset;
pub mod demosaic;
pub mod figures;
pub mod gige;
pub mod heading;
pub mod output;
pub mod poses;
pub mod progress;
pub mod recover;
pub mod render;
pub mod signals;
pub mod sky;
pub mod stream;
pub mod sun;
pub mod verify;
pub mod vis;

use psns::Error;
use std::process::ExitCode;

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

/// `psns verify` found an intact stream its producer marked aborted: exit code 3, with the reason.
#[derive(Debug)]
pub struct Aborted(pub String);
impl std::fmt::Display for Aborted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stream was aborted by its producer: {}", self.0)
    }
}
impl std::error::Error for Aborted {}

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
    if e.downcast_ref::<Unfinished>().is_some() || e.downcast_ref::<Aborted>().is_some() {
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
