//! The fast sensor path (`docs/sensor.md` "Fast and exact"): the same camera model as
//! [`super::Sensor::frame`], restructured for speed.
//!
//! What changes against the exact path, and what it costs:
//! - **Random numbers** come from a counter-based generator of (camera seed, frame, stage, row,
//!   column), five AES rounds per four pixels, instead of per-row ChaCha8 streams: any pixel's
//!   noise is computed independently, so frames do not depend on threads or on row order, and
//!   the kernel vectorises ([`super::normal`]).
//! - **Normal deviates** by inversion, z = Φ⁻¹(u) with u on a 2⁻²³ lattice in (0, 1), from a
//!   polynomial per binade of the tail probability ([`super::normal`]; absolute error below
//!   3.2e-5, far below what a code can show): tails reach |z| = 5.3.
//! - **Shot noise** stays Poisson in distribution: below [`EXACT_POISSON_BELOW`] e⁻ exact
//!   inversion of the Poisson CDF; above it a normal with a Cornish–Fisher skew correction,
//!   μ + √μ z + (z² − 1)/6, rounded to whole electrons: mean, variance (+1/12 + 1/36) and third
//!   cumulant of Poisson(μ).
//! - **Read noise folded in** when σ_read ≥ 1 e⁻: Poisson(μ) + N(0, σ²) is drawn as one
//!   Cornish–Fisher normal with mean μ, variance μ + σ² and third cumulant μ. The whole-electron
//!   lattice of the Poisson part is then invisible: its characteristic function at frequency 1 is
//!   damped by exp(−2π²σ²) ≤ 3e-9. This holds at any mean, so only pixels that may reach the full
//!   well take the unfolded path (whole electrons, clip, then DSNU and read noise); with σ_read < 1
//!   e⁻ every pixel does.
//! - f32 arithmetic throughout; an AVX2 kernel written for the CPU's pipes ([`avx2`]: AES-NI
//!   draws, in-register table reads, the square root and division on the divider beside the
//!   multiply-adds), its AVX-512 twin ([`avx512`], VAES), a portable one elsewhere, the same bits
//!   in all three.
//!
//! Everything else (optics, polarizer with its orientation error, PRNU, RI, dark current, DSNU,
//! full well, gain, black level, ADC) is the exact path's model with the exact path's fixed-pattern
//! maps, folded into four 16-bit fixed-point numbers per pixel ([`FastStatics`]).

use super::{FastSink, Sensor};
use crate::image::StokesRows;
use rayon::prelude::*;

use super::normal::{normal_from_bits, uniform_from_bits, NoiseKey};
use crate::simd::simd_dispatch;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

/// Below this mean (e⁻) shot noise is sampled exactly by inversion of the Poisson CDF.
pub const EXACT_POISSON_BELOW: f64 = 16.0;

/// Read noise at or above this σ (e⁻) is folded into the shot-noise draw.
pub const FOLD_READ_NOISE_FROM: f64 = 1.0;

/// Quantum of the gain g = RI · PRNU (range 0..2) and of the polarizer terms b cos 2θ and
/// b sin 2θ (range ±1): 3e-5.
const COEF_UNIT: f32 = 1.0 / 32_768.0;
/// Quantum of the DSNU, e⁻ (range ±32 e⁻; σ is at most 2 e⁻).
const DSNU_UNIT: f32 = 1.0 / 1024.0;
/// The polarizer orientation error is clamped to ±0.25 rad (14°; σ is at most 2°).
const DELTA_MAX: f64 = 0.25;

/// Per-camera static data of the fast path, 8 bytes per pixel (memory traffic, not arithmetic,
/// limits a per-pixel table): the electron rate is c · max(g (S0 + p_c S1 + p_s S2), 0) with
/// g = RI · PRNU, p_c = b cos 2θ and p_s = b sin 2θ, θ the pixel's pass axis (nominal plus its
/// orientation error δ), b the polarizer's diattenuation; and the DSNU. Each a 16-bit
/// fixed-point number with quanta far below their effect on a frame.
#[derive(Clone, Debug)]
pub struct FastStatics {
    /// g in units of [`COEF_UNIT`].
    gain: Vec<u16>,
    /// p_c and p_s in units of [`COEF_UNIT`].
    pol: [Vec<i16>; 2],
    /// DSNU in units of [`DSNU_UNIT`].
    dsnu: Vec<i16>,
    /// c: η · photon rate · a · [`COEF_UNIT`]² (e⁻/s per unit radiance and per unit of
    /// [`StaticRow::weighted`]).
    scale: f32,
}

/// A zeroed buffer whose first element sits on a 64-byte boundary (a `Vec<f32>` is only
/// promised 4-byte alignment): whole-vector loads and stores of a row then never straddle two
/// cache lines. Used for the row scratch, which the interpolation writes and the kernel reads.
struct Aligned<T> {
    buf: Vec<T>,
    off: usize,
    len: usize,
}

impl<T: Copy + Default> Aligned<T> {
    fn new(len: usize) -> Self {
        let pad = 64 / std::mem::size_of::<T>().max(1);
        let buf = vec![T::default(); len + pad];
        // T's own alignment divides 64, so fewer than `pad` elements reach the boundary
        let off = buf.as_ptr().align_offset(64).min(pad);
        Aligned { buf, off, len }
    }
}

impl<T> std::ops::Deref for Aligned<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.buf[self.off..self.off + self.len]
    }
}

impl<T> std::ops::DerefMut for Aligned<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.buf[self.off..self.off + self.len]
    }
}

/// `v` in units of `unit` (a power of two: the product is exact), rounded and clamped.
#[inline(always)]
fn fixed(v: f64, unit: f32) -> i16 {
    (v * (1.0 / unit as f64)).round().clamp(-32_768.0, 32_767.0) as i16
}

/// [`fixed`] for a non-negative value.
#[inline(always)]
fn fixed_u(v: f64, unit: f32) -> u16 {
    (v * (1.0 / unit as f64)).round().clamp(0.0, 65_535.0) as u16
}

/// cos x and sin x for |x| ≤ 0.5 by their Taylor series to x¹¹ (error below 2e-11), in plain
/// multiplications and additions: the same bits in every build, unlike a library call.
#[inline(always)]
fn cos_sin_small(x: f64) -> (f64, f64) {
    let x2 = x * x;
    // 1/((2k − 1) 2k) and 1/(2k (2k + 1)), k = 1..5
    const C: [f64; 5] = [1.0 / 2.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 56.0, 1.0 / 90.0];
    const S: [f64; 5] = [1.0 / 6.0, 1.0 / 20.0, 1.0 / 42.0, 1.0 / 72.0, 1.0 / 110.0];
    let (mut c, mut s) = (1.0, 1.0);
    for k in (0..5).rev() {
        c = 1.0 - x2 * C[k] * c;
        s = 1.0 - x2 * S[k] * s;
    }
    (c, x * s)
}

/// One row of [`FastStatics::new`] from the sensor's f32 maps (ones or zeros where a map is
/// off): RI, PRNU, the orientation error δ in degrees and the DSNU; `c0`, `s0` the nominal
/// cos 2θ₀ and sin 2θ₀ per column and `b` the diattenuation. Slices of one length and no
/// branches, so the loop vectorises.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn statics_row_body(
    ri: &[f32],
    prnu: &[f32],
    delta_deg: &[f32],
    dsnu: &[f32],
    c0: &[f64],
    s0: &[f64],
    b: f64,
    g: &mut [u16],
    pol: [&mut [i16]; 2],
    n: &mut [i16],
) {
    let w = g.len();
    let [pc, ps] = pol;
    let (ri, prnu, delta_deg, dsnu) = (&ri[..w], &prnu[..w], &delta_deg[..w], &dsnu[..w]);
    let (c0, s0, pc, ps, n) = (&c0[..w], &s0[..w], &mut pc[..w], &mut ps[..w], &mut n[..w]);
    for c in 0..w {
        let gk = ri[c] as f64 * prnu[c] as f64;
        let d = (delta_deg[c] as f64)
            .to_radians()
            .clamp(-DELTA_MAX, DELTA_MAX);
        let (cs, sn) = cos_sin_small(2.0 * d);
        g[c] = fixed_u(gk, COEF_UNIT);
        pc[c] = fixed(b * (c0[c] * cs - s0[c] * sn), COEF_UNIT);
        ps[c] = fixed(b * (s0[c] * cs + c0[c] * sn), COEF_UNIT);
        n[c] = fixed(dsnu[c] as f64, DSNU_UNIT);
    }
}

simd_dispatch! {
    /// [`statics_row_body`] built for the best instruction set the CPU has (`round` inline
    /// from SSE4.1 on instead of a library call; the same values).
    fn statics_row = statics_row_body(
        ri: &[f32],
        prnu: &[f32],
        delta_deg: &[f32],
        dsnu: &[f32],
        c0: &[f64],
        s0: &[f64],
        b: f64,
        g: &mut [u16],
        pol: [&mut [i16]; 2],
        n: &mut [i16],
    )
}

impl FastStatics {
    /// Folds the sensor's maps (the exact path's, same seed) into the fixed-point maps.
    pub fn new(s: &Sensor) -> Self {
        let (w, h) = (s.intrinsics.width, s.intrinsics.height);
        let (a, b, base) = s.rate_coefficients();
        let cfg = &s.cfg;
        let delta_deg = s.oriented.then(|| {
            super::noise::gaussian_map(
                w,
                h,
                s.seed,
                super::noise::MAP_ORIENTATION,
                0.0,
                cfg.orientation_sigma_deg,
            )
        });
        // nominal (cos 2θ₀, sin 2θ₀) of even and odd rows
        let axis: [[Vec<f64>; 2]; 2] = std::array::from_fn(|r| {
            std::array::from_fn(|k| {
                let pick = |(co, si): (f64, f64)| [co, si][k];
                (0..w)
                    .map(|c| pick(super::nominal_axis(&cfg.layout, r, c)))
                    .collect()
            })
        });
        let (ones, zeros) = (vec![1f32; w], vec![0f32; w]);
        let mut gain = vec![0u16; w * h];
        let mut pol: [Vec<i16>; 2] = std::array::from_fn(|_| vec![0i16; w * h]);
        let mut dsnu = vec![0i16; w * h];
        let [pc, ps] = &mut pol;
        gain.par_chunks_mut(w)
            .zip(pc.par_chunks_mut(w))
            .zip(ps.par_chunks_mut(w))
            .zip(dsnu.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, (((g, pc), ps), n))| {
                fn row<'a>(m: Option<&'a Vec<f32>>, off: &'a [f32], r: usize) -> &'a [f32] {
                    let w = off.len();
                    m.map_or(off, |m| &m[r * w..(r + 1) * w])
                }
                statics_row(
                    row(s.ri.as_ref(), &ones, r),
                    row(s.prnu.as_ref(), &ones, r),
                    row(delta_deg.as_ref(), &zeros, r),
                    row(s.dsnu.as_ref(), &zeros, r),
                    &axis[r & 1][0],
                    &axis[r & 1][1],
                    b,
                    g,
                    [pc, ps],
                    n,
                );
            });
        FastStatics {
            gain,
            pol,
            dsnu,
            scale: (base * a) as f32 * COEF_UNIT * COEF_UNIT,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        2 * (self.gain.len() + self.pol[0].len() + self.pol[1].len() + self.dsnu.len())
    }

    /// The static data of row `r` (columns k0..k0 + w of the maps).
    fn row(&self, r: usize, w: usize) -> StaticRow<'_> {
        let k = r * w..(r + 1) * w;
        StaticRow {
            g: &self.gain[k.clone()],
            pc: &self.pol[0][k.clone()],
            ps: &self.pol[1][k.clone()],
            dsnu: &self.dsnu[k],
            scale: self.scale,
        }
    }
}

/// One row of [`FastStatics`].
#[derive(Clone, Copy)]
struct StaticRow<'a> {
    g: &'a [u16],
    pc: &'a [i16],
    ps: &'a [i16],
    dsnu: &'a [i16],
    scale: f32,
}

/// 1/[`COEF_UNIT`]: S0 scaled to the polarizer terms' unit (a power of two: exact).
const S0_SCALE: f32 = 32_768.0;

impl StaticRow<'_> {
    /// g (S0 + p_c S1 + p_s S2) of column c in units of [`COEF_UNIT`]², clamped at 0 (the
    /// rate in units of 1/scale).
    #[inline(always)]
    fn weighted(&self, c: usize, s0: f32, s1: f32, s2: f32) -> f32 {
        let acc = (self.pc[c] as f32).mul_add(s1, s0 * S0_SCALE);
        let acc = (self.ps[c] as f32).mul_add(s2, acc);
        let acc = self.g[c] as f32 * acc;
        // NaN and −0 to +0, as the vector max does
        if acc > 0.0 {
            acc
        } else {
            0.0
        }
    }
    /// Electron rate (e⁻/s) of column c for Stokes (s0, s1, s2).
    #[inline(always)]
    fn rate(&self, c: usize, s0: f32, s1: f32, s2: f32) -> f32 {
        self.weighted(c, s0, s1, s2) * self.scale
    }
    #[inline(always)]
    fn dsnu(&self, c: usize) -> f32 {
        self.dsnu[c] as f32 * DSNU_UNIT
    }
}

/// Per-frame constants of the kernel.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrameConsts {
    /// Exposure, s.
    pub t: f64,
    /// Dark electrons (mean), e⁻.
    pub dark_e: f64,
    pub fwc: f64,
    pub fwc_clip: bool,
    pub shot: bool,
    pub sigma_read: f64,
    /// Output DN per e⁻.
    pub kg: f64,
    /// Black level, output DN.
    pub black: f64,
    pub max: u16,
    pub shot_key: NoiseKey,
    pub read_key: NoiseKey,
}

impl FrameConsts {
    /// Read noise folded into the shot draw in the vector loop.
    fn folded(&self) -> bool {
        self.shot && self.fwc_clip && self.sigma_read >= FOLD_READ_NOISE_FROM
    }
    /// Means above this can reach the full well within 6 σ: the unfolded path clips them.
    fn mu_high(&self) -> f64 {
        // μ + 6 √(μ + σ²) = FWC, solved for μ (√ of a quadratic), conservative by one e⁻
        let s2 = self.sigma_read * self.sigma_read;
        let x = (-6.0 + (36.0 + 4.0 * (self.fwc + s2)).sqrt()) / 2.0; // x = √(μ + σ²)
        (x * x - s2 - 1.0).max(0.0)
    }
}

/// The f32 constants of the folded kernel.
#[derive(Clone, Copy, Debug)]
struct Folded {
    /// Mean electrons per unit of [`StaticRow::weighted`]: scale · exposure.
    k: f32,
    dark: f32,
    /// σ_read².
    var_r: f32,
    kg: f32,
    black: f32,
    maxf: f32,
}

impl Folded {
    fn new(fc: &FrameConsts, scale: f32) -> Self {
        Folded {
            k: scale * fc.t as f32,
            dark: fc.dark_e as f32,
            var_r: (fc.sigma_read * fc.sigma_read) as f32,
            kg: fc.kg as f32,
            black: fc.black as f32,
            maxf: fc.max as f32,
        }
    }

    /// One pixel of the folded kernel from its weighted radiance `wt` ([`StaticRow::weighted`]),
    /// DSNU `ds` (fixed point) and normal deviate `z`: (mean electrons, code). The vector
    /// kernels do these operations in this order.
    #[inline(always)]
    fn pixel(&self, wt: f32, ds: i16, z: f32) -> (f32, u16) {
        let m = wt.mul_add(self.k, self.dark);
        let var = m + self.var_r;
        let sd = var.sqrt();
        // Cornish–Fisher with skewness γ = m / var^1.5: sd (z + γ (z² − 1)/6)
        let g6 = m / (6.0 * var);
        let e = sd.mul_add(z, g6.mul_add(z.mul_add(z, -1.0), m));
        let v = self.kg.mul_add(e + ds as f32 * DSNU_UNIT, self.black);
        (m, adc_code(v, self.maxf))
    }
}

/// Rounds to the nearest integer, ties to even, for |x| < 2²² (larger f32 values pass
/// unchanged; from 2²³ on they are integers): the add of 1.5 · 2²³ does the rounding in the
/// FPU's default mode, so the loop vectorises without a rounding call.
#[inline(always)]
fn round_even(x: f32) -> f32 {
    const M: f32 = 12_582_912.0;
    if x.abs() < 4_194_304.0 {
        (x + M) - M
    } else {
        x
    }
}

/// ADC: the nearest code (ties to even) of `v` clamped to [0, max]; NaN reads as the top code,
/// as the vector minimum gives it.
#[inline(always)]
fn adc_code(v: f32, maxf: f32) -> u16 {
    let v = if v < maxf { v } else { maxf };
    (v.round_ties_even() as i32).clamp(0, 65_535) as u16
}

/// Lanes per chunk of the unfolded kernel.
const LANES: usize = 8;

/// The unfolded kernel for one chunk of up to [`LANES`] pixels from column `c0` of row `row`:
/// whole-electron shot noise (exact inversion below [`EXACT_POISSON_BELOW`], Cornish–Fisher
/// above), full-well clip, DSNU, read noise, ADC. Writes every lane whose `redo` flag is set;
/// returns a bit mask of lanes at full well.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn chunk_unfolded(
    fc: &FrameConsts,
    mu: &[f32],
    ds: &[f32],
    row: u32,
    c0: u32,
    redo: &[bool],
    out: &mut [u16],
) -> u32 {
    let n = mu.len();
    let mut m = [0f32; LANES];
    let mut u = [0f32; LANES];
    let mut z = [0f32; LANES];
    let mut zr = [0f32; LANES];
    for l in 0..n {
        let c = c0 + l as u32;
        let b = fc.shot_key.bits(row, c);
        z[l] = normal_from_bits(b);
        u[l] = uniform_from_bits(b);
        zr[l] = normal_from_bits(fc.read_key.bits(row, c));
        m[l] = if mu[l].is_finite() {
            mu[l].max(0.0)
        } else {
            0.0
        };
    }
    let low = EXACT_POISSON_BELOW as f32;
    let mut e = [0f32; LANES];
    if fc.shot {
        // Cornish–Fisher for the lanes at or above the exact range
        for l in 0..LANES {
            let s = m[l].sqrt();
            e[l] = round_even(m[l] + s * z[l] + (z[l] * z[l] - 1.0) * (1.0 / 6.0)).max(0.0);
        }
        // exact inversion of the Poisson CDF for the lanes below it, all lanes in step
        let mut kmax = 0f32;
        let mut p = [0f32; LANES];
        let mut cdf = [1f32; LANES];
        let mut k = [0f32; LANES];
        for l in 0..LANES {
            if m[l] < low {
                p[l] = crate::vmath::exp_f32(-m[l]);
                cdf[l] = p[l];
                kmax = kmax.max(m[l] + 10.0 * m[l].sqrt() + 10.0);
            }
        }
        let mut j = 1f32;
        while j <= kmax {
            let mut any = false;
            for l in 0..LANES {
                let more = u[l] > cdf[l];
                any |= more;
                k[l] += more as u32 as f32;
                p[l] *= m[l] / j;
                cdf[l] += p[l];
            }
            if !any {
                break;
            }
            j += 1.0;
        }
        for l in 0..LANES {
            if m[l] < low {
                e[l] = k[l];
            }
        }
    } else {
        e = m;
    }
    let maxf = fc.max as f32;
    let (fwc, kg, black, sr) = (
        fc.fwc as f32,
        fc.kg as f32,
        fc.black as f32,
        fc.sigma_read as f32,
    );
    let mut full = 0u32;
    for l in 0..n {
        if !redo[l] {
            continue;
        }
        let mut x = e[l];
        if fc.fwc_clip {
            if x >= fwc {
                full |= 1 << l;
            }
            x = x.min(fwc);
        }
        x += ds[l] + sr * zr[l];
        out[l] = adc_code((kg * x + black).max(0.0), maxf);
    }
    full
}

/// The folded kernel of one row, one pixel at a time (the portable build; the AVX2 and AVX-512
/// kernels give the same bits): mean electrons, the folded Cornish–Fisher draw, the ADC.
/// Returns the row's largest mean and largest code.
fn row_folded_plain(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    let (mu_max, code_max) = row_folded_cols(f, key, s, st, row, 0, out);
    (f32::from_bits(mu_max), code_max)
}

/// [`row_folded_plain`] for columns `c0 ..` of the row (`out` holds the whole row; also the
/// last columns the vector kernels leave); the largest mean as its bits.
fn row_folded_cols(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    c0: usize,
    out: &mut [u16],
) -> (u32, u16) {
    let (mut mu_max, mut code_max) = (0u32, 0u16);
    for c in c0..out.len() {
        let z = normal_from_bits(key.bits(row, c as u32));
        let wt = st.weighted(c, s[0][c], s[1][c], s[2][c]);
        let (m, code) = f.pixel(wt, st.dsnu[c], z);
        out[c] = code;
        // means are ≥ 0, so their bits order like the values
        mu_max = mu_max.max(m.to_bits());
        code_max = code_max.max(code);
    }
    (mu_max, code_max)
}

/// The unfolded kernel for the chunks of a row holding pixels that need it (see [`row_body`]);
/// counts the full-well pixels that read below the top code in `sat`.
#[allow(clippy::too_many_arguments)]
fn row_fixup(
    fc: &FrameConsts,
    folded: bool,
    mu_hi: f32,
    mu: &[f32],
    st: &StaticRow,
    r: usize,
    row: &mut [u16],
    sat: &mut [u32; 4],
) {
    let w = row.len();
    let mut redo = [true; LANES];
    for c0 in (0..w).step_by(LANES) {
        let c1 = (c0 + LANES).min(w);
        let mut any = !folded;
        for c in c0..c1 {
            redo[c - c0] = !folded || mu[c] > mu_hi;
            any |= redo[c - c0];
        }
        if !any {
            continue;
        }
        let mut ds = [0f32; LANES];
        for c in c0..c1 {
            ds[c - c0] = st.dsnu(c);
        }
        let full = chunk_unfolded(
            fc,
            &mu[c0..c1],
            &ds[..c1 - c0],
            r as u32,
            c0 as u32,
            &redo[..c1 - c0],
            &mut row[c0..c1],
        );
        for c in c0..c1 {
            if full & (1 << (c - c0)) != 0 && row[c] != fc.max {
                sat[((r & 1) << 1) | (c & 1)] += 1;
            }
        }
    }
}

simd_dispatch! {
    /// The folded kernel of one row ([`row_folded_plain`]), in AVX-512 where the CPU has it and
    /// VAES ([`avx512::row_folded`]), in AVX2 where it has AES-NI ([`avx2::row_folded`]); the
    /// same bits everywhere.
    fn row_folded = {
        avx512: avx512::row_folded,
        avx2: avx2::row_folded,
        plain: row_folded_plain,
    }(
        f: &Folded,
        key: &NoiseKey,
        s: [&[f32]; 3],
        st: &StaticRow,
        row: u32,
        out: &mut [u16],
    ) -> (f32, u16)
}

/// One row: the folded kernel everywhere, the unfolded one for the chunks that need it (all of
/// them when the configuration is not folded, else those that may reach the full well; `mu`
/// holds their means), and the saturation counts in `sat`.
#[allow(clippy::too_many_arguments)]
fn row_kernel(
    fc: &FrameConsts,
    f: &Folded,
    folded: bool,
    mu_hi: f32,
    s: [&[f32]; 3],
    st: &StaticRow,
    r: usize,
    mu: &mut [f32],
    row: &mut [u16],
    sat: &mut [u32; 4],
) {
    let (mu_max, code_max) = row_folded(f, &fc.shot_key, s, st, r as u32, row);
    let fixup = !folded || mu_max > mu_hi;
    if fixup {
        // the means the folded kernel had (not stored there: the row's scratch then stays in L1)
        for (c, m) in mu.iter_mut().enumerate() {
            *m = st
                .weighted(c, s[0][c], s[1][c], s[2][c])
                .mul_add(f.k, f.dark);
        }
        row_fixup(fc, folded, mu_hi, mu, st, r, row, sat);
    }
    if fixup || code_max == fc.max {
        for (c, &v) in row.iter().enumerate() {
            if v == fc.max {
                sat[((r & 1) << 1) | (c & 1)] += 1;
            }
        }
    }
}

/// Output of [`render_codes`].
pub(crate) struct FastCodes {
    /// The buffer: `lead` elements, then the codes.
    pub codes: Vec<u16>,
    pub saturated: [u32; 4],
    /// CRC-32 of the codes as little-endian bytes, when the sink asked for it.
    pub crc32: Option<u32>,
}

/// Rows per parallel task (several rows so the per-task scratch is reused).
const BAND: usize = 16;

/// Raw codes of one frame from a row source of sensor-frame Stokes radiance, and what `sink`
/// asks for: the codes' CRC-32, taken band by band while each band is still in cache (a third of
/// the time of one pass over the finished 10 MB frame) and combined. (Packing each band here as
/// well was tried and measured no faster than packing the finished frame, `docs/performance.md`.)
/// The codes go after the first `lead` elements of `codes` ([`super::FrameOptions::lead`]).
pub(crate) fn render_codes(
    sensor: &Sensor,
    st: &FastStatics,
    src: &dyn StokesRows,
    fc: &FrameConsts,
    codes: Vec<u16>,
    lead: usize,
    sink: FastSink,
) -> FastCodes {
    let (w, h) = (sensor.intrinsics.width, sensor.intrinsics.height);
    // the bytes of a u16 slice are its little-endian bytes only on a little-endian machine
    let crc32 = sink == FastSink::CodesCrc32 && cfg!(target_endian = "little");
    // every code is written below: a reused buffer of the right size is not cleared
    let mut buf = super::frame::codes_buffer(codes, lead, w * h);
    let codes = &mut buf[lead..];
    let folded = fc.folded();
    let mu_hi = fc.mu_high() as f32;
    let f = Folded::new(fc, st.scale);
    let bands: Vec<([u32; 4], u32)> = codes
        .par_chunks_mut(w * BAND)
        // one band per task: a worker preempted by the writer or the reader holds up the
        // frame's end by one band, not by a quarter of the frame
        .with_max_len(1)
        .enumerate()
        // row scratch per rayon job, not per band (every row overwrites it)
        .map_init(
            || std::array::from_fn::<_, 4, _>(|_| Aligned::<f32>::new(w)),
            |rows, (band, out)| {
                let [s0, s1, s2, mu] = rows.each_mut().map(|r| &mut r[..]);
                let mut sat = [0u32; 4];
                for (i, row) in out.chunks_mut(w).enumerate() {
                    let r = band * BAND + i;
                    src.fill_row(r, s0, s1, s2);
                    let sr = st.row(r, w);
                    let s = [&s0[..], &s1[..], &s2[..]];
                    row_kernel(fc, &f, folded, mu_hi, s, &sr, r, mu, row, &mut sat);
                }
                let crc = if crc32 {
                    crc32fast::hash(bytemuck::cast_slice(out))
                } else {
                    0
                };
                (sat, crc)
            },
        )
        .collect();
    let mut saturated = [0u32; 4];
    for (s, _) in &bands {
        for i in 0..4 {
            saturated[i] += s[i];
        }
    }
    let crc32 = crc32.then(|| {
        let pieces = codes.chunks(w * BAND).zip(&bands);
        super::packing::crc32_of_pieces(pieces.map(|(band, (_, crc))| (*crc, 2 * band.len())))
    });
    FastCodes {
        codes: buf,
        saturated,
        crc32,
    }
}

/// Electron rate (e⁻/s) of every pixel from a row source (for auto-exposure).
pub(crate) fn rates(
    sensor: &Sensor,
    st: &FastStatics,
    src: &dyn StokesRows,
) -> (Vec<f64>, Vec<bool>) {
    let (w, h) = (sensor.intrinsics.width, sensor.intrinsics.height);
    let mut rate = vec![0f64; w * h];
    let mut sky = vec![false; w * h];
    rate.par_chunks_mut(w)
        .zip(sky.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (rr, sk))| {
            let mut s0 = vec![0f32; w];
            let mut s1 = vec![0f32; w];
            let mut s2 = vec![0f32; w];
            src.fill_row(r, &mut s0, &mut s1, &mut s2);
            let sr = st.row(r, w);
            for c in 0..w {
                rr[c] = sr.rate(c, s0[c], s1[c], s2[c]) as f64;
                sk[c] = s0[c] > 0.0;
            }
        });
    (rate, sky)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{with_simd, Simd};

    /// The draw of pixel i of a 2448-wide frame.
    fn bits(key: &NoiseKey, i: u32) -> u32 {
        key.bits(i / 2448, i % 2448)
    }

    #[test]
    fn aligned_rows_start_on_64_bytes() {
        for len in [0usize, 1, 17, 2448] {
            for _ in 0..8 {
                let mut a = Aligned::<f32>::new(len);
                assert_eq!(a.len(), len);
                assert_eq!(a.as_ptr() as usize % 64, 0, "len {len}");
                assert!(a.iter().all(|&x| x == 0.0));
                a.iter_mut().for_each(|x| *x = 1.0);
                let b = Aligned::<u16>::new(len + 1);
                assert_eq!(b.as_ptr() as usize % 64, 0);
            }
        }
    }

    #[test]
    fn normal_inverse_is_accurate() {
        // known quantiles of the standard normal
        let q = |u: f64| {
            let k = ((u * 16_777_216.0 - 1.0) / 2.0).round() as u32;
            normal_from_bits(k << 9) as f64
        };
        // tolerance: the fit's 3.2e-5 plus half a lattice step of u (2⁻²⁴) over the density
        for (u, z, tol) in [
            (0.841_344_746, 1.0, 5e-5),
            (0.977_249_868, 2.0, 5e-5),
            (0.998_650_102, 3.0, 1e-4),
            (0.999_968_329, 4.0, 5e-4),
            (0.158_655_254, -1.0, 5e-5),
        ] {
            assert!((q(u) - z).abs() < tol, "u {u}: {} vs {z}", q(u));
        }
        assert!(normal_from_bits(0) < -5.2 && normal_from_bits(u32::MAX) > 5.2);
        assert_eq!(normal_from_bits(0), -normal_from_bits(u32::MAX));
    }

    #[test]
    fn normal_moments() {
        let key = NoiseKey::new(7, 3, 1);
        let n = 2_000_000u32;
        let (mut s1, mut s2, mut s3, mut s4) = (0f64, 0f64, 0f64, 0f64);
        for i in 0..n {
            let z = normal_from_bits(bits(&key, i)) as f64;
            s1 += z;
            s2 += z * z;
            s3 += z * z * z;
            s4 += z * z * z * z;
        }
        let nf = n as f64;
        let (m, v) = (s1 / nf, s2 / nf);
        assert!(m.abs() < 0.004, "mean {m}");
        assert!((v - 1.0).abs() < 0.005, "var {v}");
        assert!((s3 / nf).abs() < 0.02, "skew {}", s3 / nf);
        assert!((s4 / nf - 3.0).abs() < 0.05, "kurtosis {}", s4 / nf);
    }

    #[test]
    fn streams_differ_and_neighbours_are_uncorrelated() {
        let a = NoiseKey::new(1, 0, 1);
        let b = NoiseKey::new(1, 1, 1);
        let c = NoiseKey::new(1, 0, 2);
        assert_ne!(a, b);
        assert_ne!(a, c);
        let n = 1_000_000u32;
        let (mut ab, mut ac, mut nb, mut rb) = (0f64, 0f64, 0f64, 0f64);
        for i in 0..n {
            let za = normal_from_bits(bits(&a, i)) as f64;
            ab += za * normal_from_bits(bits(&b, i)) as f64;
            ac += za * normal_from_bits(bits(&c, i)) as f64;
            nb += za * normal_from_bits(bits(&a, i + 1)) as f64;
            rb += za * normal_from_bits(bits(&a, i + 2448)) as f64;
        }
        for (name, s) in [
            ("frames", ab),
            ("stages", ac),
            ("neighbours", nb),
            ("rows", rb),
        ] {
            // 5 σ of a correlation estimate over n pairs
            assert!(
                (s / n as f64).abs() < 5.0 / (n as f64).sqrt(),
                "{name}: {}",
                s / n as f64
            );
        }
    }

    /// The row kernel gives the same bits in every instruction set the CPU has (plain, AVX2, AVX-512),
    /// folded and unfolded, over means from 0 to past the full well, at widths that are and are
    /// not a multiple of the vector.
    #[test]
    fn simd_paths_agree() {
        for w in [1000usize, 1003] {
            simd_paths_agree_at(w);
        }
    }

    fn simd_paths_agree_at(w: usize) {
        let key = NoiseKey::new(5, 9, 1);
        // a spread of Stokes values: dark, low (exact Poisson), mid, near and past the full well,
        // negative rates, a non-finite value
        let s0: Vec<f32> = (0..w)
            .map(|i| match i % 97 {
                0 => 0.0,
                1 => f32::NAN,
                2 => -1e-3,
                _ => 1e-6 * 1.2f32.powi((i % 89) as i32),
            })
            .collect();
        let s1: Vec<f32> = (0..w)
            .map(|i| s0[i] * (0.4 - (i % 7) as f32 * 0.1))
            .collect();
        let s2: Vec<f32> = (0..w)
            .map(|i| s0[i] * (0.3 - (i % 5) as f32 * 0.12))
            .collect();
        let g: Vec<u16> = (0..w).map(|i| 31_000 + (i * 37 % 3_000) as u16).collect();
        let pc: Vec<i16> = (0..w)
            .map(|i| (i * 53 % 60_001) as i32 as i16 - 30_000)
            .collect();
        let ps: Vec<i16> = (0..w)
            .map(|i| (i * 59 % 60_001) as i32 as i16 - 30_000)
            .collect();
        let dsnu: Vec<i16> = (0..w).map(|i| (i * 71 % 2_001) as i16 - 1_000).collect();
        let sr = StaticRow {
            g: &g,
            pc: &pc,
            ps: &ps,
            dsnu: &dsnu,
            scale: 1.0e7 / (32_768.0 * 32_768.0),
        };
        let run = |fc: &FrameConsts| -> Vec<(Vec<u32>, Vec<u16>, [u32; 4])> {
            let (folded, mu_hi) = (fc.folded(), fc.mu_high() as f32);
            let f = Folded::new(fc, sr.scale);
            Simd::available()
                .into_iter()
                .map(|l| {
                    with_simd(l, || {
                        let mut mu = vec![0f32; w];
                        let mut out = vec![0u16; w];
                        let mut sat = [0u32; 4];
                        let mut mus = Vec::new();
                        let mut outs = Vec::new();
                        for r in 0..6 {
                            let s = [&s0[..], &s1[..], &s2[..]];
                            row_kernel(
                                fc, &f, folded, mu_hi, s, &sr, r, &mut mu, &mut out, &mut sat,
                            );
                            mus.extend(mu.iter().map(|m| m.to_bits()));
                            outs.extend_from_slice(&out);
                        }
                        (mus, outs, sat)
                    })
                })
                .collect()
        };
        let base = FrameConsts {
            t: 1e-3,
            dark_e: 0.3,
            fwc: 10500.0,
            fwc_clip: true,
            shot: true,
            sigma_read: 2.5,
            kg: 0.39,
            black: 4.0,
            max: 4095,
            shot_key: key,
            read_key: NoiseKey::new(5, 9, 2),
        };
        let low_read = FrameConsts {
            sigma_read: 0.5, // not folded: every pixel through the unfolded kernel
            ..base
        };
        let no_shot = FrameConsts {
            shot: false,
            ..base
        };
        for (name, fc) in [
            ("folded", base),
            ("unfolded", low_read),
            ("no shot", no_shot),
        ] {
            let r = run(&fc);
            assert!(r[0].1.contains(&fc.max), "{name}: no saturated pixel");
            assert!(
                r[0].1.iter().any(|&c| c > 0 && c < 40),
                "{name}: no dark pixel"
            );
            for (l, x) in Simd::available().iter().zip(&r).skip(1) {
                assert!(x == &r[0], "{name}, width {w}: {l:?} differs from plain");
            }
        }
    }
}
