//! Full-frame (2048 x 2448, u16 12-bit) demosaic timings: `cargo bench --bench demosaic`.
//! `full_chain/*` = raw mosaic in memory → S0, S1, S2, DoLP, AoLP in memory.

use criterion::{criterion_group, criterion_main, Criterion};
use psns::demosaic::{self, Method};
use psns::image::Image;
use psns::sensor::mosaic::MosaicLayout;
use std::hint::black_box;

fn frame() -> Image<u16> {
    let (w, h) = (2448usize, 2048usize);
    let mut img = Image::new(w, h);
    // smooth content plus a deterministic hash texture, 12-bit codes
    for r in 0..h {
        for c in 0..w {
            let x = ((r * 2654435761usize) ^ (c * 40503)) % 257;
            img.data[r * w + c] = (1000 + (r + c) % 1500 + x) as u16;
        }
    }
    img
}

fn bench(cr: &mut Criterion) {
    let raw = frame();
    let layout = MosaicLayout::IMX250MZR;
    let mut g = cr.benchmark_group("full_chain");
    g.sample_size(10);
    for m in Method::ALL {
        g.bench_function(m.name(), |b| {
            b.iter(|| black_box(demosaic::full_chain(black_box(&raw), layout, m).unwrap()))
        });
    }
    g.finish();
    let mut g = cr.benchmark_group("full_chain_into");
    g.sample_size(20);
    for m in [Method::Bilinear, Method::Bicubic] {
        let mut out = demosaic::full_chain(&raw, layout, m).unwrap();
        g.bench_function(m.name(), |b| {
            b.iter(|| demosaic::full_chain_into(black_box(&raw), layout, m, &mut out).unwrap())
        });
    }
    g.finish();
    let mut g = cr.benchmark_group("stokes_only");
    g.sample_size(10);
    for m in [Method::Superpixel, Method::Bilinear, Method::Bicubic] {
        g.bench_function(m.name(), |b| {
            b.iter(|| black_box(demosaic::demosaic(black_box(&raw), layout, m).unwrap()))
        });
    }
    g.bench_function("superpixel_half", |b| {
        b.iter(|| black_box(demosaic::superpixel_half(black_box(&raw), layout).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
