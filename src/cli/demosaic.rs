//! `psns demosaic`: S0, S1, S2, DoLP and AoLP from a raw PNG/TIFF mosaic or a stream frame,
//! written as `.npy` arrays and pictures.

use super::args::finite;
use super::output::{check_memory, memory_available, memory_need, OutDir, DEMOSAIC_FILES};
use super::{vis, write_text};
use clap::Args;
use psns::demosaic::{full_chain, Method, PolarImages};
use psns::image::Image;
use psns::sensor::mosaic::MosaicLayout;
use psns::{io, Error, Result};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn parse_method(s: &str) -> std::result::Result<Method, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn parse_layout(s: &str) -> std::result::Result<MosaicLayout, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

/// Options of `psns demosaic`.
#[derive(Args)]
pub struct DemosaicArgs {
    /// Raw PNG/TIFF or psns stream file.
    pub(crate) input: PathBuf,
    /// Method: superpixel, bilinear, bicubic, ppid, newton, eari.
    #[arg(long, default_value = "bilinear", value_parser = parse_method)]
    pub(crate) method: Method,
    /// Output directory: new, empty, or a previous psns run's (replaced whole when this run
    /// has written everything).
    #[arg(long, default_value = "out")]
    pub(crate) out: PathBuf,
    /// Frame index (stream input).
    #[arg(long, value_parser = super::args::whole)]
    pub(crate) frame: Option<u64>,
    /// Mosaic layout of a PNG/TIFF input, e.g. "90,45/135,0".
    #[arg(long, default_value = "90,45/135,0", value_parser = parse_layout)]
    pub(crate) layout: MosaicLayout,
    /// Also write dolp_debiased.npy, corrected for the Rice bias with this noise σ of S1/S2 (DN).
    #[arg(long, value_parser = finite, allow_negative_numbers = true, value_name = "SIGMA_DN")]
    pub(crate) dolp_debias: Option<f64>,
}

/// Runs `psns demosaic`.
pub fn run(a: DemosaicArgs) -> anyhow::Result<()> {
    let opts = DemosaicOptions {
        input: a.input,
        method: a.method,
        out: a.out,
        frame: a.frame,
        layout: a.layout,
        debias_sigma: a.dolp_debias,
    };
    for f in demosaic_to_dir(&opts)? {
        eprintln!("wrote {f}");
    }
    Ok(())
}

/// Options of `psns demosaic`.
#[derive(Clone, Debug, PartialEq)]
pub struct DemosaicOptions {
    /// Raw PNG/TIFF (mosaic codes) or a psns frame stream.
    pub input: PathBuf,
    /// Method.
    pub method: Method,
    /// Output directory.
    pub out: PathBuf,
    /// Frame index when the input is a stream (default: the first intact frame).
    pub frame: Option<u64>,
    /// Mosaic layout of the input (default IMX250MZR `90,45/135,0`; a stream's header wins).
    pub layout: MosaicLayout,
    /// Also write `dolp_debiased.npy`, √max(0, S1² + S2² − 2σ²)/S0 with this σ of S1 and S2 in
    /// DN (the Rice bias correction of `demosaic.md` §4).
    pub debias_sigma: Option<f64>,
}

/// A raw mosaic loaded from a file or a stream.
#[derive(Clone, Debug)]
pub struct LoadedRaw {
    /// Codes.
    pub codes: Image<u16>,
    /// Layout (the stream's header, else the caller's).
    pub layout: MosaicLayout,
    /// Black level in code units (stream metadata; 0 for PNG/TIFF).
    pub black_level: f64,
    /// Significant bits (stream header; 8 or 16 for PNG/TIFF).
    pub bits: u8,
    /// Frame index for stream input.
    pub frame: Option<u64>,
}

/// Reads a raw PNG/TIFF or a psns frame stream (recognised by its magic bytes).
pub fn load_raw(input: &Path, layout: MosaicLayout, frame: Option<u64>) -> Result<LoadedRaw> {
    // a FIFO (or other non-file) can be read only once: it is taken as a stream, unpeeked
    if std::fs::metadata(input).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return load_stream(input, frame);
    }
    let mut head = [0u8; 8];
    {
        use std::io::Read;
        let mut f = std::fs::File::open(input).map_err(|e| Error::input(input, e))?;
        let n = f.read(&mut head).map_err(|e| Error::input(input, e))?;
        if n < 8 {
            return Err(Error::Format(format!(
                "{}: too short for a raw image or stream ({n} bytes)",
                input.display()
            )));
        }
    }
    if head == psns::stream::FILE_MAGIC {
        return load_stream(input, frame);
    }
    let is_image =
        head.starts_with(b"\x89PNG") || head.starts_with(b"II*\0") || head.starts_with(b"MM\0*");
    if !is_image {
        return Err(Error::Format(format!(
            "{}: not a PNG, TIFF or psns stream",
            input.display()
        )));
    }
    let g = io::read_gray(input)?;
    if frame.is_some() {
        return Err(Error::Invalid(
            "--frame applies to stream input only".into(),
        ));
    }
    Ok(LoadedRaw {
        codes: g.image,
        layout,
        black_level: 0.0,
        bits: g.bits,
        frame: None,
    })
}

fn load_stream(input: &Path, frame: Option<u64>) -> Result<LoadedRaw> {
    let ex = psns::stream::find_frame(crate::cli::open_input(input)?, frame)?;
    let h = &ex.header;
    // the black level is in DN of the payload; MSB-aligned payloads are unpacked to LSB
    let black = if h.msb_aligned {
        ex.meta.black_level / 2f64.powi(16 - h.bits_valid as i32)
    } else {
        ex.meta.black_level
    };
    Ok(LoadedRaw {
        codes: Image::from_vec(h.width as usize, h.height as usize, ex.codes),
        layout: h.layout,
        black_level: black,
        bits: h.bits_valid,
        frame: Some(ex.meta.index),
    })
}

/// Demosaics codes minus a black level (u16 directly when the black level is 0).
pub fn demosaic_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    method: Method,
) -> Result<PolarImages> {
    if black_level == 0.0 {
        full_chain(codes, layout, method)
    } else {
        let b = black_level as f32;
        let f = Image::from_vec(
            codes.width,
            codes.height,
            codes.data.par_iter().map(|&v| v as f32 - b).collect(),
        );
        full_chain(&f, layout, method)
    }
}

/// `psns demosaic`: writes s0/s1/s2/dolp/aolp `.npy` plus visualisations; returns the files.
///
/// Visualisations: `s0.png` (grey, 99.9 % quantile white), `dolp.png` (viridis over [0, 1]),
/// `aolp.png` (cyclic hue), `aolp_dolp.png` (AoLP as hue, DoLP as brightness, full at 0.5);
/// `demosaic.json` records the input, method, layout, black level and time.
pub fn demosaic_to_dir(opts: &DemosaicOptions) -> Result<Vec<String>> {
    if let Some(sigma) = opts.debias_sigma {
        psns::error::check_range("dolp-debias", sigma, 0.0, 1e6)?;
    }
    let raw = load_raw(&opts.input, opts.layout, opts.frame)?;
    psns::demosaic::check_raw(&raw.codes)?;
    // peak resident 27 B/pixel (bilinear) to 73 B/pixel (eari), measured on 3000² mosaics
    check_memory(
        &format!(
            "demosaicing {} x {} pixels",
            raw.codes.width, raw.codes.height
        ),
        memory_need(raw.codes.data.len(), 80),
        memory_available(),
    )?;
    let outdir = OutDir::begin(&opts.out, DEMOSAIC_FILES)?;
    let t0 = Instant::now();
    let p = demosaic_codes(&raw.codes, raw.black_level, raw.layout, opts.method)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut files = Vec::new();
    let mut put = |name: &str| {
        files.push(opts.out.join(name).display().to_string());
        outdir.path().join(name)
    };
    io::write_npy(&put("s0.npy"), &p.stokes.s0)?;
    io::write_npy(&put("s1.npy"), &p.stokes.s1)?;
    io::write_npy(&put("s2.npy"), &p.stokes.s2)?;
    io::write_npy(&put("dolp.npy"), &p.dolp)?;
    io::write_npy(&put("aolp.npy"), &p.aolp_deg)?;
    if let Some(sigma) = opts.debias_sigma {
        let d = psns::stokes::debiased_dolp_image(&p.stokes, sigma as f32);
        io::write_npy(&put("dolp_debiased.npy"), &d)?;
    }
    let white = vis::quantile(&p.stokes.s0, 0.999);
    io::write_png_gray8(&put("s0.png"), &vis::gray8(&p.stokes.s0, white))?;
    io::write_png_rgb8(&put("dolp.png"), &vis::dop_rgb(&p.dolp, None))?;
    io::write_png_rgb8(&put("aolp.png"), &vis::aop_rgb(&p.aolp_deg, None))?;
    io::write_png_rgb8(
        &put("aolp_dolp.png"),
        &vis::aolp_dolp_rgb(&p.aolp_deg, &p.dolp, 0.5),
    )?;
    let meta = serde_json::json!({
        "input": opts.input.display().to_string(),
        "frame": raw.frame,
        "method": opts.method.name(),
        "layout": raw.layout.to_string(),
        "width": raw.codes.width,
        "height": raw.codes.height,
        "bits": raw.bits,
        "black_level": raw.black_level,
        "aolp_units": "degrees, [0, 180), from +x (columns) toward +y (rows, down)",
        "demosaic_ms": ms,
        "dolp_debias_sigma_dn": opts.debias_sigma,
    });
    write_text(
        &put("demosaic.json"),
        &serde_json::to_string_pretty(&meta).expect("json"),
    )?;
    outdir.commit()?;
    Ok(files)
}
