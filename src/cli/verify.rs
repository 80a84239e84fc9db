//! `psns verify` (check a frame stream; exit 0 only if clean) and `psns extract` (one frame of a
//! stream as PNG, TIFF and JSON).

use super::{Aborted, NotClean, Unfinished};
use clap::Args;
use psns::image::Image;
use psns::io::{create_dir, open_input};
use psns::options::parsed;
use psns::sensor::packing::PixelFormat;
use psns::stream::{FindOptions, RecoverHint, VerifyStatus};
use psns::{io, Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Degraded mode for a stream whose file header is damaged (`--recover` and the geometry).
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct RecoverArgs {
    /// Degraded mode for a damaged file header: find the frames by their magic and CRCs and infer
    /// the geometry from the stride between frames, the payload CRC and the header fields that
    /// still agree (docs/stream-format.md §5). Always reported as damaged.
    #[arg(long)]
    recover: bool,
    /// With --recover: frame width in pixels, if it cannot be inferred.
    #[arg(long, requires = "recover", value_parser = clap::value_parser!(u32).range(1..=65535))]
    width: Option<u32>,
    /// With --recover: frame height in pixels, if it cannot be inferred.
    #[arg(long, requires = "recover", value_parser = clap::value_parser!(u32).range(1..=65535))]
    height: Option<u32>,
    /// With --recover: payload pixel format (mono8, mono12p, mono12packed, mono16).
    #[arg(long, requires = "recover", value_parser = parsed::<PixelFormat>)]
    pixel_format: Option<PixelFormat>,
}

impl RecoverArgs {
    fn hint(&self) -> Option<RecoverHint> {
        self.recover.then_some(RecoverHint {
            width: self.width,
            height: self.height,
            pixel_format: self.pixel_format,
        })
    }
}

/// Exit codes of `psns verify`, shown by `psns verify --help`.
const VERIFY_EXIT_CODES: &str = "Exit status: 0 clean (one stream, nothing damaged, finished: the last frame carries \
the LAST flag or the header frame count matches); 1 damaged (corrupt, truncated or dropped frames between intact \
ones, skipped bytes, a frame-count mismatch, a cut-short end of a stream whose header counts its frames, a damaged \
file header, or more than one stream in the input: concatenated files or a producer restart); 2 bad input (usage \
error, not a psns stream, or --recover cannot infer the geometry); 3 intact but unfinished (header frame count 0 \
and no LAST flag: the producer was killed, also while writing its last record, which is then cut short, or is \
still writing; psns recover makes a finished stream of its intact frames) or aborted (the producer marked the \
stream aborted, with its reason: bad input, an I/O error or a signal).";

/// Options of `psns verify`.
#[derive(Args)]
#[command(after_help = VERIFY_EXIT_CODES)]
pub struct VerifyArgs {
    /// Stream file, FIFO, or - for stdin.
    file: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    recover: RecoverArgs,
}

/// Options of `psns extract`.
#[derive(Args)]
#[command(
    after_help = "If the input holds more than one stream (concatenated files or a producer restart), \
the first stream holding the frame is used and a note on stderr says which (\"frame N found in stream copy \
1 of 2 (byte offset ...)\"); a regular file is read to its end to count the streams."
)]
pub struct ExtractArgs {
    /// Stream file, FIFO, or - for stdin.
    file: PathBuf,
    /// Frame index.
    #[arg(long, value_parser = psns::options::whole)]
    frame: u64,
    /// Output directory.
    #[arg(long, default_value = ".")]
    out: PathBuf,
    #[command(flatten)]
    recover: RecoverArgs,
}

/// Adds the hint to use `--recover` to the error of a damaged file header.
fn hint_recover(e: Error, cmd: &str) -> anyhow::Error {
    if matches!(e, Error::HeaderDamaged(_)) {
        anyhow::anyhow!(
            "{e}; its frames may still be readable in degraded mode: psns {cmd} --recover \
             (see docs/stream-format.md)"
        )
    } else {
        anyhow::Error::new(e)
    }
}

/// Runs `psns verify`.
pub fn run_verify(a: VerifyArgs) -> anyhow::Result<()> {
    let hint = a.recover.hint();
    let rep = psns::stream::verify_with(open_input(&a.file)?, hint.as_ref())
        .map_err(|e| hint_recover(e, "verify"))?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rep)?)?;
    } else {
        write!(out, "{rep}")?;
    }
    out.flush()?;
    match rep.status {
        VerifyStatus::Clean => Ok(()),
        VerifyStatus::Unfinished => Err(anyhow::Error::new(Unfinished)),
        VerifyStatus::Aborted => Err(anyhow::Error::new(Aborted(
            rep.aborted.clone().unwrap_or_default(),
        ))),
        VerifyStatus::Damaged => Err(anyhow::Error::new(NotClean)),
    }
}

/// Runs `psns extract`.
pub fn run_extract(a: ExtractArgs) -> anyhow::Result<()> {
    let files = extract_to_dir_with(&a.file, a.frame, &a.out, a.recover.hint().as_ref())
        .map_err(|e| hint_recover(e, "extract"))?;
    for f in files {
        eprintln!("wrote {f}");
    }
    Ok(())
}

/// `psns extract`: one frame of a stream as `frame_N.png` (8- or 16-bit grey holding the values),
/// `frame_N.tiff` (16-bit) and `frame_N.json` (file header and frame metadata); in degraded mode
/// with `Some(hint)`. Notes on stderr which stream copy the frame came from when the input holds
/// several, and how a damaged header was replaced.
pub fn extract_to_dir_with(
    input: &Path,
    frame: u64,
    dir: &Path,
    recover: Option<&RecoverHint>,
) -> Result<Vec<String>> {
    let regular =
        input.as_os_str() != "-" && std::fs::metadata(input).is_ok_and(|m| m.file_type().is_file());
    let opts = FindOptions {
        recover,
        count_copies: regular,
    };
    let ex = psns::stream::find_frame_with(open_input(input)?, Some(frame), opts)?;
    if let Some(r) = &ex.recovered {
        eprintln!("psns: DEGRADED MODE: {r}");
    }
    let loc = ex.location;
    if loc.copy > 1 || loc.copies.is_some_and(|c| c > 1) {
        eprintln!(
            "psns: note: frame {frame} found in stream copy {}{} (byte offset {}); the input holds \
             more than one stream (concatenated files or a producer restart)",
            loc.copy,
            loc.copies.map_or(String::new(), |c| format!(" of {c}")),
            loc.offset
        );
    }
    create_dir(dir)?;
    let (w, h) = (ex.header.width as usize, ex.header.height as usize);
    let img = Image::from_vec(w, h, ex.codes.clone());
    let mut files = Vec::new();
    let png = dir.join(format!("frame_{frame}.png"));
    if ex.header.bits_valid <= 8 && !ex.header.msb_aligned {
        let g = Image::from_vec(w, h, ex.codes.iter().map(|&v| v as u8).collect());
        io::write_png_gray8(&png, &g)?;
    } else {
        io::write_png_gray16(&png, &img)?;
    }
    files.push(png.display().to_string());
    let tiff = dir.join(format!("frame_{frame}.tiff"));
    io::write_tiff_u16(&tiff, &img)?;
    files.push(tiff.display().to_string());
    let json = dir.join(format!("frame_{frame}.json"));
    let text = serde_json::to_string_pretty(&ex).expect("metadata serializes");
    io::write_atomic(&json, |wr| {
        wr.write_all(text.as_bytes())
            .map_err(|e| Error::io("writing frame json", e))
    })?;
    files.push(json.display().to_string());
    Ok(files)
}
