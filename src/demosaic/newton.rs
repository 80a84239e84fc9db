//! Second-order Newton interpolation in the polarization-difference domain with a directional
//! edge classifier, after Li, Zhao, Pan & Kong, Opt. Express 27(2) 2019 (own implementation of
//! the idea, not a port of the authors' code).
//!
//! A missing channel f at pixel p (whose own channel is g) is estimated along a direction d in
//! which f is sampled at p ± d, with the second-order (Newton divided-difference) term taken
//! from g, i.e. the difference f − g is interpolated linearly:
//!   f̂_d(p) = ½(f(p − d) + f(p + d)) + ¼(2g(p) − g(p − 2d) − g(p + 2d)).
//! Horizontal and vertical neighbour channels have one such direction. The diagonal channel has
//! two; the classifier weights them by 1/(ε + G_d²) with the directional gradient
//! G_d = |f(p − d) − f(p + d)| + |2g(p) − g(p − 2d) − g(p + 2d)|, so the estimate follows the
//! edge (ε = (1 % of the mean level)², which makes the weights scale-free).
//! Uniform and affine fields are reproduced exactly.

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

pub(crate) fn channels<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let p = Padded::from_raw(raw, 4);
    let mean = mean_level(&p, w, h);
    let eps = {
        let s = if mean > 0.0 { 0.01 * mean } else { 1e-3 };
        s * s
    };
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
                for (k, o) in outs.iter_mut().enumerate() {
                    o[c] = if k == own {
                        p.at(r, ci)
                    } else if chan(&layout, r, ci + 1) == k {
                        dir_est(&p, r, ci, 0, 1).0
                    } else if chan(&layout, r + 1, ci) == k {
                        dir_est(&p, r, ci, 1, 0).0
                    } else {
                        let (e1, g1) = dir_est(&p, r, ci, 1, 1);
                        let (e2, g2) = dir_est(&p, r, ci, 1, -1);
                        let (w1, w2) = (1.0 / (eps + g1 * g1), 1.0 / (eps + g2 * g2));
                        (w1 * e1 + w2 * e2) / (w1 + w2)
                    };
                }
            }
        });
    out
}
