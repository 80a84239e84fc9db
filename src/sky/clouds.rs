//! Clouds, two ways.
//!
//! * PSNS (`sensor.md` §9, `gniicpi`): 3–8 filled ellipses, semi-axes 5–20 % of the image width,
//!   uniform centres and orientations, whose pixels are set to full scale in the raw codes
//!   ([`psns_ellipses`], [`ellipse_mask`]); drawn from the frame's noise stream by the sensor.
//! * Soft clouds ([`apply_soft_clouds`]): unpolarized bright patches with soft edges blended into
//!   a sensor-frame Stokes image before the sensor: S0 ← (1 − α) S0 + α L_c, S1,2 ← (1 − α) S1,2,
//!   α the cloud opacity (1 inside, smooth-step to 0 at the ellipse rim). Ground pixels (S0 ≤ 0)
//!   are left alone. Only a visual/robustness aid: no radiative transfer.

use crate::error::{check_range, Error, Result};
use crate::image::StokesImage;
use rand::Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// An ellipse in pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipse {
    /// Centre column.
    pub cx: f64,
    /// Centre row.
    pub cy: f64,
    /// Semi-axis along the rotated x axis, pixels.
    pub a: f64,
    /// Semi-axis along the rotated y axis, pixels.
    pub b: f64,
    /// Orientation, radians from +x toward +y.
    pub angle: f64,
}

impl Ellipse {
    /// Normalised radius ρ of (col, row): ρ ≤ 1 inside.
    #[inline]
    pub fn rho(&self, col: f64, row: f64) -> f64 {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (col - self.cx, row - self.cy);
        let u = (c * dx + s * dy) / self.a;
        let v = (-s * dx + c * dy) / self.b;
        (u * u + v * v).sqrt()
    }

    /// Columns `lo..hi` (clamped to [0, w)) outside which no pixel of row `row` has
    /// [`Self::rho`] ≤ 1: the real interval where ρ² ≤ 1 (a quadratic in the column) widened by
    /// 2 pixels. Beyond that ρ² − 1 exceeds 4/max(a, b)² (≥ 1e-8 for any semi-axis under 10⁴
    /// pixels), far above the rounding of [`Self::rho`], so testing `rho` only inside the span
    /// gives the mask the test at every pixel gives.
    fn col_span(&self, row: f64, w: usize) -> (usize, usize) {
        let (s, c) = self.angle.sin_cos();
        let (ia2, ib2) = (1.0 / (self.a * self.a), 1.0 / (self.b * self.b));
        let dy = row - self.cy;
        // ρ² = α dx² + β dx + γ with dx = col − cx
        let alpha = c * c * ia2 + s * s * ib2;
        let beta = 2.0 * dy * c * s * (ia2 - ib2);
        let gamma = dy * dy * (s * s * ia2 + c * c * ib2);
        let mid = -beta / (2.0 * alpha);
        let disc = beta * beta - 4.0 * alpha * (gamma - 1.0);
        let half = if disc > 0.0 {
            disc.sqrt() / (2.0 * alpha)
        } else {
            0.0
        };
        let lo = (self.cx + mid - half - 2.0).floor().max(0.0);
        let hi = (self.cx + mid + half + 2.0).ceil().max(0.0) + 1.0;
        if !(lo.is_finite() && hi.is_finite()) {
            return (0, w); // degenerate axes: test every pixel
        }
        ((lo as usize).min(w), (hi as usize).min(w))
    }

    /// Rows the ellipse (scaled by `grow`) can touch, clamped to [0, h).
    fn row_span(&self, h: usize, grow: f64) -> (usize, usize) {
        let r = self.a.max(self.b) * grow;
        let lo = (self.cy - r).floor().max(0.0) as usize;
        let hi = ((self.cy + r).ceil().max(0.0) as usize).min(h.saturating_sub(1));
        (lo, hi)
    }
}

fn draw_ellipses<R: Rng + ?Sized>(
    w: usize,
    h: usize,
    rng: &mut R,
    n: usize,
    min_frac: f64,
    max_frac: f64,
) -> Vec<Ellipse> {
    (0..n)
        .map(|_| Ellipse {
            cx: rng.random::<f64>() * w as f64,
            cy: rng.random::<f64>() * h as f64,
            a: w as f64 * (min_frac + (max_frac - min_frac) * rng.random::<f64>()),
            b: w as f64 * (min_frac + (max_frac - min_frac) * rng.random::<f64>()),
            angle: rng.random::<f64>() * std::f64::consts::PI,
        })
        .collect()
}

/// The PSNS cloud set: 3–8 ellipses, semi-axes 5–20 % of `width`.
pub fn psns_ellipses<R: Rng + ?Sized>(width: usize, height: usize, rng: &mut R) -> Vec<Ellipse> {
    let n = rng.random_range(3..=8usize);
    draw_ellipses(width, height, rng, n, 0.05, 0.20)
}

/// Row-major mask of pixels inside any ellipse (pixel centres).
pub fn ellipse_mask(width: usize, height: usize, ellipses: &[Ellipse]) -> Vec<bool> {
    let mut m = vec![false; width * height];
    m.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(r, row)| ellipse_row(ellipses, height, r, row.len(), |c| row[c] = true));
    m
}

/// Calls `f(c)` for every column c of row `r` (of a `width` × `height` image) whose pixel centre
/// is inside an ellipse (once per ellipse holding it): row `r` of [`ellipse_mask`].
#[inline]
pub fn ellipse_row(
    ellipses: &[Ellipse],
    height: usize,
    r: usize,
    width: usize,
    mut f: impl FnMut(usize),
) {
    for e in ellipses {
        let (lo, hi) = e.row_span(height, 1.0);
        if r < lo || r > hi {
            continue;
        }
        let (c0, c1) = e.col_span(r as f64, width);
        for c in c0..c1 {
            if e.rho(c as f64, r as f64) <= 1.0 {
                f(c);
            }
        }
    }
}

/// Soft unpolarized cloud patches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SoftClouds {
    /// Number of patches, 0..64 (default 5).
    pub count: usize,
    /// Smallest semi-axis as a fraction of the width (default 0.05).
    pub min_axis_frac: f64,
    /// Largest semi-axis as a fraction of the width (default 0.20).
    pub max_axis_frac: f64,
    /// Cloud radiance as a multiple of the median sky S0 (default 2.5).
    pub brightness: f64,
    /// Width of the soft rim as a fraction of the semi-axes, 0..1 (default 0.4).
    pub edge: f64,
}

impl Default for SoftClouds {
    fn default() -> Self {
        SoftClouds {
            count: 5,
            min_axis_frac: 0.05,
            max_axis_frac: 0.20,
            brightness: 2.5,
            edge: 0.4,
        }
    }
}

impl SoftClouds {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range("cloud count", self.count as f64, 0.0, 64.0)?;
        check_range("cloud min axis", self.min_axis_frac, 0.001, 1.0)?;
        check_range("cloud max axis", self.max_axis_frac, 0.001, 1.0)?;
        if self.min_axis_frac > self.max_axis_frac {
            return Err(Error::Invalid(format!(
                "cloud min axis {} exceeds max axis {}",
                self.min_axis_frac, self.max_axis_frac
            )));
        }
        check_range("cloud brightness", self.brightness, 0.0, 1e3)?;
        check_range("cloud edge", self.edge, 0.0, 1.0)?;
        Ok(())
    }
}

/// Opacity of one cloud at normalised radius ρ: 1 inside 1 − edge, smooth-step to 0 at ρ = 1.
#[inline]
fn opacity(rho: f64, edge: f64) -> f64 {
    if rho >= 1.0 {
        0.0
    } else if edge <= 0.0 || rho <= 1.0 - edge {
        1.0
    } else {
        let x = (1.0 - rho) / edge;
        x * x * (3.0 - 2.0 * x)
    }
}

/// Blends seeded soft clouds into `stokes`; returns the opacity map (row-major, 0..1).
pub fn apply_soft_clouds(stokes: &mut StokesImage, p: &SoftClouds, seed: u64) -> Result<Vec<f32>> {
    p.validate()?;
    let (w, h) = (stokes.width(), stokes.height());
    let mut rng = crate::rng::scene_rng(seed, 1);
    let ellipses = draw_ellipses(w, h, &mut rng, p.count, p.min_axis_frac, p.max_axis_frac);
    let mut sky: Vec<f32> = stokes
        .s0
        .data
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let median = if sky.is_empty() {
        0.0
    } else {
        let m = sky.len() / 2;
        *sky.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1 as f64
    };
    let lc = p.brightness * median;
    let mut alpha = vec![0f32; w * h];
    let StokesImage { s0, s1, s2 } = stokes;
    alpha
        .par_chunks_mut(w.max(1))
        .zip(s0.data.par_chunks_mut(w.max(1)))
        .zip(s1.data.par_chunks_mut(w.max(1)))
        .zip(s2.data.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(r, (((al, a), b), c))| {
            let live: Vec<&Ellipse> = ellipses
                .iter()
                .filter(|e| {
                    let (lo, hi) = e.row_span(h, 1.0);
                    r >= lo && r <= hi
                })
                .collect();
            if live.is_empty() {
                return;
            }
            for i in 0..w {
                if a[i].is_nan() || a[i] <= 0.0 {
                    continue;
                }
                let mut clear = 1.0;
                for e in &live {
                    clear *= 1.0 - opacity(e.rho(i as f64, r as f64), p.edge);
                }
                let al_i = 1.0 - clear;
                if al_i > 0.0 {
                    a[i] = ((1.0 - al_i) * a[i] as f64 + al_i * lc) as f32;
                    b[i] = ((1.0 - al_i) * b[i] as f64) as f32;
                    c[i] = ((1.0 - al_i) * c[i] as f64) as f32;
                    al[i] = al_i as f32;
                }
            }
        });
    Ok(alpha)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;

    #[test]
    fn psns_ellipse_counts_and_sizes() {
        let mut rng = crate::rng::frame_rng(3, 0, 4, 0);
        for _ in 0..50 {
            let e = psns_ellipses(400, 300, &mut rng);
            assert!((3..=8).contains(&e.len()));
            for x in &e {
                assert!(x.a >= 20.0 && x.a <= 80.0 && x.b >= 20.0 && x.b <= 80.0);
            }
        }
        let one = [Ellipse {
            cx: 10.0,
            cy: 10.0,
            a: 5.0,
            b: 2.0,
            angle: 0.0,
        }];
        let m = ellipse_mask(20, 20, &one);
        assert!(m[10 * 20 + 14] && !m[10 * 20 + 16] && m[12 * 20 + 10] && !m[13 * 20 + 10]);
    }

    /// The mask tests ρ only inside each row's column span: it must equal the test at every
    /// pixel, for fat, thin, tiny, rotated and off-image ellipses.
    #[test]
    fn ellipse_mask_equals_the_test_at_every_pixel() {
        let (w, h) = (97, 61);
        let mut rng = crate::rng::scene_rng(11, 0);
        let mut inside = 0;
        for k in 0..300 {
            let e = Ellipse {
                cx: rng.random::<f64>() * 140.0 - 20.0,
                cy: rng.random::<f64>() * 100.0 - 20.0,
                a: 0.3 + rng.random::<f64>() * if k % 3 == 0 { 2.0 } else { 60.0 },
                b: 0.3 + rng.random::<f64>() * if k % 5 == 0 { 1.0 } else { 40.0 },
                angle: if k % 7 == 0 {
                    0.0
                } else {
                    rng.random::<f64>() * std::f64::consts::PI
                },
            };
            let m = ellipse_mask(w, h, &[e]);
            for r in 0..h {
                for c in 0..w {
                    let want = e.rho(c as f64, r as f64) <= 1.0;
                    assert_eq!(m[r * w + c], want, "ellipse {e:?} pixel ({c}, {r})");
                    inside += want as usize;
                }
            }
        }
        assert!(inside > 10_000, "the ellipses cover pixels ({inside})");
    }

    #[test]
    fn soft_clouds_unpolarized_and_soft() {
        let (w, h) = (64, 48);
        let mk = |v: f32| Image::from_vec(w, h, vec![v; w * h]);
        let mut s = StokesImage {
            s0: mk(0.1),
            s1: mk(0.03),
            s2: mk(-0.02),
        };
        let p = SoftClouds {
            count: 3,
            ..Default::default()
        };
        let a = apply_soft_clouds(&mut s, &p, 9).unwrap();
        assert!(a.contains(&1.0), "some pixel fully cloudy");
        assert!(a.iter().any(|&x| x > 0.0 && x < 1.0), "soft rim");
        for (k, &al) in a.iter().enumerate().take(w * h) {
            let al = al as f64;
            let want0 = (1.0 - al) * 0.1 + al * 0.25;
            assert!((s.s0.data[k] as f64 - want0).abs() < 1e-6);
            assert!((s.s1.data[k] as f64 - (1.0 - al) * 0.03).abs() < 1e-6);
        }
        // same seed, same clouds
        let mut s2 = StokesImage {
            s0: mk(0.1),
            s1: mk(0.03),
            s2: mk(-0.02),
        };
        assert_eq!(apply_soft_clouds(&mut s2, &p, 9).unwrap(), a);
    }
}
