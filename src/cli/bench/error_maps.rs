//! The failure maps of `psns bench demosaic`: per-pixel AoLP error, indexed into an 8-colour
//! palette, pooled and cropped for the overview and detail pictures.

use super::demosaic::{DOLP_THRESHOLD, SAT_RADIUS};
use super::scenes::Scene;
use crate::cli::vis;
use psns::angle::SensorAngle;
use psns::error::{Error, Result};
use psns::image::{Image, StokesImage};
use psns::io;
use rayon::prelude::*;
use std::path::Path;

/// Axial AoLP error (degrees) per pixel, NaN where the true DoLP ≤ threshold.
pub fn aolp_error_map(est: &StokesImage, truth: &StokesImage) -> Image<f32> {
    let (w, h) = (truth.width(), truth.height());
    let mut out = Image::new(w, h);
    out.data.par_iter_mut().enumerate().for_each(|(i, o)| {
        let (t0, t1, t2) = (
            truth.s0.data[i] as f64,
            truth.s1.data[i] as f64,
            truth.s2.data[i] as f64,
        );
        let dt = if t0 > 0.0 { t1.hypot(t2) / t0 } else { 0.0 };
        *o = if dt > DOLP_THRESHOLD {
            SensorAngle::from_stokes(est.s1.data[i] as f64, est.s2.data[i] as f64)
                .diff(SensorAngle::from_stokes(t1, t2)) as f32
        } else {
            f32::NAN
        };
    });
    out
}

/// Error bins of the stability maps, degrees (upper edges).
pub const ERROR_BINS_DEG: [f64; 5] = [1.0, 2.0, 5.0, 10.0, 20.0];

/// Palette index of an AoLP error: 1..=6 for the bins < 1°, 1–2, 2–5, 5–10, 10–20, ≥ 20°;
/// 0 (black) where not scored (NaN). Index 7 (white) separates panels.
pub fn error_index(e: f32) -> u8 {
    if !e.is_finite() {
        return 0;
    }
    1 + ERROR_BINS_DEG
        .iter()
        .position(|&b| (e as f64) < b)
        .unwrap_or(ERROR_BINS_DEG.len()) as u8
}

/// The stability-map palette: black, six viridis steps, white.
pub fn error_palette() -> [[u8; 3]; 8] {
    let mut p = [[0u8; 3]; 8];
    for (k, c) in p.iter_mut().enumerate().skip(1).take(6) {
        *c = vis::viridis((k - 1) as f64 / 5.0);
    }
    p[7] = [255, 255, 255];
    p
}

/// Writes an indexed-colour PNG (small files for maps with few colours).
pub fn write_png_indexed(path: &Path, img: &Image<u8>, palette: &[[u8; 3]]) -> Result<()> {
    let err = |e: png::EncodingError| match e {
        png::EncodingError::IoError(e) => Error::io(format!("writing {}", path.display()), e),
        e => Error::Format(format!("writing {}: {e}", path.display())),
    };
    io::write_atomic(path, |w| {
        let mut enc = png::Encoder::new(w, img.width as u32, img.height as u32);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(palette.iter().flatten().copied().collect::<Vec<u8>>());
        enc.set_compression(png::Compression::High);
        let mut wr = enc.write_header().map_err(err)?;
        wr.write_image_data(&img.data).map_err(err)?;
        wr.finish().map_err(err)
    })
}

/// Places index images side by side (`gap` columns of `fill`), top-aligned.
pub(super) fn hstack_idx(imgs: &[Image<u8>], gap: usize, fill: u8) -> Image<u8> {
    let h = imgs.iter().map(|i| i.height).max().unwrap_or(0);
    let w = imgs.iter().map(|i| i.width).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::from_vec(w, h, vec![fill; w * h]);
    let mut x0 = 0;
    for img in imgs {
        for r in 0..img.height {
            out.data[r * w + x0..r * w + x0 + img.width].copy_from_slice(img.row(r));
        }
        x0 += img.width + gap;
    }
    out
}

/// Stacks index images vertically (`gap` rows of `fill`), left-aligned.
pub(super) fn vstack_idx(imgs: &[Image<u8>], gap: usize, fill: u8) -> Image<u8> {
    let w = imgs.iter().map(|i| i.width).max().unwrap_or(0);
    let h = imgs.iter().map(|i| i.height).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::from_vec(w, h, vec![fill; w * h]);
    let mut y0 = 0;
    for img in imgs {
        for r in 0..img.height {
            out.data[(y0 + r) * w..(y0 + r) * w + img.width].copy_from_slice(img.row(r));
        }
        y0 += img.height + gap;
    }
    out
}

/// Max-pools an error map by `factor` (NaN ignored; NaN when the whole block is), so 1-pixel
/// failures stay visible in a small picture.
pub fn max_pool(img: &Image<f32>, factor: usize) -> Image<f32> {
    let f = factor.max(1);
    let (w, h) = (img.width / f, img.height / f);
    let mut out = Image::from_vec(w, h, vec![f32::NAN; w * h]);
    out.data
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            for (c, o) in row.iter_mut().enumerate() {
                let mut m = f32::NAN;
                for dr in 0..f {
                    for dc in 0..f {
                        let v = *img.get(r * f + dr, c * f + dc);
                        // max of the finite values (m starts as NaN: the first finite value wins)
                        if v.is_finite() && (m.is_nan() || v > m) {
                            m = v;
                        }
                    }
                }
                *o = m;
            }
        });
    out
}

pub(super) fn crop(img: &Image<f32>, r0: usize, c0: usize, size: usize) -> Image<f32> {
    let s = size.min(img.width - c0).min(img.height - r0);
    let mut out = Image::new(s, s);
    for r in 0..s {
        out.data[r * s..(r + 1) * s].copy_from_slice(&img.row(r0 + r)[c0..c0 + s]);
    }
    out
}

pub(super) fn index_map(img: &Image<f32>) -> Image<u8> {
    Image::from_vec(
        img.width,
        img.height,
        img.data.iter().map(|&e| error_index(e)).collect(),
    )
}

/// Native-resolution crop (top-left row, column) shown under the max-pooled map of a scene:
/// the crossing of the straight wire and the mast for `occluder-edge`; centred on the leftmost
/// clipped pixel (the rim of the saturated region) otherwise.
pub(super) fn detail_origin(
    scene: Scene,
    w: usize,
    h: usize,
    size: usize,
    sat: &[bool],
) -> (usize, usize) {
    let (r, c) = match scene {
        Scene::OccluderEdge => (0.30 * h as f64, 0.62 * w as f64),
        _ => {
            let k = (0..w)
                .flat_map(|c| (0..h).map(move |r| (r, c)))
                .find(|&(r, c)| sat[r * w + c])
                .unwrap_or((h / 2, w / 2));
            (k.0 as f64, k.1 as f64 + SAT_RADIUS as f64)
        }
    };
    let r = (r - size as f64 / 2.0).clamp(0.0, (h - size) as f64) as usize;
    let c = (c - size as f64 / 2.0).clamp(0.0, (w - size) as f64) as usize;
    (r & !1, c & !1)
}
