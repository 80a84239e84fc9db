//! Noise laws (spec `demosaic.md` §4) and thread-count independence.

use psns::demosaic::{self, Method};
use psns::image::{Image, StokesImage};
use psns::sensor::mosaic::MosaicLayout;
use psns::stokes::{debiased_dolp, dolp};
use rand::SeedableRng;
use rand_distr::{Distribution, Poisson};

/// Poisson mosaic of a uniform field with `n` electrons per pixel on average (unpolarized).
fn poisson_mosaic(w: usize, h: usize, n: f64, seed: u64) -> Image<f32> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let p = Poisson::new(n).unwrap();
    Image::from_vec(
        w,
        h,
        (0..w * h).map(|_| p.sample(&mut rng) as f32).collect(),
    )
}

#[test]
fn superpixel_dolp_bias_follows_rice_law_and_debias_removes_it() {
    let layout = MosaicLayout::IMX250MZR;
    for n in [100.0f64, 1000.0] {
        let raw = poisson_mosaic(256, 256, n, 7);
        let half = demosaic::superpixel_half(&raw, layout).unwrap();
        let m = half.s0.data.len() as f64;
        let mean = |f: &dyn Fn(usize) -> f32| {
            (0..half.s0.data.len()).map(|i| f(i) as f64).sum::<f64>() / m
        };
        let biased = mean(&|i| dolp(half.s0.data[i], half.s1.data[i], half.s2.data[i]));
        let theory = 0.886 / n.sqrt();
        println!("N = {n}: mean DoLP {biased:.4}, theory {theory:.4}");
        assert!(
            (biased / theory - 1.0).abs() < 0.1,
            "N {n}: {biased} vs {theory}"
        );
        // σ(S1) = σ(S2) = √(2N) for Poisson samples
        let sigma = (2.0 * n).sqrt() as f32;
        let deb =
            mean(&|i| debiased_dolp(half.s0.data[i], half.s1.data[i], half.s2.data[i], sigma));
        println!("N = {n}: debiased mean DoLP {deb:.4}");
        assert!(deb < 0.5 * biased);
    }
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let raw = poisson_mosaic(64, 48, 500.0, 3);
    let layout = MosaicLayout::IMX250MZR;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for m in Method::ALL {
        let a = demosaic::full_chain(&raw, layout, m).unwrap();
        let b = pool.install(|| demosaic::full_chain(&raw, layout, m).unwrap());
        assert_eq!(a, b, "{m}");
    }
    let truth = StokesImage::zeros(64, 48);
    let est = demosaic::demosaic(&raw, layout, Method::Bilinear).unwrap();
    let s1 = psns::stokes::score(&est, &truth, 1000.0, 0.1, 4).unwrap();
    let s2 = pool.install(|| psns::stokes::score(&est, &truth, 1000.0, 0.1, 4).unwrap());
    assert_eq!(format!("{s1:?}"), format!("{s2:?}"));
}
