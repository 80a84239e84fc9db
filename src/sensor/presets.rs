//! Presets: the realistic IMX250MZR camera and the PSNS dataset variants (`sensor.md` §9).
//!
//! PSNS (Liang & Bai) eq. (24): I_k = κ · ½ LI [1 + DOP cos 2(AOP_s − θ_k)]
//! = κ · ½ (S0 + S1 cos 2θ_k + S2 sin 2θ_k), rounded and clipped to the output depth. κ is fixed
//! if configured, otherwise per frame κ = (2^bits − 1) / max over the frame of ½ RI (S0 + |S_lin|),
//! taken **after** the relative illumination RI (1 for `nfpi`), so the brightest sample of the
//! frame the network sees reads full scale and the 2 % noise is 2 % of that brightest signal.
//!
//! * `nfpi`: ideal, 8 bit, no optics and no noise;
//! * `gniipi`: plus relative-illumination falloff and additive Gaussian white noise σ = 2 % of
//!   full scale. The falloff is cos⁴ of the field angle (corner 0.12 on the full 4 mm frame), the
//!   textbook law the paper cites for its "insufficient illumination" (`docs/sensor.md`); the
//!   camera preset keeps cos^1.5. Any other model through `SensorConfig::ri`;
//! * `gniicpi`: plus 3–8 filled ellipses set to full scale, applied last (ground truth there:
//!   unpolarized with S0 = 2 × full scale, consistent with every channel reading full scale).

/// Pixels per block of the row kernels: each stage runs over a whole block, so its vector
/// iterations are independent and the long dependency chains overlap.
const BLOCK: usize = 64;
use super::optics::RelativeIllumination;
use super::{adc, noise, nominal_axis, RawFrame, Sensor, SensorConfig, Stages};
use crate::error::{check_range, Error, Result};
use crate::image::{StokesImage, StokesRows};
use crate::sky::clouds;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Named sensor presets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Realistic IMX250MZR (`sensor.md` §7 defaults).
    #[default]
    Camera,
    /// PSNS: no noise, ideal, 8 bit.
    Nfpi,
    /// PSNS: Gaussian noise + insufficient illumination toward the edge.
    Gniipi,
    /// PSNS: as `gniipi` plus clouds.
    Gniicpi,
}

crate::names::name_table!(Preset {
    Camera => "camera",
    Nfpi => "nfpi",
    Gniipi => "gniipi",
    Gniicpi => "gniicpi",
});

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = Error;
    /// Parses `camera`, `nfpi`, `gniipi`, `gniicpi` (case-insensitive).
    fn from_str(s: &str) -> Result<Self> {
        Preset::from_name(s).ok_or_else(|| Error::OutOfRange {
            name: "preset".into(),
            value: s.to_string(),
            allowed: Preset::names(),
        })
    }
}

/// The PSNS dataset model (replaces the camera model when set).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PsnsModel {
    /// Fixed κ (DN per radiance unit); `None` = per frame, brightest sample (after the relative
    /// illumination) at full scale.
    pub kappa: Option<f64>,
    /// Multiply by the relative illumination ("insufficient illumination at the edge").
    pub relative_illumination: bool,
    /// Gaussian white noise σ as a fraction of full scale (0.02 for gniipi), 0..1.
    pub noise_fraction: f64,
    /// Ellipse clouds set to full scale.
    pub clouds: bool,
}

impl Default for PsnsModel {
    fn default() -> Self {
        PsnsModel {
            kappa: None,
            relative_illumination: false,
            noise_fraction: 0.0,
            clouds: false,
        }
    }
}

impl PsnsModel {
    /// Checks κ and the noise fraction.
    pub fn validate(&self) -> Result<()> {
        if let Some(k) = self.kappa {
            check_range("kappa", k, 0.0, 1e12)?;
        }
        check_range("noise-fraction", self.noise_fraction, 0.0, 1.0)?;
        Ok(())
    }
}

/// Relative illumination of the PSNS presets: cos⁴ of the field angle, the optics-textbook law
/// the paper cites for "insufficient illumination at the edge".
pub const PSNS_RI: RelativeIllumination = RelativeIllumination::CosPower { n: 4.0 };

/// The configuration of preset `p`.
pub fn config(p: Preset) -> SensorConfig {
    let psns = |ri: bool, noise: f64, clouds: bool| SensorConfig {
        bit_depth: 8,
        ri: PSNS_RI,
        stages: Stages {
            ri,
            ..Stages::none()
        },
        psns: Some(PsnsModel {
            kappa: None,
            relative_illumination: ri,
            noise_fraction: noise,
            clouds,
        }),
        ..SensorConfig::default()
    };
    match p {
        Preset::Camera => SensorConfig::default(),
        Preset::Nfpi => psns(false, 0.0, false),
        Preset::Gniipi => psns(true, 0.02, false),
        Preset::Gniicpi => psns(true, 0.02, true),
    }
}

/// Where a PSNS frame reads its Stokes rows: the three planes as they are, or a row source (a
/// sky grid) interpolated row by row into a per-thread buffer, so no full-size planes are made.
/// Both read a pixel as the same number: [`StokesRows::fill_row`] of a grid gives the values
/// its planes would hold.
#[derive(Clone, Copy)]
pub(crate) enum PsnsSource<'a> {
    Planes(&'a StokesImage),
    Rows(&'a dyn StokesRows),
}

impl PsnsSource<'_> {
    fn width(&self) -> usize {
        match self {
            PsnsSource::Planes(s) => s.width(),
            PsnsSource::Rows(s) => s.width(),
        }
    }
    fn height(&self) -> usize {
        match self {
            PsnsSource::Planes(s) => s.height(),
            PsnsSource::Rows(s) => s.height(),
        }
    }
    /// Row r of S0, S1, S2 (a grid's through `buf`).
    fn row<'b>(&'b self, r: usize, buf: &'b mut [Vec<f32>; 3]) -> [&'b [f32]; 3] {
        let w = self.width();
        match *self {
            PsnsSource::Planes(s) => {
                let span = r * w..(r + 1) * w;
                [
                    &s.s0.data[span.clone()],
                    &s.s1.data[span.clone()],
                    &s.s2.data[span],
                ]
            }
            PsnsSource::Rows(src) => {
                let [a, b, c] = buf;
                for v in [&mut *a, &mut *b, &mut *c] {
                    v.resize(w, 0.0);
                }
                src.fill_row(r, a, b, c);
                [&a[..], &b[..], &c[..]]
            }
        }
    }
}

/// Per-frame κ of any [`PsnsSource`]: full / max RI_k · ½(S0 + |S_lin|) over finite pixels (1
/// if the frame is dark), with `ri` the relative-illumination map (`None` = 1): the brightest
/// sample the sensor can read after the falloff is full scale.
fn kappa_of(src: PsnsSource, ri: Option<&[f32]>, full: f64) -> f64 {
    let w = src.width().max(1);
    let m = (0..src.height())
        .into_par_iter()
        .map_init(
            || [Vec::new(), Vec::new(), Vec::new()],
            |buf, r| {
                let [a, b, c] = src.row(r, buf);
                kappa_row_dispatch(a, b, c, ri.map(|m| &m[r * w..(r + 1) * w]))
            },
        )
        .reduce(|| 0.0, f64::max);
    if m > 0.0 {
        full / m
    } else {
        1.0
    }
}

crate::simd::simd_dispatch!(fn psns_row_dispatch = psns_row(
    row: &mut [u16],
    s: [&[f32]; 3],
    ri: &[f32],
    hk: f64,
    axis: [&[f64]; 2],
    z: &[f32],
    sigma: f64,
    max: u16,
));
crate::simd::simd_dispatch!(fn kappa_row_dispatch = kappa_row(
    a: &[f32],
    b: &[f32],
    c: &[f32],
    g: Option<&[f32]>,
) -> f64);

/// max over a row of RI·½(S0 + |S_lin|) in f64 (0 for none finite and positive), for
/// [`kappa_of`]. The f64 value (its square root is the cost) is needed only where it can be the
/// maximum: an f32 estimate of every pixel, within `tol` of the f64 value, picks the candidates
/// block by block, and the f64 maximum over them is the f64 maximum over the row, bit for bit.
#[inline(always)]
fn kappa_row(a: &[f32], b: &[f32], c: &[f32], g: Option<&[f32]>) -> f64 {
    // plain loops, no closures: a closure is compiled apart from the AVX2 wrapper and would not
    // vectorise
    let n = a.len();
    let (b, c) = (&b[..n], &c[..n]);
    let ones = [1f32; BLOCK];
    let mut best = 0f64;
    let mut lo_max = f32::NEG_INFINITY;
    let mut est = [0f32; BLOCK];
    let mut tol = [0f32; BLOCK];
    let mut lo = [0f32; BLOCK];
    for b0 in (0..n).step_by(BLOCK) {
        let len = BLOCK.min(n - b0);
        let (ab, bb, cb) = (&a[b0..b0 + len], &b[b0..b0 + len], &c[b0..b0 + len]);
        let gb = match g {
            Some(g) => &g[b0..b0 + len],
            None => &ones[..len],
        };
        for k in 0..len {
            let r = (bb[k] * bb[k] + cb[k] * cb[k]).sqrt();
            let x = gb[k] * 0.5;
            est[k] = x * (ab[k] + r);
            // an f32 result of 6 roundings is within 6 ulp of the real value, the f64 one
            // within 1e-15: 4e-6 of the magnitudes is far outside both (the 1e-30 covers
            // subnormals)
            tol[k] = 4e-6 * x.abs() * (ab[k].abs() + r) + 1e-30;
            lo[k] = est[k] - tol[k];
        }
        // the running maximum of the lower bounds, 8 lanes at a time (vectorises); NaN never
        // wins, and a lower bound is never +inf (an infinite estimate has an infinite
        // tolerance: inf − inf is NaN)
        let mut m = [lo_max; 8];
        for ch in lo[..len].chunks(8) {
            for (j, &v) in ch.iter().enumerate() {
                m[j] = if v > m[j] { v } else { m[j] };
            }
        }
        lo_max = m.iter().fold(lo_max, |a, &v| if v > a { v } else { a });
        for k0 in (0..len).step_by(8) {
            let k1 = (k0 + 8).min(len);
            let mut any = false;
            for k in k0..k1 {
                // non-finite estimates (f32 overflow, NaN) are always checked in f64
                let up = est[k] + tol[k];
                any |= up >= lo_max || up.is_nan();
            }
            if !any {
                continue;
            }
            for k in k0..k1 {
                let up = est[k] + tol[k];
                if up >= lo_max || up.is_nan() {
                    let (bk, ck) = (bb[k] as f64, cb[k] as f64);
                    // f32 squares are exact in f64: hypot within an ulp, without libm's call;
                    // non-finite values (NaN included) never win
                    let v = gb[k] as f64 * 0.5 * (ab[k] as f64 + (bk * bk + ck * ck).sqrt());
                    best = if v.is_finite() && v > best { v } else { best };
                }
            }
        }
    }
    best
}

/// One row of a PSNS-model frame: codes of g_c·(S0 + S1 cos 2θ_c + S2 sin 2θ_c) + σ z_c with
/// g_c = ½κ·RI_c (`hk` = ½κ, `ri` the row of the relative illumination, ones without it),
/// non-finite Stokes read as 0, z empty for no noise; the codes by [`adc::quantize`], which has
/// no branches, so the loop vectorises.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn psns_row(
    row: &mut [u16],
    s: [&[f32]; 3],
    ri: &[f32],
    hk: f64,
    axis: [&[f64]; 2],
    z: &[f32],
    sigma: f64,
    max: u16,
) {
    let n = row.len();
    let (s0, s1, s2) = (&s[0][..n], &s[1][..n], &s[2][..n]);
    let (ri, co, si) = (&ri[..n], &axis[0][..n], &axis[1][..n]);
    let fin = |v: f32| if v.is_finite() { v as f64 } else { 0.0 };
    // the expression written out in both loops: a closure holding it is compiled apart from the
    // AVX2 wrapper and stops the loop vectorising
    if z.is_empty() {
        for c in 0..n {
            let g = hk * ri[c] as f64;
            let v = g * (fin(s0[c]) + fin(s1[c]) * co[c] + fin(s2[c]) * si[c]);
            row[c] = adc::quantize(v, max);
        }
    } else {
        let z = &z[..n];
        for c in 0..n {
            let g = hk * ri[c] as f64;
            let v = g * (fin(s0[c]) + fin(s1[c]) * co[c] + fin(s2[c]) * si[c]);
            row[c] = adc::quantize(v + sigma * z[c] as f64, max);
        }
    }
}

/// Renders a PSNS-model frame (called by [`Sensor::frame`] when `cfg.psns` is set, and by
/// [`Sensor::frame`] of rows); `codes` is a buffer to reuse. The ground truth needs the planes.
pub(crate) fn psns_frame(
    s: &Sensor,
    src: PsnsSource,
    frame_index: u64,
    want_truth: bool,
    codes: Vec<u16>,
    lead: usize,
) -> Result<RawFrame> {
    if want_truth && matches!(src, PsnsSource::Rows(_)) {
        return Err(Error::Invalid(
            "the ground truth needs the Stokes planes".into(),
        ));
    }
    let cfg = &s.cfg;
    let p = cfg.psns.as_ref().expect("psns model");
    let (w, h) = (s.intrinsics.width, s.intrinsics.height);
    let max = adc::max_code(cfg.bit_depth);
    let full = max as f64;
    let kappa = p
        .kappa
        .unwrap_or_else(|| kappa_of(src, s.ri.as_deref(), full));
    let sigma = p.noise_fraction * full;
    let mut buf = codes;
    buf.truncate(lead);
    let mut buf = super::frame::codes_buffer(buf, lead, w * h);
    let codes = &mut buf[lead..];
    // Gaussian noise from the fast path's counter-based generator (AES rounds of the pixel's
    // row and column, inverted by a polynomial): the frame does not depend on rows, threads or
    // blocks, and costs about a nanosecond per pixel instead of ChaCha + ziggurat
    let key = super::normal::NoiseKey::new(s.seed, frame_index, noise::STAGE_PSNS_NOISE);
    let ri = s.ri_map();
    // per-column pass-axis terms of even and odd rows
    let axis: [[Vec<f64>; 2]; 2] = std::array::from_fn(|r| {
        let a: Vec<(f64, f64)> = (0..w).map(|c| nominal_axis(&cfg.layout, r, c)).collect();
        [
            a.iter().map(|x| x.0).collect(),
            a.iter().map(|x| x.1).collect(),
        ]
    });
    // clouds: filled ellipses at full scale, applied last (drawn from the frame's stream)
    let ellipses = if p.clouds {
        let mut rng = crate::rng::frame_rng(s.seed, frame_index, noise::STAGE_PSNS_CLOUDS, 0);
        clouds::psns_ellipses(w, h, &mut rng)
    } else {
        Vec::new()
    };
    let ones = vec![1f32; if ri.is_some() { 0 } else { w }];
    let hk = kappa * 0.5;
    // one pass per row: codes, clouds, saturation counts
    let saturated = codes
        .par_chunks_mut(w)
        .enumerate()
        .map_init(
            || (Vec::new(), [Vec::new(), Vec::new(), Vec::new()]),
            |(z, buf), (r, row)| {
                z.resize(w, 0f32);
                if sigma > 0.0 {
                    super::normal::normals_row(&key, r as u32, 0, z);
                }
                let g = match ri {
                    Some(m) => &m[r * w..(r + 1) * w],
                    None => &ones[..],
                };
                let st = src.row(r, buf);
                let ax = [&axis[r & 1][0][..], &axis[r & 1][1][..]];
                let zs = if sigma > 0.0 { &z[..] } else { &[][..] };
                psns_row_dispatch(row, st, g, hk, ax, zs, sigma, max);
                clouds::ellipse_row(&ellipses, h, r, w, |c| row[c] = max);
                // even and odd columns counted apart (a computed index would not vectorise)
                let (mut even, mut odd) = (0u32, 0u32);
                for p in row.chunks_exact(2) {
                    even += (p[0] == max) as u32;
                    odd += (p[1] == max) as u32;
                }
                if let [.., last] = row.chunks_exact(2).remainder() {
                    even += (*last == max) as u32;
                }
                let mut n = [0u32; 4];
                n[(r & 1) << 1] = even;
                n[((r & 1) << 1) | 1] = odd;
                n
            },
        )
        .reduce(|| [0; 4], |a, b| std::array::from_fn(|i| a[i] + b[i]));
    let mut truth = match (want_truth, src) {
        (true, PsnsSource::Planes(stokes)) => s.truth(stokes, kappa),
        _ => StokesImage::zeros(0, 0),
    };
    if want_truth && !ellipses.is_empty() {
        // ground truth under a cloud: unpolarized, every channel at full scale
        truth.par_rows(|r, s0, s1, s2| {
            clouds::ellipse_row(&ellipses, h, r, w, |c| {
                (s0[c], s1[c], s2[c]) = ((2.0 * full) as f32, 0.0, 0.0);
            })
        });
    }
    let (codes, lead_buffer) = super::frame::split_lead(buf, lead, w, h);
    Ok(RawFrame {
        codes,
        lead_buffer,
        bit_depth: cfg.bit_depth,
        black_level_dn: 0.0,
        exposure_us: match cfg.exposure {
            super::Exposure::Fixed { us } => us,
            super::Exposure::Auto { .. } => 0.0,
        },
        gain_db: 0.0,
        dn_per_electron: 0.0,
        truth,
        saturated,
        auto_exposed: false,
        exposure_clipped: false,
        analog: None,
        codes_crc32: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PSNS row kernels give the same bits in every instruction set the CPU has.
    #[test]
    fn simd_paths_agree() {
        use crate::simd::{with_simd, Simd};
        let levels = Simd::available();
        let n = 1001;
        let s0: Vec<f32> = (0..n)
            .map(|i| match i % 61 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                _ => 1e-3 * 1.16f32.powi((i % 59) as i32),
            })
            .collect();
        let s1: Vec<f32> = (0..n)
            .map(|i| s0[i] * (0.5 - (i % 9) as f32 * 0.11))
            .collect();
        let s2: Vec<f32> = (0..n)
            .map(|i| s0[i] * (0.2 - (i % 4) as f32 * 0.1))
            .collect();
        // gain ½κ·RI = 1000 · (0.9 .. 0.99)
        let g: Vec<f32> = (0..n).map(|i| 0.9 + (i % 13) as f32 * 0.0073).collect();
        let ri: Vec<f32> = (0..n).map(|i| 1.0 - (i % 17) as f32 * 0.01).collect();
        let co: Vec<f64> = (0..n).map(|i| ((i % 8) as f64 * 0.7).cos()).collect();
        let si: Vec<f64> = (0..n).map(|i| ((i % 8) as f64 * 0.7).sin()).collect();
        let z: Vec<f32> = (0..n)
            .map(|i| ((i * 7919 % 1000) as f32 - 500.0) * 0.006)
            .collect();
        let run = |l: Simd| {
            with_simd(l, || {
                let mut rows = Vec::new();
                for zs in [&z[..], &[][..]] {
                    let mut row = vec![0u16; n];
                    psns_row_dispatch(
                        &mut row,
                        [&s0, &s1, &s2],
                        &g,
                        1000.0,
                        [&co, &si],
                        zs,
                        12.5,
                        4095,
                    );
                    rows.push(row);
                }
                let k = [
                    kappa_row_dispatch(&s0, &s1, &s2, Some(&ri)).to_bits(),
                    kappa_row_dispatch(&s0, &s1, &s2, None).to_bits(),
                ];
                (rows, k)
            })
        };
        let base = run(Simd::Plain);
        assert!(base.0[0].contains(&4095) && base.0[0].iter().any(|&c| c > 0 && c < 4095));
        for &l in &levels[1..] {
            assert!(run(l) == base, "{l:?} differs from plain");
        }
    }

    #[test]
    fn names_round_trip() {
        for p in Preset::ALL {
            assert_eq!(p.to_string().parse::<Preset>().unwrap(), p);
        }
        let e = "fancy".parse::<Preset>().unwrap_err();
        assert!(e.to_string().contains("fancy") && e.to_string().contains("gniicpi"));
        assert!(e.is_usage());
    }

    /// The f64 maximum of the row, evaluated at every pixel (what `kappa_row` must equal).
    fn kappa_row_direct(a: &[f32], b: &[f32], c: &[f32], g: Option<&[f32]>) -> f64 {
        let mut best = 0f64;
        for k in 0..a.len() {
            let (bk, ck) = (b[k] as f64, c[k] as f64);
            let gk = g.map_or(1.0, |g| g[k]) as f64;
            let v = gk * 0.5 * (a[k] as f64 + (bk * bk + ck * ck).sqrt());
            best = if v.is_finite() && v > best { v } else { best };
        }
        best
    }

    /// The candidate filter of `kappa_row` never changes the maximum: smooth skies, flat rows
    /// (every pixel tied), near-ties an ulp apart, negative S0, huge, tiny, NaN and infinite
    /// values, with and without a gain map, every row length around the block size.
    #[test]
    fn kappa_row_is_the_f64_maximum() {
        use rand::Rng;
        let mut rng = crate::rng::scene_rng(3, 0);
        let mut f32_misses = 0;
        for case in 0..600 {
            let n = [1, 7, 63, 64, 65, 130, 611, 2448][case % 8];
            let kind = case / 8 % 6;
            let mut v = |_: usize| -> f32 {
                let x: f32 = rng.random::<f32>();
                match kind {
                    0 => 0.1 + 0.02 * x,
                    1 => 0.25,
                    2 => f32::from_bits(0.3f32.to_bits() + (x * 3.0) as u32),
                    3 => 2.0 * x - 1.0,
                    4 => [1e30, 1e-30, 3e38, f32::NAN, f32::INFINITY, 5.0][(x * 6.0) as usize % 6],
                    _ => x * x * x,
                }
            };
            let a: Vec<f32> = (0..n).map(&mut v).collect();
            let b: Vec<f32> = (0..n).map(|k| 0.3 * v(k)).collect();
            let c: Vec<f32> = (0..n).map(|k| -0.2 * v(k)).collect();
            let g: Vec<f32> = (0..n).map(|_| rng.random::<f32>()).collect();
            for gm in [None, Some(&g[..])] {
                let want = kappa_row_direct(&a, &b, &c, gm);
                // does the f32 estimate alone pick a pixel whose f64 value is not the maximum?
                let est = |k: usize| {
                    let r = (b[k] * b[k] + c[k] * c[k]).sqrt();
                    gm.map_or(1.0, |g| g[k]) * 0.5 * (a[k] + r)
                };
                let top = (0..n)
                    .filter(|&k| est(k).is_finite())
                    .max_by(|&i, &j| est(i).total_cmp(&est(j)));
                if let Some(k) = top {
                    let gk = gm.map_or(1.0, |g| g[k]) as f64;
                    let (bk, ck) = (b[k] as f64, c[k] as f64);
                    let v = gk * 0.5 * (a[k] as f64 + (bk * bk + ck * ck).sqrt());
                    f32_misses += (v.is_finite() && v > 0.0 && v != want) as usize;
                }
                assert_eq!(
                    kappa_row(&a, &b, &c, gm).to_bits(),
                    want.to_bits(),
                    "case {case}"
                );
                assert_eq!(kappa_row_dispatch(&a, &b, &c, gm).to_bits(), want.to_bits());
            }
        }
        // the cases include rows where f32 alone would give the wrong maximum
        assert!(
            f32_misses > 10,
            "{f32_misses} rows where the f32 maximum is off"
        );

        // two pixels whose f32 estimates order them the other way round from their f64
        // values (the roundings of b², c² and their sum): the filter needs its tolerance
        let est = |a: f32, b: f32, c: f32| 0.5 * (a + (b * b + c * c).sqrt());
        let val = |a: f32, b: f32, c: f32| {
            let (b, c) = (b as f64, c as f64);
            0.5 * (a as f64 + (b * b + c * c).sqrt())
        };
        let near = |x: f32, k: u32| f32::from_bits(x.to_bits() + k);
        let (mut found, mut tries) = (None, 0);
        while found.is_none() && tries < 1_000_000 {
            tries += 1;
            let p = [
                near(0.3, 0),
                near(0.09, rng.random_range(0..64)),
                near(0.06, rng.random_range(0..64)),
            ];
            let q = [
                near(0.3, 0),
                near(0.09, rng.random_range(0..64)),
                near(0.06, rng.random_range(0..64)),
            ];
            if val(p[0], p[1], p[2]) > val(q[0], q[1], q[2])
                && est(p[0], p[1], p[2]) < est(q[0], q[1], q[2])
            {
                found = Some((p, q));
            }
        }
        let (p, q) = found.expect("an f32/f64 order reversal");
        let mut rows: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.1f32; 100]);
        for (i, px) in [(17, p), (40, q)] {
            // in one block: across blocks the running maximum would hide a missing tolerance
            for k in 0..3 {
                rows[k][i] = px[k];
            }
        }
        let want = val(p[0], p[1], p[2]);
        assert_eq!(kappa_row_direct(&rows[0], &rows[1], &rows[2], None), want);
        assert_eq!(
            kappa_row(&rows[0], &rows[1], &rows[2], None),
            want,
            "after {tries} tries"
        );
    }
}
