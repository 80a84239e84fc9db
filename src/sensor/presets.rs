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

use super::optics::RelativeIllumination;
use super::{adc, noise, nominal_axis, RawFrame, Sensor, SensorConfig, Stages};
use crate::error::{check_range, Error, Result};
use crate::image::{Image, StokesImage};
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

impl Preset {
    /// All presets.
    pub const ALL: [Preset; 4] = [
        Preset::Camera,
        Preset::Nfpi,
        Preset::Gniipi,
        Preset::Gniicpi,
    ];
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Preset::Camera => "camera",
            Preset::Nfpi => "nfpi",
            Preset::Gniipi => "gniipi",
            Preset::Gniicpi => "gniicpi",
        })
    }
}

impl FromStr for Preset {
    type Err = Error;
    /// Parses `camera`, `nfpi`, `gniipi`, `gniicpi` (case-insensitive).
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "camera" => Ok(Preset::Camera),
            "nfpi" => Ok(Preset::Nfpi),
            "gniipi" => Ok(Preset::Gniipi),
            "gniicpi" => Ok(Preset::Gniicpi),
            _ => Err(Error::OutOfRange {
                name: "preset".into(),
                value: s.to_string(),
                allowed: "camera, nfpi, gniipi, gniicpi".into(),
            }),
        }
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

/// Per-frame κ: full / max RI_k · ½(S0 + |S_lin|) over finite pixels (1 if the frame is dark),
/// with `ri` the relative-illumination map (`None` = 1): the brightest sample the sensor can
/// read after the falloff is full scale.
pub fn auto_kappa(stokes: &StokesImage, ri: Option<&[f32]>, full: f64) -> f64 {
    let w = stokes.width().max(1);
    let m = stokes
        .s0
        .data
        .par_chunks(w)
        .zip(stokes.s1.data.par_chunks(w))
        .zip(stokes.s2.data.par_chunks(w))
        .enumerate()
        .map(|(r, ((a, b), c))| kappa_row_dispatch(a, b, c, ri.map(|m| &m[r * w..r * w + a.len()])))
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
    g: &[f64],
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

/// max over a row of RI·½(S0 + |S_lin|) (0 for none finite and positive), for [`auto_kappa`].
#[inline(always)]
fn kappa_row(a: &[f32], b: &[f32], c: &[f32], g: Option<&[f32]>) -> f64 {
    // plain loops, no closures: a closure is compiled apart from the AVX2 wrapper and would not
    // vectorise. f32 squares are exact in f64: hypot within an ulp, without libm's call;
    // non-finite values (NaN included) never win
    let n = a.len();
    let (b, c) = (&b[..n], &c[..n]);
    let mut best = 0f64;
    match g {
        Some(g) => {
            let g = &g[..n];
            for k in 0..n {
                let (bk, ck) = (b[k] as f64, c[k] as f64);
                let v = g[k] as f64 * 0.5 * (a[k] as f64 + (bk * bk + ck * ck).sqrt());
                best = if v.is_finite() && v > best { v } else { best };
            }
        }
        None => {
            for k in 0..n {
                let (bk, ck) = (b[k] as f64, c[k] as f64);
                let v = 0.5 * (a[k] as f64 + (bk * bk + ck * ck).sqrt());
                best = if v.is_finite() && v > best { v } else { best };
            }
        }
    }
    best
}

/// One row of a PSNS-model frame: codes of g_c·(S0 + S1 cos 2θ_c + S2 sin 2θ_c) + σ z_c with
/// g = κ·RI·½ (`g` holds it per column), non-finite Stokes read as 0, z empty for no noise; the
/// codes by [`adc::quantize`], which has no branches, so the loop vectorises.
#[inline(always)]
fn psns_row(
    row: &mut [u16],
    s: [&[f32]; 3],
    g: &[f64],
    axis: [&[f64]; 2],
    z: &[f32],
    sigma: f64,
    max: u16,
) {
    let n = row.len();
    let (s0, s1, s2) = (&s[0][..n], &s[1][..n], &s[2][..n]);
    let (g, co, si) = (&g[..n], &axis[0][..n], &axis[1][..n]);
    let fin = |v: f32| if v.is_finite() { v as f64 } else { 0.0 };
    // the expression written out in both loops: a closure holding it is compiled apart from the
    // AVX2 wrapper and stops the loop vectorising
    if z.is_empty() {
        for c in 0..n {
            let v = g[c] * (fin(s0[c]) + fin(s1[c]) * co[c] + fin(s2[c]) * si[c]);
            row[c] = adc::quantize(v, max);
        }
    } else {
        let z = &z[..n];
        for c in 0..n {
            let v = g[c] * (fin(s0[c]) + fin(s1[c]) * co[c] + fin(s2[c]) * si[c]);
            row[c] = adc::quantize(v + sigma * z[c] as f64, max);
        }
    }
}

/// Renders a PSNS-model frame (called by [`Sensor::frame`] when `cfg.psns` is set).
pub(crate) fn psns_frame(
    s: &Sensor,
    stokes: &StokesImage,
    frame_index: u64,
    want_truth: bool,
) -> Result<RawFrame> {
    let cfg = &s.cfg;
    let p = cfg.psns.as_ref().expect("psns model");
    let (w, h) = (s.intrinsics.width, s.intrinsics.height);
    let max = adc::max_code(cfg.bit_depth);
    let full = max as f64;
    let kappa = p
        .kappa
        .unwrap_or_else(|| auto_kappa(stokes, s.ri.as_deref(), full));
    let sigma = p.noise_fraction * full;
    let mut codes = vec![0u16; w * h];
    // Gaussian noise from the fast path's counter-based generator (one keyed hash of the pixel
    // index per draw, inverted exactly to f32 precision): the frame does not depend on rows,
    // threads or blocks, and costs a few ns per pixel instead of ChaCha + ziggurat
    let key = super::fast::NoiseKey::new(s.seed, frame_index, noise::STAGE_PSNS_NOISE);
    let ri = s.ri_map();
    // per-column pass-axis terms of even and odd rows, and per-row gains κ·RI·½
    let axis: [[Vec<f64>; 2]; 2] = std::array::from_fn(|r| {
        let a: Vec<(f64, f64)> = (0..w).map(|c| nominal_axis(&cfg.layout, r, c)).collect();
        [
            a.iter().map(|x| x.0).collect(),
            a.iter().map(|x| x.1).collect(),
        ]
    });
    codes.par_chunks_mut(w).enumerate().for_each_init(
        || (Vec::new(), Vec::new()),
        |(z, g), (r, row)| {
            let span = r * w..(r + 1) * w;
            z.resize(w, 0f32);
            if sigma > 0.0 {
                super::fast::normals_into(&key, (r * w) as u32, z);
            }
            g.clear();
            match ri {
                Some(m) => g.extend(m[span.clone()].iter().map(|&x| kappa * 0.5 * x as f64)),
                None => g.resize(w, kappa * 0.5),
            }
            let st = [
                &stokes.s0.data[span.clone()],
                &stokes.s1.data[span.clone()],
                &stokes.s2.data[span],
            ];
            let ax = [&axis[r & 1][0][..], &axis[r & 1][1][..]];
            let zs = if sigma > 0.0 { &z[..] } else { &[][..] };
            psns_row_dispatch(row, st, g, ax, zs, sigma, max);
        },
    );
    let mut truth = if want_truth {
        s.truth(stokes, kappa)
    } else {
        StokesImage::zeros(0, 0)
    };
    if p.clouds {
        let mut rng = noise::frame_rng(s.seed, frame_index, noise::STAGE_PSNS_CLOUDS, 0);
        let ellipses = clouds::psns_ellipses(w, h, &mut rng);
        let mask = clouds::ellipse_mask(w, h, &ellipses);
        for (k, &m) in mask.iter().enumerate() {
            if m {
                codes[k] = max;
                if want_truth {
                    truth.s0.data[k] = (2.0 * full) as f32;
                    truth.s1.data[k] = 0.0;
                    truth.s2.data[k] = 0.0;
                }
            }
        }
    }
    let saturated = codes
        .par_chunks(w)
        .enumerate()
        .map(|(r, row)| {
            let mut n = [0u32; 4];
            for (c, &v) in row.iter().enumerate() {
                n[((r & 1) << 1) | (c & 1)] += (v == max) as u32;
            }
            n
        })
        .reduce(|| [0; 4], |a, b| std::array::from_fn(|i| a[i] + b[i]));
    Ok(RawFrame {
        codes: Image::from_vec(w, h, codes),
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PSNS row kernels give the same bits in every instruction set the CPU has.
    #[test]
    fn simd_paths_agree() {
        use crate::simd::{with_simd, Simd};
        let levels: Vec<Simd> = [Simd::Plain, Simd::Avx2, Simd::Avx512]
            .into_iter()
            .filter(|&l| l <= Simd::detected())
            .collect();
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
        let g: Vec<f64> = (0..n).map(|i| 900.0 + (i % 13) as f64 * 7.3).collect();
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
                    psns_row_dispatch(&mut row, [&s0, &s1, &s2], &g, [&co, &si], zs, 12.5, 4095);
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
}
