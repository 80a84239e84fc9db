//! Where the sky is cut: which pixels of a frame are sky (a mask given with the frame, or found
//! from it), and how much of the image an estimate used as sky.
//!
//! A mask is per pixel of the images an estimator reads ([`PolarView`]): nonzero = sky. It is
//! applied by setting the DoLP of every other pixel to NaN, the mark of an unusable pixel that
//! every estimator and the intensity vote already skip ([`masked_dolp`]).
//!
//! The mask found from the frame ([`find_sky_mask`], [`HeadingSetup::find_mask`]) is decided on
//! a grid of about [`MASK_GRID_SAMPLES`] pixels (every [`HeadingSetup::step`]-th or sparser);
//! every pixel takes the decision of its nearest grid pixel. A grid pixel is not sky when
//! - its AoLP or DoLP is not finite (a clipped pixel, or outside a given mask), or it looks below
//!   the level horizon (ground, with the known tilt);
//! - its intensity S0, flat-fielded by [`HeadingSetup::relative_illumination`], is more than
//!   [`MASK_BRIGHTNESS_RATIO`] times darker or brighter than the median of the polarized pixels
//!   (the frame's sky);
//! - it is polarized (DoLP ≥ `min_dolp`) but its AoLP disagrees with the sky model at the
//!   estimated yaw: the model fit's Berry field ([`model_fit_heading`]), residual beyond
//!   [`MASK_AGREE_SIGMAS`] σ / DoLP, held within [`MASK_AGREE_FLOOR_DEG`] and
//!   [`MASK_AGREE_CAP_DEG`], σ the robust scale of residual × DoLP over the pixels kept (the
//!   AoLP noise of a pixel is ∝ 1 / DoLP);
//! - fewer than [`MASK_MAJORITY`] of the polarized pixels within [`MASK_WINDOW`] grid steps
//!   agree: an obstruction is a region (a wall's noise, or foliage with random AoLP, agrees by
//!   chance here and there), while the sky agrees nearly everywhere. An unpolarized pixel in such
//!   a region is not sky either; elsewhere it is kept (the sky near the sun and the neutral
//!   points), for the intensity vote only, as no estimator uses a pixel below `min_dolp`.
//!
//! It is iterated: estimate (model fit, on [`MASK_FIT_SAMPLES`] pixels) on the pixels kept,
//! classify every grid pixel anew, until fewer than [`MASK_CHANGE_TOL`] of them would change
//! (the mask is then the one the last fit read) or after [`MASK_ITERATIONS`] fits.

use super::*;

/// The sky fraction from which the confidence is no longer reduced ([`sky_factor`]).
pub const SKY_FULL_FRACTION: f64 = 0.5;
/// A found mask drops pixels more than this factor darker or brighter (flat-fielded S0) than
/// the median of the frame's polarized pixels.
pub const MASK_BRIGHTNESS_RATIO: f64 = 8.0;
/// The smallest AoLP residual (degrees) at which a found mask drops a polarized pixel.
pub const MASK_AGREE_FLOOR_DEG: f64 = 3.0;
/// A found mask drops a polarized pixel whose AoLP residual exceeds this many σ / DoLP.
pub const MASK_AGREE_SIGMAS: f64 = 4.0;
/// The largest AoLP residual (degrees) a found mask accepts, however noisy the frame: random
/// AoLP (foliage, a picture of no sky) agrees within it a third of the time, short of
/// [`MASK_MAJORITY`].
pub const MASK_AGREE_CAP_DEG: f64 = 30.0;
/// Half-width, in grid steps, of the neighbourhood whose polarized pixels vote (5 × 5).
pub const MASK_WINDOW: usize = 2;
/// The share of a neighbourhood's polarized pixels that must agree with the sky model.
pub const MASK_MAJORITY: f64 = 0.5;
/// Estimates of the found mask's iteration at most.
pub const MASK_ITERATIONS: usize = 4;
/// The iteration stops when fewer than this share of the usable grid pixels would change.
pub const MASK_CHANGE_TOL: f64 = 0.005;
/// Grid pixels the found mask decides about: every `step`-th pixel ([`HeadingSetup::step`]) or
/// sparser, so that about this many are read.
pub const MASK_GRID_SAMPLES: f64 = 10_000.0;
/// Pixels the model fits of the iteration read (a quarter of [`MODEL_FIT_SAMPLES`]): the mask
/// needs the sky model to a fraction of [`MASK_AGREE_FLOOR_DEG`], not the final yaw.
pub const MASK_FIT_SAMPLES: f64 = 3_000.0;

/// Confidence factor of the sky fraction `f` ([`HeadingEstimate::sky_fraction`]):
/// √min(1, f / [`SKY_FULL_FRACTION`]), 0 for NaN: the noise of a yaw grows as 1/√(pixels), so
/// below half of the image the confidence falls with the square root of the sky left. A clear
/// sky leaves 0.8–1 of the image to the estimate (the rest near the sun and the neutral points,
/// unpolarized); a street canyon that hides 40 % of a fisheye's image circle about 0.55.
///
/// ```
/// use psns::heading::sky_factor;
/// assert_eq!(sky_factor(0.9), 1.0);
/// assert_eq!(sky_factor(0.125), 0.5);
/// assert_eq!(sky_factor(f64::NAN), 0.0);
/// ```
pub fn sky_factor(f: f64) -> f64 {
    let x = (f / SKY_FULL_FRACTION).clamp(0.0, 1.0).sqrt();
    if x.is_nan() {
        0.0
    } else {
        x
    }
}

/// The fraction of the image (inside the image circle of a fisheye, looking forward) that an
/// estimator can use as sky: grid pixels ([`sample_step`]) with a finite AoLP and
/// `min_dolp` ≤ DoLP ≤ 1, over the grid pixels inside the image. NaN for an empty image.
pub fn sky_fraction(aolp_deg: &Image<f32>, dolp: &Image<f32>, setup: &HeadingSetup) -> f64 {
    let i = &setup.intrinsics;
    let step = sample_step(setup);
    let (mut inside, mut sky) = (0usize, 0usize);
    for row in (0..i.height).step_by(step) {
        for col in (0..i.width).step_by(step) {
            if !i
                .ray(col as f64, row as f64)
                .is_some_and(|r| r.z > 1e-6 * r.length())
            {
                continue;
            }
            inside += 1;
            let k = row * i.width + col;
            let (a, d) = (aolp_deg.data[k], dolp.data[k] as f64);
            if a.is_finite() && d.is_finite() && d >= setup.min_dolp && d <= 1.0 {
                sky += 1;
            }
        }
    }
    sky as f64 / inside as f64
}

/// The DoLP with NaN wherever `mask` is 0 (the mask's size must be the image's).
pub fn masked_dolp(dolp: &Image<f32>, mask: &Image<u8>) -> Result<Image<f32>> {
    if (mask.width, mask.height) != (dolp.width, dolp.height) {
        return Err(Error::Invalid(format!(
            "heading: a mask of {} x {} pixels for images of {} x {}",
            mask.width, mask.height, dolp.width, dolp.height
        )));
    }
    let data = dolp
        .data
        .iter()
        .zip(&mask.data)
        .map(|(&d, &m)| if m != 0 { d } else { f32::NAN })
        .collect();
    Ok(Image::from_vec(dolp.width, dolp.height, data))
}

/// `view` with its [`PolarView::mask`] applied to the DoLP (kept in `buf`) and no mask left;
/// `view` itself without a mask.
pub fn apply_view_mask<'a>(
    view: &PolarView<'a>,
    buf: &'a mut Option<Image<f32>>,
) -> Result<PolarView<'a>> {
    match view.mask {
        None => Ok(*view),
        Some(m) => {
            let d: &'a Image<f32> = buf.insert(masked_dolp(view.dolp, m)?);
            Ok(PolarView {
                dolp: d,
                mask: None,
                ..*view
            })
        }
    }
}

/// A mask of a whole frame (`width` × `height` = the raw mosaic's) for the view of every `k`-th
/// 2 × 2 superpixel ([`crate::demosaic::superpixel::superpixel_sampled`]): a sample is sky when
/// all four pixels of its block are.
pub fn sampled_mask(mask: &Image<u8>, k: usize) -> Image<u8> {
    let (ow, oh) = (mask.width / k, mask.height / k);
    let mut out = Image::new(ow, oh);
    for i in 0..oh {
        for j in 0..ow {
            let (r, c) = (k * i, k * j);
            let sky = (r..r + 2).all(|rr| {
                (c..c + 2).all(|cc| rr < mask.height && cc < mask.width && *mask.get(rr, cc) != 0)
            });
            out.data[i * ow + j] = sky as u8;
        }
    }
    out
}

/// A mask found from the frame ([`find_sky_mask`]).
#[derive(Clone, Debug)]
pub struct FoundMask {
    /// Per pixel of the view: 1 = kept, 0 = not sky.
    pub mask: Image<u8>,
    /// Model fits made.
    pub iterations: usize,
    /// Whether the last fit's classification changed fewer than [`MASK_CHANGE_TOL`] of the
    /// usable grid pixels (the mask is the one that fit read).
    pub converged: bool,
}

/// One grid pixel of the found mask.
#[derive(Clone, Copy)]
struct Cell {
    /// Index of its pixel in the view.
    k: usize,
    /// Finite AoLP and DoLP, above the level horizon, intensity within the bounds.
    usable: bool,
    /// Usable and min_dolp ≤ DoLP ≤ 1.
    polarized: bool,
}

/// Finds which pixels of `view` are sky (module docs): its DoLP NaN where the given mask, if any,
/// is 0 first. Errors as the model fit does (too few pixels, a sun at the zenith).
pub fn find_sky_mask(view: &PolarView, setup: &HeadingSetup) -> Result<FoundMask> {
    let mut buf = None;
    let view = apply_view_mask(view, &mut buf)?;
    let i = &setup.intrinsics;
    check_image_sizes(view.aolp_deg, view.dolp, i)?;
    let g = step_for_samples(setup, MASK_GRID_SAMPLES);
    let (ni, nj) = (i.height.div_ceil(g), i.width.div_ceil(g));
    let tilt = rot_y(setup.roll_deg.to_radians()) * rot_x(setup.pitch_deg.to_radians());
    let tt = tilt.transpose();
    let mut cells = Vec::with_capacity(ni * nj);
    // the Berry residual's inputs of the polarized cells: (cell, unit ray, AoLP rad, DoLP)
    let mut rays: Vec<(usize, DVec3, f64, f64)> = Vec::new();
    // flat-fielded intensities of the polarized cells, for the frame's sky level
    let flat = |k: usize, col: usize, row: usize| -> Option<f64> {
        let l = view.s0?.data[k] as f64;
        let f = setup
            .relative_illumination
            .factor(i, col as f64, row as f64);
        (l.is_finite() && f > 0.0).then_some(l / f)
    };
    for ci in 0..ni {
        for cj in 0..nj {
            let (row, col) = (ci * g, cj * g);
            let k = row * i.width + col;
            let ray = i
                .ray(col as f64, row as f64)
                .filter(|r| r.z > 1e-6 * r.length())
                .map(|r| r.normalize());
            let Some(ray) = ray else {
                cells.push(Cell {
                    k,
                    usable: false,
                    polarized: false,
                });
                continue;
            };
            let (a, d) = (view.aolp_deg.data[k] as f64, view.dolp.data[k] as f64);
            let usable = a.is_finite() && d.is_finite() && (tt * ray).z > 0.0;
            let polarized = usable && d >= setup.min_dolp && d <= 1.0;
            if polarized {
                rays.push((cells.len(), ray, a.to_radians(), d));
            }
            cells.push(Cell {
                k,
                usable,
                polarized,
            });
        }
    }
    // intensity: within MASK_BRIGHTNESS_RATIO of the polarized pixels' median
    if view.s0.is_some() {
        let mut levels: Vec<f64> = rays
            .iter()
            .filter_map(|&(c, ..)| flat(cells[c].k, cells[c].k % i.width, cells[c].k / i.width))
            .filter(|&l| l > 0.0)
            .collect();
        if !levels.is_empty() {
            let sky = median_of(&mut levels);
            for c in cells.iter_mut().filter(|c| c.usable) {
                let l = flat(c.k, c.k % i.width, c.k / i.width).unwrap_or(f64::NAN);
                if !(l >= sky / MASK_BRIGHTNESS_RATIO && l <= sky * MASK_BRIGHTNESS_RATIO) {
                    c.usable = false;
                    c.polarized = false;
                }
            }
            rays.retain(|&(c, ..)| cells[c].polarized);
        }
    }
    let samples: Vec<(DVec3, f64, f64)> = rays.iter().map(|&(_, r, a, d)| (r, a, d)).collect();
    let pixels = fit_pixels(&samples, tilt, i.lens());
    let n = pixels.len();
    let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 4]; n]);
    // start: every usable cell
    let mut keep: Vec<bool> = cells.iter().map(|c| c.usable).collect();
    let usable = keep.iter().filter(|&&k| k).count();
    let mut converged = false;
    let mut iterations = 0;
    let mut fs = *setup;
    fs.step = step_for_samples(setup, MASK_FIT_SAMPLES);
    let mut dolp_k = view.dolp.clone();
    // the nearest grid pixel of each row and column
    let near = |x: usize, n: usize| ((x + g / 2) / g).min(n - 1);
    let cell_cols: Vec<usize> = (0..i.width).map(|c| near(c, nj)).collect();
    let cell_of = |row: usize, col: usize| near(row, ni) * nj + cell_cols[col];
    while iterations < MASK_ITERATIONS {
        // the view with every pixel whose nearest cell is not kept marked unusable
        for ((row, out), src) in dolp_k
            .data
            .chunks_mut(i.width)
            .enumerate()
            .zip(view.dolp.data.chunks(i.width))
        {
            let keep_row = &keep[near(row, ni) * nj..][..nj];
            for ((o, &d), &c) in out.iter_mut().zip(src).zip(&cell_cols) {
                *o = if keep_row[c] { d } else { f32::NAN };
            }
        }
        let v = PolarView {
            dolp: &dolp_k,
            mask: None,
            ..view
        };
        let (e, info) = model_fit_view(&v, &fs)?;
        iterations += 1;
        let p = [
            e.yaw_deg,
            info.babinet_deg,
            info.brewster_deg,
            info.sun_zenith_deg,
        ];
        fit_residuals(&pixels, p, setup.sun.azimuth_deg, false, &mut r, &mut jac);
        // robust scale of residual × DoLP over the polarized cells kept
        let mut rd: Vec<f64> = rays
            .iter()
            .zip(&r)
            .filter(|((c, ..), _)| keep[*c])
            .map(|((.., d), x)| (x * d).abs())
            .collect();
        let sigma = if rd.is_empty() {
            0.0
        } else {
            1.4826 * median_of(&mut rd)
        };
        let (floor, cap) = (
            MASK_AGREE_FLOOR_DEG.to_radians(),
            MASK_AGREE_CAP_DEG.to_radians(),
        );
        let mut agree = vec![false; cells.len()];
        for (&(c, .., d), &x) in rays.iter().zip(&r) {
            agree[c] = x.abs() <= (MASK_AGREE_SIGMAS * sigma / d).clamp(floor, cap);
        }
        // the neighbourhood vote: summed-area tables of the polarized and agreeing cells
        let table = |f: &dyn Fn(usize) -> bool| {
            let mut t = vec![0u32; (ni + 1) * (nj + 1)];
            for a in 0..ni {
                for b in 0..nj {
                    t[(a + 1) * (nj + 1) + b + 1] =
                        f(a * nj + b) as u32 + t[a * (nj + 1) + b + 1] + t[(a + 1) * (nj + 1) + b]
                            - t[a * (nj + 1) + b];
                }
            }
            t
        };
        let tp = table(&|c| cells[c].polarized);
        let ta = table(&|c| agree[c]);
        let sum = |t: &[u32], a0: usize, a1: usize, b0: usize, b1: usize| {
            t[a1 * (nj + 1) + b1] + t[a0 * (nj + 1) + b0]
                - t[a0 * (nj + 1) + b1]
                - t[a1 * (nj + 1) + b0]
        };
        let next: Vec<bool> = (0..cells.len())
            .map(|c| {
                let cell = &cells[c];
                if !cell.usable {
                    return false;
                }
                if cell.polarized && !agree[c] {
                    return false;
                }
                let (a, b) = (c / nj, c % nj);
                let (a0, a1) = (a.saturating_sub(MASK_WINDOW), (a + MASK_WINDOW + 1).min(ni));
                let (b0, b1) = (b.saturating_sub(MASK_WINDOW), (b + MASK_WINDOW + 1).min(nj));
                let np = sum(&tp, a0, a1, b0, b1);
                let na = sum(&ta, a0, a1, b0, b1);
                np == 0 || na as f64 >= MASK_MAJORITY * np as f64
            })
            .collect();
        let changed = next.iter().zip(&keep).filter(|(a, b)| a != b).count();
        if changed as f64 <= MASK_CHANGE_TOL * usable as f64 {
            converged = true;
            break;
        }
        keep = next;
    }
    let mut mask = Image::new(i.width, i.height);
    for row in 0..i.height {
        for col in 0..i.width {
            mask.data[row * i.width + col] = keep[cell_of(row, col)] as u8;
        }
    }
    Ok(FoundMask {
        mask,
        iterations,
        converged,
    })
}
