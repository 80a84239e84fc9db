//! File formats at the edge of the library: `.npy` arrays, 8/16-bit PNG, 16-bit TIFF, and
//! atomic file writes (write to a temporary name in the same directory, then rename, so a reader
//! never sees a partial file and a failed run leaves nothing behind).

use crate::error::{Error, Result};
use crate::image::Image;
use crate::sensor::mosaic::MosaicLayout;
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// Writes a file atomically: `body` writes into a temporary file next to `path`, which is renamed
/// over `path` only if `body` succeeds.
pub fn write_atomic<F>(path: &Path, body: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
{
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty());
    let name = path.file_name().ok_or_else(|| {
        Error::Invalid(format!("output path {} has no file name", path.display()))
    })?;
    let tmp: PathBuf = dir.unwrap_or(Path::new(".")).join(format!(
        ".{}.tmp-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let ctx = || format!("writing {}", path.display());
    let result = (|| {
        let f = File::create(&tmp).map_err(|e| Error::io(ctx(), e))?;
        let mut w = BufWriter::with_capacity(1 << 20, f);
        body(&mut w)?;
        w.flush().map_err(|e| Error::io(ctx(), e))?;
        Ok(())
    })();
    match result {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| Error::io(ctx(), e)),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(format!("writing {}", path.display()), e)
}

/// Element types that `.npy` files can hold here.
pub trait NpyElement: bytemuck::Pod {
    /// numpy dtype descriptor, e.g. `<f4`.
    const DESCR: &'static str;
    /// Little-endian bytes of one element.
    fn write_le(self, out: &mut Vec<u8>);
}
impl NpyElement for f32 {
    const DESCR: &'static str = "<f4";
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
}
impl NpyElement for f64 {
    const DESCR: &'static str = "<f8";
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
}
impl NpyElement for u16 {
    const DESCR: &'static str = "<u2";
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
}
impl NpyElement for u8 {
    const DESCR: &'static str = "|u1";
    fn write_le(self, out: &mut Vec<u8>) {
        out.push(self);
    }
}

/// Encodes an image as an NPY v1.0 file (C order, shape (rows, columns)).
///
/// ```
/// let img = psns::image::Image::from_vec(3, 2, vec![0f32; 6]);
/// let b = psns::io::npy_bytes(&img);
/// assert_eq!(&b[..6], b"\x93NUMPY");
/// assert_eq!((b.len() - 24) % 64, 0); // header padded to 64 bytes, 6 f32 of data
/// ```
pub fn npy_bytes<T: NpyElement>(img: &Image<T>) -> Vec<u8> {
    let mut out = npy_header(img);
    out.reserve(std::mem::size_of_val(&img.data[..]));
    for &v in &img.data {
        v.write_le(&mut out);
    }
    out
}

/// The `.npy` header (format 1.0) of `img`.
fn npy_header<T: NpyElement>(img: &Image<T>) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': ({}, {}), }}",
        T::DESCR,
        img.height,
        img.width
    );
    // magic(6) + version(2) + len(2) + dict + pad + '\n' is a multiple of 64
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let hlen = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(10 + hlen);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(hlen as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    out
}

/// Writes an image as `.npy` (atomically): the bytes of [`npy_bytes`], the data written
/// straight from the image on a little-endian host (no 20 MB copy per full-size plane).
pub fn write_npy<T: NpyElement>(path: &Path, img: &Image<T>) -> Result<()> {
    if cfg!(target_endian = "little") {
        let header = npy_header(img);
        let data: &[u8] = bytemuck::cast_slice(&img.data);
        write_atomic(path, |w| {
            w.write_all(&header)
                .and_then(|_| w.write_all(data))
                .map_err(io_err(path))
        })
    } else {
        let bytes = npy_bytes(img);
        write_atomic(path, |w| w.write_all(&bytes).map_err(io_err(path)))
    }
}

/// Reads a 2-D little-endian `<f4` `.npy` file (as written by [`write_npy`]).
pub fn read_npy_f32(path: &Path) -> Result<Image<f32>> {
    let mut b = Vec::new();
    File::open(path)
        .and_then(|mut f| f.read_to_end(&mut b))
        .map_err(|e| Error::io(format!("reading {}", path.display()), e))?;
    let bad = |m: &str| Error::Format(format!("{}: not a 2-D <f4 npy file ({m})", path.display()));
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err(bad("magic"));
    }
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(b.get(10..10 + hlen).ok_or_else(|| bad("header"))?)
        .map_err(|_| bad("header"))?;
    if !header.contains("'<f4'") || header.contains("'fortran_order': True") {
        return Err(bad("dtype"));
    }
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| bad("shape"))?;
    let dims: Vec<usize> = shape
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().map_err(|_| bad("shape")))
        .collect::<Result<_>>()?;
    if dims.len() != 2 {
        return Err(bad("shape"));
    }
    let data = &b[10 + hlen..];
    if data.len() != dims[0] * dims[1] * 4 {
        return Err(bad("size"));
    }
    let v = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(Image::from_vec(dims[1], dims[0], v))
}

fn png_encoder<'a>(
    w: &'a mut BufWriter<File>,
    width: usize,
    height: usize,
    color: png::ColorType,
    depth: png::BitDepth,
) -> png::Encoder<'a, &'a mut BufWriter<File>> {
    let mut enc = png::Encoder::new(w, width as u32, height as u32);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.set_compression(png::Compression::Fast);
    // Paeth on every row instead of Fast's adaptive choice (all five filters tried per row):
    // 22 % fewer instructions in render --raw's 13 PNGs for files within 6 % of the size
    // (docs/performance.md)
    enc.set_filter(png::Filter::Paeth);
    enc
}

fn png_write(
    path: &Path,
    width: usize,
    height: usize,
    color: png::ColorType,
    depth: png::BitDepth,
    bytes: &[u8],
) -> Result<()> {
    // a full disk or a failed write is an I/O error (exit 1), not a bad picture
    let perr = |e: png::EncodingError| match e {
        png::EncodingError::IoError(e) => Error::io(format!("writing {}", path.display()), e),
        e => Error::Format(format!("writing {}: {e}", path.display())),
    };
    write_atomic(path, |w| {
        let mut wr = png_encoder(w, width, height, color, depth)
            .write_header()
            .map_err(perr)?;
        wr.write_image_data(bytes).map_err(perr)?;
        wr.finish().map_err(perr)
    })
}

/// Writes an 8-bit greyscale PNG.
pub fn write_png_gray8(path: &Path, img: &Image<u8>) -> Result<()> {
    png_write(
        path,
        img.width,
        img.height,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &img.data,
    )
}

/// Writes a 16-bit greyscale PNG (values as given, big-endian in the file as PNG requires).
pub fn write_png_gray16(path: &Path, img: &Image<u16>) -> Result<()> {
    let mut bytes = vec![0u8; img.data.len() * 2];
    for (b, v) in bytes.chunks_exact_mut(2).zip(&img.data) {
        b.copy_from_slice(&v.to_be_bytes());
    }
    png_write(
        path,
        img.width,
        img.height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &bytes,
    )
}

/// Writes an 8-bit RGB PNG from `[r, g, b]` pixels.
pub fn write_png_rgb8(path: &Path, img: &Image<[u8; 3]>) -> Result<()> {
    png_write(
        path,
        img.width,
        img.height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        bytemuck::cast_slice(&img.data),
    )
}

/// A greyscale image read from PNG or TIFF: values and their bit depth (8 or 16).
#[derive(Clone, Debug)]
pub struct GrayImage {
    /// Pixel values.
    pub image: Image<u16>,
    /// 8 or 16.
    pub bits: u8,
}

/// The most pixels an input image may have: the same cap as a rendered frame.
pub const MAX_INPUT_PIXELS: u64 = 100_000_000;

/// Reads an 8- or 16-bit greyscale PNG or TIFF (format from the file's magic bytes) through the
/// `image` crate with decoding limits: at most [`MAX_INPUT_PIXELS`] pixels, 65 536 per side, and
/// the decoder's allocations capped, so a small file declaring a huge image is refused from its
/// header instead of exhausting memory. Colour, other depths and damaged files are
/// [`Error::Format`].
pub fn read_gray(path: &Path) -> Result<GrayImage> {
    let fmt = |m: String| Error::Format(format!("{}: {m}", path.display()));
    let mut reader = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| Error::input(path, e))?;
    // the largest accepted image at 16 bit, plus the decoder's own buffers
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_INPUT_PIXELS * 2 + (64 << 20));
    reader.limits(limits);
    let decoder = reader
        .into_decoder()
        .map_err(|e| fmt(format!("not a readable PNG or TIFF image ({e})")))?;
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    let pixels = w as u64 * h as u64;
    if pixels > MAX_INPUT_PIXELS || w > 65_536 || h > 65_536 {
        return Err(Error::Invalid(format!(
            "{}: {w} x {h} pixels is too large (allowed at most 65536 per side and {MAX_INPUT_PIXELS} pixels)",
            path.display()
        )));
    }
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| fmt(format!("cannot decode ({e})")))?;
    let (data, bits) = match img {
        image::DynamicImage::ImageLuma8(g) => {
            (g.into_raw().into_iter().map(u16::from).collect(), 8)
        }
        image::DynamicImage::ImageLuma16(g) => (g.into_raw(), 16),
        other => {
            return Err(fmt(format!(
                "expected a greyscale raw mosaic (8 or 16 bit), found {:?}",
                other.color()
            )))
        }
    };
    Ok(GrayImage {
        image: Image::from_vec(w as usize, h as usize, data),
        bits,
    })
}

/// Writes a 16-bit greyscale TIFF.
pub fn write_tiff_u16(path: &Path, img: &Image<u16>) -> Result<()> {
    let terr = |e: tiff::TiffError| match e {
        tiff::TiffError::IoError(e) => Error::io(format!("writing {}", path.display()), e),
        e => Error::Format(format!("writing {}: {e}", path.display())),
    };
    write_atomic(path, |w| {
        let mut enc = tiff::encoder::TiffEncoder::new(w).map_err(terr)?;
        enc.write_image::<tiff::encoder::colortype::Gray16>(
            img.width as u32,
            img.height as u32,
            &img.data,
        )
        .map_err(terr)
    })
}

/// Creates a directory and its parents.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(format!("creating {}", dir.display()), e))
}

/// Writes a text file atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| Error::io(format!("writing {}", path.display()), e))
    })
}

/// Opens a file, or stdin for `-`.
/// Send + Sync, so a reader kept across calls (the Python package's stream iterator) can hold
/// it; stdin is locked per read, which its large buffered reads make negligible.
pub fn open_input(path: &Path) -> Result<Box<dyn Read + Send + Sync>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(std::io::stdin()))
    } else {
        let f = File::open(path).map_err(|e| Error::input(path, e))?;
        if f.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(Error::input(path, std::io::ErrorKind::IsADirectory.into()));
        }
        Ok(Box::new(std::io::BufReader::with_capacity(1 << 20, f)))
    }
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
        let mut f = File::open(input).map_err(|e| Error::input(input, e))?;
        let n = f.read(&mut head).map_err(|e| Error::input(input, e))?;
        if n < 8 {
            return Err(Error::Format(format!(
                "{}: too short for a raw image or stream ({n} bytes)",
                input.display()
            )));
        }
    }
    if head == crate::stream::FILE_MAGIC {
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
    let g = read_gray(input)?;
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
    let ex = crate::stream::find_frame(open_input(input)?, frame)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_round_trip_and_png16() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::from_vec(3, 2, vec![1.0f32, 2.0, 3.5, -4.0, 0.0, 1e-7]);
        let p = dir.path().join("a.npy");
        write_npy(&p, &img).unwrap();
        assert_eq!(read_npy_f32(&p).unwrap(), img);
        let g = Image::from_vec(2, 2, vec![0u16, 1, 4095, 65535]);
        let p = dir.path().join("a.png");
        write_png_gray16(&p, &g).unwrap();
        let r = read_gray(&p).unwrap();
        assert_eq!((r.image, r.bits), (g.clone(), 16));
        let rgb = Image::from_vec(
            3,
            2,
            vec![
                [1u8, 2, 3],
                [255, 0, 7],
                [9, 9, 9],
                [0, 0, 0],
                [4, 5, 6],
                [200, 100, 50],
            ],
        );
        let p = dir.path().join("rgb.png");
        write_png_rgb8(&p, &rgb).unwrap();
        let back = image::open(&p).unwrap().into_rgb8();
        let px: Vec<[u8; 3]> = back.pixels().map(|p| p.0).collect();
        assert_eq!((back.width(), back.height(), px), (3, 2, rgb.data.clone()));
        let p = dir.path().join("a.tiff");
        write_tiff_u16(&p, &g).unwrap();
        assert_eq!(read_gray(&p).unwrap().image, g);
        // no temporary files left behind
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
    }

    #[test]
    fn failed_atomic_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.bin");
        let r = write_atomic(&p, |_| Err(Error::Invalid("boom".into())));
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
