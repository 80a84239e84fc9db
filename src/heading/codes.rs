//! From raw codes to an estimate: saturation masks, sampled demosaics, and the entry points the
//! front-ends call.

use super::*;

/// Marks as unusable (DoLP = NaN) every pixel within one pixel of a raw code at `full_scale`:
/// a clipped channel gives a false, structured AoLP that the estimator cannot tell from sky, and
/// interpolating demosaics spread it to the neighbours. Returns how many pixels were masked.
pub fn mask_saturated(dolp: &mut Image<f32>, codes: &Image<u16>, full_scale: u16) -> usize {
    let (w, h) = (codes.width, codes.height);
    let mut masked = 0;
    let mut bad = vec![false; w * h];
    for r in 0..h {
        for c in 0..w {
            if codes.data[r * w + c] >= full_scale {
                for rr in r.saturating_sub(1)..(r + 2).min(h) {
                    for cc in c.saturating_sub(1)..(c + 2).min(w) {
                        bad[rr * w + cc] = true;
                    }
                }
            }
        }
    }
    for (d, b) in dolp.data.iter_mut().zip(bad) {
        if b {
            *d = f32::NAN;
            masked += 1;
        }
    }
    masked
}

/// The intrinsics of a frame read as every `k`-th 2 × 2 superpixel
/// ([`crate::demosaic::superpixel::superpixel_sampled`]): (width / k) × (height / k) pixels of
/// k times the pitch, output pixel (j, i) centred on mosaic position (k j + ½, k i + ½), so the
/// principal point moves to ((c₀ − ½)/k, (r₀ − ½)/k). Same focal length, projection and lens.
pub fn sampled_intrinsics(i: &Intrinsics, k: usize) -> Intrinsics {
    let (c0, r0) = i.principal();
    let kf = k as f64;
    Intrinsics {
        width: i.width / k,
        height: i.height / k,
        pixel_pitch_um: i.pixel_pitch_um * kf,
        principal_point: Some([(c0 - 0.5) / kf, (r0 - 0.5) / kf]),
        ..*i
    }
}

/// The superpixel sampling step for a frame of `width` × `height`: the largest even k with
/// (width / k)(height / k) ≥ [`EIGEN_SAMPLES`], or `None` when that is below 4 (frames under
/// about 640 000 pixels, which the estimators read at every 4th pixel or closer anyway).
pub fn superpixel_step(width: usize, height: usize) -> Option<usize> {
    let s = ((width * height) as f64 / EIGEN_SAMPLES).sqrt().floor() as usize;
    let k = s - s % 2;
    (k >= 4).then_some(k)
}

/// [`mask_saturated`] for a superpixel-sampled view (`k` as in
/// [`crate::demosaic::superpixel::superpixel_sampled`]): a sample is unusable when a code at
/// `full_scale` lies in its 2 × 2 block or one pixel around it. Returns how many pixels of the
/// whole frame are within one pixel of a code at full scale (what [`mask_saturated`] would mask).
pub fn mask_saturated_sampled(
    dolp: &mut Image<f32>,
    codes: &Image<u16>,
    full_scale: u16,
    k: usize,
) -> usize {
    let (w, h) = (codes.width, codes.height);
    // whether a code in rows r0..r1, columns c0..c1 (clamped to the frame) reads full scale
    let any_full = |r0: usize, r1: usize, c0: usize, c1: usize| {
        let (r1, c1) = (r1.min(h), c1.min(w));
        (r0..r1).any(|r| {
            codes.row(r)[c0.min(c1)..c1]
                .iter()
                .any(|&v| v >= full_scale)
        })
    };
    // which rows hold a code at full scale, by a maximum per row the compiler vectorises (an
    // early-exit search per code does not): most frames have none, and a sun disc a few rows
    let row_full: Vec<bool> = codes
        .data
        .par_chunks(w.max(1))
        .map(|row| row.iter().fold(0u16, |m, &v| m.max(v)) >= full_scale)
        .collect();
    if !row_full.contains(&true) {
        return 0;
    }
    let rows_full = |r0: usize, r1: usize| row_full[r0..r1.min(h)].contains(&true);
    for i in 0..dolp.height {
        let r = k * i;
        if !rows_full(r.saturating_sub(1), r + 3) {
            continue;
        }
        for j in 0..dolp.width {
            let c = k * j;
            if any_full(r.saturating_sub(1), r + 3, c.saturating_sub(1), c + 3) {
                dolp.data[i * dolp.width + j] = f32::NAN;
            }
        }
    }
    // the frame's count, row by row in parallel: the columns with a code at full scale in
    // rows r−1..r+1, widened by one column each side
    (0..h)
        .into_par_iter()
        .map(|r| {
            let (r0, r1) = (r.saturating_sub(1), (r + 2).min(h));
            if !rows_full(r0, r1) {
                return 0;
            }
            let mut col = vec![false; w];
            for rr in (r0..r1).filter(|&rr| row_full[rr]) {
                for (b, &v) in col.iter_mut().zip(codes.row(rr)) {
                    *b |= v >= full_scale;
                }
            }
            (0..w)
                .filter(|&c| col[c.saturating_sub(1)..(c + 2).min(w)].contains(&true))
                .count()
        })
        .sum()
}

/// Demosaics one mosaic (codes minus the black level) and masks the pixels next to a code at
/// full scale of `bits` (DoLP = NaN); returns the images and the number of masked pixels.
pub fn polar_from_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Method,
) -> Result<(PolarImages, usize)> {
    crate::demosaic::check_raw(codes)?;
    let full = ((1u32 << bits) - 1).min(65535) as u16;
    let mut p = demosaic_codes(codes, black_level, layout, demosaic)?;
    let saturated = mask_saturated(&mut p.dolp, codes, full);
    Ok((p, saturated))
}

/// The flat-field gains (1 / relative illumination, 0 where no light falls) of the four pixels
/// of every sampled block of [`superpixel_sampled_flat`], block by block in row-major order, each
/// block's as (row, column) of its pixels. Kept for the next call with the same intrinsics,
/// falloff and step: a stream's frames all share them, and evaluating the falloff anew cost a
/// quarter of a full-size frame's estimate.
fn sampled_gains(i: &Intrinsics, ri: RelativeIllumination, k: usize) -> std::sync::Arc<Vec<f32>> {
    type Key = (Intrinsics, RelativeIllumination, usize);
    static CACHE: std::sync::Mutex<Option<(Key, std::sync::Arc<Vec<f32>>)>> =
        std::sync::Mutex::new(None);
    let key = (*i, ri, k);
    let mut c = CACHE.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((kk, g)) = c.as_ref() {
        if *kk == key {
            return g.clone();
        }
    }
    let (ow, oh) = (i.width / k, i.height / k);
    let mut g = vec![0f32; ow * oh * 4];
    g.par_chunks_mut((ow * 4).max(1))
        .enumerate()
        .for_each(|(bi, row)| {
            for (n, v) in row.iter_mut().enumerate() {
                let (bj, dr, dc) = (n / 4, (n / 2) % 2, n % 2);
                let f = ri.factor(i, (k * bj + dc) as f64, (k * bi + dr) as f64);
                *v = if f > 0.0 { (1.0 / f) as f32 } else { 0.0 };
            }
        });
    let g = std::sync::Arc::new(g);
    *c = Some((key, g.clone()));
    g
}

/// [`polar_from_codes`] for what the estimators read: with no `--demosaic` and a frame large
/// enough ([`superpixel_step`]), every k-th superpixel only, with the intrinsics of that sampled
/// view ([`sampled_intrinsics`]) in the returned setup; otherwise the whole frame.
pub fn polar_for_estimate(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Option<Method>,
    setup: &HeadingSetup,
) -> Result<(PolarImages, usize, HeadingSetup)> {
    let k = superpixel_step(codes.width, codes.height);
    match (demosaic, k) {
        (None, Some(k)) => {
            let full = ((1u32 << bits) - 1).min(65535) as u16;
            // flat-fielded pixel by pixel: a superpixel's four pixels see different falloff
            // (on a fisheye near its rim, a few % from one pixel to the next), which otherwise
            // reads as polarization; S0 is then flat, so the intensity vote takes no falloff
            let ri = setup.relative_illumination;
            let mut p = match ri {
                RelativeIllumination::None => {
                    superpixel_sampled(codes, layout, k, black_level as f32)?
                }
                _ => {
                    let g = sampled_gains(&setup.intrinsics, ri, k);
                    let ow = codes.width / k;
                    // row k i + dr, column k j + dc (dr, dc in 0..2) of block (i, j)
                    superpixel_sampled_flat(codes, layout, k, black_level as f32, |r, c| {
                        g[(((r / k) * ow + c / k) * 2 + r % k) * 2 + c % k]
                    })?
                }
            };
            let saturated = mask_saturated_sampled(&mut p.dolp, codes, full, k);
            let mut s = *setup;
            s.intrinsics = sampled_intrinsics(&setup.intrinsics, k);
            s.step = 1;
            s.relative_illumination = RelativeIllumination::None;
            Ok((p, saturated, s))
        }
        (d, _) => {
            let (p, saturated) = polar_from_codes(
                codes,
                black_level,
                layout,
                bits,
                d.unwrap_or(Method::Bilinear),
            )?;
            Ok((p, saturated, *setup))
        }
    }
}

/// The estimate from one mosaic: demosaic (see [`polar_for_estimate`]), mask clipped pixels,
/// estimate. `mask`, if given, is a sky mask of the frame (the mosaic's size, nonzero = sky;
/// [`sampled_mask`] when the frame is read as sampled superpixels). Without enough usable
/// pixels, or with the sun at the zenith, there is no estimate and [`CodesEstimate::reason`]
/// says why.
#[allow(clippy::too_many_arguments)] // the mosaic's own description, the method, the setup
pub fn estimate_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    bits: u8,
    demosaic: Option<Method>,
    method: HeadingMethod,
    setup: &HeadingSetup,
    mask: Option<&Image<u8>>,
) -> Result<CodesEstimate> {
    if let Some(m) = mask {
        if (m.width, m.height) != (codes.width, codes.height) {
            return Err(Error::Invalid(format!(
                "the mask is {} x {} pixels but the frame {} x {}: a mask has the frame's size",
                m.width, m.height, codes.width, codes.height
            )));
        }
    }
    let (p, saturated, setup) =
        polar_for_estimate(codes, black_level, layout, bits, demosaic, setup)?;
    let sampled;
    let mask = match (mask, superpixel_step(codes.width, codes.height)) {
        (Some(m), Some(k)) if p.dolp.width != codes.width => {
            sampled = sampled_mask(m, k);
            Some(&sampled)
        }
        (m, _) => m,
    };
    let view = PolarView {
        aolp_deg: &p.aolp_deg,
        dolp: &p.dolp,
        s0: Some(&p.stokes.s0),
        mask,
    };
    match estimate_heading_info(method, &view, &setup) {
        Ok((e, info)) => Ok(CodesEstimate {
            estimate: Some(e),
            saturated,
            info,
            reason: None,
        }),
        // too few usable pixels (saturated, unpolarized) or a sun at the zenith: no heading,
        // zero confidence
        Err(Error::Undetermined(m)) => Ok(CodesEstimate {
            estimate: None,
            saturated,
            info: None,
            reason: Some(m),
        }),
        // too few pixels: saturation, when it took more than a few, is the reason to give
        Err(Error::TooFewPixels(m)) => {
            let pixels = (codes.width * codes.height) as u64;
            let reason = match crate::sensor::saturation_warning(saturated as u64, pixels) {
                Some(w) => format!(
                    "heading: the frame is saturated: {w} (masked: within one pixel of a code \
                     at full scale); {}",
                    m.strip_prefix("heading: ").unwrap_or(&m)
                ),
                None => m,
            };
            Ok(CodesEstimate {
                estimate: None,
                saturated,
                info: None,
                reason: Some(reason),
            })
        }
        Err(e) => Err(e),
    }
}

/// The estimate from one mosaic ([`estimate_codes`]).
#[derive(Clone, Debug)]
pub struct CodesEstimate {
    /// The estimate; `None` when too few pixels are usable or the sun is at the zenith
    /// ([`check_sun_defines_yaw`]).
    pub estimate: Option<HeadingEstimate>,
    /// Pixels masked as within one pixel of a code at full scale.
    pub saturated: usize,
    /// The model fit's details (`--method model-fit`).
    pub info: Option<ModelFitInfo>,
    /// Why there is no estimate.
    pub reason: Option<String>,
}
