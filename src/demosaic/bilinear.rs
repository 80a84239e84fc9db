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

/// A symmetric 1-D low-pass with a zero at Nyquist: taps `h[0]` (centre) … `h[radius]`.
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

/// Scratch rows of one worker: vertically filtered rows (reflect-padded by the kernel radius)
/// and the four horizontally filtered planes of the current row.
struct Scratch {
    v0: Vec<f32>,
    v1: Vec<f32>,
    q: [Vec<f32>; 4],
    /// +1, −1, +1, … (the column carrier sign).
    signs: Vec<f32>,
}

impl Scratch {
    fn new(w: usize, r: usize) -> Scratch {
        Scratch {
            v0: vec![0f32; w + 2 * r],
            v1: vec![0f32; w + 2 * r],
            q: std::array::from_fn(|_| vec![0f32; w]),
            signs: (0..w)
                .map(|c| if c % 2 == 0 { 1.0 } else { -1.0 })
                .collect(),
        }
    }
}

/// Vertical pass for output row `r`: v0 = Σ h_k raw[r+k], v1 = Σ (−1)^k h_k raw[r+k]
/// (one tap at a time over whole rows, so the loops vectorise).
#[inline(always)]
fn vertical<T: RawPixel, const R: usize>(raw: &Image<T>, r: usize, k: &Kernel, s: &mut Scratch) {
    let (w, h) = (raw.width, raw.height);
    let v0 = &mut s.v0[R..R + w];
    let v1 = &mut s.v1[R..R + w];
    for ((a, b), x) in v0.iter_mut().zip(v1.iter_mut()).zip(raw.row(r)) {
        let x = k.h[0] * x.to_f32();
        *a = x;
        *b = x;
    }
    for j in 1..=R {
        let up = raw.row(reflect101(r as isize - j as isize, h));
        let dn = raw.row(reflect101(r as isize + j as isize, h));
        let hj = k.h[j];
        let sg = if j % 2 == 1 { -hj } else { hj };
        for (((a, b), u), d) in v0.iter_mut().zip(v1.iter_mut()).zip(up).zip(dn) {
            let p = u.to_f32() + d.to_f32();
            *a += hj * p;
            *b += sg * p;
        }
    }
    // reflect101 padding keeps the column parity
    for j in 1..=R {
        s.v0[R - j] = s.v0[R + j];
        s.v1[R - j] = s.v1[R + j];
        s.v0[R + w - 1 + j] = s.v0[R + w - 1 - j];
        s.v1[R + w - 1 + j] = s.v1[R + w - 1 - j];
    }
}

/// Horizontal pass: q = [base, A, B, C] before the carrier signs, one tap at a time.
#[inline(always)]
fn horizontal<const R: usize>(s: &mut Scratch, w: usize, k: &Kernel) {
    let (v0, v1) = (&s.v0, &s.v1);
    let [qb, qa, qc, qd] = &mut s.q;
    let h0 = k.h[0];
    for ((((o0, oa), ob), od), (x0, x1)) in qb
        .iter_mut()
        .zip(qa.iter_mut())
        .zip(qc.iter_mut())
        .zip(qd.iter_mut())
        .zip(v0[R..R + w].iter().zip(&v1[R..R + w]))
    {
        *o0 = h0 * x0;
        *oa = h0 * x1;
        *ob = h0 * x0;
        *od = h0 * x1;
    }
    for j in 1..=R {
        let hj = k.h[j];
        let sg = if j % 2 == 1 { -hj } else { hj };
        let (l0, r0) = (&v0[R - j..R - j + w], &v0[R + j..R + j + w]);
        let (l1, r1) = (&v1[R - j..R - j + w], &v1[R + j..R + j + w]);
        for (i, (((o0, oa), ob), od)) in qb
            .iter_mut()
            .zip(qa.iter_mut())
            .zip(qc.iter_mut())
            .zip(qd.iter_mut())
            .enumerate()
        {
            let p0 = l0[i] + r0[i];
            let p1 = l1[i] + r1[i];
            *o0 += hj * p0;
            *oa += hj * p1;
            *ob += sg * p0;
            *od += sg * p1;
        }
    }
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
    let w = raw.width;
    vertical::<T, R>(raw, r, k, s);
    horizontal::<R>(s, w, k);
    let (o0, o1, o2, dl) = out;
    let sr = if r.is_multiple_of(2) { 1.0f32 } else { -1.0 };
    // fold the row sign into the coefficients; the column sign comes from `signs`
    let m1 = [mix.s1[0] * sr, mix.s1[1], mix.s1[2] * sr];
    let m2 = [mix.s2[0] * sr, mix.s2[1], mix.s2[2] * sr];
    let [qb, qa, qc, qd] = &s.q;
    for (i, ((p0, p1), p2)) in o0
        .iter_mut()
        .zip(o1.iter_mut())
        .zip(o2.iter_mut())
        .enumerate()
    {
        let sc = s.signs[i];
        let (a, b, d) = (qa[i], qc[i] * sc, qd[i] * sc);
        *p0 = 2.0 * qb[i];
        *p1 = m1[0] * a + m1[1] * b + m1[2] * d;
        *p2 = m2[0] * a + m2[1] * b + m2[2] * d;
    }
    if let Some((od, oa)) = dl {
        for ((((d, a), s0), s1), s2) in od
            .iter_mut()
            .zip(oa.iter_mut())
            .zip(o0.iter())
            .zip(o1.iter())
            .zip(o2.iter())
        {
            *d = crate::stokes::dolp(*s0, *s1, *s2);
            *a = crate::stokes::aolp_deg(*s1, *s2);
        }
    }
}

fn run<T: RawPixel, const R: usize>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: &Kernel,
    fused: bool,
    out: &mut PolarImages,
) {
    let (w, h) = (raw.width, raw.height);
    let mix = Mix::new(&layout);
    let fit = |img: &mut Image<f32>, w: usize, h: usize| {
        if img.width != w || img.height != h || img.data.len() != w * h {
            *img = Image::new(w, h);
        }
    };
    fit(&mut out.stokes.s0, w, h);
    fit(&mut out.stokes.s1, w, h);
    fit(&mut out.stokes.s2, w, h);
    let (dw, dh) = if fused { (w, h) } else { (0, 0) };
    fit(&mut out.dolp, dw, dh);
    fit(&mut out.aolp_deg, dw, dh);
    let init = || Scratch::new(w, R);
    let st = &mut out.stokes;
    let planes = st
        .s0
        .data
        .par_chunks_mut(w)
        .zip(st.s1.data.par_chunks_mut(w))
        .zip(st.s2.data.par_chunks_mut(w))
        .enumerate();
    if fused {
        planes
            .zip(
                out.dolp
                    .data
                    .par_chunks_mut(w)
                    .zip(out.aolp_deg.data.par_chunks_mut(w)),
            )
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
}

/// Demodulates into `out`, reusing its buffers when they have the right size.
pub(crate) fn demodulate_into<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    k: &Kernel,
    fused: bool,
    out: &mut PolarImages,
) {
    match k.radius {
        1 => run::<T, 1>(raw, layout, k, fused, out),
        2 => run::<T, 2>(raw, layout, k, fused, out),
        _ => run::<T, 3>(raw, layout, k, fused, out),
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
    let mut out = PolarImages {
        stokes: StokesImage::zeros(0, 0),
        dolp: Image::new(0, 0),
        aolp_deg: Image::new(0, 0),
    };
    demodulate_into(raw, layout, k, fused, &mut out);
    out
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
            || Scratch::new(w, rr),
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
    let w = raw.width;
    vertical::<T, R>(raw, r, k, s);
    horizontal::<R>(s, w, k);
    let sr = if r.is_multiple_of(2) { 1.0f32 } else { -1.0 };
    let [qb, qa, qc, qd] = &s.q;
    for c in 0..w {
        let sc = s.signs[c];
        let (a, b, d) = (qa[c] * sr, qc[c] * sc, qd[c] * sr * sc);
        for (kk, o) in outs.iter_mut().enumerate() {
            let e = mix.e[kk];
            o[c] = qb[c] + e[0] * a + e[1] * b + e[2] * d;
        }
    }
}
