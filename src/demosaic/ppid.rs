//! Pseudo-panchromatic image difference (PPID) demosaicking.
//!
//! After Mihoubi, Houssou, Losson, Lapray & Macaire (IEEE TCI 2017) and its application to
//! polarization filter arrays by Mihoubi, Lapray & Bigué (Sensors 18(11):3688, 2018):
//! 1. PPI estimate Ī = M ∗ raw with M = [1 2 1]ᵀ[1 2 1]/16 (the mean of the four channels,
//!    ½S0 for ideal polarizers);
//! 2. edge-sensitive refinement Ĩ(p) = raw(p) + Σ_q γ_q (Ī(q) − raw(q)) / Σ_q γ_q over the eight
//!    same-channel neighbours q at distance 2, γ_q = 1 / (1 + |raw(p) − raw(q)| / σ), σ = 2 % of
//!    the mean mosaic level (so the weights do not depend on the bit depth);
//! 3. per channel k, the difference raw − Ĩ on k's sub-lattice is interpolated bilinearly and
//!    added back: Î_k = Ĩ + bilinear(raw − Ĩ).
//!
//! A uniform field is returned exactly: Ĩ = Ī and the differences are constant.

use super::{bilinear_sparse, Padded, RawPixel};
use crate::image::Image;
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

/// Mean mosaic level. Per-row sums are collected, then added in row order: a rayon `.sum()`
/// would combine partial sums in an order that depends on the pool size and work stealing, and
/// σ (PPID) and ε (Newton, EARI) derive from this value.
pub(crate) fn mean_level(p: &Padded, w: usize, h: usize) -> f32 {
    let rows: Vec<f64> = (0..h)
        .into_par_iter()
        .map(|r| {
            (0..w)
                .map(|c| p.at(r as isize, c as isize) as f64)
                .sum::<f64>()
        })
        .collect();
    let s: f64 = rows.iter().sum();
    (s / (w * h) as f64) as f32
}

pub(crate) fn channels<T: RawPixel>(raw: &Image<T>, layout: MosaicLayout) -> [Vec<f32>; 4] {
    let (w, h) = (raw.width, raw.height);
    let p = Padded::from_raw(raw, 4);
    // 1. PPI by the 3 x 3 binomial filter
    let mut ppi = vec![0f32; w * h];
    ppi.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let r = r as isize;
        for (c, o) in row.iter_mut().enumerate() {
            let c = c as isize;
            let v = |dr: isize| p.at(r + dr, c - 1) + 2.0 * p.at(r + dr, c) + p.at(r + dr, c + 1);
            *o = (v(-1) + 2.0 * v(0) + v(1)) / 16.0;
        }
    });
    let ppi = Padded::from_f32(&ppi, w, h, 4);
    // 2. refinement with same-channel neighbours
    let mean = mean_level(&p, w, h);
    let sigma = if mean > 0.0 { 0.02 * mean } else { 1.0 };
    let inv_sigma = 1.0 / sigma;
    let mut ref_ppi = vec![0f32; w * h];
    ref_ppi.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let r = r as isize;
        for (c, o) in row.iter_mut().enumerate() {
            let c = c as isize;
            let x = p.at(r, c);
            let (mut num, mut den) = (0f32, 0f32);
            for (dr, dc) in [
                (-2, -2),
                (-2, 0),
                (-2, 2),
                (0, -2),
                (0, 2),
                (2, -2),
                (2, 0),
                (2, 2),
            ] {
                let q = p.at(r + dr, c + dc);
                let g = 1.0 / (1.0 + (x - q).abs() * inv_sigma);
                num += g * (ppi.at(r + dr, c + dc) - q);
                den += g;
            }
            *o = x + num / den;
        }
    });
    let rp = Padded::from_f32(&ref_ppi, w, h, 4);
    // 3. bilinear interpolation of raw − PPI per channel
    let diff = Padded {
        data: p.data.iter().zip(&rp.data).map(|(a, b)| a - b).collect(),
        stride: p.stride,
        pad: p.pad,
    };
    std::array::from_fn(|k| {
        let mut d = bilinear_sparse(&diff, w, h, &layout, k);
        d.par_iter_mut().zip(&ref_ppi).for_each(|(v, t)| *v += t);
        d
    })
}
