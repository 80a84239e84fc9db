//! The fast path's shot noise on full-size flat fields: Poisson out to its 5 σ tail, and
//! independent between frames and between pixels at every 2-D lag, with no run of noise
//! repeated anywhere. Each detector is also shown to catch a generator that reuses one noise
//! table at shifted offsets.
//!
//! The run: six 2448 × 2048 flat-field frames of the camera at 24 dB (6.2 DN per e⁻, so the
//! codes hold whole electrons), every stage off but shot noise, 100 e⁻ per pixel.

use psns::camera::Intrinsics;
use psns::image::StokesImage;
use psns::sensor::{self, Exposure, FrameOptions, Radiance, Sensor, SensorConfig, Stages};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::sync::OnceLock;

const MEAN_E: f64 = 100.0;
const FRAMES: u64 = 6;

struct Run {
    w: usize,
    h: usize,
    /// Electrons of each frame (codes / k, rounded: whole electrons at 6.2 DN per e⁻).
    electrons: Vec<Vec<i32>>,
}

/// The six frames, made once for every test here.
fn run() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| {
        let intr = Intrinsics::default();
        let (w, h) = (intr.width, intr.height);
        let mut cfg = SensorConfig {
            gain_db: 24.0,
            black_level_dn: 0.0,
            exposure: Exposure::Fixed { us: 1000.0 },
            ..SensorConfig::default()
        };
        cfg.stages = Stages {
            shot: true,
            fwc_clip: true,
            quantize: true,
            ..Stages::none()
        };
        let s = Sensor::new(&cfg, &intr, 11).unwrap();
        let k = sensor::adc::system_gain(cfg.k0, cfg.gain_db);
        assert!(k > 6.0, "{k} DN per e⁻");
        let probe = sensor::flat_field(w, h, 1.0, 0.0, 0.0).unwrap();
        let rate = s.electron_rate(&probe).unwrap()[0];
        let flat: StokesImage = sensor::flat_field(w, h, MEAN_E / (rate * 1e-3), 0.0, 0.0).unwrap();
        let electrons = (0..FRAMES)
            .map(|f| {
                let fr = s
                    .frame(Radiance::Planes(&flat), f, FrameOptions::fast())
                    .unwrap();
                fr.codes
                    .data
                    .iter()
                    .map(|&c| (c as f64 / k).round() as i32)
                    .collect()
            })
            .collect();
        Run { w, h, electrons }
    })
}

/// P(X ≥ n) of Poisson(μ), summed from the probability mass in f64.
fn poisson_tail(mu: f64, n: usize) -> f64 {
    let mut p = (-mu).exp();
    let mut tail = 0.0;
    for k in 0..(mu as usize * 4 + 50) {
        if k > 0 {
            p *= mu / k as f64;
        }
        if k >= n {
            tail += p;
        }
    }
    tail
}

#[test]
fn the_tail_to_five_sigma_is_poisson() {
    let r = run();
    let n = (r.electrons.len() * r.w * r.h) as f64;
    let sd = MEAN_E.sqrt();
    for s in [3.0, 4.0, 5.0] {
        let at = (MEAN_E + s * sd).round() as i32;
        let seen = r.electrons.iter().flatten().filter(|&&e| e >= at).count() as f64;
        let want = n * poisson_tail(MEAN_E, at as usize);
        eprintln!("≥ {at} e⁻ (mean + {s} σ): {seen} pixels, Poisson {want:.1}");
        // a count's own spread is √want; 5 of it
        assert!(
            (seen - want).abs() < 5.0 * want.sqrt(),
            "≥ {at} e⁻: {seen} pixels, Poisson predicts {want:.1}"
        );
    }
}

/// The residuals of a frame, e − mean, as f64.
fn residuals(e: &[i32]) -> Vec<f64> {
    let m = e.iter().map(|&x| x as f64).sum::<f64>() / e.len() as f64;
    e.iter().map(|&x| x as f64 - m).collect()
}

#[test]
fn frames_of_one_pose_are_uncorrelated() {
    let r = run();
    for k in 0..r.electrons.len() - 1 {
        let (a, b) = (residuals(&r.electrons[k]), residuals(&r.electrons[k + 1]));
        let (ab, aa, bb) = a
            .iter()
            .zip(&b)
            .fold((0.0, 0.0, 0.0), |(ab, aa, bb), (x, y)| {
                (ab + x * y, aa + x * x, bb + y * y)
            });
        let rho = ab / (aa * bb).sqrt();
        // 5 σ of a correlation over n pairs
        let lim = 5.0 / (a.len() as f64).sqrt();
        assert!(rho.abs() < lim, "frames {k}, {}: ρ = {rho}", k + 1);
    }
}

/// The largest |correlation| of `x` (h rows of w) with itself at a 2-D lag other than (0, 0),
/// circular, by FFT: (row lag, column lag, ρ).
fn max_autocorrelation(x: &[f64], w: usize, h: usize) -> (usize, usize, f64) {
    let mut planner = FftPlanner::<f64>::new();
    let (fw, fh) = (planner.plan_fft_forward(w), planner.plan_fft_forward(h));
    let (iw, ih) = (planner.plan_fft_inverse(w), planner.plan_fft_inverse(h));
    let mut a: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
    // rows, then columns (through a transpose)
    let transpose = |a: &[Complex<f64>], w: usize, h: usize| -> Vec<Complex<f64>> {
        let mut t = vec![Complex::new(0.0, 0.0); w * h];
        for r in 0..h {
            for c in 0..w {
                t[c * h + r] = a[r * w + c];
            }
        }
        t
    };
    a.chunks_exact_mut(w).for_each(|row| fw.process(row));
    let mut t = transpose(&a, w, h);
    t.chunks_exact_mut(h).for_each(|col| fh.process(col));
    // the power spectrum, then back: the circular autocovariance (times w h)
    t.iter_mut()
        .for_each(|v| *v = Complex::new(v.norm_sqr(), 0.0));
    t.chunks_exact_mut(h).for_each(|col| ih.process(col));
    let mut a = transpose(&t, h, w);
    a.chunks_exact_mut(w).for_each(|row| iw.process(row));
    let zero = a[0].re;
    let mut best = (0, 0, 0f64);
    for (i, v) in a.iter().enumerate().skip(1) {
        let rho = v.re / zero;
        if rho.abs() > best.2.abs() {
            best = (i / w, i % w, rho);
        }
    }
    best
}

/// The limit on |ρ| at any lag: 6.7 σ of one correlation over n pixels (over the ~2.5 million
/// distinct lags of a full frame, a false alarm has a chance of about 1e-4).
fn rho_limit(n: usize) -> f64 {
    6.7 / (n as f64).sqrt()
}

#[test]
fn pixels_are_uncorrelated_at_every_lag() {
    let r = run();
    let x = residuals(&r.electrons[0]);
    let (dr, dc, rho) = max_autocorrelation(&x, r.w, r.h);
    eprintln!("largest |ρ| at lag ({dr}, {dc}): {rho:.2e}");
    assert!(
        rho.abs() < rho_limit(x.len()),
        "ρ = {rho} at lag ({dr}, {dc})"
    );
}

/// A frame whose lower half is its upper half's noise moved by (1024, 37): one table reused at
/// a shifted offset.
fn shifted_copy(e: &[i32], w: usize, h: usize) -> Vec<i32> {
    let mut out = e.to_vec();
    for r in h / 2..h {
        for c in 0..w {
            out[r * w + c] = e[(r - h / 2) * w + (c + 37) % w];
        }
    }
    out
}

#[test]
fn the_lag_test_catches_a_reused_table() {
    let r = run();
    let bad = residuals(&shifted_copy(&r.electrons[0], r.w, r.h));
    let (dr, dc, rho) = max_autocorrelation(&bad, r.w, r.h);
    assert!(rho.abs() > rho_limit(bad.len()), "missed: ρ {rho}");
    // the copy sits at (h/2, 37) from its source; ρ is the same at the opposite lag
    assert!(
        dr == r.h / 2 && (dc == 37 || dc == r.w - 37),
        "({dr}, {dc}): ρ {rho}"
    );
}

/// Runs of this many pixels: 12 draws of ~60 distinct values hold ~70 bits, so among the
/// ~15 million runs of three frames a chance repeat has a probability of about 1e-7.
const RUN: usize = 12;

/// How many runs of [`RUN`] pixels along rows, at every position of every frame, repeat
/// another run (by a 64-bit hash of their values).
fn repeated_runs(frames: &[&[i32]], w: usize) -> usize {
    let mut keys: Vec<u64> = Vec::new();
    for f in frames {
        for row in f.chunks_exact(w) {
            for run in row.windows(RUN) {
                // FNV-1a over the run's values
                let h = run.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &v| {
                    (h ^ v as u32 as u64).wrapping_mul(0x0100_0000_01b3)
                });
                keys.push(h);
            }
        }
    }
    keys.sort_unstable();
    keys.windows(2).filter(|p| p[0] == p[1]).count()
}

#[test]
fn no_run_of_noise_repeats() {
    let r = run();
    let frames: Vec<&[i32]> = r.electrons.iter().take(3).map(|f| &f[..]).collect();
    assert_eq!(repeated_runs(&frames, r.w), 0);
    // a table reused at a shifted offset repeats nearly every run of the copied half
    let bad = shifted_copy(&r.electrons[0], r.w, r.h);
    let repeats = repeated_runs(&[&bad], r.w);
    assert!(repeats > r.w * r.h / 4, "missed: {repeats} repeats");
}
