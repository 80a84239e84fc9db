//! The exact path's row kernel ([`super::Sensor::frame`], `--exact`): per-row ChaCha8 streams
//! ([`crate::rng::frame_stream`]), exact Poisson, f64 arithmetic (`docs/sensor.md` §6).
//!
//! A row runs in passes over per-thread buffers, each doing per pixel exactly what the one-loop
//! kernel did, in the same order: the mean electrons (rate, exposure, dark current) and PTRS's
//! constants, the shot- and read-noise draws (two streams, each drawn in its own order), then full
//! well, DSNU, read noise, gain and ADC. The arithmetic passes vectorise; the draw loop stays
//! small.

use super::{adc, noise, polarizer};
use crate::rng::Stream;
use crate::simd::simd_dispatch;

/// Per-frame constants of the exact path.
pub(crate) struct ExactConsts {
    /// Exposure, s.
    pub t: f64,
    /// Dark electrons per pixel (0 when the stage is off).
    pub dark_e: f64,
    /// Polarizer coefficients and η · photon rate ([`super::Sensor::rate_coefficients`]).
    pub pa: f64,
    pub pb: f64,
    pub pbase: f64,
    /// Shot-noise stage on.
    pub shot: bool,
    /// Full-well clip on, and the full well in e⁻.
    pub fwc_clip: bool,
    pub fwc: f64,
    /// σ of the read noise when the stage is on and σ > 0.
    pub read_sigma: Option<f64>,
    /// (analog system gain, digital factor) when part of the gain is digital.
    pub digital: Option<(f64, f64)>,
    /// ADC rounding on.
    pub quantize: bool,
    /// System gain (12-bit DN per e⁻), black level (12-bit DN), output scale and top code.
    pub kg: f64,
    pub black: f64,
    pub scale: f64,
    pub max: u16,
}

/// One row's inputs; every slice is one row (the frame's width).
pub(crate) struct RowIn<'a> {
    /// S0, S1, S2.
    pub s: [&'a [f32]; 3],
    /// Precomputed electron rates (auto-exposure or crosstalk); otherwise computed here.
    pub rate: Option<&'a [f64]>,
    pub ri: Option<&'a [f32]>,
    pub prnu: Option<&'a [f32]>,
    /// (cos 2θ, sin 2θ) with the orientation error; `None` = `nominal`.
    pub axis: Option<&'a [[f32; 2]]>,
    /// Nominal (cos 2θ, sin 2θ) at even and odd columns of this row.
    pub nominal: [(f64, f64); 2],
    pub dsnu: Option<&'a [f32]>,
}

#[inline(always)]
fn finite(v: f32) -> f64 {
    if v.is_finite() {
        v as f64
    } else {
        0.0
    }
}

/// Mean electrons, the usual camera (RI, PRNU and orientation error on): vectorises.
#[inline(always)]
fn means_full(
    fc: &ExactConsts,
    s: [&[f32]; 3],
    ri: &[f32],
    g: &[f32],
    ax: &[[f32; 2]],
    mean: &mut [f64],
) {
    let w = mean.len();
    let (s0, s1, s2, ri, g, ax) = (
        &s[0][..w],
        &s[1][..w],
        &s[2][..w],
        &ri[..w],
        &g[..w],
        &ax[..w],
    );
    for c in 0..w {
        let [co, si] = ax[c];
        let rate = fc.pbase
            * ri[c] as f64
            * g[c] as f64
            * polarizer::reading(
                finite(s0[c]),
                finite(s1[c]),
                finite(s2[c]),
                co as f64,
                si as f64,
                fc.pa,
                fc.pb,
            );
        mean[c] = rate * fc.t + fc.dark_e;
    }
}

/// Mean electrons, any combination of maps. A missing map is a missing factor, as
/// multiplying by the 1.0 the one-loop kernel used is exact.
#[inline(always)]
fn means_any(fc: &ExactConsts, inp: &RowIn, mean: &mut [f64]) {
    let w = mean.len();
    let (s0, s1, s2) = (&inp.s[0][..w], &inp.s[1][..w], &inp.s[2][..w]);
    for c in 0..w {
        let (co, si) = match inp.axis {
            Some(a) => (a[c][0] as f64, a[c][1] as f64),
            None => inp.nominal[c & 1],
        };
        let mut k = fc.pbase;
        if let Some(ri) = inp.ri {
            k *= ri[c] as f64;
        }
        if let Some(g) = inp.prnu {
            k *= g[c] as f64;
        }
        let rate = k * polarizer::reading(
            finite(s0[c]),
            finite(s1[c]),
            finite(s2[c]),
            co,
            si,
            fc.pa,
            fc.pb,
        );
        mean[c] = rate * fc.t + fc.dark_e;
    }
}

/// Full well, DSNU, read noise, gain, ADC of the usual camera (no digital gain, ADC on, no
/// analog image); returns the saturated pixels at even and odd columns. Vectorises.
#[inline(always)]
fn combine_common(
    fc: &ExactConsts,
    n: &[f64],
    d: &[f32],
    z: &[f64],
    sigma: f64,
    codes: &mut [u16],
) -> [u32; 2] {
    let w = codes.len();
    let (n, d, z) = (&n[..w], &d[..w], &z[..w]);
    let (fwc, kg, black, scale, max) = (fc.fwc, fc.kg, fc.black, fc.scale, fc.max);
    let mut sat = [0u32; 2];
    // pixel pairs (the width is a multiple of 4): even and odd columns count apart, and the loop
    // vectorises
    for (((cp, np), dp), zp) in codes
        .chunks_exact_mut(2)
        .zip(n.chunks_exact(2))
        .zip(d.chunks_exact(2))
        .zip(z.chunks_exact(2))
    {
        for j in 0..2 {
            let n0 = np[j];
            let well_full = n0 >= fwc;
            let e = n0.min(fwc) + dp[j] as f64 + sigma * zp[j];
            let code = adc::quantize((kg * e + black) * scale, max);
            cp[j] = code;
            sat[j] += (code == max || well_full) as u32;
        }
    }
    sat
}

/// Full well, DSNU, read noise, gain and ADC for any stage switches.
#[inline(always)]
fn combine_any(
    fc: &ExactConsts,
    inp: &RowIn,
    n: &[f64],
    z: &[f64],
    codes: &mut [u16],
    mut analog: Option<&mut [f32]>,
) -> [u32; 2] {
    let w = codes.len();
    let mut sat = [0u32; 2];
    for c in 0..w {
        let mut n = n[c];
        // with K0 = 4095/FWC a full well reads 4092..4095 after read noise: count it as
        // saturated too, not only the top code
        let well_full = fc.fwc_clip && n >= fc.fwc;
        if fc.fwc_clip {
            n = n.min(fc.fwc);
        }
        if let Some(d) = inp.dsnu {
            n += d[c] as f64;
        }
        if let Some(s) = fc.read_sigma {
            n += s * z[c];
        }
        let v = match fc.digital {
            Some((kg_analog, digital)) => {
                let a = kg_analog * n;
                let a = if fc.quantize {
                    adc::quantize(a, 4095) as f64
                } else {
                    a
                };
                (a * digital + fc.black) * fc.scale
            }
            None => (fc.kg * n + fc.black) * fc.scale,
        };
        if let Some(a) = analog.as_deref_mut() {
            a[c] = v as f32;
        }
        let code = adc::quantize(v, fc.max);
        codes[c] = code;
        sat[c & 1] += (code == fc.max || well_full) as u32;
    }
    sat
}

/// A thread's row buffers: mean electrons (then electrons), read-noise draws, PTRS constants.
pub(crate) struct RowBufs {
    mean: Vec<f64>,
    z: Vec<f64>,
    ptrs: [Vec<f64>; 3],
}

impl RowBufs {
    pub(crate) fn new(w: usize) -> Self {
        let v = || vec![0f64; w];
        RowBufs {
            mean: v(),
            z: v(),
            ptrs: [v(), v(), v()],
        }
    }
}

#[inline(always)]
fn row_body(
    fc: &ExactConsts,
    inp: &RowIn,
    rs: &mut Stream,
    rr: &mut Stream,
    bufs: &mut RowBufs,
    codes: &mut [u16],
    analog: Option<&mut [f32]>,
) -> [u32; 2] {
    let w = codes.len();
    let (mean, z) = (&mut bufs.mean[..w], &mut bufs.z[..w]);
    match (inp.rate, inp.ri, inp.prnu, inp.axis) {
        (Some(rate), ..) => {
            for (m, &r) in mean.iter_mut().zip(&rate[..w]) {
                *m = r * fc.t + fc.dark_e;
            }
        }
        (None, Some(ri), Some(g), Some(ax)) => means_full(fc, inp.s, ri, g, ax, mean),
        _ => means_any(fc, inp, mean),
    }
    if fc.shot {
        let [pb, pa, pvr] = &mut bufs.ptrs;
        let (pb, pa, pvr) = (&mut pb[..w], &mut pa[..w], &mut pvr[..w]);
        for c in 0..w {
            [pb[c], pa[c], pvr[c]] = noise::ptrs_consts(mean[c]);
        }
        let t = noise::ptrs_tables();
        if fc.read_sigma.is_some() {
            // both streams in one loop (each in its own order): the normals fill the shot
            // draws' latency
            for c in 0..w {
                mean[c] = noise::poisson_with(rs, mean[c], [pb[c], pa[c], pvr[c]], t);
                z[c] = noise::normal(rr);
            }
        } else {
            for c in 0..w {
                mean[c] = noise::poisson_with(rs, mean[c], [pb[c], pa[c], pvr[c]], t);
            }
        }
    } else if fc.read_sigma.is_some() {
        for v in z.iter_mut() {
            *v = noise::normal(rr);
        }
    }
    match (fc.fwc_clip, inp.dsnu, fc.read_sigma, fc.digital, &analog) {
        (true, Some(d), Some(sigma), None, None) if fc.quantize => {
            combine_common(fc, mean, d, z, sigma, codes)
        }
        _ => combine_any(fc, inp, mean, z, codes, analog),
    }
}

simd_dispatch! {
    /// [`row_body`] built for the best instruction set the CPU has: `floor` inline from SSE4.1
    /// on, the arithmetic passes vectorised; the same bits in every build.
    pub(crate) fn row_kernel = row_body(
        fc: &ExactConsts,
        inp: &RowIn,
        rs: &mut Stream,
        rr: &mut Stream,
        bufs: &mut RowBufs,
        codes: &mut [u16],
        analog: Option<&mut [f32]>,
    ) -> [u32; 2]
}
