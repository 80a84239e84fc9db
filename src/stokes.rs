//! Stokes parameters, DoLP and AoLP from polarizer channels; calibrated least squares; scores.
//!
//! Convention (spec `sensor.md` §2): S0 = ½(I0 + I45 + I90 + I135), S1 = I0 − I90,
//! S2 = I45 − I135, DoLP = √(S1² + S2²)/S0, AoLP = ½ atan2(S2, S1) in [0°, 180°), measured from
//! +x (columns) toward +y (rows, down).
//!
//! Noise (spec `demosaic.md` §4): √(S1² + S2²) is Rice distributed, so DoLP is biased upward;
//! [`debiased_dolp`] subtracts the noise power, √max(0, S1² + S2² − 2σ²)/S0 with σ the standard
//! deviation of S1 (= that of S2). Average S1, S2, never DoLP or AoLP.
//!
//! Calibrated polarizers (spec `sensor.md` §4): pixel k reads
//! I_k = ½ g_k [S0 + D_k (S1 cos 2θ_k + S2 sin 2θ_k)], D_k = (ER_k − 1)/(ER_k + 1); the
//! least-squares Stokes of a block solves the normal equations of this analysis matrix.

use crate::error::{Error, Result};
use crate::image::{Image, RawPixel, StokesImage};
use crate::sensor::mosaic::MosaicLayout;
use rayon::prelude::*;

/// (S0, S1, S2) from the four channel intensities.
#[inline(always)]
pub fn from_channels(i0: f32, i45: f32, i90: f32, i135: f32) -> (f32, f32, f32) {
    (0.5 * ((i0 + i90) + (i45 + i135)), i0 - i90, i45 - i135)
}

/// Degree of linear polarization, √(S1² + S2²)/S0; 0 where S0 ≤ 0 (or is NaN).
#[inline(always)]
pub fn dolp(s0: f32, s1: f32, s2: f32) -> f32 {
    let d = (s1 * s1 + s2 * s2).sqrt() / s0;
    if s0 > 0.0 {
        d
    } else {
        0.0
    }
}

/// DoLP with the Rice bias removed: √max(0, S1² + S2² − 2σ²)/S0, σ = std of S1 and of S2.
#[inline]
pub fn debiased_dolp(s0: f32, s1: f32, s2: f32, sigma: f32) -> f32 {
    if s0 > 0.0 {
        (s1 * s1 + s2 * s2 - 2.0 * sigma * sigma).max(0.0).sqrt() / s0
    } else {
        0.0
    }
}

/// atan2 in f32, max error about 2e-7 rad (octant reduction, then |z| ≤ tan(π/8) and the
/// Taylor series of atan to z¹⁵). Written with selects only, so loops over it vectorise;
/// atan2(0, 0) = 0.
#[inline(always)]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (mn, mx) = (ax.min(ay), ax.max(ay));
    let t = mn / mx.max(f32::MIN_POSITIVE);
    let big = t > 0.414_213_57;
    let zb = (t - 1.0) / (t + 1.0);
    let z = if big { zb } else { t };
    let z2 = z * z;
    let p = -1.0 / 15.0;
    let p = p * z2 + 1.0 / 13.0;
    let p = p * z2 - 1.0 / 11.0;
    let p = p * z2 + 1.0 / 9.0;
    let p = p * z2 - 1.0 / 7.0;
    let p = p * z2 + 1.0 / 5.0;
    let p = p * z2 - 1.0 / 3.0;
    let a = z + z * z2 * p + if big { FRAC_PI_4 } else { 0.0 };
    let a = if ay > ax { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// AoLP in degrees, ½ atan2(S2, S1) wrapped to [0, 180).
#[inline(always)]
pub fn aolp_deg(s1: f32, s2: f32) -> f32 {
    let d = fast_atan2(s2, s1) * (90.0 / std::f32::consts::PI);
    let d = d + if d < 0.0 { 180.0 } else { 0.0 };
    if d >= 180.0 {
        0.0
    } else {
        d
    }
}

/// DoLP and AoLP (degrees) images of a Stokes image, row-parallel.
pub fn dolp_aolp_images(st: &StokesImage) -> (Image<f32>, Image<f32>) {
    let (w, h) = (st.width(), st.height());
    let mut d = Image::new(w, h);
    let mut a = Image::new(w, h);
    d.data
        .par_chunks_mut(w.max(1))
        .zip(a.data.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(r, (dr, ar))| {
            let (s0, s1, s2) = (st.s0.row(r), st.s1.row(r), st.s2.row(r));
            for c in 0..w {
                dr[c] = dolp(s0[c], s1[c], s2[c]);
                ar[c] = aolp_deg(s1[c], s2[c]);
            }
        });
    (d, a)
}

/// Debiased DoLP image ([`debiased_dolp`]) with one noise σ for the frame.
pub fn debiased_dolp_image(st: &StokesImage, sigma: f32) -> Image<f32> {
    let (w, h) = (st.width(), st.height());
    let mut d = Image::new(w, h);
    d.data.par_iter_mut().enumerate().for_each(|(i, v)| {
        *v = debiased_dolp(st.s0.data[i], st.s1.data[i], st.s2.data[i], sigma);
    });
    d
}

/// Doubled-angle circular mean of AoLP values in degrees (period 180°), in [0, 180).
pub fn circular_mean_aolp_deg(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (mut c, mut s) = (0f64, 0f64);
    for v in values {
        let t = (2.0 * v).to_radians();
        c += t.cos();
        s += t.sin();
    }
    if c == 0.0 && s == 0.0 {
        None
    } else {
        Some(crate::angle::SensorAngle::from_stokes(c, s).deg())
    }
}

/// Per-pixel polarizer calibration: transmission-axis angle, diattenuation and gain.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Transmission-axis angle per pixel, degrees from +x toward +y.
    pub angle_deg: Vec<f32>,
    /// Diattenuation D = (ER − 1)/(ER + 1) per pixel, in (0, 1].
    pub diattenuation: Vec<f32>,
    /// Relative gain per pixel (PRNU, pass-axis transmission), > 0.
    pub gain: Vec<f32>,
}

impl Calibration {
    /// Nominal angles of the layout, D = 1, gain 1 (least squares then equals superpixel).
    pub fn ideal(width: usize, height: usize, layout: MosaicLayout) -> Calibration {
        let mut angle_deg = vec![0f32; width * height];
        for r in 0..height {
            for c in 0..width {
                angle_deg[r * width + c] = layout.angle_deg(r, c) as f32;
            }
        }
        Calibration {
            width,
            height,
            angle_deg,
            diattenuation: vec![1.0; width * height],
            gain: vec![1.0; width * height],
        }
    }

    /// Nominal angles with one extinction ratio ER ≥ 1 for every pixel.
    pub fn with_extinction_ratio(
        width: usize,
        height: usize,
        layout: MosaicLayout,
        er: f64,
    ) -> Result<Calibration> {
        crate::error::check_range("extinction_ratio", er, 1.0 + 1e-9, f64::MAX)?;
        let mut c = Self::ideal(width, height, layout);
        let d = ((er - 1.0) / (er + 1.0)) as f32;
        c.diattenuation.iter_mut().for_each(|v| *v = d);
        Ok(c)
    }

    fn validate(&self) -> Result<()> {
        let n = self.width * self.height;
        if self.angle_deg.len() != n || self.diattenuation.len() != n || self.gain.len() != n {
            return Err(Error::Invalid(
                "calibration maps do not match width x height".into(),
            ));
        }
        if let Some(d) = self
            .diattenuation
            .iter()
            .find(|d| !(**d > 0.0 && **d <= 1.0))
        {
            return Err(Error::range("diattenuation", *d as f64, "(0, 1]"));
        }
        if let Some(g) = self.gain.iter().find(|g| !(**g > 0.0 && g.is_finite())) {
            return Err(Error::range("gain", *g as f64, "a finite number > 0"));
        }
        Ok(())
    }
}

/// Least-squares Stokes per `block` x `block` tile (block even, ≥ 2) with the calibrated
/// analysis matrix A_k = ½ g_k [1, D_k cos 2θ_k, D_k sin 2θ_k]: S = (AᵀA)⁻¹ Aᵀ I.
/// Output is (width / block) x (height / block).
pub fn least_squares_stokes<T: RawPixel>(
    raw: &Image<T>,
    cal: &Calibration,
    block: usize,
) -> Result<StokesImage> {
    cal.validate()?;
    if block < 2 || !block.is_multiple_of(2) {
        return Err(Error::range("block", block as f64, "an even number >= 2"));
    }
    if raw.width != cal.width
        || raw.height != cal.height
        || raw.data.len() != raw.width * raw.height
    {
        return Err(Error::Invalid(format!(
            "mosaic {} x {} does not match the calibration {} x {}",
            raw.width, raw.height, cal.width, cal.height
        )));
    }
    let (bw, bh) = (raw.width / block, raw.height / block);
    if bw == 0 || bh == 0 {
        return Err(Error::Invalid("mosaic smaller than one block".into()));
    }
    let mut st = StokesImage::zeros(bw, bh);
    let singular = std::sync::atomic::AtomicBool::new(false);
    st.s0
        .data
        .par_chunks_mut(bw)
        .zip(st.s1.data.par_chunks_mut(bw))
        .zip(st.s2.data.par_chunks_mut(bw))
        .enumerate()
        .for_each(|(i, ((o0, o1), o2))| {
            for j in 0..bw {
                let mut ata = [[0f64; 3]; 3];
                let mut atb = [0f64; 3];
                for r in i * block..(i + 1) * block {
                    for c in j * block..(j + 1) * block {
                        let k = r * raw.width + c;
                        let th = 2.0 * (cal.angle_deg[k] as f64).to_radians();
                        let (g, d) = (cal.gain[k] as f64, cal.diattenuation[k] as f64);
                        let a = [0.5 * g, 0.5 * g * d * th.cos(), 0.5 * g * d * th.sin()];
                        let y = raw.data[k].to_f32() as f64;
                        for p in 0..3 {
                            atb[p] += a[p] * y;
                            for q in 0..3 {
                                ata[p][q] += a[p] * a[q];
                            }
                        }
                    }
                }
                match solve3(ata, atb) {
                    Some(s) => {
                        o0[j] = s[0] as f32;
                        o1[j] = s[1] as f32;
                        o2[j] = s[2] as f32;
                    }
                    None => singular.store(true, std::sync::atomic::Ordering::Relaxed),
                }
            }
        });
    if singular.into_inner() {
        return Err(Error::Invalid(
            "calibrated analysis matrix is singular in some block (angles do not span 0..180)"
                .into(),
        ));
    }
    Ok(st)
}

/// Solves a 3 x 3 system by Cramer's rule; None when (nearly) singular.
fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det3 = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(&m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if d.is_nan() || d.abs() <= 1e-9 * scale.abs() {
        return None;
    }
    let mut x = [0f64; 3];
    for (col, xc) in x.iter_mut().enumerate() {
        let mut mc = m;
        for row in 0..3 {
            mc[row][col] = b[row];
        }
        *xc = det3(&mc) / d;
    }
    Some(x)
}

/// Demosaic quality against ground truth (spec `demosaic.md` §2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// 10 log10(peak² / MSE(S0)); infinite when exact.
    pub s0_psnr_db: f64,
    /// RMS of DoLP_est − DoLP_true.
    pub dolp_rmse: f64,
    /// Mean of DoLP_est − DoLP_true (false polarization shows as positive bias).
    pub dolp_bias: f64,
    /// RMS axial AoLP error (mod 180°) in degrees over pixels with true DoLP > threshold.
    pub aolp_rmse_deg: f64,
    /// Mean absolute axial AoLP error in degrees over the same pixels.
    pub aolp_mean_abs_deg: f64,
    /// Pixels scored for AoLP.
    pub n_aolp_pixels: usize,
    /// Pixels scored for S0 and DoLP (the image minus the border).
    pub n_pixels: usize,
}

/// Scores an estimate against the truth, excluding `border` pixels on every side. DoLP and AoLP
/// are formed per pixel in f64 from the Stokes planes; AoLP is scored where true DoLP exceeds
/// `dolp_threshold` (NaN when there is no such pixel).
pub fn score(
    est: &StokesImage,
    truth: &StokesImage,
    peak: f64,
    dolp_threshold: f64,
    border: usize,
) -> Result<Scores> {
    score_with(est, truth, peak, dolp_threshold, border, None, false)
}

/// [`score`] with two options: pixels where `exclude` is true are skipped by every score (and
/// the pixel counts), and `clip_dolp` limits the estimated DoLP to 1 (where a kernel rings to
/// S0 ≈ 0 in a dark region the raw ratio can reach 10³ and own the RMSE).
pub fn score_with(
    est: &StokesImage,
    truth: &StokesImage,
    peak: f64,
    dolp_threshold: f64,
    border: usize,
    exclude: Option<&[bool]>,
    clip_dolp: bool,
) -> Result<Scores> {
    use crate::angle::SensorAngle;
    let (w, h) = (truth.width(), truth.height());
    if est.width() != w || est.height() != h {
        return Err(Error::Invalid(format!(
            "estimate {} x {} does not match the truth {} x {}",
            est.width(),
            est.height(),
            w,
            h
        )));
    }
    if exclude.is_some_and(|m| m.len() != w * h) {
        return Err(Error::Invalid("mask does not match the image".into()));
    }
    crate::error::check_positive("peak", peak)?;
    if 2 * border >= w || 2 * border >= h {
        return Err(Error::range(
            "border",
            border as f64,
            "less than half the image size",
        ));
    }
    let d = |s0: f64, s1: f64, s2: f64| if s0 > 0.0 { s1.hypot(s2) / s0 } else { 0.0 };
    let dmax = if clip_dolp { 1.0 } else { f64::INFINITY };
    // per-row partial sums, then a fixed-order reduction: independent of the thread count
    let rows: Vec<[f64; 7]> = (border..h - border)
        .into_par_iter()
        .map(|r| {
            let mut acc = [0f64; 7];
            for c in border..w - border {
                let i = r * w + c;
                if exclude.is_some_and(|m| m[i]) {
                    continue;
                }
                let (e0, e1, e2) = (
                    est.s0.data[i] as f64,
                    est.s1.data[i] as f64,
                    est.s2.data[i] as f64,
                );
                let (t0, t1, t2) = (
                    truth.s0.data[i] as f64,
                    truth.s1.data[i] as f64,
                    truth.s2.data[i] as f64,
                );
                acc[0] += (e0 - t0) * (e0 - t0);
                let (de, dt) = (d(e0, e1, e2).min(dmax), d(t0, t1, t2));
                acc[1] += (de - dt) * (de - dt);
                acc[2] += de - dt;
                acc[6] += 1.0;
                if dt > dolp_threshold {
                    let err =
                        SensorAngle::from_stokes(e1, e2).diff(SensorAngle::from_stokes(t1, t2));
                    acc[3] += err * err;
                    acc[4] += err;
                    acc[5] += 1.0;
                }
            }
            acc
        })
        .collect();
    let mut s = [0f64; 7];
    for a in &rows {
        for k in 0..7 {
            s[k] += a[k];
        }
    }
    let n = s[6].max(1.0);
    let mse = s[0] / n;
    let na = s[5];
    Ok(Scores {
        s0_psnr_db: if mse > 0.0 {
            10.0 * (peak * peak / mse).log10()
        } else {
            f64::INFINITY
        },
        dolp_rmse: (s[1] / n).sqrt(),
        dolp_bias: s[2] / n,
        aolp_rmse_deg: if na > 0.0 {
            (s[3] / na).sqrt()
        } else {
            f64::NAN
        },
        aolp_mean_abs_deg: if na > 0.0 { s[4] / na } else { f64::NAN },
        n_aolp_pixels: na as usize,
        n_pixels: s[6] as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_atan2_matches_std() {
        let mut worst = 0f64;
        for i in 0..20000 {
            let a = i as f64 * 0.000314159 * 2.0 - 3.2;
            for r in [1e-3f64, 1.0, 7e4] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let e = (fast_atan2(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
                worst = worst.max(e);
            }
        }
        assert!(worst < 5e-7, "worst {worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert!((fast_atan2(0.0, -1.0) - std::f32::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn aolp_range_and_convention() {
        assert_eq!(aolp_deg(1.0, 0.0), 0.0);
        assert!((aolp_deg(0.0, 1.0) - 45.0).abs() < 1e-5);
        assert!((aolp_deg(-1.0, 0.0) - 90.0).abs() < 1e-5);
        assert!((aolp_deg(0.0, -1.0) - 135.0).abs() < 1e-5);
        for i in 0..3600 {
            let t = (i as f32 * 0.05).to_radians() * 2.0;
            let a = aolp_deg(t.cos(), t.sin());
            assert!((0.0..180.0).contains(&a));
        }
    }

    #[test]
    fn dolp_guard_and_debias() {
        assert_eq!(dolp(0.0, 1.0, 1.0), 0.0);
        assert_eq!(dolp(-1.0, 1.0, 1.0), 0.0);
        assert!((dolp(2.0, 0.6, 0.8) - 0.5).abs() < 1e-7);
        assert_eq!(debiased_dolp(2.0, 0.1, 0.0, 1.0), 0.0);
        assert!((debiased_dolp(2.0, 0.6, 0.8, 0.0) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn score_exact_and_known_offset() {
        let mut t = StokesImage::zeros(16, 16);
        t.s0.data.iter_mut().for_each(|v| *v = 1.0);
        t.s1.data.iter_mut().for_each(|v| *v = 0.5);
        let s = score(&t, &t, 1.0, 0.1, 2).unwrap();
        assert!(s.s0_psnr_db.is_infinite() && s.dolp_rmse == 0.0 && s.aolp_rmse_deg == 0.0);
        assert_eq!(s.n_aolp_pixels, 144);
        // rotate AoLP by 10°: S1, S2 rotate by 20°
        let mut e = t.clone();
        let a = 20f32.to_radians();
        e.s1.data.iter_mut().for_each(|v| *v = 0.5 * a.cos());
        e.s2.data.iter_mut().for_each(|v| *v = 0.5 * a.sin());
        let s = score(&e, &t, 1.0, 0.1, 2).unwrap();
        assert!((s.aolp_rmse_deg - 10.0).abs() < 1e-4, "{s:?}");
        assert!(s.dolp_rmse < 1e-6);
    }
}
