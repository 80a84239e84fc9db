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
    map_rgb(aop_deg, mask, |v| cyclic_hue(v as f64))
}

/// DOP (or DoLP) image with viridis over [0, 1].
pub fn dop_rgb(dop: &Image<f32>, mask: Option<&Image<u8>>) -> Image<[u8; 3]> {
    map_rgb(dop, mask, |v| viridis(v as f64))
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

fn map_rgb(
    img: &Image<f32>,
    mask: Option<&Image<u8>>,
    f: impl Fn(f32) -> [u8; 3],
) -> Image<[u8; 3]> {
    let data = match mask {
        Some(m) => img
            .data
            .iter()
            .zip(&m.data)
            .map(|(&v, &m)| if m == 0 { [0, 0, 0] } else { f(v) })
            .collect(),
        None => img.data.iter().map(|&v| f(v)).collect(),
    };
    Image::from_vec(img.width, img.height, data)
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

/// The `q`-quantile (0..1) of the finite values of an image (for display scaling).
pub fn quantile(img: &Image<f32>, q: f64) -> f64 {
    let mut v: Vec<f32> = img.data.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let k = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
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
        // every f32 between 0 and 1 with its low 8 bits cleared, and a fine sweep of angles
        let (lo, hi) = (0f32.to_bits(), 1f32.to_bits());
        vals.extend((lo..=hi).step_by(256).map(f32::from_bits));
        vals.extend((-2_000_000..2_000_000).map(|k| k as f32 * 1e-4 * 137.0));
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
    }
}
