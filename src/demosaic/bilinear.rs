//! Bilinear demosaicking as Nyquist demodulation, fused with the Stokes (and DoLP/AoLP) step.
//!
//! Per-channel bilinear interpolation (Gao & Gruev, Opt. Express 19(27) 2011) followed by the
//! Stokes formulas equals, exactly, demodulation of the mosaic with the separable low-pass
//! LP = [1 2 1]/4 (spec `demosaic.md` §1). Writing the mosaic as
//! raw = ½S0 + A(−1)^r + B(−1)^c + C(−1)^(r+c), the four coefficients are
//! base = LP(raw) = ½S0, A = LP(raw·(−1)^r), B = LP(raw·(−1)^c), C = LP(raw·(−1)^(r+c)), and
//! channel k at superpixel position (pr, pc) reads I_k = base + ε_r A + ε_c B + ε_r ε_c C with
//! ε_r = +1 on row 0, −1 on row 1 (same for columns). Modulating by (−1)^n commutes with a
//! symmetric filter h into (−1)^n times the filter (−1)^k h_k, so all four planes come from one
//! vertical pass (two row buffers) and one horizontal pass; no full-frame intermediate.
//! The same code runs the Keys cubic kernel ([`super::bicubic`]).

use super::{reflect101, PolarImages, RawPixel};
use crate::image::{Image, StokesImage};
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

/// A symmetric 1-D low-pass with a zero at Nyquist: taps h[0] (centre) … h[radius].
#[derive(Clone, Copy, Debug)]
pub struct Kernel {
    /// Half-width (1 for bilinear, 3 for Keys cubic).
    pub radius: usize,
    /// Centre tap first; unused entries are zero.
    pub h: [f32; 4],
}

/// [1 2 1]/4: per-channel bilinear interpolation.
pub const LP3: Kernel = Kernel {
    radius: 1,
    h: [0.5, 0.25, 0.0, 0.0],
};

/// Coefficients turning (base, A, B, C) into S0, S1, S2 for a layout.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mix {
    /// I_k = base + e[k][0] A + e[k][1] B + e[k][2] C.
    pub e: [[f32; 3]; 4],
    /// S1 = s1[0] A + s1[1] B + s1[2] C.
    pub s1: [f32; 3],
    /// S2 = s2[0] A + s2[1] B + s2[2] C.
    pub s2: [f32; 3],
}

impl Mix {
    pub fn new(layout: &MosaicLayout) -> Mix {
        let mut e = [[0f32; 3]; 4];
        for (k, ek) in e.iter_mut().enumerate() {
            let (pr, pc) = layout.position_of(k);
            let er = if pr == 0 { 1.0 } else { -1.0 };
            let ec = if pc == 0 { 1.0 } else { -1.0 };
            *ek = [er, ec, er * ec];
        }
        let d = |a: usize, b: usize| [e[a][0] - e[b][0], e[a][1] - e[b][1], e[a][2] - e[b][2]];
        Mix {
            e,
            s1: d(0, 2),
            s2: d(1, 3),
        }
    }
}

/// Scratch rows of one worker: vertically filtered, reflect-padded by the kernel radius.
struct Scratch {
    v0: Vec<f32>,
    v1: Vec<f32>,
}

/// Vertical pass for output row `r`: v0 = Σ h_k raw[r+k], v1 = Σ (−1)^k h_k raw[r+k].
#[inline(always)]
fn vertical<T: RawPixel, const R: usize>(raw: &Image<T>, r: usize, k: &Kernel, s: &mut Scratch) {
    let (w, h) = (raw.width, raw.height);
    let rows: [&[T]; 7] = std::array::from_fn(|i| {
        let off = i as isize - 3;
        if off.unsigned_abs() <= R {
            raw.row(reflect101(r as isize + off, h))
        } else {
            raw.row(r)
        }
    });
    let v0 = &mut s.v0[R..R + w];
    let v1 = &mut s.v1[R..R + w];
    let centre = rows[3];
    for c in 0..w {
        let x = centre[c].to_f32();
        let mut a = k.h[0] * x;
        let mut b = k.h[0] * x;
        for j in 1..=R {
            let p = rows[3 - j][c].to_f32() + rows[3 + j][c].to_f32();
            let t = k.h[j] * p;
            a += t;
            b += if j % 2 == 1 { -t } else { t };
        }
        v0[c] = a;
        v1[c] = b;
    }
    // reflect101 padding keeps the column parity
    for j in 1..=R {
        s.v0[R - j] = s.v0[R + j];
        s.v1[R - j] = s.v1[R + j];
        s.v0[R + w - 1 + j] = s.v0[R + w - 1 - j];
        s.v1[R + w - 1 + j] = s.v1[R + w - 1 - j];
    }
}

/// Horizontal pass at column c (padded index c + R): (base, A, B, C) before the ± signs.
#[inline(always)]
fn horizontal<const R: usize>(
    v0: &[f32],
    v1: &[f32],
    c: usize,
    k: &Kernel,
) -> (f32, f32, f32, f32) {
    let i = c + R;
    let (mut base, mut a, mut b, mut d) = (
        k.h[0] * v0[i],
        k.h[0] * v1[i],
        k.h[0] * v0[i],
        k.h[0] * v1[i],
    );
    for j in 1..=R {
        let p0 = v0[i - j] + v0[i + j];
        let p1 = v1[i - j] + v1[i + j];
        let (t0, t1) = (k.h[j] * p0, k.h[j] * p1);
        base += t0;
        a += t1;
        if j % 2 == 1 {
            b -= t0;
            d -= t1;
        } else {
            b += t0;
            d += t1;
        }
    }
    (base, a, b, d)
}

type RowOut<'a> = (
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    Option<(&'a mut [f32], &'a mut [f32])>,
);

fn row_kernel<T: RawPixel, const R: usize>(
    raw: &Image<T>,
    r: usize,
    k: &Kernel,
    mix: &Mix,
    s: &mut Scratch,
    out: RowOut,
) {
    vertical::<T, R>(raw, r, k, s);
    let (o0, o1, o2, dl) = out;
    let sr = if r % 2 == 0 { 1.0f32 } else { -1.0 };
    let w = raw.width;
    let (v0, v1) = (&s.v0[..], &s.v1[..]);
    // fold the row sign into the coefficients; the column sign alternates
    let m1 = [mix.s1[0] * sr, mix.s1[1], mix.s1[2] * sr];
    let m2 = [mix.s2[0] * sr, mix.s2[1], mix.s2[2] * sr];
    let px = |c: usize| {
        let sc = if c % 2 == 0 { 1.0f32 } else { -1.0 };
        let (base, a, b, d) = horizontal::<R>(v0, v1, c, k);
        let (b, d) = (b * sc, d * sc);
        (
            2.0 * base,
            m1[0] * a + m1[1] * b + m1[2] * d,
            m2[0] * a + m2[1] * b + m2[2] * d,
        )
    };
    match dl {
        None => {
            for c in 0..w {
                let (s0, s1, s2) = px(c);
                o0[c] = s0;
                o1[c] = s1;
                o2[c] = s2;
            }
        }
        Some((od, oa)) => {
            for c in 0..w {
                let (s0, s1, s2) = px(c);
                o0[c] = s0;
                o1[c] = s1;
                o2[c] = s2;
                od[c] = crate::stokes::dolp(s0, s1, s2);
                oa[c] = crate::stokes::aolp_deg(s1, s2);
            }
        }
    }
}

fn run<T: RawPixel, const R: usize>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: &Kernel,
    fused: bool,
) -> PolarImages {
    let (w, h) = (raw.width, raw.height);
    let mix = Mix::new(&layout);
    let mut st = StokesImage::zeros(w, h);
    let (mut dolp, mut aolp) = if fused {
        (Image::new(w, h), Image::new(w, h))
    } else {
        (Image::new(0, 0), Image::new(0, 0))
    };
    let init = || Scratch {
        v0: vec![0f32; w + 2 * R],
        v1: vec![0f32; w + 2 * R],
    };
    let planes = st
        .s0
        .data
        .par_chunks_mut(w)
        .zip(st.s1.data.par_chunks_mut(w))
        .zip(st.s2.data.par_chunks_mut(w))
        .enumerate();
    if fused {
        planes
            .zip(dolp.data.par_chunks_mut(w).zip(aolp.data.par_chunks_mut(w)))
            .with_min_len(4)
            .for_each_init(init, |s, ((r, ((o0, o1), o2)), (od, oa))| {
                row_kernel::<T, R>(raw, r, k, &mix, s, (o0, o1, o2, Some((od, oa))))
            });
    } else {
        planes
            .with_min_len(4)
            .for_each_init(init, |s, (r, ((o0, o1), o2))| {
                row_kernel::<T, R>(raw, r, k, &mix, s, (o0, o1, o2, None))
            });
    }
    PolarImages {
        stokes: st,
        dolp,
        aolp_deg: aolp,
    }
}

/// Demodulates with kernel `k` (radius 1 or 3); with `fused` also fills DoLP and AoLP
/// (otherwise those images are 0 x 0). The caller has checked the input size.
pub(crate) fn demodulate<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: &Kernel,
    fused: bool,
) -> PolarImages {
    match k.radius {
        1 => run::<T, 1>(raw, layout, k, fused),
        2 => run::<T, 2>(raw, layout, k, fused),
        _ => run::<T, 3>(raw, layout, k, fused),
    }
}

/// Channel images I0, I45, I90, I135 of the demodulator (equal to per-channel interpolation).
pub(crate) fn channels<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: &Kernel,
) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let mix = Mix::new(&layout);
    let mut out: [Vec<f32>; 4] = std::array::from_fn(|_| vec![0f32; w * h]);
    let [c0, c1, c2, c3] = &mut out;
    let rr = k.radius;
    c0.par_chunks_mut(w)
        .zip(c1.par_chunks_mut(w))
        .zip(c2.par_chunks_mut(w).zip(c3.par_chunks_mut(w)))
        .enumerate()
        .for_each_init(
            || Scratch {
                v0: vec![0f32; w + 2 * rr],
                v1: vec![0f32; w + 2 * rr],
            },
            |s, (r, ((o0, o1), (o2, o3)))| {
                let outs = [o0, o1, o2, o3];
                match rr {
                    1 => chan_row::<T, 1>(raw, r, k, &mix, s, outs),
                    2 => chan_row::<T, 2>(raw, r, k, &mix, s, outs),
                    _ => chan_row::<T, 3>(raw, r, k, &mix, s, outs),
                }
            },
        );
    out
}

fn chan_row<T: RawPixel, const R: usize>(
    raw: &Image<T>,
    r: usize,
    k: &Kernel,
    mix: &Mix,
    s: &mut Scratch,
    mut outs: [&mut [f32]; 4],
) {
    vertical::<T, R>(raw, r, k, s);
    let sr = if r % 2 == 0 { 1.0f32 } else { -1.0 };
    for c in 0..raw.width {
        let sc = if c % 2 == 0 { 1.0f32 } else { -1.0 };
        let (base, a, b, d) = horizontal::<R>(&s.v0, &s.v1, c, k);
        let (a, b, d) = (a * sr, b * sc, d * sr * sc);
        for (kk, o) in outs.iter_mut().enumerate() {
            let e = mix.e[kk];
            o[c] = base + e[0] * a + e[1] * b + e[2] * d;
        }
    }
}
