//! Two-stage directional Newton interpolation with an edge classifier, simplified after Li,
//! Zhao, Pan & Kong, "Demosaicking DoFP images using Newton's polynomial interpolation and
//! polarization difference model", Opt. Express 27(2):1376, 2019 (own code, not a port: the
//! paper's exact classifier thresholds and fusion scheme are not reproduced).
//!
//! A missing channel f at pixel p (own channel g) is estimated along a direction d in which f is
//! known at p ± d; the second-order Newton term comes from g, i.e. the difference f − g is
//! interpolated linearly:
//!   f̂_d(p) = ½(f(p − d) + f(p + d)) + ¼(2g(p) − g(p − 2d) − g(p + 2d)),
//! with the directional gradient G_d = |f(p − d) − f(p + d)| + |2g(p) − g(p − 2d) − g(p + 2d)|.
//! 1. Diagonal channel: both diagonals, fused with weights 1/(ε + G_d²) so the estimate
//!    follows the edge.
//! 2. Horizontal and vertical channels: f is sampled at p ± (0, 1); after stage 1 it is also
//!    known (as the diagonal estimate) at p ± (1, 0). Both directions are estimated and the
//!    classifier weights them by 1/(ε + G²), G summed over p and its two neighbours across the
//!    direction from the raw mosaic (so a 1-px line is seen by the pixels beside it too).
//!
//! ε = (1 % of the mean level)², which makes the weights scale-free. Uniform and affine fields
//! are reproduced exactly.

use super::{chan, ppid::mean_level, Padded, RawPixel};
use crate::image::Image;
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

#[inline(always)]
fn dir_est(p: &Padded, r: isize, c: isize, dr: isize, dc: isize) -> (f32, f32) {
    let f1 = p.at(r - dr, c - dc);
    let f2 = p.at(r + dr, c + dc);
    let lap = 2.0 * p.at(r, c) - p.at(r - 2 * dr, c - 2 * dc) - p.at(r + 2 * dr, c + 2 * dc);
    (0.5 * (f1 + f2) + 0.25 * lap, (f1 - f2).abs() + lap.abs())
}

/// Raw-mosaic gradient along (dr, dc) at (r, c): both terms compare same-channel samples.
#[inline(always)]
fn raw_grad(p: &Padded, r: isize, c: isize, dr: isize, dc: isize) -> f32 {
    (p.at(r - dr, c - dc) - p.at(r + dr, c + dc)).abs()
        + (2.0 * p.at(r, c) - p.at(r - 2 * dr, c - 2 * dc) - p.at(r + 2 * dr, c + 2 * dc)).abs()
}

pub(crate) fn channels<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let p = Padded::from_raw(raw, 4);
    let mean = mean_level(&p, w, h);
    let eps = {
        let s = if mean > 0.0 { 0.01 * mean } else { 1e-3 };
        s * s
    };
    // 1. the diagonal channel of every pixel
    let mut diag = vec![0f32; w * h];
    diag.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let r = r as isize;
        for (c, o) in row.iter_mut().enumerate() {
            let ci = c as isize;
            let (e1, g1) = dir_est(&p, r, ci, 1, 1);
            let (e2, g2) = dir_est(&p, r, ci, 1, -1);
            let (w1, w2) = (1.0 / (eps + g1 * g1), 1.0 / (eps + g2 * g2));
            *o = (w1 * e1 + w2 * e2) / (w1 + w2);
        }
    });
    let dg = Padded::from_f32(&diag, w, h, 4);
    // 2. horizontal and vertical channels, both directions, classifier-weighted
    let mut out: [Vec<f32>; 4] = std::array::from_fn(|_| vec![0f32; w * h]);
    let [c0, c1, c2, c3] = &mut out;
    c0.par_chunks_mut(w)
        .zip(c1.par_chunks_mut(w))
        .zip(c2.par_chunks_mut(w).zip(c3.par_chunks_mut(w)))
        .enumerate()
        .for_each(|(r, ((o0, o1), (o2, o3)))| {
            let mut outs = [o0, o1, o2, o3];
            let r = r as isize;
            for c in 0..w {
                let ci = c as isize;
                let own = chan(&layout, r, ci);
                let g0 = p.at(r, ci);
                let lap_h = 2.0 * g0 - p.at(r, ci - 2) - p.at(r, ci + 2);
                let lap_v = 2.0 * g0 - p.at(r - 2, ci) - p.at(r + 2, ci);
                let gh: f32 = (-1..=1).map(|k| raw_grad(&p, r + k, ci, 0, 1)).sum();
                let gv: f32 = (-1..=1).map(|k| raw_grad(&p, r, ci + k, 1, 0)).sum();
                let (wh, wv) = (1.0 / (eps + gh * gh), 1.0 / (eps + gv * gv));
                for (k, o) in outs.iter_mut().enumerate() {
                    o[c] = if k == own {
                        g0
                    } else if chan(&layout, r, ci + 1) == k {
                        // sampled horizontally, stage-1 estimate vertically
                        let eh = 0.5 * (p.at(r, ci - 1) + p.at(r, ci + 1)) + 0.25 * lap_h;
                        let ev = 0.5 * (dg.at(r - 1, ci) + dg.at(r + 1, ci)) + 0.25 * lap_v;
                        (wh * eh + wv * ev) / (wh + wv)
                    } else if chan(&layout, r + 1, ci) == k {
                        let ev = 0.5 * (p.at(r - 1, ci) + p.at(r + 1, ci)) + 0.25 * lap_v;
                        let eh = 0.5 * (dg.at(r, ci - 1) + dg.at(r, ci + 1)) + 0.25 * lap_h;
                        (wh * eh + wv * ev) / (wh + wv)
                    } else {
                        diag[r as usize * w + c]
                    };
                }
            }
        });
    out
}
