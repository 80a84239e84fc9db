//! `psns verify` (check a frame stream; exit 0 only if clean) and `psns extract` (one frame of a
//! stream as PNG, TIFF and JSON).

use super::{create_dir, open_input, NotClean};
use clap::Args;
use psns::image::Image;
use psns::{io, Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Options of `psns verify`.
#[derive(Args)]
pub struct VerifyArgs {
    /// Stream file, FIFO, or - for stdin.
    file: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// Options of `psns extract`.
#[derive(Args)]
pub struct ExtractArgs {
    /// Stream file, FIFO, or - for stdin.
    file: PathBuf,
    /// Frame index.
    #[arg(long)]
    frame: u64,
    /// Output directory.
    #[arg(long, default_value = ".")]
    out: PathBuf,
}

/// Runs `psns verify`.
pub fn run_verify(a: VerifyArgs) -> anyhow::Result<()> {
    let rep = psns::stream::verify(open_input(&a.file)?)?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rep)?)?;
    } else {
        write!(out, "{rep}")?;
    }
    if !rep.clean() {
        return Err(anyhow::Error::new(NotClean));
    }
    Ok(())
}

/// Runs `psns extract`.
pub fn run_extract(a: ExtractArgs) -> anyhow::Result<()> {
    for f in extract_to_dir(&a.file, a.frame, &a.out)? {
        eprintln!("wrote {f}");
    }
    Ok(())
}

/// `psns extract`: one frame of a stream as `frame_N.png` (8- or 16-bit grey holding the values),
/// `frame_N.tiff` (16-bit) and `frame_N.json` (file header and frame metadata).
pub fn extract_to_dir(input: &Path, frame: u64, dir: &Path) -> Result<Vec<String>> {
    let ex = psns::stream::extract_frame(open_input(input)?, frame)?;
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
