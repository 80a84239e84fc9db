//! The per-pixel sky and its elementary functions, one thread: `cargo bench --bench sky`.
//! `sky/sample_*` = one `Sky::sample` (radiance, DOP, E-vector) per upper-hemisphere direction;
//! `hosek/*` = one Hosek–Wilkie radiance; `vmath/*` = psns's f64 functions in a loop built for
//! the CPU's instruction set, beside libm's (`docs/performance.md`).

use criterion::{criterion_group, criterion_main, Criterion};
use psns::angle;
use psns::sky::hosek::HosekWilkie;
use psns::sky::{PolarizationModel, Sky, SkyParams};
use psns::sun::SunPosition;
use std::hint::black_box;

/// Directions spread over the upper hemisphere on a spiral.
fn directions(n: usize) -> Vec<glam::DVec3> {
    (0..n)
        .map(|i| {
            let f = (i as f64 + 0.5) / n as f64;
            angle::direction(89.0 * f.sqrt(), i as f64 * 137.508)
        })
        .collect()
}

fn sky(cr: &mut Criterion) {
    let dirs = directions(100_000);
    let mut g = cr.benchmark_group("sky");
    for (name, model) in [
        ("sample_wang", PolarizationModel::Wang),
        ("sample_rayleigh", PolarizationModel::Rayleigh),
    ] {
        let p = SkyParams {
            model,
            ..SkyParams::default()
        };
        let sky = Sky::new(SunPosition::new(50.0, 200.0), &p).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for &v in &dirs {
                    let s = sky.sample(black_box(v));
                    acc += s.radiance + s.dop + s.e.x;
                }
                black_box(acc)
            })
        });
    }
    g.finish();
    let m = HosekWilkie::new(4.0, 0.1, 40f64.to_radians(), 450.0).unwrap();
    let mut g = cr.benchmark_group("hosek");
    g.bench_function("radiance_100k", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for i in 0..100_000 {
                let th = (i % 1000) as f64 * 1.5e-3;
                let gm = (i % 997) as f64 * 3.1e-3;
                acc += m.radiance(black_box(th), gm);
            }
            black_box(acc)
        })
    });
    g.bench_function("radiance_cos_100k", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for i in 0..100_000 {
                let ct = 1.0 - (i % 1000) as f64 * 1e-3;
                let gm = (i % 997) as f64 * 3.1e-3;
                acc += m.radiance_cos(black_box(ct), gm, 1.0 - gm * gm * 0.5);
            }
            black_box(acc)
        })
    });
    g.finish();
}

macro_rules! loops {
    ($($name:ident: $f:expr),* $(,)?) => {$(
        mod $name {
            #[allow(unused_imports)]
            use psns::vmath::*;
            psns::simd_dispatch!(pub fn run = body(xs: &[f64], out: &mut [f64]));
            #[inline(always)]
            fn body(xs: &[f64], out: &mut [f64]) {
                for (o, &x) in out.iter_mut().zip(xs) {
                    *o = $f(x);
                }
            }
        }
    )*};
}

loops!(
    exp_loop: exp,
    ln_loop: ln,
    acos_loop: acos,
    pow_loop: |x| powf(x, 0.3),
    atan2_loop: |x| atan2(x, 0.7),
    hypot_loop: |x| hypot(x, 0.7),
);

fn elementary(cr: &mut Criterion) {
    let n = 1 << 16;
    let span = |lo: f64, hi: f64| -> Vec<f64> {
        (0..n)
            .map(|i| lo + (hi - lo) * ((i as f64 * 0.618_034) % 1.0))
            .collect()
    };
    type Loop = fn(&[f64], &mut [f64]);
    type Case = (&'static str, Vec<f64>, Loop, fn(f64) -> f64);
    let cases: [Case; 6] = [
        ("exp", span(-20.0, 5.0), exp_loop::run, f64::exp),
        ("ln", span(1e-3, 10.0), ln_loop::run, f64::ln),
        ("acos", span(-1.0, 1.0), acos_loop::run, f64::acos),
        ("powf", span(1e-3, 1.0), pow_loop::run, |x| x.powf(0.3)),
        ("atan2", span(-3.0, 3.0), atan2_loop::run, |x| x.atan2(0.7)),
        ("hypot", span(-3.0, 3.0), hypot_loop::run, |x| x.hypot(0.7)),
    ];
    let mut g = cr.benchmark_group("vmath");
    let mut out = vec![0.0; n];
    for (name, xs, ours, libm) in cases {
        g.bench_function(format!("{name}_psns_64k"), |b| {
            b.iter(|| ours(black_box(&xs), &mut out))
        });
        g.bench_function(format!("{name}_libm_64k"), |b| {
            b.iter(|| {
                for (o, &x) in out.iter_mut().zip(&xs) {
                    *o = libm(black_box(x));
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, sky, elementary);
criterion_main!(benches);
