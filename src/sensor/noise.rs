//! Random streams, fixed-pattern maps and the sampling kernels of the electron-domain pipeline
//! (`sensor.md` §6).
//!
//! The seeded random streams themselves are in [`crate::rng`].

use crate::rng::map_rng;
use rand::Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use rayon::prelude::*;

/// Fixed-pattern map id: polarizer orientation error δ_k.
pub const MAP_ORIENTATION: u32 = 1;
/// Fixed-pattern map id: PRNU gain g_k.
pub const MAP_PRNU: u32 = 2;
/// Fixed-pattern map id: DSNU offset.
pub const MAP_DSNU: u32 = 3;

/// Temporal stage id: shot noise (Poisson), dark current included.
pub const STAGE_SHOT: u32 = 1;
/// Temporal stage id: read noise N(0, σ_d²).
pub const STAGE_READ: u32 = 2;
/// Temporal stage id: PSNS additive Gaussian white noise.
pub const STAGE_PSNS_NOISE: u32 = 3;
/// Temporal stage id: PSNS ellipse clouds (one stream, row 0).
pub const STAGE_PSNS_CLOUDS: u32 = 4;

/// A `width` x `height` map of `offset + sigma · N(0, 1)`, one stream per row.
pub fn gaussian_map(
    width: usize,
    height: usize,
    seed: u64,
    map_id: u32,
    offset: f64,
    sigma: f64,
) -> Vec<f32> {
    let mut out = vec![0f32; width * height];
    out.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            let mut rng = map_rng(seed, map_id, r as u64);
            for v in row.iter_mut() {
                let z: f64 = rng.sample(StandardNormal);
                *v = (offset + sigma * z) as f32;
            }
        });
    out
}

/// Above this mean the Poisson draw uses N(μ, μ): such pixels are far above any full well and
/// `rand_distr` limits λ (its `MAX_LAMBDA` ≈ 1.8e19).
const POISSON_NORMAL_ABOVE: f64 = 1e15;

/// Below this mean the draw uses `rand_distr` (Knuth's multiplication method below 12).
const POISSON_PTRS_ABOVE: f64 = 12.0;

/// One draw of Poisson(`mean`) as f64; exact for every mean a sensor can hold: `rand_distr`
/// (Knuth's method) below 12, Hörmann's PTRS transformed rejection with squeeze above
/// (W. Hörmann, "The transformed rejection method for generating Poisson random variables",
/// Insurance: Mathematics and Economics 12, 1993; the algorithm NumPy uses), and N(μ, μ) only
/// above 1e15 e⁻. Non-positive or non-finite means give 0.
#[inline(always)]
pub fn poisson<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> f64 {
    poisson_with(rng, mean, ptrs_consts(mean), ptrs_tables())
}

/// PTRS's constants (b, a, v_r) of mean λ, as [`poisson_with`] takes them.
#[inline(always)]
pub(crate) fn ptrs_consts(lam: f64) -> [f64; 3] {
    let slam = lam.sqrt();
    let b = 0.931 + 2.53 * slam;
    let a = -0.059 + 0.02483 * b;
    let vr = 0.9277 - 3.6224 / (b - 2.0);
    [b, a, vr]
}

/// [`poisson`] given [`ptrs_consts`]`(mean)` (a row loop computes them for every pixel first,
/// vectorised: the square root and the division leave the loop of draws) and [`ptrs_tables`].
#[inline(always)]
pub(crate) fn poisson_with<R: Rng + ?Sized>(
    rng: &mut R,
    mean: f64,
    c: [f64; 3],
    t: &PtrsTables,
) -> f64 {
    // the usual sky pixel first; range tests rather than `is_finite`, which compiled to ~20
    // integer instructions (NaN is in no range)
    if (POISSON_PTRS_ABOVE..POISSON_NORMAL_ABOVE).contains(&mean) {
        poisson_ptrs(rng, mean, c, t)
    } else if mean > 0.0 && mean < POISSON_PTRS_ABOVE {
        poisson_knuth(rng, mean)
    } else if (POISSON_NORMAL_ABOVE..f64::INFINITY).contains(&mean) {
        poisson_huge(rng, mean)
    } else {
        0.0
    }
}

// Kept out of line: the PTRS loop of a row of sky pixels stays small.
#[inline(never)]
fn poisson_knuth<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> f64 {
    match Poisson::new(mean) {
        Ok(p) => p.sample(rng),
        Err(_) => 0.0,
    }
}

#[cold]
#[inline(never)]
fn poisson_huge<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> f64 {
    let z: f64 = rng.sample(StandardNormal);
    (mean + mean.sqrt() * z).max(0.0)
}

/// A uniform f64 in [0, 1): `rng.random::<f64>()` (53 bits times 2⁻⁵³), inline.
#[inline(always)]
fn uniform<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// PTRS for λ ≥ 10 (Hörmann 1993, algorithm PTRS): the first candidate and the squeeze inline
/// (it accepts ~77 % of the draws of a sky frame); everything else in [`ptrs_rest`].
#[inline(always)]
fn poisson_ptrs<R: Rng + ?Sized>(
    rng: &mut R,
    lam: f64,
    [b, a, vr]: [f64; 3],
    t: &PtrsTables,
) -> f64 {
    let u = uniform(rng) - 0.5;
    let v = uniform(rng);
    let us = 0.5 - u.abs();
    let k = ((2.0 * a / us + b) * u + lam + 0.43).floor();
    if us >= 0.07 && v <= vr {
        return k;
    }
    ptrs_rest(rng, t, lam, a, b, vr, v, us, k)
}

/// The rest of PTRS from a rejected first squeeze: the same candidates and the same decisions
/// as the reference loop ([`ptrs_accepts`]), so the same draws and results.
///
/// Each decision compares L = ln v + ln(1/α) − ln(a/u_s² + b) with R = −λ + k ln λ − ln k!. It is
/// first made with [`ln_fast`] (within 2e-15 + 6e-16 |ln x| of ln, as libm's `ln` is within an
/// ulp); only when the two sides are within `tol` of each other is it made again exactly as the
/// reference does. `tol` is 1e-13 of the sum S of the terms' magnitudes (with 2(k + 1) for the
/// terms inside ln k!). The two computations differ by less than 5e-15 S: the logarithms' errors,
/// k ln λ and (k + ½) ln(k + 1) carrying them k-fold (each k-fold product below S), and a few
/// roundings of each side, each below 1.2e-16 S. So a filtered decision is the reference's, with
/// a factor of 20 to spare; the tests compare ~4 M draws with the reference's. With no libm
/// call left (the reference test is out of line) it is inlined into the row kernel, built per
/// instruction set.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn ptrs_rest<R: Rng + ?Sized>(
    rng: &mut R,
    t: &PtrsTables,
    lam: f64,
    a: f64,
    b: f64,
    vr: f64,
    mut v: f64,
    mut us: f64,
    mut k: f64,
) -> f64 {
    let alpha_arg = 1.1239 + 1.1328 / (b - 3.4);
    let (loglam_f, lia_f) = (ln_fast(t, lam), ln_fast(t, alpha_arg));
    loop {
        if !(k < 0.0 || (us < 0.013 && v > us)) {
            let q = a / (us * us) + b;
            // ln_fast needs a normal argument: v = 0 (ln v = −∞) takes the exact test
            let filtered = if v >= f64::MIN_POSITIVE {
                let (lv, lq) = (ln_fast(t, v), ln_fast(t, q));
                // k ≥ 0 here; the table holds the reference's own values
                let lf = match t.ln_factorial.get(k as usize) {
                    Some(&f) => f,
                    None => ln_factorial_with(k, |n| ln_fast(t, n)),
                };
                let kl = k * loglam_f;
                let d = (lv + lia_f - lq) - (-lam + kl - lf);
                let tol = 1e-13
                    * (1.0
                        + lv.abs()
                        + lia_f.abs()
                        + lq.abs()
                        + lam
                        + kl.abs()
                        + lf.abs()
                        + 2.0 * (k + 1.0));
                if d < -tol {
                    Some(true)
                } else if d > tol {
                    Some(false)
                } else {
                    None
                }
            } else {
                None
            };
            let accept = filtered.unwrap_or_else(|| {
                #[cfg(test)]
                tests::FALLBACKS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                ptrs_accepts(lam, a, b, v, us, k)
            });
            if accept {
                return k;
            }
        }
        let u = uniform(rng) - 0.5;
        v = uniform(rng);
        us = 0.5 - u.abs();
        k = ((2.0 * a / us + b) * u + lam + 0.43).floor();
        if us >= 0.07 && v <= vr {
            return k;
        }
    }
}

/// The reference acceptance test of PTRS (after the squeeze and the k < 0 and tail rejections).
/// Its logarithms are computed here, out of line: computed lazily in the loop, the compiler would
/// hoist them into every call of [`ptrs_rest`].
#[cold]
#[inline(never)]
fn ptrs_accepts(lam: f64, a: f64, b: f64, v: f64, us: f64, k: f64) -> bool {
    let (loglam, log_inv_alpha) = (lam.ln(), (1.1239 + 1.1328 / (b - 3.4)).ln());
    v.ln() + log_inv_alpha - (a / (us * us) + b).ln() <= -lam + k * loglam - ln_factorial(k)
}

/// Tables of PTRS's rejection branch: ln k! for k < 2¹⁵ as [`ln_factorial`] gives it, and
/// [`ln_fast`]'s table: for m in [1 + i/128, 1 + (i + 1)/128), c ≈ 1/m at the interval's centre
/// and −ln c by libm.
pub(crate) struct PtrsTables {
    ln_factorial: Vec<f64>,
    ln: [[f64; 2]; 128],
}

/// The tables of PTRS (built on first use, ~1 ms).
pub(crate) fn ptrs_tables() -> &'static PtrsTables {
    static T: std::sync::OnceLock<PtrsTables> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut ln = [[0.0; 2]; 128];
        for (i, e) in ln.iter_mut().enumerate() {
            let c = 1.0 / (1.0 + (i as f64 + 0.5) / 128.0);
            *e = [c, -c.ln()];
        }
        PtrsTables {
            ln_factorial: (0..1u32 << 15).map(|k| ln_factorial(k as f64)).collect(),
            ln,
        }
    })
}

/// ln x for normal x > 0, within 2e-15 + 6e-16 |ln x| of the exact value: x = 2ᵉ m, m in [1, 2),
/// ln x = e ln 2 − ln c + ln(1 + r) with r = m c − 1, |r| < 1/255 (c from a 128-entry table), the
/// series of ln(1 + r) to r⁵ (the rest is below r⁶/6 < 1e-15). For [`ptrs_rest`]'s filtered
/// decision only: inline, short dependency chains, no libm call.
#[inline(always)]
fn ln_fast(t: &PtrsTables, x: f64) -> f64 {
    let bits = x.to_bits();
    let e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let [c, minus_ln_c] = t.ln[((bits >> 45) & 0x7f) as usize];
    let r = m * c - 1.0;
    let r2 = r * r;
    let p = r - r2 * 0.5 + r2 * r * (1.0 / 3.0 - r * 0.25 + r2 * 0.2);
    (e as f64 * std::f64::consts::LN_2 + minus_ln_c) + p
}

/// ln k! (exact table to 9, Stirling series with three correction terms above).
fn ln_factorial(k: f64) -> f64 {
    ln_factorial_with(k, f64::ln)
}

/// [`ln_factorial`] with the logarithm `ln`.
#[inline(always)]
fn ln_factorial_with(k: f64, ln: impl Fn(f64) -> f64) -> f64 {
    const T: [f64; 10] = [
        0.0,
        0.0,
        std::f64::consts::LN_2,
        1.791_759_469_228_055,
        3.178_053_830_347_146,
        4.787_491_742_782_046,
        6.579_251_212_010_101,
        8.525_161_361_065_415,
        10.604_602_902_745_25,
        12.801_827_480_081_469,
    ];
    if k < 10.0 {
        return T[k as usize];
    }
    let n = k + 1.0; // ln Γ(n)
    let inv = 1.0 / n;
    let inv2 = inv * inv;
    (n - 0.5) * ln(n) - n
        + 0.918_938_533_204_672_8
        + inv * (1.0 / 12.0 - inv2 * (1.0 / 360.0 - inv2 / 1260.0))
}

/// One standard-normal draw (`rand_distr::StandardNormal`).
#[inline]
pub fn normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    rng.sample(StandardNormal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::frame_rng;
    use rand::RngCore;

    #[test]
    fn key_derivation_golden() {
        // Golden values of the key derivation (sensor.md §6): a change here changes every camera.
        let mut a = map_rng(42, MAP_PRNU, 7);
        let mut b = frame_rng(42, 3, STAGE_SHOT, 7);
        let (x, y) = (a.next_u64(), b.next_u64());
        assert_ne!(x, y);
        assert_eq!(x, map_rng(42, MAP_PRNU, 7).next_u64());
        assert_eq!(
            crate::rng::key(0x0102030405060708, 9, 2, 1, 5)[..],
            [
                8, 7, 6, 5, 4, 3, 2, 1, 9, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 5, 0, 0, 0,
                0, 0, 0, 0
            ]
        );
        assert_eq!(x, GOLDEN_MAP_PRNU_42_7);
        assert_eq!(y, GOLDEN_SHOT_42_3_7);
    }
    // Recorded from the first implementation (rand_chacha 0.9 ChaCha8, key layout above).
    const GOLDEN_MAP_PRNU_42_7: u64 = 3222751305945780762;
    const GOLDEN_SHOT_42_3_7: u64 = 13565395923466616630;

    /// PTRS against the exact pmf (chi-square over the bulk) at several means, and ln k!.
    #[test]
    fn ptrs_matches_pmf() {
        for k in [10.0f64, 11.0, 30.0, 170.0] {
            let exact: f64 = (1..=k as u64).map(|i| (i as f64).ln()).sum();
            assert!((ln_factorial(k) - exact).abs() < 1e-10, "{k}");
        }
        for lam in [12.0f64, 37.5, 400.0, 1e4] {
            let mut rng = frame_rng(3, 0, STAGE_SHOT, lam as u64);
            let n = 200_000usize;
            let sd = lam.sqrt();
            let lo = (lam - 3.0 * sd).floor().max(0.0) as i64;
            let hi = (lam + 3.0 * sd).ceil() as i64;
            // bins of ~sd/4 width
            let w = ((sd / 4.0).floor() as i64).max(1);
            let nb = ((hi - lo) / w + 1) as usize;
            let mut obs = vec![0f64; nb];
            let (mut sum, mut sum2) = (0.0, 0.0);
            for _ in 0..n {
                let x = poisson(&mut rng, lam);
                assert_eq!(x, x.floor());
                sum += x;
                sum2 += x * x;
                let xi = x as i64;
                if xi >= lo && xi < lo + nb as i64 * w {
                    obs[((xi - lo) / w) as usize] += 1.0;
                }
            }
            let mut exp = vec![0f64; nb];
            for x in lo..lo + nb as i64 * w {
                let lp = -lam + x as f64 * lam.ln() - ln_factorial(x as f64);
                exp[((x - lo) / w) as usize] += n as f64 * lp.exp();
            }
            let chi2: f64 = obs
                .iter()
                .zip(&exp)
                .filter(|(_, &e)| e > 20.0)
                .map(|(o, e)| (o - e) * (o - e) / e)
                .sum();
            let dof = exp.iter().filter(|&&e| e > 20.0).count() as f64;
            // chi-square with ~dof degrees of freedom: mean dof, sd sqrt(2 dof)
            assert!(
                chi2 < dof + 5.0 * (2.0 * dof).sqrt(),
                "λ {lam}: χ² {chi2} dof {dof}"
            );
            let m = sum / n as f64;
            let v = sum2 / n as f64 - m * m;
            assert!(
                (m - lam).abs() < 5.0 * sd / (n as f64).sqrt(),
                "λ {lam} mean {m}"
            );
            assert!((v / lam - 1.0).abs() < 0.02, "λ {lam} var {v}");
        }
    }

    /// Filtered decisions taken exactly (counted by `ptrs_same_as_reference`).
    pub(super) static FALLBACKS: std::sync::atomic::AtomicU64 =
        std::sync::atomic::AtomicU64::new(0);

    /// PTRS as it was written before the filtered decision: the reference of every exact frame.
    fn ptrs_reference<R: Rng + ?Sized>(rng: &mut R, lam: f64) -> f64 {
        let slam = lam.sqrt();
        let b = 0.931 + 2.53 * slam;
        let a = -0.059 + 0.02483 * b;
        let vr = 0.9277 - 3.6224 / (b - 2.0);
        let mut slow: Option<(f64, f64)> = None;
        loop {
            let u = rng.random::<f64>() - 0.5;
            let v = rng.random::<f64>();
            let us = 0.5 - u.abs();
            let k = ((2.0 * a / us + b) * u + lam + 0.43).floor();
            if us >= 0.07 && v <= vr {
                return k;
            }
            if k < 0.0 || (us < 0.013 && v > us) {
                continue;
            }
            let (loglam, log_inv_alpha) =
                *slow.get_or_insert_with(|| (lam.ln(), (1.1239 + 1.1328 / (b - 3.4)).ln()));
            if v.ln() + log_inv_alpha - (a / (us * us) + b).ln()
                <= -lam + k * loglam - ln_factorial(k)
            {
                return k;
            }
        }
    }

    /// The same draws and results as the reference, and the generator left in the same place,
    /// over ~1 M decisions of the slow branch at means from 12 to 1.2e12 e⁻; few decisions fall
    /// back to the exact test below 1.2e7 e⁻.
    #[test]
    fn ptrs_same_as_reference() {
        use std::sync::atomic::Ordering::Relaxed;
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let (mut draws, mut fell_back) = (0u64, 0u64);
        for row in 0..40u64 {
            let mut a = frame_rng(5, row, STAGE_SHOT, row);
            let mut b = a.clone();
            for _ in 0..100_000 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // log-uniform means over 12 .. 1.2e12, some repeated exactly
                let lam = 12.0 * 10f64.powf((x >> 11) as f64 / (1u64 << 53) as f64 * 11.0);
                // rows 0..30: 12 .. 1.2e7 (sky levels and far above), the rest up to 1.2e12
                let lam = if row < 30 {
                    lam.powf(6.0 / 11.0) * 12f64.powf(5.0 / 11.0)
                } else {
                    lam
                };
                let n0 = FALLBACKS.load(Relaxed);
                let (p, q) = (poisson(&mut a, lam), ptrs_reference(&mut b, lam));
                assert_eq!(p.to_bits(), q.to_bits(), "λ {lam}");
                if row < 30 {
                    draws += 1;
                    fell_back += FALLBACKS.load(Relaxed) - n0;
                }
            }
            assert_eq!(a.next_u64(), b.next_u64());
        }
        assert!(
            fell_back * 1_000 < draws,
            "{fell_back} exact decisions in {draws} draws"
        );
    }

    /// `ln_fast` against libm over the arguments PTRS gives it.
    #[test]
    fn ln_fast_error() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..2_000_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let e = (x % 200) as i32 - 60;
            let m = 1.0 + (x >> 11) as f64 / (1u64 << 53) as f64;
            let v = m * 2f64.powi(e);
            let (f, l) = (ln_fast(ptrs_tables(), v), v.ln());
            assert!((f - l).abs() <= 2e-15 + 6e-16 * l.abs(), "{v}: {f} vs {l}");
        }
        for v in [
            f64::MIN_POSITIVE,
            2f64.powi(-53),
            0.5,
            1.0,
            2.0,
            std::f64::consts::SQRT_2,
            1e300,
        ] {
            let (f, l) = (ln_fast(ptrs_tables(), v), v.ln());
            assert!((f - l).abs() <= 2e-15 + 6e-16 * l.abs(), "{v}");
        }
    }

    #[test]
    fn poisson_edge_cases() {
        let mut r = frame_rng(1, 0, STAGE_SHOT, 0);
        assert_eq!(poisson(&mut r, 0.0), 0.0);
        assert_eq!(poisson(&mut r, -3.0), 0.0);
        assert_eq!(poisson(&mut r, f64::NAN), 0.0);
        let big = poisson(&mut r, 1e18);
        assert!(big.is_finite() && big > 9e17);
        let huge = poisson(&mut r, 1e25);
        assert!(huge.is_finite() && huge > 0.0);
    }
}
