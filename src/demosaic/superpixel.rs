//! Superpixel (2 x 2 block) Stokes: the four samples of each block are taken as I0, I45, I90,
//! I135 of one scene point. Half resolution; cheapest method; suffers the IFOV error (the four
//! samples see four scene points, spec `demosaic.md` §3).

use super::{check_raw, RawPixel};
use crate::error::Result;
use crate::image::{Image, StokesImage};
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

/// Offsets within the block of channels 0°, 45°, 90°, 135°.
fn offsets(layout: &MosaicLayout) -> [(usize, usize); 4] {
    std::array::from_fn(|k| layout.position_of(k))
}

/// Stokes (S0, S1, S2) of one 2 × 2 block from its 0°, 45°, 90°, 135° samples.
#[inline(always)]
fn block_stokes(v: [f32; 4]) -> (f32, f32, f32) {
    (
        0.5 * ((v[0] + v[2]) + (v[1] + v[3])),
        v[0] - v[2],
        v[1] - v[3],
    )
}

/// Half-resolution Stokes planes, (width / 2) x (height / 2); block (i, j) covers rows 2i, 2i + 1
/// and columns 2j, 2j + 1 (a trailing odd row or column is dropped).
pub fn superpixel_half<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> Result<StokesImage> {
    check_raw(raw)?;
    let (hw, hh) = (raw.width / 2, raw.height / 2);
    let off = offsets(&layout);
    let mut st = StokesImage::zeros(hw, hh);
    st.s0
        .data
        .par_chunks_mut(hw)
        .zip(st.s1.data.par_chunks_mut(hw))
        .zip(st.s2.data.par_chunks_mut(hw))
        .enumerate()
        .for_each(|(i, ((o0, o1), o2))| {
            let rows = [raw.row(2 * i), raw.row(2 * i + 1)];
            for j in 0..hw {
                let v = off.map(|(dr, dc)| rows[dr][2 * j + dc].to_f32());
                (o0[j], o1[j], o2[j]) = block_stokes(v);
            }
        });
    Ok(st)
}

/// Replicates a half-resolution plane to w x h (a trailing odd row/column repeats the last block).
pub(crate) fn replicate(half: &Image<f32>, w: usize, h: usize) -> Image<f32> {
    let mut out = Image::new(w, h);
    let hw = half.width;
    out.data.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let src = half.row((r / 2).min(half.height - 1));
        for (c, o) in row.iter_mut().enumerate() {
            *o = src[(c / 2).min(hw - 1)];
        }
    });
    out
}

/// Full-size planes: each block's Stokes vector replicated to its four pixels.
pub(crate) fn superpixel_full<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> StokesImage {
    let half = superpixel_half(raw, layout).expect("checked by the caller");
    let (w, h) = (raw.width, raw.height);
    StokesImage {
        s0: replicate(&half.s0, w, h),
        s1: replicate(&half.s1, w, h),
        s2: replicate(&half.s2, w, h),
    }
}

/// Full chain at half resolution, then replicated (DoLP/AoLP computed once per block).
pub(crate) fn full_chain<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> super::PolarImages {
    let mut out = super::PolarImages {
        stokes: StokesImage::zeros(0, 0),
        dolp: Image::new(0, 0),
        aolp_deg: Image::new(0, 0),
    };
    full_chain_into(raw, layout, &mut out);
    out
}

/// [`full_chain`] in one pass into caller-owned planes (resized when needed): each block's S0,
/// S1, S2, DoLP and AoLP are computed once and written to its 2 x 2 pixels; a trailing odd
/// row/column repeats the last block.
pub(crate) fn full_chain_into<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    out: &mut super::PolarImages,
) {
    let (w, h) = (raw.width, raw.height);
    let (hw, hh) = (w / 2, h / 2);
    let fit = |img: &mut Image<f32>| {
        if img.width != w || img.height != h || img.data.len() != w * h {
            *img = Image::new(w, h);
        }
    };
    fit(&mut out.stokes.s0);
    fit(&mut out.stokes.s1);
    fit(&mut out.stokes.s2);
    fit(&mut out.dolp);
    fit(&mut out.aolp_deg);
    let off = offsets(&layout);
    let st = &mut out.stokes;
    st.s0
        .data
        .par_chunks_mut(2 * w)
        .zip(st.s1.data.par_chunks_mut(2 * w))
        .zip(st.s2.data.par_chunks_mut(2 * w))
        .zip(out.dolp.data.par_chunks_mut(2 * w))
        .zip(out.aolp_deg.data.par_chunks_mut(2 * w))
        .enumerate()
        .for_each(|(i, ((((o0, o1), o2), od), oa))| {
            let bi = i.min(hh - 1);
            let rows = [raw.row(2 * bi), raw.row(2 * bi + 1)];
            for j in 0..hw {
                let v = off.map(|(dr, dc)| rows[dr][2 * j + dc].to_f32());
                let (s0, s1, s2) = block_stokes(v);
                let d = crate::stokes::dolp(s0, s1, s2);
                let a = crate::stokes::aolp_deg(s1, s2);
                for (o, x) in [
                    (&mut *o0, s0),
                    (&mut *o1, s1),
                    (&mut *o2, s2),
                    (&mut *od, d),
                    (&mut *oa, a),
                ] {
                    o[2 * j] = x;
                    o[2 * j + 1] = x;
                }
            }
            let n_rows = o0.len() / w;
            for o in [o0, o1, o2, od, oa] {
                if w % 2 == 1 {
                    o[w - 1] = o[w - 2];
                }
                if n_rows == 2 {
                    o.copy_within(0..w, w);
                }
            }
        });
}

/// Channel images: every pixel of a block gets the block's four samples.
pub(crate) fn channels<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let off = offsets(&layout);
    let mut out: [Vec<f32>; 4] = std::array::from_fn(|_| vec![0f32; w * h]);
    let [c0, c1, c2, c3] = &mut out;
    c0.par_chunks_mut(w)
        .zip(c1.par_chunks_mut(w))
        .zip(c2.par_chunks_mut(w).zip(c3.par_chunks_mut(w)))
        .enumerate()
        .for_each(|(r, ((o0, o1), (o2, o3)))| {
            // clamp a trailing odd row/column onto the last complete block
            let br = (r / 2).min(h / 2 - 1) * 2;
            let mut outs = [o0, o1, o2, o3];
            for c in 0..w {
                let bc = (c / 2).min(w / 2 - 1) * 2;
                for (k, o) in outs.iter_mut().enumerate() {
                    let (dr, dc) = off[k];
                    o[c] = raw.data[(br + dr) * w + bc + dc].to_f32();
                }
            }
        });
    out
}

/// Superpixel Stokes, DoLP and AoLP of every `k`-th 2 × 2 block only (`k` even, ≥ 2): output
/// pixel (i, j) is the block at rows k i, k i + 1 and columns k j, k j + 1, so the output is
/// (width / k) × (height / k), its pixel centre at (k j + ½, k i + ½) of the mosaic. `black` is
/// subtracted from every code. For a consumer that reads only a sample of a large frame
/// (`psns heading`): the rest of the frame is never demosaicked.
pub fn superpixel_sampled<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: usize,
    black: f32,
) -> Result<super::PolarImages> {
    superpixel_sampled_flat(raw, layout, k, black, |_, _| 1.0)
}

/// [`superpixel_sampled`] of a flat-fielded mosaic: each code less `black` is multiplied by
/// `gain(row, col)` (e.g. the inverse of the lens's relative illumination at that pixel) before
/// the block's Stokes are formed. The four pixels of a block sit at different field angles, so
/// a falloff that changes across the block (a fisheye's near its rim) reads as polarization
/// unless each pixel is corrected by its own factor. A gain of 1 gives [`superpixel_sampled`]'s
/// values exactly.
pub fn superpixel_sampled_flat<T: RawPixel, G: Fn(usize, usize) -> f32 + Sync>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: usize,
    black: f32,
    gain: G,
) -> Result<super::PolarImages> {
    check_raw(raw)?;
    if k < 2 || !k.is_multiple_of(2) {
        return Err(crate::error::Error::Invalid(format!(
            "superpixel sampling step {k}: must be even and at least 2"
        )));
    }
    let (ow, oh) = (raw.width / k, raw.height / k);
    let off = offsets(&layout);
    let mut st = StokesImage::zeros(ow, oh);
    let mut dolp = Image::new(ow, oh);
    let mut aolp = Image::new(ow, oh);
    st.s0
        .data
        .par_chunks_mut(ow.max(1))
        .zip(st.s1.data.par_chunks_mut(ow.max(1)))
        .zip(st.s2.data.par_chunks_mut(ow.max(1)))
        .zip(dolp.data.par_chunks_mut(ow.max(1)))
        .zip(aolp.data.par_chunks_mut(ow.max(1)))
        .enumerate()
        .for_each(|(i, ((((o0, o1), o2), od), oa))| {
            let rows = [raw.row(k * i), raw.row(k * i + 1)];
            for j in 0..ow {
                let v = off.map(|(dr, dc)| {
                    (rows[dr][k * j + dc].to_f32() - black) * gain(k * i + dr, k * j + dc)
                });
                let (s0, s1, s2) = block_stokes(v);
                o0[j] = s0;
                o1[j] = s1;
                o2[j] = s2;
                od[j] = crate::stokes::dolp(s0, s1, s2);
                oa[j] = crate::stokes::aolp_deg(s1, s2);
            }
        });
    Ok(super::PolarImages {
        stokes: st,
        dolp,
        aolp_deg: aolp,
    })
}
