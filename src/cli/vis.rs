//! Colour visualisations for people: AOP as a cyclic hue, DOP with a perceptual map (viridis),
//! radiance as grey. Purely for looking; the numbers live in the `.npy` files.

use psns::image::{round_clamp, Image};

/// Viridis anchor colours at 0, 1/8, …, 1 (sampled from matplotlib's map).
const VIRIDIS: [[f64; 3]; 9] = [
    [68.0, 1.0, 84.0],
    [71.0, 44.0, 122.0],
    [59.0, 81.0, 139.0],
    [44.0, 113.0, 142.0],
    [33.0, 144.0, 141.0],
    [39.0, 173.0, 129.0],
    [92.0, 200.0, 99.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 37.0],
];

/// Viridis colour of `t` in [0, 1] (clamped), piecewise linear between 9 anchors.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * 8.0;
    // t >= 0 here, so the cast is floor (without its libm call)
    let i = (t as usize).min(7);
    let f = t - i as f64;
    std::array::from_fn(|k| {
        round_clamp(VIRIDIS[i][k] * (1.0 - f) + VIRIDIS[i + 1][k] * f, 255.0) as u8
    })
}

/// Fully saturated hue for an axial angle in degrees (period 180°): 0° red, 60° green, 120° blue.
///
/// ```
/// assert_eq!(psns::vis::cyclic_hue(0.0), [255, 0, 0]);
/// assert_eq!(psns::vis::cyclic_hue(180.0), [255, 0, 0]); // no seam at 0/180
/// ```
pub fn cyclic_hue(angle_deg: f64) -> [u8; 3] {
    // rem_euclid and % without their fmod calls: an AoP is in [0, 180) already, and for h in
    // [0, 6) the subtraction of the even integer below h is exact (Sterbenz), as fmod is
    let a = if (0.0..180.0).contains(&angle_deg) {
        angle_deg
    } else {
        angle_deg.rem_euclid(180.0)
    };
    let h = (a / 180.0) * 6.0;
    let x = 1.0 - ((h - ((h as u32) & !1) as f64) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

/// AOP image as cyclic hue; `mask` 0 pixels black.
pub fn aop_rgb(aop_deg: &Image<f32>, mask: Option<&Image<u8>>) -> Image<[u8; 3]> {
    map_image(aop_deg, mask, Map::Hue)
}

/// DOP (or DoLP) image with viridis over [0, 1].
pub fn dop_rgb(dop: &Image<f32>, mask: Option<&Image<u8>>) -> Image<[u8; 3]> {
    map_image(dop, mask, Map::Viridis)
}

/// AoLP as hue with DoLP as brightness (DoLP scaled by `dolp_full`, e.g. 0.5).
pub fn aolp_dolp_rgb(aop_deg: &Image<f32>, dop: &Image<f32>, dolp_full: f64) -> Image<[u8; 3]> {
    let data = aop_deg
        .data
        .iter()
        .zip(&dop.data)
        .map(|(&a, &d)| {
            let k = if d.is_finite() {
                (d as f64 / dolp_full).clamp(0.0, 1.0)
            } else {
                0.0
            };
            cyclic_hue(a as f64).map(|c| round_clamp(c as f64 * k, 255.0) as u8)
        })
        .collect();
    Image::from_vec(aop_deg.width, aop_deg.height, data)
}

/// A colour map of [`map_image`].
#[derive(Clone, Copy)]
enum Map {
    /// [`viridis`] over [0, 1].
    Viridis,
    /// [`cyclic_hue`] of an angle in degrees.
    Hue,
}

/// `map` of every pixel (black where `mask` is 0), eight pixels at a time: the operations of
/// [`viridis`] and [`cyclic_hue`] (so the same bytes, tested) in fixed-size loops the compiler
/// vectorises, built for AVX2 where the CPU has it and `PSNS_SIMD` allows. Per pixel, the
/// scalar maps were a tenth of `render --raw`'s instructions (docs/performance.md).
fn map_image(img: &Image<f32>, mask: Option<&Image<u8>>, map: Map) -> Image<[u8; 3]> {
    let mut out = vec![[0u8; 3]; img.data.len()];
    map_pixels(&img.data, &mut out, map);
    if let Some(m) = mask {
        // (a mask shorter than the image panics, as before)
        for (o, &m) in out.iter_mut().zip(&m.data[..img.data.len()]) {
            if m == 0 {
                *o = [0, 0, 0];
            }
        }
    }
    Image::from_vec(img.width, img.height, out)
}

psns::simd_dispatch! {
    /// `map` of every value of `src` into `out`, built for AVX2 where `psns::simd` allows.
    fn map_pixels = {
        avx2: map_avx2,
        plain: map_body,
    }(src: &[f32], out: &mut [[u8; 3]], map: Map)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn map_avx2(src: &[f32], out: &mut [[u8; 3]], map: Map) {
    map_body(src, out, map)
}

#[inline(always)]
fn map_body(src: &[f32], out: &mut [[u8; 3]], map: Map) {
    let src = &src[..out.len()];
    let mut sc = src.chunks_exact(8);
    let mut oc = out.chunks_exact_mut(8);
    for (s, o) in (&mut sc).zip(&mut oc) {
        let s: &[f32; 8] = s.try_into().unwrap();
        let o: &mut [[u8; 3]; 8] = o.try_into().unwrap();
        match map {
            Map::Viridis => viridis8(s, o),
            Map::Hue => {
                if s.iter().all(|v| (0.0..180.0).contains(v)) {
                    // SAFETY: every value is in [0, 180) (checked just above)
                    unsafe { hue8(s, o) }
                } else {
                    for (o, &v) in o.iter_mut().zip(s) {
                        *o = cyclic_hue(v as f64);
                    }
                }
            }
        }
    }
    for (o, &v) in oc.into_remainder().iter_mut().zip(sc.remainder()) {
        *o = match map {
            Map::Viridis => viridis(v as f64),
            Map::Hue => cyclic_hue(v as f64),
        };
    }
}

/// [`viridis`] of eight values (through i32 where it used usize and u32: the same values in
/// range, and conversions the vector units have).
#[inline(always)]
fn viridis8(s: &[f32; 8], o: &mut [[u8; 3]; 8]) {
    let mut f = [0f64; 8];
    let mut i = [0usize; 8];
    for j in 0..8 {
        let v = s[j] as f64;
        let t = if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        } * 8.0;
        // SAFETY: t is in [0, 8] and x in [0, 255] (here and below), so the truncations fit
        // i32; `as` would add saturation code that keeps the loops from vectorising
        let k = unsafe { t.to_int_unchecked::<i32>() }.min(7);
        f[j] = t - k as f64;
        i[j] = k as usize;
    }
    for c in 0..3 {
        for j in 0..8 {
            let (a, b) = (VIRIDIS[i[j]][c], VIRIDIS[i[j] + 1][c]);
            let x = (a * (1.0 - f[j]) + b * f[j]).clamp(0.0, 255.0);
            // SAFETY: as above
            let t = unsafe { x.to_int_unchecked::<i32>() };
            o[j][c] = (t + (x - t as f64 >= 0.5) as i32) as u8;
        }
    }
}

/// [`cyclic_hue`] of eight angles in [0, 180), the sector's match as selects.
///
/// # Safety
/// Every value of `s` must lie in [0, 180): the truncations are unchecked.
#[inline(always)]
unsafe fn hue8(s: &[f32; 8], o: &mut [[u8; 3]; 8]) {
    for j in 0..8 {
        let h = (s[j] as f64 / 180.0) * 6.0;
        // SAFETY: h is in [0, 6) and the channels in [0, 255] (here and below), so the
        // truncations fit i32 (`as` would add saturation code)
        let k = unsafe { h.to_int_unchecked::<i32>() };
        let x = 1.0 - ((h - (k & !1) as f64) - 1.0).abs();
        let r = if k == 0 || k >= 5 {
            1.0
        } else if k == 1 || k == 4 {
            x
        } else {
            0.0
        };
        let g = if k == 1 || k == 2 {
            1.0
        } else if k == 0 || k == 3 {
            x
        } else {
            0.0
        };
        let b = if k == 3 || k == 4 {
            1.0
        } else if k == 2 || k >= 5 {
            x
        } else {
            0.0
        };
        // SAFETY: as above
        let u = |c: f64| unsafe { (c * 255.0).to_int_unchecked::<i32>() } as u8;
        o[j] = [u(r), u(g), u(b)];
    }
}

/// Linear grey scaled so `white` maps to 255 (values above clip).
pub fn gray8(img: &Image<f32>, white: f64) -> Image<u8> {
    let k = if white > 0.0 { 255.0 / white } else { 0.0 };
    let data = img
        .data
        .iter()
        .map(|&v| round_clamp(v as f64 * k, 255.0) as u8)
        .collect();
    Image::from_vec(img.width, img.height, data)
}

/// The `q`-quantile (0..1) of the finite values of an image (for display scaling): the value of
/// rank round((n − 1) q) among the n finite values in `total_cmp` order, found by a histogram of
/// the top 16 bits of an order-preserving key and a selection inside the one bucket that holds
/// the rank (for `li.png` of a full frame 0.18 G instructions, against 0.24 G for a selection
/// over a copy of all 5 M values).
pub fn quantile(img: &Image<f32>, q: f64) -> f64 {
    // f32::total_cmp's order as an unsigned key: negatives flipped whole, positives above them
    let key = |v: f32| {
        let b = v.to_bits();
        if b >> 31 == 1 {
            !b
        } else {
            b | 0x8000_0000
        }
    };
    let mut hist = vec![0usize; 1 << 16];
    let mut n = 0;
    for &v in img.data.iter().filter(|v| v.is_finite()) {
        hist[(key(v) >> 16) as usize] += 1;
        n += 1;
    }
    if n == 0 {
        return 0.0;
    }
    let mut k = ((n - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    let bucket = hist
        .iter()
        .position(|&c| {
            if k < c {
                return true;
            }
            k -= c;
            false
        })
        .expect("the rank is below the count") as u32;
    let mut v: Vec<f32> = img
        .data
        .iter()
        .copied()
        .filter(|v| v.is_finite() && key(*v) >> 16 == bucket)
        .collect();
    let (_, x, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *x as f64
}

/// Box-downsamples an image by an integer factor (for small figures in docs).
pub fn downsample<T: Copy + Into<f64>>(img: &Image<T>, factor: usize) -> Image<f32> {
    let (w, h) = (img.width / factor, img.height / factor);
    let mut out = Image::new(w, h);
    for r in 0..h {
        for c in 0..w {
            let mut s = 0.0;
            for dr in 0..factor {
                for dc in 0..factor {
                    s += (*img.get(r * factor + dr, c * factor + dc)).into();
                }
            }
            *out.get_mut(r, c) = (s / (factor * factor) as f64) as f32;
        }
    }
    out
}

/// Nearest-neighbour downsample (for angle images, where box averaging would be wrong).
pub fn decimate<T: Copy + Default>(img: &Image<T>, factor: usize) -> Image<T> {
    let (w, h) = (img.width / factor, img.height / factor);
    let mut out = Image::from_vec(w, h, vec![T::default(); w * h]);
    for r in 0..h {
        for c in 0..w {
            *out.get_mut(r, c) = *img.get(r * factor + factor / 2, c * factor + factor / 2);
        }
    }
    out
}

/// Places images side by side (same height) with a `gap` of black pixels.
pub fn hstack(imgs: &[&Image<[u8; 3]>], gap: usize) -> Image<[u8; 3]> {
    let h = imgs.iter().map(|i| i.height).max().unwrap_or(0);
    let w = imgs.iter().map(|i| i.width).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::from_vec(w, h, vec![[0u8; 3]; w * h]);
    let mut x0 = 0;
    for img in imgs {
        for r in 0..img.height {
            for c in 0..img.width {
                *out.get_mut(r, x0 + c) = *img.get(r, c);
            }
        }
        x0 += img.width + gap;
    }
    out
}

/// Stacks images vertically (same width) with a `gap` of black pixels.
pub fn vstack(imgs: &[&Image<[u8; 3]>], gap: usize) -> Image<[u8; 3]> {
    let w = imgs.iter().map(|i| i.width).max().unwrap_or(0);
    let h = imgs.iter().map(|i| i.height).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::from_vec(w, h, vec![[0u8; 3]; w * h]);
    let mut y0 = 0;
    for img in imgs {
        for r in 0..img.height {
            for c in 0..img.width {
                *out.get_mut(y0 + r, c) = *img.get(r, c);
            }
        }
        y0 += img.height + gap;
    }
    out
}

/// Grey image to RGB.
pub fn gray_rgb(img: &Image<u8>) -> Image<[u8; 3]> {
    Image::from_vec(
        img.width,
        img.height,
        img.data.iter().map(|&v| [v, v, v]).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The maps as first written (floor and fmod calls): the faster forms must give the same bytes.
    fn viridis_ref(t: f64) -> [u8; 3] {
        let t = if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.0
        } * 8.0;
        let i = (t.floor() as usize).min(7);
        let f = t - i as f64;
        std::array::from_fn(|k| {
            round_clamp(VIRIDIS[i][k] * (1.0 - f) + VIRIDIS[i + 1][k] * f, 255.0) as u8
        })
    }

    fn cyclic_hue_ref(angle_deg: f64) -> [u8; 3] {
        let h = (angle_deg.rem_euclid(180.0) / 180.0) * 6.0;
        let x = 1.0 - ((h % 2.0) - 1.0).abs();
        let (r, g, b) = match h as u32 {
            0 => (1.0, x, 0.0),
            1 => (x, 1.0, 0.0),
            2 => (0.0, 1.0, x),
            3 => (0.0, x, 1.0),
            4 => (x, 0.0, 1.0),
            _ => (1.0, 0.0, x),
        };
        [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
    }

    /// The histogram quantile is the selection over all finite values, at every rank tried.
    #[test]
    fn quantile_is_the_selected_value() {
        use rand::{Rng, SeedableRng};
        let reference = |img: &Image<f32>, q: f64| {
            let mut v: Vec<f32> = img.data.iter().copied().filter(|v| v.is_finite()).collect();
            if v.is_empty() {
                return 0.0;
            }
            let k = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
            *v.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1 as f64
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut data: Vec<f32> = (0..20_000)
            .map(|k| match k % 5 {
                0 => rng.random_range(-1e3..1e3),
                1 => rng.random_range(0.0..1e-30),
                2 => (k % 17) as f32,                   // ties
                3 => 1.0 + rng.random_range(0.0..1e-6), // one bucket, many values
                _ => -rng.random_range(0.0..1.0),
            })
            .collect();
        data.extend([
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
        ]);
        let img = Image::from_vec(data.len(), 1, data);
        for q in [
            0.0, 1e-4, 0.1, 0.25, 0.5, 0.6, 0.999, 0.9999, 1.0, 2.0, -1.0,
        ] {
            assert_eq!(
                quantile(&img, q).to_bits(),
                reference(&img, q).to_bits(),
                "q {q}"
            );
        }
        let empty = Image::from_vec(2, 1, vec![f32::NAN, f32::INFINITY]);
        assert_eq!(quantile(&empty, 0.5), 0.0);
        let one = Image::from_vec(1, 1, vec![-0.0f32]);
        assert_eq!(quantile(&one, 0.9).to_bits(), (-0.0f64).to_bits());
        // -0 ranks below +0 (total_cmp), in different buckets
        let zeros = Image::from_vec(6, 1, vec![0.0f32, -0.0, 0.0, -0.0, 0.0, -0.0]);
        assert_eq!(quantile(&zeros, 0.4).to_bits(), (-0.0f64).to_bits());
        assert_eq!(quantile(&zeros, 0.6).to_bits(), 0f64.to_bits());
    }

    /// Every f32 in a dense sweep (and the edges) maps as before.
    #[test]
    fn maps_match_their_first_form() {
        let mut vals: Vec<f32> = vec![
            0.0,
            -0.0,
            1.0,
            0.125,
            0.5,
            1e-30,
            -1e-30,
            179.99998,
            180.0,
            360.0,
            -180.0,
            -0.001,
            1e9,
            -1e9,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // every f32 between 0 and 1 with its low 9 bits cleared, and a fine sweep of angles
        let (lo, hi) = (0f32.to_bits(), 1f32.to_bits());
        vals.extend((lo..=hi).step_by(512).map(f32::from_bits));
        vals.extend((-500_000..500_000).map(|k| k as f32 * 4e-4 * 137.0));
        // the eight-at-a-time hue takes only blocks that are all in [0, 180): a dense run of them
        vals.extend((0..200_000).map(|k| k as f32 * 9e-4));
        for k in 0..=6000 {
            // the breakpoints of the hue (multiples of 30 degrees) and their neighbours
            let a = k as f32 * 0.03;
            vals.extend([
                a,
                f32::from_bits(a.to_bits() + 1),
                f32::from_bits(a.to_bits().max(1) - 1),
            ]);
        }
        for &v in &vals {
            let v = v as f64;
            assert_eq!(viridis(v), viridis_ref(v), "viridis({v})");
            assert_eq!(cyclic_hue(v), cyclic_hue_ref(v), "cyclic_hue({v})");
        }
        // the whole-image forms (eight at a time, AVX2 where the CPU has it), with a mask
        let n = vals.len();
        let img = Image::from_vec(n, 1, vals.clone());
        let mask = Image::from_vec(n, 1, (0..n).map(|k| (k % 7 != 3) as u8).collect());
        let black = |k: usize, c: [u8; 3]| if k % 7 == 3 { [0, 0, 0] } else { c };
        for level in psns::simd::Simd::available() {
            psns::simd::with_simd(level, || {
                let (d, a) = (dop_rgb(&img, Some(&mask)), aop_rgb(&img, Some(&mask)));
                for (k, &v) in vals.iter().enumerate() {
                    let (dw, aw) = (viridis_ref(v as f64), cyclic_hue_ref(v as f64));
                    assert_eq!(d.data[k], black(k, dw), "{level:?} dop_rgb({v})");
                    assert_eq!(a.data[k], black(k, aw), "{level:?} aop_rgb({v})");
                }
                let all: Vec<_> = vals.iter().map(|&v| viridis_ref(v as f64)).collect();
                assert_eq!(dop_rgb(&img, None).data, all, "{level:?}");
            });
        }
    }
}
