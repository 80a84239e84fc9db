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
    // 512 x 512 so that rayon splits every parallel loop (including the mean level behind the
    // σ/ε of PPID, Newton and EARI) differently for 1, 2 and 3 threads
    let (w, h) = (512, 512);
    // fractional samples: sums of small integers would be exact in f64 in any order
    let mut raw = poisson_mosaic(w, h, 500.0, 3);
    raw.data.iter_mut().for_each(|v| *v *= 0.3137);
    let layout = MosaicLayout::IMX250MZR;
    let pools: Vec<rayon::ThreadPool> = [1, 2, 3]
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        })
        .collect();
    let bits = |p: &demosaic::PolarImages| -> Vec<u32> {
        [
            &p.stokes.s0,
            &p.stokes.s1,
            &p.stokes.s2,
            &p.dolp,
            &p.aolp_deg,
        ]
        .iter()
        .flat_map(|i| i.data.iter().map(|v| v.to_bits()))
        .collect()
    };
    for m in Method::ALL {
        let r: Vec<Vec<u32>> = pools
            .iter()
            .map(|p| p.install(|| bits(&demosaic::full_chain(&raw, layout, m).unwrap())))
            .collect();
        assert!(r[0] == r[1], "{m}: 1 vs 2 threads");
        assert!(r[0] == r[2], "{m}: 1 vs 3 threads");
    }
    let truth = StokesImage::zeros(w, h);
    let est = demosaic::demosaic(&raw, layout, Method::Bilinear).unwrap();
    let s: Vec<String> = pools
        .iter()
        .map(|p| {
            p.install(|| {
                format!(
                    "{:?}",
                    psns::stokes::score(&est, &truth, 1000.0, 0.1, 4).unwrap()
                )
            })
        })
        .collect();
    assert_eq!(s[0], s[1]);
    assert_eq!(s[0], s[2]);
}
