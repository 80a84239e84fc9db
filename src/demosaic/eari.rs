//! Edge-aware residual interpolation (EARI), after Morimatsu, Monno, Tanaka & Okutomi,
//! "Monochrome and color polarization demosaicking using edge-aware residual interpolation",
//! ICIP 2020 (own implementation of the idea, not a port of the authors' code).
//!
//! 1. Edge-aware guide (intensity, ½S0): the four 2 x 2 blocks containing p each give a mean;
//!    they are combined with weights 1/(ε + E_b²), where E_b = |I0 + I90 − I45 − I135| inside
//!    block b vanishes for any uniformly polarized block and grows where the block straddles an
//!    intensity edge (the intensity-correlation check I0 + I90 = I45 + I135).
//! 2. Minimised-Laplacian residual interpolation per channel k (Kiku et al.'s MLRI): over a
//!    7 x 7 window, fit raw ≈ a G + b on k's sub-lattice with a from the sparse Laplacians,
//!    a = Σ L_G L_raw / (Σ L_G² + ε_a), b = mean(raw) − a mean(G); tentative T_k = a G + b.
//! 3. The residual raw − T_k on k's sub-lattice is interpolated bilinearly and added:
//!    Î_k = T_k + bilinear(raw − T_k).
//!
//! Uniform fields are reproduced exactly (all Laplacians vanish, so T_k = I_k).

use super::{bilinear_sparse, chan, ppid::mean_level, Padded, RawPixel};
use crate::image::Image;
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

const WIN: isize = 3;

/// Sum over the (2·WIN + 1)² window, truncated at the image border (separable, f64 accumulate).
fn box_sum(src: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut tmp = vec![0f32; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let s = &src[r * w..(r + 1) * w];
        for (c, o) in row.iter_mut().enumerate() {
            let lo = c.saturating_sub(WIN as usize);
            let hi = (c + WIN as usize).min(w - 1);
            *o = s[lo..=hi].iter().map(|&v| v as f64).sum::<f64>() as f32;
        }
    });
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let lo = r.saturating_sub(WIN as usize);
        let hi = (r + WIN as usize).min(h - 1);
        for (c, o) in row.iter_mut().enumerate() {
            *o = (lo..=hi).map(|rr| tmp[rr * w + c] as f64).sum::<f64>() as f32;
        }
    });
    out
}

pub(crate) fn channels<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let p = Padded::from_raw(raw, 4);
    let mean = mean_level(&p, w, h);
    let scale = if mean > 0.0 { mean } else { 1.0 };
    // 1. edge-aware guide
    let eps_b = (0.01 * scale) * (0.01 * scale);
    let mut guide = vec![0f32; w * h];
    guide.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let r = r as isize;
        for (c, o) in row.iter_mut().enumerate() {
            let c = c as isize;
            let (mut num, mut den) = (0f32, 0f32);
            for (br, bc) in [(r - 1, c - 1), (r - 1, c), (r, c - 1), (r, c)] {
                let mut v = [0f32; 4];
                for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    v[chan(&layout, br + dr, bc + dc)] = p.at(br + dr, bc + dc);
                }
                let m = 0.25 * ((v[0] + v[2]) + (v[1] + v[3]));
                let e = (v[0] + v[2]) - (v[1] + v[3]);
                let wt = 1.0 / (eps_b + e * e);
                num += wt * m;
                den += wt;
            }
            *o = num / den;
        }
    });
    let g = Padded::from_f32(&guide, w, h, 4);
    std::array::from_fn(|k| {
        let (kr, kc) = layout.position_of(k);
        let on = |r: usize, c: usize| (r & 1) == kr && (c & 1) == kc;
        // 2. masked moments on k's sub-lattice
        let mut m = [
            vec![0f32; w * h],
            vec![0f32; w * h],
            vec![0f32; w * h],
            vec![0f32; w * h],
            vec![0f32; w * h],
        ];
        {
            let [m_n, m_r, m_g, m_gg, m_gr] = &mut m;
            m_n.par_chunks_mut(w)
                .zip(m_r.par_chunks_mut(w))
                .zip(m_g.par_chunks_mut(w))
                .zip(m_gg.par_chunks_mut(w).zip(m_gr.par_chunks_mut(w)))
                .enumerate()
                .for_each(|(r, (((n, mr), mg), (mgg, mgr)))| {
                    for c in 0..w {
                        if !on(r, c) {
                            continue;
                        }
                        let (ri, ci) = (r as isize, c as isize);
                        let lap = |x: &Padded| {
                            4.0 * x.at(ri, ci)
                                - x.at(ri - 2, ci)
                                - x.at(ri + 2, ci)
                                - x.at(ri, ci - 2)
                                - x.at(ri, ci + 2)
                        };
                        let (lr, lg) = (lap(&p), lap(&g));
                        n[c] = 1.0;
                        mr[c] = p.at(ri, ci);
                        mg[c] = g.at(ri, ci);
                        mgg[c] = lg * lg;
                        mgr[c] = lg * lr;
                    }
                });
        }
        let s: Vec<Vec<f32>> = m.iter().map(|x| box_sum(x, w, h)).collect();
        let mut tent = vec![0f32; w * h];
        tent.par_iter_mut().enumerate().for_each(|(i, t)| {
            let (n, sr, sg, sgg, sgr) = (s[0][i], s[1][i], s[2][i], s[3][i], s[4][i]);
            let eps_a = 1e-4 * n * scale * scale * 1e-2;
            let a = sgr / (sgg + eps_a + f32::MIN_POSITIVE);
            let b = (sr - a * sg) / n;
            *t = a * guide[i] + b;
        });
        // 3. residual interpolation
        let tp = Padded::from_f32(&tent, w, h, 4);
        let res = Padded {
            data: p.data.iter().zip(&tp.data).map(|(a, b)| a - b).collect(),
            stride: p.stride,
            pad: p.pad,
        };
        let mut out = bilinear_sparse(&res, w, h, &layout, k);
        out.par_iter_mut().zip(&tent).for_each(|(v, t)| *v += t);
        out
    })
}
