//! Demosaicking of a division-of-focal-plane polarization mosaic into Stokes planes.
//!
//! Physics (spec `demosaic.md` §1): with ideal polarizers each pixel reads
//! I_θ = ½(S0 + S1 cos 2θ + S2 sin 2θ), θ from the [`MosaicLayout`]. For the IMX250MZR layout
//! `90,45/135,0` the mosaic is raw(r, c) = ½S0 + ¼(S2 − S1)(−1)^r − ¼(S1 + S2)(−1)^c: S0 at
//! baseband, the linear polarization on the Nyquist carriers. Every linear shift-invariant method
//! is a demodulator; bilinear-then-Stokes is demodulation with the low-pass [1 2 1]/4 and Keys
//! cubic convolution with [−1 0 9 16 9 0 −1]/32 (see [`bilinear`]).
//!
//! Frame: rows top to bottom, angles from +x (columns) toward +y (rows, down);
//! S0 = ½(I0 + I45 + I90 + I135), S1 = I0 − I90, S2 = I45 − I135, AoLP = ½ atan2(S2, S1).
//!
//! Methods ([`Method`]): superpixel (half resolution, replicated to full size), bilinear, bicubic
//! (Keys), PPID (Mihoubi, Lapray & Bigué, Sensors 2018), Newton (after Li, Zhao, Pan & Kong,
//! Opt. Express 2019) and EARI (after Morimatsu, Monno, Tanaka & Okutomi, ICIP 2020). Input is
//! any [`RawPixel`] (u8, u16 with 8–16 significant bits, f32) on any of the 24 layouts.
//! Borders use even reflection about the edge pixel (`reflect101`), which keeps the mosaic
//! phase, so uniform fields are reproduced up to the edge.
//!
//! All kernels run row-parallel with rayon; every output row depends only on the input, so the
//! result does not depend on the number of threads.

pub mod bicubic;
pub mod bilinear;
pub mod eari;
pub mod newton;
pub mod ppid;
pub mod superpixel;

use crate::error::{Error, Result};
pub use crate::image::RawPixel;
use crate::image::{Image, StokesImage};
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

pub use superpixel::superpixel_half;

/// Demosaic method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Stokes per 2 x 2 block (half resolution), replicated to each of the block's four pixels.
    Superpixel,
    /// Per-channel bilinear ≡ demodulation with [1 2 1]/4 (fused, fastest full-resolution path).
    Bilinear,
    /// Per-channel Keys cubic convolution (a = −½) ≡ demodulation with [−1 0 9 16 9 0 −1]/32.
    Bicubic,
    /// Pseudo-panchromatic image difference (Mihoubi et al. 2018).
    Ppid,
    /// Second-order Newton interpolation with a directional edge classifier (after Li et al. 2019).
    Newton,
    /// Edge-aware guide + minimised-Laplacian residual interpolation (after Morimatsu et al. 2020).
    Eari,
}

// every method, cheapest first
crate::names::name_table!(Method {
    Superpixel => "superpixel",
    Bilinear => "bilinear",
    Bicubic => "bicubic",
    Ppid => "ppid",
    Newton => "newton",
    Eari => "eari",
});

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = Error;
    /// ```
    /// use psns::demosaic::Method;
    /// assert_eq!("eari".parse::<Method>().unwrap(), Method::Eari);
    /// assert!("vng".parse::<Method>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        Method::from_name(s).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown demosaic method '{s}' (allowed: {})",
                Method::names()
            ))
        })
    }
}

/// Stokes planes plus DoLP and AoLP (degrees, [0, 180)), all full resolution.
#[derive(Clone, Debug, PartialEq)]
pub struct PolarImages {
    /// S0, S1, S2.
    pub stokes: StokesImage,
    /// √(S1² + S2²)/S0, 0 where S0 ≤ 0.
    pub dolp: Image<f32>,
    /// ½ atan2(S2, S1) in degrees, [0, 180), from +x toward +y.
    pub aolp_deg: Image<f32>,
}

/// Smallest accepted mosaic side (the widest kernel reaches 4 pixels out).
pub const MIN_SIDE: usize = 8;

/// Checks that a mosaic is large enough to demosaic and that its buffer matches its size.
pub fn check_raw<T>(raw: &Image<T>) -> Result<()> {
    if raw.width < MIN_SIDE || raw.height < MIN_SIDE {
        return Err(Error::Invalid(format!(
            "mosaic of {} x {} is too small for demosaicking (minimum {MIN_SIDE} x {MIN_SIDE})",
            raw.width, raw.height
        )));
    }
    if raw.data.len() != raw.width * raw.height {
        return Err(Error::Invalid(format!(
            "mosaic buffer has {} samples, expected {} x {}",
            raw.data.len(),
            raw.width,
            raw.height
        )));
    }
    Ok(())
}

/// Even reflection about the edge pixel (−1 → 1, n → n − 2): keeps the index parity.
#[inline(always)]
pub(crate) fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    let mut i = i;
    // n >= MIN_SIDE and |offset| <= 4, so one reflection suffices
    if i < 0 {
        i = -i;
    }
    if i >= n {
        i = 2 * (n - 1) - i;
    }
    i as usize
}

/// An f32 copy of the mosaic with `pad` reflected pixels on each side (parity preserved).
pub(crate) struct Padded {
    pub data: Vec<f32>,
    pub stride: usize,
    pub pad: usize,
}

impl Padded {
    pub fn from_f32(src: &[f32], w: usize, h: usize, pad: usize) -> Padded {
        let stride = w + 2 * pad;
        let mut data = vec![0f32; stride * (h + 2 * pad)];
        data.par_chunks_mut(stride)
            .enumerate()
            .for_each(|(pr, row)| {
                let r = reflect101(pr as isize - pad as isize, h);
                let s = &src[r * w..(r + 1) * w];
                for (pc, v) in row.iter_mut().enumerate() {
                    *v = s[reflect101(pc as isize - pad as isize, w)];
                }
            });
        Padded { data, stride, pad }
    }

    pub fn from_raw<T: RawPixel>(raw: &Image<T>, pad: usize) -> Padded {
        let f: Vec<f32> = raw.data.par_iter().map(|v| v.to_f32()).collect();
        Self::from_f32(&f, raw.width, raw.height, pad)
    }

    /// Sample at image coordinates (r, c), which may lie up to `pad` outside.
    #[inline(always)]
    pub fn at(&self, r: isize, c: isize) -> f32 {
        self.data[(r + self.pad as isize) as usize * self.stride + (c + self.pad as isize) as usize]
    }
}

/// Channel index (0 = 0°, 1 = 45°, 2 = 90°, 3 = 135°) at a possibly negative position.
#[inline(always)]
pub(crate) fn chan(layout: &MosaicLayout, r: isize, c: isize) -> usize {
    layout.channel(r.rem_euclid(2) as usize, c.rem_euclid(2) as usize)
}

/// Per-channel bilinear interpolation of values known on channel `k`'s sub-lattice.
///
/// `vals` is a full-size image whose entries are used only at channel-`k` pixels. This is the
/// tent kernel [½ 1 ½] ⊗ [½ 1 ½] over the sparse lattice (exact for affine fields).
pub(crate) fn bilinear_sparse(
    vals: &Padded,
    w: usize,
    h: usize,
    layout: &MosaicLayout,
    k: usize,
) -> Vec<f32> {
    let (kr, kc) = layout.position_of(k);
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let r = r as isize;
        let on_r = (r as usize & 1) == kr;
        for (c, o) in row.iter_mut().enumerate() {
            let ci = c as isize;
            let on_c = (c & 1) == kc;
            *o = match (on_r, on_c) {
                (true, true) => vals.at(r, ci),
                (true, false) => 0.5 * (vals.at(r, ci - 1) + vals.at(r, ci + 1)),
                (false, true) => 0.5 * (vals.at(r - 1, ci) + vals.at(r + 1, ci)),
                (false, false) => {
                    0.25 * (vals.at(r - 1, ci - 1)
                        + vals.at(r - 1, ci + 1)
                        + vals.at(r + 1, ci - 1)
                        + vals.at(r + 1, ci + 1))
                }
            };
        }
    });
    out
}

pub(crate) fn stokes_from_channel_vecs(ch: [&Vec<f32>; 4], w: usize, h: usize) -> StokesImage {
    let mut st = StokesImage::zeros(w, h);
    st.s0
        .data
        .par_iter_mut()
        .zip(st.s1.data.par_iter_mut())
        .zip(st.s2.data.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((s0, s1), s2))| {
            let (a, b, c, d) = (ch[0][i], ch[1][i], ch[2][i], ch[3][i]);
            *s0 = 0.5 * (a + b + c + d);
            *s1 = a - c;
            *s2 = b - d;
        });
    st
}

/// Demosaics a raw mosaic into full-resolution S0, S1, S2 (f32, same units as the input).
///
/// Superpixel output replicates each 2 x 2 block's Stokes vector to its four pixels (use
/// [`superpixel_half`] for the half-resolution planes).
pub fn demosaic<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
) -> Result<StokesImage> {
    check_raw(raw)?;
    Ok(match method {
        Method::Superpixel => superpixel::superpixel_full(raw, layout),
        Method::Bilinear => bilinear::demodulate(raw, layout, &bilinear::LP3, false).stokes,
        Method::Bicubic => bilinear::demodulate(raw, layout, &bicubic::LP7, false).stokes,
        Method::Ppid | Method::Newton | Method::Eari => {
            let ch = channel_vecs(raw, layout, method)?;
            stokes_from_channel_vecs([&ch[0], &ch[1], &ch[2], &ch[3]], raw.width, raw.height)
        }
    })
}

/// The full chain raw → S0, S1, S2, DoLP, AoLP. Bilinear and bicubic fuse everything into one
/// pass; the other methods demosaic, then call [`crate::stokes::dolp_aolp_images`].
pub fn full_chain<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
) -> Result<PolarImages> {
    check_raw(raw)?;
    match method {
        Method::Bilinear => Ok(bilinear::demodulate(raw, layout, &bilinear::LP3, true)),
        Method::Bicubic => Ok(bilinear::demodulate(raw, layout, &bicubic::LP7, true)),
        Method::Superpixel => Ok(superpixel::full_chain(raw, layout)),
        _ => {
            let stokes = demosaic(raw, layout, method)?;
            let (dolp, aolp_deg) = crate::stokes::dolp_aolp_images(&stokes);
            Ok(PolarImages {
                stokes,
                dolp,
                aolp_deg,
            })
        }
    }
}

/// [`full_chain`] of codes minus a black level (the codes as u16 directly when the black
/// level is 0): what `psns demosaic`, `psns heading` and Python's `psns.demosaic` run on a raw
/// frame.
pub fn demosaic_codes(
    codes: &Image<u16>,
    black_level: f64,
    layout: MosaicLayout,
    method: Method,
) -> Result<PolarImages> {
    if black_level == 0.0 {
        full_chain(codes, layout, method)
    } else {
        let b = black_level as f32;
        let f = Image::from_vec(
            codes.width,
            codes.height,
            codes.data.par_iter().map(|&v| v as f32 - b).collect(),
        );
        full_chain(&f, layout, method)
    }
}

/// [`full_chain`] into caller-owned images (resized when their size differs), so a frame
/// stream does not pay for fresh allocations and page faults on every frame. Superpixel,
/// bilinear and bicubic write in place; the other methods compute and move their results in.
pub fn full_chain_into<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
    out: &mut PolarImages,
) -> Result<()> {
    check_raw(raw)?;
    match method {
        Method::Bilinear => bilinear::demodulate_into(raw, layout, &bilinear::LP3, true, out),
        Method::Bicubic => bilinear::demodulate_into(raw, layout, &bicubic::LP7, true, out),
        Method::Superpixel => superpixel::full_chain_into(raw, layout, out),
        _ => *out = full_chain(raw, layout, method)?,
    }
    Ok(())
}

fn channel_vecs<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
) -> Result<[Vec<f32>; 4]> {
    check_raw(raw)?;
    Ok(match method {
        Method::Superpixel => superpixel::channels(raw, layout),
        Method::Bilinear => bilinear::channels(raw, layout, &bilinear::LP3),
        Method::Bicubic => bilinear::channels(raw, layout, &bicubic::LP7),
        Method::Ppid => ppid::channels(raw, layout),
        Method::Newton => newton::channels(raw, layout),
        Method::Eari => eari::channels(raw, layout),
    })
}

/// Full-resolution channel images (I0, I45, I90, I135) as each method estimates them.
pub fn channels<T: RawPixel>(
    raw: &Image<T>,
    layout: MosaicLayout,
    method: Method,
) -> Result<[Image<f32>; 4]> {
    let (w, h) = (raw.width, raw.height);
    let [a, b, c, d] = channel_vecs(raw, layout, method)?;
    Ok([
        Image::from_vec(w, h, a),
        Image::from_vec(w, h, b),
        Image::from_vec(w, h, c),
        Image::from_vec(w, h, d),
    ])
}

/// Builds the ideal mosaic of a Stokes field: raw(r, c) = ½(S0 + S1 cos 2θ + S2 sin 2θ), θ the
/// layout's nominal angle at (r, c). Test and benchmark helper (no noise, no quantisation).
pub fn mosaic_from_stokes(st: &StokesImage, layout: MosaicLayout) -> Image<f32> {
    let (w, h) = (st.width(), st.height());
    let mut out = Image::new(w, h);
    out.data.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        for (c, o) in row.iter_mut().enumerate() {
            let th = layout.angle_deg(r, c).to_radians() * 2.0;
            let i = r * w + c;
            let v = 0.5
                * (st.s0.data[i] as f64
                    + st.s1.data[i] as f64 * th.cos().snap_integer()
                    + st.s2.data[i] as f64 * th.sin().snap_integer());
            *o = v as f32;
        }
    });
    out
}

/// cos/sin of multiples of 90° come out as ±1e-16; snap them so ideal mosaics are exact.
trait SnapExact {
    fn snap_integer(self) -> f64;
}
impl SnapExact for f64 {
    #[inline]
    fn snap_integer(self) -> f64 {
        let r = self.round();
        if (self - r).abs() < 1e-12 {
            r
        } else {
            self
        }
    }
}
